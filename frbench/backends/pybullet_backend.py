"""PyBullet backend: one ``BulletClient`` (DIRECT) per simulation.

See :mod:`frbench.backends.base` for the conventions. What Bullet does
differently, converted here:

* ``getBasePositionAndOrientation`` gives the root's *inertial* frame and
  quaternions are x, y, z, w: poses are converted to the URDF root link frame
  and w-first;
* base velocities come in the world frame: the angular one is rotated into the
  body frame and the linear one moved from the CoM to the root frame origin;
* the default velocity motors are switched off and the PD torque is computed
  in Python at every physics step (a ``TORQUE_CONTROL`` command lasts one
  ``stepSimulation``);
* Bullet's default link damping (0.04) is set to 0 and lateral friction of
  every robot link to 1, so the product with the terrain's value is the
  terrain's value.
"""

from __future__ import annotations

import contextlib
import os
import sys

import numpy as np

from frbench.backends.base import (
    CONTROL_DT,
    Contacts,
    PhysicsParams,
    RobotState,
    actuator_torque,
    check_targets,
    divergence_mask,
    summarize_contacts,
)
from frbench.backends.bullet import BulletClient, pybullet as p
from frbench.backends.explicit_pd import ExplicitPdBatch
from frbench.portable_products import transposed_times, unit
from frbench.robots.sim_urdf import self_collision_exclusions, sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain


_LOAD_FLAGS = p.URDF_USE_INERTIA_FROM_FILE | p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS


@contextlib.contextmanager
def _c_stdout_silenced():
    """Silence C-level stdout (Bullet prints ``argv[0]=`` on every connect, which breaks ``--json`` output)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(devnull)
        os.close(saved)


def _rotation(client: BulletClient, xyzw) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(xyzw)).reshape(3, 3)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (``np.cross``'s arithmetic, without its overhead on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _joint_arrays(states) -> tuple[np.ndarray, np.ndarray]:
    """(positions, velocities) from ``getJointStates``."""
    return np.array([s[0] for s in states]), np.array([s[1] for s in states])


def _matrix_to_wxyz(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) with w >= 0 of a rotation matrix (3, 3)."""
    w = np.sqrt(max(0.0, 1.0 + rot[0, 0] + rot[1, 1] + rot[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1.0 + rot[0, 0] - rot[1, 1] - rot[2, 2])) / 2, rot[2, 1] - rot[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - rot[0, 0] + rot[1, 1] - rot[2, 2])) / 2, rot[0, 2] - rot[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - rot[0, 0] - rot[1, 1] + rot[2, 2])) / 2, rot[1, 0] - rot[0, 1])
    quat = np.array([w, x, y, z])
    return unit(quat)


class _Simulation:
    """One Bullet world with the robot and the terrain."""

    def __init__(self, spec: RobotSpec, urdf_path: str, terrain, link_names: tuple[str, ...]):
        from frbench.backends.terrain_build import add_to_bullet

        with _c_stdout_silenced():
            self.client = BulletClient(connection_mode=p.DIRECT)
        c = self.client
        self.cid = c._client  # the hot loops call pybullet directly: BulletClient wraps each call anew
        c.setGravity(0, 0, -9.81)
        c.setPhysicsEngineParameter(fixedTimeStep=spec.physics_dt, numSubSteps=0)
        self.terrain_bodies = add_to_bullet(c, terrain, 1.0)
        self.robot = c.loadURDF(urdf_path, [0, 0, 1], flags=_LOAD_FLAGS)
        index_of = {c.getJointInfo(self.robot, j)[12].decode(): j for j in range(c.getNumJoints(self.robot))}
        joint_of = {c.getJointInfo(self.robot, j)[1].decode(): j for j in range(c.getNumJoints(self.robot))}
        self.joints = [joint_of[name] for name in spec.joint_names]
        # link index per simulated link: -1 for the root
        self.link_index = np.array([-1 if i == 0 else index_of[name] for i, name in enumerate(link_names)])
        self.row_of_link = {int(idx): row for row, idx in enumerate(self.link_index)}
        self.child_links = [int(idx) for idx in self.link_index[1:]]
        row = {name: int(self.link_index[i]) for i, name in enumerate(link_names)}
        for link_a, link_b in self_collision_exclusions(spec):
            c.setCollisionFilterPair(self.robot, self.robot, row[link_a], row[link_b], 0)
        for j in range(c.getNumJoints(self.robot)):
            c.setJointMotorControl2(self.robot, j, p.VELOCITY_CONTROL, force=0)
        for link in self.link_index:
            c.changeDynamics(
                self.robot, int(link), lateralFriction=1.0, restitution=0.0, rollingFriction=0.0,
                spinningFriction=0.0, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
            )
        info = c.getDynamicsInfo(self.robot, -1)
        self.base_mass = info[0]
        self.inertial_pos = np.array(info[3])
        self.inertial_orn = info[4]
        self.inertial_rot_inv = _rotation(c, info[4]).T
        self.diverged = False


class PybulletBackend(ExplicitPdBatch):
    """N PyBullet simulations of ``spec`` on ``terrain``. See `frbench.backends.base.Backend`."""

    name = "pybullet"

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, variants=None):
        """N simulations of ``spec`` on ``terrain`` (flat if None); ``variants`` as for `MujocoBackend`."""
        self.spec = spec
        self.num_envs = int(num_envs)
        self.terrain = terrain if terrain is not None else make_terrain("flat", 1, 0)
        self.physics_dt = float(spec.physics_dt)
        self.substeps = int(round(CONTROL_DT / self.physics_dt))
        self.link_names = sim_robot_file(spec).links
        specs, assignment = ([spec], np.zeros(self.num_envs, dtype=int)) if variants is None else variants[:2]
        self.sims = [
            _Simulation(specs[k], str(sim_robot_file(specs[k]).path), self.terrain, self.link_names) for k in assignment
        ]
        self._init_batch(spec, self.num_envs, variants)

    # ------------------------------------------------------------------ params
    def set_params(self, params: PhysicsParams) -> None:
        """Per-simulation gains, motor strength, terrain friction and payload."""
        payload = np.zeros(self.num_envs) if params.payload is None else params.payload
        for i, sim in enumerate(self.sims):
            for body in sim.terrain_bodies:
                sim.client.changeDynamics(body, -1, lateralFriction=float(params.friction[i]))
            sim.client.changeDynamics(sim.robot, -1, mass=float(sim.base_mass + payload[i]))
        self.params = params
        self._masses = None

    # ------------------------------------------------------------------ state
    def reset(self, ids, state: RobotState) -> None:
        """Place simulations ``ids`` in ``state``."""
        for row, i in enumerate(np.asarray(ids, dtype=int)):
            sim = self.sims[i]
            c = sim.client
            w, x, y, z = unit(state.base_quat[row])
            orn = [x, y, z, w]
            pos, com_orn = c.multiplyTransforms(state.base_pos[row].tolist(), orn, sim.inertial_pos.tolist(), sim.inertial_orn)
            c.resetBasePositionAndOrientation(sim.robot, pos, com_orn)
            rot = _rotation(c, orn)
            omega_world = rot @ state.base_angvel[row]
            v_com = state.base_linvel[row] + np.cross(omega_world, np.array(pos) - state.base_pos[row])
            c.resetBaseVelocity(sim.robot, v_com.tolist(), omega_world.tolist())
            for j, angle, rate in zip(sim.joints, state.q[row], state.qd[row]):
                c.resetJointState(sim.robot, j, float(angle), float(rate))
            self._tau[i] = 0.0
            sim.diverged = False
        self.diverged[np.asarray(ids, dtype=int)] = divergence_mask(state)
        self._state = None

    def step(self, joint_targets) -> None:
        """One control period: ``substeps`` × (PD torque in Python, ``stepSimulation``)."""
        targets = check_targets(joint_targets, self.num_envs, self.spec.n_joints)
        params, limits = self.params, self._limits
        for i, sim in enumerate(self.sims):
            if self.diverged[i]:
                continue
            cid, robot, joints, target = sim.cid, sim.robot, sim.joints, targets[i]
            force = self._base_force[i].tolist() if self._base_force[i].any() else None
            for _ in range(self.substeps):  # the hot loop: keep it lean
                q, qd = _joint_arrays(p.getJointStates(robot, joints, physicsClientId=cid))
                tau = actuator_torque(params, limits, target, q, qd, i)
                p.setJointMotorControlArray(robot, joints, p.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=cid)
                if force is not None:  # Bullet clears external forces after every stepSimulation
                    base = p.getBasePositionAndOrientation(robot, physicsClientId=cid)[0]
                    p.applyExternalForce(robot, -1, force, base, p.WORLD_FRAME, physicsClientId=cid)
                p.stepSimulation(physicsClientId=cid)
            self._tau[i] = tau
        self._finish_step()

    def _read_state(self) -> RobotState:
        n, nj = self.num_envs, self.spec.n_joints
        out = RobotState(
            base_pos=np.zeros((n, 3)), base_quat=np.zeros((n, 4)), base_linvel=np.zeros((n, 3)),
            base_angvel=np.zeros((n, 3)), q=np.zeros((n, nj)), qd=np.zeros((n, nj)), tau=self._tau.copy(),
        )
        for i, sim in enumerate(self.sims):
            cid = sim.cid
            com_pos, com_orn = p.getBasePositionAndOrientation(sim.robot, physicsClientId=cid)
            v_com, omega = p.getBaseVelocity(sim.robot, physicsClientId=cid)
            rot = _rotation(sim.client, com_orn) @ sim.inertial_rot_inv  # root link frame orientation
            pos = np.asarray(com_pos) - rot @ sim.inertial_pos
            omega = np.asarray(omega)
            out.base_pos[i] = pos
            out.base_quat[i] = _matrix_to_wxyz(rot)
            out.base_linvel[i] = np.asarray(v_com) + _cross(omega, pos - np.asarray(com_pos))
            out.base_angvel[i] = transposed_times(rot, omega)
            out.q[i], out.qd[i] = _joint_arrays(p.getJointStates(sim.robot, sim.joints, physicsClientId=cid))
        return out

    def _link_masses(self) -> np.ndarray:
        """(N, n_links) link masses [kg] as Bullet holds them, links in ``link_names`` order."""
        return np.array([[sim.client.getDynamicsInfo(sim.robot, int(link))[0] for link in sim.link_index]
                         for sim in self.sims])

    def whole_body_com(self) -> np.ndarray:
        """Whole-body CoM in the world [m] (N, 3): one ``getLinkStates`` per simulation, the weighting in numpy."""
        if self._masses is None:
            self._masses = self._link_masses()
        positions = np.zeros((self.num_envs, len(self.link_names), 3))
        for i, sim in enumerate(self.sims):
            c = sim.client
            positions[i, 0] = c.getBasePositionAndOrientation(sim.robot)[0]
            states = c.getLinkStates(sim.robot, sim.child_links, computeForwardKinematics=True)
            positions[i, 1:] = [state[0] for state in states]
        masses = self._masses
        return np.einsum("nl,nlx->nx", masses, positions) / masses.sum(axis=1, keepdims=True)

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total robot mass [kg] (N,), whole-body CoM in the world [m] (N, 3)) as Bullet holds them."""
        self._masses = self._link_masses()
        return self._masses.sum(axis=1), self.whole_body_com()

    def contacts(self) -> Contacts:
        """Net contact force per link from ``getContactPoints`` (world frame), summarised by group."""
        link_force = np.zeros((self.num_envs, len(self.link_names), 3))
        for i, sim in enumerate(self.sims):
            points = p.getContactPoints(bodyA=sim.robot, physicsClientId=sim.cid)
            if not points:
                continue
            rows = [sim.row_of_link[point[3]] for point in points]
            # normal force along the normal on B (pointing from B to A) plus both friction forces
            magnitude = np.array([(point[9], point[10], point[12]) for point in points])
            directions = np.array([(point[7], point[11], point[13]) for point in points])
            np.add.at(link_force[i], rows, np.einsum("pk,pkx->px", magnitude, directions))
        return summarize_contacts(self.spec, self.link_names, link_force)

    def close(self) -> None:
        """Disconnect every client."""
        for sim in self.sims:
            try:
                sim.client.disconnect()
            except p.error:
                pass
        self.sims = []
