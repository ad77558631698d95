"""A generated quadruped's URDF and `RobotSpec`, from its `frbench.robots.morphology.MorphologyParams`.

Primitive geometry only (a box trunk, cylinder hips, box or cylinder thighs and calves, sphere feet), inertias
from the solids unless the parameters give them, joints in frbench's canonical order (FL, FR, RL, RR × hip,
thigh, calf). The file's joint convention (`frbench.robots.morphology`, "File conventions") is written into
the joints: an axis of direction −1 as ``-1 0 0`` / ``0 -1 0``, a joint zero that is not a straight leg as a
rotation about y in the thigh and calf joints' origins (the geometric zero angle, ``m · zero_pose`` with m = −1
on a leg whose knee points forward), and the standing pose and limits in the file's convention. With Go2's
convention the text is what it always was. `cached_spec` writes the URDF once per distinct text (atomically)
and returns its spec.
Units are SI: metres, kilograms, radians, newton-metres, seconds.
"""

from __future__ import annotations

from pathlib import Path

from frbench.io import atomic_write_text
from frbench.robots.morphology import (
    FOOT_LINKS,
    JOINT_NAMES,
    Inertia3,
    MorphologyParams,
    hip_position,
    nominal_height,
    total_mass,
    validate,
)
from frbench.robots.morphology_frame import default_pose, is_go2_convention, joint_limits, knee_mirror, leg_signs
from frbench.robots.spec import QUADRUPED_LEGS, RobotSpec, quadruped_groups


# --------------------------------------------------------------------------- inertia


def box_inertia(mass: float, sx: float, sy: float, sz: float) -> Inertia3:
    """Diagonal inertia [kg·m²] of a solid box of ``mass`` [kg] and sizes [m] about its centre."""
    return (mass * (sy * sy + sz * sz) / 12, mass * (sx * sx + sz * sz) / 12, mass * (sx * sx + sy * sy) / 12)


def cylinder_y_inertia(mass: float, radius: float, length: float) -> Inertia3:
    """Diagonal inertia [kg·m²] of a solid cylinder with its axis along y, about its centre."""
    across = mass * (3 * radius * radius + length * length) / 12
    return (across, mass * radius * radius / 2, across)


def sphere_inertia(mass: float, radius: float) -> Inertia3:
    """Diagonal inertia [kg·m²] of a solid sphere about its centre."""
    i = 0.4 * mass * radius * radius
    return (i, i, i)


# --------------------------------------------------------------------------- URDF


def _num(x: float) -> str:
    """Exact, round-tripping decimal text of ``x``."""
    return repr(float(x))


def _vec(*xs: float) -> str:
    """Space-separated exact decimals."""
    return " ".join(repr(float(x)) for x in xs)


def _link(name: str, mass: float, centre: str, inertia: Inertia3, collision: str) -> str:
    """A ``<link>`` with one inertial at ``centre`` (an ``"x y z"`` string) and one collision."""
    ixx, iyy, izz = inertia
    return (
        f'  <link name="{name}">\n'
        f'    <inertial>\n'
        f'      <origin xyz="{centre}" rpy="0 0 0"/>\n'
        f'      <mass value="{_num(mass)}"/>\n'
        f'      <inertia ixx="{_num(ixx)}" ixy="0" ixz="0" iyy="{_num(iyy)}" iyz="0" izz="{_num(izz)}"/>\n'
        f'    </inertial>\n'
        f'    <collision>\n'
        f'{collision}'
        f'    </collision>\n'
        f'  </link>\n'
    )


def _geometry(origin_xyz: str, shape: str, rpy: str = "0 0 0") -> str:
    """A collision's ``<origin>`` and ``<geometry>`` lines."""
    return f'      <origin xyz="{origin_xyz}" rpy="{rpy}"/>\n      <geometry><{shape}/></geometry>\n'


def _joint(name: str, parent: str, child: str, xyz: str, axis: str | None = None,
           limit: tuple[float, float, float, float] | None = None, pitch: float = 0.0) -> str:
    """A revolute joint (``axis`` and ``limit`` = (lower, upper, effort, velocity) given) or a fixed one; its
    origin turned by ``pitch`` [rad] about y (the child's zero angle; 0 written as ``rpy="0 0 0"``)."""
    kind = "fixed" if axis is None else "revolute"
    rpy = "0 0 0" if pitch == 0.0 else f"0 {_num(pitch)} 0"
    text = (
        f'  <joint name="{name}" type="{kind}">\n'
        f'    <origin xyz="{xyz}" rpy="{rpy}"/>\n'
        f'    <parent link="{parent}"/>\n'
        f'    <child link="{child}"/>\n'
    )
    if axis is not None and limit is not None:
        lo, hi, effort, velocity = limit
        text += (
            f'    <axis xyz="{axis}"/>\n'
            f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="{_num(effort)}" velocity="{_num(velocity)}"/>\n'
        )
    return text + "  </joint>\n"


def _trunk(p: MorphologyParams) -> str:
    """The ``base`` link: a box centred on the base frame, its centre of mass shifted by ``trunk_com_shift``."""
    size = _vec(p.trunk_length, p.trunk_width, p.trunk_height)
    inertia = p.trunk_inertia or box_inertia(p.trunk_mass, p.trunk_length, p.trunk_width, p.trunk_height)
    centre = _vec(*p.trunk_com_shift) if any(p.trunk_com_shift) else "0 0 0"  # unshifted URDFs stay byte-identical
    return _link("base", p.trunk_mass, centre, inertia, _geometry("0 0 0", f'box size="{size}"'))


def _leg(p: MorphologyParams, leg: str, hip_xy: tuple[float, float],
         lower: tuple[float, ...], upper: tuple[float, ...]) -> str:
    """Links and joints of one leg; ``lower``/``upper`` are this leg's 3 joint limits."""
    sx, sy = leg_signs(leg)
    hip, thigh, calf, foot = (f"{leg}_{part}" for part in ("hip", "thigh", "calf", "foot"))
    hip_centre = _vec(0.0, sy * p.hip_length / 2, 0.0)
    thigh_centre = _vec(0.0, 0.0, -p.thigh_length / 2)
    calf_centre = _vec(0.0, 0.0, -p.calf_length / 2)
    hip_inertia = p.hip_inertia or cylinder_y_inertia(p.hip_mass, p.hip_radius, p.hip_length)
    thigh_inertia = p.thigh_inertia or box_inertia(p.thigh_mass, p.thigh_height, p.thigh_width, p.thigh_length)
    calf_inertia = p.calf_inertia or box_inertia(p.calf_mass, p.calf_height, p.calf_width, p.calf_length)
    thigh_box = f'box size="{_vec(p.thigh_height, p.thigh_width, p.thigh_length)}"'
    calf_box = f'box size="{_vec(p.calf_height, p.calf_width, p.calf_length)}"'
    cylinder = f'cylinder radius="{_num(p.hip_radius)}" length="{_num(p.hip_length)}"'
    hip_axis, thigh_axis, calf_axis = _axes(p)
    mirror = knee_mirror(p, leg)
    thigh_zero, calf_zero = (mirror * z + 0.0 for z in p.zero_pose)  # geometric zero angles about +y [rad]
    return "".join((
        _joint(f"{hip}_joint", "base", hip, _vec(sx * hip_xy[0], sy * hip_xy[1], 0.0), hip_axis,
               (lower[0], upper[0], p.hip_torque, p.hip_velocity)),
        _link(hip, p.hip_mass, hip_centre, hip_inertia, _geometry(hip_centre, cylinder, "1.5707963267948966 0 0")),
        _joint(f"{thigh}_joint", hip, thigh, _vec(0.0, sy * p.hip_length, 0.0), thigh_axis,
               (lower[1], upper[1], p.thigh_torque, p.thigh_velocity), thigh_zero),
        _link(thigh, p.thigh_mass, thigh_centre, thigh_inertia, _geometry(thigh_centre, thigh_box)),
        _joint(f"{calf}_joint", thigh, calf, _vec(0.0, 0.0, -p.thigh_length), calf_axis,
               (lower[2], upper[2], p.calf_torque, p.calf_velocity), calf_zero),
        _link(calf, p.calf_mass, calf_centre, calf_inertia, _geometry(calf_centre, calf_box)),
        _joint(f"{foot}_joint", calf, foot, _vec(0.0, 0.0, -p.calf_length)),
        _link(foot, p.foot_mass, "0 0 0", sphere_inertia(p.foot_mass, p.foot_radius),
              _geometry("0 0 0", f'sphere radius="{_num(p.foot_radius)}"')),
    ))


def _axes(p: MorphologyParams) -> tuple[str, str, str]:
    """The hip (x), thigh and calf (y) joint axes of the file, ``joint_axes`` directions."""
    a_h, a_t, a_c = ("1" if a > 0 else "-1" for a in p.joint_axes)
    return f"{a_h} 0 0", f"0 {a_t} 0", f"0 {a_c} 0"


def urdf_string(params: MorphologyParams, name: str = "morph") -> str:
    """The URDF text of ``params``: primitives only (no meshes, no visuals).

    Args:
        params: the morphology (validated here).
        name: the ``<robot name>``.

    Returns:
        A URDF with 17 links (``base`` + 4 × hip, thigh, calf, foot), 12 revolute
        and 4 fixed joints; see the module docstring for the layout.
    """
    validate(params)
    hip_xy = hip_position(params)
    lower, upper = joint_limits(params)
    parts = ['<?xml version="1.0"?>\n', f'<robot name="{name}">\n', _trunk(params)]
    for i, leg in enumerate(QUADRUPED_LEGS):
        parts.append(_leg(params, leg, hip_xy, lower[3 * i:3 * i + 3], upper[3 * i:3 * i + 3]))
    parts.append("</robot>\n")
    return "".join(parts)


def write_urdf(params: MorphologyParams, path: str | Path, name: str = "morph") -> Path:
    """Write :func:`urdf_string` of ``params`` to ``path`` (parents created); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(urdf_string(params, name=name), encoding="utf-8")
    return path


# --------------------------------------------------------------------------- RobotSpec


def spec_from_params(
    params: MorphologyParams,
    name: str,
    urdf_path: str | Path,
    *,
    source: str = "frbench morphology generator",
    license: str = "BSD-3-Clause",
) -> RobotSpec:
    """The :class:`RobotSpec` of a generated quadruped.

    Args:
        params: the morphology.
        name: registry name of the robot.
        urdf_path: where :func:`write_urdf` wrote (or will write) its URDF.
        source, license: provenance shown by ``frbench robots``.

    Returns:
        A quadruped spec with 12 joints in canonical order, 4 mass groups,
        13 contact groups, physics_dt 0.005 s.
    """
    validate(params)
    hips, thighs, calves = ([f"{leg}_{part}" for leg in QUADRUPED_LEGS] for part in ("hip", "thigh", "calf"))
    mass_groups, contact_groups, knee_groups = quadruped_groups("base", tuple(hips), tuple(thighs), tuple(calves))
    lower, upper = joint_limits(params)
    shapes = tuple((h, "cylinder") for h in hips) + tuple((f, "sphere") for f in FOOT_LINKS)
    return RobotSpec(
        name=name,
        kind="quadruped",
        urdf_path=Path(urdf_path),
        joint_names=JOINT_NAMES,
        default_pose=default_pose(params),
        kp=(float(params.kp),) * 12,
        kd=(float(params.kd),) * 12,
        torque_limits=(float(params.hip_torque), float(params.thigh_torque), float(params.calf_torque)) * 4,
        joint_lower=lower,
        joint_upper=upper,
        foot_links=FOOT_LINKS,
        mass_groups=mass_groups,
        contact_groups=contact_groups,
        knee_groups=knee_groups,
        nominal_height=nominal_height(params),
        physics_dt=0.005,
        collision_shapes=shapes,
        source=source,
        license=license,
        notes=f"primitive-geometry quadruped, total mass {total_mass(params):.3f} kg" + _convention_note(params),
    )


def _convention_note(params: MorphologyParams) -> str:
    """``""`` for Go2's convention, else the file's knees, axes and zero pose."""
    if is_go2_convention(params):
        return ""
    return (f"; knees {params.knees[0]} (front), {params.knees[1]} (rear), joint axes {params.joint_axes}, "
            f"zero pose {params.zero_pose} rad")


def cached_spec(params: MorphologyParams, name: str, path: str | Path, **spec_kwargs) -> RobotSpec:
    """Write ``params``' URDF to ``path`` unless it already holds that text (atomically), and return its spec.

    ``spec_kwargs`` go to :func:`spec_from_params` (e.g. ``source``).
    """
    path = Path(path)
    text = urdf_string(params, name=name)
    try:
        current = path.read_text(encoding="utf-8")
    except OSError:
        current = None
    if current != text:
        atomic_write_text(path, text)
    return spec_from_params(params, name, path, **spec_kwargs)
