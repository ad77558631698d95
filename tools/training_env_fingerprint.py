"""Record (or check) a rollout fingerprint of `RecoveryTrainingEnv` for a few configs.

For every config in `CONFIGS`: the env built from it takes ``steps`` decisions with fixed actions
(a seeded normal draw, scale 0.5), and the fingerprint keeps

* ``<name>/policy``: the ``policy`` observation group (steps + 1, N, 6 + 3J) float32, first observation included;
* ``<name>/reward`` (steps, N) float32 and ``<name>/done`` (steps, N) bool;
* ``<name>/sums``: per step, for every observation group in name order, the float64 sum and sum of
  absolute values of its entries (steps + 1, 2 x groups): the whole privileged view in numbers;
* ``<name>/digest``: per step a SHA-256 of every observation group's bytes (the full privileged view,
  histories and labels, bit for bit) and of the step's log dictionary.

Bit-exact agreement (``--check``, the digests) holds on one kind of CPU: NumPy picks its SIMD kernels by
the CPU (AVX-512 vs AVX2), which moves results by an ulp (measured: 5.7e-16 in a velocity after an
episode restart). tests/test_training_env_fingerprint.py therefore compares the numbers (observations,
rewards, group sums) within float32 round-off and the episode ends exactly, not the digests.

The refactor of the training env into an adapter over `frbench.tasks.recovery.RecoveryTask` was checked
against a reference recorded on the env before it (identical for every config); the reference was then
re-recorded when MuJoCo's native position actuators changed the simulator's numerics, and again, with the
same numbers, to add the group sums.
tests/test_training_env_fingerprint.py checks that the env still reproduces it (within round-off, episode ends
exactly), so a change of the training env's numbers is a deliberate act (re-record it and say why in the commit).

    PYTHONPATH=$PWD python tools/training_env_fingerprint.py --out tests/data/training_env_fingerprint.npz
    PYTHONPATH=$PWD python tools/training_env_fingerprint.py --check tests/data/training_env_fingerprint.npz
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np

#: name -> (TrainEnvConfig keyword arguments, decisions to take). Episodes are short enough that every
#: config except the first ends and restarts episodes within its decisions.
CONFIGS = {
    "frnet-default-16": ({"num_envs": 16}, 60),
    "frnet-short-episodes": ({"num_envs": 6, "num_morphologies": 3, "families": ("flat", "stairs"),
                              "episode_steps": 20, "settle_steps": 5}, 60),
    "go2-demo-starts-assist": ({"num_envs": 6, "robot": "go2", "families": ("flat",), "episode_steps": 15,
                                "settle_steps": 5, "demo_start_fraction": 0.6, "demo_start_until": 5000.0,
                                "demo_refresh_episodes": 2, "demo_steps": 40, "demo_stride": 4,
                                "assist_force": 0.5, "assist_until": 3000.0}, 60),
    "g1-residual-hold": ({"num_envs": 3, "robot": "g1", "randomize": False, "families": ("flat",),
                          "episode_steps": 60, "settle_steps": 10, "base_controller": "keyframe-humanoid",
                          "residual_gate": True,
                          "gate_phases": ("tuck", "prop", "rock", "crouch", "rise", "hold"),
                          "action_hold": 4, "action_scale": 0.1, "rise_start_fraction": 0.5}, 40),
    "go2-split-backend-hold": ({"num_envs": 4, "robot": "go2", "backend": "mujoco+pybullet", "families": ("flat",),
                                "episode_steps": 12, "settle_steps": 5, "action_hold": 2}, 30),
}
#: Configs the default (fast) test checks; the others run under the slow marker.
FAST_CONFIGS = ("frnet-short-episodes", "go2-demo-starts-assist")
#: Configs whose rollout an ulp moves by more than round-off (a contact made or missed: frnet-default-16's
#: observations differ by 0.04 from step 14, 12 by step 60, between an AVX-512 and an AVX2 recording); they
#: are compared only on the CPU kind the reference was recorded on.
CPU_SENSITIVE_CONFIGS = ("frnet-default-16",)


def cpu_kind() -> str:
    """The SIMD extensions NumPy found on this CPU (the AVX family), which pick its kernels' round-off."""
    from numpy._core._multiarray_umath import __cpu_features__

    return ",".join(sorted(name for name, on in __cpu_features__.items() if on and name.startswith("AVX")))


def make_config(name: str):
    """The `TrainEnvConfig` of fingerprint ``name`` (a G1 gets the humanoid reward table: the reference was recorded
    with ``reward=humanoid_reward_config()`` given explicitly, before the config chose it by the robot's kind)."""
    from frbench.training.env import TrainEnvConfig

    return TrainEnvConfig(**CONFIGS[name][0])


def _digest(obs, log: dict) -> bytes:
    h = hashlib.sha256()
    for key in sorted(obs.keys()):
        h.update(key.encode())
        h.update(obs[key].numpy().tobytes())
    h.update(json.dumps(log, sort_keys=True).encode())
    return h.digest()


def _sums(obs) -> np.ndarray:
    """[sum, sum of |x|] of every observation group in name order, float64: shape (2 x groups,)."""
    values = [obs[key].numpy().astype(np.float64) for key in sorted(obs.keys())]
    return np.array([f(v) for v in values for f in (np.sum, lambda a: np.sum(np.abs(a)))])


def fingerprint(name: str) -> dict[str, np.ndarray]:
    """The rollout fingerprint of config ``name`` (see the module docstring)."""
    import torch

    from frbench.training.env import RecoveryTrainingEnv

    torch.set_num_threads(1)
    env = RecoveryTrainingEnv(make_config(name))
    steps = CONFIGS[name][1]
    actions = np.random.default_rng(1234).normal(0.0, 0.5, size=(steps, env.num_envs, env.num_actions))
    try:
        obs = env.get_observations()
        policy, rewards, dones, digests = [obs["policy"].numpy().copy()], [], [], [_digest(obs, {})]
        sums = [_sums(obs)]
        for t in range(steps):
            obs, reward, done, extras = env.step(torch.as_tensor(actions[t], dtype=torch.float32))
            policy.append(obs["policy"].numpy().copy())
            rewards.append(reward.numpy().copy())
            dones.append(done.numpy().copy())
            digests.append(_digest(obs, extras["log"]))
            sums.append(_sums(obs))
    finally:
        env.close()
    return {f"{name}/policy": np.stack(policy), f"{name}/reward": np.stack(rewards),
            f"{name}/done": np.stack(dones), f"{name}/sums": np.stack(sums), f"{name}/digest": np.frombuffer(b"".join(digests), np.uint8).reshape(-1, 32)}


def mismatches(reference: dict, names) -> list[str]:
    """The arrays of configs ``names`` that differ from ``reference`` (empty: identical)."""
    bad = []
    for name in names:
        for key, value in fingerprint(name).items():
            if key not in reference or not np.array_equal(reference[key], value):
                bad.append(key)
    return bad


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="write the fingerprint of every config here (.npz)")
    parser.add_argument("--check", help="compare every config with this reference (.npz)")
    parser.add_argument("--configs", default=",".join(CONFIGS), help="comma-separated config names")
    args = parser.parse_args(argv)
    names = [n for n in args.configs.split(",") if n]
    if args.check:
        bad = mismatches(dict(np.load(args.check)), names)
        print("identical" if not bad else "DIFFERENT: " + ", ".join(bad))
        return 1 if bad else 0
    arrays = {}
    for name in names:
        arrays.update(fingerprint(name))
        print(name, "recorded", flush=True)
    np.savez_compressed(args.out, cpu_kind=np.array(cpu_kind()), **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main())
