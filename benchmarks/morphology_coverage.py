"""Where the benchmark's quadrupeds lie relative to FR-Net's morphology table and training gain ranges.

For each robot, measures the table's 14 quantities from its URDF (`frbench.robots.morphology_fit`) and prints
each value [kg or m], the table range, and whether it lies inside, below or above it, with the distance outside
as a fraction of the range's width; then the robot's Kp [N·m/rad] and Kd [N·m·s/rad] against the training gain
ranges (`frbench.training.config.TRAINING_GAIN_RANGES`). The last lines count, per robot, the fields outside.

Run: ``python benchmarks/morphology_coverage.py`` (all five quadrupeds), or test a widened table with
``python benchmarks/morphology_coverage.py --ranges trunk_length=0.37,0.9 hip_length=0.03,0.12``.
"""

from __future__ import annotations

import argparse
import sys

from frbench.errors import FrbenchError
from frbench.robots import get_robot
from frbench.robots.morphology import morphology_ranges
from frbench.robots.morphology_fit import measure_morphology
from frbench.training.config import TRAINING_GAIN_RANGES

QUADRUPEDS = ("go2", "go1", "aliengo", "spot_like", "lite3_like")


def placement(value: float | None, low: float, high: float) -> tuple[str, float]:
    """("inside" | "below" | "above" | "unmeasured", distance outside as a fraction of high − low)."""
    if value is None:
        return "unmeasured", 0.0
    width = high - low if high > low else 1.0
    if value < low:
        return "below", (low - value) / width
    if value > high:
        return "above", (value - high) / width
    return "inside", 0.0


def parse_ranges(items: list[str]) -> dict[str, tuple[float, float]]:
    """``FIELD=LOW,HIGH`` strings → the table with those rows replaced; ValueError naming a bad item."""
    overrides = {}
    for item in items:
        name, sep, bounds = item.partition("=")
        parts = bounds.split(",")
        if not sep or len(parts) != 2:
            raise ValueError(f"--ranges {item!r}: expected FIELD=LOW,HIGH")
        try:
            overrides[name] = (float(parts[0]), float(parts[1]))
        except ValueError:
            raise ValueError(f"--ranges {item!r}: LOW and HIGH must be numbers") from None
    return morphology_ranges(overrides)


def _line(name: str, value: float | None, low: float, high: float) -> tuple[str, str, float]:
    where, distance = placement(value, low, high)
    shown = "n/a" if value is None else f"{value:.4g}"
    note = f" by {distance:.2f} of the range" if where in ("below", "above") else ""
    return f"  {name:<13} {shown:>8}   [{low:g}, {high:g}]   {where}{note}", where, distance


def report(robot: str, ranges: dict[str, tuple[float, float]]) -> str:
    """Print one robot's table; return its summary line."""
    spec = get_robot(robot)
    fit = measure_morphology(spec)
    print(f"{robot} (foot mass {fit.foot_mass:.3f} kg, not a table field)")
    outside = []
    for name, (low, high) in ranges.items():
        text, where, distance = _line(name, fit.values[name], low, high)
        print(f"{text}   ({fit.sources[name]})")
        if where in ("below", "above"):
            outside.append(f"{name} {where} {distance:.2f}")
        elif where == "unmeasured":
            outside.append(f"{name} unmeasured")
    gains = []
    for gain, values in (("kp", spec.kp), ("kd", spec.kd)):
        low, high = TRAINING_GAIN_RANGES[gain]
        value = min(values) if min(values) < low else max(values)
        text, where, distance = _line(gain, value, low, high)
        print(text + ("" if min(values) == max(values) else f"   (per joint {min(values):g}-{max(values):g})"))
        gains.append(f"{gain} {value:g} {where}" + (f" {distance:.2f}" if where != "inside" else ""))
    n_out = sum(1 for item in outside if "unmeasured" not in item)
    return f"{robot}: {n_out}/14 fields outside ({'; '.join(outside) or 'none'}); {', '.join(gains)}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(QUADRUPEDS), help="quadruped names or URDF specs")
    parser.add_argument("--ranges", nargs="+", default=[], metavar="FIELD=LOW,HIGH",
                        help="replace rows of the morphology table [kg or m]")
    args = parser.parse_args()
    try:
        ranges = parse_ranges(args.ranges)
        summaries = [report(robot, ranges) for robot in args.robots]
    except (ValueError, FrbenchError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    print("\nfields outside the table (distance as a fraction of the range width):")
    for line in summaries:
        print(line)


if __name__ == "__main__":
    main()
