"""Where a result came from: versions, git commit, checksums of robots and checkpoints."""

from __future__ import annotations

import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import frbench

_PACKAGES = {"mujoco": "mujoco", "pybullet": "pybullet", "pinocchio": "pin", "numpy": "numpy",
             "torch": "torch", "gymnasium": "gymnasium", "rsl_rl": "rsl-rl-lib", "example_robot_data": "example-robot-data",
             "mujoco_warp": "mujoco-warp", "warp": "warp-lang",  # the optional gpu extra
             "sapien": "sapien"}  # the optional physx extra (PhysX 5 inside)


def library_versions() -> dict[str, str]:
    """Python and the simulator/library versions."""
    out = {"python": platform.python_version()}
    for key, dist in _PACKAGES.items():
        try:
            out[key] = version(dist)
        except PackageNotFoundError:
            out[key] = "not installed"
    return out


def _git(*args: str) -> str | None:
    root = Path(frbench.__file__).resolve().parent.parent
    try:
        out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def frbench_info() -> dict:
    """frbench's version, git commit (40 hex, or ``unknown`` outside a checkout) and whether the tree was modified."""
    commit = _git("rev-parse", "HEAD")
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return {"version": frbench.__version__, "git_commit": commit or "unknown", "git_dirty": bool(dirty)}
