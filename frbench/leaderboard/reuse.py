"""Results that reuse another record's episodes, and the proof that they are that record's.

A new protocol version that leaves some episodes as they were (the same starts, terrains, physics and policy give
bit-identical episodes) lets a record of a policy hold its earlier record's episodes unchanged beside the new ones:
a 1.3 record holds its 1.2 record's MuJoCo and PyBullet episodes beside its new PhysX episodes
(tools/rescore_physx.py); a 1.4 record holds its 1.3 record's episodes except those whose start 1.4 redraws
(tools/rescore_starts.py). Its results say so in their ``reused`` field:

* ``record``: the id of the record whose episodes it reuses, ``protocol_version``: that record's version;
* ``backends``: the simulators whose episodes are reused (every one of their episodes in the results, except
  ``rerun``);
* ``rerun`` (optional): the episodes of those simulators that ran again, each as (robot, backend, terrain, level,
  seed, episode), neither reused nor counted;
* ``episodes`` and ``episodes_sha256``: the number of reused episodes and `episodes_sha256` of them.

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


def episode_key(episode: Mapping) -> tuple:
    """An episode's identity: its values of `EPISODE_ORDER`."""
    return tuple(episode[k] for k in EPISODE_ORDER)


def _ordered(episodes: Sequence[Mapping], backends: Sequence[str], rerun: Sequence[Sequence] = ()) -> list[Mapping]:
    left_out = {tuple(key) for key in rerun}
    chosen = [e for e in episodes if e["backend"] in backends and episode_key(e) not in left_out]
    return sorted(chosen, key=episode_key)


def episodes_sha256(episodes: Sequence[Mapping], backends: Sequence[str], rerun: Sequence[Sequence] = ()) -> str:
    """The sha256 of the canonical JSON (`frbench.leaderboard.jsonfile.canonical_json`) of the list of
    ``episodes`` whose backend is one of ``backends`` and whose key (`episode_key`) is not in ``rerun``, in
    `EPISODE_ORDER`."""
    return hashlib.sha256(canonical_json(_ordered(episodes, backends, rerun)).encode("ascii")).hexdigest()


def reused_field(source: Mapping, backends: Sequence[str], rerun: Sequence[Sequence] = ()) -> dict:
    """The ``reused`` field of results that take the episodes of ``backends`` from the record ``source``, except
    the episodes ``rerun`` (keys, `episode_key`: listed in the field, sorted, when there are any)."""
    episodes = source["results"]["episodes"]
    field = {"record": source["id"], "protocol_version": source["results"]["protocol_version"],
             "backends": list(backends)}
    if rerun:
        field["rerun"] = [list(key) for key in sorted({tuple(key) for key in rerun})]
    return {**field, "episodes": len(_ordered(episodes, backends, rerun)),
            "episodes_sha256": episodes_sha256(episodes, backends, rerun)}


def reused_episodes(source: Mapping, backends: Sequence[str], rerun: Sequence[Sequence] = ()) -> list[dict]:
    """The episodes of ``backends`` in the record ``source``, except ``rerun``, in `EPISODE_ORDER` (copies)."""
    return [dict(e) for e in _ordered(source["results"]["episodes"], backends, rerun)]


def _described(reused: Mapping) -> str:
    rerun = reused.get("rerun", [])
    return ", ".join(reused["backends"]) + (f" except the {len(rerun)} re-run" if rerun else "")


def check_reused(results: Mapping) -> None:
    """When ``results`` has a ``reused`` field: its simulators are among the results' backends, its source is of
    an earlier protocol, every ``rerun`` episode is one of the results' of those simulators, and the results'
    other episodes of those simulators are as many as it says and have its checksum (a `ResultsError` naming the
    field otherwise)."""
    reused = results.get("reused")
    if reused is None:
        return
    missing = [b for b in reused["backends"] if b not in results["config"]["backends"]]
    if missing:
        raise ResultsError(f"reused.backends: {', '.join(missing)} not among config.backends")
    if version_key(reused["protocol_version"]) >= version_key(results["protocol_version"]):
        raise ResultsError(f"reused.protocol_version: {reused['protocol_version']} is not earlier than the results' "
                           f"{results['protocol_version']}")
    rerun = reused.get("rerun", [])
    held = {episode_key(e) for e in _ordered(results["episodes"], reused["backends"])}
    absent = [key for key in rerun if tuple(key) not in held]
    if absent:
        raise ResultsError(f"reused.rerun: {' '.join(map(str, absent[0]))} is not an episode of the results' "
                           f"{', '.join(reused['backends'])}")
    count = len(_ordered(results["episodes"], reused["backends"], rerun))
    if count != reused["episodes"]:
        raise ResultsError(f"reused.episodes: {reused['episodes']} but the results hold {count} episodes of "
                           f"{_described(reused)}")
    if episodes_sha256(results["episodes"], reused["backends"], rerun) != reused["episodes_sha256"]:
        raise ResultsError(f"reused.episodes_sha256: the results' episodes of {_described(reused)} have another "
                           "checksum")


def check_against_source(results: Mapping, source: Mapping) -> None:
    """The record ``source`` is the one ``results.reused`` names, of its protocol version, and its episodes of the
    reused simulators have the same checksum as the results' (a `ResultsError` otherwise)."""
    reused = results["reused"]
    if source["id"] != reused["record"]:
        raise ResultsError(f"reused.record: {reused['record'][:12]} is not record {source['id'][:12]}")
    if source["results"]["protocol_version"] != reused["protocol_version"]:
        raise ResultsError(f"reused.protocol_version: {reused['protocol_version']} but record "
                           f"{source['id'][:12]} is of protocol {source['results']['protocol_version']}")
    rerun = reused.get("rerun", [])
    if episodes_sha256(source["results"]["episodes"], reused["backends"], rerun) != reused["episodes_sha256"]:
        raise ResultsError(f"reused.episodes_sha256: record {source['id'][:12]}'s episodes of {_described(reused)} "
                           "have another checksum")


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
