"""Control steps per second of frbench's backends beside the raw simulator loop they wrap.

For Go2 and G1 and each backend, the robot starts fallen (random orientation and
joints, 0.5 m up) and tracks random joint targets:

* frbench step: ``backend.step(targets)`` (PD + physics + reading the state
  into frbench's conventions, which every step does for divergence checks);
* frbench step+contacts: the same plus ``backend.contacts()`` (what the task
  calls every control step for rewards and success);
* raw MuJoCo: the same batch, ``substeps`` × (the same PD torque in numpy,
  ``Batch.step(nstep=1)``) — the simulator loop the backend wraps;
* raw PyBullet: the same clients, ``getJointStates`` → PD torque →
  ``setJointMotorControlArray`` → ``stepSimulation`` for each physics step.

The three loops are timed in turn, ``--repeats`` times, and the medians are
printed (the machine is noisy). Ratio = frbench step / raw; target >= 0.8.

Run: ``python benchmarks/throughput.py [--seconds 1] [--repeats 5]``.
"""

from __future__ import annotations

import argparse

import numpy as np
import pybullet as p
from common import fallen, median_rates

from frbench.backends import make_backend
from frbench.robots import get_robot

SIZES = {"mujoco": 64, "pybullet": 4}


def measure(robot: str, backend_name: str, seconds: float, repeats: int) -> dict[str, float]:
    """Median control steps/s (summed over the batch) of each loop."""
    spec = get_robot(robot)
    n = SIZES[backend_name]
    rng = np.random.default_rng(0)
    backend = make_backend(backend_name, spec, n)
    targets = rng.uniform(spec.joint_lower, spec.joint_upper, size=(n, spec.n_joints))
    start = fallen(spec, n, rng)

    def frbench_step():
        backend.step(targets)

    def frbench_step_contacts():
        backend.step(targets)
        backend.contacts()

    limits, kp, kd = np.asarray(spec.torque_limits), np.asarray(spec.kp), np.asarray(spec.kd)
    if backend_name == "mujoco":
        batch = backend.batch
        ctrl, qpos, qvel = batch.bind("ctrl"), batch.bind("qpos"), batch.bind("qvel")
        qadr, dadr = backend._qadr, backend._dadr

        def raw_step():
            for _ in range(backend.substeps):
                ctrl[:] = np.clip(kp * (targets - qpos[:, qadr]) - kd * qvel[:, dadr], -limits, limits)
                batch.step(nstep=1)
    else:

        def raw_step():
            for i, sim in enumerate(backend.sims):
                c = sim.client
                for _ in range(backend.substeps):
                    states = c.getJointStates(sim.robot, sim.joints)
                    q = np.array([s[0] for s in states])
                    qd = np.array([s[1] for s in states])
                    tau = np.clip(kp * (targets[i] - q) - kd * qd, -limits, limits)
                    c.setJointMotorControlArray(sim.robot, sim.joints, p.TORQUE_CONTROL, forces=tau.tolist())
                    c.stepSimulation()

    loops = {"step": frbench_step, "step+contacts": frbench_step_contacts, "raw": raw_step}
    rates = median_rates(loops, lambda: backend.reset(np.arange(n), start), seconds, repeats)
    backend.close()
    return {name: rate * n for name, rate in rates.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="timing window per measurement")
    parser.add_argument("--repeats", type=int, default=5, help="measurements per loop (median reported)")
    args = parser.parse_args()
    print("control steps/s summed over the batch (medians)")
    print(f"{'robot':<6} {'backend':<9} {'envs':>4} {'frbench step':>13} {'+contacts':>10} {'raw':>8} {'ratio':>6} {'ratio+c':>8}")
    for robot in ("go2", "g1"):
        for backend in ("mujoco", "pybullet"):
            r = measure(robot, backend, args.seconds, args.repeats)
            print(
                f"{robot:<6} {backend:<9} {SIZES[backend]:>4} {r['step']:>13.0f} {r['step+contacts']:>10.0f} "
                f"{r['raw']:>8.0f} {r['step'] / r['raw']:>6.2f} {r['step+contacts'] / r['raw']:>8.2f}"
            )


if __name__ == "__main__":
    main()
