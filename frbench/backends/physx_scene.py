"""One PhysX simulation (SAPIEN 3): a scene with the terrain and the robot, set up by frbench's conventions.

`frbench.backends.physx_backend` holds N of them. What the set-up does, and why:

* SAPIEN is imported quietly (`import_sapien`): on a machine without a system Vulkan loader its import warns
  ``Failed to find system libvulkan. Fallback to SAPIEN builtin libvulkan.``; frbench's scenes have no render
  system and never touch Vulkan, so that one message, matched by its text, is dropped;
* the scene (`PhysxSettings`): the TGS solver with 4 position and 0 velocity iterations, the settings legged_gym
  (``LeggedRobotCfg.sim.physx``) and Isaac Lab's quadruped configurations train with, so that PhysX cells show
  a policy in its training engine as it was set up there; enhanced determinism (the same inputs give
  bit-identical trajectories, so ``frbench verify`` is exact), no worker threads, the robot's physics step;
* the robot is frbench's simulation URDF (`frbench.robots.sim_urdf`), loaded by SAPIEN's URDF loader with a
  floating root; no link damping, no joint friction, damping or armature, no sleeping, and speed caps far above
  the divergence limit (PhysX caps link speeds at 10 m/s and 50 rad/s and joint speeds at 100 rad/s by default);
* self-collision (`collision_bits`): PhysX ignores parent/child pairs only; frbench excludes each link against
  all its ancestors (as MuJoCo and PyBullet do here) and the pairs of
  `frbench.robots.sim_urdf.self_collision_exclusions`. SAPIEN's filter ignores two shapes of one articulation
  whose ``collision_groups[2]`` words share a bit; one bit per root-to-leaf chain ignores exactly the
  ancestor pairs, one more bit per other excluded pair. A robot needing more than 32 bits, or with more links
  than a PhysX articulation takes, is refused (`physx_refusal`);
* friction: PhysX averages two materials' coefficients, so robot and terrain share one material per
  simulation whose coefficient is the protocol's friction (self-contacts then use it too, where MuJoCo and
  PyBullet use 1); no restitution.
"""

from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass

from frbench.errors import FrbenchError
from frbench.robots.sim_urdf import SimRobotFile, self_collision_exclusions, sim_robot_file
from frbench.robots.spec import RobotSpec

#: Bits of the collision-group word SAPIEN's filter reads for ignored pairs within an articulation.
COLLISION_BITS = 32
#: Links a PhysX articulation holds at most (PxArticulationReducedCoordinate).
MAX_ARTICULATION_LINKS = 64


@dataclass(frozen=True)
class PhysxSettings:
    """The PhysX scene and body settings of every frbench simulation.

    Attributes:
        position_iterations: solver position iterations per articulation.
        velocity_iterations: solver velocity iterations per articulation.
        enhanced_determinism: PhysX's enhanced determinism (results independent of insertion order and history
            of other actors).
        tgs: the temporal Gauss-Seidel solver (else PGS).
        max_link_speed: cap on every link's linear [m/s] and angular [rad/s] speed.
        max_joint_speed: cap on every joint's speed [rad/s].
    """

    position_iterations: int = 4
    velocity_iterations: int = 0
    enhanced_determinism: bool = True
    tgs: bool = True
    max_link_speed: float = 1e4
    max_joint_speed: float = 1e4


def import_sapien():
    """The ``sapien`` module, imported without its libvulkan fallback warning (module docstring); a
    `FrbenchError` with the install command when the ``physx`` extra is missing."""
    try:
        with warnings.catch_warnings():
            # SAPIEN 3.0.3 warns on import when no system Vulkan loader exists and loads its own; frbench's
            # physics-only scenes never render, so the message says nothing about what frbench does
            warnings.filterwarnings("ignore", message="Failed to find system libvulkan", category=UserWarning)
            import sapien
    except ImportError:
        raise FrbenchError("backend physx: SAPIEN is not installed; install it with "
                           "pip install 'frbench[physx]'") from None
    return sapien


def collision_bits(sim: SimRobotFile, exclusions) -> tuple[dict[str, int], int]:
    """(link name → collision-group bits, number of bits used) that make SAPIEN's filter ignore exactly each link
    against its ancestors and the ``exclusions`` pairs (link names): one bit per root-to-leaf chain (two links
    share one iff one is an ancestor of the other), one more per excluded pair that is not such a pair. Bits
    past `COLLISION_BITS` are counted, not set."""
    parents = {link: parent for link, parent in sim.parent}
    leaves = [link for link in sim.links if link not in set(parents.values())]
    bits = {link: 0 for link in sim.links}
    used = 0

    def add(links) -> None:
        nonlocal used
        if used < COLLISION_BITS:
            for link in links:
                bits[link] |= 1 << used
        used += 1

    for leaf in leaves:
        add([leaf, *sim.ancestors(leaf)])
    for link_a, link_b in exclusions:
        if link_a not in sim.ancestors(link_b) and link_b not in sim.ancestors(link_a):
            add([link_a, link_b])
    return bits, used


def physx_refusal(spec: RobotSpec) -> str | None:
    """Why PhysX (through SAPIEN) cannot simulate ``spec`` as frbench's protocol asks, or None when it can."""
    sim = sim_robot_file(spec)
    if len(sim.links) > MAX_ARTICULATION_LINKS:
        return (f"robot {spec.name!r} has {len(sim.links)} links after merging fixed joints; a PhysX articulation "
                f"holds at most {MAX_ARTICULATION_LINKS}")
    _, used = collision_bits(sim, self_collision_exclusions(spec))
    if used > COLLISION_BITS:
        return (f"robot {spec.name!r} needs {used} self-collision groups (one per root-to-leaf chain and per excluded "
                f"link pair that is not an ancestor pair); SAPIEN's collision filter has {COLLISION_BITS}")
    return None


@contextlib.contextmanager
def _scene_config(sapien, settings: PhysxSettings):
    """SAPIEN's process-wide scene configuration set to ``settings`` while a system is made, then put back."""
    before = sapien.physx.get_scene_config()
    sapien.physx.set_scene_config(gravity=[0.0, 0.0, -9.81], enable_tgs=settings.tgs,
                                  enable_enhanced_determinism=settings.enhanced_determinism, cpu_workers=0)
    try:
        yield
    finally:
        sapien.physx.set_scene_config(before)


@dataclass
class PhysxSimulation:
    """One PhysX scene: the robot (``robot``, a ``PhysxArticulation``), the terrain and their shared ``material``.

    Attributes:
        scene: the ``sapien.Scene``.
        robot: the articulation.
        material: the ``PhysxMaterial`` of every robot and terrain shape.
        links: the articulation's link components in the simulation URDF's link order.
        joint_dof: (n_joints,) the dof index of each canonical joint.
        dof: the articulation's number of dofs (canonical joints and any passive ones).
        base_mass: the root link's mass as loaded [kg].
    """

    scene: object
    robot: object
    material: object
    links: list
    joint_dof: list[int]
    dof: int
    base_mass: float


def build_simulation(spec: RobotSpec, terrain, link_names: tuple[str, ...],
                     settings: PhysxSettings = PhysxSettings()) -> PhysxSimulation:
    """A PhysX scene of ``spec`` on ``terrain`` (module docstring), friction 1; a `FrbenchError` when PhysX cannot
    take the robot (`physx_refusal`). ``link_names``: the links' order (the simulation URDF's)."""
    from frbench.backends.terrain_build import add_to_physx

    reason = physx_refusal(spec)
    if reason:
        raise FrbenchError(f"backend physx: {reason}")
    sapien = import_sapien()
    with _scene_config(sapien, settings):
        scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(spec.physics_dt)
    material = sapien.physx.PhysxMaterial(1.0, 1.0, 0.0)
    add_to_physx(scene, terrain, material)
    sim = sim_robot_file(spec)
    loader = scene.create_urdf_loader()
    loader.fix_root_link = False
    robot = loader.load(str(sim.path))
    robot.set_solver_position_iterations(settings.position_iterations)
    robot.set_solver_velocity_iterations(settings.velocity_iterations)
    robot.set_sleep_threshold(0.0)
    bits, _ = collision_bits(sim, self_collision_exclusions(spec))
    by_name = {link.get_name(): link for link in robot.get_links()}
    for name, link in by_name.items():
        link.set_linear_damping(0.0)
        link.set_angular_damping(0.0)
        link.set_max_linear_velocity(settings.max_link_speed)
        link.set_max_angular_velocity(settings.max_link_speed)
        for shape in link.get_collision_shapes():
            shape.set_physical_material(material)
            groups = shape.get_collision_groups()
            groups[2] = bits[name]
            shape.set_collision_groups(groups)
    joints = robot.get_active_joints()
    for joint in joints:
        joint.set_friction(0.0)
        joint.set_armature([0.0] * joint.get_dof())
        joint.set_max_velocity(settings.max_joint_speed)
    dof_of = {joint.get_name(): k for k, joint in enumerate(joints)}
    links = [by_name[name] for name in link_names]
    return PhysxSimulation(scene=scene, robot=robot, material=material, links=links,
                           joint_dof=[dof_of[name] for name in spec.joint_names], dof=len(joints),
                           base_mass=float(links[0].get_mass()))
