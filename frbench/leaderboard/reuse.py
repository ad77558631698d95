"""Results that reuse another record's episodes, and the proof that they are that record's.

A new protocol version that adds a simulator to the grids (1.3: PhysX) leaves the other simulators' cells as
they were: the same starts, terrains, physics and policy give bit-identical episodes. A 1.3 record of a policy
therefore holds its 1.2 record's MuJoCo and PyBullet episodes unchanged beside its new PhysX episodes
(tools/rescore_physx.py), and says so in its results' ``reused`` field:

* ``record``: the id of the record whose episodes it reuses, ``protocol_version``: that record's version;
* ``backends``: the simulators whose episodes are reused (every one of their episodes in the results);
* ``episodes`` and ``episodes_sha256``: their number and `episodes_sha256` of them.

`check_reused` (run by `frbench.leaderboard.results.check_results` on every results object) checks that the
results' episodes of those simulators are the ones the checksum names; `check_against_source` checks that the
named record's episodes of those simulators have the same checksum, so that both hold the same episodes, bit for
bit (`frbench leaderboard --check` and tests/test_physx_records.py run it for every record on the board whose
source is there too). ``frbench verify`` re-runs a sample of all the record's episodes, reused ones included,
under the record's protocol version.
"""

from __future__ import annotations

import hashlib
from typing import Mapping, Sequence

from frbench.errors import ResultsError
from frbench.leaderboard.jsonfile import canonical_json
from frbench.tasks.protocol import version_key

#: The key that orders episodes in results (and in the checksum).
EPISODE_ORDER = ("robot", "backend", "terrain", "level", "seed", "episode")


def _ordered(episodes: Sequence[Mapping], backends: Sequence[str]) -> list[Mapping]:
    chosen = [e for e in episodes if e["backend"] in backends]
    return sorted(chosen, key=lambda e: tuple(e[k] for k in EPISODE_ORDER))


def episodes_sha256(episodes: Sequence[Mapping], backends: Sequence[str]) -> str:
    """The sha256 of the canonical JSON (`frbench.leaderboard.jsonfile.canonical_json`) of the list of
    ``episodes`` whose backend is one of ``backends``, in `EPISODE_ORDER`."""
    return hashlib.sha256(canonical_json(_ordered(episodes, backends)).encode("ascii")).hexdigest()


def reused_field(source: Mapping, backends: Sequence[str]) -> dict:
    """The ``reused`` field of results that take the episodes of ``backends`` from the record ``source``."""
    episodes = source["results"]["episodes"]
    return {"record": source["id"], "protocol_version": source["results"]["protocol_version"],
            "backends": list(backends), "episodes": len(_ordered(episodes, backends)),
            "episodes_sha256": episodes_sha256(episodes, backends)}


def reused_episodes(source: Mapping, backends: Sequence[str]) -> list[dict]:
    """The episodes of ``backends`` in the record ``source``, in `EPISODE_ORDER` (copies)."""
    return [dict(e) for e in _ordered(source["results"]["episodes"], backends)]


def check_reused(results: Mapping) -> None:
    """When ``results`` has a ``reused`` field: its simulators are among the results' backends, its source is of
    an earlier protocol, and the results' episodes of those simulators are as many as it says and have its
    checksum (a `ResultsError` naming the field otherwise)."""
    reused = results.get("reused")
    if reused is None:
        return
    missing = [b for b in reused["backends"] if b not in results["config"]["backends"]]
    if missing:
        raise ResultsError(f"reused.backends: {', '.join(missing)} not among config.backends")
    if version_key(reused["protocol_version"]) >= version_key(results["protocol_version"]):
        raise ResultsError(f"reused.protocol_version: {reused['protocol_version']} is not earlier than the results' "
                           f"{results['protocol_version']}")
    count = len(_ordered(results["episodes"], reused["backends"]))
    if count != reused["episodes"]:
        raise ResultsError(f"reused.episodes: {reused['episodes']} but the results hold {count} episodes of "
                           f"{', '.join(reused['backends'])}")
    if episodes_sha256(results["episodes"], reused["backends"]) != reused["episodes_sha256"]:
        raise ResultsError("reused.episodes_sha256: the results' episodes of "
                           f"{', '.join(reused['backends'])} have another checksum")


def check_against_source(results: Mapping, source: Mapping) -> None:
    """The record ``source`` is the one ``results.reused`` names, of its protocol version, and its episodes of the
    reused simulators have the same checksum as the results' (a `ResultsError` otherwise)."""
    reused = results["reused"]
    if source["id"] != reused["record"]:
        raise ResultsError(f"reused.record: {reused['record'][:12]} is not record {source['id'][:12]}")
    if source["results"]["protocol_version"] != reused["protocol_version"]:
        raise ResultsError(f"reused.protocol_version: {reused['protocol_version']} but record "
                           f"{source['id'][:12]} is of protocol {source['results']['protocol_version']}")
    if episodes_sha256(source["results"]["episodes"], reused["backends"]) != reused["episodes_sha256"]:
        raise ResultsError(f"reused.episodes_sha256: record {source['id'][:12]}'s episodes of "
                           f"{', '.join(reused['backends'])} have another checksum")


def check_board_reuse(records: Sequence[Mapping]) -> list[str]:
    """Every record on the board that reuses a record also on the board, checked against it
    (`check_against_source`); returns the ids of the records checked. A reused record that is not on the board
    is not an error (it may have been archived elsewhere)."""
    by_id = {r["id"]: r for r in records}
    checked = []
    for record in records:
        reused = record["results"].get("reused")
        if reused is not None and reused["record"] in by_id:
            try:
                check_against_source(record["results"], by_id[reused["record"]])
            except ResultsError as exc:
                raise ResultsError(f"record {record['id'][:12]}: {exc}") from None
            checked.append(record["id"])
    return checked
