"""Training throughput: the training env and a full PPO+MCP iteration beside the simulator's own limit.

Three loops on ONE MuJoCo batch (the training env's: 256 randomised robots on
the terrain grid, Go2-sized morphologies), timed in turn, interleaved, for
``--repeats`` rounds so that the machine's load falls on all three alike:

* raw: the true limit — targets written to the native actuators' controls and
  one ``Batch.step(nstep=substeps)`` per control step, nothing else;
* env: `RecoveryTrainingEnv.step` (zero actions; episodes long enough not to
  reset inside a timing), with observations, rewards, success signals;
* iteration: rsl-rl's ``OnPolicyRunner.learn`` of FR-Net (rollout of 24 steps
  + PPO with the MCP on its mini-batches), as env steps per second.

Prints the per-round ratios, then exactly ``env / raw: R`` and
``iteration / raw: R`` (medians of the rounds) and ``construction: S s``: the
time to build the env a second time in this process (feasibility checks,
compiled variants and height rasters then come from frbench's cache; the first
build, which may fill it, is printed before). Targets (256 envs, Go2, MuJoCo):
env / raw >= 0.9, iteration / raw >= 0.6, construction <= 5 s.

Then where an iteration's seconds go (medians of the rounds): the rollout's
physics at the raw rate, ``env.step``, the rest of the rollout (the policy's
actions and values, storage, returns), PPO+MCP's update, and that update's
arithmetic alone: forward, backward and one fused Adam step of each network
(actor, critic, estimator encoder and decoder; copies) on random mini-batches
of PPO's size, epochs × mini-batches times, on the update's threads. The last
line bounds ``iteration / raw`` from above: the raw rollout plus that
arithmetic, with no overhead at all.

Run: ``python benchmarks/training_throughput.py [--envs 256] [--seconds 3] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np
import torch
from common import timed

from rsl_rl.modules import MLP

from frbench.training.algorithm import torch_threads, update_threads
from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig


def build_env(envs: int) -> tuple[RecoveryTrainingEnv, float]:
    """The benchmark's training env and the seconds its construction took."""
    start = time.perf_counter()
    env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=envs, episode_steps=100000))
    return env, time.perf_counter() - start


def timed_phases(runner, env, iterations: int) -> tuple[float, dict[str, float]]:
    """Env steps/s of ``iterations`` PPO iterations and their seconds per iteration in ``env.step``, in the update
    and in the rest of the loop."""
    spent = {"env.step": 0.0, "update": 0.0}

    def timing(name, call):
        def wrapper(*args):
            start = time.perf_counter()
            result = call(*args)
            spent[name] += time.perf_counter() - start
            return result
        return wrapper

    step, update = env.step, runner.alg.update
    env.step, runner.alg.update = timing("env.step", step), timing("update", update)
    try:
        start = time.perf_counter()
        runner.learn(iterations)
        total = time.perf_counter() - start
    finally:
        env.step, runner.alg.update = step, update
    phases = {name: value / iterations for name, value in spent.items()}
    phases["rest of the rollout"] = total / iterations - phases["env.step"] - phases["update"]
    rate = iterations * runner.cfg["num_steps_per_env"] * env.num_envs / total
    return rate, phases


def update_arithmetic(runner, repeats: int = 3) -> float:
    """Seconds of the update's arithmetic alone (see the module docstring): the median of ``repeats``."""
    alg = runner.alg
    modules = [m for net in (alg.actor, alg.critic) for m in net.modules() if isinstance(m, MLP)]
    networks = [copy.deepcopy(m) for m in modules]
    rows = alg.storage.num_envs * alg.storage.num_transitions_per_env // alg.num_mini_batches
    inputs = [torch.randn(rows, next(n.parameters()).shape[1]) for n in networks]
    optimizer = torch.optim.Adam([p for n in networks for p in n.parameters()], lr=1e-3, fused=True)
    times = []
    with torch_threads(update_threads()):
        for _ in range(repeats):
            start = time.perf_counter()
            for _ in range(alg.num_learning_epochs * alg.num_mini_batches):
                loss = sum(n(x).square().mean() for n, x in zip(networks, inputs))
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
            times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--seconds", type=float, default=3.0, help="seconds per timing of the raw and env loops")
    parser.add_argument("--iterations", type=int, default=1, help="PPO iterations per timing")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)  # the rollout's setting in `frbench train`; the update takes the cores itself
    first, first_s = build_env(args.envs)
    first.close()
    print(f"first construction: {first_s:.1f} s")
    env, construction_s = build_env(args.envs)
    backend = env.backend
    batch, n_joints = backend.batch, env.num_actions
    ctrl = batch.bind("ctrl")
    targets = np.tile(env.spec.default_pose, (args.envs, 1))

    def raw_step():
        ctrl[:, :n_joints] = targets
        batch.step(nstep=backend.substeps)

    actions = torch.zeros(args.envs, n_joints)
    from rsl_rl.runners import OnPolicyRunner

    from frbench.training.methods import make_train_cfg

    cfg = make_train_cfg("frnet")
    runner = OnPolicyRunner(env, cfg, log_dir=None, device="cpu")
    runner.learn(1)  # warm-up
    steps_per_iteration = cfg["num_steps_per_env"] * args.envs

    env_ratios, iteration_ratios, breakdowns = [], [], []
    for repeat in range(args.repeats):
        raw = timed(raw_step, args.seconds) * args.envs
        stepped = timed(lambda: env.step(actions), args.seconds) * args.envs
        learned, phases = timed_phases(runner, env, args.iterations)
        breakdowns.append({"raw physics": steps_per_iteration / raw, **phases,
                           "update arithmetic": update_arithmetic(runner)})
        env_ratios.append(stepped / raw)
        iteration_ratios.append(learned / raw)
        print(f"round {repeat}: raw {raw:.0f}, env {stepped:.0f}, iteration {learned:.0f} env steps/s "
              f"(env / raw {stepped / raw:.2f}, iteration / raw {learned / raw:.2f})", flush=True)
    env.close()
    print(f"env / raw: {np.median(env_ratios):.2f}")
    print(f"iteration / raw: {np.median(iteration_ratios):.2f}")
    print(f"construction: {construction_s:.1f} s")
    median = {name: float(np.median([b[name] for b in breakdowns])) for name in breakdowns[0]}
    print("seconds per iteration: " + ", ".join(f"{name} {value:.3f}" for name, value in median.items()))
    ceiling = median["raw physics"] / (median["raw physics"] + median["update arithmetic"])
    print(f"iteration / raw with no overhead (raw rollout + update arithmetic): {ceiling:.2f}")


if __name__ == "__main__":
    main()
