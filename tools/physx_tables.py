"""PhysX beside MuJoCo and PyBullet: the Markdown tables of docs/physx.md, from results of protocol 1.3 on.

Reads ``frbench evaluate`` results files, or with ``--board`` the main-board records of one protocol version
(``--protocol``, the current one by default; records superseded by a re-score left out, as the board leaves them
out), and prints one of:

* ``--family-levels`` (one results file): success per terrain family x level x simulator over the standard
  grid's cells of that family and level;
* ``--per-record``: for each results file or record, the standard grid's success per simulator, the three
  signed pairwise gaps (first − second, points) and the simulator it scores lowest in; then one line on the
  learned records (``results.policy.sha256`` set): the mean of PyBullet − PhysX, in how many its interval lies
  wholly on either side of 0, i.e. whether a policy trained in MuJoCo loses more in PhysX than in PyBullet.

Every success is a mean of cell success rates with its 95 % stratified-bootstrap interval, computed by
`frbench.leaderboard.scores` as the board computes it::

    zcat leaderboard/records/2a4e25df0d24*.json.gz | jq .results > /tmp/scripted.json   # a board record's results
    python tools/physx_tables.py --family-levels /tmp/scripted.json
    python tools/physx_tables.py --per-record /tmp/scripted.json
    python tools/physx_tables.py --per-record --board leaderboard --protocol 1.4
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from generalisation_table import markdown, mean_success, with_interval  # noqa: E402

from frbench.errors import FrbenchError  # noqa: E402

#: The grid simulators of protocol 1.3 on, in the tables' column order.
SIMULATORS = ("mujoco", "pybullet", "physx")
LABELS = {"mujoco": "MuJoCo", "pybullet": "PyBullet", "physx": "PhysX"}
#: The signed pairwise gaps of `frbench.leaderboard.scores.score_intervals`, first − second.
PAIRS = ("mujoco-pybullet", "mujoco-physx", "pybullet-physx")


def standard_cells(results: Mapping, label: str) -> list[Mapping]:
    """The standard grid's cells of ``results`` (`frbench.leaderboard.scores.scored_cells`); a `FrbenchError`
    naming ``label`` when a simulator of `SIMULATORS` has none."""
    from frbench.leaderboard.scores import scored_cells

    cells = scored_cells(results["cells"], "main")
    missing = [s for s in SIMULATORS if not any(c["backend"] == s for c in cells)]
    if missing:
        raise FrbenchError(f"{label}: no standard-grid cells in {', '.join(missing)} (protocol 1.3 results needed)")
    return cells


def family_level_rows(cells: Sequence[Mapping], levels: Sequence[int]) -> list[list[str]]:
    """One row per terrain family and level of ``levels`` found in ``cells``: the mean cell success per simulator
    with the 95 % interval of `score_intervals` over that family and level's cells."""
    from frbench.leaderboard.scores import score_intervals
    from frbench.tasks.protocol import STANDARD_TERRAINS

    rows = []
    for family in STANDARD_TERRAINS:
        for level in levels:
            chosen = [c for c in cells if c["terrain"] == family and c["level"] == level]
            if not chosen:
                continue
            intervals = score_intervals(chosen)["per_backend"]
            rows.append([family, str(level), *(
                with_interval([mean_success([c for c in chosen if c["backend"] == s]), *intervals[s]])
                for s in SIMULATORS)])
    return rows


def family_level_table(results: Mapping, label: str, levels: Sequence[int]) -> str:
    """`family_level_rows` of one results file as a Markdown table."""
    rows = family_level_rows(standard_cells(results, label), levels)
    if not rows:
        raise FrbenchError(f"{label}: no standard-grid cells at levels {','.join(map(str, levels))}")
    return markdown(["family", "level", *(LABELS[s] for s in SIMULATORS)], rows)


def record_summary(results: Mapping, label: str) -> dict:
    """The standard grid's numbers of one record: ``per_simulator`` (name → [point, low, high], fractions),
    ``gaps`` (`PAIRS` → [point, low, high]), ``lowest`` (the simulator of lowest success) and ``learned``."""
    from frbench.leaderboard.scores import record_scores, score_intervals

    cells = standard_cells(results, label)
    points = record_scores(cells, "main")["per_backend"]
    intervals = score_intervals(cells)
    per_simulator = {s: [points[s], *intervals["per_backend"][s]] for s in SIMULATORS}
    return {"label": label, "per_simulator": per_simulator, "gaps": {p: intervals["signed_gaps"][p] for p in PAIRS},
            "lowest": min(SIMULATORS, key=lambda s: points[s]),
            "learned": bool((results.get("policy") or {}).get("sha256"))}


def per_record_table(summaries: Sequence[Mapping]) -> str:
    """The per-record table and, below it, the line on the learned records (`physx_against_pybullet`)."""
    header = ["record", *LABELS.values(), *(f"{LABELS[p.split('-')[0]]} − {LABELS[p.split('-')[1]]} [points]"
                                            for p in PAIRS), "lowest"]
    rows = [[f"`{s['label']}`", *(with_interval(s["per_simulator"][sim]) for sim in SIMULATORS),
             *(with_interval(s["gaps"][p], signed=True) for p in PAIRS), LABELS[s["lowest"]]] for s in summaries]
    return markdown(header, rows) + "\n\n" + physx_against_pybullet(summaries)


def physx_against_pybullet(summaries: Sequence[Mapping]) -> str:
    """Whether a policy trained in MuJoCo loses more in PhysX than in PyBullet, from the learned records: the mean
    over them of PyBullet − PhysX (points), the records whose 95 % interval of that gap lies wholly above 0 (PhysX
    lower) or wholly below 0 (PhysX higher), and the answer: a direction only when the records that separate the
    two engines all point one way."""
    learned = [s for s in summaries if s["learned"]]
    if not learned:
        return "Learned records: none among these, so no PhysX − PyBullet comparison."
    gaps = [s["gaps"]["pybullet-physx"] for s in learned]
    mean = 100 * math.fsum(g[0] for g in gaps) / len(gaps)
    lower, higher = sum(g[1] > 0 for g in gaps), sum(g[2] < 0 for g in gaps)
    if lower and not higher and mean > 0:
        answer = "loses more in PhysX than in PyBullet"
    elif higher and not lower and mean < 0:
        answer = "loses less in PhysX than in PyBullet"
    else:
        answer = "does not lose consistently more in either"
    return (f"Learned records ({len(learned)}): PyBullet − PhysX = {mean:+.1f} points on average; PhysX is lower "
            f"beyond its interval in {lower} and higher in {higher} of {len(learned)}: a policy trained in MuJoCo "
            f"{answer}.")


def load_inputs(args: argparse.Namespace) -> list[tuple[str, Mapping]]:
    """(label, results) for each results file of ``args.files`` (label: its folder for ``results.json``, else its
    stem), or for each main-board record of ``args.protocol`` under ``args.board`` (label: its name)."""
    if args.board is None:
        from frbench.leaderboard.jsonfile import read_json_object

        return [(p.parent.name if p.name == "results.json" else p.name.split(".")[0], read_json_object(p))
                for p in args.files]
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.leaderboard.sections import superseded

    every = load_records(args.board)
    replaced = superseded(every)
    records = [r for r in every if r["track"] == "main" and r["results"]["protocol_version"] == args.protocol
               and r["id"] not in replaced]
    if not records:
        raise FrbenchError(f"{args.board}: no main-board record of protocol {args.protocol}")
    records.sort(key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"]))
    return [(r["submission"]["name"], r["results"]) for r in records]


def parse_levels(text: str) -> list[int]:
    """``1,5`` → [1, 5]; an `argparse.ArgumentTypeError` for anything else."""
    try:
        levels = [int(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"levels must be comma-separated integers, got {text!r}") from None
    return levels


def main(argv: Sequence[str] | None = None) -> int:
    from frbench.tasks.protocol import PROTOCOL_VERSION

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    table = parser.add_mutually_exclusive_group(required=True)
    table.add_argument("--family-levels", action="store_true", help="success per family x level x simulator")
    table.add_argument("--per-record", action="store_true", help="success and gaps per record")
    parser.add_argument("files", nargs="*", type=Path, help="results files (protocol 1.3 on)")
    parser.add_argument("--board", type=Path, help="a leaderboard folder: read its main-board records instead")
    parser.add_argument("--protocol", default=PROTOCOL_VERSION,
                        help="with --board: the records' protocol (default: the current one)")
    parser.add_argument("--levels", type=parse_levels, default=[1, 5], help="with --family-levels (default 1,5)")
    args = parser.parse_args(argv)
    if (args.board is None) == (not args.files):
        parser.error("give results files or --board (one of the two)")
    try:
        inputs = load_inputs(args)
        if args.family_levels:
            if len(inputs) != 1:
                parser.error("--family-levels takes one results file or record")
            print(family_level_table(inputs[0][1], inputs[0][0], args.levels))
        else:
            print(per_record_table([record_summary(results, label) for label, results in inputs]))
    except FrbenchError as exc:
        print(f"physx_tables: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
