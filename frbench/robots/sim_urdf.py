"""The simulation URDF: one file that Pinocchio, MuJoCo and PyBullet all load.

From a robot's source URDF and its `RobotSpec` this module derives a single
self-contained URDF so that the three libraries see exactly the same robot:

* fixed joints are merged into their parent link (exact inertia combination),
  except the feet's, which stay links so foot contacts can be told apart;
  PyBullet's own ``URDF_MERGE_FIXED_LINKS`` is never used (it loses CoM offsets);
* collision meshes are replaced by primitives that MuJoCo's compiler fits to
  each mesh (``fitaabb``), written into the URDF, so both simulators collide
  with the same boxes, spheres and cylinders;
* continuous joints get the spec's limits; visuals, ``<dynamics>`` damping and
  friction, transmissions and simulator extensions are dropped;
* every link is checked: positive mass, positive-definite inertia obeying the
  triangle inequality, moving joints with limits and effort.

The result is cached under :func:`frbench.robots.paths.cache_dir` by content
hash; its sha256 is the robot's checksum in every results file.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from frbench.errors import RobotFileError
from frbench.io import atomic_write_text, sha256_file, sha256_text
from frbench.robots.paths import cache_dir
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import Collision, UrdfTree, merge_fixed_joints, parse_urdf, write_urdf

#: Bump when the derivation changes (invalidates caches, changes checksums).
SIM_URDF_VERSION = 1
_MUJOCO_GEOM = {"box": "mjGEOM_BOX", "sphere": "mjGEOM_SPHERE", "cylinder": "mjGEOM_CYLINDER"}


@dataclass(frozen=True)
class SimRobotFile:
    """The derived simulation URDF of a robot.

    Attributes:
        path: the cached URDF file (absolute).
        sha256: checksum of its text.
        source_sha256: checksum of the source URDF.
        links: link names in file order (root first).
        parent: per link, its parent link (root: None).
        masses: per link mass [kg] after merging.
    """

    path: Path
    sha256: str
    source_sha256: str
    links: tuple[str, ...]
    parent: tuple[tuple[str, str | None], ...]
    masses: tuple[tuple[str, float], ...]

    def ancestors(self, link: str) -> list[str]:
        """Links above ``link`` up to the root."""
        parents = dict(self.parent)
        out, current = [], parents[link]
        while current is not None:
            out.append(current)
            current = parents[current]
        return out

    @property
    def total_mass(self) -> float:
        """Sum of link masses [kg]."""
        return float(sum(m for _, m in self.masses))


def _check_inertial(tree: UrdfTree) -> None:
    label = str(tree.path)
    for link in tree.links.values():
        merged = f" (with merged links {', '.join(link.merged)})" if link.merged else ""
        if link.mass <= 0 or not np.isfinite(link.mass):
            raise RobotFileError(
                f"{label}: link {link.name!r}{merged} has mass {link.mass:g} kg; every simulated link needs a positive mass"
            )
        eig = np.linalg.eigvalsh(0.5 * (link.inertia + link.inertia.T))
        scale = max(float(np.max(np.abs(eig))), 1e-12)
        if eig[0] <= 1e-9 * scale or eig[0] <= 0:
            raise RobotFileError(
                f"{label}: link {link.name!r}{merged} has an inertia that is not positive definite "
                f"(principal moments {', '.join(f'{e:.3g}' for e in eig)} kg·m²)"
            )
        if eig[0] + eig[1] < eig[2] * (1 - 1e-6):
            raise RobotFileError(
                f"{label}: link {link.name!r}{merged} inertia violates the triangle inequality "
                f"(principal moments {', '.join(f'{e:.3g}' for e in eig)} kg·m²)"
            )


def _apply_joint_limits(tree: UrdfTree, spec: RobotSpec) -> None:
    overrides = {name: (lo, hi) for name, lo, hi in spec.joint_limit_overrides}
    label = str(tree.path)
    for name in spec.joint_names:
        if name not in tree.joints:
            raise RobotFileError(f"{label}: joint {name!r} of robot {spec.name!r} is not in the file")
    for joint in tree.moving_joints():
        if joint.name in overrides:
            joint.lower, joint.upper = overrides[joint.name]
            if joint.type == "continuous":
                joint.type = "revolute"
        if joint.type == "continuous":
            raise RobotFileError(
                f"{label}: joint {joint.name!r} is continuous (no limits); give it limits in the robot's sidecar "
                "(joint_limits) — a leg joint needs lower and upper limits"
            )
        if joint.lower is None or joint.upper is None or not joint.lower < joint.upper:
            raise RobotFileError(
                f"{label}: joint {joint.name!r} has no usable limits (lower={joint.lower}, upper={joint.upper}); "
                "expected <limit lower=... upper=...> with lower < upper"
            )
        if joint.effort is None or joint.effort <= 0:
            raise RobotFileError(
                f"{label}: joint {joint.name!r} has no positive effort limit (effort={joint.effort}); "
                "expected <limit effort=...> in N·m"
            )
    for name, lower, upper, effort in zip(spec.joint_names, spec.joint_lower, spec.joint_upper, spec.torque_limits):
        joint = tree.joints[name]
        joint.lower, joint.upper, joint.effort = lower, upper, effort


def _fit_meshes(tree: UrdfTree, spec: RobotSpec) -> None:
    """Replace every mesh collision by the primitive MuJoCo's compiler fits to it."""
    import mujoco

    jobs: list[tuple[str, int, Collision]] = []
    for link in tree.links.values():
        for index, collision in enumerate(link.collisions):
            if collision.kind == "mesh":
                jobs.append((link.name, index, collision))
    if not jobs:
        return
    mj = mujoco.MjSpec()
    mj.compiler.fitaabb = True
    mj.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    kinds = []
    for number, (link_name, _, collision) in enumerate(jobs):
        mesh = mj.add_mesh()
        mesh.name = f"m{number}"
        mesh.file = str(collision.mesh)
        mesh.scale = list(collision.size)
        body = mj.worldbody.add_body()
        body.mass, body.inertia = 1.0, [1.0, 1.0, 1.0]
        geom = body.add_geom()
        kind = spec.shape_of(link_name)
        if kind not in _MUJOCO_GEOM:
            raise RobotFileError(f"robot {spec.name!r}: collision shape {kind!r} for link {link_name!r}, expected box, sphere or cylinder")
        geom.type = getattr(mujoco.mjtGeom, _MUJOCO_GEOM[kind])
        geom.meshname = mesh.name
        geom.pos = collision.origin[:3, 3]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, collision.origin[:3, :3].flatten())
        geom.quat = quat
        kinds.append(kind)
    try:
        model = mj.compile()
    except ValueError as exc:
        raise RobotFileError(f"{tree.path}: MuJoCo could not read a collision mesh: {exc}") from None
    for number, ((link_name, index, _), kind) in enumerate(zip(jobs, kinds)):
        size = model.geom_size[number]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[number])
        origin = np.eye(4)
        origin[:3, :3] = rot.reshape(3, 3)
        origin[:3, 3] = model.geom_pos[number]
        if kind == "box":
            fitted = Collision("box", tuple(2 * size), origin)
        elif kind == "sphere":
            fitted = Collision("sphere", (float(size[0]),), origin)
        else:
            fitted = Collision("cylinder", (float(size[0]), 2 * float(size[1])), origin)
        tree.links[link_name].collisions[index] = fitted


def build_sim_tree(spec: RobotSpec) -> UrdfTree:
    """The checked, merged, mesh-free kinematic tree of ``spec`` (not cached)."""
    tree = parse_urdf(spec.urdf_path)
    for foot in spec.foot_links:
        if foot not in tree.links:
            raise RobotFileError(f"{spec.urdf_path}: foot link {foot!r} of robot {spec.name!r} is not in the file")
    _apply_joint_limits(tree, spec)
    tree = merge_fixed_joints(tree, keep_links=set(spec.foot_links))
    _check_inertial(tree)
    _fit_meshes(tree, spec)
    names = set(tree.links)
    for group in (*spec.mass_groups, *spec.contact_groups, *spec.knee_groups):
        for link in group.links:
            if link not in names:
                raise RobotFileError(
                    f"{spec.urdf_path}: group {group.name!r} of robot {spec.name!r} names link {link!r}, "
                    f"which is not a simulated link (links: {', '.join(tree.links)})"
                )
    tree.name = spec.name
    return tree


def _spec_key(spec: RobotSpec, source_sha: str) -> str:
    fields = dataclasses.asdict(spec)
    fields["urdf_path"] = source_sha
    for key in ("source", "license", "notes", "extra", "name"):
        fields.pop(key, None)
    return sha256_text(f"v{SIM_URDF_VERSION}:{fields!r}")[:20]


@lru_cache(maxsize=256)
def sim_robot_file(spec: RobotSpec) -> SimRobotFile:
    """The simulation URDF of ``spec``, generated once and cached on disk."""
    source_sha = sha256_file(spec.urdf_path) if Path(spec.urdf_path).is_file() else ""
    if not source_sha:
        raise RobotFileError(f"{spec.urdf_path}: no such URDF file (robot {spec.name!r})")
    path = cache_dir() / "sim_urdf" / f"{spec.name}-{_spec_key(spec, source_sha)}.urdf"
    if path.is_file():
        tree = parse_urdf(path)
    else:
        tree = build_sim_tree(spec)
        atomic_write_text(path, write_urdf(tree))
    parents = tuple((name, (tree.parent_joint(name).parent if tree.parent_joint(name) else None)) for name in tree.links)
    return SimRobotFile(
        path=path.resolve(),
        sha256=sha256_file(path),
        source_sha256=source_sha,
        links=tuple(tree.links),
        parent=parents,
        masses=tuple((name, link.mass) for name, link in tree.links.items()),
    )


@lru_cache(maxsize=256)
def self_collision_exclusions(spec: RobotSpec) -> tuple[tuple[str, str], ...]:
    """Pairs of links whose collision geometry overlaps at the standing or the zero pose.

    Fitted primitives are coarser than meshes, so neighbouring links (Go2's
    rear hips, for example) can overlap where the meshes did not. Like a
    planning library's "default collision matrix", such pairs are excluded from
    self-collision — in both simulators. Ancestor/descendant pairs are always
    excluded as well (see the backends).
    """
    import mujoco

    sim = sim_robot_file(spec)
    mj = mujoco.MjSpec.from_file(str(sim.path))
    mj.compiler.fusestatic = False
    mj.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    mj.worldbody.first_body().add_freejoint()
    model = mj.compile()
    data = mujoco.MjData(model)
    pairs = set()
    for pose in (spec.default_pose, np.zeros(spec.n_joints)):
        data.qpos[:] = 0
        data.qpos[2] = 5.0
        data.qpos[3] = 1.0
        for name, angle in zip(spec.joint_names, pose):
            data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
        mujoco.mj_forward(model, data)
        for contact in data.contact[: data.ncon]:
            a = model.body(model.geom_bodyid[contact.geom1]).name
            b = model.body(model.geom_bodyid[contact.geom2]).name
            pairs.add(tuple(sorted((a, b))))
    return tuple(sorted(pairs))
