"""``frbench policies``: the policies frbench can load, and the robots each supports.

Listing loads no network: a shipped checkpoint is described from the config stored in it (read without
torch, `frbench.policies.registry.checkpoint_metadata`); built-in and plugin policies from their docstring.
"""

from __future__ import annotations

import argparse
import json


#: What ``--policy`` accepts (``frbench policies --help``).
POLICY_KINDS = """List the policies frbench ships and the installed plugins. `frbench evaluate --policy` also takes:

  NAME                  a listed policy (built in, shipped checkpoint or plugin)
  run/ or policy.pt     a checkpoint of `frbench train`
  my.onnx               an ONNX network (onnxruntime), e.g. `frbench export`'s or a torch.onnx.export of your own
  my.pt                 a TorchScript module (torch.jit.save)
  model.zip             a Stable-Baselines3 model trained on frbench/FallRecovery-v1 (pip install 'frbench[sb3]')
  module:attr           a Python policy: a class, object or function with act(obs) [and reset(info)]
  path/to/file.py:attr  the same, from a file

ONNX, TorchScript and Python policies read the observation layout of `frbench spec --robot NAME`, or the one in
their sidecar <file>.json or `frbench evaluate --spec FILE`. See docs/own-policy.md."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``policies`` to the CLI."""
    p = sub.add_parser("policies", help="list the available policies", description=POLICY_KINDS,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def _checkpoint_supports(metadata: dict, spec) -> bool:
    """The rule of `LearnedPolicy.supports` from a checkpoint's metadata (base controllers are checked by name)."""
    from frbench.policies.registry import load_policy

    if spec.kind != metadata.get("robot_kind", "quadruped") or spec.n_joints != int(metadata.get("num_actions", -1)):
        return False
    base = json.loads(metadata.get("config_json") or "{}").get("env", {}).get("base_controller")
    return base is None or load_policy(base).supports(spec)


def policy_rows() -> list[dict]:
    """One row per policy: name, supported robots, checkpoint, description (and, for checkpoints, method,
    env steps and training time [s])."""
    from frbench.policies.registry import (
        SHIPPED_CHECKPOINTS,
        checkpoint_metadata,
        describe_checkpoint,
        load_policy,
        policy_names,
        shipped_checkpoint,
    )
    from frbench.robots import get_robot, robot_names

    specs = [get_robot(name) for name in robot_names()]
    rows = []
    for name in policy_names():
        if name in SHIPPED_CHECKPOINTS:
            path = shipped_checkpoint(name)
            metadata = checkpoint_metadata(path)
            rows.append({"name": name, "robots": [s.name for s in specs if _checkpoint_supports(metadata, s)],
                         "checkpoint": str(path), "description": describe_checkpoint(metadata),
                         "method": metadata.get("method"), "env_steps": metadata.get("env_steps"),
                         "training_s": metadata.get("wall_s")})
            continue
        policy = load_policy(name)
        doc = (type(policy).__doc__ or "").strip()
        rows.append({"name": name, "robots": [spec.name for spec in specs if policy.supports(spec)],
                     "checkpoint": str(policy.checkpoint) if getattr(policy, "checkpoint", None) else None,
                     "description": doc.splitlines()[0] if doc else ""})
    return rows


def run(args) -> int:
    """Print the policy table (or JSON)."""
    rows = policy_rows()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    width = max(len(row["name"]) for row in rows) + 2
    for row in rows:
        print(f"{row['name']:<{width}}robots: {', '.join(row['robots'])}")
        if row["description"]:
            print(f"{'':<{width}}{row['description']}")
    return 0
