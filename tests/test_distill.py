"""`frbench distill` (DAgger of mpc into a proprioceptive MLP) on a tiny budget, and the shipped distilled policy."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from frbench.cli import main
from frbench.errors import FrbenchError
from frbench.evaluation.episodes import run_episodes
from frbench.policies.checkpoint import read_checkpoint
from frbench.policies.registry import (checkpoint_metadata, describe_checkpoint, load_policy, policy_names,
                                      shipped_checkpoint)
from frbench.robots import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain
from frbench.training import distill
from frbench.training.distill import DistillConfig, run_distillation
from frbench.training.distill_data import load_rounds, read_meta, shard_path
from frbench.training.distill_student import build_actor, student_actions

#: One 6-step MuJoCo episode per round, a 4-sample planner, 2 training epochs: about a second per round.
TINY = DistillConfig(teacher_settings="samples=4,horizon=0.1,knots=2", simulators=("mujoco",), rounds=2,
                     episodes_per_round=1, batch=1, steps=6, frames=2, hidden=(16, 16), epochs=2)


def _weights(path):
    return read_checkpoint(path)["actor_state_dict"]


def test_dagger_is_deterministic_and_resumes(tmp_path, monkeypatch):
    whole = run_distillation(tmp_path / "a", TINY, log=lambda line: None)
    assert [r["episodes"] for r in whole["rounds"]] == [1, 1]
    assert whole["dataset"]["samples"] == 12 and whole["dataset"]["episodes"] == 2
    assert whole["rounds"][0]["teacher"]["episodes"] == 1 and whole["rounds"][1]["student"]["episodes"] == 1
    assert whole["rounds"][1]["training"]["samples"] == 12
    obs, history, actions, metas = load_rounds(tmp_path / "a", 1)
    assert obs.shape == (12, 6 + 3 * 29) and history.shape == (12, 2 * obs.shape[1]) and actions.shape == (12, 29)
    assert np.isfinite(actions).all() and np.abs(actions).max() > 0.0
    assert [m["acted_by"] for m in metas] == ["teacher", "student"]

    # the same run in two goes: round 0, then round 1 resumed without redoing round 0's batch
    run_distillation(tmp_path / "b", DistillConfig(**{**TINY.__dict__, "rounds": 1}), log=lambda line: None)
    first = shard_path(tmp_path / "b", 0, 0, 0).stat().st_mtime_ns
    calls = []
    real = distill.collect_batch
    monkeypatch.setattr(distill, "collect_batch", lambda *a: calls.append(a[2:]) or real(*a))
    run_distillation(tmp_path / "b", TINY, log=lambda line: None)
    assert calls == [(1, 0)] and shard_path(tmp_path / "b", 0, 0, 0).stat().st_mtime_ns == first
    for r in (0, 1):
        a, b = _weights(tmp_path / "a" / "checkpoints" / f"round{r}.pt"), _weights(tmp_path / "b" / "checkpoints" / f"round{r}.pt")
        assert all(torch.equal(a[k], b[k]) for k in a)
    with np.load(shard_path(tmp_path / "a", 1, 0, 0)) as x, np.load(shard_path(tmp_path / "b", 1, 0, 0)) as y:
        assert np.array_equal(x["actions"], y["actions"]) and np.array_equal(x["obs"], y["obs"])
    assert read_meta(shard_path(tmp_path / "a", 1, 0, 0))["start_seed"] == 2000


def test_resume_with_other_settings_is_refused(tmp_path):
    run_distillation(tmp_path, DistillConfig(**{**TINY.__dict__, "rounds": 1}), log=lambda line: None)
    status = main(["distill", "--out", str(tmp_path), "--rounds", "1", "--episodes-per-round", "1", "--steps", "6",
                   "--simulators", "mujoco", "--teacher-settings", "samples=4,horizon=0.1,knots=2", "--batch", "1"])
    assert status == 2
    assert main(["distill", "--out", str(tmp_path / "x"), "--teacher", "keyframe"]) == 2
    assert main(["distill", "--out", str(tmp_path / "x"), "--teacher-settings", "samples"]) == 2
    assert not (tmp_path / "x").exists()



def test_extra_data_joins_the_training_set(tmp_path):
    """``extra_data``: another run's shards join each student's training set; a run of other frames is refused."""
    one = DistillConfig(**{**TINY.__dict__, "rounds": 1})
    run_distillation(tmp_path / "a", one, log=lambda line: None)
    joined = run_distillation(tmp_path / "b", DistillConfig(**{**one.__dict__, "extra_data": (str(tmp_path / "a"),)}),
                              log=lambda line: None)
    assert joined["dataset"]["samples"] == 6 and joined["rounds"][0]["training"]["samples"] == 12
    record = json.loads((tmp_path / "b" / "checkpoints" / "round0.config.json").read_text())
    assert record["distill"]["dataset"]["episodes"] == 2 and record["distill"]["extra_data"] == [str(tmp_path / "a")]
    args = ["distill", "--out", str(tmp_path / "c"), "--rounds", "1", "--episodes-per-round", "1", "--steps", "6",
            "--simulators", "mujoco", "--teacher-settings", "samples=4,horizon=0.1,knots=2", "--batch", "1"]
    assert main([*args, "--frames", "3", "--extra-data", str(tmp_path / "a")]) == 2  # a has 2 frames
    assert main([*args, "--frames", "2", "--extra-data", str(tmp_path / "missing")]) == 2
    assert not (tmp_path / "c" / "data").exists()
    assert main([*args, "--frames", "2", "--hidden", "16,16", "--epochs", "2", "--start-seed", "5000",
                 "--extra-data", str(tmp_path / "a")]) == 0
    assert read_meta(shard_path(tmp_path / "c", 0, 0, 0))["start_seed"] == 5000
    assert json.loads((tmp_path / "c" / "training.json").read_text())["0"]["samples"] == 12
    # settings stored before extra_data existed lack it: they count as its default, not as stale
    older = {k: v for k, v in distill._training_settings(one).items() if k != "extra_data"}
    assert not distill._stale(older, one) and distill._stale({**older, "epochs": 3}, one)
    assert distill._stale(older, DistillConfig(**{**one.__dict__, "extra_data": ("x",)}))

def test_checkpoint_loads_as_learned_policy_with_the_students_inputs(tmp_path):
    """The saved student acts through `LearnedPolicy` exactly as it acted during DAgger."""
    run_distillation(tmp_path, DistillConfig(**{**TINY.__dict__, "rounds": 1}), log=lambda line: None)
    path = tmp_path / "checkpoints" / "round0.pt"
    policy, actor = load_policy(str(path)), build_actor(read_checkpoint(path))
    assert policy.name == "mpc-distill-round0" and json.loads((tmp_path / "checkpoints" / "round0.config.json")
                                                               .read_text())["method"] == "mpc-distill"
    spec = get_robot("g1")
    policy.reset(spec, 2)
    tracker = distill.ObservationHistory(spec.default_pose, 2, TINY.frames)
    rng = np.random.default_rng(0)
    for _ in range(4):
        obs = {"base_angvel": rng.normal(size=(2, 3)), "projected_gravity": rng.normal(size=(2, 3)),
               "joint_pos": rng.normal(size=(2, 29)), "joint_vel": rng.normal(size=(2, 29)),
               "previous_action": rng.normal(size=(2, 29))}
        o_t, history = tracker.observe(obs)
        mine = student_actions(actor, o_t, history)
        tracker.acted(mine)
        # the policy infers in float64 (protocol 1.2), `student_actions` in float32: equal to float32 rounding,
        # which on these untrained outputs of order 10 reaches about 2e-5
        np.testing.assert_allclose(policy.act(obs), np.asarray(spec.default_pose) + tracker.previous, atol=1e-4)


@pytest.mark.parametrize("simulator", ["mujoco", "pybullet"])
def test_shipped_distilled_policy_runs_in_both_simulators(simulator):
    assert shipped_checkpoint("mpc-distilled-g1").is_file() and "mpc-distilled-g1" in policy_names()
    description = describe_checkpoint(checkpoint_metadata(shipped_checkpoint("mpc-distilled-g1")))
    assert "distilled from mpc" in description and "episodes" in description
    policy = load_policy("mpc-distilled-g1")
    spec, terrain = get_robot("g1"), make_terrain("flat", 1, 0)
    assert policy.supports(spec) and not policy.supports(get_robot("go2"))
    seen = []
    run_episodes(spec, simulator, terrain, draw_starts(spec, terrain, "flat", 1, 0, [0, 1]), policy, steps=5,
                 on_step=lambda task, targets: seen.append(np.array(targets)))
    targets = np.stack(seen)
    assert targets.shape == (5, 2, 29) and np.isfinite(targets).all()
    assert np.abs(targets - np.asarray(spec.default_pose)).max() > 1e-3  # it acts, not just holds the pose


def test_student_blind_to_previous_action_ignores_it():
    """With blind_to_previous_action the normaliser hides every a_{t−1} input; the other inputs still count."""
    from frbench.training.distill_student import train_student

    rng = np.random.default_rng(0)
    frame, joints = 6 + 3 * 29, 29
    obs, actions = rng.normal(size=(64, frame)), rng.normal(size=(64, joints))
    history = np.tile(obs, 2)
    config = DistillConfig(**{**TINY.__dict__, "blind_to_previous_action": True})
    actor, loss = train_student(obs, history, actions, config, 0)
    assert np.isfinite(loss)
    changed = obs.copy()
    changed[:, -joints:] += 5.0
    base = student_actions(actor, obs, history)
    assert np.abs(student_actions(actor, changed, np.tile(changed, 2)) - base).max() < 1e-4
    changed = obs.copy()
    changed[:, :6] += 5.0
    assert np.abs(student_actions(actor, changed, np.tile(changed, 2)) - base).max() > 1e-3


def test_checkpoint_metadata_reads_a_file_holding_a_torch_state_dict(tmp_path):
    """``torch.save`` of a module's state dict pickles an OrderedDict with a ``_metadata`` attribute."""
    import torch

    from frbench.policies.checkpoint import CHECKPOINT_FORMAT

    path = tmp_path / "policy.pt"
    torch.save({"format": CHECKPOINT_FORMAT, "method": "mpc-distill", "env_steps": 5,
                "actor_state_dict": torch.nn.Linear(2, 2).state_dict()}, path)
    assert checkpoint_metadata(path) == {"format": CHECKPOINT_FORMAT, "method": "mpc-distill", "env_steps": 5}


def _bimodal(groups: int = 8, each: int = 16, joints: int = 29):
    """``groups`` distinct inputs repeated ``each`` times, labelled +0.5 or −0.5 rad on every joint at random:
    two answers for the same observation (an average of them, ~0, is neither)."""
    rng = np.random.default_rng(0)
    obs = np.repeat(rng.normal(size=(groups, 6 + 3 * joints)), each, axis=0)
    actions = np.repeat(np.where(rng.random(groups * each) < 0.5, -0.5, 0.5)[:, None], joints, axis=1)
    return obs, np.tile(obs, 2), actions


def test_mixture_student_fits_two_answers_where_mse_averages():
    from frbench.training.distill_student import mixture_fit, train_student

    obs, history, actions = _bimodal()
    mdn = DistillConfig(**{**TINY.__dict__, "student": "mdn", "components": 3, "minibatch": 32, "hidden": (32, 32)})
    actor, _ = train_student(obs, history, actions, DistillConfig(**{**mdn.__dict__, "epochs": 1}), 0)
    first = mixture_fit(actor, obs, history, actions)
    actor, _ = train_student(obs, history, actions, DistillConfig(**{**mdn.__dict__, "epochs": 150}), 0)
    last = mixture_fit(actor, obs, history, actions)
    assert np.isfinite(first["nll"]) and last["nll"] < first["nll"] - 40.0  # the NLL [nats per sample] falls
    chosen = student_actions(actor, obs, history)
    assert chosen.shape == (128, 29) and np.abs(np.abs(chosen) - 0.5).mean() < 0.1  # one of the two answers
    mse, _ = train_student(obs, history, actions, DistillConfig(**{**mdn.__dict__, "student": "mse", "epochs": 150}), 0)
    assert np.abs(student_actions(mse, obs, history)).mean() < 0.2  # the MLP's average of them


def test_mixture_student_saves_and_acts_deterministically(tmp_path):
    config = DistillConfig(**{**TINY.__dict__, "rounds": 1, "student": "mdn", "components": 2})
    run_distillation(tmp_path, config, log=lambda line: None)
    path = tmp_path / "checkpoints" / "round0.pt"
    record = json.loads(path.with_suffix(".config.json").read_text())
    assert record["train_cfg"]["actor"]["class_name"] == "frbench.networks.mixture:MixtureDensityModel"
    assert record["train_cfg"]["actor"]["components"] == 2 and record["distill"]["student"] == "mdn"
    trained = json.loads((tmp_path / "training.json").read_text())["0"]
    assert np.isfinite(trained["loss"]) and np.isfinite(trained["nll"]) and trained["mse"] >= 0.0
    assert trained["settings"]["student"] == "mdn"
    assert "2-component mixture-density" in read_checkpoint(path)["description"]
    spec, rng = get_robot("g1"), np.random.default_rng(0)
    obs = {"base_angvel": rng.normal(size=(2, 3)), "projected_gravity": rng.normal(size=(2, 3)),
           "joint_pos": rng.normal(size=(2, 29)), "joint_vel": rng.normal(size=(2, 29)),
           "previous_action": rng.normal(size=(2, 29))}
    acted = []
    for policy in (load_policy(str(path)), load_policy(str(path))):
        policy.reset(spec, 2)
        acted.append(policy.act(obs))
    assert acted[0].shape == (2, 29) and np.isfinite(acted[0]).all() and np.array_equal(acted[0], acted[1])
    tracker = distill.ObservationHistory(spec.default_pose, 2, config.frames)
    o_t, history = tracker.observe(obs)
    np.testing.assert_allclose(acted[0] - spec.default_pose, student_actions(build_actor(read_checkpoint(path)),
                                                                             o_t, history), atol=1e-5)
    with pytest.raises(FrbenchError, match="student"):
        DistillConfig(student="gmm")
    with pytest.raises(FrbenchError, match="components"):
        DistillConfig(student="mdn", components=0)
