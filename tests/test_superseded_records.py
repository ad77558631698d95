"""A learned record re-scored in the canonical joint frame supersedes the record of the same policy file that ran
in the robot's frame, and a record that holds every cell of another record of the same policy, and more,
supersedes that one: the older one leaves the ranking for the archived section, and both keep their ids."""

from __future__ import annotations

from frbench.leaderboard.render import section_of, superseded
from frbench.leaderboard.sections import CANONICAL_RESCORE, EXTENDED, superseded_why
from frbench.tasks.protocol import PROTOCOL_VERSION


def _record(id_: str, sha: str | None, frame: str | None = None, version: str = PROTOCOL_VERSION) -> dict:
    policy = {"name": "frnet", "checkpoint": "x.pt" if sha else None, "sha256": sha}
    if frame is not None:
        policy["joint_frame"] = frame
    return {"id": id_, "track": "main", "results": {"protocol_version": version, "policy": policy}}


def test_the_robot_frame_record_of_a_policy_file_with_a_canonical_record_is_superseded():
    old, new = _record("a" * 64, "1" * 64), _record("b" * 64, "1" * 64, "canonical")
    other = _record("c" * 64, "2" * 64)  # another policy file: no canonical record, stays ranked
    builtin = _record("d" * 64, None)  # a built-in policy (no file): never superseded
    earlier = _record("e" * 64, "1" * 64, version="1.1")  # already archived by its version
    replaced = superseded([old, new, other, builtin, earlier])
    assert replaced == {"a" * 64: "b" * 64}
    assert [section_of(r, replaced) for r in (old, new, other, builtin, earlier)] == [
        "archived", "main", "main", "main", "archived"]


def test_an_earlier_versions_robot_frame_record_is_superseded_within_its_version_only():
    old, new = _record("a" * 64, "1" * 64, version="1.1"), _record("b" * 64, "1" * 64, "canonical", version="1.1")
    current = _record("c" * 64, "1" * 64)  # the current version's robot-frame record: no canonical one of its version
    assert superseded([old, new, current]) == {"a" * 64: "b" * 64}
    assert [section_of(r, superseded([old, new, current])) for r in (old, new, current)] == [
        "archived", "archived", "main"]


def _cells(robots, success: bool = False) -> list[dict]:
    """A record's cells: seeds 0-2 of each robot."""
    return [{"robot": r, "backend": "mujoco", "terrain": "flat", "level": 1, "seed": k, "episodes": 3,
             "successes": int(success and k == 0), "mean_energy": 10.0 + k} for r in robots for k in range(3)]


def _humanoid(id_: str, name: str, sha: str | None, cells: list[dict]) -> dict:
    policy = {"name": name, "checkpoint": "p.json" if sha else None, "sha256": sha}
    return {"id": id_, "track": "humanoid", "results": {"protocol_version": PROTOCOL_VERSION, "policy": policy,
                                                        "cells": cells}}


def test_a_record_that_holds_every_cell_of_another_of_the_same_policy_and_more_supersedes_it():
    g1_only = _humanoid("a" * 64, "keyframe-humanoid", "1" * 64, _cells(["g1"]))
    with_set = _humanoid("b" * 64, "keyframe-humanoid", "1" * 64, _cells(["g1", "icub", "talos"]))
    code_only = _humanoid("c" * 64, "scripted-humanoid", None, _cells(["g1"]))  # code in frbench: matched by name
    code_set = _humanoid("d" * 64, "scripted-humanoid", None, _cells(["g1", "icub"]))
    assert superseded([g1_only, with_set, code_only, code_set]) == {"a" * 64: "b" * 64, "c" * 64: "d" * 64}
    assert [section_of(r, superseded([g1_only, with_set])) for r in (g1_only, with_set)] == ["archived", "humanoid"]
    assert superseded_why(g1_only, with_set) == EXTENDED


def test_a_wider_record_whose_shared_cells_differ_or_of_another_policy_supersedes_nothing():
    g1_only = _humanoid("a" * 64, "keyframe-humanoid", "1" * 64, _cells(["g1"]))
    changed = _humanoid("b" * 64, "keyframe-humanoid", "1" * 64, _cells(["g1"], success=True) + _cells(["icub"]))
    other_file = _humanoid("c" * 64, "keyframe-humanoid", "2" * 64, _cells(["g1", "icub"]))
    other_name = _humanoid("d" * 64, "zero", "1" * 64, _cells(["g1", "icub"]))
    same = _humanoid("e" * 64, "keyframe-humanoid", "1" * 64, _cells(["g1"]))  # equal, not more: neither goes
    assert superseded([g1_only, changed, other_file, other_name, same]) == {}


def test_the_canonical_rescore_is_named_as_such():
    old, new = _record("a" * 64, "1" * 64), _record("b" * 64, "1" * 64, "canonical")
    assert superseded_why(old, new) == CANONICAL_RESCORE
