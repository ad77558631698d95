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
hash (file names keep only safe characters of the robot's name, so nothing is
written outside the cache; at most `CACHE_MAX_FILES` files, least recently used
deleted first); its sha256 is the robot's checksum in every results file.
"""

from __future__ import annotations

import dataclasses
import re
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from frbench.errors import RobotFileError
from frbench.io import atomic_write_text, sha256_file, sha256_text
from frbench.portable_products import transposed_times
from frbench.robots.mesh_vertices import binary_stl_vertices, text_mesh_vertices
from frbench.robots.paths import cache_dir
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import Collision, UrdfTree, merge_fixed_joints, parse_urdf, rotate_root, write_urdf

#: Bump when the derivation changes (invalidates caches, changes checksums).
SIM_URDF_VERSION = 3
#: Principal moments below this fraction of a link's largest count as zero (round-off).
ROUND_OFF = 1e-9
#: [kg·m²] moments below this count as zero whatever the link (a 1 g, 1 mm sphere has 4e-10).
NEGLIGIBLE_MOMENT = 1e-12
#: A link whose smallest moment is zero (point mass, rod) gets this fraction of its largest on the diagonal.
MIN_MOMENT_FRACTION = 1e-3
#: Radius [m] of the sphere whose inertia a point-mass link (all moments zero) gets.
POINT_MASS_RADIUS = 0.01
#: A link whose largest moment is below this [kg·m²] and breaks the triangle inequality is balanced, not refused.
SMALL_LINK_MOMENT = 1e-4
#: A triangle-inequality violation up to this fraction of the largest moment is repaired, not refused.
TRIANGLE_SLACK = 0.1
#: [rad/s] velocity limit written for an actuated joint whose file gives none (no frbench code reads it).
DEFAULT_VELOCITY_LIMIT = 100.0
#: [kg] mass given to a massless foot link (kept apart for its contacts).
MASSLESS_FOOT_MASS = 1e-6
#: The cache keeps at most this many files per folder; the least recently used go first.
CACHE_MAX_FILES = 200
#: [s] a cached file used this recently is never pruned: another process may be about to load it.
CACHE_MIN_AGE_S = 3600.0
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

    def lineage(self) -> frozenset[frozenset[str]]:
        """Every pair of links one of which is an ancestor of the other (never in contact in either simulator)."""
        return frozenset(frozenset((ancestor, link)) for link in self.links for ancestor in self.ancestors(link))

    @property
    def total_mass(self) -> float:
        """Sum of link masses [kg]."""
        return float(sum(m for _, m in self.masses))


def _check_inertial(tree: UrdfTree, feet=()) -> None:
    label = str(tree.path)
    for link in tree.links.values():
        merged = f" (with merged links {', '.join(link.merged)})" if link.merged else ""
        if link.name in feet and link.mass == 0 and not tree.child_joints(link.name):
            # a massless foot frame kept as a link for its contacts: the smallest mass both simulators accept
            link.mass, link.has_inertial = MASSLESS_FOOT_MASS, True
            link.inertia = np.eye(3) * 0.4 * link.mass * POINT_MASS_RADIUS**2
        if not link.has_inertial and link.mass == 0 and tree.child_joints(link.name) and tree.parent_joint(link.name):
            # a link with no <inertial> between two joints: the virtual link of a multi-axis joint (a hip
            # as three revolute joints, human.urdf); MuJoCo refuses a massless moving body, so it gets the
            # same negligible mass as a massless foot
            link.mass, link.has_inertial = MASSLESS_FOOT_MASS, True
            link.inertia = np.eye(3) * 0.4 * link.mass * POINT_MASS_RADIUS**2
        parent = tree.parent_joint(link.name)
        if link.mass == 0 and not link.has_inertial and parent is not None and parent.type != "fixed":
            raise RobotFileError(
                f"{label}: link {link.name!r} has no <inertial> and nothing below it, so joint {parent.name!r} moves "
                "no mass (a simulator cannot integrate it); give the link an <inertial> or make the joint fixed in the URDF"
            )
        if link.mass <= 0 or not np.isfinite(link.mass):
            raise RobotFileError(
                f"{label}: link {link.name!r}{merged} has mass {link.mass:g} kg; every simulated link needs a positive mass: "
                "set its <inertial><mass> in the URDF"
            )
        eig = np.linalg.eigvalsh(0.5 * (link.inertia + link.inertia.T))
        scale = max(float(np.max(np.abs(eig))), 1e-12)
        # round-off: moments within ROUND_OFF of the largest count as zero (a point-mass foot gives -2e-22)
        eig = np.where((np.abs(eig) <= ROUND_OFF * scale) | (np.abs(eig) < NEGLIGIBLE_MOMENT), 0.0, eig)
        if eig[-1] == 0:  # a point mass: the inertia of a 1 cm sphere of its mass
            link.inertia = np.eye(3) * 0.4 * link.mass * POINT_MASS_RADIUS**2
            continue
        if eig[0] < 0:
            raise RobotFileError(
                f"{label}: link {link.name!r}{merged} has an inertia that is not positive definite "
                f"(principal moments {', '.join(f'{e:.3g}' for e in eig)} kg·m²); fix its <inertia> in the URDF"
            )
        if eig[0] == 0:
            # a point mass or a rod: give it the smallest moment both simulators accept
            link.inertia = link.inertia + np.eye(3) * MIN_MOMENT_FRACTION * scale
            eig = np.linalg.eigvalsh(0.5 * (link.inertia + link.inertia.T))
        if eig[0] + eig[1] < eig[2] * (1 - 1e-6):
            if eig[0] + eig[1] >= eig[2] * (1 - TRIANGLE_SLACK):
                # a small violation (a rounded file): raise the smallest moment to meet the inequality
                vals, vecs = np.linalg.eigh(0.5 * (link.inertia + link.inertia.T))
                vals[0] = vals[2] - vals[1] + 1e-3 * vals[2]
                link.inertia = vecs @ np.diag(vals) @ vecs.T
                continue
            if eig[2] > SMALL_LINK_MOMENT:
                raise RobotFileError(
                    f"{label}: link {link.name!r}{merged} inertia violates the triangle inequality "
                    f"(principal moments {', '.join(f'{e:.3g}' for e in eig)} kg·m²); fix its <inertia> in the URDF"
                )
            # a tiny link (a point-mass foot): its moments become their mean, as MuJoCo's balanceinertia does
            link.inertia = np.eye(3) * float(np.mean(eig))


def _apply_joint_limits(tree: UrdfTree, spec: RobotSpec) -> None:
    overrides = {name: (lo, hi) for name, lo, hi in spec.joint_limit_overrides}
    label = str(tree.path)
    for name in spec.joint_names:
        if name not in tree.joints:
            raise RobotFileError(f"{label}: joint {name!r} of robot {spec.name!r} is not in the file")
    actuated = set(spec.joint_names)  # their limits and effort come from the spec (checked when it was built)
    for joint in tree.moving_joints():
        if joint.name in actuated:
            if joint.type == "continuous":
                joint.type = "revolute"
            if joint.velocity is None:  # urdfdom (Pinocchio) needs one; frbench's PD does not read it
                joint.velocity = DEFAULT_VELOCITY_LIMIT
            continue
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


#: COLLADA ``<up_axis>`` → the rotation that turns the document's vertices z-up (URDF frames are z-up).
def _aabb_primitive(vertices: np.ndarray, collision: Collision, kind: str, label) -> Collision:
    """The primitive fitted to the axis-aligned bounding box of ``vertices`` (mesh frame, before scaling)."""
    if len(vertices) == 0:
        raise RobotFileError(f"{label}: collision mesh {collision.mesh} has no vertices frbench can read")
    scaled = vertices * np.asarray(collision.size)
    low, high = scaled.min(axis=0), scaled.max(axis=0)
    center, extent = (low + high) / 2, np.maximum(high - low, 1e-4)
    origin = collision.origin.copy()
    origin[:3, 3] = collision.origin[:3, :3] @ center + collision.origin[:3, 3]
    if kind == "sphere":
        return Collision("sphere", (float(extent.max() / 2),), origin)
    if kind == "cylinder":
        return Collision("cylinder", (float(max(extent[0], extent[1]) / 2), float(extent[2])), origin)
    return Collision("box", tuple(float(v) for v in extent), origin)


def _fit_meshes(tree: UrdfTree, spec: RobotSpec) -> None:
    """Replace every mesh collision by the primitive MuJoCo's compiler fits to it.

    MuJoCo fits a box along the mesh's principal axes of inertia; a humanoid's sole must
    lie flat on the ground, so a humanoid's foot meshes get the box along the mesh's own
    axes instead (Talos' ankle mesh has principal axes 10° off its sole, and the fitted
    box stood on an edge and tipped the robot over backwards).
    """
    import mujoco

    soles = set(spec.foot_links) if spec.kind == "humanoid" else set()
    jobs: list[tuple[str, int, Collision]] = []
    for link in tree.links.values():
        for index, collision in enumerate(link.collisions):
            if collision.kind != "mesh":
                continue
            vertices = text_mesh_vertices(collision.mesh)
            if vertices is None and link.name in soles:
                vertices = binary_stl_vertices(collision.mesh)
            if vertices is None:
                jobs.append((link.name, index, collision))
            else:
                link.collisions[index] = _aabb_primitive(vertices, collision, spec.shape_of(link.name), tree.path)
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


def _trim_shins(tree: UrdfTree, feet) -> None:
    """Shorten each box or cylinder of a foot's parent link to end a foot radius short of the foot's centre (the foot stands).

    A box fitted to a lower-leg mesh that includes the foot reaches the ground
    beside the foot sphere; along its longest axis it is cut back to the foot
    centre when that removes less than half of it.
    """
    for foot in feet:
        joint = tree.parent_joint(foot)
        if joint is None:
            continue
        foot_link = tree.links[foot]
        centre = joint.origin[:3, 3] + (joint.origin[:3, :3] @ foot_link.collisions[0].origin[:3, 3] if foot_link.collisions else 0)
        radius = max((c.size[0] for c in foot_link.collisions if c.kind == "sphere"), default=0.0)
        shin = tree.links[joint.parent]
        for index, box in enumerate(shin.collisions):
            if box.kind not in ("box", "cylinder"):
                continue
            rot, pos = box.origin[:3, :3], box.origin[:3, 3]
            local = transposed_times(rot, centre - pos)
            axis = int(np.argmax(box.size)) if box.kind == "box" else 2
            half = (box.size[axis] if box.kind == "box" else box.size[1]) / 2
            end = np.sign(local[axis]) * half  # the box end on the foot's side
            cut = local[axis] - np.sign(local[axis]) * radius  # a foot radius short of the foot centre
            if abs(local[axis]) >= half + radius or abs(end - cut) > half or np.sign(cut) != np.sign(local[axis]):
                continue
            keep = -end
            new_center, new_length = (keep + cut) / 2, abs(cut - keep)
            size = list(box.size)
            size[axis if box.kind == "box" else 1] = new_length
            shift = np.zeros(3)
            shift[axis] = new_center
            origin = box.origin.copy()
            origin[:3, 3] = pos + rot @ shift
            shin.collisions[index] = Collision(box.kind, tuple(size), origin)


def build_sim_tree(spec: RobotSpec) -> UrdfTree:
    """The checked, merged, mesh-free kinematic tree of ``spec`` (not cached)."""
    tree = parse_urdf(spec.urdf_path)
    for foot in spec.foot_links:
        if foot not in tree.links:
            raise RobotFileError(f"{spec.urdf_path}: foot link {foot!r} of robot {spec.name!r} is not in the file")
    _apply_joint_limits(tree, spec)
    if spec.root_rotation:
        tree = rotate_root(tree, spec.root_rotation)
    tree = merge_fixed_joints(tree, keep_links=set(spec.foot_links))
    _check_inertial(tree, set(spec.foot_links))
    _fit_meshes(tree, spec)
    if spec.trim_shins:
        _trim_shins(tree, spec.foot_links)
    names = set(tree.links)
    for group in (*spec.mass_groups, *spec.contact_groups, *spec.knee_groups):
        for link in group.links:
            if link not in names:
                raise RobotFileError(
                    f"{spec.urdf_path}: group {group.name!r} of robot {spec.name!r} names link {link!r}, "
                    f"which is not a simulated link (links: {', '.join(tree.links)})"
                )
    tree.name = spec.name
    if next(iter(tree.links)) != tree.root:  # the backends read the first link as the root
        root = tree.root
        tree.links = {root: tree.links[root], **{k: v for k, v in tree.links.items() if k != root}}
    return tree


def _spec_key(spec: RobotSpec, source_sha: str) -> str:
    """Content key of the simulation URDF: only the fields the file depends on."""
    fields = dataclasses.asdict(spec)
    fields["urdf_path"] = source_sha
    for key in ("source", "license", "notes", "extra", "name", "kp", "kd", "nominal_height", "physics_dt", "default_pose"):
        fields.pop(key, None)
    return sha256_text(f"v{SIM_URDF_VERSION}:{fields!r}")[:20]


def safe_file_stem(name: str) -> str:
    """``name`` reduced to letters, digits, '_' and '-' (at most 64): a file name that stays in its folder."""
    stem = re.sub(r"[^A-Za-z0-9_-]", "_", name)[:64]
    return stem or "robot"


def prune_cache(folder: Path, keep: int = CACHE_MAX_FILES, min_age_s: float = CACHE_MIN_AGE_S) -> None:
    """Delete the least recently used files of ``folder`` beyond ``keep``, sparing those used within ``min_age_s``.

    The cache stays bounded at ``keep`` files plus what running processes used in the last ``min_age_s`` seconds.
    """
    try:
        stamped = sorted(((p.stat().st_mtime, p) for p in folder.iterdir() if p.is_file()), reverse=True)
    except OSError:
        return
    newest_removable = time.time() - min_age_s
    for mtime, old in stamped[keep:]:
        if mtime > newest_removable:
            continue
        try:
            old.unlink()
        except OSError:
            pass


def sim_robot_file(spec: RobotSpec) -> SimRobotFile:
    """The simulation URDF of ``spec``, generated once per process and cached on disk.

    If the cached file has vanished since this process first asked (another process pruned the cache, or
    ``frbench cache clear`` ran), it is generated again: its content, and so its checksum, are the same.
    """
    found = _sim_robot_file(spec)
    if found.path.is_file():
        return found
    _sim_robot_file.cache_clear()
    return _sim_robot_file(spec)


@lru_cache(maxsize=256)
def _sim_robot_file(spec: RobotSpec) -> SimRobotFile:
    source_sha = sha256_file(spec.urdf_path) if Path(spec.urdf_path).is_file() else ""
    if not source_sha:
        raise RobotFileError(f"{spec.urdf_path}: no such URDF file (robot {spec.name!r})")
    folder = cache_dir() / "sim_urdf"
    path = folder / f"{safe_file_stem(spec.name)}-{_spec_key(spec, source_sha)}.urdf"
    if path.is_file():
        tree = parse_urdf(path)
        path.touch()
    else:
        tree = build_sim_tree(spec)
        atomic_write_text(path, write_urdf(tree))
        prune_cache(folder)
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
    try:
        model = mj.compile()
    except ValueError as exc:
        raise RobotFileError(f"{spec.urdf_path}: MuJoCo cannot compile its simulation URDF ({str(exc).splitlines()[0]})") from None
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


def crossing_links(spec: RobotSpec) -> tuple[tuple[str, str], ...]:
    """The pairs of `self_collision_exclusions` that are not ancestor and descendant: unrelated links (two legs,
    a leg and the trunk) that overlap at the standing or the zero pose and so pass through each other."""
    lineage = sim_robot_file(spec).lineage()
    return tuple(pair for pair in self_collision_exclusions(spec) if frozenset(pair) not in lineage)
