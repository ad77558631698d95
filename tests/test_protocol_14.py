"""Protocol 1.4: a start's joint angles are redrawn until its links are free of each other (at most
`MAX_FREE_REDRAWS` redraws, an error beyond), where protocols up to 1.3 kept the last of 50 redraws
(docs/protocol.md, "Protocol 1.4")."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.backends.self_collision import self_intersects
from frbench.errors import FrbenchError
from frbench.robots.registry import get_robot
from frbench.tasks import initial_states
from frbench.tasks.initial_states import JointRedraws, draw_starts, joint_redraws
from frbench.tasks.protocol import FREE_STARTS_PROTOCOL, KNOWN_PROTOCOL_VERSIONS
from frbench.terrains import make_terrain

#: Starts of the grids whose 51 joint draws all overlap (tools/start_overlap_audit.py) and the number of joint
#: draws `self_intersects` tests for each under 1.3 (50, the 51st kept untested) and under 1.4 (the first free).
OVERLAPPING_UNDER_13 = {
    ("icub", "flat", 1, 0, 0): 72,
    ("talos", "flat", 1, 0, 0): 129,
    ("mini_cheetah", "rough", 1, 1, 1): 59,
    ("mini_cheetah", "stairs", 5, 2, 1): 62,
}
#: Cells whose starts no rule changes: a standard quadruped, the unseen mini_cheetah's cell without an exhausted
#: start, and the G1 of the humanoid grid.
UNCHANGED_CELLS = (("go2", "stairs", 10, 3), ("mini_cheetah", "flat", 1, 0), ("g1", "slopes", 5, 2))


def _starts(robot, family, level, seed, episodes, rule):
    return draw_starts(get_robot(robot), make_terrain(family, level, seed), family, level, seed, episodes, rule=rule)


def _counting_draws(monkeypatch) -> list[int]:
    tested = [0]

    def counting(spec, q):
        tested[0] += 1
        return self_intersects(spec, q)

    monkeypatch.setattr(initial_states, "self_intersects", counting)
    return tested


def test_the_rule_depends_on_the_protocol_version():
    assert "1.4" in KNOWN_PROTOCOL_VERSIONS and FREE_STARTS_PROTOCOL == "1.4"
    assert [joint_redraws(v) for v in ("1.0", "1.2", "1.3")] == [JointRedraws(50, False)] * 3
    assert joint_redraws("1.4") == JointRedraws(5000, True)


@pytest.mark.parametrize("start", OVERLAPPING_UNDER_13, ids=lambda s: "-".join(map(str, s)))
def test_a_start_that_overlapped_under_13_is_free_under_14(start, monkeypatch):
    robot, family, level, seed, episode = start
    tested = _counting_draws(monkeypatch)
    old = _starts(robot, family, level, seed, [episode], "1.3")
    assert tested[0] == 50 and self_intersects(get_robot(robot), old.q[0])
    tested[0] = 0
    new = _starts(robot, family, level, seed, [episode], "1.4")
    assert tested[0] == OVERLAPPING_UNDER_13[start] and not self_intersects(get_robot(robot), new.q[0])
    # the fall kind and orientation come before the joints: only the joint angles and the drop height change
    assert new.kinds == old.kinds and np.array_equal(new.base_quat, old.base_quat)
    assert not np.array_equal(new.q, old.q) and np.array_equal(new.base_pos[:, :2], old.base_pos[:, :2])


@pytest.mark.parametrize("cell", UNCHANGED_CELLS, ids=lambda c: "-".join(map(str, c)))
def test_starts_that_never_exhausted_the_redraws_are_bit_identical(cell):
    old, new = _starts(*cell, range(3), "1.3"), _starts(*cell, range(3), "1.4")
    for name in ("base_pos", "base_quat", "q"):
        assert np.array_equal(getattr(old, name), getattr(new, name))
    assert old.kinds == new.kinds


def test_a_start_still_overlapping_after_the_budget_is_a_one_line_error(monkeypatch):
    monkeypatch.setattr(initial_states, "MAX_FREE_REDRAWS", 10)
    with pytest.raises(FrbenchError) as raised:
        _starts("talos", "flat", 1, 0, [0], "1.4")
    message = str(raised.value)
    assert "\n" not in message
    assert message.startswith("start of talos flat level 1 seed 0 episode 0: its links overlap in every one of 11 "
                              "joint draws")


def test_the_screenings_redraws_follow_the_starts_rule():
    from frbench.tasks.start_screening import redraw

    starts = _starts("mini_cheetah", "flat", 1, 1, [0, 1], "1.4")
    redraw(starts, np.array([True, False]))
    redraw(starts, np.array([True, False]))
    redraw(starts, np.array([True, False]))  # attempt 3 of episode 0 exhausts 50 redraws
    assert starts.attempts.tolist() == [3, 0] and starts.redraws == JointRedraws(5000, True)
    assert not self_intersects(get_robot("mini_cheetah"), starts.q[0])


# --------------------------------------------------------------------------- a 1.4 record reusing a 1.3 record


def _reuse_pair():
    """A 1.3 record (go2, 64 episodes in three simulators) and 1.4 results holding its episodes but two, re-run."""
    import copy
    import sys
    from pathlib import Path

    from frbench.leaderboard.records import build_record
    from frbench.leaderboard.reuse import episode_key, reused_field

    sys.path.insert(0, str(Path(__file__).parent))
    from test_protocol_13 import _fields, rebuilt, three_simulator_results

    results = three_simulator_results()
    source = build_record(results, _fields(results))
    new = copy.deepcopy(results)
    rerun = []
    for episode in (new["episodes"][0], new["episodes"][-1]):
        episode["success"], episode["time_to_recover"] = not episode["success"], None
        rerun.append(episode_key(episode))
    new = rebuilt(new, "1.4")
    new["reused"] = reused_field(source, ["mujoco", "pybullet", "physx"], rerun)
    return source, new, rerun


def test_a_14_record_reuses_every_episode_of_its_13_record_but_the_re_run_ones():
    from frbench.leaderboard.results import check_results
    from frbench.leaderboard.reuse import check_against_source, check_reused

    source, new, rerun = _reuse_pair()
    reused = new["reused"]
    assert reused["episodes"] == 96 - 2 and reused["rerun"] == sorted(list(key) for key in rerun)
    assert rerun[0] == ("go2", "mujoco", "flat", 1, 0, 0)
    check_results(new)
    check_against_source(new, source)
    # a reused episode changed: refused; a re-run key that is no episode of the results: refused
    edited = {**new, "episodes": [dict(e) for e in new["episodes"]]}
    edited["episodes"][1]["initial_pose"] = "prone"
    with pytest.raises(FrbenchError, match=r"^reused\.episodes_sha256: the results' episodes of mujoco, pybullet, "
                                           r"physx except the 2 re-run have another checksum$"):
        check_reused(edited)
    wrong = {**new, "reused": {**reused, "rerun": [*reused["rerun"], ["go2", "mujoco", "flat", 1, 0, 9]]}}
    with pytest.raises(FrbenchError, match=r"^reused\.rerun: go2 mujoco flat 1 0 9 is not an episode of the "):
        check_reused(wrong)


def test_the_re_score_finds_the_changed_episodes_of_a_record():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from rescore_starts import StartDraws, changed_episodes

    def episode(robot, terrain, level, seed, number, redraws=0):
        return {"robot": robot, "backend": "mujoco", "terrain": terrain, "level": level, "seed": seed,
                "episode": number, "start_redraws": redraws}

    results = {"episodes": [
        episode("mini_cheetah", "rough", 1, 1, 1),     # its first draw exhausts 50 redraws
        episode("mini_cheetah", "flat", 1, 1, 0, 2),   # attempts 0-2 are free within 50 redraws
        episode("mini_cheetah", "flat", 1, 1, 0, 3),   # its screening's attempt 3 exhausts them
        episode("go2", "stairs", 10, 3, 2, 8),
        episode("g1", "flat", 1, 0, 0),
    ]}
    assert changed_episodes(results, StartDraws()) == [("mini_cheetah", "mujoco", "rough", 1, 1, 1),
                                                       ("mini_cheetah", "mujoco", "flat", 1, 1, 0)]


def test_the_humanoid_job_adopts_an_earlier_protocols_chunks_whose_starts_are_unchanged(tmp_path):
    import json
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from humanoid_records import GRID, HumanoidJob
    from rescore import chunk_path
    from rescore_starts import StartDraws

    earlier, out = tmp_path / "humanoid-1.3", tmp_path / "humanoid-1.4"
    old, new = HumanoidJob("zero", earlier, "1.3"), HumanoidJob("zero", out, "1.4")
    old.meta()
    chosen = [c for c in old.chunks[GRID] if c[:3] in (("g1", "mujoco", "flat"), ("icub", "mujoco", "flat"))]
    for robot, backend, family, cells in chosen:
        episodes = [{"robot": robot, "backend": backend, "terrain": family, "level": c.level, "seed": c.seed,
                     "episode": e, "start_redraws": 0, "success": False} for c in cells for e in range(c.episodes)]
        document = {"cells": [list(c.key()) for c in cells], "episodes": episodes}
        chunk_path(earlier, "zero", GRID, robot, backend, family).parent.mkdir(parents=True, exist_ok=True)
        chunk_path(earlier, "zero", GRID, robot, backend, family).write_text(json.dumps(document))
    taken = new.adopt(earlier, StartDraws("1.3", "1.4"))
    # the G1's starts are the same under both protocols; iCub's flat starts are redrawn under 1.4
    assert [p.name for p in taken] == ["humanoid-g1-mujoco-flat.json"]
    assert json.loads(taken[0].read_text())["adopted_from"] == "1.3"
    assert len(new.pending(GRID)) == len(new.chunks[GRID]) - 1
