"""Black-box search of the ``keyframe-humanoid`` parameters (CMA-ES, optional extra ``tune``).

Every generation runs ``popsize × len(starts)`` real recovery episodes side by
side in one batched simulator per backend (one candidate per simulation), through
the episode runner (`frbench.evaluation.episodes.run_episodes`: the drawn starts,
their settle, the success test; the per-step pelvis heights come back through its
``on_step`` callback), scores each candidate
by `episode_scores` averaged over its starts, and writes the best parameters
found so far to ``--out`` (JSON, the same format as the shipped
``keyframe_humanoid_params.json``) after every generation. ``--stage rise``
tunes only the ``CROUCH``/``RISE``/feedback parameters from recorded states
(``--states``: an ``.npz`` of `RobotState` fields and the controller's targets,
as `tools/keyframe_states.py` writes them; ``BACKEND:FILE`` runs them in
that simulator, and several ``--states`` score the mean over simulators;
``--deadline`` bounds when the robot must be up). ``--stage prone`` tunes only the
way from the belly into the crouch (`PRONE_PARAMETERS`) on whole episodes from
prone starts (``--prone-seeds``), ``--stage roll`` only the roll (``--roll-seeds``),
``--stage supine`` only the sit-up from the back and its own rise (`SUPINE_PARAMETERS`, from
the supine starts of ``--supine-seeds``); ``--extra``/``--only`` tune named parameters
besides/instead of the stage's own; ``--backends mujoco,pybullet`` runs those stages in both
simulators and scores the mean. The last runs behind the shipped parameters are in the
parameter file (``search``, ``situp_search``); the rise stage's:

    .venv/bin/python -m tools.keyframe_search --stage rise \
        --states mujoco:mj24.npz --states pybullet:pb24.npz --steps 150 --deadline 48 \
        --init riseE.json --popsize 10 --sigma 0.35 --max-minutes 25 --seed 36 \
        --out keyframe_humanoid_params.json
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from frbench.policies.keyframe_humanoid import (
    INITIAL,
    PARAMETER_NAMES,
    SCALE,
    KeyframeHumanoidPolicy,
    decode,
)
from tools.keyframe_states import STATE_FIELDS, parse_seeds
from frbench.evaluation.episodes import run_episodes
from frbench.tasks.initial_states import FALL_KINDS, FallenStarts, RecordedStarts, draw_starts
from frbench.backends import make_backend
from frbench.tasks.recovery import EPISODE_STEPS

#: The key frames were searched on protocol 1.0's starts; the seeds in keyframe_humanoid_params.json name those.
SEARCH_STARTS_PROTOCOL = "1.0"


def parse_starts(text: str) -> list[tuple[int, int]]:
    """``"seed:episode,seed:episode"`` → [(seed, episode), …] of g1/flat/level-1 starts."""
    return [tuple(int(v) for v in item.split(":")) for item in text.split(",") if item]


#: Projected gravity z below this counts as upright for the score.
UPRIGHT_GZ = -0.5
#: Control steps the pelvis must then stay up until the episode ends (0.5 s) for an up to count.
MIN_UP_STEPS = 25
#: Pelvis heights above this [m] mean the robot jumped (flight): penalised by `JUMP_PENALTY` per metre.
JUMP_HEIGHT = 0.85
JUMP_PENALTY = 60.0


def episode_scores(heights: np.ndarray, gravity_z: np.ndarray, success: np.ndarray, up: float, floor: float,
                   deadline: int | None = None, late: int = 0) -> np.ndarray:
    """Shaped score per episode (higher is better) from pelvis heights (T, N) above the ground and the projected
    gravity z (T, N) (−1 upright; the pelvis counts as upright below `UPRIGHT_GZ`).

    The task's humanoid test reads the pelvis height only, which a head or hand stand (pelvis upside down,
    0.53-0.8 m) also passes; the score counts a step as up only with the pelvis upright. Up: the first step the
    pelvis is upright above ``up``, at least `MIN_UP_STEPS` before the end (so that a tumble that happens to be
    upright in the last steps does not count) and, with a ``deadline`` [control steps], before it. 100 if the task's ``success`` holds and the pelvis stays upright above
    ``floor`` from up to the end; + 20 once up plus 30 × the fraction of the remaining episode it then stayed
    upright above ``floor``; + 10 × the highest height × max(−g_z, 0) / ``up`` (capped at 1); + 5 × the fraction of
    steps upright above ``floor``; − `JUMP_PENALTY` × the max height above `JUMP_HEIGHT` (a get-up by jumping
    and landing is fragile). ``late`` [control steps]: an up in the ``late`` steps after the deadline (and still
    `MIN_UP_STEPS` before the end) earns the 20 + 30 part scaled down linearly with its lateness (no 100): a
    search then sees which candidates get up earlier before any meets the deadline.
    """
    steps, n = heights.shape
    upright = gravity_z < UPRIGHT_GZ
    good = (heights > floor) & upright
    top_upright = (heights * np.clip(-gravity_z, 0.0, 1.0)).max(axis=0)
    score = 10.0 * np.minimum(top_upright / up, 1.0) + 5.0 * good.mean(axis=0)
    score -= JUMP_PENALTY * np.maximum(heights.max(axis=0) - JUMP_HEIGHT, 0.0)
    last = steps - MIN_UP_STEPS if deadline is None else min(steps - MIN_UP_STEPS, deadline)
    late_last = last if deadline is None else min(steps - MIN_UP_STEPS, last + late)
    for i in range(n):
        ups = np.flatnonzero((heights[:late_last, i] > up) & upright[:late_last, i])
        if not ups.size:
            continue
        in_time = ups[0] < last
        weight = 1.0 if in_time else 1.0 - (ups[0] - last + 1) / (late + 1)
        after = good[ups[0]:, i]
        stayed = np.argmin(after) if not after.all() else len(after)
        score[i] += weight * (20.0 + 30.0 * stayed / len(after))
        score[i] += 100.0 if in_time and success[i] and after.all() else 0.0
    return score


def upright_success(heights: np.ndarray, gravity_z: np.ndarray, success: np.ndarray, up: float, floor: float,
                    deadline: int | None = None):
    """(N,) the task's success with the pelvis upright from the first upright step above ``up`` (at least
    `MIN_UP_STEPS` before the end and before ``deadline`` if given) to the end."""
    upright = gravity_z < UPRIGHT_GZ
    out = np.zeros(heights.shape[1], dtype=bool)
    last = heights.shape[0] - MIN_UP_STEPS if deadline is None else min(heights.shape[0] - MIN_UP_STEPS, deadline)
    for i in np.flatnonzero(success):
        ups = np.flatnonzero((heights[:last, i] > up) & upright[:last, i])
        out[i] = bool(ups.size) and bool(((heights[ups[0]:, i] > floor) & upright[ups[0]:, i]).all())
    return out


#: Control steps of a ``--stage roll`` episode (2.4 s): a roll that takes longer leaves no time to get up.
ROLL_EPISODE_STEPS = 120


def roll_scores(phases: np.ndarray, gravity_x: np.ndarray) -> np.ndarray:
    """Score per episode of the roll onto the belly from the controller's phases (T, N) and the projected
    gravity x (T, N) (+1 face down): 2 once the controller leaves ``LIE``/``ROLL`` face down (it then pushes
    up), + 1 − (that step / T) for getting there early, + 0.5 × the largest and + 0.5 × the final face-down
    g_x (clipped to [0, 1]; the second penalises tipping back while pushing up)."""
    from frbench.policies.scripted_humanoid import LIE, ROLL

    steps = phases.shape[0]
    rolled = (phases != LIE) & (phases != ROLL)
    reached = rolled.any(axis=0)
    first = np.where(reached, np.argmax(rolled, axis=0), steps)
    down = np.clip(gravity_x, 0.0, 1.0)
    return 2.0 * reached + reached * (1.0 - first / steps) + 0.5 * down.max(axis=0) + 0.5 * down[-1]


def starts_of_kind(seeds, kinds: tuple[str, ...], episodes: int = 8) -> list[tuple[int, int]]:
    """(seed, episode) of every g1/flat/level-1 start in ``seeds`` whose drawn kind is in ``kinds`` (names of
    `frbench.tasks.initial_states.FALL_KINDS`)."""
    from frbench.robots import get_robot
    from frbench.terrains import make_terrain

    spec, out = get_robot("g1"), []
    for seed in seeds:
        drawn = draw_starts(spec, make_terrain("flat", 1, seed), "flat", 1, seed, range(episodes), SEARCH_STARTS_PROTOCOL).kinds
        out += [(seed, e) for e, kind in enumerate(drawn) if kind in kinds]
    return out


def non_prone_starts(seeds, episodes: int = 8) -> list[tuple[int, int]]:
    """(seed, episode) of every g1/flat/level-1 start in ``seeds`` that is not prone (the ones that roll)."""
    return starts_of_kind(seeds, tuple(k for k in FALL_KINDS if k != "prone"), episodes=episodes)


class Evaluator:
    """Runs candidates from fixed g1/flat/level-1 starts in one batched simulator of ``backend``, built once and
    reused by every generation, through `run_episodes` (episodes of ``steps`` control steps, default a whole
    episode, scored by `episode_scores` with ``deadline``; ``roll=True``: `ROLL_EPISODE_STEPS` scored by
    `roll_scores`)."""

    def __init__(self, starts: list[tuple[int, int]], popsize: int, backend: str = "mujoco", roll: bool = False,
                 steps: int = EPISODE_STEPS, deadline: int | None = None, late: int = 0):
        from frbench.robots import get_robot
        from frbench.terrains import make_terrain

        self.spec = get_robot("g1")
        self.popsize, self.n_starts = popsize, len(starts)
        drawn = [draw_starts(self.spec, make_terrain("flat", 1, s), "flat", 1, s, [e], SEARCH_STARTS_PROTOCOL) for s, e in starts]
        self.kinds = [d.kinds[0] for d in drawn]
        # environment j = candidate (j // n_starts), start (j % n_starts)
        self.starts = FallenStarts(
            base_pos=np.tile(np.concatenate([d.base_pos for d in drawn]), (popsize, 1)),
            base_quat=np.tile(np.concatenate([d.base_quat for d in drawn]), (popsize, 1)),
            q=np.tile(np.concatenate([d.q for d in drawn]), (popsize, 1)),
            kinds=self.kinds * popsize,
        )
        self.terrain, n = make_terrain("flat", 1, starts[0][0]), popsize * len(starts)
        self.backend = make_backend(backend, self.spec, n, terrain=self.terrain)
        self.roll, self.steps, self.deadline, self.late = roll, steps, deadline, late

    def run(self, parameters: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(scores (popsize,), successes (popsize, n_starts), max heights (popsize, n_starts)) of candidate
        parameter rows (popsize, D)."""
        rows = np.repeat(np.asarray(parameters, dtype=float), self.n_starts, axis=0)
        policy = KeyframeHumanoidPolicy(rows)
        steps = ROLL_EPISODE_STEPS if self.roll else self.steps
        trace = StepTrace(steps, len(rows), policy if self.roll else None)
        task = run_episodes(self.spec, self.backend, self.terrain, self.starts, policy, steps=steps, on_step=trace,
                            check=False)
        shape = (self.popsize, self.n_starts)
        if self.roll:
            return _roll_result(trace, shape)
        return _scored_result(task, trace, shape, self.deadline, self.late)

    def close(self) -> None:
        self.backend.close()


class StepTrace:
    """Per-step records of N episodes over ``steps`` control steps, as an ``on_step(task, targets)`` callback of
    `run_episodes`: the pelvis height above the ground ``heights`` (T, N) [m] and the projected gravity z
    ``gravity_z`` (T, N), both as the success test read them; with a ``policy`` also its ``phases`` (T, N) and
    the projected gravity x ``gravity_x`` (T, N) (the roll stage).
    """

    def __init__(self, steps: int, n: int, policy=None):
        self.heights, self.gravity_z = np.empty((steps, n)), np.zeros((steps, n))
        self.policy = policy
        if policy is not None:
            self.phases, self.gravity_x = np.empty((steps, n), dtype=int), np.empty((steps, n))
        self.t = 0

    def __call__(self, task, targets=None) -> None:
        t, signals = self.t, task.signals
        self.heights[t], self.gravity_z[t] = signals.height, signals.gravity_z
        if self.policy is not None:
            self.phases[t], self.gravity_x[t] = self.policy.phase, task.gravity[:, 0]
        self.t += 1


def _scored_result(task, trace: StepTrace, shape: tuple[int, int], deadline: int | None = None, late: int = 0):
    """(mean score per candidate (popsize,), upright successes and max pelvis heights [m], both ``shape`` =
    (popsize, n_starts)) of the episodes ``trace`` recorded and ``task``'s success test; ``deadline``, ``late``:
    see `episode_scores`."""
    heights, tracker = trace.heights, task.success
    args = (heights, trace.gravity_z, tracker.success, tracker.up_height, tracker.floor_height)
    scores, good = episode_scores(*args, deadline=deadline, late=late), upright_success(*args, deadline=deadline)
    return scores.reshape(shape).mean(axis=1), good.reshape(shape), heights.max(axis=0).reshape(shape)


def _roll_result(trace: StepTrace, shape: tuple[int, int]):
    """Like `_scored_result`, scored by `roll_scores`; the "successes" are the episodes that reached the
    push-up face down and were still face down (g_x > 0.5) at the end."""
    from frbench.policies.scripted_humanoid import LIE, ROLL

    phases, gravity_x = trace.phases, trace.gravity_x
    scores = roll_scores(phases, gravity_x)
    good = ((phases != LIE) & (phases != ROLL)).any(axis=0) & (gravity_x[-1] > 0.5)
    return scores.reshape(shape).mean(axis=1), good.reshape(shape), trace.heights.max(axis=0).reshape(shape)


#: Parameters tuned by ``--stage roll`` (the others stay at ``--init``). Not ``ramp.lie``: it also sets how prone
#: starts, which the roll stage does not run, settle before the push-up (a search that could shorten it to 3
#: steps did, and prone starts then failed more often).
ROLL_PARAMETERS = tuple(n for n in PARAMETER_NAMES if n.startswith(("roll", "ramp.roll")))
#: Parameters tuned by ``--stage prone`` (the way from the belly into the crouch: key poses and ramps of
#: ``PUSH_B`` … ``CROUCH``; the roll, the rise and the feedback stay at ``--init``).
PRONE_PARAMETERS = tuple(n for n in PARAMETER_NAMES if n.startswith(("push_b.", "lift.", "pike.", "squat.", "crouch."))
                         or n in ("ramp.push_b", "ramp.lift", "ramp.pike", "ramp.squat", "ramp.crouch"))
#: Parameters tuned by ``--stage supine`` (the sit-up from the back: key poses and ramps of ``TUCK``, ``PROP``,
#: ``ROCK`` and the sit-up path's own crouch, rise and feedback, ``sit_*``; the search makes one sit-up attempt,
#: ``situp.tries`` = 1, whatever ``--init`` has).
SUPINE_PARAMETERS = tuple(n for n in PARAMETER_NAMES if n.startswith(("tuck.", "prop.", "rock.", "sit_", "ramp.sit_"))
                          or n in ("ramp.tuck", "ramp.prop", "ramp.rock"))
#: Parameters no stage tunes (counts, not magnitudes).
FIXED_PARAMETERS = ("situp.tries",)
#: Parameters tuned by ``--stage rise`` (the others stay at ``--init``).
RISE_PARAMETERS = tuple(n for n in PARAMETER_NAMES
                        if n.startswith(("crouch.", "stand.", "fb.")) or n in ("ramp.crouch", "ramp.rise"))


class RiseEvaluator:
    """Runs candidates from recorded mid-recovery states (a ``.npz`` of `RobotState` fields, e.g. folded on
    hands and feet at the end of ``SQUAT``) with the controller entering ``CROUCH``: the rise alone, at full
    gains and without the settle, for ``steps`` control steps, with the task's success test; ``deadline``
    [control steps]: an up after it does not count (`episode_scores`).

    Its episodes go through `run_episodes` from `RecordedStarts` (`RecoveryTask.begin`: the recorded states
    themselves, velocities included, no settle, nominal physics, the previous action = the placed angles) in one
    batched simulator of ``backend``, built once and reused by every generation; the controller enters the
    crouch in ``on_reset`` and a `StepTrace` records the steps."""

    def __init__(self, states_file: str, popsize: int, steps: int = 150, backend: str = "mujoco",
                 deadline: int | None = None):
        from frbench.backends.base import RobotState
        from frbench.robots import get_robot
        from frbench.terrains import make_terrain

        self.spec = get_robot("g1")
        data = np.load(states_file)
        self.popsize, self.n_starts, self.steps, self.deadline = popsize, len(data["q"]), steps, deadline
        n = popsize * self.n_starts
        self.starts = RecordedStarts(RobotState(**{k: np.tile(data[k], (popsize, 1)) for k in STATE_FIELDS}))
        #: The controller's targets when the state was recorded (J,) per state, if the file has them (else the
        #: measured angles): the crouch then ramps from where the recorded run's targets were.
        self.targets = np.tile(data["targets"], (popsize, 1)) if "targets" in data else self.starts.state.q
        self.terrain = make_terrain("flat", 1, 0)
        self.backend = make_backend(backend, self.spec, n, terrain=self.terrain)
        self.kinds = ["recorded"] * self.n_starts

    def run(self, parameters: np.ndarray):
        """(scores (popsize,), successes (popsize, n_starts), max heights (popsize, n_starts)) of candidate
        parameter rows (popsize, D)."""
        n = self.popsize * self.n_starts
        policy = KeyframeHumanoidPolicy(np.repeat(np.asarray(parameters, dtype=float), self.n_starts, axis=0))
        trace = StepTrace(self.steps, n)
        task = run_episodes(self.spec, self.backend, self.terrain, self.starts, policy, steps=self.steps,
                            on_reset=lambda task: policy.enter_gate(np.arange(n), self.targets, task.state.q),
                            on_step=trace, check=False)
        return _scored_result(task, trace, (self.popsize, self.n_starts), self.deadline)

    def close(self) -> None:
        self.backend.close()


class PooledEvaluator:
    """Several evaluators (e.g. `RiseEvaluator` in MuJoCo and in PyBullet) as one: a candidate's score is the mean
    of its scores in each, its successes and heights are theirs side by side."""

    def __init__(self, evaluators: list):
        self.evaluators = evaluators
        self.kinds = [kind for e in evaluators for kind in e.kinds]

    def run(self, parameters: np.ndarray):
        results = [e.run(parameters) for e in self.evaluators]
        return (np.mean([r[0] for r in results], axis=0), np.concatenate([r[1] for r in results], axis=1),
                np.concatenate([r[2] for r in results], axis=1))

    def close(self) -> None:
        for e in self.evaluators:
            e.close()


def pooled(evaluators: list):
    """One evaluator alone, several as a `PooledEvaluator`."""
    return evaluators[0] if len(evaluators) == 1 else PooledEvaluator(evaluators)


def rise_evaluator(states: list[str], popsize: int, steps: int, deadline: int | None):
    """The rise stage's evaluator for ``--states`` values ``FILE`` (MuJoCo) or ``BACKEND:FILE``, pooled if several."""
    evaluators = []
    for item in states:
        backend, _, path = item.rpartition(":") if item.startswith(("mujoco:", "pybullet:")) else ("", "", item)
        evaluators.append(RiseEvaluator(path, popsize, steps, backend=backend or "mujoco", deadline=deadline))
    return pooled(evaluators)


def extra_parameters(text: str, already: tuple[str, ...], flag: str = "--extra") -> tuple[str, ...]:
    """Parameter names selected by ``--extra`` or ``--only`` (``flag``; comma-separated names, or prefixes ending
    in '.') not in ``already``; an item that selects none is an error naming the flag and the item."""
    out = []
    for item in filter(None, (t.strip() for t in text.split(","))):
        hits = [n for n in PARAMETER_NAMES if (n.startswith(item) if item.endswith(".") else n == item)]
        if not hits or set(hits) & set(FIXED_PARAMETERS):
            raise SystemExit(f"{flag}: {item!r} names no tunable parameter (names: keyframe_humanoid.PARAMETERS)")
        out += [n for n in hits if n not in already and n not in out]
    return tuple(out)


def save(path: Path, parameters: np.ndarray, info: dict) -> None:
    """Write parameters (D,) by name plus ``info`` to ``path`` as JSON (atomically)."""
    from frbench.io import atomic_write_text

    data = {**info, "parameters": {n: round(float(v), 6) for n, v in zip(PARAMETER_NAMES, parameters)}}
    atomic_write_text(path, json.dumps(data, indent=1) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", default="0:4,1:16,2:8,3:3", help="seed:episode of g1/flat/level-1 starts")
    parser.add_argument("--popsize", type=int, default=12)
    parser.add_argument("--generations", type=int, default=150)
    parser.add_argument("--sigma", type=float, default=0.5, help="initial step size in normalised coordinates")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--init", default=None, help="start from the parameters of this JSON file")
    parser.add_argument("--out", required=True)
    parser.add_argument("--max-minutes", type=float, default=60.0)
    parser.add_argument("--stage", choices=("full", "prone", "rise", "roll", "supine"), default="full",
                        help="full: whole episodes from --starts; prone: the same, tuning only the way from the belly "
                             "into the crouch (PRONE_PARAMETERS); supine: the same, tuning only the sit-up from the "
                             "back (SUPINE_PARAMETERS); rise: only the rise from --states; roll: the roll "
                             "onto the belly (2.4 s) from --starts")
    parser.add_argument("--roll-seeds", default=None,
                        help="instead of --starts, every non-prone start of these seeds (e.g. 4-9)")
    parser.add_argument("--prone-seeds", default=None,
                        help="instead of --starts, every prone start of these seeds (e.g. 4-15)")
    parser.add_argument("--extra", default="",
                        help="comma-separated parameter names, or prefixes ending in '.', tuned besides the stage's own "
                             "(e.g. stand.,ramp.rise)")
    parser.add_argument("--only", default="",
                        help="like --extra, but tune only these parameters instead of the stage's own")
    parser.add_argument("--supine-seeds", default=None,
                        help="instead of --starts, every supine start of these seeds (e.g. 4-15)")
    parser.add_argument("--backends", default="mujoco",
                        help="full, prone, supine and roll stages: comma-separated simulators; the score is the mean over them")
    parser.add_argument("--states", action="append", default=None,
                        help="rise stage: .npz of recorded states (`keyframe_states`), as FILE (MuJoCo) or "
                             "BACKEND:FILE; repeat to score the mean over several backends")
    parser.add_argument("--steps", type=int, default=None,
                        help="control steps per episode (rise stage: default 150; full and prone: a whole episode)")
    parser.add_argument("--deadline", type=int, default=None,
                        help="an up after this many control steps does not count (rise stage: the crouch starts "
                             "about 58 steps before a 5 s episode ends; full and prone: leaves time for a roll)")
    parser.add_argument("--late", type=int, default=0,
                        help="full and prone stages: ups up to this many steps after --deadline earn part of the "
                             "up credit, less the later they are (a gradient towards earlier ups)")
    args = parser.parse_args(argv)
    import cma

    command = "python -m tools.keyframe_search " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    out = Path(args.out)
    starts = parse_starts(args.starts)
    if args.roll_seeds:
        starts = non_prone_starts(parse_seeds(args.roll_seeds))
    if args.prone_seeds:
        starts = starts_of_kind(parse_seeds(args.prone_seeds), ("prone",))
    if args.supine_seeds:
        starts = starts_of_kind(parse_seeds(args.supine_seeds), ("supine",))
    backends = args.backends.split(",")
    base = INITIAL.copy()
    if args.init:
        from frbench.policies.keyframe_humanoid import load_parameters

        base = load_parameters(args.init)
    if args.stage == "supine":
        base[PARAMETER_NAMES.index("situp.tries")] = max(1, base[PARAMETER_NAMES.index("situp.tries")])
    tuned = np.arange(len(INITIAL))
    if args.stage == "rise":
        tuned = np.array([PARAMETER_NAMES.index(n) for n in RISE_PARAMETERS])
        if not args.states:
            parser.error("--stage rise needs --states")
        if args.extra or args.only:
            parser.error("--extra and --only apply to the full, prone, roll and supine stages, not to rise")
        evaluator = rise_evaluator(args.states, args.popsize, args.steps or 150, args.deadline)
    else:
        subset = {"roll": ROLL_PARAMETERS, "prone": PRONE_PARAMETERS, "supine": SUPINE_PARAMETERS}.get(
            args.stage, tuple(n for n in PARAMETER_NAMES if n not in FIXED_PARAMETERS))
        if args.only:
            subset = extra_parameters(args.only, (), "--only")
        tuned = np.array([PARAMETER_NAMES.index(n) for n in subset + extra_parameters(args.extra, subset)])
        evaluator = pooled([Evaluator(starts, args.popsize, backend, roll=args.stage == "roll",
                                      steps=args.steps or EPISODE_STEPS, deadline=args.deadline, late=args.late)
                            for backend in backends])
    x0 = ((base - INITIAL) / SCALE)[tuned]

    def full(xs: np.ndarray) -> np.ndarray:
        out = np.tile((base - INITIAL) / SCALE, (len(xs), 1))
        out[:, tuned] = xs
        return decode(out)

    print("starts", starts, evaluator.kinds, flush=True)
    es = cma.CMAEvolutionStrategy(x0, args.sigma, {"popsize": args.popsize, "seed": args.seed, "verbose": -9})
    best = (-np.inf, None, None)
    began = time.time()
    try:
        for generation in range(args.generations):
            xs = es.ask()
            params = full(np.array(xs))
            scores, successes, heights = evaluator.run(params)
            es.tell(xs, (-scores).tolist())
            k = int(np.argmax(scores))
            if scores[k] > best[0]:
                best = (float(scores[k]), params[k], {"successes": successes[k].tolist(),
                                                      "max_heights": np.round(heights[k], 3).tolist()})
                save(out, best[1], {"command": command, "score": best[0], "generation": generation,
                                    "starts": [list(s) for s in starts], **best[2]})
            print(f"gen {generation:3d} {time.time() - began:6.0f}s best {scores[k]:7.2f} mean {scores.mean():7.2f} "
                  f"succ {int(successes.sum()):2d} hmax {heights.max():.3f} | overall {best[0]:.2f} {best[2]}",
                  flush=True)
            if (time.time() - began) / 60 > args.max_minutes:
                break
    finally:
        evaluator.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
