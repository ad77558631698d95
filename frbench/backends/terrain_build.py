"""Turn a :class:`~frbench.terrains.geometry.Terrain` into simulator geometry.

This is the only code that does so; every backend calls it, so MuJoCo,
PyBullet and PhysX get the same boxes (same centres, half extents and
quaternions) and the same floor plane.

Friction: MuJoCo takes the contact friction from the geom with the higher
``priority``; the terrain's geoms have priority 1 (robot geoms keep 0), so
every robot–terrain contact uses (friction, 0.005, 0.0001). PyBullet multiplies
the two bodies' lateral friction coefficients; robot links are set to 1.0 by
the backend, so the product is the terrain's value. PhysX averages the two
materials' coefficients; the PhysX backend gives robot and terrain one shared
material, so the average is the terrain's value.
"""

from __future__ import annotations

import math
import mujoco
import numpy as np

from frbench.terrains.geometry import Terrain

#: MuJoCo sliding, torsional and rolling friction besides the sliding value.
MJ_TORSIONAL_FRICTION = 0.005
MJ_ROLLING_FRICTION = 0.0001

_FLOOR_RGBA = (0.42, 0.45, 0.50, 1.0)


def _check_friction(friction: float) -> float:
    friction = float(friction)
    if not (math.isfinite(friction) and friction >= 0.0):
        raise ValueError(f"terrain friction must be a finite number >= 0, got {friction!r}")
    return friction


def _box_rgba(z_top: float, z_lo: float, z_hi: float) -> tuple[float, float, float, float]:
    """A colour ramp by height, so steps and stones read well in renders."""
    t = 0.5 if z_hi <= z_lo else (z_top - z_lo) / (z_hi - z_lo)
    return (0.55 + 0.35 * t, 0.50 + 0.25 * t, 0.38 + 0.1 * t, 1.0)


def add_to_mjspec(spec: "mujoco.MjSpec", terrain: Terrain, friction: float) -> list[str]:
    """Add the terrain to ``spec``'s world body as static geoms.

    Adds an infinite plane ``terrain_floor`` at ``terrain.floor_z`` and one box
    geom ``terrain_box_<i>`` per box (in ``terrain.boxes`` order), all with
    ``priority = 1`` and friction (friction, 0.005, 0.0001).

    Returns:
        the geom names, floor first.
    """
    friction = _check_friction(friction)
    fr = [friction, MJ_TORSIONAL_FRICTION, MJ_ROLLING_FRICTION]
    body = spec.worldbody
    body.add_geom(
        name="terrain_floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0.0, 0.0, 0.05],  # 0: infinite (also when rendered)
        pos=[0.0, 0.0, terrain.floor_z],
        priority=1,
        friction=fr,
        rgba=_FLOOR_RGBA,
    )
    names = ["terrain_floor"]
    tops = [b.top_z for b in terrain.boxes]
    z_lo, z_hi = (min(tops), max(tops)) if tops else (0.0, 0.0)
    for i, (box, top) in enumerate(zip(terrain.boxes, tops)):
        name = f"terrain_box_{i}"
        body.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=list(box.half_extents),
            pos=list(box.center),
            quat=list(box.quat_wxyz()),
            priority=1,
            friction=fr,
            rgba=_box_rgba(top, z_lo, z_hi),
        )
        names.append(name)
    return names


#: PyBullet keeps at most this many children in one ``createCollisionShapeArray``
#: compound (MAX_COMPOUND_COLLISION_SHAPES; extra children are dropped silently).
BULLET_COMPOUND_MAX = 16


def _spatial_groups(centers: np.ndarray, members: np.ndarray, size: int) -> list[np.ndarray]:
    """Split box indices into spatially compact groups of at most ``size``
    (recursive median split along the wider of x and y)."""
    if len(members) <= size:
        return [members]
    xy = centers[members, :2]
    axis = int(np.argmax(xy.max(axis=0) - xy.min(axis=0)))
    order = members[np.argsort(xy[:, axis], kind="stable")]
    half = len(order) // 2
    return _spatial_groups(centers, order[:half], size) + _spatial_groups(centers, order[half:], size)


def add_to_bullet(client, terrain: Terrain, friction: float) -> list[int]:
    """Add the terrain to a PyBullet client as static (mass 0) bodies.

    The floor is a ``GEOM_PLANE`` at ``terrain.floor_z``: like MuJoCo's plane it
    is infinite, and rays hit it exactly (triangle ray test). A large thin box
    would be finite, and Bullet casts rays against boxes by an iterative convex
    cast that stops within a tolerance, so the backends would disagree more.

    The boxes are ``GEOM_BOX`` children of compound collision shapes
    (``createCollisionShapeArray``), at most :data:`BULLET_COMPOUND_MAX` per
    static body, grouped by position. Measured with a sphere resting on the
    400 boxes of ``rough``: one static multibody per box ran at 6–8 k steps/s,
    ``batchPositions`` 7–10 k, one multibody with 400 fixed links 11–17 k, 25
    compound bodies 100 k, the floor plane alone 220–280 k: each static
    multibody costs Bullet about 0.35 µs per step, whatever it holds.

    Args:
        client: a ``pybullet_utils.bullet_client.BulletClient`` (or anything
            with pybullet's functions bound to one physics client).
        terrain: the terrain.
        friction: lateral friction of every terrain body (restitution, rolling
            and spinning friction 0).

    Returns:
        body ids: the floor first, then the compound bodies holding the boxes.
    """
    friction = _check_friction(friction)
    from frbench.backends.bullet import pybullet  # here: MuJoCo's builders work without PyBullet (a GPU machine)

    floor_shape = client.createCollisionShape(pybullet.GEOM_PLANE, planeNormal=[0.0, 0.0, 1.0])
    bodies = [
        client.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=floor_shape, basePosition=[0.0, 0.0, terrain.floor_z]
        )
    ]
    boxes = terrain.boxes
    if boxes:
        centers = np.array([b.center for b in boxes])
        for group in _spatial_groups(centers, np.arange(len(boxes)), BULLET_COMPOUND_MAX):
            chosen = [boxes[k] for k in group]
            shape = client.createCollisionShapeArray(
                shapeTypes=[pybullet.GEOM_BOX] * len(chosen),
                halfExtents=[list(b.half_extents) for b in chosen],
                collisionFramePositions=[list(b.center) for b in chosen],
                collisionFrameOrientations=[list(b.quat_xyzw()) for b in chosen],
            )
            bodies.append(client.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape))
    for body in bodies:
        client.changeDynamics(
            body, -1, lateralFriction=friction, restitution=0.0, rollingFriction=0.0, spinningFriction=0.0
        )
    return bodies


def add_to_physx(scene, terrain: Terrain, material) -> list:
    """Add the terrain to a SAPIEN scene as static actors (PhysX).

    The floor is PhysX's infinite plane at ``terrain.floor_z`` (``scene.add_ground``); the boxes are box shapes of
    one static actor, in ``terrain.boxes`` order.

    Args:
        scene: a ``sapien.Scene`` with a PhysX system.
        terrain: the terrain.
        material: the ``sapien.physx.PhysxMaterial`` of every terrain shape (its friction is the contact's:
            see the module docstring).

    Returns:
        the actors' entities: the floor first, then the boxes' actor (when there are boxes).
    """
    from frbench.backends.physx_scene import import_sapien

    sapien = import_sapien()
    entities = [scene.add_ground(terrain.floor_z, render=False, material=material)]
    if terrain.boxes:
        builder = scene.create_actor_builder()
        for box in terrain.boxes:
            builder.add_box_collision(sapien.Pose(list(box.center), list(box.quat_wxyz())), list(box.half_extents),
                                      material=material)
        builder.set_physx_body_type("static")
        builder.set_name("terrain_boxes")
        entities.append(builder.build())
    return entities
