"""``frbench verify RECORD [--sample N] [--seed S]``: re-run a sample of a leaderboard record's episodes.

RECORD is a record file (``leaderboard/records/<id>.json.gz``) or a record id (or
its first 8+ hex digits) in the leaderboard folder. The record is checked like
``frbench leaderboard --check`` does; then ``--sample`` episodes drawn with
``--seed`` are re-run with the record's policy and compared episode by episode
(`frbench.leaderboard.verify`), and the tier reached is printed: exact (bit-identical),
reproduced (every outcome equal, every metric within the stated relative tolerance;
the largest deviation is printed), consistent (a foreign policy's successes pass the
statistical check) or failed. The processors that made the record (when its results
name it) and that verified it are printed. Exit 0: exact or reproduced; 1:
failed: a mismatch (the differences are listed), a replaced or missing policy file, or
a record of another protocol version; 2: bad input. A foreign policy (ONNX,
TorchScript, Stable-Baselines3) whose episodes differ on this processor gets a
statistical check of its successes instead: exit 1 only when they are
inconsistent with the record (p < 0.001), else exit 0 saying that the record is
consistent but not verified. ``--save`` adds a passed
verification to the record, which the board and page then mark.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``verify`` to the CLI."""
    p = sub.add_parser(
        "verify", help="re-run a sample of a leaderboard record's episodes and compare them",
        description="Re-run a seeded random sample of a record's episodes from its provenance with its policy and compare "
                    "them episode by episode: bit-identical where the library versions match, else within the stated "
                    "tolerance. Exit 0: reproduced; 1: a mismatch; 2: bad input.")
    p.add_argument("record", metavar="RECORD", help="a record file, or a record id (at least its first 8 hex digits)")
    p.add_argument("--sample", type=int, default=8, help="episodes to re-run (default 8; each runs inside its whole cell)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sample's random draw (default 0)")
    p.add_argument("--tolerance", action="store_true",
                   help="compare within the tolerance even where the versions match (e.g. a record made on other hardware)")
    p.add_argument("--save", action="store_true", help="on a pass, add the verification to the record and regenerate the board")
    p.add_argument("--root", default=None, help="leaderboard folder (default: the record's, else see `frbench leaderboard --help`)")
    p.set_defaults(func=run)


def _locate(text: str, root_option: str | None) -> tuple[Path, Path]:
    """(record file, leaderboard folder) for RECORD."""
    from frbench.leaderboard.paths import RECORDS, resolve_root
    from frbench.leaderboard.records import ID_PREFIX_RE, find_record

    path = Path(text)
    if ID_PREFIX_RE.match(text) and not path.exists():
        root = resolve_root(root_option)
        return find_record(root, text), root
    if root_option is not None:
        return path, resolve_root(root_option)
    return path, (path.parent.parent if path.parent.name == RECORDS else path.parent)


def run(args: argparse.Namespace) -> int:
    from frbench.leaderboard.board import add_verification
    from frbench.leaderboard.records import load_record
    from frbench.evaluation.provenance import processor_label
    from frbench.leaderboard.verify import STATISTICAL_ALPHA, entry_of, verify

    path, root = _locate(args.record, args.root)
    record = load_record(path)
    results = record["results"]
    short = record["id"][:12]
    total = len(results["episodes"])
    print(f"record {short} ({record['submission']['name']}, protocol {results['protocol_version']}, {total} episodes)")
    report = verify(record, root, sample=args.sample, seed=args.seed, tolerance=args.tolerance,
                    progress=lambda key: print(f"  re-ran cell {' '.join(map(str, key))}", file=sys.stderr))
    if report.policy:
        print(f"policy: {report.policy_kind} {report.policy}")
    for note in report.notes:
        print(f"note: {note}")
    print(f"processor: the record's {processor_label(results.get('processor'))}; "
          f"this run's {processor_label(report.processor)}")
    if report.sample:
        how = ("bit-identical first (the record's library versions are these)" if report.mode == "exact" else
               "within tolerance (other library versions)")
        print(f"sample: {len(report.sample)} of {total} episodes (seed {args.seed}) in {report.cells} cells, compared {how}; "
              f"tier reproduced: discrete outcomes equal, time_to_recover within one control period, other metrics "
              f"within {report.tolerance:g} relative")
        where = f" ({report.deviation_at})" if report.deviation_at else ""
        print(f"largest deviation of a metric: {report.largest_deviation:.3g} relative{where}")
    for failure in report.failures:
        print(f"mismatch: {failure}")
    check = report.statistical
    if check is not None:
        print(f"statistical check: {check.successes} of {check.episodes} re-run episodes succeeded; the record's cells "
              f"predict {check.expected:.2f} (two-sided p = {check.p_value:.3g}; inconsistent below {STATISTICAL_ALPHA:g})")
    if not report.ok:
        print(f"frbench verify: record {short} does NOT verify, tier failed ({len(report.failures)} problem(s) above)")
        return 1
    if check is not None:
        print(f"frbench verify: record {short}, tier consistent: consistent with its re-run episodes but NOT verified: a foreign "
              f"policy's episodes differ by processor, and {check.episodes} episodes cannot confirm a record")
        if args.save:
            print("frbench verify: --save records only verifications; nothing written")
        return 0
    how = "bit for bit" if report.tier == "exact" else f"within {report.tolerance:g} relative"
    print(f"frbench verify: record {short} verified, tier {report.tier}: {len(report.sample)} of {len(report.sample)} "
          f"sampled episodes reproduced {how}")
    if args.save:
        add_verification(root, path, entry_of(report))
        print(f"wrote the verification into {path}; commit it with {root / 'README.md'} and {root / 'index.html'}")
    return 0
