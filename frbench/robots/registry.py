"""Find robots by name or path: built-ins, user-added robots, and plugins.

Lookup order for ``get_robot(name_or_path)``:

1. a path to a ``.urdf`` file → :func:`frbench.robots.infer.spec_from_path`;
2. a built-in robot (:mod:`frbench.robots.builtin`);
3. a robot added with ``frbench robot add`` (``<config>/robots.toml``);
4. plugins: entry points of group ``frbench.robots``, each loading to a
   zero-argument callable that returns a `RobotSpec` (read only on a miss of
   1–3 or when listing, never at ``import frbench``).

An unknown name lists the known ones and suggests the closest. A robot by path
(1, 3) comes with its kinematic standing height: nothing here runs a simulator;
:func:`frbench.robot_checks.lookup.get_robot` gives it the measured one.
"""

from __future__ import annotations

import json
import tomllib
from functools import lru_cache
from importlib.metadata import entry_points
from pathlib import Path
from typing import Callable

from frbench.errors import RobotFileError, unknown_name
from frbench.io import atomic_write_text
from frbench.robots.builtin import BUILTIN_ROBOTS
from frbench.robots.infer import sidecar_path, spec_from_path
from frbench.robots.paths import config_dir
from frbench.robots.sidecar import NAME_PATTERN
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.unseen import UNSEEN_ROBOTS, unseen_spec
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


def unavailable_reason(entry: dict) -> str | None:
    """Why a user robot cannot load (its URDF or sidecar file is gone), or None."""
    urdf = Path(entry.get("urdf", ""))
    if not urdf.is_file():
        return f"its URDF {urdf} no longer exists"
    sidecar = entry.get("sidecar")
    if sidecar and not Path(sidecar).is_file():
        return f"its sidecar {sidecar} no longer exists"
    return None


@lru_cache(maxsize=128)
def _spec_by_name(name: str) -> RobotSpec:
    if name in BUILTIN_ROBOTS:
        return BUILTIN_ROBOTS[name]()
    if name in UNSEEN_ROBOTS:  # protocol 1.2's unseen robots: installed files by a portable name
        return unseen_spec(name)
    users = user_robots()
    if name in users:
        entry = users[name]
        reason = unavailable_reason(entry)
        if reason:
            raise RobotFileError(f"robot {name!r} is unavailable: {reason}; `frbench robot remove {name}` unregisters it")
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
        path = Path(name_or_path)
        if not path.is_file():
            raise RobotFileError(f"{path}: no such URDF file")
        return spec_from_path(path)
    return _spec_by_name(name_or_path)


def robot_names() -> list[str]:
    """Every usable robot name: built-ins first, then user robots (those whose files exist) and plugins."""
    names = list(BUILTIN_ROBOTS)
    names += [n for n, entry in user_robots().items() if n not in names and unavailable_reason(entry) is None]
    names += [n for n in plugin_robots() if n not in names]
    return names


def unavailable_robots() -> dict[str, str]:
    """User robots that cannot load: name → reason."""
    out = {}
    for name, entry in user_robots().items():
        reason = unavailable_reason(entry)
        if reason:
            out[name] = reason
    return out


def _write_user_robots(robots: dict[str, dict]) -> None:
    lines = []
    for robot, entry in sorted(robots.items()):
        lines.append(f'[robots."{robot}"]')
        lines += [f"{key} = {json.dumps(value)}" for key, value in entry.items()]
        lines.append("")
    atomic_write_text(user_robots_file(), "\n".join(lines))
    _spec_by_name.cache_clear()


def check_name(name: str) -> None:
    """Refuse a registry name that is unsafe or taken by a built-in robot."""
    if not NAME_PATTERN.fullmatch(name):
        raise RobotFileError(f"--name {name!r}: expected 1-64 letters, digits, '_' or '-', starting with a letter or digit")
    if name in BUILTIN_ROBOTS or name in UNSEEN_ROBOTS:
        raise RobotFileError(f"robot name {name!r} is a built-in robot; choose another name")


def add_user_robot(urdf: str | Path, name: str, force: bool = False, check=None) -> RobotSpec:
    """Register ``urdf`` persistently as ``name``.

    Args:
        force: replace a robot of that name, and register even when ``check`` fails.
        check: None, or a callable spec -> (ok, problems) run before anything is
            written (``frbench robot add`` passes the conformance check, which measures the standing height
            first: the spec given here carries the kinematic one).

    Raises:
        RobotFileError: bad name, taken name without ``force``, unusable file, or a failed check without ``force``.
    """
    check_name(name)
    robots = user_robots()
    if name in robots and not force:
        raise RobotFileError(f"robot {name!r} is already registered (urdf {robots[name].get('urdf')}); pass --force to replace it")
    urdf = Path(urdf).resolve()
    if not urdf.is_file():
        raise RobotFileError(f"{urdf}: no such URDF file")
    spec = spec_from_path(urdf, name=name)
    sim_robot_file(spec)  # refuses an unusable file before anything is written
    entry = {"urdf": str(urdf)}
    side = sidecar_path(urdf)
    if side.is_file():
        entry["sidecar"] = str(side)
    if check is not None:
        ok, problems = check(spec)
        if not ok and not force:
            raise CheckFailedError(
                f"robot {name!r} not added: `frbench robot check` fails ({'; '.join(problems)}); fix it, or pass --force to add it anyway"
            )
        entry["check"] = "pass" if ok else "fail"
    robots[name] = entry
    _write_user_robots(robots)
    return spec


def remove_user_robot(name: str) -> dict:
    """Unregister a user robot; returns its entry."""
    if name in BUILTIN_ROBOTS:
        raise RobotFileError(f"robot {name!r} is built in and cannot be removed")
    robots = user_robots()
    if name not in robots:
        raise unknown_name("user robot", name, robots)
    entry = robots.pop(name)
    _write_user_robots(robots)
    return entry


class CheckFailedError(RobotFileError):
    """A robot that fails `frbench robot check` (exit status 1, like a failing check)."""

    exit_status = 1
