"""The planner's model: a MuJoCo copy of the episode's robot and terrain with the sensors the cost reads.

The copy is built by frbench's own model builder (`frbench.backends.mujoco_model.build_spec`: the same
simulation URDF, actuators, friction and terrain geoms as the MuJoCo backend) and then changed only where
planning asks for it:

* its physics step is the planner's ``planning_dt``; a coarser one than the robot's own takes MuJoCo's
  ``implicitfast`` integrator, which keeps the stiff PD damping stable at that step (at the robot's own step
  the copy keeps the acting model's explicit Euler and predicts the MuJoCo backend exactly);
* sensors that MuJoCo evaluates inside `mujoco.rollout` (in C, no Python per step), in this order:
  root position (3), root z axis (3), upper-body z axis (3), upper-body position (3), whole-body CoM (3),
  CoM velocity (3), each foot's position (3 each), and one contact count per non-foot link (1 each).

The "upper body" is a humanoid's torso link (its head is on it) and a quadruped's root.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from frbench.backends.base import RobotState
from frbench.backends.mujoco_model import build_spec, joint_addresses
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.tasks.protocol import CONTROL_DT

#: MuJoCo's contact-sensor data bit for "found" (the number of matching contacts).
_CONTACT_FOUND = 1
#: The humanoid torso link the success test reads (`frbench.tasks.success.TorsoFrame`).
HUMANOID_TORSO_LINK = "torso_link"


@dataclass(frozen=True)
class SensorLayout:
    """Column slices of the planning model's sensordata (module docstring), each (…, width)."""

    root_pos: slice
    root_z: slice
    upper_z: slice
    upper_pos: slice
    com: slice
    com_vel: slice
    feet: slice
    body_contact: slice

    @property
    def n_feet(self) -> int:
        """Number of feet."""
        return (self.feet.stop - self.feet.start) // 3


@dataclass
class PlanningModel:
    """A compiled planning copy and what the planner needs to drive it.

    Attributes:
        model: the ``MjModel`` (``opt.timestep`` is the planning step [s]).
        sensors: where each sensor's values lie in ``sensordata``.
        qadr, dadr: (n_joints,) qpos and qvel addresses of the canonical joints.
        substeps: planning steps per control period (0.02 s).
        n_state: length of a ``mjSTATE_FULLPHYSICS`` state vector.
    """

    model: mujoco.MjModel
    sensors: SensorLayout
    qadr: np.ndarray
    dadr: np.ndarray
    substeps: int
    n_state: int

    def initial_state(self, state: RobotState, row: int, data: mujoco.MjData) -> np.ndarray:
        """The full-physics state vector (n_state,) of row ``row`` of ``state`` (frbench's conventions: root
        link frame, world linear and body angular velocity, which are MuJoCo's free-joint coordinates)."""
        mujoco.mj_resetData(self.model, data)
        quat = np.asarray(state.base_quat[row], dtype=float)
        data.qpos[0:3] = state.base_pos[row]
        data.qpos[3:7] = quat / np.linalg.norm(quat)
        data.qpos[self.qadr] = state.q[row]
        data.qvel[0:3] = state.base_linvel[row]
        data.qvel[3:6] = state.base_angvel[row]
        data.qvel[self.dadr] = state.qd[row]
        out = np.empty(self.n_state)
        mujoco.mj_getState(self.model, data, out, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        return out


def upper_body_link(spec: RobotSpec) -> str:
    """The link whose height and tilt the cost reads besides the root's: a humanoid's torso, else the root."""
    links = sim_robot_file(spec).links
    if spec.kind == "humanoid" and HUMANOID_TORSO_LINK in links:
        return HUMANOID_TORSO_LINK
    return links[0]


def _sensor(mj: mujoco.MjSpec, kind, objtype, objname: str, refname: str = "") -> None:
    sensor = mj.add_sensor()
    sensor.type, sensor.objtype, sensor.objname = kind, objtype, objname
    if refname:
        sensor.reftype, sensor.refname = mujoco.mjtObj.mjOBJ_BODY, refname


def build_planning_model(spec: RobotSpec, terrain, planning_dt: float) -> PlanningModel:
    """The planning copy of ``spec`` on ``terrain`` with physics step ``planning_dt`` [s] (a divisor of the
    0.02 s control period, at least the robot's own physics step)."""
    substeps = int(round(CONTROL_DT / planning_dt))
    if substeps < 1 or abs(substeps * planning_dt - CONTROL_DT) > 1e-9:
        raise ValueError(f"planning_dt: expected a divisor of the control period {CONTROL_DT} s, got {planning_dt}")
    mj = build_spec(spec, terrain)
    if abs(planning_dt - spec.physics_dt) > 1e-12:  # at the acting step the copy keeps the acting integrator
        mj.option.timestep = float(planning_dt)
        mj.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # the acting model's accelerometer only made MuJoCo fill cfrc_ext; the planner does not read it
    for sensor in list(mj.sensors):
        mj.delete(sensor)
    links = sim_robot_file(spec).links
    root, upper = links[0], upper_body_link(spec)
    body, xbody = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_XBODY
    sens = mujoco.mjtSensor
    _sensor(mj, sens.mjSENS_FRAMEPOS, xbody, root)
    _sensor(mj, sens.mjSENS_FRAMEZAXIS, xbody, root)
    _sensor(mj, sens.mjSENS_FRAMEZAXIS, xbody, upper)
    _sensor(mj, sens.mjSENS_FRAMEPOS, xbody, upper)
    _sensor(mj, sens.mjSENS_SUBTREECOM, body, root)
    _sensor(mj, sens.mjSENS_SUBTREELINVEL, body, root)
    for foot in spec.foot_links:
        _sensor(mj, sens.mjSENS_FRAMEPOS, xbody, foot)
    feet = set(spec.foot_links)
    non_foot = [link for link in links if link not in feet]
    for link in non_foot:
        sensor = mj.add_sensor()
        sensor.type, sensor.objtype, sensor.objname = sens.mjSENS_CONTACT, body, link
        sensor.intprm = [_CONTACT_FOUND, 0, 1] + [0] * (len(sensor.intprm) - 3)
    model = mj.compile()
    n_feet = len(spec.foot_links)
    cursor = 18
    layout = SensorLayout(root_pos=slice(0, 3), root_z=slice(3, 6), upper_z=slice(6, 9), upper_pos=slice(9, 12),
                          com=slice(12, 15), com_vel=slice(15, 18), feet=slice(cursor, cursor + 3 * n_feet),
                          body_contact=slice(cursor + 3 * n_feet, cursor + 3 * n_feet + len(non_foot)))
    if model.nsensordata != layout.body_contact.stop:
        raise RuntimeError(f"planning model: {model.nsensordata} sensor values, expected {layout.body_contact.stop}")
    qadr, dadr = joint_addresses(model, spec)
    n_state = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return PlanningModel(model, layout, qadr, dadr, substeps, n_state)
