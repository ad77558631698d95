"""The training env's composable parts, each on its own: config, presets, reward tables, held actions,
assist force, direct targets and start sources."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from frbench.backends.base import RobotState
from frbench.training.action_hold import HeldAction
from frbench.training.assist import GRAVITY, AssistForce
from frbench.training.config import TrainEnvConfig, parse_field
from frbench.training.presets import PRESETS
from frbench.tasks.actions import DirectTargets
from frbench.training.reward_tables import humanoid_reward_config, reward_table, training_reward_config
from frbench.training.start_sources import DemoStarts, RiseStarts

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------------------------------- config
def test_the_config_is_frozen_and_its_mappings_read_only():
    cfg = TrainEnvConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.num_envs = 3
    with pytest.raises(TypeError):
        cfg.gain_ranges["kp"] = (1.0, 2.0)
    assert cfg.gain_ranges["kp"] == (50.0, 80.0) and isinstance(cfg.families, tuple)
    assert TrainEnvConfig(families=["flat", "stairs"]).families == ("flat", "stairs")


@pytest.mark.parametrize("fields, message", [
    ({"action_hold": 0}, "action_hold 0: expected at least 1"),
    ({"num_envs": 0}, "num_envs 0"),
    ({"settle_steps": -1}, "settle_steps -1"),
    ({"action_scale": 0.0}, "action_scale 0.0: expected a positive number"),
    ({"families": ("flat", "lava")}, "families"),
    ({"backend": "mujoco+bullet"}, "backend 'mujoco\\+bullet'"),
    ({"demo_start_fraction": 1.5}, "demo_start_fraction 1.5: expected a fraction in \\[0, 1\\]"),
    ({"assist_force": 2.5}, "assist_force 2.5"),
    ({"residual_gate": True}, "residual_gate True: expected a base_controller"),
    ({"robot": "g1", "base_controller": "keyframe-humanoid", "rise_start_fraction": 0.5},
     "rise_start_fraction 0.5: expected residual_gate"),
    ({"robot": "g1", "base_controller": "keyframe-humanoid", "gate_phases": ("rise",)}, "gate_phases .*residual_gate"),
    ({"robot": "g1", "base_controller": "keyframe-humanoid", "residual_gate": True, "gate_phases": ("rise", "stand")},
     "gate_phases .*stand"),
    ({"morphology_ranges": {"calf_width": (0.04, 0.01)}}, "morphology_ranges"),
])
def test_the_config_refuses_bad_values_naming_the_field(fields, message):
    with pytest.raises(ValueError, match=message):
        TrainEnvConfig(**fields)


def test_the_reward_table_follows_the_robots_kind_in_the_library():
    assert TrainEnvConfig(robot="g1").reward == humanoid_reward_config() == reward_table("humanoid")
    assert TrainEnvConfig().reward == TrainEnvConfig(robot="go2").reward == training_reward_config()
    assert "head_height" in TrainEnvConfig(robot="g1").reward.weights
    assert "head_height" not in TrainEnvConfig(robot="go2").reward.weights
    explicit = training_reward_config().with_weight("action_smoothing", -0.2, "a test")
    assert TrainEnvConfig(robot="g1", reward=explicit).reward == explicit  # a given table is kept
    with pytest.raises(ValueError, match="robot kind 'tripod'"):
        reward_table("tripod")


def test_the_json_form_round_trips():
    cfg = TrainEnvConfig(robot="g1", families=("flat",), base_controller="keyframe-humanoid", residual_gate=True,
                         gate_phases=("tuck", "rise"), action_hold=4, morphology_ranges={"calf_width": (0.016, 0.04)},
                         base_controller_parameters={"stand.knee": 0.9})
    data = json.loads(json.dumps(cfg.to_dict()))
    assert TrainEnvConfig.from_dict(data) == cfg
    with pytest.raises(ValueError, match="unknown fields \\['no_such_field'\\]"):
        TrainEnvConfig.from_dict({**data, "no_such_field": 1})


def _shipped_configs():
    import torch

    yield "checkpoints/frnet-15m/config.json", json.loads((ROOT / "checkpoints/frnet-15m/config.json").read_text())
    yield "frbench/policies/checkpoints/frnet.config.json", json.loads(
        (ROOT / "frbench/policies/checkpoints/frnet.config.json").read_text())
    for path in sorted((ROOT / "frbench/policies/checkpoints/budget3m").glob("*.pt")):
        yield str(path.relative_to(ROOT)), json.loads(torch.load(path, weights_only=True)["config_json"])


def test_the_configs_of_shipped_runs_and_policies_still_load():
    loaded = 0
    for name, config in _shipped_configs():
        cfg = TrainEnvConfig.from_dict(config["env"])
        assert cfg.num_envs == config["env"]["num_envs"] and list(cfg.families) == config["env"]["families"], name
        assert dict(cfg.reward.weights) == config["env"]["reward"]["weights"], name  # the run's own table, not today's
        assert TrainEnvConfig.from_dict(cfg.to_dict()) == cfg, name
        loaded += 1
    assert loaded == 10


def test_set_parses_a_field_by_its_type():
    assert parse_field("action_hold", "10") == 10 and parse_field("assist_force", "0.6") == 0.6
    assert parse_field("curriculum", "false") is False and parse_field("families", "flat, stairs") == ("flat", "stairs")
    assert parse_field("robot", "none") is None and parse_field("base_controller", "keyframe-humanoid") == "keyframe-humanoid"
    with pytest.raises(ValueError, match="--set action_hold=ten: expected a number"):
        parse_field("action_hold", "ten")
    with pytest.raises(ValueError, match="--set reward: not a settable field"):
        parse_field("reward", "x")


def test_every_preset_builds_a_valid_config():
    for name, preset in PRESETS.items():
        cfg = TrainEnvConfig(**preset.env)
        assert cfg.robot_kind() in ("quadruped", "humanoid"), name
    g1 = TrainEnvConfig(**PRESETS["g1-residual"].env)
    assert (g1.robot, g1.base_controller, g1.residual_gate, g1.action_hold, g1.action_scale) == (
        "g1", "keyframe-humanoid", True, 10, 0.1)
    assert g1.gate_phases == ("tuck", "prop", "rock", "crouch", "rise", "hold") and not g1.randomize


# ---------------------------------------------------------------------------------------------- held actions
def test_a_held_action_yields_its_predecessors_for_each_held_step():
    held = HeldAction(3)
    assert held.decisions_per_episode(7) == 3 and HeldAction(1).decisions_per_episode(7) == 7
    zero, a, b = np.zeros((1, 2)), np.full((1, 2), 1.0), np.full((1, 2), 2.0)
    held.begin(zero)
    steps = [(p.copy(), p2.copy()) for p, p2 in held.decide(a, steps_left=7)]
    assert held.held == 3 and [(p[0, 0], p2[0, 0]) for p, p2 in steps] == [(0, 0), (1, 0), (1, 1)]
    assert held.current is a and held.previous is a  # the next decision's a_{t-1} and a_{t-2} are both a
    steps = [(p[0, 0], p2[0, 0]) for p, p2 in held.decide(b, steps_left=1)]  # the episode ends after one step
    assert held.held == 1 and steps == [(1, 1)]
    with pytest.raises(ValueError, match="action_hold 0"):
        HeldAction(0)


def test_an_action_held_for_one_step_is_the_plain_predecessor_chain():
    held = HeldAction(1)
    held.begin(np.zeros((1, 1)))
    seen = []
    for value in (1.0, 2.0, 3.0):
        seen += [(p[0, 0], p2[0, 0]) for p, p2 in held.decide(np.full((1, 1), value), steps_left=10)]
    assert seen == [(0, 0), (1, 0), (2, 1)]


# ---------------------------------------------------------------------------------------------- assist force
class _ForceRecorder:
    num_envs = 2

    def set_base_force(self, force):
        self.force = np.array(force)


def test_the_assist_force_is_a_fraction_of_the_weight_falling_to_zero():
    masses = np.array([[10.0, 2.0], [20.0, 4.0]])
    assist, backend = AssistForce(0.6, 1000.0, masses), _ForceRecorder()
    assist.apply(backend, env_steps=0)
    np.testing.assert_allclose(backend.force[:, 2], 0.6 * masses.sum(axis=1) * GRAVITY)
    assert (backend.force[:, :2] == 0).all()
    assist.apply(backend, env_steps=500)
    assert assist.fraction == pytest.approx(0.3)
    np.testing.assert_allclose(backend.force[:, 2], 0.3 * masses.sum(axis=1) * GRAVITY)
    assist.apply(backend, env_steps=2000)
    assert assist.fraction == 0.0 and (backend.force == 0).all()
    AssistForce(0.6, 1000.0, masses).clear(backend)
    assert (backend.force == 0).all()


# ---------------------------------------------------------------------------------------------- targets
def test_direct_targets_are_the_default_pose_plus_the_scaled_action():
    pose = np.array([0.1, -0.2])
    targets = DirectTargets(pose, 0.5).targets(None, np.array([[1.0, 2.0], [0.0, -1.0]]))
    np.testing.assert_allclose(targets, [[0.6, 0.8], [0.1, -0.7]])


def test_a_residual_over_a_base_controller_adds_the_scaled_action_to_its_targets():
    from frbench.robots import get_robot
    from frbench.training.residual import ResidualController

    spec = get_robot("g1")
    residual = ResidualController("zero", {}, spec, 0.25)
    residual.reset(spec, 2)
    state = RobotState.standing(spec, 2)
    action = np.ones((2, spec.n_joints))
    np.testing.assert_allclose(residual.targets(state, action), np.tile(np.asarray(spec.default_pose) + 0.25, (2, 1)))
    with pytest.raises(ValueError, match="base controller 'zero' has no residual_gate"):
        ResidualController("zero", {}, spec, 0.25, gated=True)
    with pytest.raises(ValueError, match="does not support"):
        ResidualController("keyframe-humanoid", {}, get_robot("go2"), 0.1)


# ---------------------------------------------------------------------------------------------- start sources
def test_demo_starts_draw_every_reset_and_take_valid_recordings_only():
    from frbench.training.demo_starts import DemoStartBank

    demo = DemoStarts(0.5, 1000.0, refresh_episodes=2, steps=10, stride=5)
    assert demo.fraction(0) == 0.5 and demo.fraction(500) == 0.25 and demo.fraction(1000) == 0.0
    assert demo.needs_recording(0.5) and not demo.needs_recording(0.0)
    rng, twin = np.random.default_rng(0), np.random.default_rng(0)
    assert not demo.draw(rng, 4, 0.0).any()  # off, but the generator moved on as when on
    twin.random(4)
    assert rng.random() == twin.random()
    demo.bank = DemoStartBank(states=[], targets=np.zeros((1, 4, 2)), tile_row=np.zeros(4, int),
                              valid=np.array([True, False, True, False]))
    demo.episodes_since = 0
    drawn = demo.draw(np.random.default_rng(1), 4, 1.0)
    assert drawn.tolist() == [True, False, True, False] and demo.episodes_since == 1
    demo.draw(np.random.default_rng(1), 4, 1.0)
    assert demo.needs_recording(0.5)  # two episodes since the recording: re-record


def test_rise_starts_come_from_the_bank_and_skip_taken_episodes():
    rise = RiseStarts(1.0, refresh_episodes=10)
    assert rise.needs_recording()
    assert rise.draw(np.random.default_rng(0), np.zeros(3, bool)) is None  # an empty bank starts nothing
    row = RobotState(base_pos=np.ones((1, 3)), base_quat=np.array([[1.0, 0, 0, 0]]), base_linvel=np.zeros((1, 3)),
                     base_angvel=np.zeros((1, 3)), q=np.full((1, 2), 0.5), qd=np.zeros((1, 2)))
    rise.bank, rise.episodes_since = [(row, 7, np.array([0.1, 0.2]), 3)], 0
    ids, state, tiles, targets, paths = rise.draw(np.random.default_rng(0), np.array([False, True, False]))
    assert ids.tolist() == [0, 2] and tiles == [7, 7] and paths.tolist() == [3, 3]
    np.testing.assert_array_equal(state.q, np.full((2, 2), 0.5))
    np.testing.assert_array_equal(targets, [[0.1, 0.2], [0.1, 0.2]])
    assert not rise.needs_recording()
    assert not RiseStarts(0.0, 10).needs_recording()
