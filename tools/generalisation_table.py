"""The generalisation table of docs/results.md: standard against unseen success for every main-board record.

Reads the leaderboard's records of one protocol version's main board (default: the current protocol) and prints
one Markdown row per record: the standard grid's overall success, the matched standard cells (the same families
and levels as the unseen grid, `frbench.leaderboard.scores.matched_standard_cells`), the unseen grid, their gap
(matched − unseen) with 95 % stratified-bootstrap intervals, and the matched / unseen means per simulator.
With ``--standard`` it prints the standard grid's table instead: each record's overall and per-family success
beside the overall success of the record of the same name under ``--against`` (the protocol it was re-scored
from). Every number is computed by `frbench.leaderboard.scores`, as the board computes it::

    python tools/generalisation_table.py                 # the current protocol's main board
    python tools/generalisation_table.py --standard --against 1.1
    python tools/generalisation_table.py --per-robot
    python tools/generalisation_table.py --per-robot --superseded   # the same in each robot's own joint frame

Records superseded by a re-score in the canonical joint frame (`frbench.leaderboard.render.superseded`) are left
out, as the board leaves them out of its ranking; ``--superseded`` prints them alone.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def percent(value: float) -> str:
    return f"{100 * value:.1f}"


def with_interval(triple: Sequence[float], signed: bool = False) -> str:
    """``[point, low, high]`` (fractions) as ``point [low, high]`` in percent (points when ``signed``)."""
    point, low, high = (100 * v for v in triple)
    if signed:
        return f"{point:+.1f} [{low:+.1f}, {high:+.1f}]"
    return f"{point:.1f} % [{low:.1f}, {high:.1f}]"


def mean_success(cells: Sequence[Mapping]) -> float:
    """Mean cell success rate (the board's score) of ``cells``."""
    return sum(c["successes"] / c["episodes"] for c in cells) / len(cells)


def row(record: Mapping) -> list[str]:
    """The table's cells for one main-board record."""
    from frbench.leaderboard.scores import (generalisation, matched_standard_cells, score_intervals, scored_cells,
                                            unseen_cells)

    cells = record["results"]["cells"]
    overall = [record["scores"]["overall"], *score_intervals(scored_cells(cells, "main"))["overall"]]
    general = generalisation(cells, "main")
    per_backend = []
    for backend in ("mujoco", "pybullet"):
        matched = [c for c in matched_standard_cells(cells) if c["backend"] == backend]
        unseen = [c for c in unseen_cells(cells) if c["backend"] == backend]
        per_backend.append(f"{percent(mean_success(matched))} / {percent(mean_success(unseen))} %")
    humanoids = "n/a" if general["humanoids"] is None else with_interval(general["humanoids"])
    return [f"`{record['submission']['name']}`", with_interval(overall), with_interval(general["matched"]),
            with_interval(general["unseen"]), with_interval(general["gap"], signed=True), *per_backend, humanoids]


def standard_row(record: Mapping, earlier: Mapping | None) -> list[str]:
    """The standard grid's cells for one record (its board scores, `frbench.leaderboard.scores.record_scores`), and
    the overall success of ``earlier`` (same name, the protocol it was re-scored from; "-" if none)."""
    from frbench.leaderboard.scores import score_intervals, scored_cells

    standard = scored_cells(record["results"]["cells"], "main")
    scores = record["scores"]
    overall = [scores["overall"], *score_intervals(standard)["overall"]]
    before = "-" if earlier is None else percent(earlier["scores"]["overall"]) + " %"
    up, episodes = sum(c["successes"] for c in standard), sum(c["episodes"] for c in standard)
    return [f"`{record['submission']['name']}`", "**" + with_interval(overall) + "**", before,
            *(percent(scores["per_family"][f]) + " %" for f in FAMILIES), f"{up} / {episodes}"]


FAMILIES = ("flat", "stairs", "gaps", "beams")


def table(records: Sequence[Mapping]) -> str:
    header = ["record", "standard", "matched std", "unseen", "matched − unseen [points]",
              "MuJoCo matched / unseen", "PyBullet matched / unseen", "humanoids"]
    return markdown(header, [row(r) for r in records])


def standard_table(records: Sequence[Mapping], earlier: Mapping[str, Mapping], against: str) -> str:
    header = ["record", "overall", f"overall ({against})", *FAMILIES, "episodes up"]
    return markdown(header, [standard_row(r, earlier.get(r["submission"]["name"])) for r in records])


def per_robot_table(records: Sequence[Mapping]) -> str:
    """Mean success (percent) of each record on each robot of the unseen grid."""
    from frbench.leaderboard.scores import unseen_cells

    robots = sorted({c["robot"] for c in unseen_cells(records[0]["results"]["cells"])})
    rows = []
    for record in records:
        cells = unseen_cells(record["results"]["cells"])
        rows.append([f"`{record['submission']['name']}`",
                     *(f"{100 * mean_success([c for c in cells if c['robot'] == robot]):.0f}" for robot in robots)])
    return markdown(["record", *robots], rows)


def markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows])


def main(argv: Sequence[str] | None = None) -> int:
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.tasks.protocol import PROTOCOL_VERSION

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=ROOT / "leaderboard", help="leaderboard folder")
    parser.add_argument("--protocol", default=PROTOCOL_VERSION, help="protocol version (default: the current one)")
    parser.add_argument("--standard", action="store_true", help="print the standard grid's table")
    parser.add_argument("--per-robot", action="store_true", help="print the success per unseen robot")
    parser.add_argument("--against", default="1.1", help="with --standard: the protocol to compare with (default 1.1)")
    parser.add_argument("--superseded", action="store_true",
                        help="the records a canonical-joint-frame re-score superseded (the robot's frame) instead")
    args = parser.parse_args(argv)
    from frbench.leaderboard.render import superseded

    every = load_records(args.root)
    replaced = superseded(every)
    records = [r for r in every if r["track"] == "main" and r["results"]["protocol_version"] == args.protocol
               and (r["id"] in replaced) == args.superseded]
    records.sort(key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"]))
    if args.standard:
        earlier = {r["submission"]["name"]: r for r in every
                   if r["results"]["protocol_version"] == args.against and r["track"] == "main"}
        print(standard_table(records, earlier, args.against))
    elif args.per_robot:
        print(per_robot_table(records))
    else:
        print(table(records))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
