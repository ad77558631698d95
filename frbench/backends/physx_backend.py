"""PhysX backend (PhysX 5 through SAPIEN 3, CPU): one SAPIEN scene per simulation.

See :mod:`frbench.backends.base` for the conventions and `frbench.backends.physx_scene` for how a scene is set
up (solver, determinism, self-collision groups, shared friction material). What PhysX does differently,
converted here:

* the root pose is the URDF root link frame, quaternion w-first, as frbench's; the root's linear velocity is
  its centre of mass's and its angular velocity is in the world frame: both are converted (to the root frame
  origin's, and to the body frame) when read and back when a state is written;
* joints are PhysX's dofs in SAPIEN's order: canonical joints are mapped by name;
* the PD of `frbench.backends.base.actuator_torque` is computed in numpy at every physics step from PhysX's
  joint positions and velocities and applied as joint forces (``set_qf``), as the PyBullet backend does;
  PhysX's own joint drives stay off;
* the base force is applied at the root link's centre of mass before every physics step (PhysX clears external
  forces after each);
* contact forces are the impulses PhysX reports per contact point divided by the physics step. PhysX reports
  the normal impulse only (no friction impulse per point), so a link's contact force here lacks its friction
  part: the vertical force of a robot standing on flat ground is its weight, the horizontal force on a knee
  dragged along flat ground is 0;
* PhysX state is float32: states read back differ from the ones written by float32 rounding.
"""

from __future__ import annotations

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
from frbench.backends.explicit_pd import ExplicitPdBatch
from frbench.backends.physx_scene import PhysxSettings, build_simulation, import_sapien, physx_refusal
from frbench.portable_products import dot, transposed_times, unit
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain


class PhysxBackend(ExplicitPdBatch):
    """N PhysX simulations of ``spec`` on ``terrain``. See `frbench.backends.base.Backend`."""

    name = "physx"

    @staticmethod
    def refusal(spec: RobotSpec) -> str | None:
        """Why PhysX cannot simulate ``spec`` (`frbench.backends.physx_scene.physx_refusal`), or None; a
        `FrbenchError` when SAPIEN is not installed."""
        import_sapien()
        return physx_refusal(spec)

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, variants=None,
                 settings: PhysxSettings = PhysxSettings()):
        """N simulations of ``spec`` on ``terrain`` (flat if None); ``variants`` (specs, assignment, frictions,
        payloads): simulation i runs ``specs[assignment[i]]`` (friction and payload then come from
        `set_params`, as in the PyBullet backend). ``settings``: the PhysX solver's (the protocol's by default;
        another is for measurements such as benchmarks/physx_throughput.py, never for scores)."""
        self._sapien = import_sapien()
        self.spec = spec
        self.num_envs = int(num_envs)
        self.terrain = terrain if terrain is not None else make_terrain("flat", 1, 0)
        self.physics_dt = float(spec.physics_dt)
        self.substeps = int(round(CONTROL_DT / self.physics_dt))
        self.link_names = sim_robot_file(spec).links
        specs, assignment = ([spec], np.zeros(self.num_envs, dtype=int)) if variants is None else variants[:2]
        self.sims = [build_simulation(specs[k], self.terrain, self.link_names, settings) for k in assignment]
        # per simulation: the root's centre of mass in its link frame [m], the links' CoM poses in their frames,
        # and each articulation link index's row in `link_names`
        self._root_com = np.array([sim.links[0].get_cmass_local_pose().p for sim in self.sims], dtype=float)
        self._link_com = [[link.get_cmass_local_pose() for link in sim.links] for sim in self.sims]
        self._row_of_index = []
        for sim in self.sims:
            rows = np.zeros(len(sim.links), dtype=int)
            for row, link in enumerate(sim.links):
                rows[link.get_index()] = row
            self._row_of_index.append(rows)
        self._link_class = self._sapien.physx.PhysxArticulationLinkComponent
        self._joint_dof = self.sims[0].joint_dof  # the same in every simulation (variants share the joints)
        if any(sim.joint_dof != self._joint_dof or sim.dof != self.sims[0].dof for sim in self.sims):
            raise ValueError("physx backend: the morphology variants' joints differ from the robot's")
        self._init_batch(spec, self.num_envs, variants)

    # ------------------------------------------------------------------ params
    def set_params(self, params: PhysicsParams) -> None:
        """Per-simulation gains, motor strength, motor friction, friction (the shared material's coefficient) and
        payload (added to the root link's mass, its CoM unchanged)."""
        payload = np.zeros(self.num_envs) if params.payload is None else params.payload
        for i, sim in enumerate(self.sims):
            sim.material.set_static_friction(float(params.friction[i]))
            sim.material.set_dynamic_friction(float(params.friction[i]))
            sim.links[0].set_mass(float(sim.base_mass + payload[i]))
        self.params = params
        self._masses = None

    # ------------------------------------------------------------------ state
    def reset(self, ids, state: RobotState) -> None:
        """Place simulations ``ids`` in ``state``; a row with a non-finite or exploding value is flagged diverged
        and not written (PhysX refuses non-finite input)."""
        ids = np.asarray(ids, dtype=int)
        bad = divergence_mask(state)
        pose_of = self._sapien.Pose
        for row, i in enumerate(ids):
            self._tau[i] = 0.0
            if bad[row]:
                continue
            sim = self.sims[i]
            pose = pose_of(state.base_pos[row].tolist(), unit(state.base_quat[row]).tolist())
            sim.robot.set_root_pose(pose)
            qpos, qvel = np.zeros(sim.dof, dtype=np.float32), np.zeros(sim.dof, dtype=np.float32)
            qpos[sim.joint_dof], qvel[sim.joint_dof] = state.q[row], state.qd[row]
            sim.robot.set_qpos(qpos)
            sim.robot.set_qvel(qvel)
            sim.robot.set_qf(np.zeros(sim.dof, dtype=np.float32))
            rot = pose.to_transformation_matrix()[:3, :3].astype(float)
            omega = dot(rot, state.base_angvel[row])
            sim.robot.set_root_linear_velocity(state.base_linvel[row] + np.cross(omega, dot(rot, self._root_com[i])))
            sim.robot.set_root_angular_velocity(omega)
        self.diverged[ids] = bad
        self._state = None

    def step(self, joint_targets) -> None:
        """One control period: ``substeps`` × (the PD torques of every live simulation in one numpy call, then per
        simulation ``set_qf``, the base force and ``scene.step``)."""
        targets = check_targets(joint_targets, self.num_envs, self.spec.n_joints)
        live = np.flatnonzero(~self.diverged)
        if live.size == 0:
            self._finish_step()
            return
        sims = [self.sims[i] for i in live]
        dofs, zero = self._joint_dof, np.zeros(3, dtype=np.float32)
        pushed = [(sim.links[0], self._base_force[i].astype(np.float32))
                  for i, sim in zip(live, sims) if self._base_force[i].any()]
        qf = np.zeros((live.size, sims[0].dof), dtype=np.float32)
        targets = targets[live]
        for _ in range(self.substeps):  # the hot loop: keep it lean
            q = np.array([sim.robot.get_qpos() for sim in sims])[:, dofs]
            qd = np.array([sim.robot.get_qvel() for sim in sims])[:, dofs]
            tau = actuator_torque(self.params, self._limits, targets, q, qd, live)
            qf[:, dofs] = tau
            for sim, torques in zip(sims, qf):
                sim.robot.set_qf(torques)
            for link, force in pushed:  # PhysX clears external forces after every step
                link.add_force_torque(force, zero)
            for sim in sims:
                sim.scene.step()
        self._tau[live] = tau
        self._finish_step()

    def _read_state(self) -> RobotState:
        robots = [sim.robot for sim in self.sims]
        poses = [robot.get_root_pose() for robot in robots]
        rot = np.array([pose.to_transformation_matrix()[:3, :3] for pose in poses], dtype=float)
        omega = np.array([robot.get_root_angular_velocity() for robot in robots], dtype=float)
        com_offset = dot(rot, self._root_com[:, None, :])  # root link origin → its CoM, world frame
        return RobotState(
            base_pos=np.array([pose.p for pose in poses], dtype=float),
            base_quat=np.array([pose.q for pose in poses], dtype=float),
            base_linvel=np.array([robot.get_root_linear_velocity() for robot in robots], dtype=float)
            - np.cross(omega, com_offset),
            base_angvel=transposed_times(rot, omega),
            q=np.array([sim.robot.get_qpos()[sim.joint_dof] for sim in self.sims], dtype=float),
            qd=np.array([sim.robot.get_qvel()[sim.joint_dof] for sim in self.sims], dtype=float),
            tau=self._tau.copy(),
        )

    def whole_body_com(self) -> np.ndarray:
        """Whole-body CoM in the world [m] (N, 3): each link's CoM position from PhysX, weighted by its mass
        (`frbench.portable_products` sums, as every product that can reach an episode here)."""
        if self._masses is None:
            self._masses = np.array([[link.get_mass() for link in sim.links] for sim in self.sims], dtype=float)
        positions = np.array([[(link.get_entity_pose() * com).p for link, com in zip(sim.links, coms)]
                              for sim, coms in zip(self.sims, self._link_com)], dtype=float)
        masses = self._masses
        return dot(masses[:, None, :], np.swapaxes(positions, 1, 2)) / dot(masses, np.ones_like(masses))[:, None]

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total robot mass [kg] (N,), whole-body CoM in the world [m] (N, 3)) as PhysX holds them."""
        self._masses = None
        com = self.whole_body_com()
        return dot(self._masses, np.ones_like(self._masses)), com

    def contacts(self) -> Contacts:
        """Net contact force per link (world frame): the normal impulses of the last physics step's contact points
        over the step (module docstring), on both links of a self-contact, summarised by group."""
        n_links = len(self.link_names)
        link_class = self._link_class
        # per contact point and link it acts on: the (simulation, link) row, ±1 and the impulse; a link's rows keep
        # the points' order, so its sum below is the same however the links' rows interleave
        index, sign, impulses = [], [], []
        for i, sim in enumerate(self.sims):
            rows = self._row_of_index[i] + i * n_links
            for contact in sim.scene.get_contacts():
                first, second = contact.bodies
                points = [point.impulse for point in contact.points]
                for body, direction in ((first, 1.0), (second, -1.0)):  # the impulses act on the first body
                    if isinstance(body, link_class):
                        index += [rows[body.get_index()]] * len(points)
                        sign += [direction] * len(points)
                        impulses += points
        link_force = np.zeros((self.num_envs * n_links, 3))
        if index:  # added point after point (np.add.at): the sums' last bits are the same on any processor
            np.add.at(link_force, index, np.array(impulses, dtype=float) * (np.array(sign) / self.physics_dt)[:, None])
        return summarize_contacts(self.spec, self.link_names, link_force.reshape(self.num_envs, n_links, 3))

    def close(self) -> None:
        """Free the scenes."""
        self.sims = []
