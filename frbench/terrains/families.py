"""The seven terrain families and their ten difficulty levels.

``generate(family, level, rng)`` turns (family, level, random generator) into a
:class:`~frbench.terrains.geometry.Terrain` made of box primitives; the same
inputs give the same boxes bit for bit. ``level_parameters(family, level)`` is
the deterministic part: every difficulty parameter moves linearly from its
level-1 value to its level-10 value, so each one is monotone in the level.
The random generator only places things (cell heights, stones, platform
sizes, beam phase) and picks the spawn pose.

Layout shared by all families: the robot's base is spawned near the origin,
on the feature that makes the family hard, and every surface the robot can
reach lies in the 6 × 6 m tile |x|, |y| ≤ ``TILE_HALF_M``; beyond it there is
only the floor plane. Boxes reach ``BURY_M`` below the floor so no seam opens
between a box and the floor.

Ranges (see docs/terrains.md and the notes on legged_gym / Isaac Lab /
extreme-parkour): rough ±0.01…0.10 m (Isaac Lab noise 0.02–0.10 m), slopes
4…40° (legged_gym 0.4 rad·d, the paper's 40° slope), stairs 0.05…0.25 m on
0.31 m treads (legged_gym 0.05 + 0.18·d on 0.31 m; the paper's 38.5–40°
stairs), stones up to 0.22 m (legged_gym discrete obstacles 0.05 + 0.2·d),
gaps 0.1…0.8 m wide and 0.2…1.0 m deep (extreme-parkour 0.1 + 0.7·d, depth
0.2–1 m), beams 0.50…0.15 m wide (the paper's air-beam / suspended-beam
scenes).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from frbench.terrains.geometry import Box, Terrain

FAMILIES: tuple[str, ...] = ("flat", "rough", "slopes", "stairs", "stones", "gaps", "beams")
LEVELS = range(1, 11)

#: Half side of the square tile around the spawn that holds every reachable surface [m].
TILE_HALF_M = 3.0
#: How far boxes reach below the floor plane [m].
BURY_M = 0.1

#: One sentence per family, for listings and the docs.
FAMILY_SUMMARIES: dict[str, str] = {
    "flat": "Flat ground (the floor plane only); every level is the same.",
    "rough": "A grid of square cells whose tops are uniform in ±amplitude; the robot lies on the grid.",
    "slopes": "One large pitched box; the robot lies on the incline, facing up or down the slope.",
    "stairs": "A straight flight, steps up and steps down from the spawn; the robot lies across a step edge, "
    "facing up or down the flight.",
    "stones": "Axis-aligned rectangular blocks of random height scattered on the floor, three of them under the robot.",
    "gaps": "A grid of platforms separated by gaps over a pit; the robot lies on a platform, near its centre at "
    "level 1 and beside a gap edge, its body overhanging the gap, at level 10.",
    "beams": "Parallel beams suspended over a pit, narrower and further apart with the level; the robot lies across "
    "them, centred on one wide beam at level 1 and anywhere across the beams at level 10.",
}


@dataclasses.dataclass(frozen=True)
class LevelParameter:
    """One difficulty parameter of a family.

    Attributes:
        name: key in ``level_parameters(...)``; the suffix is the unit
            (``_m`` metres, ``_deg`` degrees, ``_per_m2`` per square metre).
        level1, level10: values at levels 1 and 10; levels between are linear.
        meaning: what the parameter controls (one line).
        derive: for a derived parameter, its value from the others (then
            level1 and level10 are ignored).
        digits: decimals shown in the docs table.
    """

    name: str
    level1: float
    level10: float
    meaning: str
    derive: Callable[[dict[str, float]], float] | None = None
    digits: int = 3

    def value(self, level: int) -> float:
        """The value at ``level`` (1–10): exact at both ends and for constants."""
        if self.level1 == self.level10:
            return float(self.level1)
        d = (level - 1) / 9.0
        return (1.0 - d) * self.level1 + d * self.level10


_P = LevelParameter
_PARAMETERS: dict[str, tuple[LevelParameter, ...]] = {
    "flat": (),
    "rough": (
        _P("amplitude_m", 0.01, 0.10, "cell top heights are uniform in [−amplitude, +amplitude]"),
        _P("cell_m", 0.25, 0.25, "side of a square cell"),
    ),
    "slopes": (_P("slope_deg", 4.0, 40.0, "incline angle", digits=1),),
    "stairs": (
        _P("step_height_m", 0.02, 0.25, "rise of every step"),
        _P("tread_m", 0.31, 0.31, "run of every step"),
        _P(
            "stair_angle_deg", 0.0, 0.0, "atan(step_height / tread)", digits=1,
            derive=lambda p: math.degrees(math.atan2(p["step_height_m"], p["tread_m"])),
        ),
        _P("steps_each_way", 8, 8, "steps up and steps down from the spawn edge", digits=0),
    ),
    "stones": (
        _P("stone_height_min_m", 0.01, 0.055, "lowest stone top above the floor"),
        _P("stone_height_max_m", 0.04, 0.22, "highest stone top above the floor"),
        _P("stones_per_m2", 0.8, 3.2, "stones per square metre of the 5 × 5 m stone field", digits=2),
        _P("stone_size_min_m", 0.2, 0.2, "smallest stone side"),
        _P("stone_size_max_m", 0.5, 0.5, "largest stone side"),
    ),
    "gaps": (
        _P("gap_width_m", 0.10, 0.80, "width of every gap between platforms"),
        _P("gap_depth_m", 0.20, 1.00, "drop from the platform tops to the pit floor"),
        _P("base_to_edge_min_m", 0.80, 0.05, "smallest distance from the spawn to the nearest gap edge"),
        _P("base_to_edge_max_m", 1.00, 0.25, "largest distance from the spawn to the nearest gap edge"),
        _P("platform_min_m", 2.0, 1.0, "smallest platform side"),
        _P("platform_max_m", 2.4, 1.4, "largest platform side"),
    ),
    "beams": (
        _P("beam_width_m", 1.20, 0.15, "width of every beam (narrower is harder)"),
        _P("beam_gap_m", 0.05, 0.35, "clear gap between neighbouring beams"),
        _P("pit_depth_m", 0.30, 1.00, "drop from the beam tops to the pit floor"),
        _P("spawn_offset_max_m", 0.0, 0.25, "largest distance from the spawn to the centre line of the beam under it"),
        _P("beam_thickness_m", 0.10, 0.10, "vertical thickness of a suspended beam"),
    ),
}
del _P


def _check_family(family: str) -> None:
    if family not in FAMILIES:
        raise ValueError(f"unknown terrain family {family!r}; valid families: {', '.join(FAMILIES)}")


def _check_level(level: int) -> None:
    ok = isinstance(level, (int, np.integer)) and not isinstance(level, bool) and LEVELS[0] <= level <= LEVELS[-1]
    if not ok:
        raise ValueError(
            f"invalid terrain level {level!r}; valid levels: integers {', '.join(str(v) for v in LEVELS)}"
        )


def parameter_specs(family: str) -> tuple[LevelParameter, ...]:
    """The parameters of a family, in table order."""
    _check_family(family)
    return _PARAMETERS[family]


def level_parameters(family: str, level: int) -> dict[str, float]:
    """The deterministic parameters of one level (units in the key suffixes).

    Every parameter is monotone in the level, each in the direction that makes the scene harder:
    non-decreasing, except ``beam_width_m``, ``base_to_edge_*`` and ``platform_*``, which decrease
    (narrower beams, a spawn nearer the edge of a smaller platform are harder).
    """
    _check_family(family)
    _check_level(level)
    params: dict[str, float] = {}
    for spec in _PARAMETERS[family]:
        params[spec.name] = float(spec.derive(params) if spec.derive else spec.value(int(level)))
    return params


def parameters_table_markdown() -> str:
    """Markdown tables of every family's parameters per level (used in docs/terrains.md)."""
    out: list[str] = []
    for family in FAMILIES:
        out.append(f"### `{family}`\n")
        out.append(FAMILY_SUMMARIES[family] + "\n")
        specs = _PARAMETERS[family]
        if not specs:
            out.append("No parameters: the floor plane at z = 0 and no boxes, at every level.\n")
            continue
        out.append("| level | " + " | ".join(f"`{s.name}`" for s in specs) + " |")
        out.append("|---:|" + "---:|" * len(specs))
        for level in LEVELS:
            p = level_parameters(family, level)
            out.append(f"| {level} | " + " | ".join(f"{p[s.name]:.{s.digits}f}" for s in specs) + " |")
        out.append("")
        for s in specs:
            out.append(f"- `{s.name}`: {s.meaning}.")
        out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------------------
# Geometry helpers


def _slab(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> Box:
    """Axis-aligned box spanning [x0, x1] × [y0, y1] × [z0, z1] [m]."""
    return Box(((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2), ((x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2))


def _wrap(angle: float) -> float:
    """Angle wrapped to [−π, π] [rad]."""
    return math.remainder(float(angle), math.tau)


def _up_or_down(rng: np.random.Generator, jitter_deg: float = 15.0) -> float:
    """Heading along ±x (chosen by rng) plus a uniform jitter of ±jitter_deg [rad]."""
    base = math.pi * int(rng.integers(2))
    return _wrap(base + math.radians(rng.uniform(-jitter_deg, jitter_deg)))


@dataclasses.dataclass
class _Layout:
    boxes: list[Box]
    floor_z: float
    spawn_xy: tuple[float, float]
    spawn_yaw: float
    description: str


# ---------------------------------------------------------------------------
# Families. Each takes the level's parameters and the generator and draws from
# the generator in a fixed order.


def _flat(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    yaw = rng.uniform(-math.pi, math.pi)
    return _Layout([], 0.0, (0.0, 0.0), yaw, "flat ground")


def _rough(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    amp, cell = p["amplitude_m"], p["cell_m"]
    n = int(round(2 * (TILE_HALF_M - 0.5) / cell))  # a 5 × 5 m field of cells
    x0 = -n * cell / 2
    tops = rng.uniform(-amp, amp, size=(n, n))
    # Equal-sized columns whose bottoms lie below the floor.
    height = 2 * amp + BURY_M
    boxes = [
        _slab(x0 + i * cell, x0 + (i + 1) * cell, x0 + j * cell, x0 + (j + 1) * cell, tops[i, j] - height, tops[i, j])
        for i in range(n)
        for j in range(n)
    ]
    xy = rng.uniform(-0.15, 0.15, size=2)
    yaw = rng.uniform(-math.pi, math.pi)
    return _Layout(boxes, -amp, (xy[0], xy[1]), yaw, f"rough: {n}×{n} cells of {cell:.2f} m, tops ±{amp:.3f} m")


def _slopes(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    theta = math.radians(p["slope_deg"])
    # Horizontal half run: the top face spans x in [−a, a], z = x·tanθ. Its ends
    # lie 1 m outside the tile, so the robot (and a ray test) only meets the face.
    a = TILE_HALF_M + 1.0
    hx = a / math.cos(theta)
    hz = a * math.sin(theta) + BURY_M * math.cos(theta) / 2 + 0.05  # bottom stays under the floor
    normal = (-math.sin(theta), 0.0, math.cos(theta))
    center = (-hz * normal[0], 0.0, -hz * normal[2])  # top face centred on the origin
    box = Box(center, (hx, TILE_HALF_M, hz), (0.0, -theta, 0.0))  # rises towards +x
    xy = rng.uniform(-0.2, 0.2, size=2)
    yaw = _up_or_down(rng)
    facing = "up" if abs(yaw) < math.pi / 2 else "down"
    return _Layout(
        [box], -a * math.tan(theta), (xy[0], xy[1]), yaw, f"slopes: {p['slope_deg']:.1f}° incline, facing {facing}"
    )


def _stairs(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    rise, run, n = p["step_height_m"], p["tread_m"], int(p["steps_each_way"])
    floor_z = -n * rise  # the bottom landing
    boxes = []
    for i in range(-n, n):  # tread i spans [i·run, (i+1)·run], top (i + 1)·rise; the edge at x = 0 rises by one step
        x1 = (i + 1) * run if i < n - 1 else max((i + 1) * run, TILE_HALF_M)  # the top tread is the top landing
        boxes.append(_slab(i * run, x1, -TILE_HALF_M, TILE_HALF_M, floor_z - BURY_M, (i + 1) * rise))
    x = rng.uniform(-0.05, 0.05)
    y = rng.uniform(-0.3, 0.3)
    yaw = _up_or_down(rng)
    facing = "up" if abs(yaw) < math.pi / 2 else "down"
    return _Layout(
        boxes, floor_z, (x, y), yaw,
        f"stairs: {n} steps up and {n} down, {rise:.3f} m on {run:.2f} m treads "
        f"({p['stair_angle_deg']:.1f}°), across the edge at x = 0, facing {facing}",
    )


def _stones(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    field_half = TILE_HALF_M - 0.5
    count = int(round(p["stones_per_m2"] * (2 * field_half) ** 2))
    near = 3  # stones under the robot
    boxes = []
    for k in range(count):
        if k < near:
            r, phi = 0.3 * math.sqrt(rng.uniform()), rng.uniform(0, math.tau)
            cx, cy = r * math.cos(phi), r * math.sin(phi)
        else:
            cx, cy = rng.uniform(-field_half, field_half, size=2)
        sx, sy = rng.uniform(p["stone_size_min_m"], p["stone_size_max_m"], size=2)
        top = rng.uniform(p["stone_height_min_m"], p["stone_height_max_m"])
        boxes.append(_slab(cx - sx / 2, cx + sx / 2, cy - sy / 2, cy + sy / 2, -BURY_M, top))
    yaw = rng.uniform(-math.pi, math.pi)
    return _Layout(
        boxes, 0.0, (0.0, 0.0), yaw,
        f"stones: {count} blocks {p['stone_height_min_m']:.3f}–{p['stone_height_max_m']:.3f} m high",
    )


def _intervals(rng: np.random.Generator, first: tuple[float, float], gap: float, lo: float, hi: float) -> list:
    """Platform intervals along one axis: ``first``, then alternating gap and
    platform (side U(lo, hi)) outwards, clipped to the tile."""
    out = [first]
    cursor = first[1] + gap
    while cursor < TILE_HALF_M:
        w = rng.uniform(lo, hi)
        out.append((cursor, min(cursor + w, TILE_HALF_M)))
        cursor += w + gap
    cursor = first[0] - gap
    while cursor > -TILE_HALF_M:
        w = rng.uniform(lo, hi)
        out.append((max(cursor - w, -TILE_HALF_M), cursor))
        cursor -= w + gap
    return [iv for iv in out if iv[1] - iv[0] > 0.05]


def _gaps(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    gap, depth = p["gap_width_m"], p["gap_depth_m"]
    lo, hi = p["platform_min_m"], p["platform_max_m"]
    edge = rng.uniform(p["base_to_edge_min_m"], p["base_to_edge_max_m"])  # spawn → the gap edge at +x
    w0 = rng.uniform(lo, hi)
    xs = _intervals(rng, (edge - w0, edge), gap, lo, hi)
    v = rng.uniform(lo / 2, hi / 2, size=2)  # the spawn platform's y edges
    ys = _intervals(rng, (-v[0], v[1]), gap, lo, hi)
    boxes = [_slab(x0, x1, y0, y1, -depth - BURY_M, 0.0) for (x0, x1) in xs for (y0, y1) in ys]
    yaw = rng.uniform(-math.pi, math.pi)
    return _Layout(
        boxes, -depth, (0.0, 0.0), yaw,
        f"gaps: {len(boxes)} platforms, gaps {gap:.2f} m wide and {depth:.2f} m deep, base {edge:.2f} m from an edge",
    )


def _beams(p: dict[str, float], rng: np.random.Generator) -> _Layout:
    width, gap, depth, thick = p["beam_width_m"], p["beam_gap_m"], p["pit_depth_m"], p["beam_thickness_m"]
    pitch = width + gap
    offset = min(p["spawn_offset_max_m"], pitch / 2)
    phase = rng.uniform(-offset, offset)  # the centre line of the beam under the spawn
    k0 = math.ceil((-TILE_HALF_M + width / 2 - phase) / pitch)
    k1 = math.floor((TILE_HALF_M - width / 2 - phase) / pitch)
    boxes = [Box((phase + k * pitch, 0.0, -thick / 2), (width / 2, TILE_HALF_M, thick / 2)) for k in range(k0, k1 + 1)]
    yaw = _up_or_down(rng)  # the robot's long axis across the beams (which run along y)
    return _Layout(
        boxes, -depth, (0.0, 0.0), yaw,
        f"beams: {len(boxes)} beams {width:.2f} m wide, {gap:.2f} m apart, over a {depth:.2f} m pit",
    )


_GENERATORS: dict[str, Callable[[dict[str, float], np.random.Generator], _Layout]] = {
    "flat": _flat,
    "rough": _rough,
    "slopes": _slopes,
    "stairs": _stairs,
    "stones": _stones,
    "gaps": _gaps,
    "beams": _beams,
}


def generate(family: str, level: int, rng: np.random.Generator) -> Terrain:
    """One terrain instance of ``family`` at ``level`` (1–10), drawn with ``rng``.

    The result depends only on (family, level, the generator's state): the
    same inputs give identical boxes. ``Terrain.seed`` is −1 (unknown); use
    :func:`make_terrain` to generate from an integer seed.

    Raises:
        ValueError: unknown family or level outside 1–10.
        TypeError: ``rng`` is not a ``numpy.random.Generator``.
    """
    _check_family(family)
    _check_level(level)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    params = level_parameters(family, level)
    lay = _GENERATORS[family](params, rng)
    return Terrain(
        family=family,
        level=int(level),
        seed=-1,
        boxes=tuple(lay.boxes),
        floor_z=lay.floor_z,
        spawn_xy=lay.spawn_xy,
        spawn_yaw=_wrap(lay.spawn_yaw),
        params=params,
        description=f"{lay.description} (level {int(level)})",
    )


def terrain_rng(family: str, level: int, seed: int) -> np.random.Generator:
    """The generator ``make_terrain`` uses: SeedSequence([seed, family index, level])."""
    _check_family(family)
    _check_level(level)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"terrain seed must be an integer >= 0, got {seed!r}")
    return np.random.default_rng(np.random.SeedSequence([int(seed), FAMILIES.index(family), int(level)]))


def make_terrain(family: str, level: int, seed: int) -> Terrain:
    """The terrain instance for (family, level, seed), reproducible bit for bit."""
    terrain = generate(family, level, terrain_rng(family, level, seed))
    return dataclasses.replace(terrain, seed=int(seed))
