"""Learned policies in the canonical joint frame: frbench's checkpoints are canonical-frame policies (their
recorded episodes stand where the frame is the identity, bit for bit), an ONNX export carries the frame and scores
on Solo12 as the checkpoint does, a record made in the robot's frame still verifies in it, and a layout that
declares a frame a robot cannot have is refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from frbench.cli import main
from frbench.evaluation.runner import Cell, run_cell
from policy_factory import export_onnx, mlp

#: frnet-30m's policy file, and nine episodes of its protocol 1.2 record 3c903178dd7d, made when learned policies ran in
#: each robot's own frame (the record left the tree with protocol 1.3; leaderboard/README.md names the commit).
BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
FRNET_30M = BOARD / "policies" / "00408d899d9213b7dd35e1bc8be6537f8c40666cdb4c49571bb9b333c3418fe4.pt"
RECORD_30M = "3c903178dd7ddcf815bc5a06718a6d390b133084701a5dbbf4a700cb0cc98f8d"
RECORDED_EPISODES = Path(__file__).resolve().parent / "data" / "frnet-30m-robot-frame-episodes.json"


@pytest.fixture(scope="module")
def recorded_30m() -> dict:
    recorded = json.loads(RECORDED_EPISODES.read_text())
    assert recorded["record"] == RECORD_30M and "joint_frame" not in recorded["policy"]  # the robot's frame
    return recorded


def _recorded(results: dict, robot: str, backend: str, terrain: str, level: int, seed: int) -> list[dict]:
    return [e for e in results["episodes"] if (e["robot"], e["backend"], e["terrain"], e["level"], e["seed"]) ==
            (robot, backend, terrain, level, seed)]


def test_frbench_checkpoints_declare_the_canonical_frame_and_residuals_and_humanoids_the_robot_s():
    from frbench.policies.registry import load_policy

    assert load_policy(str(FRNET_30M)).joint_frame == "canonical"  # a checkpoint older than the field
    assert load_policy("frnet-3m").joint_frame == "canonical"
    assert load_policy("mpc-distilled-g1").joint_frame == "robot"


@pytest.mark.parametrize("robot, terrain, level", [("go2", "stairs", 5), ("a1", "flat", 5)])
def test_a_recorded_episode_on_an_identity_frame_robot_is_bit_identical_in_the_canonical_frame(recorded_30m, robot,
                                                                                               terrain, level):
    """A standard-grid robot and an unseen one whose frame is the identity: the record stands as it is."""
    fresh = run_cell(Cell(robot, "mujoco", terrain, level, 0, 3), str(FRNET_30M), joint_frame="canonical")
    assert fresh == _recorded(recorded_30m, robot, "mujoco", terrain, level, 0)


def test_a_record_made_in_the_robot_s_frame_verifies_in_it_and_the_canonical_frame_changes_solo12(recorded_30m):
    cell = Cell("solo12", "mujoco", "flat", 1, 0, 3)
    recorded = _recorded(recorded_30m, *cell.key())
    assert run_cell(cell, str(FRNET_30M), joint_frame="robot") == recorded
    canonical = run_cell(cell, str(FRNET_30M))
    assert sum(e["success"] for e in recorded) == 0 and sum(e["success"] for e in canonical) == 1


def test_the_onnx_export_carries_the_frame_and_scores_on_solo12_as_the_checkpoint(tmp_path):
    out = tmp_path / "frnet-30m.onnx"
    assert main(["export", "--policy", str(FRNET_30M), "--out", str(out)]) == 0
    sidecar = json.loads(out.with_name(out.name + ".json").read_text())
    assert sidecar["layout"]["joint_frame"] == "canonical"
    cells = [Cell("solo12", backend, "rough", 1, 1, 3) for backend in ("mujoco", "pybullet")]
    exported = [e for cell in cells for e in run_cell(cell, str(out))]
    checkpoint = [e for cell in cells for e in run_cell(cell, str(FRNET_30M))]
    assert [e["success"] for e in exported] == [e["success"] for e in checkpoint]
    assert sum(e["success"] for e in checkpoint) == 1
    # the same targets on Solo12's joints, to float32 rounding (the checkpoint infers in float64, protocol 1.2)
    from frbench.policies.base import policy_joint_frame
    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot

    spec, rng = get_robot("solo12"), np.random.default_rng(4)
    obs = {"base_angvel": rng.normal(size=(4, 3)), "projected_gravity": np.tile([0.0, 0.0, 1.0], (4, 1)),
           "joint_pos": rng.uniform(spec.joint_lower, spec.joint_upper, size=(4, 12)),
           "joint_vel": rng.normal(size=(4, 12)), "previous_action": np.tile(spec.default_pose, (4, 1))}
    targets = []
    for policy in (load_policy(str(out)), load_policy(str(FRNET_30M))):
        frame = policy_joint_frame(policy, spec)
        policy.reset(frame.canonical_spec(spec), 4)
        targets.append(frame.targets(policy.act(frame.observation(obs))))
    np.testing.assert_allclose(targets[0], targets[1], atol=1e-5)


def _refused(tmp_path, capsys, policy: str, robot: str) -> str:
    out = tmp_path / "results" / "r.json"
    assert main(["evaluate", "--policy", policy, "--robots", robot, "--terrains", "flat", "--levels", "1", "--seeds",
                 "0", "--backends", "mujoco", "--episodes", "1", "--jobs", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.parent.exists()
    return err


def test_a_canonical_layout_on_a_humanoid_is_one_line_and_exit_2(tmp_path, capsys):
    joints = 29
    path = export_onnx(mlp(inputs=6 + 3 * joints, outputs=joints), tmp_path / "g1.onnx", inputs=6 + 3 * joints)
    path.with_name(path.name + ".json").write_text(json.dumps({"joint_frame": "canonical"}))
    err = _refused(tmp_path, capsys, str(path), "g1")
    assert "declares joint_frame 'canonical', but robot 'g1': no canonical joint frame" in err


def test_an_unknown_joint_frame_is_one_line_and_exit_2(tmp_path, capsys):
    path = export_onnx(mlp(), tmp_path / "m.onnx")
    path.with_name(path.name + ".json").write_text(json.dumps({"joint_frame": "mirrored"}))
    err = _refused(tmp_path, capsys, str(path), "go2")
    assert "joint_frame 'mirrored', expected one of robot, canonical" in err
