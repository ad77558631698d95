"""Terrain as data, and its exact analytic geometry.

A terrain is a tuple of static boxes over an infinite floor plane. This module
defines those two records (:class:`Box`, :class:`Terrain`) and answers
geometric questions about them without any simulator:

* :func:`height_at` — the height a vertical ray cast downward from high above
  first hits (the same number MuJoCo's ``mj_ray`` and PyBullet's ``rayTest``
  return for the geometry :mod:`frbench.backends.terrain_build` creates);
* :func:`height_scan` — the 187-point height scan of the FR-Net critic;
* :func:`support_height` — the highest terrain point within a disc (to drop a
  robot without intersecting the terrain).

Conventions: SI units (metres, radians), z up, world frame. Rotations use the
URDF convention R = Rz(yaw)·Ry(pitch)·Rx(roll). Nothing here imports a
simulator or touches a global random generator.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

#: Scan grid along the base's heading x [m]: 17 values, −0.8 … 0.8.
SCAN_X = np.round(np.linspace(-0.8, 0.8, 17), 10)
#: Scan grid across the base's heading y [m]: 11 values, −0.5 … 0.5.
SCAN_Y = np.round(np.linspace(-0.5, 0.5, 11), 10)
#: The 187 scan points (x, y) in the base's yaw frame [m], shape (187, 2),
#: x-major order: point ``i * 11 + j`` is ``(SCAN_X[i], SCAN_Y[j])`` (the order of
#: legged_gym's ``meshgrid(x, y)`` flattening). Point 93 is (0, 0).
SCAN_POINTS = np.stack(np.meshgrid(SCAN_X, SCAN_Y, indexing="ij"), axis=-1).reshape(-1, 2)
SCAN_POINTS.setflags(write=False)

_CHUNK = 1 << 14  # points evaluated per vectorised batch in height_at


def _triple(name: str, value) -> tuple[float, float, float]:
    out = tuple(float(v) for v in value)
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise ValueError(f"Box.{name} must be 3 finite numbers, got {value!r}")
    return out  # type: ignore[return-value]


@dataclasses.dataclass(frozen=True)
class Box:
    """A static box primitive.

    Attributes:
        center: centre of the box in the world frame [m].
        half_extents: half sizes along the box's own x, y, z axes [m], all > 0.
        rpy: orientation as (roll, pitch, yaw) [rad], URDF convention
            R = Rz(yaw)·Ry(pitch)·Rx(roll) (the box's axes are R's columns).
    """

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("center", "half_extents", "rpy"):
            object.__setattr__(self, name, _triple(name, getattr(self, name)))
        if min(self.half_extents) <= 0.0:
            raise ValueError(f"Box.half_extents must be > 0, got {self.half_extents}")

    def rotation(self) -> np.ndarray:
        """Rotation matrix R = Rz(yaw)·Ry(pitch)·Rx(roll), shape (3, 3)."""
        r, p, y = self.rpy
        cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
        return np.array(
            [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ]
        )

    def quat_wxyz(self) -> tuple[float, float, float, float]:
        """Orientation as a unit quaternion (w, x, y, z) (MuJoCo order)."""
        r, p, y = (0.5 * a for a in self.rpy)
        cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
        return (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        )

    def quat_xyzw(self) -> tuple[float, float, float, float]:
        """Orientation as a unit quaternion (x, y, z, w) (PyBullet order)."""
        w, x, y, z = self.quat_wxyz()
        return (x, y, z, w)

    def corners(self) -> np.ndarray:
        """The 8 vertices in the world frame [m], shape (8, 3)."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        return np.asarray(self.center) + (signs * np.asarray(self.half_extents)) @ self.rotation().T

    @property
    def top_z(self) -> float:
        """Highest z of the box [m]."""
        return float(self.corners()[:, 2].max())


@dataclasses.dataclass(frozen=True)
class Terrain:
    """One terrain instance: static boxes over an infinite floor plane.

    Attributes:
        family: terrain family name (one of ``frbench.terrains.FAMILIES``).
        level: difficulty level, 1 (easiest) … 10 (hardest).
        seed: the integer seed given to ``make_terrain``; −1 when the terrain
            was generated from a caller's ``numpy.random.Generator``.
        boxes: the static boxes; the same tuple is built in every backend.
        floor_z: height of the infinite floor plane under everything [m]
            (0 on flat ground, the pit bottom for gaps and beams, the foot
            of the flight or incline for stairs and slopes).
        spawn_xy: where the fallen robot's base is placed (x, y) [m], on the
            feature that makes the family hard.
        spawn_yaw: heading of the base's x axis at the spawn [rad], in [−π, π].
        params: the level's parameters (``level_parameters(family, level)``).
        description: one human-readable line about this instance.
    """

    family: str
    level: int
    seed: int
    boxes: tuple[Box, ...]
    floor_z: float
    spawn_xy: tuple[float, float]
    spawn_yaw: float
    params: dict[str, float] = dataclasses.field(default_factory=dict, hash=False)
    description: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "boxes", tuple(self.boxes))
        if not all(isinstance(b, Box) for b in self.boxes):
            raise TypeError("Terrain.boxes must hold Box instances")
        object.__setattr__(self, "floor_z", float(self.floor_z))
        object.__setattr__(self, "spawn_xy", (float(self.spawn_xy[0]), float(self.spawn_xy[1])))
        object.__setattr__(self, "spawn_yaw", float(self.spawn_yaw))
        object.__setattr__(self, "params", {str(k): float(v) for k, v in self.params.items()})

    @property
    def top_z(self) -> float:
        """Highest point of the terrain (boxes or floor) [m]."""
        return max([self.floor_z] + [b.top_z for b in self.boxes])

    @functools.cached_property
    def _index(self) -> "_HeightIndex":
        return _HeightIndex(self.boxes, self.floor_z)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_index", None)  # a cache: rebuilt on first use
        return state


class _BoxGrid:
    """Some boxes' parameters packed in one array, plus a uniform xy grid
    listing the candidate boxes of each cell (padded with −1)."""

    def __init__(self, boxes: list[Box], packed: np.ndarray, cell: float = 0.25, max_cells: int = 64):
        self.packed = packed  # (B, F), one row per box
        corners = np.stack([b.corners() for b in boxes])  # (B, 8, 3)
        lo = corners[:, :, :2].min(axis=1)
        hi = corners[:, :, :2].max(axis=1)
        self.origin = lo.min(axis=0)
        extent = hi.max(axis=0) - self.origin
        self.cell = np.maximum(cell, extent / max_cells)  # (2,) cell size [m]
        self.shape = np.maximum(np.ceil(extent / self.cell).astype(np.int64), 1)  # (2,)
        i0 = np.clip(np.floor((lo - self.origin) / self.cell).astype(np.int64), 0, self.shape - 1)
        i1 = np.clip(np.floor((hi - self.origin) / self.cell).astype(np.int64), 0, self.shape - 1)
        lists: list[list[int]] = [[] for _ in range(int(self.shape[0] * self.shape[1]))]
        for k in range(len(boxes)):
            for ix in range(i0[k, 0], i1[k, 0] + 1):
                for iy in range(i0[k, 1], i1[k, 1] + 1):
                    lists[ix * self.shape[1] + iy].append(k)
        width = max(1, max(len(c) for c in lists))
        self.candidates = np.full((len(lists), width), -1, dtype=np.int64)
        for i, c in enumerate(lists):
            self.candidates[i, : len(c)] = c

    def gather(self, x: np.ndarray, y: np.ndarray):
        """Rows of the points that fall in the grid (P,), their candidate ids
        (P, K) and the candidates' packed parameters (P, K, F)."""
        ix = np.floor((x - self.origin[0]) / self.cell[0]).astype(np.int64)
        iy = np.floor((y - self.origin[1]) / self.cell[1]).astype(np.int64)
        rows = np.nonzero((ix >= 0) & (ix < self.shape[0]) & (iy >= 0) & (iy < self.shape[1]))[0]
        cand = self.candidates[ix[rows] * self.shape[1] + iy[rows]]
        return rows, cand, self.packed[cand]


class _HeightIndex:
    """Exact ray-hit heights of a box set, vectorised.

    Boxes with a horizontal top (rotation about z only) are tested as rotated
    rectangles. For other boxes, a point (x, y, z) of the vertical line
    expressed in the box's frame is ``a + z·b`` with ``a = Rᵀ((x, y, 0) − c)``
    and ``b = Rᵀ e_z`` (the third row of R); the line is inside the box where
    ``|a_i + z b_i| ≤ h_i`` for i = x, y, z (the slab method), and the upper end
    of that z interval is where a ray cast downward enters the box.
    """

    def __init__(self, boxes: tuple[Box, ...], floor_z: float):
        self.floor_z = float(floor_z)
        level, tilted = [], []
        for box in boxes:
            (level if box.rotation()[2, 2] == 1.0 else tilted).append(box)
        self.level = None
        self.tilted_corners = np.zeros((0, 8, 3))  # (T, 8, 3) vertices of the tilted boxes
        if level:  # packed: cx, cy, R00, R10, R01, R11, hx, hy, top
            rows = []
            for box in level:
                r = box.rotation()
                rows.append([*box.center[:2], r[0, 0], r[1, 0], r[0, 1], r[1, 1], *box.half_extents[:2],
                             box.center[2] + box.half_extents[2]])
            self.level = _BoxGrid(level, np.array(rows))
        self.tilted = None
        if tilted:  # packed: c (3), h (3), R row 0 (3), R row 1 (3), R row 2 (3)
            rows = [[*b.center, *b.half_extents, *b.rotation().ravel()] for b in tilted]
            self.tilted = _BoxGrid(tilted, np.array(rows))
            self.tilted_corners = np.stack([b.corners() for b in tilted])

    def heights(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ray-hit heights [m] at flat arrays x, y (shape (P,)) → shape (P,)."""
        out = np.full(x.shape, self.floor_z)
        if self.level is not None:
            rows, cand, p = self.level.gather(x, y)
            dx = x[rows, None] - p[..., 0]
            dy = y[rows, None] - p[..., 1]
            u = p[..., 2] * dx + p[..., 3] * dy
            v = p[..., 4] * dx + p[..., 5] * dy
            hit = (cand >= 0) & (np.abs(u) <= p[..., 6]) & (np.abs(v) <= p[..., 7])
            top = np.where(hit, p[..., 8], -np.inf).max(axis=1)
            out[rows] = np.maximum(out[rows], top)
        if self.tilted is not None:
            rows, cand, p = self.tilted.gather(x, y)
            top = _slab_entry(x[rows, None], y[rows, None], p)
            top = np.where(cand >= 0, top, -np.inf).max(axis=1)
            out[rows] = np.maximum(out[rows], top)
        return out


def _slab_entry(x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Entry height [m] of a downward vertical ray through (x, y) into oriented
    boxes packed as in ``_HeightIndex`` (p shape (..., 15)); −inf on a miss."""
    c, h, rot = p[..., 0:3], p[..., 3:6], p[..., 6:15].reshape(p.shape[:-1] + (3, 3))
    b = rot[..., 2, :]
    a = rot[..., 0, :] * (x - c[..., 0])[..., None] + rot[..., 1, :] * (y - c[..., 1])[..., None] - b * c[..., 2:3]
    flat = b == 0.0  # the line is parallel to this slab
    with np.errstate(divide="ignore", invalid="ignore"):
        z1 = (-h - a) / b
        z2 = (h - a) / b
    upper = np.where(flat, np.inf, np.maximum(z1, z2)).min(axis=-1)
    lower = np.where(flat, -np.inf, np.minimum(z1, z2)).max(axis=-1)
    ok = (lower <= upper) & ~(flat & (np.abs(a) > h)).any(axis=-1)
    return np.where(ok, upper, -np.inf)


def height_at(terrain: Terrain, xy: np.ndarray) -> np.ndarray:
    """Terrain height [m] under each point: the top surface a vertical ray cast
    downward from high above hits first (box entry point, else ``floor_z``).

    Args:
        terrain: the terrain.
        xy: world (x, y) [m], shape (..., 2).

    Returns:
        heights [m], shape (...). Exact (float64), no sampling.
    """
    xy = np.asarray(xy, dtype=float)
    if xy.ndim == 0 or xy.shape[-1] != 2:
        raise ValueError(f"height_at: xy must have shape (..., 2), got {xy.shape}")
    flat = xy.reshape(-1, 2)
    out = np.empty(flat.shape[0])
    index = terrain._index
    for s in range(0, flat.shape[0], _CHUNK):
        part = flat[s : s + _CHUNK]
        out[s : s + _CHUNK] = index.heights(part[:, 0], part[:, 1])
    return out.reshape(xy.shape[:-1])


def scan_points_world(base_pos: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World (x, y) of the 187 scan points [m], shape (N, 187, 2).

    Args:
        base_pos: base positions [m], shape (N, 3) (z is ignored).
        yaw: base headings [rad], shape (N,).
    """
    base_pos = np.asarray(base_pos, dtype=float)
    yaw = np.asarray(yaw, dtype=float)
    if base_pos.ndim != 2 or base_pos.shape[1] != 3 or yaw.shape != (base_pos.shape[0],):
        raise ValueError(
            f"height_scan: expected base_pos (N, 3) and yaw (N,), got {base_pos.shape} and {yaw.shape}"
        )
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    px, py = SCAN_POINTS[:, 0], SCAN_POINTS[:, 1]
    wx = base_pos[:, 0:1] + c * px - s * py
    wy = base_pos[:, 1:2] + s * px + c * py
    return np.stack([wx, wy], axis=-1)


def height_scan(terrain: Terrain, base_pos: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """The 187-point height scan h_t of the FR-Net critic.

    The points are :data:`SCAN_POINTS` (17 × 11, 0.1 m apart, x-major) rotated
    by each base's yaw only (not roll or pitch) and placed at its xy.

    Args:
        terrain: the terrain.
        base_pos: base positions [m], shape (N, 3).
        yaw: base headings [rad], shape (N,).

    Returns:
        ``base_z − terrain height`` at each point [m], shape (N, 187) (legged_gym
        convention before its offset: legged_gym feeds ``clip(base_z − 0.5 −
        height, −1, 1) · 5``; any such normalisation belongs to the task).
    """
    pts = scan_points_world(base_pos, yaw)
    return np.asarray(base_pos, dtype=float)[:, 2:3] - height_at(terrain, pts)


def support_height(terrain: Terrain, xy_center, radius: float, n_circle: int = 720) -> float:
    """Highest terrain point [m] within the disc of ``radius`` [m] around ``xy_center``.

    Exact for boxes with a horizontal top (disc–rectangle overlap). For tilted
    boxes the top is a concave function over the box's footprint, so its maximum
    over the disc lies at a box vertex inside the disc or on the disc's rim;
    the rim is sampled at ``n_circle`` angles (error ≤ r·(1 − cos(π/n))·slope,
    about 5 µm for r = 0.5 m).
    """
    cx, cy = (float(v) for v in xy_center)
    r = float(radius)
    if not (r >= 0.0 and math.isfinite(r)):
        raise ValueError(f"support_height: radius must be a finite number >= 0, got {radius!r}")
    phi = np.linspace(0.0, 2.0 * np.pi, n_circle, endpoint=False)
    probes = np.concatenate([[[cx, cy]], np.stack([cx + r * np.cos(phi), cy + r * np.sin(phi)], axis=-1)])
    best = float(height_at(terrain, probes).max())  # the floor, the centre and the rim
    index = terrain._index
    if index.level is not None:  # horizontal tops: exact disc–rectangle overlap, all boxes at once
        p = index.level.packed
        dx, dy = cx - p[:, 0], cy - p[:, 1]
        u = p[:, 2] * dx + p[:, 3] * dy
        v = p[:, 4] * dx + p[:, 5] * dy
        gap_u = np.abs(u) - np.minimum(np.abs(u), p[:, 6])
        gap_v = np.abs(v) - np.minimum(np.abs(v), p[:, 7])
        touching = gap_u * gap_u + gap_v * gap_v <= r * r
        if touching.any():
            best = max(best, float(p[touching, 8].max()))
    corners = index.tilted_corners.reshape(-1, 3)
    near = (corners[:, 0] - cx) ** 2 + (corners[:, 1] - cy) ** 2 <= r * r
    if near.any():  # vertices of tilted boxes inside the disc
        best = max(best, float(corners[near, 2].max()))
    return best
