"""All terrain families and levels in one world, for training with a curriculum.

A batched simulator holds one world, so training lays the 7 × 10 terrain
tiles (`make_terrain(family, level, seed)`) side by side: tile (f, l) is
shifted by (f·`TILE_PITCH`, (l − 1)·`TILE_PITCH`). An environment moves to
another family or level by being reset on another tile. Each tile keeps the
boxes within `CROP_RADIUS` of its spawn point (a recovering robot stays
within about 1 m of it) and gets a base box up to its own floor height, so
tiles with different floors (gap and beam pits) share one floor plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.terrains import FAMILIES, Box, Terrain, make_terrain

TILE_PITCH = 8.0  # m between tile centres
CROP_RADIUS = 1.6  # m of terrain kept around each spawn (a robot that moves further has failed)
BASE_HALF = 2.0  # m: half side of each tile's base box


@dataclass(frozen=True)
class TerrainGrid:
    """The combined world and, per tile, its own terrain and offset.

    Attributes:
        world: one `Terrain` holding every tile's boxes (family ``"grid"``).
        tiles: (family index, level) → the tile's own terrain (unshifted).
        offsets: (family index, level) → (x, y) shift of that tile [m].
    """

    world: Terrain
    tiles: dict
    offsets: dict

    def spawn(self, family: int, level: int) -> tuple[float, float, float]:
        """World (x, y, yaw) of a tile's spawn point."""
        tile, (dx, dy) = self.tiles[(family, level)], self.offsets[(family, level)]
        return tile.spawn_xy[0] + dx, tile.spawn_xy[1] + dy, tile.spawn_yaw


def _shifted(box: Box, dx: float, dy: float) -> Box:
    x, y, z = box.center
    return Box((x + dx, y + dy, z), box.half_extents, box.rpy)


def _near(box: Box, xy, radius: float) -> bool:
    corners = box.corners()[:, :2]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    nearest = np.clip(np.asarray(xy), lo, hi)
    return bool(np.linalg.norm(nearest - np.asarray(xy)) <= radius)


def build_grid(families=FAMILIES, levels=range(1, 11), seed: int = 0) -> TerrainGrid:
    """The training world for ``families`` × ``levels`` (tile seeds from ``seed``)."""
    tiles, offsets, boxes = {}, {}, []
    floors = []
    for f, family in enumerate(families):
        for level in levels:
            tile = make_terrain(family, level, seed + level)
            dx, dy = f * TILE_PITCH, (level - 1) * TILE_PITCH
            tiles[(f, level)], offsets[(f, level)] = tile, (dx, dy)
            floors.append(tile.floor_z)
            cx, cy = tile.spawn_xy
            boxes += [_shifted(b, dx, dy) for b in tile.boxes if _near(b, (cx, cy), CROP_RADIUS)]
    floor = min(floors) - 0.5
    for (f, level), tile in tiles.items():
        dx, dy = offsets[(f, level)]
        cx, cy = tile.spawn_xy
        top = tile.floor_z
        boxes.append(Box((cx + dx, cy + dy, (top + floor) / 2), (BASE_HALF, BASE_HALF, (top - floor) / 2)))
    world = Terrain(family="grid", level=0, seed=seed, boxes=tuple(boxes), floor_z=floor, spawn_xy=(0.0, 0.0),
                    spawn_yaw=0.0, description=f"{len(families)} families x {len(levels)} levels")
    return TerrainGrid(world=world, tiles=tiles, offsets=offsets)

