"""The device a simulator and its arrays live on: one validated value for torch and MuJoCo Warp alike.

``cpu``, ``cuda`` (= ``cuda:0``) or ``cuda:N``. `parse_device` checks the name and that torch sees such a
device, and returns the canonical string (``cpu`` or ``cuda:N``), which both torch (``torch.device``) and Warp
(``wp.get_device``) read as the same CUDA ordinal: `frbench train --device` and `frbench evaluate --device` pass
it to the simulator and the trainer unchanged, so a run on ``cuda:1`` has its worlds and its tensors on GPU 1.
The CPU simulators run on ``cpu`` only.
"""

from __future__ import annotations

import re

from frbench.errors import FrbenchError

#: What ``--device`` accepts.
DEVICE_FORM = "cpu, cuda or cuda:N"
_PATTERN = re.compile(r"^(cpu|cuda)(?::(\d+))?$")


def parse_device(text: str | None, flag: str = "--device") -> str:
    """``text`` as ``cpu`` or ``cuda:N``; a `FrbenchError` (one line, naming ``flag`` and the value) when it is
    no device name, when torch sees no CUDA device, or fewer than N + 1 of them."""
    match = _PATTERN.match(text.strip().lower()) if isinstance(text, str) else None
    if match is None or (match.group(1) == "cpu" and match.group(2) is not None):
        raise FrbenchError(f"{flag} {text!r}: expected {DEVICE_FORM}")
    if match.group(1) == "cpu":
        return "cpu"
    import torch

    index = int(match.group(2) or 0)
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if count == 0:
        raise FrbenchError(f"{flag} {text}: torch sees no CUDA device on this machine; use {flag} cpu")
    if index >= count:
        raise FrbenchError(f"{flag} {text}: torch sees {count} CUDA device(s) (cuda:0 … cuda:{count - 1})")
    return f"cuda:{index}"
