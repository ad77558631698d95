"""pybullet (and its ``BulletClient``), imported in this one place without the "pybullet build time: ..." line
that its C extension prints when it loads (to stderr with this wheel; stdout and stderr are both silenced for
the import); every frbench module takes pybullet from here."""

from __future__ import annotations

import os
import sys


def _flush_c_stdio() -> None:
    """``fflush(NULL)`` of the C library (a no-op where it cannot be reached)."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


def _import_quietly():
    """Import pybullet with file descriptors 1 and 2 pointed at /dev/null for the duration of the import."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        with open(os.devnull, "w") as null:
            for fd in saved:
                os.dup2(null.fileno(), fd)
            import pybullet

            _flush_c_stdio()  # a line left in C's stdio buffer would be written after the descriptors return
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
    return pybullet


pybullet = _import_quietly()
from pybullet_utils.bullet_client import BulletClient  # noqa: E402 (after the quiet import)

__all__ = ["BulletClient", "pybullet"]
