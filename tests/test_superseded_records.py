"""A learned record re-scored in the canonical joint frame supersedes the record of the same policy file that ran
in the robot's frame: the older one leaves the ranking for the archived section, and both keep their ids."""

from __future__ import annotations

from frbench.leaderboard.render import section_of, superseded
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
