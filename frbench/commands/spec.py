"""``frbench spec``: the observation/action contract a policy must meet on a robot, as text or JSON.

The contract is `frbench.policies.contract.Contract`: frbench's layout (or a
policy's, ``--policy``, or a layout file's, ``--spec``) bound to the robot.
Its ``--json`` form is a layout file ``frbench evaluate --spec`` reads.
"""

from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``spec`` to the CLI."""
    p = sub.add_parser("spec", help="print the observation/action contract a policy must meet on a robot",
                       description="Joint order, default pose, gains, control rate, the observation frame (names, "
                       "order, units, scales), history inputs and the action rule. Default: frbench's layout; "
                       "--policy: the layout a policy uses; --spec: check a layout file against the robot. "
                       "--json prints a file `frbench evaluate --spec` reads.")
    p.add_argument("--robot", required=True, help="robot name or URDF path")
    p.add_argument("--policy", default=None, help="a policy (name, checkpoint, ONNX file, ...): its layout")
    p.add_argument("--spec", default=None, help="a layout file (JSON) to bind to the robot")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def policy_layout(reference: str, spec):
    """The `PolicyLayout` a policy reads its observations with on robot ``spec`` (`PolicyError` if it has none
    or does not drive the robot)."""
    from frbench.errors import PolicyError
    from frbench.policies.contract import learned_layout
    from frbench.policies.learned import LearnedPolicy
    from frbench.policies.registry import load_policy

    policy = load_policy(reference)
    if not policy.supports(spec):
        raise PolicyError(f"policy {policy.name!r} does not support robot {spec.name!r} ({spec.kind})")
    if isinstance(policy, LearnedPolicy):
        return learned_layout(policy)
    if getattr(policy, "layout", None) is not None:
        return policy.layout
    raise PolicyError(f"policy {policy.name!r} reads frbench's observation dict itself (frbench.policies.base); "
                      "it has no layout")


def _vector(values) -> str:
    return " ".join(f"{v:7.3f}" for v in values)


def contract_text(contract) -> str:
    """The contract as a human-readable page."""
    from frbench.policies.contract import TERMS

    layout, n = contract.layout, contract.n_joints
    lines = [f"frbench policy contract: robot {contract.robot} ({contract.kind}, {n} joints), "
             f"protocol {contract.protocol_version}",
             f"control: {1 / contract.control_dt:.0f} Hz (control_dt {contract.control_dt} s), physics step "
             f"{contract.physics_dt} s; PD at every physics step: tau = clip(kp (q* - q) - kd qd, +-torque limit)",
             "", "joints, canonical order     q_default [rad]  lower   upper   kp [N m/rad]  kd [N m s/rad]  torque [N m]"]
    for k, name in enumerate(contract.joint_names):
        lines.append(f"  {k:2d} {name:<24}{contract.default_pose[k]:7.3f}  {contract.joint_lower[k]:7.3f} "
                     f"{contract.joint_upper[k]:7.3f}  {contract.kp[k]:8.1f}  {contract.kd[k]:10.2f}  "
                     f"{contract.torque_limits[k]:10.1f}")
    order = "canonical" if layout.joint_names is None else ", ".join(layout.joint_names)
    lines += ["", f"policy joint order: {order}"]
    if layout.default_pose is not None:
        lines.append(f"policy q_default [rad]: {_vector(contract.policy_default_pose)}")
    lines += ["", f"observation frame o_t ({layout.frame_size(n)} values, float32), in this order:"]
    start = 0
    for term in layout.observation:
        width = term.width(n)
        unit, meaning, _ = TERMS[term.name]
        lines.append(f"  [{start:3d}:{start + width:3d}] {term.name:<18} {unit:<7} x {term.scale:<6g} {meaning}")
        start += width
    if layout.observation_clip is not None:
        lines.append(f"  then clipped to +-{layout.observation_clip:g}")
    lines += ["", "inputs:"]
    for item in layout.inputs:
        what = "o_t" if item.frames == 1 else (f"the last {item.frames} frames, oldest first, o_t last "
                                                f"(filled with the first frame at t = 0)")
        lines.append(f"  {item.name}: (N, {item.frames * layout.frame_size(n)}) = {what}")
    clip = f"a clipped to +-{layout.action_clip:g}, " if layout.action_clip is not None else ""
    rule = (f"q* = q_default + {layout.action_scale:g} * a" if layout.action == "normalised" else "q* = a [rad]")
    hold = "every control step" if layout.action_hold == 1 else f"every {layout.action_hold} control steps (held between)"
    lines += ["", f"action a (N, {n}), {layout.action}, policy joint order: {clip}{rule}, q* clipped to the joint "
              f"limits; a new action {hold}"]
    return "\n".join(lines)


def joint_frame_entry(spec) -> dict:
    """The robot's canonical joint frame as JSON (`frbench.robots.joint_frame.JointFrame.to_dict`), or
    ``{"reason": ...}`` saying why it has none."""
    from frbench.robots.joint_frame import JointFrameError, joint_frame

    try:
        return joint_frame(spec).to_dict()
    except JointFrameError as exc:
        return {"reason": str(exc)}


def joint_frame_text(entry: dict, joint_names) -> list[str]:
    """The lines of ``frbench spec`` that show the canonical joint frame (or why there is none)."""
    if "reason" in entry:
        return ["", f"canonical joint frame: none ({entry['reason']})"]
    lines = ["", "canonical joint frame (a policy with joint_frame 'canonical' sees canonical[j] = sign[j] * q[order[j]] "
             "+ offset[j]):", "  knees: " + ", ".join(f"{leg} {way}" for leg, way in entry["knees"].items())
             + ("; every knee points forward, so the robot is seen from behind (FL <-> RR, FR <-> RL, body x and y "
                "negated)" if entry["turned"] else "")]
    for k, name in enumerate(joint_names):
        joint = entry["order"][k]
        lines.append(f"  canonical {k:2d} = robot {joint:2d} {joint_names[joint]:<24} sign {entry['sign'][k]:+.0f}  "
                     f"offset {entry['offset'][k]:7.3f} rad")
    return lines


def g1_frame_entry(spec) -> dict | None:
    """A humanoid's G1 joint frame as JSON (`frbench.robots.humanoid_frame.HumanoidFrame.to_dict`), ``{"reason":
    ...}`` saying why it has none, or None for a quadruped."""
    from frbench.robots.humanoid_frame import HumanoidFrameError, humanoid_frame

    if spec.kind != "humanoid":
        return None
    try:
        return humanoid_frame(spec).to_dict(spec)
    except HumanoidFrameError as exc:
        return {"reason": str(exc)}


def g1_frame_text(entry: dict | None) -> list[str]:
    """The lines of ``frbench spec`` that show a humanoid's G1 joint frame (none for a quadruped)."""
    if entry is None:
        return []
    if "reason" in entry:
        return ["", f"G1 joint frame: none ({entry['reason']})"]
    lines = ["", "G1 joint frame (scripted-humanoid and keyframe-humanoid drive the robot through it: g1 = sign * q "
             "+ offset; a G1 joint it lacks is not driven):"]
    for name, joint in entry["joints"].items():
        lines.append(f"  {name:<26} " + ("-" if joint is None else
                                         f"= {joint['sign']:+.0f} * {joint['joint']:<20} {joint['offset']:+7.3f} rad"))
    return lines


def run(args) -> int:
    """Print the contract."""
    from frbench.errors import FrbenchError
    from frbench.policies.contract import contract_for, read_layout
    from frbench.robots import get_robot

    if args.policy and args.spec:
        raise FrbenchError("--policy and --spec: give one of them")
    spec = get_robot(args.robot)
    layout = read_layout(args.spec) if args.spec else policy_layout(args.policy, spec) if args.policy else None
    contract = contract_for(spec, layout)
    frame, g1_frame = joint_frame_entry(spec), g1_frame_entry(spec)
    if args.json:
        print(json.dumps({**contract.to_dict(), "joint_frame": frame,
                          **({"g1_joint_frame": g1_frame} if g1_frame is not None else {})}, indent=1))
    else:
        print("\n".join([contract_text(contract), *joint_frame_text(frame, contract.joint_names),
                         *g1_frame_text(g1_frame)]))
    return 0
