"""``frbench policies``: the policies frbench can load, and the robots each supports."""

from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``policies`` to the CLI."""
    p = sub.add_parser("policies", help="list the available policies")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def policy_rows() -> list[dict]:
    """One row per policy: name, supported robots, checkpoint."""
    from frbench.policies.registry import load_policy, policy_names
    from frbench.robots import get_robot, robot_names

    specs = [get_robot(name) for name in robot_names()]
    rows = []
    for name in policy_names():
        policy = load_policy(name)
        rows.append(
            {
                "name": name,
                "robots": [spec.name for spec in specs if policy.supports(spec)],
                "checkpoint": str(policy.checkpoint) if getattr(policy, "checkpoint", None) else None,
                "description": (type(policy).__doc__ or "").strip().splitlines()[0] if type(policy).__doc__ else "",
            }
        )
    return rows


def run(args) -> int:
    """Print the policy table (or JSON)."""
    rows = policy_rows()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for row in rows:
        print(f"{row['name']:<10} robots: {', '.join(row['robots'])}")
        if row["description"]:
            print(f"{'':<10} {row['description']}")
    return 0
