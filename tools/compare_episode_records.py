"""Compare two `frbench evaluate` results files, ignoring provenance (versions, commit, dates, timings).

    python tools/compare_episode_records.py BEFORE.json AFTER.json

Prints ``identical`` and exits 0 when the episode records, cells and summaries are equal (floats compared
exactly); otherwise names the first differing record and exits 1.
"""

from __future__ import annotations

import json
import sys

#: The parts of a results file that the episodes determine (the rest is provenance).
COMPARED = ("episodes", "cells", "summary", "sim_to_sim")
#: Keys inside records that are provenance or timing, not outcome.
IGNORED_KEYS = {"wall_s", "created", "elapsed_s", "seconds"}


def _strip(value):
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in IGNORED_KEYS}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def main(argv=None) -> int:
    before_path, after_path = (argv or sys.argv[1:])[:2]
    before, after = json.load(open(before_path)), json.load(open(after_path))
    for part in COMPARED:
        a, b = _strip(before.get(part)), _strip(after.get(part))
        if a != b:
            rows = [i for i, (x, y) in enumerate(zip(a or [], b or [])) if x != y]
            print(f"DIFFERENT: {part} (first differing row {rows[0] if rows else 'length'})")
            return 1
    print(f"identical: {len(before['episodes'])} episodes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
