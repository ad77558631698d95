"""The observation/action contract between frbench and a policy, as data.

A `PolicyLayout` says how a policy reads frbench's proprioception and what its
output means. It does not depend on the robot: the terms, their order and
scales, the history frames, the action convention and scale. A `Contract`
binds a layout to a robot (`contract_for`): joint names in canonical order,
default pose, joint and torque limits, PD gains, control rate, physics step
and the protocol version. ``frbench spec`` prints a contract; the ONNX
export's sidecar (``<file>.onnx.json``) records its layout under
``"layout"``; ``frbench evaluate --spec FILE`` reads one (a layout, a sidecar
or the output of ``frbench spec --json``).

One observation frame o_t is the concatenation of the layout's terms, each
``scale · value`` (then clipped to ±``observation_clip`` when set), float32:

* ``base_angvel`` [rad/s] (3): the base's angular velocity in the body frame;
* ``projected_gravity`` [-] (3): the unit gravity direction in the body frame,
  (0, 0, −1) upright, (0, 0, +1) on the back;
* ``joint_pos`` [rad] (J): q − q_default;
* ``joint_vel`` [rad/s] (J): q̇;
* ``previous_action`` (J): the policy's previous output a_{t−1} after
  ``action_clip`` (for the ``targets`` convention a_{t−1} − q_default); zeros at t = 0;
* ``previous_target`` [rad] (J): q*_{t−1} − q_default, the previous joint
  targets as applied (clipped to the joint limits); zeros at t = 0;
* ``constant`` (``size`` values equal to ``value``): inputs frbench has no
  counterpart for, e.g. zero velocity commands.

Per-joint terms follow the layout's ``joint_names`` (default: the robot's
canonical order; matched by name). Each input of the policy is the current
frame (``frames`` = 1, width F) or the last ``frames`` frames, oldest first and
the current one last (width frames·F), filled with the first frame at t = 0.

``joint_frame``: ``robot`` (default) — joint terms and actions in the robot file's own convention; ``canonical``
— in the robot's canonical joint frame (`frbench.robots.joint_frame`: canonical = sign · q + offset, the Unitree
convention with legs hanging straight down at zero), so one policy drives robots whose files turn their joints
the other way (Solo12, Mini Cheetah, ANYmal) or fold their legs at zero (Spirit40, Vision60). Its q_default, joint
limits and every joint term are then the canonical ones; frbench maps them where it builds the policy's input and
reads its output (`frbench.evaluation.episodes.run_episodes`). Only quadrupeds of hip-thigh-calf legs have one.

Actions a (N, J) in the layout's joint order: ``normalised``: q* = q_default +
action_scale · a; ``targets``: q* = a [rad]; a is first clipped to
±``action_clip`` when set, and q* is clipped to the joint limits. The policy
decides every ``action_hold`` control steps (50 Hz) and its action is held in between.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

from frbench.errors import PolicyError
from frbench.robots.joint_frame import JOINT_FRAMES
from frbench.tasks.protocol import CONTROL_DT, PROTOCOL_VERSION

#: ``"format"`` of a layout dict.
LAYOUT_FORMAT = "frbench-policy-layout-v1"
#: Key under which a model file carries its layout's JSON (ONNX ``metadata_props``; TorchScript extra file
#: ``frbench_layout.json``).
EMBEDDED_LAYOUT_KEY = "frbench_layout"
#: ``"format"`` of a contract dict (``frbench spec --json``).
CONTRACT_FORMAT = "frbench-policy-contract-v1"
#: Observation terms: name → (unit, meaning, size: an int, "J" (one per joint) or None (given by ``size``)).
TERMS = {
    "base_angvel": ("rad/s", "base angular velocity, body frame", 3),
    "projected_gravity": ("-", "unit gravity direction, body frame: (0, 0, -1) upright", 3),
    "joint_pos": ("rad", "q - q_default", "J"),
    "joint_vel": ("rad/s", "joint velocity", "J"),
    "previous_action": ("action", "previous output a_{t-1} after action_clip (targets: a_{t-1} - q_default); 0 at t=0",
                        "J"),
    "previous_target": ("rad", "previous joint targets as applied (joint-limit clipped) - q_default; 0 at t=0", "J"),
    "constant": ("-", "a constant: `size` values equal to `value`", None),
}
#: Action conventions: ``normalised`` (q* = q_default + action_scale · a) and ``targets`` (q* = a [rad]).
ACTION_CONVENTIONS = ("normalised", "targets")


@dataclass(frozen=True)
class ObservationTerm:
    """One term of the observation frame: ``scale`` · its value (``size``, ``value``: a ``constant`` only)."""

    name: str
    scale: float = 1.0
    size: int = 0
    value: float = 0.0

    def width(self, n_joints: int) -> int:
        """Values the term adds to the frame."""
        size = TERMS[self.name][2]
        return n_joints if size == "J" else self.size if size is None else size

    def to_dict(self) -> dict:
        """JSON form: name and scale (and size, value for a constant)."""
        data = {"name": self.name, "scale": self.scale}
        return {**data, "size": self.size, "value": self.value} if self.name == "constant" else data


@dataclass(frozen=True)
class LayoutInput:
    """One input of the policy: the last ``frames`` observation frames (1: the current frame only)."""

    name: str
    frames: int = 1


#: frbench's own frame: the paper's o_t, [ω, g, q − q̊, q̇, a_{t−1}] (42 values for a quadruped).
FRBENCH_TERMS = tuple(ObservationTerm(name) for name in
                      ("base_angvel", "projected_gravity", "joint_pos", "joint_vel", "previous_action"))


@dataclass(frozen=True)
class PolicyLayout:
    """How a policy reads the observation and what its output means (module docstring); robot-independent.

    ``joint_names`` / ``default_pose``: the policy's joint order (a permutation of the robot's joint names)
    and its q_default [rad] in that order; None: the robot's canonical order and default pose.
    """

    observation: tuple[ObservationTerm, ...] = FRBENCH_TERMS
    inputs: tuple[LayoutInput, ...] = (LayoutInput("obs"),)
    action: str = "normalised"
    action_scale: float = 1.0
    action_clip: float | None = 10.0
    observation_clip: float | None = None
    action_hold: int = 1
    joint_names: tuple[str, ...] | None = None
    default_pose: tuple[float, ...] | None = None
    joint_frame: str = "robot"

    def frame_size(self, n_joints: int) -> int:
        """Values in one observation frame for a robot of ``n_joints`` joints (42 for frbench's, J = 12)."""
        return sum(term.width(n_joints) for term in self.observation)

    def input_sizes(self, n_joints: int) -> dict[str, int]:
        """Input name → width (frames · frame size)."""
        frame = self.frame_size(n_joints)
        return {i.name: i.frames * frame for i in self.inputs}

    def describe(self, n_joints: int) -> str:
        """One line: the inputs, the frame's terms and the action, e.g. for a layout error."""
        frame = self.frame_size(n_joints)
        terms = ", ".join(f"{t.name} {t.width(n_joints)}" + (f" x{t.scale:g}" if t.scale != 1 else "")
                          for t in self.observation)
        inputs = "; ".join(f"{i.name} (N, {i.frames * frame})" + (f" = last {i.frames} frames" if i.frames > 1 else "")
                           for i in self.inputs)
        rule = (f"q* = q_default + {self.action_scale:g}*a" if self.action == "normalised" else "q* = a [rad]")
        frame_note = "; joints in the canonical frame" if self.joint_frame == "canonical" else ""
        return f"inputs {inputs} float32, frame [{terms}]; action a (N, {n_joints}) {self.action}: {rule}{frame_note}"

    def to_dict(self) -> dict:
        """JSON form (`from_dict` reads it back)."""
        return {
            "format": LAYOUT_FORMAT,
            "observation": [term.to_dict() for term in self.observation],
            "inputs": [{"name": i.name, "frames": i.frames} for i in self.inputs],
            "action": self.action,
            "action_scale": self.action_scale,
            "action_clip": self.action_clip,
            "observation_clip": self.observation_clip,
            "action_hold": self.action_hold,
            "joint_names": list(self.joint_names) if self.joint_names is not None else None,
            "default_pose": list(self.default_pose) if self.default_pose is not None else None,
            "joint_frame": self.joint_frame,
        }

    @classmethod
    def from_dict(cls, data, source: str = "layout") -> "PolicyLayout":
        """A layout from its JSON form (fields left out keep frbench's defaults), or from a contract or ONNX
        sidecar that holds one under ``"layout"``. Raises `PolicyError` naming ``source`` and the field."""
        if isinstance(data, dict) and isinstance(data.get("layout"), dict):
            data, source = data["layout"], f"{source}: layout"
        if not isinstance(data, dict):
            raise PolicyError(f"{source}: expected a JSON object (a policy layout), got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)} | {"format"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise PolicyError(f"{source}: unknown field {unknown[0]!r} (known: {', '.join(sorted(known))})")
        if data.get("format", LAYOUT_FORMAT) != LAYOUT_FORMAT:
            raise PolicyError(f"{source}: format {data['format']!r}, expected {LAYOUT_FORMAT!r}")
        d = cls()
        fields = {
            "observation": tuple(_term(t, f"{source}: observation[{k}]") for k, t in
                                 enumerate(_list(data.get("observation", [t.to_dict() for t in d.observation]),
                                                 f"{source}: observation"))),
            "inputs": tuple(_input(i, f"{source}: inputs[{k}]") for k, i in
                            enumerate(_list(data.get("inputs", [{"name": "obs"}]), f"{source}: inputs"))),
            "action": data.get("action", d.action),
            "action_scale": _number(data.get("action_scale", d.action_scale), f"{source}: action_scale", positive=True),
            "action_clip": _optional_number(data.get("action_clip", d.action_clip), f"{source}: action_clip"),
            "observation_clip": _optional_number(data.get("observation_clip"), f"{source}: observation_clip"),
            "action_hold": _count(data.get("action_hold", 1), f"{source}: action_hold"),
            "joint_frame": data.get("joint_frame", d.joint_frame),
        }
        if fields["joint_frame"] not in JOINT_FRAMES:
            raise PolicyError(f"{source}: joint_frame {fields['joint_frame']!r}, expected one of {', '.join(JOINT_FRAMES)}")
        if fields["action"] not in ACTION_CONVENTIONS:
            raise PolicyError(f"{source}: action {fields['action']!r}, expected one of {', '.join(ACTION_CONVENTIONS)}")
        if not fields["observation"] or not fields["inputs"]:
            raise PolicyError(f"{source}: observation and inputs need at least one entry each")
        names = [i.name for i in fields["inputs"]]
        if len(set(names)) != len(names):
            raise PolicyError(f"{source}: inputs: names repeat ({', '.join(names)})")
        joints, pose = data.get("joint_names"), data.get("default_pose")
        if joints is not None:
            joints = _list(joints, f"{source}: joint_names")
            if not all(isinstance(j, str) for j in joints) or len(set(joints)) != len(joints):
                raise PolicyError(f"{source}: joint_names: expected distinct joint names")
            fields["joint_names"] = tuple(joints)
        if pose is not None:
            pose = tuple(_number(v, f"{source}: default_pose[{k}]") for k, v in
                         enumerate(_list(pose, f"{source}: default_pose")))
            if joints is not None and len(pose) != len(joints):
                raise PolicyError(f"{source}: default_pose has {len(pose)} values, joint_names {len(joints)}")
            fields["default_pose"] = pose
        return cls(**fields)


def _list(value, where: str) -> list:
    if not isinstance(value, list):
        raise PolicyError(f"{where}: expected a list, got {type(value).__name__}")
    return value


def _number(value, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (
            positive and value <= 0):
        raise PolicyError(f"{where}: {value!r}, expected a {'positive ' if positive else ''}finite number")
    return float(value)


def _optional_number(value, where: str) -> float | None:
    return None if value is None else _number(value, where, positive=True)


def _count(value, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise PolicyError(f"{where}: {value!r}, expected a whole number of at least 1")
    return value


def _term(data, where: str) -> ObservationTerm:
    if isinstance(data, str):
        data = {"name": data}
    if not isinstance(data, dict) or data.get("name") not in TERMS:
        name = data.get("name") if isinstance(data, dict) else data
        raise PolicyError(f"{where}: term {name!r}, expected one of {', '.join(TERMS)}")
    unknown = sorted(set(data) - {"name", "scale", "size", "value"})
    if unknown:
        raise PolicyError(f"{where}: unknown field {unknown[0]!r} (known: name, scale, size, value)")
    scale = _number(data.get("scale", 1.0), f"{where}: scale")
    if data["name"] != "constant":
        return ObservationTerm(data["name"], scale)
    return ObservationTerm("constant", scale, _count(data.get("size"), f"{where}: size"),
                           _number(data.get("value", 0.0), f"{where}: value"))


def _input(data, where: str) -> LayoutInput:
    if not isinstance(data, dict) or not isinstance(data.get("name"), str) or not data["name"]:
        raise PolicyError(f"{where}: expected {{\"name\": ..., \"frames\": ...}}")
    unknown = sorted(set(data) - {"name", "frames"})
    if unknown:
        raise PolicyError(f"{where}: unknown field {unknown[0]!r} (known: name, frames)")
    return LayoutInput(data["name"], _count(data.get("frames", 1), f"{where}: frames"))


def read_layout(path: str | Path) -> PolicyLayout:
    """The layout in a JSON file (a layout, an ONNX sidecar or ``frbench spec --json``); `PolicyError` if not."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(), parse_constant=lambda c: float("nan"))
    except OSError as exc:
        raise PolicyError(f"{path}: cannot read the policy layout ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PolicyError(f"{path}: not a JSON policy layout ({exc})") from None
    return PolicyLayout.from_dict(data, str(path))


@dataclass(frozen=True)
class Contract:
    """A layout bound to a robot: everything a policy trained elsewhere must match (`contract_for`).

    Joint arrays are in the robot's canonical order ``joint_names``; ``order`` maps the layout's joint order
    onto it (layout joint k is canonical joint ``order[k]``) and ``policy_default_pose`` is the layout's
    q_default [rad] in the layout's order.
    """

    protocol_version: str
    robot: str
    kind: str
    joint_names: tuple[str, ...]
    default_pose: tuple[float, ...]
    joint_lower: tuple[float, ...]
    joint_upper: tuple[float, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    torque_limits: tuple[float, ...]
    control_dt: float
    physics_dt: float
    layout: PolicyLayout
    order: tuple[int, ...]
    policy_default_pose: tuple[float, ...]

    @property
    def n_joints(self) -> int:
        """Number of actuated joints J."""
        return len(self.joint_names)

    def to_dict(self) -> dict:
        """JSON form (``frbench spec --json``; `PolicyLayout.from_dict` reads its ``layout``)."""
        robot = {name: list(v) if isinstance(v, tuple) else v for name, v in (
            ("name", self.robot), ("kind", self.kind), ("joint_names", self.joint_names),
            ("default_pose", self.default_pose), ("joint_lower", self.joint_lower),
            ("joint_upper", self.joint_upper), ("kp", self.kp), ("kd", self.kd),
            ("torque_limits", self.torque_limits))}
        layout = self.layout
        n = self.n_joints
        return {
            "format": CONTRACT_FORMAT,
            "protocol_version": self.protocol_version,
            "robot": robot,
            "control_dt": self.control_dt,
            "physics_dt": self.physics_dt,
            "pd": "tau = clip(kp * (q* - q) - kd * qd, -torque_limits, torque_limits) at every physics step",
            "frame": [{"name": t.name, "size": t.width(n), "unit": TERMS[t.name][0], "scale": t.scale,
                       "meaning": TERMS[t.name][1]} for t in layout.observation],
            "frame_size": layout.frame_size(n),
            "input_sizes": layout.input_sizes(n),
            "layout": layout.to_dict(),
        }


def contract_for(spec, layout: PolicyLayout | None = None) -> Contract:
    """``layout`` (default: frbench's `PolicyLayout()`) bound to robot ``spec`` (a `RobotSpec`).

    Raises:
        PolicyError: the layout's joint names are not the robot's, or its default pose has the wrong length.
    """
    layout = layout or PolicyLayout()
    names = tuple(spec.joint_names)
    if layout.joint_names is None:
        order = tuple(range(len(names)))
    elif sorted(layout.joint_names) != sorted(names):
        missing = sorted(set(names) - set(layout.joint_names)) or sorted(set(layout.joint_names) - set(names))
        raise PolicyError(f"layout joint_names do not match robot {spec.name!r}'s {len(names)} joints "
                          f"(first difference: {missing[0] if missing else '?'}; expected a permutation of "
                          f"{', '.join(names)})")
    else:
        order = tuple(names.index(j) for j in layout.joint_names)
    pose = layout.default_pose if layout.default_pose is not None else tuple(spec.default_pose[k] for k in order)
    if len(pose) != len(names):
        raise PolicyError(f"layout default_pose has {len(pose)} values, robot {spec.name!r} has {len(names)} joints")
    return Contract(PROTOCOL_VERSION, spec.name, spec.kind, names, tuple(spec.default_pose), tuple(spec.joint_lower),
                    tuple(spec.joint_upper), tuple(spec.kp), tuple(spec.kd), tuple(spec.torque_limits), CONTROL_DT,
                    float(spec.physics_dt), layout, order, tuple(float(v) for v in pose))


def learned_layout(policy) -> PolicyLayout:
    """The layout of a trained frbench policy (`frbench.policies.learned.LearnedPolicy`): o_t, then its
    history groups as the ONNX export names them (``history``, ``long_history``), normalised actions of its
    ``action_scale`` clipped to ±10. A residual policy has none (its targets come from Python code)."""
    if getattr(policy, "base_controller", None) is not None:
        raise PolicyError(f"policy {policy.name!r} is a residual over {policy.base_controller_name!r}: its targets "
                          "come from a base controller outside the network, which no layout describes")
    frames = {"policy": 1, "history": policy.frames, "long_history": policy.long_frames}
    names = {"policy": "obs"}
    inputs = tuple(LayoutInput(names.get(g, g), frames[g]) for g in policy.groups if g in frames)
    return PolicyLayout(inputs=inputs, action_scale=policy.action_scale, action_clip=10.0,
                        action_hold=policy.action_hold, joint_frame=policy.joint_frame)


def sidecar_path(model_path: Path) -> Path:
    """``<file>.onnx.json`` beside ``<file>.onnx`` (never ``<file>.json``, which may be a results file): where a
    model file's layout and conventions are written (`frbench.policies.export`) and read."""
    return Path(model_path).with_name(Path(model_path).name + ".json")
