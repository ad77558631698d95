"""The task, ``frbench evaluate``, policies, rendering and the gymnasium registration."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from frbench.backends import make_backend
from frbench.tasks.protocol import PROTOCOL_VERSION
from frbench.backends.base import RobotState
from frbench.cli import main
from frbench.errors import PolicyError
from frbench.evaluation.runner import Cell, run_cell
from frbench.policies.registry import BUDGET_3M_POLICIES
from frbench.robots import get_robot
from frbench.tasks.initial_states import (
    DROP_HEIGHT,
    FALL_KINDS,
    draw_starts,
    lowest_offset_and_reach,
)
from frbench.terrains import FAMILIES, make_terrain, support_height


def test_same_policy_seed_and_backend_give_identical_results():
    for backend in ("mujoco", "pybullet"):
        cell = Cell("go1", backend, "rough", 5, 0, 2)
        assert run_cell(cell, "zero") == run_cell(cell, "zero")


def test_starts_are_identical_across_backends_before_settling():
    spec = get_robot("go2")
    terrain = make_terrain("stairs", 5, 1)
    starts = draw_starts(spec, terrain, "stairs", 5, 1, range(3))
    again = draw_starts(spec, terrain, "stairs", 5, 1, range(3))
    assert np.array_equal(starts.base_pos, again.base_pos) and np.array_equal(starts.q, again.q)
    states = []
    for backend in ("mujoco", "pybullet"):
        sim = make_backend(backend, spec, 3, terrain=terrain)
        sim.reset(np.arange(3), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
        states.append(sim.state())
        sim.close()
    for field in ("base_pos", "q", "qd"):
        np.testing.assert_allclose(getattr(states[0], field), getattr(states[1], field), atol=1e-6)
    sign = np.sign(np.sum(states[0].base_quat * states[1].base_quat, axis=1, keepdims=True))  # q and -q are one rotation
    np.testing.assert_allclose(states[0].base_quat, sign * states[1].base_quat, atol=1e-6)


def test_starts_depend_on_the_episode_and_mix_every_fall_kind():
    spec = get_robot("go2")
    starts = draw_starts(spec, make_terrain("flat", 1, 0), "flat", 1, 0, range(80))
    assert set(starts.kinds) == set(FALL_KINDS)
    assert len({tuple(np.round(q, 6)) for q in starts.q}) == 80
    assert np.all(starts.q >= np.asarray(spec.joint_lower)) and np.all(starts.q <= np.asarray(spec.joint_upper))


@pytest.mark.parametrize("family", FAMILIES)
def test_starts_never_intersect_the_terrain(family):
    spec = get_robot("go2")
    terrain = make_terrain(family, 10, 0)
    starts = draw_starts(spec, terrain, family, 10, 0, range(4))
    for pos, quat, q in zip(starts.base_pos, starts.base_quat, starts.q):
        lowest, reach = lowest_offset_and_reach(spec, quat, q)
        assert pos[2] + lowest == pytest.approx(support_height(terrain, pos[:2], reach) + DROP_HEIGHT)
    sim = make_backend("mujoco", spec, 4, terrain=terrain)
    sim.reset(np.arange(4), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
    assert np.abs(sim.contacts().link_force).max() == 0.0  # nothing touches at placement
    sim.close()


def test_zero_policy_almost_never_recovers():
    records = run_cell(Cell("go2", "mujoco", "flat", 1, 0, 20), "zero")
    assert {r["initial_pose"] for r in records} >= {"supine", "left_side", "right_side"}
    assert not any(r["success"] for r in records if r["initial_pose"] == "supine")
    assert sum(r["success"] for r in records) <= 0.15 * len(records)


class _BadPolicy:
    name = "bad"
    checkpoint = None

    def __init__(self, output):
        self.output = output

    def supports(self, spec):
        return True

    def reset(self, spec, num_envs):
        self.n = num_envs

    def act(self, obs):
        return self.output(self.n)


@pytest.mark.parametrize("output, message", [
    (lambda n: np.zeros((n, 11)), "policy 'bad' returned actions of shape (2, 11), expected (2, 12)"),
    (lambda n: np.full((n, 12), np.nan), "policy 'bad' returned NaN targets (24 values; first at environment 0, joint 0)"),
    (lambda n: np.full((n, 12), np.inf), "policy 'bad' returned infinite targets"),
])
def test_a_misbehaving_policy_is_stopped_with_its_name(monkeypatch, output, message):
    from frbench.evaluation import runner

    monkeypatch.setattr(runner, "_policy", lambda reference: _BadPolicy(output))
    with pytest.raises(PolicyError, match=re.escape(message)):
        run_cell(Cell("go2", "mujoco", "flat", 1, 0, 2), "bad")


def test_results_of_a_trained_policy_are_accepted_by_the_leaderboard(tmp_path, capsys):
    from frbench.leaderboard import check_results

    out = tmp_path / "frnet.json"
    argv = ["evaluate", "--policy", "frnet", "--terrains", "flat", "--levels", "1", "--seeds", "0",
            "--episodes", "1", "--jobs", "1", "--out", str(out)]
    assert main(argv) == 0
    results = json.loads(out.read_text())
    assert results["policy"]["name"] == "frnet" and len(results["policy"]["sha256"]) == 64
    check_results(results)  # raises on anything the leaderboard would refuse


def test_evaluate_writes_consistent_results(tmp_path, capsys):
    out = tmp_path / "r.json"
    argv = ["evaluate", "--policy", "zero", "--robots", "go2", "--terrains", "flat,gaps", "--levels", "1",
            "--seeds", "0,1", "--episodes", "2", "--jobs", "1", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "gap (mj-pb)" in printed and "gap (mj-px)" in printed and "gap (pb-px)" in printed
    assert f"Results written to {out}" in printed
    results = json.loads(out.read_text())
    assert results["schema_version"] == 1 and results["protocol_version"] == PROTOCOL_VERSION
    assert len(results["cells"]) == 2 * 3 * 2 and len(results["episodes"]) == 24  # the protocol's three simulators
    assert len(results["robots"]["go2"]["urdf_sha256"]) == 64
    assert set(results["versions"]) >= {"python", "mujoco", "pybullet", "pinocchio", "numpy", "torch"}
    for cell in results["cells"]:
        mine = [e for e in results["episodes"] if all(e[k] == cell[k] for k in ("robot", "backend", "terrain", "level", "seed"))]
        assert cell["episodes"] == len(mine) == 2
        assert cell["successes"] == sum(e["success"] for e in mine)
        assert cell["success_rate"] == cell["successes"] / 2
    assert {g["terrain"] for g in results["sim_to_sim"]} == {"flat", "gaps"}
    # the per-start-pose table counts every episode once, per backend
    pose_table = printed.split("Success by initial pose:")[1].split("\n\n")[0]
    assert sum(int(n) for _, n in re.findall(r"(\d+)/(\d+)", pose_table)) == 24


def test_initial_pose_table_counts_successes_per_pose_and_backend():
    from frbench.evaluation.results import initial_pose_table

    episodes = [{"robot": "g1", "backend": b, "initial_pose": pose, "success": won}
                for b, pose, won in [("mujoco", "prone", True), ("mujoco", "prone", False), ("pybullet", "prone", False),
                                     ("mujoco", "supine", False), ("pybullet", "supine", True)]]
    rows = initial_pose_table(episodes).splitlines()
    assert rows[0].split()[-2:] == ["mujoco", "pybullet"]
    assert rows[2].split() == ["g1", "prone", "1/2", "(", "50.0%)", "0/1", "(", "0.0%)"]
    assert rows[3].split() == ["g1", "supine", "0/1", "(", "0.0%)", "1/1", "(100.0%)"]


@pytest.mark.parametrize("argv, message", [
    (["--robots", "go3"], "unknown robot 'go3'"),
    (["--terrains", "stair"], "unknown terrain 'stair'"),
    (["--policy", "scriptd"], "unknown policy 'scriptd'"),
    (["--levels", "11"], "level 11 is out of range: levels are 1 to 10"),
    (["--backends", "bullet"], "unknown backend 'bullet'"),
])
def test_bad_evaluate_arguments_exit_2_with_one_line(tmp_path, capsys, argv, message):
    out = tmp_path / "r.json"
    assert main(["evaluate", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists()


def test_suggestions_for_misspelt_names(tmp_path, capsys):
    assert main(["evaluate", "--terrains", "stair", "--out", str(tmp_path / "r.json")]) == 2
    assert "did you mean 'stairs'?" in capsys.readouterr().err


def test_unreadable_and_incompatible_checkpoints(tmp_path, capsys):
    import torch

    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    assert main(["evaluate", "--policy", str(garbage), "--out", str(tmp_path / "r.json")]) == 2
    assert f"{garbage}: unreadable checkpoint" in capsys.readouterr().err
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    assert main(["evaluate", "--policy", str(other), "--out", str(tmp_path / "r.json")]) == 2
    assert f"{other}: incompatible checkpoint (format None, expected 'frbench-policy-v1')" in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()


def test_an_unwritable_output_path_fails_before_running(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    out = blocker / "r.json"  # cannot exist: its parent is a file (root ignores permission bits)
    assert main(["evaluate", "--policy", "zero", "--terrains", "flat", "--out", str(out)]) == 2
    assert f"--out {out}: cannot create it, {blocker} is a file, not a folder" in capsys.readouterr().err
    assert blocker.read_text() == "not a folder"


def test_policies_lists_the_builtins(capsys):
    assert main(["policies", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert {"zero", "scripted"} <= set(rows)
    assert "go2" in rows["scripted"]["robots"]


def test_render_writes_a_gif(tmp_path, capsys):
    out = tmp_path / "episode.gif"
    assert main(["render", "--policy", "zero", "--robot", "go2", "--size", "96x72", "--fps", "10", "--out", str(out)]) == 0
    import imageio.v3 as iio

    frames = iio.imread(out, index=None)
    assert frames.shape[1:] == (72, 96, 3)
    assert 2 <= frames.shape[0] <= 51  # 5 s at 10 fps (the GIF writer merges identical frames)
    assert frames.std() > 5  # not a blank image


def test_terrain_show_writes_a_png(tmp_path):
    out = tmp_path / "stairs.png"
    assert main(["terrain", "show", "stairs", "--level", "10", "--size", "120x90", "--out", str(out)]) == 0
    import imageio.v3 as iio

    assert iio.imread(out).shape == (90, 120, 3)


@pytest.mark.parametrize("name", BUDGET_3M_POLICIES)
def test_each_equal_budget_checkpoint_is_shipped_with_its_budget_and_acts(name):
    import torch

    from frbench.policies.registry import load_policy, shipped_checkpoint

    data = torch.load(shipped_checkpoint(name), weights_only=True)
    assert data["format"] == "frbench-policy-v1" and name.startswith(data["method"])
    if data["method"] == "rma-adaptation":  # phase 2: 82 iterations of 256 × 24 on the frozen 3.07 M phase-1 policy
        assert data["env_steps"] == 503_808 and json.loads(data["config_json"])["teacher"].endswith("budget3m/rma")
    else:
        assert data["env_steps"] == 3_072_000
    policy = load_policy(name)
    assert policy.name == name and policy.supports(get_robot("go2"))
    policy.reset(get_robot("go2"), 2)
    obs = {"base_angvel": np.zeros((2, 3)), "projected_gravity": np.tile([0.0, 0.0, 1.0], (2, 1)),
           "joint_pos": np.tile(get_robot("go2").default_pose, (2, 1)), "joint_vel": np.zeros((2, 12)),
           "previous_action": np.tile(get_robot("go2").default_pose, (2, 1))}
    assert np.isfinite(policy.act(obs)).all()


def test_the_shipped_frnet_checkpoint_loads_and_acts():
    import torch

    from frbench.policies.registry import load_policy, shipped_checkpoint

    data = torch.load(shipped_checkpoint("frnet"), weights_only=True)
    assert data["format"] == "frbench-policy-v1" and data["method"] == "frnet"
    policy = load_policy("frnet")
    assert policy.name == "frnet"
    records = run_cell(Cell("go2", "mujoco", "flat", 1, 0, 2), "frnet")
    assert len(records) == 2 and all(np.isfinite(r["energy"]) for r in records)
    assert policy.supports(get_robot("go1")) and not policy.supports(get_robot("g1"))


def test_results_record_the_commit_the_episodes_started_with(tmp_path, monkeypatch):
    """A commit made while a long evaluation runs is not the code that ran its episodes."""
    import frbench.evaluation.provenance as provenance

    commits = iter(["a" * 40, "b" * 40, "c" * 40])
    monkeypatch.setattr(provenance, "frbench_info",
                        lambda: {"version": "x", "git_commit": next(commits), "git_dirty": False})
    out = tmp_path / "r.json"
    assert main(["evaluate", "--policy", "zero", "--robots", "go2", "--terrains", "flat", "--levels", "1",
                 "--seeds", "0", "--episodes", "1", "--jobs", "1", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["frbench"]["git_commit"] == "a" * 40
