"""The training env reproduces its recorded rollout (tests/data/training_env_fingerprint.npz, written by
tools/training_env_fingerprint.py; see there for when it was recorded): observations, rewards and the sums of
every observation group within float32 round-off, episode ends exactly. (Bit for bit only on the CPU kind
it was recorded on: `tools/training_env_fingerprint.py --check`.)"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from training_env_fingerprint import CONFIGS, CPU_SENSITIVE_CONFIGS, FAST_CONFIGS, cpu_kind, fingerprint  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "training_env_fingerprint.npz"


@pytest.fixture(scope="module")
def reference():
    return dict(np.load(REFERENCE))


def _check(reference, name):
    if name in CPU_SENSITIVE_CONFIGS and str(reference["cpu_kind"]) != cpu_kind():
        pytest.skip(f"{name} is reproducible only on the CPU kind it was recorded on ({reference['cpu_kind']})")
    arrays = fingerprint(name)
    assert sorted(arrays) == sorted(k for k in reference if k.startswith(f"{name}/"))
    for key, value in arrays.items():
        assert value.shape == reference[key].shape, key
        if key.endswith("/done"):
            assert np.array_equal(value, reference[key]), key
        elif not key.endswith("/digest"):
            np.testing.assert_allclose(value, reference[key], rtol=1e-5, atol=1e-5, err_msg=key)


def test_the_reference_covers_every_config_and_ends_episodes(reference):
    assert str(reference["cpu_kind"]).startswith("AVX")
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
