"""Policies trained "elsewhere", built on the fly for the tests: torch MLPs exported to ONNX, Python files,
a Stable-Baselines3 model; and the one-cell evaluation the tests score them with."""

from __future__ import annotations

import contextlib
import json
import warnings
from pathlib import Path
from typing import Iterator

from frbench.cli import main

#: One cell per simulator: Go2, flat level 1, seed 0.
CELL = ["--robots", "go2", "--terrains", "flat", "--levels", "1", "--seeds", "0"]


def evaluate(out: Path, policy: str, *extra: str, backends: str = "mujoco,pybullet", episodes: int = 2) -> dict:
    """``frbench evaluate`` of ``policy`` on `CELL` in ``backends`` (in this process); the results."""
    status = main(["evaluate", "--policy", policy, *CELL, "--backends", backends, "--episodes", str(episodes),
                   "--jobs", "1", "--out", str(out), *extra])
    assert status == 0
    return json.loads(out.read_text())


def mlp(inputs: int = 42, outputs: int = 12, seed: int = 0, zero_output: bool = False):
    """A small torch MLP (inputs → 32 → outputs, ELU), seeded; ``zero_output``: its last layer all zeros."""
    import torch

    torch.manual_seed(seed)
    model = torch.nn.Sequential(torch.nn.Linear(inputs, 32), torch.nn.ELU(), torch.nn.Linear(32, outputs))
    if zero_output:
        torch.nn.init.zeros_(model[2].weight)
        torch.nn.init.zeros_(model[2].bias)
    return model.eval()


def export_onnx(model, path: Path, inputs: int = 42, dynamic_batch: bool = False, dtype=None,
                example: tuple | None = None, **options) -> Path:
    """``torch.onnx.export`` of ``model`` as a user would write it with torch's current exporter (one file): batch 1
    unless ``dynamic_batch``; ``example``: the example inputs (default one zero tensor (1, ``inputs``))."""
    import torch

    from frbench.policies.export import quiet_onnx_exporter

    example = example or (torch.zeros(1, inputs, dtype=dtype or torch.float32),)
    if dynamic_batch:
        options.update(input_names=["obs"], output_names=["actions"], dynamic_shapes=({0: "batch"},))
    with quiet_onnx_exporter():
        torch.onnx.export(model.eval(), example, str(path), dynamo=True, external_data=False, verbose=False, **options)
    return path


@contextlib.contextmanager
def writing_torchscript() -> Iterator[None]:
    """Build a user's TorchScript policy file as other training setups write one (legged_gym's play.py traces its
    actor and saves it; rsl-rl scripts it): torch 2.13 deprecates those calls, frbench still reads such files, and
    the tests make them here, with the calls' deprecation warnings silenced for this and nothing else."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"`torch\.jit\.(trace|trace_method|script|save|load)` is deprecated",
                                category=DeprecationWarning)
        yield


#: A Python policy file: a batched class, a single-environment class, a joint-target function and broken ones.
POLICY_FILE = '''
import numpy as np


class Zero:
    """Normalised actions 0: q* = q_default (the zero policy)."""

    def reset(self, info):
        self.info = info

    def act(self, obs):
        assert obs.dtype == np.float32 and obs.shape == (self.info["num_envs"], 42)
        return np.zeros((len(obs), 12))


class Single:
    """The same, one environment at a time."""

    batched = False

    def act(self, obs):
        assert obs.shape == (42,)
        return np.zeros(12)


class Targets:
    """Joint targets q* = q_default, read from the contract."""

    layout = {"action": "targets"}

    def reset(self, info):
        self.pose = np.array(info["contract"]["robot"]["default_pose"])

    def act(self, obs):
        return np.tile(self.pose, (len(obs), 1))


def ten_actions(obs):
    return np.zeros((len(obs), 10))


def words(obs):
    return np.full((len(obs), 12), "up")


def one_row(obs):
    return np.zeros(12)


def crashes(obs):
    return obs[:, 100]
'''
