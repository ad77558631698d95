"""Where installed packages keep robot files, and the user's cache and config folders.

Nothing here downloads anything: every robot file comes from an installed
package (example-robot-data, pybullet_data) or from the user.
"""

from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path

from frbench.errors import RobotFileError


@lru_cache(maxsize=1)
def cmeel_share() -> Path:
    """``<site-packages>/cmeel.prefix/share``, where example-robot-data installs."""
    for entry in sys.path:
        candidate = Path(entry) / "cmeel.prefix" / "share"
        if (candidate / "example-robot-data").is_dir():
            return candidate
    raise RobotFileError(
        "example-robot-data is not installed: no cmeel.prefix/share/example-robot-data on sys.path "
        "(install it with `pip install example-robot-data==6.0.0`)"
    )


def example_robot_data(relative: str) -> Path:
    """A file of example-robot-data's ``robots/`` folder."""
    return cmeel_share() / "example-robot-data" / "robots" / relative


def pybullet_data_file(relative: str) -> Path:
    """A file of pybullet_data (shipped with the pybullet wheel)."""
    import pybullet_data

    return Path(pybullet_data.getDataPath()) / relative


def resolve_mesh(filename: str, urdf_dir: Path) -> Path:
    """Absolute path of a URDF mesh reference (``package://`` or relative)."""
    if filename.startswith("package://"):
        rest = filename[len("package://"):].lstrip("/")
        package, _, inner = rest.partition("/")
        candidates = [cmeel_share() / rest]
        # ROS convention: package://<pkg>/... relative to a folder named <pkg> above the URDF
        for parent in [urdf_dir, *urdf_dir.parents]:
            if parent.name == package:
                candidates.append(parent / inner)
        for candidate in candidates:
            if candidate.exists():
                return candidate
        return candidates[0]
    if filename.startswith("file://"):
        return Path(filename[len("file://"):])
    path = Path(filename)
    return path if path.is_absolute() else (urdf_dir / path)


def cache_dir() -> Path:
    """frbench's cache (generated simulation URDFs): ``$FRBENCH_CACHE`` or ``~/.cache/frbench``."""
    root = os.environ.get("FRBENCH_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "frbench"
    )
    return Path(root)


def config_dir() -> Path:
    """frbench's user config (robots added with ``frbench robot add``): ``$FRBENCH_CONFIG`` or ``~/.config/frbench``."""
    root = os.environ.get("FRBENCH_CONFIG") or os.path.join(
        os.environ.get("XDG_CONFIG_HOME") or os.path.expanduser("~/.config"), "frbench"
    )
    return Path(root)
