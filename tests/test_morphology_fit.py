"""`frbench.robots.morphology_fit`: the URDF measurement inverts the morphology generator, and reads the
installed Go1/Go2 files as their URDFs state."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from frbench.errors import RobotFileError
from frbench.robots import get_robot
from frbench.robots.morphology import MORPHOLOGY_RANGES, sample
from frbench.robots.morphology_fit import measure_morphology
from frbench.robots.morphology_presets import LITE3_LIKE, SPOT_LIKE
from frbench.robots.morphology_urdf import cached_spec
from frbench.robots.urdf_tree import parse_urdf


def _assert_inverts(fit, params) -> None:
    for name in MORPHOLOGY_RANGES:
        assert fit.values[name] == pytest.approx(getattr(params, name), rel=1e-9, abs=1e-12), name
    assert fit.foot_mass == pytest.approx(params.foot_mass, rel=1e-9)


@pytest.mark.parametrize("robot, params", [("spot_like", SPOT_LIKE), ("lite3_like", LITE3_LIKE)])
def test_presets_measure_back_to_their_params(robot, params):
    fit = measure_morphology(get_robot(robot))
    _assert_inverts(fit, params)
    assert fit.sources["trunk_length"] == "box" and fit.sources["calf_width"] == "box"


def test_sampled_morphology_with_shifted_com_measures_back(tmp_path):
    params = dataclasses.replace(sample(np.random.default_rng(7)), trunk_com_shift=(0.02, -0.01, 0.005))
    fit = measure_morphology(cached_spec(params, "sampled", tmp_path / "sampled.urdf"))
    _assert_inverts(fit, params)
    # The draw differs from the defaults, so the check is not comparing defaults with defaults.
    assert fit.values["trunk_mass"] != pytest.approx(6.921, abs=0.01)


def test_go2_masses_and_lengths_from_its_urdf():
    spec = get_robot("go2")
    links = parse_urdf(spec.urdf_path).links
    assert links["base"].mass == pytest.approx(6.921)  # the MorphologyParams docstring's value: base link alone
    fit = measure_morphology(spec)
    # Trunk = base + the four hip-motor rotors fixed to it (0.089 kg each) + imu and radar (0 kg).
    assert fit.values["trunk_mass"] == pytest.approx(6.921 + 4 * 0.089, abs=1e-9)
    assert fit.values["hip_mass"] == pytest.approx(0.678 + 0.089, abs=1e-9)  # + thigh rotor
    assert fit.values["thigh_mass"] == pytest.approx(1.152 + 0.089, abs=1e-9)  # + calf rotor
    assert fit.values["calf_mass"] == pytest.approx(0.154, abs=1e-9)
    assert fit.foot_mass == pytest.approx(0.04, abs=1e-9)
    assert fit.values["hip_length"] == pytest.approx(0.0955, abs=1e-9)
    assert fit.values["thigh_length"] == pytest.approx(0.213, abs=1e-9)
    assert fit.values["calf_length"] == pytest.approx(0.213, abs=1e-9)
    # Go2's collisions are convex meshes: sizes come from their vertex bounds.
    assert fit.sources["trunk_length"] == "mesh bounds"
    assert 0.40 < fit.values["trunk_length"] < 0.55 and 0.15 < fit.values["trunk_width"] < 0.25


def test_go1_rotated_thigh_box_reads_as_width_and_height():
    fit = measure_morphology(get_robot("go1"))
    # The file's thigh box is 0.213 × 0.0245 × 0.034 turned by pi/2 about y: x = 0.034, y = 0.0245.
    assert fit.values["thigh_width"] == pytest.approx(0.0245, abs=1e-9)
    assert fit.values["thigh_height"] == pytest.approx(0.034, abs=1e-9)
    trunk = [fit.values[f"trunk_{k}"] for k in ("length", "width", "height")]
    assert trunk == pytest.approx([0.3762, 0.0935, 0.114], abs=1e-9)
    assert fit.values["hip_length"] == pytest.approx(0.08, abs=1e-9)


def test_non_quadruped_is_refused():
    spec = get_robot("go1").replace(kind="humanoid")
    with pytest.raises(RobotFileError, match="'go1'.*quadruped"):
        measure_morphology(spec)


def test_the_covering_table_holds_the_benchmark_quadrupeds_hip_offsets_and_shares_one_collision_structure():
    """`symmetry-assist-cover`'s table holds every benchmark quadruped's hip → thigh offset (the paper's table holds
    none), and its sampled robots all get the same self-collision exclusions, which batched MuJoCo variants need
    (thighs to 0.12 m on 0.03 m hip offsets gave 28 exclusions instead of 24 in one robot of ten)."""
    from frbench.backends.mujoco_backend import build_model
    from frbench.terrains import make_terrain
    from frbench.training.population import morphology_spec, sample_morphologies
    from frbench.training.presets import COVERING_MORPHOLOGY_RANGES, PRESETS

    low, high = COVERING_MORPHOLOGY_RANGES["hip_length"]
    table_low, table_high = MORPHOLOGY_RANGES["hip_length"]
    for robot in ("go2", "go1", "aliengo", "spot_like", "lite3_like"):
        offset = measure_morphology(get_robot(robot)).values["hip_length"]
        assert low <= offset <= high and offset > table_high, robot
    assert dict(PRESETS["symmetry-assist-cover"].env["morphology_ranges"]) == dict(COVERING_MORPHOLOGY_RANGES)
    terrain = make_terrain("flat", 1, seed=0)
    rng = np.random.default_rng(0)
    robots = sample_morphologies(40, rng, ranges=dict(COVERING_MORPHOLOGY_RANGES))
    exclusions = {build_model(morphology_spec(m, f"m{i}"), terrain).nexclude for i, m in enumerate(robots)}
    assert exclusions == {24}


def test_the_light_table_s_robots_weigh_what_the_benchmark_s_light_quadrupeds_weigh():
    """`symmetry-assist-steady-light` draws robots of 8-24 kg, a range that holds Go1, Lite3-like, Go2 and Aliengo
    (12-21 kg); the paper's table draws 19-45 kg (median 32 kg, none of 40 below 15 kg) before the standing check."""
    from frbench.robots import ground_truth
    from frbench.robots.morphology import total_mass
    from frbench.training.population import sample_morphologies
    from frbench.training.presets import LIGHT_MORPHOLOGY_RANGES, PRESETS

    assert dict(PRESETS["symmetry-assist-steady-light"].env["morphology_ranges"]) == dict(LIGHT_MORPHOLOGY_RANGES)
    assert PRESETS["symmetry-assist-steady-light"].algorithm["entropy_coef"] == 0.005
    light = [total_mass(m) for m in sample_morphologies(200, np.random.default_rng(0), ranges=dict(LIGHT_MORPHOLOGY_RANGES))]
    paper = [total_mass(m) for m in sample_morphologies(40, np.random.default_rng(0))]
    assert 8.0 <= min(light) and max(light) <= 24.0
    assert max(paper) > 35.0 and min(paper) > 15.0
    for robot in ("go1", "lite3_like", "go2", "aliengo"):
        mass = ground_truth.total_mass(get_robot(robot))
        assert 11.0 <= mass <= 22.0 and min(light) <= mass <= max(light), (robot, mass)
