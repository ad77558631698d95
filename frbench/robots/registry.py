"""Find robots by name or path: built-ins, user-added robots, and plugins.

Lookup order for ``get_robot(name_or_path)``:

1. a path to a ``.urdf`` file → :func:`frbench.robots.infer.spec_from_path`;
2. a built-in robot (:mod:`frbench.robots.builtin`);
3. a robot added with ``frbench robot add`` (``<config>/robots.toml``);
4. plugins: entry points of group ``frbench.robots``, each loading to a
   zero-argument callable that returns a `RobotSpec` (read only on a miss of
   1–3 or when listing, never at ``import frbench``).

An unknown name lists the known ones and suggests the closest.
"""

from __future__ import annotations

import tomllib
from functools import lru_cache
from importlib.metadata import entry_points
from pathlib import Path
from typing import Callable

from frbench.errors import RobotFileError, unknown_name
from frbench.io import atomic_write_text
from frbench.robots.builtin import BUILTIN_ROBOTS
from frbench.robots.paths import config_dir
from frbench.robots.spec import RobotSpec

ENTRY_POINT_GROUP = "frbench.robots"


def user_robots_file() -> Path:
    """The file ``frbench robot add`` writes: ``<config>/robots.toml``."""
    return config_dir() / "robots.toml"


def user_robots() -> dict[str, dict]:
    """Robots added by the user: name → {"urdf": path, "sidecar": path | None}."""
    path = user_robots_file()
    if not path.is_file():
        return {}
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path}: not valid TOML ({exc})") from None
    return data.get("robots", {})


def plugin_robots() -> dict[str, Callable[[], RobotSpec]]:
    """Robots registered by installed packages through the ``frbench.robots`` entry points."""
    return {ep.name: ep.load for ep in entry_points(group=ENTRY_POINT_GROUP)}


def _is_path(name: str) -> bool:
    return name.endswith(".urdf") or "/" in name or Path(name).suffix == ".urdf"


@lru_cache(maxsize=128)
def _spec_by_name(name: str) -> RobotSpec:
    from frbench.robots.infer import spec_from_path

    if name in BUILTIN_ROBOTS:
        return BUILTIN_ROBOTS[name]()
    users = user_robots()
    if name in users:
        entry = users[name]
        return spec_from_path(entry["urdf"], entry.get("sidecar"), name=name)
    plugins = plugin_robots()
    if name in plugins:
        spec = plugins[name]()()
        if not isinstance(spec, RobotSpec):
            raise RobotFileError(f"plugin robot {name!r} returned {type(spec).__name__}, expected a RobotSpec")
        return spec
    raise unknown_name("robot", name, robot_names())


def get_robot(name_or_path: str | RobotSpec) -> RobotSpec:
    """The `RobotSpec` of a registered name or of a URDF path (see the module docstring)."""
    if isinstance(name_or_path, RobotSpec):
        return name_or_path
    if _is_path(name_or_path):
        from frbench.robots.infer import spec_from_path

        path = Path(name_or_path)
        if not path.is_file():
            raise RobotFileError(f"{path}: no such URDF file")
        return spec_from_path(path)
    return _spec_by_name(name_or_path)


def robot_names() -> list[str]:
    """Every registered robot name: built-ins first, then user robots and plugins."""
    names = list(BUILTIN_ROBOTS)
    names += [n for n in user_robots() if n not in names]
    names += [n for n in plugin_robots() if n not in names]
    return names


def add_user_robot(urdf: str | Path, name: str) -> RobotSpec:
    """Register ``urdf`` persistently as ``name`` (checked first: it must load)."""
    from frbench.robots.infer import sidecar_path, spec_from_path

    if name in BUILTIN_ROBOTS:
        raise RobotFileError(f"robot name {name!r} is a built-in robot; choose another name")
    if not name.replace("_", "").replace("-", "").isalnum():
        raise RobotFileError(f"robot name {name!r}: use letters, digits, '_' and '-' only")
    urdf = Path(urdf).resolve()
    if not urdf.is_file():
        raise RobotFileError(f"{urdf}: no such URDF file")
    spec = spec_from_path(urdf, name=name)
    from frbench.robots.sim_urdf import sim_robot_file

    sim_robot_file(spec)  # refuses an unusable file before anything is written
    robots = user_robots()
    side = sidecar_path(urdf)
    robots[name] = {"urdf": str(urdf), **({"sidecar": str(side)} if side.is_file() else {})}
    lines = []
    for robot, entry in sorted(robots.items()):
        lines.append(f'[robots."{robot}"]')
        lines += [f'{key} = "{value}"' for key, value in entry.items()]
        lines.append("")
    atomic_write_text(user_robots_file(), "\n".join(lines))
    _spec_by_name.cache_clear()
    return spec
