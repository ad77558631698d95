"""The training env reproduces, bit for bit, its recorded rollout (tests/data/training_env_fingerprint.npz,
written by tools/training_env_fingerprint.py; see there for when it was recorded)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from training_env_fingerprint import CONFIGS, FAST_CONFIGS, fingerprint  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "training_env_fingerprint.npz"


@pytest.fixture(scope="module")
def reference():
    return dict(np.load(REFERENCE))


def _check(reference, name):
    arrays = fingerprint(name)
    assert sorted(arrays) == sorted(k for k in reference if k.startswith(f"{name}/"))
    for key, value in arrays.items():
        assert value.shape == reference[key].shape, key
        assert np.array_equal(value, reference[key]), key


def test_the_reference_covers_every_config_and_ends_episodes(reference):
    for name, (_, steps) in CONFIGS.items():
        assert reference[f"{name}/reward"].shape[0] == steps
        assert reference[f"{name}/digest"].shape == (steps + 1, 32)
    assert not reference["frnet-default-16/done"].any()  # one 350-step episode, not ended
    assert all(reference[f"{name}/done"].any() for name in CONFIGS if name != "frnet-default-16")


@pytest.mark.parametrize("name", FAST_CONFIGS)
def test_the_training_env_reproduces_its_recorded_rollout(reference, name):
    _check(reference, name)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in CONFIGS if n not in FAST_CONFIGS])
def test_the_training_env_reproduces_its_recorded_rollout_slow_configs(reference, name):
    _check(reference, name)
