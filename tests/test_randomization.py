"""Domain randomisation: ranges, determinism, shapes, generated morphologies."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.backends.base import PhysicsParams
from frbench.robots import morphology, morphology_urdf
from frbench.robots.morphology import MORPHOLOGY_RANGES, MorphologyParams
from frbench.training import randomization as RD

N = 512


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    return RD.morphology_spec(MorphologyParams(), "rd_default", tmp_path_factory.mktemp("morph"))


def test_control_ranges_are_the_papers():
    assert RD.CONTROL_RANGES["kp"] == (20.0, 80.0)
    assert RD.CONTROL_RANGES["kd"] == (0.6, 2.0)
    assert RD.CONTROL_RANGES["motor_strength"] == (0.9, 1.1)
    assert RD.CONTROL_RANGES["com_shift"] == (-0.05, 0.05)
    assert RD.CONTROL_RANGES["payload"] == (-2.0, 2.0)
    assert RD.CONTROL_RANGES["motor_friction"] == (0.2, 1.25)
    assert set(RD.PAPER_CONTROL_KEYS) | {"friction"} == set(RD.CONTROL_RANGES)


def _within(values: np.ndarray, key: str) -> bool:
    low, high = RD.CONTROL_RANGES[key]
    return bool(np.all((values >= low) & (values <= high)))


def test_physics_shapes_and_ranges(spec):
    p = RD.sample_physics(spec, N, np.random.default_rng(0))
    assert isinstance(p, PhysicsParams)
    assert p.kp.shape == p.kd.shape == p.motor_strength.shape == (N, 12)
    assert p.friction.shape == p.payload.shape == (N,)
    for key in ("kp", "kd", "motor_strength", "friction", "payload"):
        assert _within(getattr(p, key), key), key
    # one gain per environment, shared by its joints; strength per joint
    assert np.all(p.kp == p.kp[:, :1]) and np.all(p.kd == p.kd[:, :1])
    assert len(np.unique(p.kp[:, 0])) == N
    assert not np.all(p.motor_strength == p.motor_strength[:, :1])
    # the draws spread over the range
    assert p.kp.min() < 25 and p.kp.max() > 75
    assert p.payload.min() < -1.5 and p.payload.max() > 1.5


def test_per_joint_gains(spec):
    p = RD.sample_physics(spec, N, np.random.default_rng(0), per_joint_gains=True)
    assert _within(p.kp, "kp") and _within(p.kd, "kd")
    assert not np.all(p.kp == p.kp[:, :1])


def test_extra_shapes_and_ranges(spec):
    e = RD.sample_extra(spec, N, np.random.default_rng(0))
    assert e.com_shift.shape == (N, 3) and e.motor_friction.shape == (N, 12)
    assert _within(e.com_shift, "com_shift") and _within(e.motor_friction, "motor_friction")


def test_same_seed_same_values_different_seed_differs(spec):
    a = RD.sample_physics(spec, 64, np.random.default_rng(7))
    b = RD.sample_physics(spec, 64, np.random.default_rng(7))
    c = RD.sample_physics(spec, 64, np.random.default_rng(8))
    for key in ("kp", "kd", "motor_strength", "friction", "payload"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        assert not np.array_equal(getattr(a, key), getattr(c, key))
    ea, eb, ec = (RD.sample_extra(spec, 64, np.random.default_rng(s)) for s in (7, 7, 8))
    np.testing.assert_array_equal(ea.com_shift, eb.com_shift)
    np.testing.assert_array_equal(ea.motor_friction, eb.motor_friction)
    assert not np.array_equal(ea.com_shift, ec.com_shift)


def test_absent_keys_are_nominal(spec):
    ranges = {k: v for k, v in RD.CONTROL_RANGES.items() if k not in ("kp", "kd", "payload", "com_shift")}
    p = RD.sample_physics(spec, 8, np.random.default_rng(0), ranges)
    np.testing.assert_array_equal(p.kp, np.tile(spec.kp, (8, 1)))
    np.testing.assert_array_equal(p.kd, np.tile(spec.kd, (8, 1)))
    np.testing.assert_array_equal(p.payload, np.zeros(8))
    assert _within(p.friction, "friction")
    e = RD.sample_extra(spec, 8, np.random.default_rng(0), ranges)
    np.testing.assert_array_equal(e.com_shift, np.zeros((8, 3)))


def test_bad_ranges_rejected(spec):
    with pytest.raises(ValueError, match="kp"):
        RD.sample_physics(spec, 2, np.random.default_rng(0), {**RD.CONTROL_RANGES, "kp": (80.0, 20.0)})
    with pytest.raises(ValueError, match="unknown"):
        RD.sample_physics(spec, 2, np.random.default_rng(0), {**RD.CONTROL_RANGES, "kpp": (1.0, 2.0)})


def test_morphologies_within_ranges_and_deterministic():
    params = RD.sample_morphologies(32, np.random.default_rng(3))
    for p in params:
        for name, (low, high) in MORPHOLOGY_RANGES.items():
            assert low <= getattr(p, name) <= high, name
    assert params == RD.sample_morphologies(32, np.random.default_rng(3))
    assert params != RD.sample_morphologies(32, np.random.default_rng(4))


def test_morphology_specs_distinct(tmp_path):
    params = RD.sample_morphologies(64, np.random.default_rng(0))
    specs = RD.morphology_specs(params, tmp_path)
    assert len(specs) == 64
    assert all(s.n_joints == 12 and s.kind == "quadruped" for s in specs)
    assert all(s.urdf_path.is_file() for s in specs)
    assert len({s.name for s in specs}) == 64
    assert len({s.urdf_path for s in specs}) == 64
    masses = [morphology.total_mass(p) for p in params]
    assert len(set(masses)) == 64
    # the written file is the morphology's URDF, and its masses are the params'
    text = specs[5].urdf_path.read_text()
    assert text == morphology_urdf.urdf_string(params[5], name=specs[5].name)
    assert repr(params[5].trunk_mass) in text


def test_morphology_spec_cache_is_keyed_by_params(tmp_path):
    a, b = RD.sample_morphologies(2, np.random.default_rng(1))
    sa = RD.morphology_spec(a, "robot", tmp_path)
    mtime = sa.urdf_path.stat().st_mtime_ns
    assert RD.morphology_spec(a, "robot", tmp_path).urdf_path == sa.urdf_path
    assert sa.urdf_path.stat().st_mtime_ns == mtime  # not rewritten
    sb = RD.morphology_spec(b, "robot", tmp_path)
    assert sb.urdf_path != sa.urdf_path
    assert RD.params_hash(a) == RD.params_hash(MorphologyParams(**{f: getattr(a, f) for f in a.__dataclass_fields__}))
    assert RD.params_hash(a) != RD.params_hash(b)
    assert sa.urdf_path.parent.name == RD.params_hash(a)


def test_can_stand_separates_holding_from_sagging_robots():
    from frbench.robots import get_robot
    from frbench.training.feasibility import can_stand

    go2 = get_robot("go2")
    assert can_stand(go2, kp=40.0, kd=1.0)
    assert not can_stand(go2, kp=3.0, kd=0.1)  # sinks onto its body


def test_training_morphologies_all_stand_at_the_lowest_training_gains():
    import torch

    from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig
    from frbench.training.feasibility import can_stand

    torch.set_num_threads(1)
    env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=4, num_morphologies=4, episode_steps=2, settle_steps=1,
                                             families=("flat",)))
    assert len(env.specs) == 4 and env.robots.rejected >= 1  # the paper's table yields many robots too heavy to stand
    assert all(can_stand(spec, 50.0, 1.0) for spec in env.specs)
    env.close()
