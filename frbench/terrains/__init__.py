"""Terrains for fall recovery: seven families × ten levels, built from boxes.

``make_terrain(family, level, seed)`` gives a :class:`Terrain` (static boxes
over a floor plane, plus the spawn pose of the fallen robot);
:func:`height_at`, :func:`height_scan` and :func:`support_height` answer
geometric questions analytically. The simulator side lives in
:mod:`frbench.backends.terrain_build` (``add_to_mjspec``, ``add_to_bullet``), which is
not imported here so that importing this package loads no simulator.
"""

from frbench.terrains.families import (
    BURY_M,
    FAMILIES,
    FAMILY_SUMMARIES,
    LEVELS,
    TILE_HALF_M,
    LevelParameter,
    generate,
    level_parameters,
    make_terrain,
    parameter_specs,
    parameters_table_markdown,
    terrain_rng,
)
from frbench.terrains.geometry import (
    SCAN_POINTS,
    Box,
    Terrain,
    height_at,
    height_scan,
    scan_points_world,
    support_height,
)

__all__ = [
    "BURY_M",
    "FAMILIES",
    "FAMILY_SUMMARIES",
    "LEVELS",
    "SCAN_POINTS",
    "TILE_HALF_M",
    "Box",
    "LevelParameter",
    "Terrain",
    "generate",
    "height_at",
    "height_scan",
    "level_parameters",
    "make_terrain",
    "parameter_specs",
    "parameters_table_markdown",
    "scan_points_world",
    "support_height",
    "terrain_rng",
]
