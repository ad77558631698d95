"""Whole-body centres of mass of a MuJoCo batch's simulations at their current state, without a forward pass
of the batch itself.

MuJoCo computes ``subtree_com`` in the position stage (``mj_kinematics`` then ``mj_comPos``) from the joint
positions and the bodies' frames, inertial frames and masses. Computing that stage for the simulation batch
after every step (``Batch.step(stage=mjSTAGE_VEL)``) also runs its collision detection against every terrain
geom, which cost a quarter of the physics time on the training world of 70 terrain tiles. `CentreOfMass`
instead keeps a second batch of the robot alone (a flat floor, contacts and constraints disabled) whose body,
joint and dof fields mirror the simulation batch's, copies the joint positions into it and runs its position
stage: the same MuJoCo functions on the same numbers, so the result is bit for bit the simulation batch's
``subtree_com`` (tests/test_backends.py checks it along a motion, with morphology variants and payloads).
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import batch as mjbatch

#: Model fields the position stage's kinematics and centre of mass read: these must agree between the batches.
_MIRRORED_PREFIXES = ("body_", "jnt_", "dof_")
#: Body fields that differ between the robot alone and the robot on a terrain (the world body's geoms).
_GEOM_BOOKKEEPING = {"body_geomadr", "body_geomnum", "body_bvhadr", "body_bvhnum"}


def _mirrored(name: str) -> bool:
    return name.startswith(_MIRRORED_PREFIXES) and name not in _GEOM_BOOKKEEPING


class CentreOfMass:
    """The root's ``subtree_com`` (N, 3) [m] of a batch's N simulations, at the state in their ``qpos``.

    Args:
        model: the simulation batch's model (the robot on its terrain).
        robot_model: the same robot compiled alone (e.g. on the flat terrain); its kinematic fields must equal
            ``model``'s (a ValueError names the first that does not).
        num_envs: N.
        root_body: the robot's root body id (the same in both models).
        nthread: threads of the second batch.
    """

    def __init__(self, model: mujoco.MjModel, robot_model: mujoco.MjModel, num_envs: int, root_body: int,
                 nthread: int):
        for name in sorted(n for n in dir(model) if _mirrored(n)):
            ours = getattr(model, name)
            if isinstance(ours, np.ndarray) and not np.array_equal(ours, getattr(robot_model, name)):
                raise ValueError(f"centre of mass: model field {name} differs between the robot alone and on its "
                                 "terrain")
        robot_model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(
            mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        self.batch = mjbatch.Batch(robot_model, num_envs, nthread)
        self.root_body = int(root_body)
        self._qpos = self.batch.bind("qpos")
        self._subtree_com = self.batch.bind("subtree_com")

    def mirror(self, simulations: mjbatch.Batch) -> None:
        """Give this batch the per-simulation kinematic fields ``simulations`` has expanded (after any change of
        them: morphology variants, payloads)."""
        for name in mjbatch.MODEL_FIELDS:
            values = simulations.expanded(name) if _mirrored(name) else None
            if values is not None:
                self.batch.expand(name)[:] = values

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """Whole-body CoM in the world [m] (N, 3) of the simulations at joint positions ``qpos`` (N, nq)."""
        self._qpos[:] = qpos
        self.batch.forward(stage=mujoco.mjtStage.mjSTAGE_POS)
        return self._subtree_com[:, self.root_body].copy()
