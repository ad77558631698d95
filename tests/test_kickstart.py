"""DAgger from ``scripted`` inside the training env, and kickstarting PPO (frbench.training.dagger, teacher,
imitation; the ``kickstart-scripted`` preset)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from frbench.policies.scripted import ScriptedPolicy
from frbench.robots.joint_frame import JointFrame
from frbench.training.config import TrainEnvConfig
from frbench.training.dagger import ImitationSchedule, teacher_acts, teacher_label
from frbench.training.imitation import ImitationLoss, imitation_loss
from frbench.training.presets import KICKSTART_SCRIPTED, PRESETS


def test_the_presets_schedule_numbers():
    cfg = TrainEnvConfig(**KICKSTART_SCRIPTED)
    s = cfg.imitation_schedule()
    assert [s.round_at(x) for x in (0, 1.999e6, 2e6, 20e6)] == [0, 0, None, None]
    assert [s.imitation_weight(x) for x in (0, 1.9e6, 2e6, 7e6, 10e6, 12e6, 30e6)] == pytest.approx(
        [1.0, 1.0, 1.0, 0.5, 0.2, 0.0, 0.0])
    assert [s.rl_weight(x) for x in (0, 1.999e6, 2e6, 12e6)] == [0.0, 0.0, 1.0, 1.0]
    assert cfg.dagger_noise == 0.2  # DART: the teacher acts with 0.2 rad of noise
    assert s.acts(0, 5, 64).all()  # behaviour cloning
    decay = np.mean([s.acts(5e6, e, 256).mean() for e in range(40)])
    assert decay == pytest.approx(0.25, abs=0.02)  # the teacher goes on acting in a quarter of the episodes
    assert not s.acts(12e6, 50, 64).any()
    acting = s.acts(5e6, 3, 64)
    imitation, rl = s.row_weights(5e6, acting)  # weight 0.7 at 5 M, on the teacher's rows only
    assert np.array_equal(imitation, np.where(acting, 0.7, 0.0)) and np.array_equal(rl, np.where(acting, 0.0, 1.0))
    every_row = TrainEnvConfig(**{**KICKSTART_SCRIPTED, "imitate_rows": "all"}).imitation_schedule()
    assert np.allclose(every_row.row_weights(5e6, acting)[0], 0.7)
    assert PRESETS["kickstart-scripted"].train_overrides()["algorithm"]["class_name"].endswith(":KickstartPPO")


def test_an_imitation_floor_keeps_the_term_and_the_teachers_quarter_on_after_the_decay():
    cfg = TrainEnvConfig(**{**KICKSTART_SCRIPTED, "imitation_floor": 0.1})
    s = cfg.imitation_schedule()
    assert [s.imitation_weight(x) for x in (0, 2e6, 7e6, 11e6, 12e6, 30e6)] == pytest.approx(
        [1.0, 1.0, 0.5, 0.1, 0.1, 0.1])  # the decay of the preset, stopped at 0.1 (reached at 11 M)
    after = np.mean([s.acts(20e6, e, 256).mean() for e in range(40)])
    assert after == pytest.approx(0.25, abs=0.02)  # the teacher's quarter goes on past imitation_until
    acting = s.acts(20e6, 3, 64)
    imitation, rl = s.row_weights(20e6, acting)
    assert np.array_equal(imitation, np.where(acting, 0.1, 0.0)) and np.array_equal(rl, np.where(acting, 0.0, 1.0))
    unchanged = TrainEnvConfig(**KICKSTART_SCRIPTED).imitation_schedule()
    assert unchanged.floor == 0.0 and not unchanged.acts(20e6, 3, 64).any()
    with pytest.raises(ValueError, match="imitation_floor"):
        TrainEnvConfig(**{**KICKSTART_SCRIPTED, "imitation_floor": 1.5})
    from frbench.training.config import STAGE_FIELDS

    assert "imitation_floor" in STAGE_FIELDS  # frbench train --resume RUN --set imitation_floor=W: a new stage


def test_the_dagger_draw_is_distills_rule_and_bad_values_name_their_field():
    for r, b in ((1, 0), (2, 7)):  # the draw frbench distill made before the rule moved to dagger.py
        expected = np.random.default_rng([3, r, b]).random(50) < 0.3
        assert np.array_equal(teacher_acts(3, r, b, 50, 0.3), expected)
    assert teacher_acts(3, 0, 1, 5, 0.0).all()
    with pytest.raises(ValueError, match="dagger_beta"):
        ImitationSchedule(dagger_steps=1, beta=1.5)
    with pytest.raises(ValueError, match="dagger_rounds"):
        TrainEnvConfig(teacher="scripted", dagger_steps=1e6, dagger_rounds=0)
    with pytest.raises(ValueError, match="action_hold"):
        TrainEnvConfig(teacher="scripted", action_hold=2)
    with pytest.raises(ValueError, match="teacher"):
        TrainEnvConfig(teacher="mpc")
    with pytest.raises(ValueError, match="imitate_rows"):
        TrainEnvConfig(teacher="scripted", imitate_rows="learner")
    with pytest.raises(ValueError, match="kickstart_beta"):
        TrainEnvConfig(teacher="scripted", kickstart_beta=2.0)


def test_a_label_is_the_teachers_target_in_the_canonical_frame():
    rng = np.random.default_rng(0)
    sign = tuple(float(s) for s in rng.choice([-1.0, 1.0], 12))
    offset = tuple(float(o) for o in rng.uniform(-1, 1, 12))
    frame = JointFrame("x", sign, offset, ("forward",) * 4, turned=True)
    targets, pose = rng.normal(size=(5, 12)), rng.normal(size=12)
    label = teacher_label(targets, pose, frame, scale=0.5)
    assert np.allclose(frame.to_joints(0.5 * label + pose), targets)  # the action asks for the teacher's targets
    assert np.allclose(label, (frame.to_canonical(targets) - pose) / 0.5)


def test_env_labels_are_scripteds_actions_on_the_visited_observations_and_dagger_executes_them():
    from frbench.training.env import RecoveryTrainingEnv

    cfg = TrainEnvConfig(num_envs=6, num_morphologies=2, families=("flat",), episode_steps=20, settle_steps=5,
                         teacher="scripted", dagger_steps=120, dagger_rounds=1, imitation_until=240, seed=1)
    env = RecoveryTrainingEnv(cfg)
    try:
        replica = [ScriptedPolicy() for _ in env.specs]
        groups = [np.flatnonzero(env.assignment == k) for k in range(len(env.specs))]
        rng = np.random.default_rng(2)
        obs = env.get_observations()
        for step in range(45):  # three episodes: two of DAgger (teacher acts), one after
            proprio = env.core.observation()
            if env.step_count == 0:
                for policy, spec, ids in zip(replica, env.specs, groups):
                    policy.reset(spec, len(ids))
            expected = np.zeros((6, 12))
            for policy, ids in zip(replica, groups):
                expected[ids] = policy.act({k: proprio[k][ids] for k in ("projected_gravity", "joint_pos")})
            expected = expected - env.default_pose  # the morphologies' frame is the identity, scale 1
            teacher = obs["teacher"].numpy()
            assert np.allclose(teacher[:, :12], expected, atol=1e-5), step
            dagger = env.env_steps < 120
            assert teacher[0, 12:].tolist() == pytest.approx([1.0 if dagger else max(0.0, 1.0 - (env.env_steps - 120) / 120),
                                                0.0 if dagger else 1.0, 1.0 if dagger else 0.0], abs=1e-6)
            action = rng.normal(size=(6, 12))
            obs, *_ = env.step(torch.as_tensor(action, dtype=torch.float32))
            if env.step_count:  # (a new episode begins its actions at zero)
                executed = env.core.actions.current
                assert np.allclose(executed, teacher[:, :12] if dagger else action.astype(np.float32), atol=1e-6)
    finally:
        env.close()


def _executed_and_label(noise: float, steps: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """What the training env executed and the teacher's labels, each (steps - 1, 6, 12), the learner asking for
    zeros (the first step of the second episode left out: a new episode begins its actions at zero)."""
    from frbench.training.env import RecoveryTrainingEnv

    cfg = TrainEnvConfig(num_envs=6, num_morphologies=2, families=("flat",), episode_steps=20, settle_steps=5,
                         teacher="scripted", dagger_steps=20, dagger_rounds=1, imitation_until=40, seed=3,
                         dagger_noise=noise)
    env = RecoveryTrainingEnv(cfg)
    try:
        obs, executed, labels = env.get_observations(), [], []
        for _ in range(steps):
            label = obs["teacher"].numpy()[:, :12].copy()
            obs, *_ = env.step(torch.zeros(6, 12))
            if env.step_count:
                executed.append(np.asarray(env.core.actions.current, dtype=np.float64))
                labels.append(label)
        return np.array(executed), np.array(labels)
    finally:
        env.close()


def test_dart_noise_perturbs_what_the_teacher_executes_not_its_label_and_ends_with_dagger():
    executed, labels = _executed_and_label(0.1)
    gaps = executed[:19] - labels[:19]  # the DAgger episode (the teacher acts); then the learner's zeros
    assert np.std(gaps) == pytest.approx(0.1, rel=0.1) and abs(np.mean(gaps)) < 0.01
    assert np.allclose(executed[19:], 0.0) and np.abs(labels[19:]).max() > 0.1
    assert np.allclose(_executed_and_label(0.1)[0], executed)  # seeded by (seed, episode): the same noise again
    clean, clean_labels = _executed_and_label(0.0)
    assert np.allclose(clean[:19], clean_labels[:19], atol=1e-6)  # no noise: the label itself
    with pytest.raises(ValueError, match="dagger_noise"):
        TrainEnvConfig(teacher="scripted", dagger_steps=1e6, dagger_noise=-0.1)


def test_the_imitation_term_pulls_the_mean_action_toward_the_label_with_its_weight():
    mean = torch.tensor([[0.5, -1.0], [2.0, 0.0]], requires_grad=True)
    teacher = torch.tensor([[0.0, 0.0, 2.0, 0.0, 1.0], [2.0, 1.0, 0.5, 1.0, 0.0]])
    loss = imitation_loss(mean, teacher)
    assert float(loss.detach()) == pytest.approx((2.0 * 1.25 + 0.5 * 1.0) / 2)
    loss.backward()
    # d/dμ of w·|μ − a*|² averaged over 2 rows: w·(μ − a*): a gradient step moves μ toward a*
    assert torch.allclose(mean.grad, torch.tensor([[1.0, -2.0], [0.0, -0.5]]))
    zero = torch.tensor([[0.3, 0.3]], requires_grad=True)
    imitation_loss(zero, torch.tensor([[1.0, 1.0, 0.0, 1.0, 0.0]])).backward()
    assert torch.equal(zero.grad, torch.zeros(1, 2))  # weight 0: no pull


def test_imitation_loss_reads_the_actors_forward_pass():
    from tensordict import TensorDict
    from rsl_rl.models import MLPModel

    torch.manual_seed(0)
    obs = TensorDict({"policy": torch.randn(32, 4), "teacher": torch.cat(
        [torch.ones(32, 2), torch.ones(32, 1), torch.zeros(32, 2)], dim=1)}, batch_size=[32])
    actor = MLPModel(obs, {"actor": ["policy"]}, "actor", 2, hidden_dims=[8],
                     distribution_cfg={"class_name": "GaussianDistribution", "init_std": 0.5})
    optimizer = torch.optim.SGD(actor.parameters(), lr=0.05)
    batch = type("Batch", (), {"observations": obs})()
    losses = []
    for _ in range(20):
        actor(obs, stochastic_output=True)
        loss = ImitationLoss().compute_loss(actor, batch, 32)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.5 * losses[0]


def test_a_tiny_kickstart_run_trains_logs_its_weights_and_writes_a_policy_evaluate_loads(tmp_path):
    run = tmp_path / "run"
    command = [sys.executable, "-m", "frbench", "train", "--method", "frnet", "--preset", "kickstart-scripted",
               "--envs", "8", "--steps", "960", "--terrains", "flat", "--checkpoint-every", "1", "--out", str(run),
               "--set", "num_morphologies=2", "--set", "episode_steps=24", "--set", "settle_steps=5",
               "--set", "dagger_steps=384", "--set", "imitation_until=768"]
    subprocess.run(command, check=True, capture_output=True)
    progress = json.loads((run / "progress.json").read_text())
    assert [r["env_steps"] for r in progress] == [192, 384, 576, 768, 960]
    schedule = TrainEnvConfig(**{**KICKSTART_SCRIPTED, "dagger_steps": 384, "imitation_until": 768}).imitation_schedule()
    share = [schedule.acts(steps, steps // 192, 8).mean() for steps in (384, 576)]  # one episode per iteration
    assert 0 < share[0] + share[1] < 2  # the teacher acts in some episodes of the decay, not all
    assert [r["loss_imitation_weight"] for r in progress] == pytest.approx(  # on the teacher's rows only
        [1.0, 1.0, share[0] * np.mean([1 - (s - 384) / 384 for s in range(384, 576, 8)]),
         share[1] * np.mean([1 - (s - 384) / 384 for s in range(576, 768, 8)]), 0.0], rel=1e-5)
    assert progress[0]["loss_surrogate"] == 0.0 and progress[-1]["loss_surrogate"] != 0.0
    assert progress[0]["loss_imitation"] > 0 and progress[-1]["loss_imitation"] == 0.0
    out = tmp_path / "eval.json"
    subprocess.run([sys.executable, "-m", "frbench", "evaluate", "--policy", str(run), "--robots", "go2",
                    "--terrains", "flat", "--levels", "1", "--seeds", "0", "--episodes", "1", "--backends", "mujoco",
                    "--jobs", "1", "--out", str(out)], check=True, capture_output=True)
    result = json.loads(out.read_text())
    assert len(result["episodes"]) == 1 and result["policy"]["joint_frame"] == "canonical"
