"""``frbench export``: a trained policy as ONNX (estimator included)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``export`` to the CLI."""
    p = sub.add_parser("export", help="export a trained policy to ONNX (runs without frbench)")
    p.add_argument("--policy", required=True, help="run folder, policy.pt or shipped name")
    p.add_argument("--out", type=Path, required=True, help="output .onnx (a <file>.onnx.json sidecar is written beside it)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Export and say where."""
    from frbench.policies.export import export_onnx, sidecar_path

    path = export_onnx(args.policy, args.out)
    print(f"wrote {path} and {sidecar_path(path)}")
    return 0
