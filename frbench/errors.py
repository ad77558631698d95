"""frbench's error types. The CLI prints ``str(error)`` on one line and exits 2.

Every message names the file, field or value at fault and says what was
expected; no simulator traceback reaches a user for bad input.
"""

from __future__ import annotations

import difflib
from typing import Iterable


class FrbenchError(Exception):
    """Base of every error frbench raises on purpose (bad input, bad files)."""

    exit_status = 2


class RobotFileError(FrbenchError):
    """A URDF (or its sidecar) that frbench cannot use."""


class UnknownNameError(FrbenchError, KeyError):
    """A name (robot, policy, terrain, backend) that no registry knows."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class PolicyError(FrbenchError):
    """A policy that returned unusable actions or could not be loaded."""


class ResultsError(FrbenchError):
    """A results or leaderboard file that is malformed or inconsistent."""


def unknown_name(kind: str, name: str, known: Iterable[str]) -> UnknownNameError:
    """An `UnknownNameError` listing the known names and the closest match."""
    known = sorted(known)
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return UnknownNameError(f"unknown {kind} {name!r} (known: {', '.join(known)}){hint}")
