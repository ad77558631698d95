"""Throughput of the training env on MuJoCo Warp's worlds (`frbench.training.env.RecoveryTrainingEnv` on
``mujoco-warp``, its arrays torch tensors on the device), split by phase.

For each batch size N: env steps per second of

* bare Warp stepping (one control period of every world, the backend's ``advance``, nothing else);
* the environment (random actions through ``step``: targets, physics, observations, privileged groups, rewards,
  success, divergence, episode ends with bank resets and the curriculum), with its time split into physics and
  environment work, and its ratio to bare stepping; resets: one episode end's bank draw and refill timed on its
  own (``reset_s``) and its share of an episode of ``episode_steps`` control steps;
* training (rsl-rl's PPO + the FR-Net estimator, ``runner.learn``): the rollout (policy inference + environment)
  and the PPO update's share;

the time to set the worlds up (``setup_s``: model and data put on the device, the first resets; with an empty
kernel cache, ``--fresh-kernel-cache``, the compile of the kernels those run) and of the first control period
(the step's kernels compiled or loaded, on a GPU the CUDA graph captured). Robots: Go2 with sampled morphologies on the training terrain grid (``go2``) and the G1
(``g1``), from device bundles built here (`device_bundle.build_bundle`, one settled start per tile and robot) or
given (``--bundle``), resized to each N; the env is built from the bundle's parts (`device_bundle.bundle_parts`).

    python benchmarks/gpu_throughput.py --device cpu --toy [--fresh-kernel-cache]  # 4 and 8 envs on Warp's CPU
    python benchmarks/gpu_throughput.py --device cuda --envs 256,1024,4096,8192 --bundle bundles/go2 --bundle-g1 bundles/g1

Prints one JSON line per (robot, N) and, with ``--out``, writes them all as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from frbench.io import atomic_write_text
from frbench.training.device_bundle import build_bundle, bundle_parts, load_bundle, resized
from frbench.training.env import RecoveryTrainingEnv

#: The bundles built when none is given: Go2 with sampled morphologies on every terrain family, and the G1.
CONFIGS = {"go2": {"num_morphologies": 32}, "g1": {"robot": "g1"}}


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


class _Timer:
    """Wall time [s] of wrapped calls, the device synchronised around each."""

    def __init__(self, device: str):
        self.device, self.total, self.calls = device, 0.0, 0

    def wrap(self, function):
        def timed(*args, **kwargs):
            _sync(self.device)
            start = time.perf_counter()
            out = function(*args, **kwargs)
            _sync(self.device)
            self.total += time.perf_counter() - start
            self.calls += 1
            return out
        return timed


def measure(bundle, n: int, device: str, steps: int, iterations: int, method: str = "frnet") -> dict:
    """The numbers of the module docstring for ``bundle`` resized to ``n`` environments."""
    from frbench.training import distributed
    from frbench.training.methods import make_train_cfg
    from frbench.training.run import estimator_sized_for

    _sync(device)
    start = time.perf_counter()
    sized = resized(bundle, n)  # model and data put, first resets (kernels loaded)
    env = RecoveryTrainingEnv(sized.config, device, bundle_parts(sized))
    _sync(device)
    setup = time.perf_counter() - start
    try:
        _sync(device)
        start = time.perf_counter()
        backend = env.backend
        backend.advance()  # the first control period: kernels compiled or loaded, the graph captured
        _sync(device)
        first = time.perf_counter() - start
        bare = _Timer(device)
        advance = bare.wrap(backend.advance)
        for _ in range(steps):
            advance()
        env._new_episodes()
        physics, resets, whole = _Timer(device), _Timer(device), _Timer(device)
        raw_advance, raw_reset = backend.advance, env._new_episodes
        backend.advance, env._new_episodes = physics.wrap(raw_advance), resets.wrap(raw_reset)
        step = whole.wrap(env.step)
        gen = torch.Generator(device=env.device).manual_seed(1)
        for _ in range(steps):
            step(0.5 * torch.randn(n, env.num_actions, device=env.device, generator=gen))
        env_time = whole.total
        one_reset = resets.wrap(raw_reset)
        before = resets.total
        one_reset()  # one episode end's resets, timed even when no episode ended within the steps
        reset_s = resets.total - before
        per_episode = env.max_episode_length * (env_time - before) / steps  # an episode's steps without resets
        out = {"envs": n, "device": device, "setup_s": round(setup, 2), "first_control_period_s": round(first, 2),
               "bare_env_steps_per_s": round(n * steps / bare.total, 1),
               "env_steps_per_s": round(n * steps / env_time, 1),
               "ratio_to_bare": round(bare.total / env_time, 3),
               "share_physics": round(physics.total / env_time, 3),
               "share_env_work": round(1 - (physics.total + before) / env_time, 3),
               "reset_s": round(reset_s, 4),
               "share_resets_per_episode": round(reset_s / (reset_s + per_episode), 4)}
        backend.advance, env._new_episodes = raw_advance, raw_reset
        if iterations:
            train_cfg = estimator_sized_for(make_train_cfg(method), env.env_masses.shape[1],
                                            len(env.spec.contact_groups), env.env_masses[0])
            runner = distributed.runner_class()(env, json.loads(json.dumps(train_cfg)), log_dir=None, device=env.device)
            runner.learn(1)  # warm-up iteration (graphs, allocator)
            _sync(device)
            start = time.perf_counter()
            runner.learn(iterations)  # the rate, nothing synchronised inside
            _sync(device)
            total = time.perf_counter() - start
            rollout = _Timer(device)  # the split: one more iteration with the environment's steps timed
            env.step = rollout.wrap(env.step)
            _sync(device)
            start = time.perf_counter()
            runner.learn(1)
            _sync(device)
            split = time.perf_counter() - start
            env_steps = n * train_cfg["num_steps_per_env"] * iterations
            out.update(train_env_steps_per_s=round(env_steps / total, 1),
                       share_ppo_update=round(1 - rollout.total / split, 3))
        return out
    finally:
        env.close()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--envs", default="256,1024,4096,8192", help="comma-separated batch sizes")
    parser.add_argument("--toy", action="store_true", help="CPU sizes: 4 and 8 envs, 20 steps, 1 iteration")
    parser.add_argument("--robots", default="go2,g1")
    parser.add_argument("--bundle", type=Path, default=None, help="the Go2 bundle (default: built here)")
    parser.add_argument("--bundle-g1", type=Path, default=None, help="the G1 bundle (default: built here)")
    parser.add_argument("--steps", type=int, default=100, help="control steps per measurement")
    parser.add_argument("--iterations", type=int, default=2, help="PPO iterations timed (0: none)")
    parser.add_argument("--morphologies", type=int, default=None, help="sampled Go2 morphologies of a built bundle")
    parser.add_argument("--fresh-kernel-cache", action="store_true",
                        help="compile Warp's kernels into an empty cache (the first control period then shows the "
                             "compile time a fresh machine pays)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.fresh_kernel_cache:
        import os
        import tempfile

        os.environ["WARP_CACHE_PATH"] = tempfile.mkdtemp(prefix="warp-cache-")  # read when Warp initialises
    sizes = [4, 8] if args.toy else [int(s) for s in args.envs.split(",")]
    steps, iterations = (20, 1) if args.toy else (args.steps, args.iterations)
    results = []
    for robot in args.robots.split(","):
        given = {"go2": args.bundle, "g1": args.bundle_g1}[robot]
        if given is not None:
            bundle = load_bundle(given)
        else:
            from frbench.training.config import TrainEnvConfig

            fields = dict(CONFIGS[robot])
            if robot == "go2" and args.morphologies:
                fields["num_morphologies"] = args.morphologies
            start = time.perf_counter()
            bundle = build_bundle(TrainEnvConfig(num_envs=max(sizes), backend="mujoco-warp", start_bank=1, **fields),
                                  log=lambda *a: print(*a, file=sys.stderr))
            print(f"{robot}: bundle built in {time.perf_counter() - start:.0f} s", file=sys.stderr)
        for n in sizes:
            row = {"robot": robot, "variants": int(np.max(bundle.arrays["robots/assignment"])) + 1,
                   "families": len(bundle.meta["config"]["families"]),
                   **measure(bundle, n, args.device, steps, iterations)}
            results.append(row)
            print(json.dumps(row), flush=True)
    if args.out:
        atomic_write_text(args.out, json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
