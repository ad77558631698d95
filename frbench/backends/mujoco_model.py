"""Compile a robot on a terrain into an ``MjModel`` that follows frbench's conventions.

The robot comes from its simulation URDF (the same file PyBullet and
Pinocchio load). What this adds, and why:

* a free joint on the root (without it MuJoCo welds the root to the world);
* ``fusestatic`` off and ``inertiafromgeom`` off, so every URDF link is one
  body with exactly the file's inertia;
* each body's collisions with all its ancestors excluded (MuJoCo only excludes
  parent/child; Bullet's ``URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS`` does this),
  and the pairs of :func:`~frbench.robots.sim_urdf.self_collision_exclusions` that are not such pairs already;
* two native actuators per joint, so that MuJoCo computes the actuation of
  `frbench.backends.base.actuator_torque` itself at every physics step and one
  ``Batch.step(nstep=substeps)`` call advances a whole control period:

  - the PD, a position actuator ``pd_<joint>`` (rows ``0 .. J−1``, canonical
    order, ctrl = q*): force = clip(gainprm₀·ctrl + biasprm₁·q + biasprm₂·q̇,
    forcerange) with gainprm₀ = s·Kp, biasprm = [0, −s·Kp, −s·Kd] and
    forcerange = ±s·τmax, which is s·clip(Kp (q* − q) − Kd q̇, ±τmax) for a
    strength s ≥ 0 (gear 1: a gear of s would scale the length and velocity
    the bias reads too);
  - the motor friction, ``friction_<joint>`` (rows ``J .. 2J−1``, no ctrl):
    force = clip(−(f / v_f)·q̇, ±f) = −f·clip(q̇ / v_f, ±1);

  the gains here are the spec's at strength 1 and no friction; the backend
  writes per-simulation values (``Batch.expand``). The Euler integrator keeps
  both velocity terms explicit, as in PyBullet, where the backend computes the
  same formula in numpy;
* an accelerometer on the root so that MuJoCo computes ``cfrc_ext`` (the net
  contact force on every body) at every step;
* an elliptic friction cone with impratio 100 (see ``build_spec``);
* the terrain's geoms (priority 1, so contacts use the terrain's friction).
"""

from __future__ import annotations

import logging

import mujoco
import numpy as np

from frbench.backends.terrain_build import add_to_mjspec
from frbench.content_cache import cached_bytes, content_key, object_key, source_key
from frbench.robots.sim_urdf import self_collision_exclusions, sim_robot_file
from frbench.robots.spec import RobotSpec


def build_spec(spec: RobotSpec, terrain, friction: float = 1.0) -> mujoco.MjSpec:
    """An ``MjSpec`` of ``spec`` on ``terrain`` (see the module docstring)."""
    sim = sim_robot_file(spec)
    mj = mujoco.MjSpec.from_file(str(sim.path))
    mj.compiler.fusestatic = False
    mj.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    mj.option.timestep = spec.physics_dt
    mj.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    # elliptic cone with a high impratio: friction close to hard Coulomb, as Bullet's
    # (with the defaults a standing Go2's feet creep outward and it sinks 25 %)
    mj.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    mj.option.impratio = 100.0
    root = mj.worldbody.first_body()
    root.add_freejoint()
    site = root.add_site()
    site.name = "frbench_imu"
    sensor = mj.add_sensor()
    sensor.type = mujoco.mjtSensor.mjSENS_ACCELEROMETER
    sensor.objtype = mujoco.mjtObj.mjOBJ_SITE
    sensor.objname = site.name
    lineage = sim.lineage()  # every ancestor/descendant pair, excluded here or (the parent) by MuJoCo
    for link in sim.links:
        for ancestor in sim.ancestors(link)[1:]:  # the parent is excluded by MuJoCo already
            exclude = mj.add_exclude()
            exclude.bodyname1, exclude.bodyname2 = ancestor, link
    for link_a, link_b in self_collision_exclusions(spec):
        if frozenset((link_a, link_b)) in lineage:  # excluded already: a second entry changes nothing but the
            continue  # model's layout (files that differ only in their joint zero compile alike)
        exclude = mj.add_exclude()
        exclude.bodyname1, exclude.bodyname2 = link_a, link_b
    for geom in mj.geoms:
        geom.friction = [1.0, 0.005, 0.0001]
        geom.condim = 3
    for name in spec.joint_names:
        joint = mj.joint(name)
        joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        joint.damping = np.zeros(3)
        joint.armature, joint.frictionloss = 0.0, 0.0
    for (name, kp, kd, limit) in zip(spec.joint_names, spec.kp, spec.kd, spec.torque_limits):
        _add_joint_actuator(mj, f"pd_{name}", name, gain=float(kp), bias=(-float(kp), -float(kd)), limit=float(limit))
    for name in spec.joint_names:  # no friction until the backend sets it (the range must be non-empty)
        _add_joint_actuator(mj, f"friction_{name}", name, gain=0.0, bias=(0.0, 0.0), limit=1.0)
    add_to_mjspec(mj, terrain, friction)
    light = mj.worldbody.add_light()
    light.pos, light.dir = [0, 0, 6], [0, 0, -1]
    return mj


def _add_joint_actuator(mj: mujoco.MjSpec, name: str, joint: str, gain: float, bias: tuple[float, float],
                        limit: float) -> None:
    """A gear-1 actuator on ``joint``: force = clip(gain·ctrl + bias₀·q + bias₁·q̇, ±limit), no dynamics."""
    actuator = mj.add_actuator()
    actuator.name, actuator.target = name, joint
    actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
    actuator.dyntype = mujoco.mjtDyn.mjDYN_NONE
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gear = [1.0, 0, 0, 0, 0, 0]
    actuator.gainprm = [gain] + [0.0] * 9
    actuator.biasprm = [0.0, bias[0], bias[1]] + [0.0] * 7
    actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = [-limit, limit]


def _log_warning(message: str) -> None:
    logging.getLogger("frbench.mujoco").warning("MuJoCo: %s", message)


def route_warnings() -> None:
    """Send MuJoCo's warnings (e.g. "Nan, Inf or huge value in QACC" of an unstable model) to the
    ``frbench.mujoco`` logger: MuJoCo's own handler prints them and appends them to ``MUJOCO_LOG.TXT`` in the
    working directory, a file frbench must not leave behind. frbench reports divergence itself (``diverged``)."""
    if mujoco.get_mju_user_warning() is not _log_warning:
        mujoco.set_mju_user_warning(_log_warning)


class CountedWarnings:
    """Within ``with CountedWarnings() as muted:`` MuJoCo's warnings are counted (``muted.count``), not logged: for
    a sampling planner whose rollouts are expected to blow up now and then (the cheapest plans are never the
    unstable ones). The handler before it comes back on exit."""

    def __init__(self):
        self.count = 0
        self._before = None

    def _count(self, message: str) -> None:
        self.count += 1

    def __enter__(self) -> "CountedWarnings":
        self._before = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self._count)
        return self

    def __exit__(self, *exc) -> None:
        mujoco.set_mju_user_warning(self._before)


def build_model(spec: RobotSpec, terrain, friction: float = 1.0) -> mujoco.MjModel:
    """Compiled model of ``spec`` on ``terrain``, from frbench's cache when it was compiled before.

    The entry (MuJoCo's binary model, exact) is keyed by the spec, its simulation URDF's text, the
    terrain, the friction, the MuJoCo version and the source of the modules that build the model.
    """
    route_warnings()
    sim = sim_robot_file(spec)
    key = content_key(spec, sim.path.read_bytes(), object_key(terrain), float(friction), mujoco.__version__,
                      source_key(__name__, "frbench.backends.terrain_build", "frbench.robots.sim_urdf"))

    def compile_model() -> bytes:
        model = build_spec(spec, terrain, friction).compile()
        buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, buffer)
        return buffer.tobytes()

    return cached_bytes("mujoco-models", key, ".mjb", compile_model, _model_from_bytes)


def _model_from_bytes(data: bytes) -> mujoco.MjModel:
    return mujoco.MjModel.from_binary_path("model.mjb", {"model.mjb": data})


def joint_addresses(model: mujoco.MjModel, spec: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """(qpos addresses, dof addresses) of the canonical joints, each (n_joints,)."""
    ids = [model.joint(name).id for name in spec.joint_names]
    return model.jnt_qposadr[ids].copy(), model.jnt_dofadr[ids].copy()
