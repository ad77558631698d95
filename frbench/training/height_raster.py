"""Fast terrain heights for the critic's 187-point scan: one raster per grid tile.

The exact `height_at` costs about 0.3 s for 512 × 187 points on the training
world; the scan is privileged information for the critic, so a 4 cm raster of
each tile (built once with `height_at`) and a nearest-cell lookup suffice. The lookups take numpy arrays or torch
tensors (`frbench.arrays`: the rasters go to a device once).
"""

from __future__ import annotations

import numpy as np

from frbench.arrays import namespace, resident
from frbench.content_cache import cached_bytes, content_key, object_key, source_key
from frbench.terrains import SCAN_POINTS, height_at

RESOLUTION = 0.04  # m
HALF_SIZE = 3.2  # m around each tile's spawn


def raster_size() -> int:
    """Cells per side of a tile's raster."""
    return int(round(2 * HALF_SIZE / RESOLUTION)) + 1


class HeightRaster:
    """Heights around every tile of a `TerrainGrid`, looked up per environment. Attributes: ``tile_keys`` (T,)
    (family index, level), ``index`` key → row, ``centres`` (T, 2) [m], ``heights`` (T, n, n) float32 [m],
    ``floor`` [m] (the height off the rasters), ``n``."""

    def __init__(self, grid, tile_keys: list[tuple[int, int]]):
        n = raster_size()
        axis = np.linspace(-HALF_SIZE, HALF_SIZE, n)
        gx, gy = np.meshgrid(axis, axis, indexing="ij")
        centres = np.array([grid.spawn(*key)[:2] for key in tile_keys], dtype=float).reshape(-1, 2)

        def rasters() -> bytes:  # slow (`height_at` on every cell), so cached by its inputs
            heights = np.zeros((len(tile_keys), n, n), dtype=np.float32)
            for i, (x, y) in enumerate(centres):
                points = np.stack([gx + x, gy + y], axis=-1).reshape(-1, 2)
                heights[i] = height_at(grid.world, points).reshape(n, n)
            return heights.tobytes()

        key = content_key(object_key(grid.world), centres.tobytes(), RESOLUTION, HALF_SIZE,
                          source_key(__name__, "frbench.terrains.geometry"))
        heights = cached_bytes("height-rasters", key, ".f32", rasters,
                               lambda data: np.frombuffer(data, dtype=np.float32).reshape(len(tile_keys), n, n))
        self._hold(tile_keys, centres, heights, float(grid.world.floor_z))

    @classmethod
    def from_arrays(cls, tile_keys, centres: np.ndarray, heights: np.ndarray, floor: float) -> "HeightRaster":
        """The raster of `HeightRaster` attributes made before (a bundle's), without the grid."""
        raster = cls.__new__(cls)
        raster._hold([tuple(map(int, key)) for key in tile_keys], np.asarray(centres, dtype=float),
                     np.asarray(heights, dtype=np.float32), float(floor))
        return raster

    def _hold(self, tile_keys, centres: np.ndarray, heights: np.ndarray, floor: float) -> None:
        self.tile_keys = tile_keys
        self.index = {key: i for i, key in enumerate(tile_keys)}
        self.centres, self.heights, self.floor, self.n = centres, heights, floor, heights.shape[-1]
        # one cell of the world's floor height (as float32, the rasters' type) around every raster: a point off
        # the raster reads it after its cell indices are clipped to [-1, n]
        self._bordered = np.pad(self.heights, ((0, 0), (1, 1), (1, 1)), constant_values=np.float32(self.floor)).ravel()

    def lookup(self, tile, xy):
        """Heights [m] at world points ``xy`` (N, P, 2) for environments on tiles ``tile`` (N,) (row indices, in
        ``xy``'s namespace)."""
        return self._heights(tile, xy[..., 0], xy[..., 1])

    def _heights(self, tile, x, y):
        """Heights (N, P) float32 [m] at world points (``x``, ``y``) (N, P) each: the nearest raster cell of each
        environment's tile, the floor off the raster; numpy or torch (``tile`` in the same namespace)."""
        xp, side = namespace(x), self.n + 2
        centres = resident(self.centres, x)[tile]
        i = xp.astype(xp.round((x - centres[:, :1] + HALF_SIZE) / RESOLUTION), xp.int64)
        j = xp.astype(xp.round((y - centres[:, 1:] + HALF_SIZE) / RESOLUTION), xp.int64)
        i = (xp.clip(i, -1, self.n) + 1) * side + xp.clip(j, -1, self.n) + 1 + (tile * (side * side))[:, None]
        return resident(self._bordered, x)[i]

    def scan(self, tile, base_pos, yaw):
        """The 187-point scan (N, 187): base z − terrain height at the yaw-frame grid (see `height_scan`)."""
        xp = namespace(base_pos)
        points = resident(SCAN_POINTS, base_pos)
        c, s = xp.cos(yaw)[:, None], xp.sin(yaw)[:, None]
        px, py = points[:, 0][None], points[:, 1][None]
        x = base_pos[:, :1] + c * px - s * py
        y = base_pos[:, 1:2] + s * px + c * py
        return base_pos[:, 2:3] - self._heights(tile, x, y)
