"""Load a policy from a checkpoint file (``.pt``) or a training run folder.

A frbench policy checkpoint is a ``torch.save``'d dict that loads with
``torch.load(weights_only=True)`` and holds at least::

    {"format": "frbench-policy-v1", "method": "<training method>", ...}

The method's module turns it into a policy. Anything else is refused with a
message naming the file and what was expected.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from frbench.errors import PolicyError

CHECKPOINT_FORMAT = "frbench-policy-v1"
#: Training method → "module:function" building a policy from a checkpoint dict.
CHECKPOINT_LOADERS: dict[str, str] = {
    method: "frbench.policies.learned:load_learned_policy"
    for method in ("frnet", "frnet-no-mass", "frnet-no-contact", "frnet-no-est", "dreamriser", "rma", "rma-adaptation",
                   "ppo", "mpc-distill")
}


def resolve_checkpoint_file(path: Path) -> Path:
    """The checkpoint file of ``path`` (a file, or a run folder's ``policy.pt``)."""
    if path.is_dir():
        candidate = path / "policy.pt"
        if not candidate.is_file():
            raise PolicyError(f"{path}: run folder without a policy.pt checkpoint")
        return candidate
    return path


def read_checkpoint(path: Path) -> dict:
    """The checkpoint dict, checked for frbench's format."""
    import torch

    file = resolve_checkpoint_file(path)
    try:
        data = torch.load(file, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for unreadable files
        raise PolicyError(f"{file}: unreadable checkpoint ({type(exc).__name__}: {str(exc).splitlines()[0][:200]})") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise PolicyError(f"{file}: incompatible checkpoint (format {found!r}, expected {CHECKPOINT_FORMAT!r})")
    return data


def load_checkpoint_policy(path: Path):
    """A policy built from the checkpoint at ``path``."""
    data = read_checkpoint(path)
    method = data.get("method")
    if method not in CHECKPOINT_LOADERS:
        known = ", ".join(sorted(CHECKPOINT_LOADERS)) or "none yet"
        raise PolicyError(f"{path}: checkpoint of unknown method {method!r} (known: {known})")
    module, _, function = CHECKPOINT_LOADERS[method].partition(":")
    policy = getattr(importlib.import_module(module), function)(data, resolve_checkpoint_file(path))
    return policy
