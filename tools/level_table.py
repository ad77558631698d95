"""Success per family and level with 95 % Wilson intervals, and whether it is non-increasing L1 → L5 → L10.

    PYTHONPATH=. python tools/level_table.py results/scripted.json [--robot go2] [--markdown]

"Non-increasing within the intervals": a level fails the check only when its Wilson interval lies wholly
above the previous level's (the data then show it easier). Also prints, per family and simulator, the
level-1 success against the protocol's target (the scripted controller at least 90 % on Go2).
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

from frbench.evaluation.intervals import wilson_interval


def table(results: dict, robot: str) -> dict:
    """(terrain, backend) -> {level: (successes, episodes)} for ``robot``."""
    counts: dict = defaultdict(lambda: defaultdict(lambda: [0, 0]))
    for cell in results["cells"]:
        if cell["robot"] == robot:
            entry = counts[(cell["terrain"], cell["backend"])][cell["level"]]
            entry[0] += cell["successes"]
            entry[1] += cell["episodes"]
    return counts


def monotone(levels: dict) -> bool:
    """Whether no level's Wilson interval lies wholly above the previous level's."""
    ordered = [wilson_interval(*levels[level]) for level in sorted(levels)]
    return all(later[0] <= earlier[1] for earlier, later in zip(ordered, ordered[1:]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="+")
    parser.add_argument("--robot", default="go2")
    args = parser.parse_args()
    for path in args.results:
        results = json.load(open(path))
        counts = table(results, args.robot)
        backends = sorted({b for _, b in counts})
        levels = sorted({lv for v in counts.values() for lv in v})
        print(f"\n{results['policy']['name']} on {args.robot}, protocol {results['protocol_version']} ({path})\n")
        print("| family | " + " | ".join(f"L{lv} {b}" for b in backends for lv in levels) + " | non-increasing |")
        print("|---|" + "---|" * (len(backends) * len(levels) + 1))
        for family in dict.fromkeys(t for t, _ in sorted(counts, key=lambda k: k[0])):
            row, ok = [], []
            for b in backends:
                for lv in levels:
                    k, n = counts[(family, b)][lv]
                    low, high = wilson_interval(k, n)
                    row.append(f"{k}/{n} {100 * k / n:.0f} % ({100 * low:.0f}–{100 * high:.0f})")
                ok.append(f"{b}: {'yes' if monotone(counts[(family, b)]) else 'NO'}")
            print(f"| {family} | " + " | ".join(row) + " | " + ", ".join(ok) + " |")


if __name__ == "__main__":
    main()
