"""The protocol's fallen starting states, drawn identically for every backend.

Each episode's start is a pure function of (protocol version, robot, terrain
family, level, seed, episode index): a policy always faces the same starts,
and MuJoCo and PyBullet get the same drawn configuration (they then settle it
for `SETTLE_SECONDS` each, under their own physics, before t = 0).

Draw (docs/protocol.md): the fall kind is one of supine, prone, left side,
right side and a uniformly random orientation, with `FALL_WEIGHTS`; yaw is uniform (flat) or
the terrain's spawn yaw ± 0.3 rad; joints are uniform within their limits,
redrawn while links intersect each other (`joint_redraws`: up to `MAX_REDRAWS` times, then the last draw
is kept, under protocols up to 1.3; until free, at most `MAX_FREE_REDRAWS` times, from 1.4). The
robot is then lifted so its lowest collision point is `DROP_HEIGHT` above the
highest terrain point within its reach.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from frbench.backends.base import RobotState
from frbench.backends.self_collision import self_intersects
from frbench.errors import FrbenchError
from frbench.portable_products import unit
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import parse_urdf
from frbench.tasks.protocol import FREE_STARTS_PROTOCOL, PROTOCOL_VERSION, STARTS_KEY_VERSION, version_key
from frbench.tasks.start_geometry import StartGeometry
from frbench.terrains import support_height

FALL_KINDS = ("supine", "prone", "left_side", "right_side", "random")
#: Probability of each fall kind. Prone starts are rare: from the belly a robot
#: that just pushes to its standing pose gets up, so they test little.
FALL_WEIGHTS = (0.3, 0.1, 0.2, 0.2, 0.2)
#: Side starts lean this far [rad] past 90° towards the back, so the settle
#: leaves them on their side or back rather than tipping them onto their feet.
SIDE_LEAN = 0.35
#: Height [m] of the lowest point above the terrain when dropped.
DROP_HEIGHT = 0.05
#: Settling time [s] before t = 0, joints held softly at the drawn angles.
SETTLE_SECONDS = 1.0
#: Gain scale during settling ("held softly").
SETTLE_GAIN_SCALE = 0.3
#: Yaw jitter [rad] around a terrain's spawn yaw.
YAW_JITTER = 0.3
#: Joint redraws tried before giving up on a self-intersection-free draw (protocols up to 1.3, and training
#: starts): the next draw is then kept, overlapping or not.
MAX_REDRAWS = 50
#: Joint redraws allowed from protocol 1.4 (`FREE_STARTS_PROTOCOL`) on, until a draw is free; a start whose draws
#: all overlap is an error. The evaluation grids' largest need is 1828 joint draws (Talos; docs/protocol.md,
#: "Protocol 1.4").
MAX_FREE_REDRAWS = 5000


@dataclass(frozen=True)
class JointRedraws:
    """How a start's joint angles are redrawn while its links overlap: at most ``limit`` redraws after the first
    draw; ``free`` True: a start whose last draw still overlaps raises a `FrbenchError`, False: it is kept."""

    limit: int
    free: bool


def joint_redraws(version: str = PROTOCOL_VERSION) -> JointRedraws:
    """The redraw rule of protocol ``version``: `MAX_REDRAWS` keeping the last draw before
    `FREE_STARTS_PROTOCOL`, `MAX_FREE_REDRAWS` until free from it on (the first 51 draws are the same under both,
    so only starts that exhausted 50 redraws differ)."""
    if version_key(version) >= version_key(FREE_STARTS_PROTOCOL):
        return JointRedraws(MAX_FREE_REDRAWS, True)
    return JointRedraws(MAX_REDRAWS, False)


@dataclass
class FallenStarts:
    """N drawn starts. base_pos (N, 3) [m], base_quat (N, 4) wxyz, q (N, n_joints) [rad], kinds (N,).

    ``cell`` (spec, terrain, family, level, seed, episode indices), ``attempts`` (N,) and ``redraws`` (the
    protocol's `JointRedraws`) are set by `draw_starts`: they let `frbench.tasks.start_screening` redraw a start
    deterministically.
    """

    base_pos: np.ndarray
    base_quat: np.ndarray
    q: np.ndarray
    kinds: list[str]
    cell: tuple | None = None
    attempts: np.ndarray | None = None
    redraws: JointRedraws | None = None


@dataclass(frozen=True)
class RecordedStarts:
    """N recorded starts, begun as they are (`frbench.tasks.recovery.RecoveryTask.begin`: no settle, velocities
    included) instead of drawn and settled: ``state`` a `RobotState` of N rows (e.g. mid-recovery states that
    ``tools/keyframe_states.py`` recorded), ``previous_action`` (N, n_joints) [rad] the joint targets the first
    observation reports as the previous action, or None for the state's joint angles. `run_episodes` takes them
    in place of `FallenStarts`; ``kinds`` (N,) are all ``"recorded"``."""

    state: RobotState
    previous_action: np.ndarray | None = None

    @property
    def kinds(self) -> list[str]:
        return ["recorded"] * len(self.state.q)


def episode_rng(robot: str, family: str, level: int, seed: int, episode: int, attempt: int = 0,
                protocol_version: str = STARTS_KEY_VERSION) -> np.random.Generator:
    """The generator of one episode's start: a pure function of the protocol version, the cell and the
    draw attempt (0 for the first draw; `frbench.tasks.start_screening` redraws with 1, 2, ...)."""
    key = f"{protocol_version}|{robot}|{family}|{int(level)}|{int(seed)}|{int(episode)}"
    if attempt:
        key += f"|redraw {int(attempt)}"
    words = np.frombuffer(hashlib.sha256(key.encode()).digest(), dtype=np.uint32)
    return np.random.default_rng(np.random.SeedSequence(words.tolist()))


def _quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def _axis_quat(axis: int, angle: float) -> np.ndarray:
    quat = np.zeros(4)
    quat[0] = np.cos(angle / 2)
    quat[1 + axis] = np.sin(angle / 2)
    return quat


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = unit(quat)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def fall_orientation(kind: str, robot_kind: str, yaw: float, rng: np.random.Generator) -> np.ndarray:
    """Base quaternion (w, x, y, z) of a fall kind, then yawed by ``yaw`` [rad].

    Quadrupeds lie on their back by rolling π about x; humanoids by pitching
    −π/2 about y (face up). Sides roll π/2 + `SIDE_LEAN` about x. A tilt of up
    to 0.2 rad is added to the named kinds.
    """
    if kind == "random":
        quat = rng.normal(size=4)
        return unit(quat)
    lying = {
        ("quadruped", "supine"): _axis_quat(0, np.pi),
        ("quadruped", "prone"): _axis_quat(0, 0.0),
        ("humanoid", "supine"): _axis_quat(1, -np.pi / 2),
        ("humanoid", "prone"): _axis_quat(1, np.pi / 2),
    }
    if kind in ("left_side", "right_side"):
        roll = np.pi / 2 + SIDE_LEAN
        base = _axis_quat(0, -roll if kind == "left_side" else roll)
    else:
        base = lying[(robot_kind, kind)]
    tilt = _quat_multiply(_axis_quat(0, rng.uniform(-0.2, 0.2)), _axis_quat(1, rng.uniform(-0.2, 0.2)))
    return _quat_multiply(_axis_quat(2, yaw), _quat_multiply(base, tilt))


@lru_cache(maxsize=32)
def _geometry(spec: RobotSpec) -> StartGeometry:
    return StartGeometry(parse_urdf(sim_robot_file(spec).path), spec.joint_names)


def lowest_offset_and_reach(spec: RobotSpec, quat: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """(lowest collision point z relative to the base [m], horizontal reach [m]) of a configuration: base
    orientation ``quat`` (4,) wxyz, joint angles ``q`` (n_joints,) [rad] (`StartGeometry`)."""
    rotation = np.eye(4)
    rotation[:3, :3] = quat_to_matrix(quat)
    return _geometry(spec).lowest_offset_and_reach(rotation, np.asarray(q))


def draw_start(spec: RobotSpec, terrain, rng: np.random.Generator, redraws: JointRedraws | None = None,
               where: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """One fallen start on ``terrain``: (base_pos (3,), base_quat (4,), q (n_joints,), kind). ``redraws``: the
    joint-redraw rule (None: `MAX_REDRAWS`, keeping the last draw, as training starts do); ``where`` names the
    start in the error a free rule raises when every draw overlaps."""
    redraws = redraws or JointRedraws(MAX_REDRAWS, False)
    kind = FALL_KINDS[rng.choice(len(FALL_KINDS), p=FALL_WEIGHTS)]
    if terrain.family == "flat":
        yaw = rng.uniform(-np.pi, np.pi)
    else:
        yaw = terrain.spawn_yaw + rng.uniform(-YAW_JITTER, YAW_JITTER)
    quat = fall_orientation(kind, spec.kind, yaw, rng)
    q = rng.uniform(spec.joint_lower, spec.joint_upper)
    for _ in range(redraws.limit):
        if not self_intersects(spec, q):
            break
        q = rng.uniform(spec.joint_lower, spec.joint_upper)
    else:
        if redraws.free and self_intersects(spec, q):
            raise FrbenchError(f"start of {spec.name}{' ' + where if where else ''}: its links overlap in every one "
                               f"of {redraws.limit + 1} joint draws (docs/protocol.md, \"Protocol 1.4\")")
    lowest, reach = lowest_offset_and_reach(spec, quat, q)
    x, y = terrain.spawn_xy
    ground = support_height(terrain, (x, y), reach)
    z = ground - lowest + DROP_HEIGHT
    return np.array([x, y, z]), quat, q, kind


def start_name(family: str, level: int, seed: int, episode: int, attempt: int = 0) -> str:
    """How an error names one start of a cell: ``flat level 1 seed 0 episode 2`` (``attempt 1``: a redraw)."""
    return f"{family} level {int(level)} seed {int(seed)} episode {int(episode)}" + (
        f" attempt {int(attempt)}" if attempt else "")


def draw_starts(spec: RobotSpec, terrain, family: str, level: int, seed: int, episodes,
                protocol_version: str = STARTS_KEY_VERSION, rule: str = PROTOCOL_VERSION) -> FallenStarts:
    """The starts of ``episodes`` (indices) in one (robot, terrain, level, seed) cell, with the joint-redraw rule
    of protocol ``rule`` (`joint_redraws`; a start whose draws all overlap under 1.4 raises a one-line
    `FrbenchError` naming it). An earlier ``protocol_version`` re-draws that version's first draws, e.g. to compare
    success rules on them."""
    episodes = list(episodes)
    redraws = joint_redraws(rule)
    rows = [draw_start(spec, terrain, episode_rng(spec.name, family, level, seed, e, protocol_version=protocol_version),
                       redraws, start_name(family, level, seed, e))
            for e in episodes]
    return FallenStarts(
        base_pos=np.array([r[0] for r in rows]),
        base_quat=np.array([r[1] for r in rows]),
        q=np.array([r[2] for r in rows]),
        kinds=[r[3] for r in rows],
        cell=(spec, terrain, family, int(level), int(seed), tuple(episodes)),
        attempts=np.zeros(len(episodes), dtype=int),
        redraws=redraws,
    )
