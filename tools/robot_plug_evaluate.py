"""Evaluation of every quadruped of the robot-plug table by one or more policies, through the CLI.

For each file and policy it runs, one after the other::

    frbench evaluate --policy POLICY --robots PATH --terrains flat --levels 1 --seeds 0 --episodes 8

and prints the successes per simulator (or the error).

    PYTHONPATH=$PWD python tools/robot_plug_evaluate.py [--only SUBSTRING] [--policies scripted,frnet]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from robot_plug_table import QUADRUPEDS, resolve  # noqa: E402


def evaluate(path: str, policy: str, episodes: int, backends: str = "mujoco,pybullet") -> dict:
    """Run `frbench evaluate` on one robot; success rate per backend or the error."""
    out = Path(tempfile.mkdtemp(prefix="frbench-plug-eval-")) / "results.json"
    command = [sys.executable, "-m", "frbench.cli", "evaluate", "--policy", policy, "--robots", path, "--terrains", "flat",
               "--levels", "1", "--seeds", "0", "--episodes", str(episodes), "--backends", backends, "--jobs", "1", "--out", str(out)]
    started = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True)
    row = {"rc": run.returncode, "seconds": round(time.perf_counter() - started, 1)}
    if run.returncode != 0:
        row["error"] = run.stderr.strip().splitlines()[-1] if run.stderr.strip() else ""
        return row
    results = json.loads(out.read_text())
    for cell in results["cells"]:
        row[cell["backend"]] = f"{cell['successes']}/{cell['episodes']}"
    row["check_ok"] = next(iter(results["robots"].values())).get("check", {}).get("ok")
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="")
    parser.add_argument("--policies", default="scripted", help="comma-separated policies (default: scripted)")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per simulator (default: 8)")
    parser.add_argument("--skip", default="pb:laikago/laikago.urdf,pb:mini_cheetah/mini_cheetah.urdf",
                        help="files left out (refused without a sidecar)")
    args = parser.parse_args()
    skip = set(args.skip.split(","))
    for entry in QUADRUPEDS:
        if args.only not in entry or entry in skip:
            continue
        row = {"file": entry}
        for policy in args.policies.split(","):
            row[policy] = evaluate(resolve(entry), policy, args.episodes)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
