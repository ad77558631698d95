"""The full PPO+MCP training iteration of this checkout beside another commit's, interleaved in one run.

Two worker processes, one per code base (``PYTHONPATH`` = this checkout and
``--base``, e.g. a ``git worktree add /tmp/base-6f84212 6f84212``), each build
the default FR-Net training env (``TrainEnvConfig(num_envs=N)``) and rsl-rl's
runner once, run one warm-up iteration, then take turns: each round times
``--iterations`` iterations of this checkout, then of the base, so that the
machine's load falls on both alike. Prints each round's env steps per second
of wall-clock and per second of the worker's CPU time (all its threads: a
proxy that depends less on what else the machine runs), and the median ratios
``iteration this / base: R`` (wall-clock) and ``iteration this / base, CPU time: R``.

Run: ``python benchmarks/iteration_vs_commit.py --base /tmp/base-6f84212 [--envs 256] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

#: The worker: builds env + runner, then answers each line "go K" with the env steps per wall-clock second and
#: per CPU second of K iterations.
WORKER = """
import sys, time, torch
torch.set_num_threads(1)
from rsl_rl.runners import OnPolicyRunner
from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig
from frbench.training.methods import make_train_cfg
envs = int(sys.argv[1])
env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=envs))
cfg = make_train_cfg("frnet")
runner = OnPolicyRunner(env, cfg, log_dir=None, device="cpu")
runner.learn(1)
print("ready", flush=True)
for line in sys.stdin:
    k = int(line.split()[1])
    start, cpu = time.perf_counter(), time.process_time()
    runner.learn(k)
    steps = k * cfg["num_steps_per_env"] * envs
    print(steps / (time.perf_counter() - start), steps / (time.process_time() - cpu), flush=True)
"""


def start_worker(code_root: Path, envs: int) -> subprocess.Popen:
    """A worker process importing frbench from ``code_root``."""
    env = {**os.environ, "PYTHONPATH": str(code_root)}
    return subprocess.Popen([sys.executable, "-c", WORKER, str(envs)], cwd=code_root, env=env, text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)


def ask(worker: subprocess.Popen, iterations: int) -> tuple[float, float]:
    """(env steps per wall-clock second, per CPU second) of ``iterations`` iterations in ``worker``."""
    worker.stdin.write(f"go {iterations}\n")
    worker.stdin.flush()
    wall, cpu = worker.stdout.readline().split()
    return float(wall), float(cpu)


def wait_ready(worker: subprocess.Popen, name: str) -> None:
    for line in worker.stdout:
        if line.strip() == "ready":
            return
    raise SystemExit(f"the {name} worker stopped before it was ready (exit status {worker.wait()})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", type=Path, required=True, help="a checkout of the other commit")
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--iterations", type=int, default=2, help="iterations per timing")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if not (args.base / "frbench" / "__init__.py").is_file():
        print(f"--base {args.base}: expected a checkout of frbench (no frbench/__init__.py there)", file=sys.stderr)
        raise SystemExit(2)
    this = Path(__file__).resolve().parents[1]
    workers = {"this": start_worker(this, args.envs), "base": start_worker(args.base.resolve(), args.envs)}
    try:
        for name, worker in workers.items():
            wait_ready(worker, name)
        ratios, cpu_ratios = [], []
        for repeat in range(args.repeats):
            rates = {name: ask(worker, args.iterations) for name, worker in workers.items()}
            ratios.append(rates["this"][0] / rates["base"][0])
            cpu_ratios.append(rates["this"][1] / rates["base"][1])
            print(f"round {repeat}: this {rates['this'][0]:.0f}, base {rates['base'][0]:.0f} env steps/s "
                  f"(ratio {ratios[-1]:.2f}); per CPU second this {rates['this'][1]:.0f}, base "
                  f"{rates['base'][1]:.0f} (ratio {cpu_ratios[-1]:.2f})", flush=True)
        print(f"iteration this / base: {np.median(ratios):.2f}")
        print(f"iteration this / base, CPU time: {np.median(cpu_ratios):.2f}")
    finally:
        for worker in workers.values():
            worker.stdin.close()
            worker.wait()


if __name__ == "__main__":
    main()
