"""Re-run a seeded random sample of a record's episodes from its provenance and compare them episode by episode.

A record keeps every episode with the config, versions, commit and checksums
that produced it, and evaluation is deterministic, so a sampled episode can be
run again and compared:

1. the sample: ``sample`` episodes drawn without replacement by
   ``numpy.random.default_rng(seed)``; each is re-run inside its whole cell (all
   ``config.episodes`` episodes side by side, as ``frbench evaluate`` ran them,
   with `frbench.evaluation.runner.run_cell`);
2. the policy (:func:`resolve_policy`): the record's attached policy file
   (``attached``, its sha256 checked first: a replaced file fails), else a
   checkpoint shipped with frbench whose sha256 is the results' one
   (``shipped``), else a built-in policy by name (``built-in``: code in frbench,
   re-run with this checkout's code; a record made at another commit reproduces
   only where that code did not change);
3. the comparison (:func:`compare_episode`), and the *tier* it reaches (:data:`TIERS`):

   * ``exact``: every sampled episode bit-identical;
   * ``reproduced``: discrete outcomes (success, rollover, divergence, initial
     pose, start redraws) equal, ``time_to_recover`` within one control period
     and every continuous metric within a relative tolerance: :data:`REPRODUCED_TOLERANCE`
     when the record's library versions equal this installation's (mode
     ``exact``), :data:`RELATIVE_TOLERANCE` when they differ or ``--tolerance``
     is given (mode ``tolerance``); the largest deviation is reported;
   * ``consistent``: a foreign policy (ONNX, TorchScript, Stable-Baselines3),
     whose float32 kernels frbench cannot make portable, whose episodes differ
     beyond that but whose successes pass the statistical check (verifies nothing);
   * ``failed``: anything else; every difference beyond the tier's allowance is listed.

   The processor of the record (its results' ``processor``, when recorded) and of
   this run are reported (`frbench.evaluation.provenance.processor_info`).

A record of another protocol version cannot be re-run by this frbench and does
not verify; nor does one whose policy file is missing or replaced.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frbench.errors import FrbenchError
from frbench.evaluation.provenance import frbench_info, library_versions, processor_info
from frbench.evaluation.runner import Cell, run_cell
from frbench.io import sha256_file
from frbench.leaderboard.policy_files import stored_problems
from frbench.policies.registry import BUILTIN_POLICIES, SHIPPED_CHECKPOINTS, shipped_checkpoint
from frbench.robots import get_robot
from frbench.robots.sim_urdf import sim_robot_file
from frbench.tasks.protocol import CONTROL_DT, PROTOCOL_VERSION, REPRODUCED_FROM, version_key

#: Relative tolerance on continuous episode metrics when library versions differ (mode ``tolerance``).
RELATIVE_TOLERANCE = 1e-3
#: Relative tolerance of the tier ``reproduced`` when the library versions are the record's (mode ``exact``):
#: far above the last bits a processor can change (1e-16 relative per operation) and far below any edit that
#: moves a score.
REPRODUCED_TOLERANCE = 1e-6
#: What a verification can show, best first (the module docstring).
TIERS = ("exact", "reproduced", "consistent", "failed")
#: The statistical check's level: a record is called inconsistent with its re-run episodes only when the
#: probability of so extreme a success count, were the record true, is below this (a false alarm at most once
#: in a thousand checks); above it the check says "consistent", which verifies nothing.
STATISTICAL_ALPHA = 1e-3
#: Fields that do not depend on the policy (the start draw): equal in every mode.
START_FIELDS = ("initial_pose", "start_redraws")
#: Episode fields that must be equal in both modes.
DISCRETE_FIELDS = ("initial_pose", "start_redraws", "success", "rolled_over", "diverged")
CELL_FIELDS = ("robot", "backend", "terrain", "level", "seed")


@dataclass
class Verification:
    """What :func:`verify` found; ``ok`` when nothing failed."""

    record_id: str
    protocol_version: str
    seed: int = 0
    policy: str = ""
    policy_kind: str = ""
    mode: str = "exact"
    sample: list[int] = field(default_factory=list)
    cells: int = 0
    notes: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    #: For a foreign policy whose episodes did not reproduce bit for bit: the statistical check's outcome.
    statistical: "StatisticalCheck | None" = None
    #: Every sampled episode bit-identical.
    identical: bool = False
    #: The relative tolerance of the tier ``reproduced`` in this mode.
    tolerance: float = REPRODUCED_TOLERANCE
    #: The largest relative deviation of a continuous metric, and where (``field, episode``).
    largest_deviation: float = 0.0
    deviation_at: str = ""
    #: The processor this verification ran on (`processor_info`).
    processor: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return bool(self.sample) and not self.failures

    @property
    def verified(self) -> bool:
        """Reproduced episode by episode (a statistical check that finds the record consistent verifies nothing)."""
        return self.ok and self.statistical is None

    @property
    def tier(self) -> str:
        """One of :data:`TIERS`."""
        if not self.ok:
            return "failed"
        if self.statistical is not None:
            return "consistent"
        return "exact" if self.identical else "reproduced"


@dataclass(frozen=True)
class StatisticalCheck:
    """The sampled episodes' re-run successes against the record's cells.

    Attributes:
        successes: re-run episodes that succeeded.
        expected: successes the record predicts: the sum of the sampled episodes' cell success rates.
        p_value: two-sided probability, were every re-run episode an independent draw with its cell's recorded
            success rate (a Poisson-binomial count), of a count no more likely than the observed one.
        consistent: ``p_value >= STATISTICAL_ALPHA``.
    """

    episodes: int
    successes: int
    expected: float
    p_value: float

    @property
    def consistent(self) -> bool:
        return self.p_value >= STATISTICAL_ALPHA


def poisson_binomial_p_value(rates: list[float], observed: int) -> float:
    """Two-sided p-value of ``observed`` successes of independent Bernoulli(rates): the total probability of the
    counts no more likely than it (exact, by convolution)."""
    pmf = np.array([1.0])
    for p in rates:
        pmf = np.convolve(pmf, [1.0 - p, p])
    return float(min(1.0, pmf[pmf <= pmf[observed] * (1 + 1e-9)].sum()))


def statistical_check(recorded: list[dict], fresh: list[dict], cell_rates: list[float]) -> StatisticalCheck:
    """`StatisticalCheck` of re-run episodes ``fresh`` (the recorded ones' order) with their cells' rates."""
    successes = sum(bool(e.get("success")) for e in fresh)
    return StatisticalCheck(len(recorded), successes, float(sum(cell_rates)),
                            poisson_binomial_p_value(cell_rates, successes))


def is_foreign(reference: str) -> bool:
    """Whether the policy runs through a layout adapter (ONNX, TorchScript, Stable-Baselines3): inference in
    another runtime's float32 kernels, which frbench cannot make processor-independent."""
    from frbench.evaluation.runner import _policy
    from frbench.policies.layout_policy import LayoutPolicy

    return isinstance(_policy(reference), LayoutPolicy)


def sample_indices(total: int, sample: int, seed: int) -> list[int]:
    """``min(sample, total)`` distinct episode indices from ``numpy.random.default_rng(seed)``, sorted."""
    if sample < 1:
        raise FrbenchError(f"--sample {sample}: expected at least 1 episode")
    if not 0 <= seed <= 2**32 - 1:
        raise FrbenchError(f"--seed {seed}: expected 0 to 4294967295")
    rng = np.random.default_rng(seed)
    return sorted(int(i) for i in rng.choice(total, size=min(sample, total), replace=False))


def _sha256(path: Path) -> str:
    return sha256_file(path)


def resolve_policy(record: dict, root: Path, report: Verification) -> str | None:
    """The policy reference to re-run (None after adding a failure); see the module doc for the order."""
    results = record["results"]
    attached = record.get("policy_file")
    recorded = results["policy"]["sha256"] or (attached or {}).get("sha256")
    if attached is not None:
        problems = stored_problems(root, attached)
        if problems:
            report.failures += problems
            return None
    if attached is not None and "file" in attached:  # else a shipped checkpoint, found below by its sha256
        report.policy_kind = "attached"
        path = root / attached["file"]
        requested = results["config"]["policy"]
        attribute = requested.rpartition(":")[2] if path.suffix == ".py" and ":" in requested else ""
        return f"{path}:{attribute}" if attribute else str(path)
    if recorded is not None:
        for name in SHIPPED_CHECKPOINTS:
            path = shipped_checkpoint(name)
            if path.is_file() and _sha256(path) == recorded:
                report.policy_kind = "shipped"
                return name
    name = results["policy"]["name"]
    if name in BUILTIN_POLICIES and results["config"]["policy"] == name:
        report.policy_kind = "built-in"
        commit = results["frbench"]["git_commit"]
        report.notes.append(f"policy {name!r} is code in frbench: re-run with this checkout's code (the record ran at "
                            f"commit {commit[:12]})")
        return name
    raise FrbenchError(
        f"record {record['id'][:12]}: its policy {name!r} is neither attached, shipped with frbench nor built in; "
        "nothing to re-run (attach it with `frbench submit RESULTS --policy-file FILE`)"
    )


def _same(key: str, a, b, exact: bool, tolerance: float) -> bool:
    if exact:
        return a == b and type(a) is type(b)
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))
    if key == "time_to_recover" and numbers:
        return abs(a - b) <= CONTROL_DT + 1e-9
    if key not in DISCRETE_FIELDS and isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=tolerance, abs_tol=1e-9)
    return a == b


def compare_episode(recorded: dict, fresh: dict, exact: bool, tolerance: float = RELATIVE_TOLERANCE) -> list[str]:
    """The fields where a re-run episode differs from the recorded one (``field recorded -> re-run``): any
    difference when ``exact``, else discrete outcomes, ``time_to_recover`` beyond one control period and
    continuous metrics beyond ``tolerance`` relative."""
    differences = []
    for key in sorted(set(recorded) | set(fresh)):
        a, b = recorded.get(key, "(absent)"), fresh.get(key, "(absent)")
        if not _same(key, a, b, exact, tolerance):
            differences.append(f"{key} {a!r} -> {b!r}")
    return differences


def largest_deviation(recorded: dict, fresh: dict) -> tuple[float, str]:
    """(largest relative deviation |a - b| / max(|a|, |b|) of the continuous metrics, its field); (0, "") if none."""
    found = (0.0, "")
    for key in sorted(recorded):
        a, b = recorded[key], fresh.get(key)
        if key in DISCRETE_FIELDS or key == "time_to_recover" or not (isinstance(a, float) and isinstance(b, float)):
            continue
        scale = max(abs(a), abs(b))
        deviation = abs(a - b) / scale if scale > 0 else 0.0
        if deviation > found[0]:
            found = (deviation, key)
    return found


def _describe(episode: dict) -> str:
    return " ".join(str(episode[k]) for k in CELL_FIELDS[:3]) + f" level {episode['level']} seed {episode['seed']} episode {episode['episode']}"


def reproducible(version: str) -> bool:
    """Whether this code reproduces the episodes of a record of protocol ``version``: from `REPRODUCED_FROM` up
    to the current protocol."""
    return version_key(REPRODUCED_FROM) <= version_key(version) <= version_key(PROTOCOL_VERSION)


def verify(record: dict, root: Path, *, sample: int = 8, seed: int = 0, tolerance: bool = False,
           progress=None) -> Verification:
    """Re-run ``sample`` of the (already checked) ``record``'s episodes and compare them."""
    results = record["results"]
    report = Verification(record["id"], results["protocol_version"], seed)
    episodes = results["episodes"]
    indices = sample_indices(len(episodes), sample, seed)
    if not reproducible(results["protocol_version"]):
        report.failures.append(
            f"the record ran under protocol {results['protocol_version']}, this frbench runs protocol {PROTOCOL_VERSION} "
            f"and reproduces episodes from {REPRODUCED_FROM} on: "
            f"its episodes cannot be reproduced here (verify it with frbench at commit {results['frbench']['git_commit'][:12]})"
        )
        return report
    reference = resolve_policy(record, root, report)
    if reference is None:
        return report
    report.policy = reference
    versions = library_versions()
    changed = {k: (v, versions.get(k)) for k, v in results["versions"].items() if versions.get(k) != v}
    report.mode = "tolerance" if tolerance or changed else "exact"
    report.tolerance = RELATIVE_TOLERANCE if report.mode == "tolerance" else REPRODUCED_TOLERANCE
    report.processor = processor_info()
    for name, (then, now) in sorted(changed.items()):
        report.notes.append(f"version of {name}: {then} in the record, {now} here")
    _note_robot_changes(results, report)
    by_cell: dict[tuple, list[dict]] = defaultdict(list)
    for index in indices:
        by_cell[tuple(episodes[index][k] for k in CELL_FIELDS)].append(episodes[index])
    started = time.monotonic()
    foreign = is_foreign(reference)
    rates = {tuple(c[k] for k in CELL_FIELDS): c["success_rate"] for c in results["cells"]}
    recorded, fresh_episodes, cell_rates, differing, identical = [], [], [], [], True
    for key, wanted in sorted(by_cell.items(), key=lambda item: tuple(map(str, item[0]))):
        fresh = run_cell(Cell(*key, results["config"]["episodes"]), reference, results["config"]["noise"],
                         joint_frame=results["policy"].get("joint_frame", "robot"),
                         protocol_version=results["protocol_version"])
        by_episode = {e["episode"]: e for e in fresh}
        for episode in wanted:
            again = by_episode.get(episode["episode"], {})
            recorded.append(episode)
            fresh_episodes.append(again)
            cell_rates.append(rates[key])
            identical = identical and not compare_episode(episode, again, exact=True)
            deviation, metric = largest_deviation(episode, again)
            if deviation > report.largest_deviation:
                report.largest_deviation, report.deviation_at = deviation, f"{metric}, {_describe(episode)}"
            differences = compare_episode(episode, again, exact=False, tolerance=report.tolerance)
            if differences:
                differing.append((episode, differences))
        if progress:
            progress(key)
    start_problems = [(e, d) for e, d in differing if any(d_.split()[0] in START_FIELDS for d_ in d)]
    if foreign and differing and not start_problems:
        report.notes.append(
            f"the policy runs in another runtime's float32 kernels (ONNX, TorchScript or Stable-Baselines3), whose "
            f"last bits depend on the processor: {len(differing)} of {len(recorded)} episodes differ, so the "
            "record cannot be verified bit for bit here; a statistical check of the successes follows instead")
        report.statistical = statistical_check(recorded, fresh_episodes, cell_rates)
        if not report.statistical.consistent:
            check = report.statistical
            report.failures.append(
                f"statistical check: {check.successes} of {check.episodes} re-run episodes succeeded where the record's "
                f"cells predict {check.expected:.2f} (p = {check.p_value:.2g} < {STATISTICAL_ALPHA:g})")
    else:
        report.failures += [f"{_describe(e)}: {'; '.join(d)}" for e, d in differing]
    report.identical = identical and not differing
    report.sample = indices
    report.cells = len(by_cell)
    report.notes.append(f"re-ran {len(by_cell)} cells in {time.monotonic() - started:.1f} s")
    return report


def _note_robot_changes(results: dict, report: Verification) -> None:
    """Note robots whose URDF differs from the one the record evaluated (its checksum)."""
    for name, entry in sorted(results["robots"].items()):
        sim = sim_robot_file(get_robot(name))
        if sim.source_sha256 != entry["urdf_sha256"]:
            report.notes.append(f"robot {name}: URDF sha256 {sim.source_sha256[:16]}... here, "
                                f"{entry['urdf_sha256'][:16]}... in the record")


def entry_of(report: Verification) -> dict:
    """The record's ``verifications`` item for a passed verification."""
    info = frbench_info()
    return {
        "verified": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "sample": len(report.sample), "cells": report.cells, "seed": report.seed, "mode": report.mode,
        "policy": report.policy_kind, "protocol_version": report.protocol_version,
        "frbench_commit": info["git_commit"], "frbench_dirty": info["git_dirty"],
        "tier": report.tier, **({"tolerance": report.tolerance} if report.tier == "reproduced" else {}),
        "largest_deviation": report.largest_deviation, "processor": report.processor,
    }
