"""The training environment, a run's checkpoint/resume, and the learned-policy loader."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from frbench.errors import FrbenchError, PolicyError
from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig
from frbench.training.reward_tables import training_reward_config
from frbench.training.rewards import PAPER_WEIGHTS


@pytest.fixture(scope="module")
def env():
    torch.set_num_threads(1)
    environment = RecoveryTrainingEnv(TrainEnvConfig(num_envs=8, episode_steps=6, settle_steps=5, num_morphologies=4))
    yield environment
    environment.close()


def test_observation_groups_have_the_papers_sizes(env):
    obs = env.get_observations()
    widths = {key: tuple(value.shape) for key, value in obs.items()}
    assert widths == {"policy": (8, 42), "history": (8, 210), "privileged": (8, 277), "mass": (8, 4),
                      "contact": (8, 13), "velocity": (8, 3), "extrinsics": (8, 11)}
    assert torch.isfinite(obs["privileged"]).all()


def test_mass_labels_are_pinocchio_group_masses_plus_payload(env):
    from frbench.robots import ground_truth

    obs = env.get_observations()
    for i in range(env.num_envs):
        spec = env.specs[env.assignment[i]]
        expected = ground_truth.group_masses(spec)
        expected[0] += env.env_payload[i]
        np.testing.assert_allclose(obs["mass"][i].numpy(), expected, rtol=1e-5)


def test_episodes_end_together_and_the_curriculum_moves(env):
    dones = []
    for _ in range(6):
        obs, reward, done, extras = env.step(torch.zeros(env.num_envs, env.num_actions))
        dones.append(bool(done.all()))
        assert reward.shape == (env.num_envs,) and torch.isfinite(reward).all()
    assert dones == [False] * 5 + [True]
    assert extras["time_outs"].all()
    assert "/episode/success_all" in extras["log"] and "/curriculum/level/all" in extras["log"]
    assert env.step_count == 0  # a new episode started


def test_the_training_reward_keeps_the_papers_weights_visible():
    config = training_reward_config()
    deviations = config.deviations()
    assert set(deviations) == {"joint_velocity", "joint_acceleration", "joint_torques", "safety_force", "base_height"}
    assert config.weights["base_height"] == 6.0 and config.weights["safety_force"] == pytest.approx(-1e-3)
    assert deviations["joint_velocity"][0] == PAPER_WEIGHTS["joint_velocity"] == -1e-2
    assert config.weights["joint_velocity"] == pytest.approx(-1e-3)
    assert config.weights["upright_orientation"] == 6.0


def test_a_run_checkpoints_resumes_and_its_policy_acts_identically(tmp_path, monkeypatch):
    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot
    from frbench.training import run as run_module
    from frbench.training.run import TrainingRun

    monkeypatch.setattr(run_module, "SNAPSHOT_EVERY_STEPS", 200)

    cfg = TrainEnvConfig(num_envs=8, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat", "rough"))
    run = TrainingRun(tmp_path / "run", "frnet", cfg, total_steps=8 * 24 * 2, checkpoint_every=1)
    run.train(progress_bar=False)
    assert run.iteration == 2 and run.env_steps == 384
    levels = run.env.curriculum.level.copy()
    data = torch.load(tmp_path / "run" / "policy.pt", weights_only=True)
    assert data["format"] == "frbench-policy-v1" and data["method"] == "frnet" and data["env_steps"] == 384
    resumed = TrainingRun(tmp_path / "run", total_steps=8 * 24 * 3, resume=True, checkpoint_every=1)
    assert resumed.iteration == 2 and resumed.env_steps == 384
    assert np.array_equal(resumed.env.curriculum.level, levels)
    resumed.train(progress_bar=False)
    assert resumed.iteration == 3 and resumed.env_steps == 576
    assert [row["iteration"] for row in json.loads((tmp_path / "run" / "progress.json").read_text())] == [1, 2, 3]
    # a snapshot each time the run crosses another 200 env steps: at 384 and 576 (192 crossed none)
    assert sorted(p.name for p in (tmp_path / "run" / "snapshots").iterdir()) == ["policy_384.pt", "policy_576.pt"]
    assert (tmp_path / "run" / "curve.png").stat().st_size > 1000
    spec = get_robot("go2")
    obs = {"base_angvel": np.full((2, 3), 0.1), "projected_gravity": np.tile([0.0, 0.0, 1.0], (2, 1)),
           "joint_pos": np.tile(spec.default_pose, (2, 1)), "joint_vel": np.zeros((2, 12)),
           "previous_action": np.tile(spec.default_pose, (2, 1))}
    actions = []
    for _ in range(2):
        policy = load_policy(str(tmp_path / "run"))
        policy.reset(spec, 2)
        actions.append(np.stack([policy.act(obs) for _ in range(3)]))
    assert np.array_equal(actions[0], actions[1])
    assert actions[0].shape == (3, 2, 12) and np.isfinite(actions[0]).all()
    # the ONNX export carries the estimator and matches the torch actor
    import onnx
    from onnx.reference import ReferenceEvaluator
    from tensordict import TensorDict

    from frbench.policies.export import export_onnx, sidecar_path

    path = export_onnx(str(tmp_path / "run"), tmp_path / "policy.onnx")
    onnx.checker.check_model(onnx.load(path))
    o, h = np.random.default_rng(0).normal(size=(1, 42)).astype(np.float32), np.zeros((1, 210), np.float32)
    exported = ReferenceEvaluator(str(path)).run(None, {"obs": o, "history": h})[0]
    with torch.inference_mode():
        reference = policy.actor(TensorDict({"policy": torch.tensor(o), "history": torch.tensor(h)}, batch_size=[1]))
    np.testing.assert_allclose(exported, reference.numpy(), atol=1e-5)
    assert json.loads(sidecar_path(path).read_text())["inputs"] == {"obs": ["batch", 42], "history": ["batch", 210]}


def test_a_resumed_run_can_start_a_reward_stage_with_the_papers_motion_penalties(tmp_path):
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    TrainingRun(tmp_path / "run", "ppo", cfg, total_steps=4 * 24, checkpoint_every=1).train(progress_bar=False)
    from frbench.commands.train import reward_weight_changes

    changes = reward_weight_changes(1.0, ["action_smoothing=-0.1"])
    assert changes == {"joint_velocity": -1e-2, "joint_acceleration": -2.5e-6, "joint_torques": -5e-4,
                       "action_smoothing": -0.1}
    staged = TrainingRun(tmp_path / "run", total_steps=4 * 24 * 2, resume=True, checkpoint_every=1,
                         command="frbench train --resume run --motion-penalties 1", reward_stage=changes)
    for term in ("joint_velocity", "joint_acceleration", "joint_torques"):
        assert staged.env.core.reward.config.weights[term] == PAPER_WEIGHTS[term]
    assert staged.env.core.reward.config.weights["action_smoothing"] == -0.1
    assert staged.env.core.reward.config.weights["safety_force"] == pytest.approx(0.1 * PAPER_WEIGHTS["safety_force"])
    assert staged.env_steps == 96
    staged.train(progress_bar=False)
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["stages"] == [{"from_env_steps": 96, "weights": changes,
                                 "command": "frbench train --resume run --motion-penalties 1"}]
    # the policy checkpoint carries the staged config; a plain resume keeps the stage's weights
    data = torch.load(tmp_path / "run" / "policy.pt", weights_only=True)
    assert json.loads(data["config_json"])["stages"][0]["from_env_steps"] == 96
    again = TrainingRun(tmp_path / "run", resume=True)
    assert again.env.core.reward.config.weights["joint_velocity"] == PAPER_WEIGHTS["joint_velocity"]
    with pytest.raises(FrbenchError, match="expected a scale >= 0"):
        reward_weight_changes(-1.0, [])
    with pytest.raises(FrbenchError, match="expected TERM=WEIGHT, e.g. action_smoothing=-0.1"):
        reward_weight_changes(None, ["action_smoothing"])
    with pytest.raises(FrbenchError, match=r"unknown reward terms \['smoothness'\]"):
        reward_weight_changes(None, ["smoothness=-1"])


def test_a_resumed_run_can_start_a_stage_with_another_entropy_coefficient(tmp_path):
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    TrainingRun(tmp_path / "run", "ppo", cfg, total_steps=4 * 24, checkpoint_every=1,
                train_overrides={"algorithm": {"entropy_coef": 0.01}}).train(progress_bar=False)
    staged = TrainingRun(tmp_path / "run", total_steps=4 * 24 * 2, resume=True, checkpoint_every=1,
                         command="frbench train --resume run --entropy-coef 0.005",
                         algorithm_stage={"entropy_coef": 0.005})
    assert staged.runner.alg.entropy_coef == 0.005 and staged.env_steps == 96
    staged.train(progress_bar=False)
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["train_cfg"]["algorithm"]["entropy_coef"] == 0.005
    assert config["stages"] == [{"from_env_steps": 96, "weights": {}, "algorithm": {"entropy_coef": 0.005},
                                 "command": "frbench train --resume run --entropy-coef 0.005"}]
    assert TrainingRun(tmp_path / "run", resume=True).runner.alg.entropy_coef == 0.005


def test_an_action_held_for_several_control_steps_is_one_decision_in_training_and_deployment(tmp_path):
    """``action_hold`` 3 over 7-step episodes: decisions advance 3, 3, 1 control steps, their rewards summed; the
    deployed policy asks its network once every 3 `act` calls and adds the same action in between."""
    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot
    from frbench.training.env import RecoveryTrainingEnv
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=2, robot="go2", randomize=False, families=("flat",), episode_steps=7,
                         settle_steps=2, action_hold=3)
    env = RecoveryTrainingEnv(cfg)
    assert env.max_episode_length == 3
    seen, rewards = [], []
    original = env.core._control_step

    def counted(*args):
        seen.append(env.step_count)
        rewards.append(original(*args))
        return rewards[-1]

    env.core._control_step = counted
    action = torch.full((2, 12), 0.3)
    for steps, done in ((3, False), (6, False), (7, True)):
        first = len(rewards)
        _, reward, dones, _ = env.step(action)
        assert len(seen) == steps and bool(dones.all()) == done and np.allclose(env.core.actions.current, 0.0 if done else 0.3)
        np.testing.assert_allclose(reward.numpy(), sum(r for r, _, _ in rewards[first:]), rtol=1e-6)
        if not done:  # the next decision's a_{t-2} is this held action, not the one before it
            assert np.allclose(env.core.actions.previous, 0.3)
    assert seen == list(range(7)) and env.step_count == 0  # a new episode after the seventh step
    assert env.episode_length_buf.tolist() == [0, 0]
    with pytest.raises(ValueError, match="action_hold 0: expected at least 1"):
        TrainEnvConfig(num_envs=2, robot="go2", families=("flat",), action_hold=0)

    run = TrainingRun(tmp_path / "held", "ppo", TrainEnvConfig(num_envs=2, robot="go2", randomize=False,
                      families=("flat",), episode_steps=6, settle_steps=2, action_hold=3), total_steps=2 * 24 * 3,
                      checkpoint_every=1)
    assert run.steps_per_iteration == 2 * 24 * 3
    run.train(progress_bar=False)
    policy = load_policy(str(tmp_path / "held"))
    spec = get_robot("go2")
    policy.reset(spec, 2)
    asked = []
    decide = policy._decide
    policy._decide = lambda obs: asked.append(policy.calls) or decide(obs)
    obs = {"base_angvel": np.zeros((2, 3)), "projected_gravity": np.tile([0.0, 0.0, -1.0], (2, 1)),
           "joint_pos": np.tile(spec.default_pose, (2, 1)), "joint_vel": np.zeros((2, 12)),
           "previous_action": np.tile(spec.default_pose, (2, 1))}
    targets = []
    for k in range(7):
        obs["joint_vel"] = np.full((2, 12), 0.1 * k)  # a new observation every call
        targets.append(policy.act(obs))
    assert asked == [0, 3, 6]
    np.testing.assert_array_equal(targets[0], targets[2])
    assert not np.array_equal(targets[2], targets[3])


def test_train_refuses_to_overwrite_a_run(tmp_path):
    from frbench.training.run import TrainingRun

    (tmp_path / "config.json").write_text("{}")
    with pytest.raises(FrbenchError, match="a run is already there; use --resume"):
        TrainingRun(tmp_path, "frnet", TrainEnvConfig(num_envs=2), total_steps=10)


def test_a_humanoid_residual_policy_trains_and_adds_its_action_to_the_base_controller(tmp_path):
    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot
    from frbench.training.run import TrainingRun

    # no reward given: the library picks the humanoid table by the robot's kind
    cfg = TrainEnvConfig(num_envs=2, robot="g1", randomize=False, families=("flat",), episode_steps=4, settle_steps=2,
                         base_controller="zero", action_scale=0.25)
    run = TrainingRun(tmp_path / "g1", "ppo", cfg, total_steps=2 * 24, checkpoint_every=1)
    obs = run.env.get_observations()
    assert obs["policy"].shape == (2, 6 + 3 * 29) and obs["history"].shape == (2, 5 * (6 + 3 * 29))
    run.train(progress_bar=False)
    assert run.env_steps == 48
    logged = run.env.core.reward.config.weights
    assert {"head_height", "feet_on_ground", "upper_body_posture", "action_jerk"} <= set(logged)
    assert "feet_contact" not in logged
    assert 1.1 < run.env.robots.head.standing_height < 1.35  # the G1's head centre stands about 1.23 m high

    spec = get_robot("g1")
    policy = load_policy(str(tmp_path / "g1"))
    assert policy.supports(spec) and not policy.supports(get_robot("go2"))
    policy.reset(spec, 2)
    state = {"base_angvel": np.zeros((2, 3)), "projected_gravity": np.tile([0.0, 0.0, -1.0], (2, 1)),
             "joint_pos": np.tile(spec.default_pose, (2, 1)), "joint_vel": np.zeros((2, 29)),
             "previous_action": np.tile(spec.default_pose, (2, 1))}
    targets = policy.act(state)
    base = load_policy("zero")
    base.reset(spec, 2)
    # q* = base(o) + 0.25 · a
    np.testing.assert_allclose(targets, base.act(state) + 0.25 * policy.action, atol=1e-12)
    assert targets.shape == (2, 29) and np.abs(policy.action).max() > 0


def test_a_residual_policy_keeps_the_base_controller_parameters_it_was_trained_with(tmp_path):
    from frbench.policies.keyframe_humanoid import (
        PARAMETER_NAMES,
        KeyframeHumanoidPolicy,
        load_parameters,
    )
    from frbench.policies.registry import (
        base_controller_parameters,
        load_base_controller,
        load_policy,
    )
    from frbench.robots import get_robot
    from frbench.training.run import TrainingRun

    shipped = base_controller_parameters("keyframe-humanoid")
    assert list(shipped) == list(PARAMETER_NAMES) and np.allclose(list(shipped.values()), load_parameters())
    assert base_controller_parameters("zero") == {}
    trained_with = {**shipped, "stand.knee": 0.9}  # as if the shipped parameters were tuned after training
    cfg = TrainEnvConfig(num_envs=2, robot="g1", randomize=False, families=("flat",), episode_steps=3, settle_steps=2,
                         base_controller="keyframe-humanoid", base_controller_parameters=trained_with,
                         action_scale=0.1)
    run = TrainingRun(tmp_path / "g1", "ppo", cfg, total_steps=2 * 24, checkpoint_every=1)
    assert run.env.core.transform.controller.parameter_dict()["stand.knee"] == 0.9
    run.train(progress_bar=False)
    policy = load_policy(str(tmp_path / "g1"))
    assert isinstance(policy.base_controller, KeyframeHumanoidPolicy)
    assert policy.base_controller.parameter_dict() == trained_with
    from frbench.policies.export import export_onnx

    with pytest.raises(PolicyError, match="is a residual over 'keyframe-humanoid'"):
        export_onnx(str(tmp_path / "g1"), tmp_path / "g1.onnx")
    assert not (tmp_path / "g1.onnx").exists()
    with pytest.raises(PolicyError, match="base controller 'zero' takes no parameters"):
        load_base_controller("zero", {"stand.knee": 0.9})
    spec = get_robot("g1")
    policy.reset(spec, 1)
    assert policy.act({"base_angvel": np.zeros((1, 3)), "projected_gravity": np.array([[1.0, 0.0, 0.0]]),
                       "joint_pos": np.tile(spec.default_pose, (1, 1)), "joint_vel": np.zeros((1, 29)),
                       "previous_action": np.tile(spec.default_pose, (1, 1))}).shape == (1, 29)


def test_rma_phase_two_runs_on_the_recovery_env_and_deploys_without_extrinsics(tmp_path):
    from frbench.errors import FrbenchError
    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, robot="go2", families=("flat",), episode_steps=5, settle_steps=2)
    phase1 = TrainingRun(tmp_path / "rma", "rma", cfg, total_steps=4 * 24, checkpoint_every=1)
    phase1.train(progress_bar=False)
    with pytest.raises(FrbenchError, match="expected a training run folder"):
        TrainingRun(tmp_path / "x", "rma-adaptation", total_steps=96, teacher=tmp_path / "nothing")
    phase2 = TrainingRun(tmp_path / "adapt", "rma-adaptation", total_steps=4 * 24 * 2, checkpoint_every=1,
                         teacher=tmp_path / "rma")
    assert phase2.env.cfg_obj.long_history == 50
    assert phase2.env.get_observations()["long_history"].shape == (4, 50 * 42)
    frozen = {k: v.clone() for k, v in phase2.runner.alg.actor.state_dict().items() if k.startswith("mlp.")}
    phase2.train(progress_bar=False)
    after = phase2.runner.alg.actor.state_dict()
    assert all(torch.equal(v, after[k]) for k, v in frozen.items())  # π frozen, only φ learns
    resumed = TrainingRun(tmp_path / "adapt", total_steps=4 * 24 * 3, resume=True, checkpoint_every=1)
    assert resumed.env_steps == 192 and resumed.runner.alg.actor.use_adaptation
    # the deployed policy reads o_t and its 50-frame history only (zeros stand in for the extrinsics)
    policy = load_policy(str(tmp_path / "adapt"))
    spec = get_robot("go2")
    policy.reset(spec, 2)
    obs = {"base_angvel": np.zeros((2, 3)), "projected_gravity": np.tile([0.0, 0.0, 1.0], (2, 1)),
           "joint_pos": np.tile(spec.default_pose, (2, 1)), "joint_vel": np.zeros((2, 12)),
           "previous_action": np.tile(spec.default_pose, (2, 1))}
    targets = [policy.act(obs) for _ in range(3)]
    assert policy.long_history.shape == (2, 50, 42) and np.isfinite(targets).all()
    with pytest.raises(Exception, match="extrinsics"):
        load_policy(str(tmp_path / "rma"))  # phase 1 needs privileged extrinsics: refused


def test_learned_policy_names_keep_a_stem_that_starts_with_the_method():
    from pathlib import Path

    from frbench.policies.learned import policy_name

    assert policy_name("frnet", Path("frbench/policies/checkpoints/frnet.pt")) == "frnet"
    assert policy_name("ppo", Path("checkpoints/ppo-3m.pt")) == "ppo-3m"
    assert policy_name("frnet", Path("runs/my run/policy.pt")) == "frnet-my-run"
    assert policy_name("rma", Path("runs/rma-adaptation/policy.pt")) == "rma-adaptation"


def test_a_resumed_run_can_widen_a_morphology_range_and_redraws_its_robots(tmp_path):
    from frbench.commands.train import morphology_range_changes
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    first = TrainingRun(tmp_path / "run", "ppo", cfg, total_steps=4 * 24, checkpoint_every=1)
    first.train(progress_bar=False)
    assert all(0.013 <= m.calf_height <= 0.019 for m in first.env.robots.morphologies)
    ranges = morphology_range_changes(["calf_height=0.040,0.045", "calf_width=0.030,0.040"])
    assert ranges == {"calf_height": (0.040, 0.045), "calf_width": (0.030, 0.040)}
    staged = TrainingRun(tmp_path / "run", total_steps=4 * 24 * 2, resume=True, checkpoint_every=1,
                         command="frbench train --resume run --morphology-range ...", morphology_stage=ranges)
    assert [0.040 <= m.calf_height <= 0.045 and 0.030 <= m.calf_width <= 0.040 for m in staged.env.robots.morphologies] \
        == [True, True]
    assert staged.env_steps == 96
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["stages"][-1]["morphology_ranges"] == {"calf_height": [0.040, 0.045], "calf_width": [0.030, 0.040]}
    assert config["env"]["morphology_ranges"]["calf_height"] == [0.040, 0.045]
    again = TrainingRun(tmp_path / "run", resume=True)  # a plain resume keeps the widened table
    assert all(0.040 <= m.calf_height <= 0.045 for m in again.env.robots.morphologies)
    with pytest.raises(FrbenchError, match="'calf_girth': not a randomised field"):
        morphology_range_changes(["calf_girth=0.01,0.02"])
    with pytest.raises(FrbenchError, match="expected FIELD=LOW,HIGH"):
        morphology_range_changes(["calf_width=0.02"])
    with pytest.raises(FrbenchError, match=r"calf_width=\(0.05, 0.02\): expected finite 0 < low <= high"):
        morphology_range_changes(["calf_width=0.05,0.02"])


def test_the_assist_force_lifts_with_a_fraction_of_the_weight_and_fades_out():
    cfg = TrainEnvConfig(num_envs=2, episode_steps=3, settle_steps=2, num_morphologies=2, families=("flat",),
                         assist_force=0.8, assist_until=12)
    env = RecoveryTrainingEnv(cfg)
    weight = env.env_masses.sum(axis=1) * 9.81
    np.testing.assert_allclose(env.backend._base_force[:, 2], 0.8 * weight)
    np.testing.assert_allclose(env.backend._base_force[:, :2], 0.0)
    for _ in range(3):  # one episode: 6 env steps of 12, the next episode gets 0.8 · (1 - 6/12)
        env.step(torch.zeros(2, env.num_actions))
    assert env.last_episode_stats["assist_fraction"] == pytest.approx(0.8)  # the episode that just ended
    np.testing.assert_allclose(env.backend._base_force[:, 2], 0.4 * weight)
    for _ in range(3):
        env.step(torch.zeros(2, env.num_actions))
    np.testing.assert_allclose(env.backend._base_force, 0.0)
    assert env.core.assist.fraction == 0.0


@pytest.mark.parametrize("backend", ["mujoco", "pybullet"])
def test_a_base_force_of_one_and_a_half_weights_lifts_the_robot_at_half_g(backend):
    from frbench.backends import make_backend
    from frbench.backends.base import RobotState
    from frbench.robots import get_robot

    spec = get_robot("go2")
    sim = make_backend(backend, spec, 2)
    try:
        mass = sim.mass_properties()[0] if backend == "mujoco" else np.full(2, 16.085)
        force = np.zeros((2, 3))
        force[0, 2] = 1.5 * mass[0] * 9.81
        sim.set_base_force(force)
        start = RobotState.standing(spec, 2, clearance=0.2)  # in the air: no contact forces
        sim.reset(np.arange(2), start)
        for _ in range(5):  # 0.1 s
            sim.step(np.tile(spec.default_pose, (2, 1)))
        vz = sim.state().base_linvel[:, 2]
        assert vz[0] == pytest.approx(0.5 * 9.81 * 0.1, rel=0.03)   # + half g
        assert vz[1] == pytest.approx(-9.81 * 0.1, rel=0.03)        # free fall
        # the force is no contact (MuJoCo's cfrc_ext holds xfrc_applied; the backend takes it out)
        contacts = sim.contacts()
        assert not contacts.group_contact.any() and float(contacts.norm.max()) < 1e-6
        with pytest.raises(ValueError, match=r"expected a finite \(2, 3\) array"):
            sim.set_base_force(np.zeros(3))
    finally:
        sim.close()


def test_a_named_robot_keeps_its_per_joint_gains_scaled_by_one_factor_per_episode():
    from frbench.backends.base import PhysicsParams
    from frbench.robots import get_robot
    from frbench.training.population import NAMED_ROBOT_GAIN_FACTORS

    cfg = TrainEnvConfig(num_envs=4, episode_steps=3, settle_steps=2, robot="g1", families=("flat",))
    env = RecoveryTrainingEnv(cfg)
    nominal = PhysicsParams.nominal(get_robot("g1"), 4)
    assert np.ptp(nominal.kp) > 100.0  # the G1's gains differ by joint (N·m/rad)
    for ours, theirs in ((env.params.kp, nominal.kp), (env.params.kd, nominal.kd)):
        factor = ours / theirs
        np.testing.assert_allclose(factor, factor[:, :1].repeat(factor.shape[1], axis=1), rtol=1e-12)
        assert (factor >= NAMED_ROBOT_GAIN_FACTORS[0]).all() and (factor <= NAMED_ROBOT_GAIN_FACTORS[1]).all()


def test_train_command_records_the_settle_and_the_base_controller_parameters(tmp_path):
    from frbench.cli import main
    from frbench.policies.registry import base_controller_parameters

    out = tmp_path / "g1"
    assert main(["train", "--method", "ppo", "--preset", "g1-residual", "--envs", "2", "--steps", "48",
                 "--set", "episode_steps=3", "--set", "settle_steps=4", "--set", "action_hold=1",
                 "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    env = config["env"]
    assert config["train_cfg"]["actor"]["distribution_cfg"]["init_std"] == 0.25  # the preset's
    policy = torch.load(out / "policy.pt", weights_only=True)
    assert json.loads(policy["config_json"])["train_cfg"]["actor"]["distribution_cfg"]["init_std"] == 0.25
    assert env["settle_steps"] == 4 and env["episode_steps"] == 3 and env["action_hold"] == 1
    assert env["robot"] == "g1" and env["residual_gate"] and env["action_scale"] == 0.1 and not env["randomize"]
    assert env["base_controller_parameters"] == base_controller_parameters("keyframe-humanoid")
    assert env["reward"]["weights"]["velocity_limit"] == -0.01 and "head_height" in env["reward"]["weights"]
    assert env["reward"]["weights"]["joint_velocity"] == pytest.approx(0.01 * PAPER_WEIGHTS["joint_velocity"])
    bad = ["--out", str(tmp_path / "bad")]
    assert main(["train", "--robots", "g1", "--set", "settle_steps=-1", *bad]) == 2
    assert main(["train", "--robots", "g1", "--set", "base_controller=keyframe-humanoid",
                 "--set", "rise_start_fraction=0.5", *bad]) == 2  # rise starts need the gate
    assert main(["train", "--robots", "g1", "--set", "base_controller=keyframe-humanoid",
                 "--set", "gate_phases=rise", *bad]) == 2  # gate phases need the gate
    assert main(["train", "--preset", "g1-residual", "--set", "gate_phases=rise,stand", *bad]) == 2  # no 'stand'
    assert main(["train", "--preset", "g2-residual", *bad]) == 2
    assert main(["train", "--set", "action_hold=ten", *bad]) == 2
    assert main(["train", "--set", "no_such_field=1", *bad]) == 2
    assert not (tmp_path / "bad").exists()


def test_a_gated_residual_acts_only_in_the_base_controllers_rise(tmp_path):
    from frbench.policies.keyframe_humanoid import KeyframeHumanoidPolicy
    from frbench.policies.learned import residual_targets
    from frbench.policies.registry import load_policy
    from frbench.policies.scripted_humanoid import (
        CROUCH,
        HOLD,
        LIE,
        PROP,
        RISE,
        ROLL,
        TUCK,
    )
    from frbench.robots import get_robot
    from frbench.training.run import TrainingRun

    spec = get_robot("g1")
    controller = KeyframeHumanoidPolicy()
    controller.reset(spec, 5)
    controller.phase[:] = [LIE, ROLL, CROUCH, RISE, HOLD]
    assert controller.residual_gate().tolist() == [0.0, 0.0, 1.0, 1.0, 1.0]

    cfg = TrainEnvConfig(num_envs=2, robot="g1", randomize=False, families=("flat",), episode_steps=3, settle_steps=2,
                         base_controller="keyframe-humanoid", residual_gate=True, action_scale=0.1,
                         gate_phases=("tuck", "crouch", "rise", "hold"))
    run = TrainingRun(tmp_path / "g1", "ppo", cfg, total_steps=2 * 24, checkpoint_every=1)
    with torch.inference_mode():  # a new residual starts as its base controller: mean action 0 everywhere
        mean = run.runner.alg.actor(run.env.get_observations())
    assert mean.shape == (2, 29) and float(mean.abs().max()) == 0.0
    run.train(progress_bar=False)
    policy = load_policy(str(tmp_path / "g1"))
    assert policy.residual_gate and list(policy.gate_phases) == ["tuck", "crouch", "rise", "hold"]
    controller.phase[:] = [TUCK, PROP, CROUCH, LIE, HOLD]  # the run's gate adds the sit-up's first phase
    residual = residual_targets(np.zeros((5, 29)), np.ones((5, 29)), 0.1, controller, True, policy.gate_phases)
    assert residual[:, 0].tolist() == pytest.approx([0.1, 0.0, 0.1, 0.0, 0.1])
    assert residual_targets(np.zeros((5, 29)), np.ones((5, 29)), 0.1, controller, True)[:, 0].tolist() == \
        pytest.approx([0.0, 0.0, 0.1, 0.0, 0.1])  # runs from before gate_phases: the rise alone
    policy.reset(spec, 2)
    reference = KeyframeHumanoidPolicy()
    reference.reset(spec, 2)
    obs = {"base_angvel": np.zeros((2, 3)), "projected_gravity": np.tile([1.0, 0.0, 0.0], (2, 1)),
           "joint_pos": np.tile(spec.default_pose, (2, 1)), "joint_vel": np.zeros((2, 29)),
           "previous_action": np.tile(spec.default_pose, (2, 1))}
    targets = policy.act(obs)  # both lie face down: the gate is closed, the key frames act alone
    assert np.abs(policy.action).max() > 0
    np.testing.assert_array_equal(targets, reference.act(obs))
    for c in (policy.base_controller, reference):
        c.phase[:] = [HOLD, LIE]  # the first one stands (and stays in HOLD while upright): its residual passes
    obs["projected_gravity"] = np.tile([0.0, 0.0, -1.0], (2, 1))
    targets = policy.act(obs)
    assert policy.base_controller.phase.tolist() == [HOLD, LIE]
    base = reference.act(obs)
    np.testing.assert_allclose(targets[0], base[0] + 0.1 * policy.action[0], atol=1e-12)
    np.testing.assert_array_equal(targets[1], base[1])
    with pytest.raises(ValueError, match="base controller 'zero' has no residual_gate"):
        TrainingRun(tmp_path / "zero", "ppo", TrainEnvConfig(num_envs=2, robot="g1", randomize=False,
                    families=("flat",), base_controller="zero", residual_gate=True), total_steps=48)


def test_rise_starts_begin_where_the_gate_opened_with_the_controller_in_its_rise(tmp_path, monkeypatch):
    from frbench.policies.scripted_humanoid import CROUCH, HumanoidScriptedPolicy
    from frbench.training.env import RecoveryTrainingEnv

    # a gate that opens at the first step, so that a 3-step recording fills the bank with every environment
    monkeypatch.setattr(HumanoidScriptedPolicy, "residual_gate", lambda self, phases=None: np.ones(self.num_envs))
    cfg = TrainEnvConfig(num_envs=3, robot="g1", randomize=False, families=("flat",), episode_steps=3, settle_steps=2,
                         base_controller="keyframe-humanoid", residual_gate=True, rise_start_fraction=1.0,
                         action_scale=0.1)
    env = RecoveryTrainingEnv(cfg)
    assert len(env.starts.rise.bank) == 3  # each environment once, at the step its gate first opened
    assert env.starts.from_demo.all() and (env.core.transform.controller.phase == CROUCH).all()
    recorded_q = np.concatenate([row[0].q for row in env.starts.rise.bank])
    assert {tuple(np.round(q, 9)) for q in env.core.state.q} <= {tuple(np.round(q, 9)) for q in recorded_q}
    starts = {tuple(np.round(env.core.transform.controller._clip(row[2]), 9)) for row in env.starts.rise.bank}
    assert {tuple(np.round(s, 9)) for s in env.core.transform.controller.start} <= starts  # the ramp starts at recorded targets
    for _ in range(3):
        env.step(torch.zeros(3, 29))
    assert env.last_episode_stats["demo_start_share"] == 1.0 and "success_demo_starts" in env.last_episode_stats
    with pytest.raises(ValueError, match="rise_start_fraction 0.5: expected residual_gate"):
        TrainEnvConfig(num_envs=2, robot="g1", randomize=False, families=("flat",),
                       base_controller="keyframe-humanoid", rise_start_fraction=0.5)


def test_a_run_kept_without_its_optimisers_resumes_at_its_learning_rate(tmp_path):
    import subprocess
    import sys

    from frbench.training.run import OPTIMISER_KEYS, TrainingRun

    cfg = TrainEnvConfig(num_envs=8, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    run = TrainingRun(tmp_path / "run", "frnet", cfg, total_steps=8 * 24 * 2, checkpoint_every=1)
    run.train(progress_bar=False)
    rate = run.runner.alg.learning_rate
    subprocess.run([sys.executable, "tools/keep_run.py", str(tmp_path / "run"), str(tmp_path / "kept")], check=True,
                   capture_output=True)
    full, kept = (torch.load(tmp_path / f / "runner.pt", weights_only=False) for f in ("run", "kept"))
    assert not set(OPTIMISER_KEYS) & set(kept) and set(OPTIMISER_KEYS) <= set(full)
    assert kept["learning_rate"] == pytest.approx(rate)
    assert (tmp_path / "kept" / "runner.pt").stat().st_size < 0.5 * (tmp_path / "run" / "runner.pt").stat().st_size
    resumed = TrainingRun(tmp_path / "kept", total_steps=8 * 24 * 3, resume=True, checkpoint_every=1)
    assert resumed.env_steps == 384 and resumed.runner.alg.learning_rate == pytest.approx(rate)
    assert all(group["lr"] == pytest.approx(rate) for group in resumed.runner.alg.optimizer.param_groups)
    for name, weights in kept["actor_state_dict"].items():
        assert torch.equal(resumed.runner.alg.get_policy().state_dict()[name], weights)
    resumed.train(progress_bar=False)
    assert resumed.env_steps == 576
