"""Average the actor weights of several policy snapshots of one training run into one policy checkpoint.

Stochastic weight averaging (Izmailov et al., UAI 2018) over the snapshots a run writes every ~1.1 M env steps
(``OUT/seed<S>/snapshots/policy_<env steps>.pt``, `frbench.training.run.SNAPSHOT_DIR`): every floating-point
tensor of ``actor_state_dict`` (network weights, the observation normaliser's statistics, the action std) is the
plain mean over the snapshots; everything else is the last snapshot's. The result loads like any frbench policy
checkpoint (``frbench evaluate --policy OUT.pt``)::

    python tools/average_snapshots.py runs/kickstart-floor/seed1/snapshots/policy_{10002432,11108352,12005376}.pt \
        --out runs/swa/seed1-10-12m.pt

Snapshots of different methods, or with different actor tensors or shapes, are refused (exit status 2, one line).
docs/training.md ("Averaging snapshots") has what it measured.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from frbench.errors import FrbenchError
from frbench.policies.checkpoint import read_checkpoint


def average(checkpoints: list[dict], names: list[str]) -> dict:
    """One checkpoint whose actor tensors are the mean of ``checkpoints``' (module docstring); ``names`` label
    them in errors."""
    import torch

    if len(checkpoints) < 2:
        raise FrbenchError(f"averaging needs at least two snapshots, got {len(checkpoints)}")
    first, last = checkpoints[0], checkpoints[-1]
    for data, name in zip(checkpoints, names):
        if data.get("method") != first.get("method"):
            raise FrbenchError(f"{name}: method {data.get('method')!r} differs from {names[0]}'s {first.get('method')!r}")
        if set(data["actor_state_dict"]) != set(first["actor_state_dict"]):
            raise FrbenchError(f"{name}: actor tensors differ from {names[0]}'s")
    state = {}
    for key, value in last["actor_state_dict"].items():
        tensors = [data["actor_state_dict"][key] for data in checkpoints]
        if not torch.is_floating_point(value):
            state[key] = value
            continue
        for tensor, name in zip(tensors[1:], names[1:]):
            if tensor.shape != tensors[0].shape:
                raise FrbenchError(f"{name}: actor tensor {key} has shape {tuple(tensor.shape)}, expected "
                                   f"{tuple(tensors[0].shape)} as in {names[0]}")
        state[key] = sum(tensors) / len(tensors)
    return {**last, "actor_state_dict": state, "averaged_env_steps": [data.get("env_steps") for data in checkpoints]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("snapshots", type=Path, nargs="+", help="policy checkpoints of one run (at least two)")
    parser.add_argument("--out", type=Path, required=True, help="the averaged checkpoint (.pt)")
    args = parser.parse_args(argv)
    import torch

    try:
        averaged = average([read_checkpoint(path) for path in args.snapshots], [str(p) for p in args.snapshots])
    except FrbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    args.out.parent.mkdir(parents=True, exist_ok=True)
    partial = args.out.with_name(args.out.name + ".partial")
    torch.save(averaged, partial)
    partial.replace(args.out)
    print(f"{args.out}: mean of {len(args.snapshots)} snapshots at env steps {averaged['averaged_env_steps']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
