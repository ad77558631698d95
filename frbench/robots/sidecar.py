"""The sidecar of a robot given by path: ``<stem>.frbench.toml`` beside its URDF, read strictly.

Every key is typed and range-checked twice: first on its own (:func:`read_sidecar`:
types, finiteness, signs, safe names), then against the robot's kinematic tree
(:meth:`Sidecar.check_against`: joints and links that exist, complete per-joint
tables). Every refusal is one :class:`~frbench.errors.RobotFileError` line of
the form ``<sidecar>: <key> = <value>: expected <what>``.

Keys (all optional)::

    name = "mydog"            # registry name: letters, digits, '_' and '-', at most 64
    kind = "quadruped"        # or "humanoid"
    kp = 60.0                 # [N·m/rad] one value, or a table naming EVERY actuated joint
    kd = 1.5                  # [N·m·s/rad] likewise
    effort = 30.0             # [N·m] one value or a table joint -> value (replaces the file's)
    nominal_height = 0.31     # [m] standing height of the root link (default: measured)
    physics_dt = 0.005        # [s] one of PHYSICS_STEPS (default: derived, see gains.py)
    feet = ["FL_foot", "FR_foot", "RL_foot", "RR_foot"]   # links (humanoid: left, right)
    [default_pose]            # joint -> angle [rad], inside the joint's limits
    [joint_limits]            # joint -> [lower, upper] [rad], lower < upper
    [legs]                    # quadruped: FL/FR/RL/RR -> [hip, thigh, calf] joints
                              # humanoid: left/right -> the leg's joints, pelvis to foot
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from frbench.errors import RobotFileError
from frbench.robots.urdf_tree import MOVING_TYPES

SIDECAR_SUFFIX = ".frbench.toml"
#: Physics steps [s] both backends run identically: the 0.02 s control period in 4 to 20 equal steps.
PHYSICS_STEPS = (0.005, 0.004, 0.0025, 0.002, 0.001)
#: Safe registry names: they become file names in frbench's cache.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
QUADRUPED_LEG_KEYS = ("FL", "FR", "RL", "RR")
HUMANOID_LEG_KEYS = ("left", "right")
KEYS = (
    "name", "kind", "kp", "kd", "effort", "nominal_height", "physics_dt", "feet", "default_pose", "joint_limits", "legs",
)
MAX_HEIGHT = 5.0  # [m]
MAX_GAIN = 1e5


def sidecar_path(urdf: Path) -> Path:
    """Where the sidecar of ``urdf`` is looked for: ``<stem>.frbench.toml`` beside it."""
    return urdf.with_name(urdf.stem + SIDECAR_SUFFIX)


def _show(value) -> str:
    """A value as the user wrote it, on one line and short."""
    if isinstance(value, str):
        text = repr(value)
    elif isinstance(value, dict):
        text = "{" + ", ".join(f"{k} = {_show(v)}" for k, v in value.items()) + "}"
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(_show(v) for v in value) + "]"
    else:
        text = str(value).lower() if isinstance(value, bool) else str(value)
    text = text.replace("\n", " ")
    return text if len(text) <= 120 else text[:117] + "..."


def refuse(path: Path | str, key: str, value, expected: str) -> RobotFileError:
    """The one-line refusal ``<path>: <key> = <value>: expected <expected>``."""
    return RobotFileError(f"{path}: {key} = {_show(value)}: expected {expected}")


def _number(path, key, value, *, positive: bool = False, upper: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise refuse(path, key, value, "a number" + (" > 0" if positive else ""))
    value = float(value)
    if not math.isfinite(value):
        raise refuse(path, key, value, "a finite number")
    if positive and value <= 0:
        raise refuse(path, key, value, "a number > 0")
    if upper is not None and value > upper:
        raise refuse(path, key, value, f"a number <= {upper:g}")
    return value


def _table(path, key, value) -> dict:
    if not isinstance(value, dict):
        raise refuse(path, key, value, "a table of joint = value")
    return value


@dataclass(frozen=True)
class Sidecar:
    """A sidecar's values after the type and range checks; absent keys are None or empty.

    Per-joint values are dicts joint -> value; ``kp``/``kd``/``effort`` are a
    float (every joint) or such a dict.
    """

    path: Path | None = None
    name: str | None = None
    kind: str | None = None
    kp: float | dict | None = None
    kd: float | dict | None = None
    effort: float | dict | None = None
    nominal_height: float | None = None
    physics_dt: float | None = None
    feet: tuple[str, ...] | None = None
    default_pose: dict = field(default_factory=dict)
    joint_limits: dict = field(default_factory=dict)
    legs: dict | None = None

    @property
    def label(self) -> str:
        """The file named in messages."""
        return str(self.path) if self.path else "sidecar"

    def check_against(self, tree, kind: str) -> None:
        """Refuse names of joints and links that ``tree`` (a `UrdfTree`) lacks, and malformed legs."""
        moving = [j.name for j in tree.joints.values() if j.type in MOVING_TYPES]
        known = f"one of the file's moving joints ({_few(moving)})"
        for key in ("default_pose", "joint_limits"):
            for joint, value in getattr(self, key).items():
                if joint not in moving:
                    raise refuse(self.label, f"{key}.{joint}", value, known)
        for key in ("kp", "kd", "effort"):
            value = getattr(self, key)
            if isinstance(value, dict):
                for joint, gain in value.items():
                    if joint not in moving:
                        raise refuse(self.label, f"{key}.{joint}", gain, known)
        for foot in self.feet or ():
            if foot not in tree.links:
                raise refuse(self.label, "feet", list(self.feet), f"links of the file (no link {foot!r}; links: {_few(list(tree.links))})")
        expected_feet = 4 if kind == "quadruped" else 2
        if self.feet is not None and len(self.feet) != expected_feet:
            order = "FL, FR, RL, RR" if kind == "quadruped" else "left, right"
            raise refuse(self.label, "feet", list(self.feet), f"{expected_feet} link names ({order}) for a {kind}")
        if self.legs is None:
            return
        keys = QUADRUPED_LEG_KEYS if kind == "quadruped" else HUMANOID_LEG_KEYS
        if set(self.legs) != set(keys):
            raise refuse(self.label, "legs", self.legs, f"a table with exactly the legs {', '.join(keys)} for a {kind}")
        seen: set[str] = set()
        for leg in keys:
            joints = self.legs[leg]
            if kind == "quadruped" and len(joints) != 3:
                raise refuse(self.label, f"legs.{leg}", joints, "3 joint names: hip, thigh, calf")
            if kind == "humanoid" and len(joints) < 3:
                raise refuse(self.label, f"legs.{leg}", joints, "at least 3 joint names, pelvis to foot")
            for joint in joints:
                if joint not in moving:
                    raise refuse(self.label, f"legs.{leg}", joints, f"moving joints of the file (no moving joint {joint!r}; {_few(moving)})")
                if joint in seen:
                    raise refuse(self.label, f"legs.{leg}", joints, f"each joint in one leg only ({joint!r} is named twice)")
                seen.add(joint)
            for upper, lower in zip(joints, joints[1:]):
                if upper not in [j.name for j in _joints_above(tree, lower)]:
                    raise refuse(self.label, f"legs.{leg}", joints, f"joints in order from the body to the foot ({upper!r} is not above {lower!r})")

    def check_complete(self, joint_names) -> None:
        """Refuse a kp or kd table that does not name every actuated joint."""
        for key in ("kp", "kd"):
            value = getattr(self, key)
            if isinstance(value, dict):
                missing = [j for j in joint_names if j not in value]
                if missing:
                    raise refuse(self.label, key, value, f"one number, or a table naming every actuated joint (missing {_few(missing)})")
        for joint, angle in self.default_pose.items():
            if joint not in joint_names:
                raise refuse(self.label, f"default_pose.{joint}", angle, f"an actuated joint ({_few(list(joint_names))})")


def _joints_above(tree, joint_name: str):
    out, joint = [], tree.parent_joint(tree.joints[joint_name].parent)
    while joint is not None:
        out.append(joint)
        joint = tree.parent_joint(joint.parent)
    return out


def _few(names: list[str], n: int = 6) -> str:
    return ", ".join(names[:n]) + (f", ... ({len(names)} in all)" if len(names) > n else "")


def _per_joint(path, key, value, *, positive: bool, upper: float) -> float | dict:
    if isinstance(value, dict):
        return {str(j): _number(path, f"{key}.{j}", v, positive=positive, upper=upper) for j, v in value.items()}
    return _number(path, key, value, positive=positive, upper=upper)


def parse_sidecar(data: dict, path: Path | None) -> Sidecar:
    """Type- and range-check a sidecar's table (see the module docstring)."""
    label = str(path) if path else "sidecar"
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise refuse(label, unknown[0], data[unknown[0]], f"a known key ({', '.join(KEYS)})")
    values: dict = {"path": path}
    if "name" in data:
        name = data["name"]
        if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
            raise refuse(label, "name", name, "1-64 letters, digits, '_' or '-', starting with a letter or digit")
        values["name"] = name
    if "kind" in data:
        if data["kind"] not in ("quadruped", "humanoid"):
            raise refuse(label, "kind", data["kind"], "'quadruped' or 'humanoid'")
        values["kind"] = data["kind"]
    for key in ("kp", "kd", "effort"):
        if key in data:
            values[key] = _per_joint(label, key, data[key], positive=True, upper=MAX_GAIN)
    if "nominal_height" in data:
        values["nominal_height"] = _number(label, "nominal_height", data["nominal_height"], positive=True, upper=MAX_HEIGHT)
    if "physics_dt" in data:
        dt = data["physics_dt"]
        ok = not isinstance(dt, bool) and isinstance(dt, (int, float)) and any(abs(dt - s) < 1e-12 for s in PHYSICS_STEPS)
        if not ok:
            steps = ", ".join(f"{s:g}" for s in PHYSICS_STEPS)
            raise refuse(label, "physics_dt", dt, f"one of {steps} s (the 0.02 s control period in 4 to 20 equal steps)")
        values["physics_dt"] = float(dt)
    if "feet" in data:
        feet = data["feet"]
        if not isinstance(feet, list) or not feet or not all(isinstance(f, str) for f in feet) or len(set(feet)) != len(feet):
            raise refuse(label, "feet", feet, "a list of distinct link names")
        values["feet"] = tuple(feet)
    if "default_pose" in data:
        table = _table(label, "default_pose", data["default_pose"])
        values["default_pose"] = {str(j): _number(label, f"default_pose.{j}", v) for j, v in table.items()}
    if "joint_limits" in data:
        table = _table(label, "joint_limits", data["joint_limits"])
        limits = {}
        for joint, pair in table.items():
            key = f"joint_limits.{joint}"
            if not isinstance(pair, list) or len(pair) != 2:
                raise refuse(label, key, pair, "[lower, upper] in rad")
            lower, upper = (_number(label, key, v) for v in pair)
            if not lower < upper:
                raise refuse(label, key, pair, "[lower, upper] with lower < upper")
            limits[str(joint)] = (lower, upper)
        values["joint_limits"] = limits
    if "legs" in data:
        legs = data["legs"]
        if not isinstance(legs, dict):
            raise refuse(label, "legs", legs, "a table leg = [joint, ...]")
        for leg, joints in legs.items():
            if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
                raise refuse(label, f"legs.{leg}", joints, "a list of joint names")
        values["legs"] = {str(k): tuple(v) for k, v in legs.items()}
    return Sidecar(**values)


def read_sidecar(path: Path | None) -> Sidecar:
    """The checked sidecar at ``path`` (an empty `Sidecar` when there is no file)."""
    if path is None or not path.is_file():
        return Sidecar(path=path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError:
        raise RobotFileError(f"{path}: not UTF-8 text; expected a TOML file") from None
    return parse_sidecar(data, path)


def check_pose_in_limits(side: Sidecar, lower: dict, upper: dict) -> None:
    """Refuse a ``default_pose`` angle outside its joint's limits (joint -> lower/upper [rad])."""
    for joint, angle in side.default_pose.items():
        if not lower[joint] - 1e-9 <= angle <= upper[joint] + 1e-9:
            raise refuse(side.label, f"default_pose.{joint}", angle, f"an angle inside the joint's limits [{lower[joint]:g}, {upper[joint]:g}] rad")
