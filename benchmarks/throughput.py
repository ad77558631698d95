"""Control steps per second of frbench's backends beside the raw simulator loop they wrap.

For Go2 and G1 and each backend, the robot starts fallen (random orientation and
joints, 0.5 m up) and tracks random joint targets:

* frbench step: ``backend.step(targets)`` (PD + physics + reading the state
  into frbench's conventions, which every step does for divergence checks);
* frbench step+contacts: the same plus ``backend.contacts()`` (what the task
  calls every control step for rewards and success);
* raw MuJoCo: ``Batch.step(nstep=substeps)`` on the same model and batch size,
  with the same targets written to ``ctrl`` (MuJoCo's position actuators are the PD);
* raw PyBullet: the same clients, ``getJointStates`` → PD torque →
  ``setJointMotorControlArray`` → ``stepSimulation`` for each physics step.

The three loops are timed in turn, ``--repeats`` times, and the medians are
printed (the machine is noisy). Ratio = frbench step / raw; target >= 0.8.

Run: ``python benchmarks/throughput.py [--seconds 1] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet as p

from frbench.backends import make_backend
from frbench.backends.base import RobotState
from frbench.robots import get_robot
from frbench.robots.check import random_configurations

SIZES = {"mujoco": 64, "pybullet": 4}


def _fallen(spec, n, rng):
    pos, quat, q = random_configurations(spec, rng, n)
    pos[:, :2] = 0.0
    pos[:, 2] = 0.5
    return RobotState.at_rest(pos, quat, q)


def _timed(step, seconds: float) -> float:
    """Calls of ``step`` per second over about ``seconds``."""
    step()
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        count += 1
    return count / (time.perf_counter() - start)


def measure(robot: str, backend_name: str, seconds: float, repeats: int) -> dict[str, float]:
    """Median control steps/s (summed over the batch) of each loop."""
    spec = get_robot(robot)
    n = SIZES[backend_name]
    rng = np.random.default_rng(0)
    backend = make_backend(backend_name, spec, n)
    targets = rng.uniform(spec.joint_lower, spec.joint_upper, size=(n, spec.n_joints))
    start = _fallen(spec, n, rng)

    def frbench_step():
        backend.step(targets)

    def frbench_step_contacts():
        backend.step(targets)
        backend.contacts()

    if backend_name == "mujoco":
        ctrl = backend.batch.bind("ctrl")

        def raw_step():
            ctrl[:] = targets
            backend.batch.step(nstep=backend.substeps)
    else:
        limits, kp, kd = np.asarray(spec.torque_limits), np.asarray(spec.kp), np.asarray(spec.kd)

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
    rates: dict[str, list[float]] = {name: [] for name in loops}
    for _ in range(repeats):
        for name, loop in loops.items():
            backend.reset(np.arange(n), start)
            rates[name].append(_timed(loop, seconds) * n)
    backend.close()
    return {name: float(np.median(values)) for name, values in rates.items()}


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
