"""Which section of the board a record belongs to: the ranked main board, the ranked humanoid track, the partial
records, or the archive (records of other protocol versions, and records superseded by a canonical-joint-frame
re-score of the same policy file or by a record of the same policy that holds every one of their cells and more),
and what a record's policy read."""

from __future__ import annotations

from typing import Mapping, Sequence

from frbench.tasks.protocol import PROTOCOL_VERSION


#: Why a record is superseded (`superseded_why`), by rule.
CANONICAL_RESCORE = "the same policy file re-scored in the canonical joint frame"
EXTENDED = "the same policy's record that holds every cell of it unchanged, and more"


def _canonical_rescores(records: Sequence[Mapping]) -> dict[str, str]:
    """Record id → id: a learned policy's robot-frame record → the canonical-frame record of the same protocol
    version and policy file (sha256)."""
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


def _cell_key(cell: Mapping) -> tuple:
    return (cell["robot"], cell["backend"], cell["terrain"], cell["level"], cell["seed"])


def _extensions(records: Sequence[Mapping]) -> dict[str, str]:
    """Record id → the id of the record with the most cells that *extends* it: the same protocol version, policy
    name, policy file (sha256, or none for both: code in frbench) and joint frame, every cell of it present and
    equal there (episodes, successes, rates and every metric's mean, to the last bit: the cells of a record's
    summary, `frbench.leaderboard.summaries`, which holds no episode list), and more cells (e.g. the humanoid set's
    robots, which the first run did not drive)."""
    def policy_key(record):
        policy = record["results"]["policy"]
        return (record["results"]["protocol_version"], policy.get("name"), policy.get("sha256"),
                policy.get("joint_frame", "robot"))

    groups: dict[tuple, list[Mapping]] = {}
    for record in records:
        groups.setdefault(policy_key(record), []).append(record)
    out = {}
    for group in (g for g in groups.values() if len(g) > 1):
        cells = {r["id"]: {_cell_key(c): c for c in r["results"].get("cells", ())} for r in group}
        for record in group:
            mine = cells[record["id"]]
            wider = [other for other in group if len(cells[other["id"]]) > len(mine) > 0
                     and all(cells[other["id"]].get(key) == c for key, c in mine.items())]
            if wider:
                out[record["id"]] = max(wider, key=lambda r: len(cells[r["id"]]))["id"]
    return out


def superseded(records: Sequence[Mapping]) -> dict[str, str]:
    """Record id → the id of the record that supersedes it (`superseded_why` says why): a record of a learned
    policy run in the robot's own joint frame, where a record of the same protocol version and the same policy
    file (its sha256) ran it in the canonical frame (`frbench.robots.joint_frame`; docs/protocol.md, "The joint
    frame"); or a record another record of the same policy extends (`_extensions`). Each id keeps meaning its own
    results; the superseded one moves to the archived section (an earlier version's, from its ranking there)."""
    return {**_extensions(records), **_canonical_rescores(records)}


def superseded_why(record: Mapping, by: Mapping) -> str:
    """Why ``by`` supersedes ``record`` (`superseded`): `CANONICAL_RESCORE` or `EXTENDED`."""
    frames = (record["results"]["policy"].get("joint_frame", "robot"), by["results"]["policy"].get("joint_frame", "robot"))
    return CANONICAL_RESCORE if frames == ("robot", "canonical") else EXTENDED


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
