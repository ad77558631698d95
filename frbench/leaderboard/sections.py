"""Which section of the board a record belongs to: the ranked main board, the ranked humanoid track, the partial
records, or the archive (records of other protocol versions, and records superseded by a canonical-joint-frame
re-score of the same policy file), and what a record's policy read."""

from __future__ import annotations

from typing import Mapping, Sequence

from frbench.tasks.protocol import PROTOCOL_VERSION


def superseded(records: Sequence[Mapping]) -> dict[str, str]:
    """Record id → the id of the record that supersedes it: a record of a learned policy run in the robot's own
    joint frame, where a record of the same protocol version and the same policy file (its sha256) ran it in the
    canonical frame (`frbench.robots.joint_frame`; docs/protocol.md, "The joint frame"). Each id keeps meaning
    its own results; the superseded one moves to the archived section (an earlier version's, from its ranking
    there)."""
    canonical = {}
    for record in records:
        policy = record["results"]["policy"]
        if policy.get("sha256") and policy.get("joint_frame") == "canonical":
            canonical.setdefault((record["results"]["protocol_version"], policy["sha256"]), record["id"])
    out = {}
    for record in records:
        policy = record["results"]["policy"]
        key = (record["results"]["protocol_version"], policy.get("sha256"))
        if policy.get("joint_frame", "robot") == "robot" and key in canonical:
            out[record["id"]] = canonical[key]
    return out


def section_of(record: Mapping, replaced: Mapping[str, str] | None = None) -> str:
    """``main`` / ``humanoid`` / ``partial`` for records of the current protocol version (their track),
    ``archived`` for any other version and for a record ``replaced`` names (`superseded`). A policy that reads
    the simulator's state (`inputs_of`) is never ranked with blind policies on the main board: ``partial``; on
    the humanoid track it is ranked, marked (docs/protocol.md, "The humanoid track")."""
    if record["results"]["protocol_version"] != PROTOCOL_VERSION or record.get("id") in (replaced or {}):
        return "archived"
    if record["track"] == "humanoid":
        return "humanoid"
    return "partial" if inputs_of(record) == SIMULATOR_STATE else record["track"]


#: The board's sections, in the order it shows them.
SECTIONS = ("main", "humanoid", "partial", "archived")


#: ``results.policy.inputs`` of a policy that reads the acting simulator's full state (a planner such as ``mpc``).
SIMULATOR_STATE = "simulator-state"


def inputs_of(record: Mapping) -> str:
    """What the record's policy read: ``proprioception`` (the default: a blind policy) or ``simulator-state``."""
    return record["results"]["policy"].get("inputs", "proprioception")
