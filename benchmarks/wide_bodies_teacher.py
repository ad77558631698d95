"""How well the teacher, ``scripted``, gets the training population's bodies up: wide bodies against the paper's.

Draws ``--bodies`` robots of each body distribution (`frbench.training.bodies`: ``paper`` and ``wide``) as a
training run draws them (`population.TrainingRobots` with ``population_seed`` = ``--seed``: feasible, the CoM
shift baked in) and runs ``scripted`` on each as an evaluation cell runs it (`frbench.evaluation.runner.run_cell`:
the protocol's starts of flat ground, level 1, evaluation seed 0, ``--episodes`` episodes, MuJoCo, one
process), on the robot as training simulates it: its own file convention, torque limits and physics step
(0.005 s), at the middle of the training gains (Kp 65 N·m/rad, Kd 1.5 N·m·s/rad) times its size's factors
(`bodies.WideBodies.factors`). Prints one row per body (mass, size factor, knees, joint axes, zero pose, the
explicit PD's stiffest-mode numbers b = Kp dt²/I and a = Kd dt/I at those gains, successes) and each
distribution's total and its totals per mass bin, knee layout, joint axes and joint zero. With ``--twins`` each
wide body's paper-table draw (its size and file convention undone: Go2's convention at the paper's size and
gains) is scored on the same start draws, which separates what the wide generation does from what the draw is.

``frbench evaluate --robots PATH`` scores a robot file too, but derives its gains and physics step from the file
(stiffer than training's, `frbench.robots.gains`), so it does not simulate the bodies as training does.

Run: ``nice -n 10 python benchmarks/wide_bodies_teacher.py --bodies 12 --episodes 8`` (docs/training.md,
"Wider bodies").
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.policies.registry import load_policy
from frbench.robots.morphology import total_mass
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain
from frbench.training.bodies import body_distribution
from frbench.training.config import TRAINING_GAIN_RANGES, TrainEnvConfig
from frbench.training.population import TrainingRobots
from frbench.training.randomization import morphology_spec


def training_gains(scales, bodies) -> tuple[np.ndarray, np.ndarray]:
    """(Kp [N·m/rad], Kd [N·m·s/rad]) (K,) of bodies of size factors ``scales``: the middle of the training gain
    range, times their sizes' factors (``bodies`` None: the paper's, unscaled)."""
    kp, kd = (float(np.mean(TRAINING_GAIN_RANGES[k])) for k in ("kp", "kd"))
    scales = np.asarray(scales, dtype=float)
    if bodies is None:
        return np.full(len(scales), kp), np.full(len(scales), kd)
    factors = bodies.factors(scales)
    return kp * factors["kp"], kd * factors["kd"]


def draw(name: str, count: int, seed: int) -> TrainingRobots:
    """The ``count`` robots of body distribution ``name`` a run with ``population_seed`` ``seed`` trains on."""
    cfg = TrainEnvConfig(num_envs=count, num_morphologies=count, bodies=name, population_seed=seed)
    return TrainingRobots.drawn(cfg, np.random.default_rng(seed))


def stiffest_mode(spec, kp: float, kd: float) -> tuple[float, float]:
    """(b, a): the explicit PD's Kp dt²/I and Kd dt/I of ``spec``'s stiffest free-floating mode at its standing pose
    (`frbench.robots.gains`; stable while b + 2a < 4)."""
    import pinocchio

    from frbench.robots.gains import _mode_rate, static_model

    model, data, q, joints = static_model(spec)
    mass = pinocchio.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    dt = spec.physics_dt
    return (_mode_rate(mass, joints, np.full(spec.n_joints, kp)) * dt ** 2,
            _mode_rate(mass, joints, np.full(spec.n_joints, kd)) * dt)


def successes(spec, episodes: int) -> int:
    """``scripted``'s successes on ``spec`` in the cell (flat, level 1, seed 0, MuJoCo) of ``episodes`` episodes."""
    terrain = make_terrain("flat", 1, 0)
    starts = draw_starts(spec, terrain, "flat", 1, 0, range(episodes))
    task = run_episodes(spec, "mujoco", terrain, starts, load_policy("scripted"))
    diverged = task.metrics.diverged | task.settle_diverged
    return int((task.success.success & ~diverged).sum())


def twin(params, scale: float, bodies, name: str):
    """The paper-table draw a wide body was made from (``params`` scaled back by 1 / ``scale``, in Go2's
    convention), its spec named ``name`` (the body's: the same start draws), at the middle training gains."""
    paper = dataclasses.replace(bodies.scaled(params, 1.0 / scale), knees=("backward", "backward"),
                                joint_axes=(1.0, 1.0, 1.0), zero_pose=(0.0, 0.0))
    kp, kd = training_gains([1.0], None)
    spec = morphology_spec(paper, name)
    return spec.replace(kp=(float(kp[0]),) * spec.n_joints, kd=(float(kd[0]),) * spec.n_joints)


def score(name: str, count: int, seed: int, episodes: int, twins: bool) -> None:
    """Print the table of the module docstring for body distribution ``name``."""
    bodies = body_distribution(name)
    robots = draw(name, count, seed)
    kps, kds = training_gains(robots.scales, bodies)
    print(f"\n{name}: {len(robots.specs)} bodies ({robots.rejected} redrawn)")
    print("body  mass [kg]  size  knees (front, rear)  axes (hip, thigh, calf)  zero [rad]     Kp [N·m/rad]"
          "      b      a  success" + ("  twin" if twins else ""))
    rows = []
    for i, (spec, params, scale, kp, kd) in enumerate(zip(robots.specs, robots.morphologies, robots.scales, kps, kds)):
        spec = spec.replace(kp=(float(kp),) * spec.n_joints, kd=(float(kd),) * spec.n_joints)
        b, a = stiffest_mode(spec, kp, kd)
        ok = successes(spec, episodes)
        paired = successes(twin(params, scale, bodies, spec.name), episodes) if twins else 0
        print(f"{i:4d} {total_mass(params):9.2f} {scale:5.2f}  {params.knees[0]:8s} {params.knees[1]:8s}   "
              f"{str(tuple(int(x) for x in params.joint_axes)):23s}  "
              f"{str(tuple(round(z, 2) for z in params.zero_pose)):13s} {kp:12.2f} {b:6.2f} {a:6.2f}  "
              f"{ok}/{episodes}" + (f"    {paired}/{episodes}" if twins else ""))
        rows.append((total_mass(params), params.knees, params.joint_axes != (1.0, 1.0, 1.0), any(params.zero_pose),
                     ok, paired))
    total = len(rows) * episodes
    print(f"{name}: {sum(r[4] for r in rows)}/{total} = {sum(r[4] for r in rows) / total:.3f}"
          + (f"; twins {sum(r[5] for r in rows)}/{total}" if twins else ""))
    for label, group in classes(rows).items():
        print(f"  {label:28s} {sum(r[4] for r in group)}/{len(group) * episodes} ({len(group)} bodies)"
              + (f"; twins {sum(r[5] for r in group)}/{len(group) * episodes}" if twins else ""))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=12, help="robots per distribution")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per robot")
    parser.add_argument("--seed", type=int, default=0, help="the population seed")
    parser.add_argument("--twins", action="store_true",
                        help="also score each wide body's paper-table draw (its size and convention undone)")
    args = parser.parse_args(argv)
    for name in ("paper", "wide"):
        score(name, args.bodies, args.seed, args.episodes, args.twins and name == "wide")
    return 0


#: Mass bins [kg] of the summary.
MASS_BINS = (0.0, 5.0, 15.0, 35.0, float("inf"))


def classes(rows: list[tuple]) -> dict[str, list[tuple]]:
    """Rows (mass [kg], knees, flipped axes, folded zero, successes, twin's successes) grouped by mass bin, knee
    layout, flipped axes and folded zero (a row in one group of each)."""
    groups: dict[str, list[tuple]] = {}
    for row in rows:
        mass, knees, flipped, folded = row[:4]
        low = max(b for b in MASS_BINS if b <= mass)
        high = min(b for b in MASS_BINS if b > mass)
        for label in (f"mass {low:g}-{high:g} kg", f"knees {knees[0]}/{knees[1]}",
                      "axes flipped" if flipped else "axes Go2's", "zero folded" if folded else "zero straight"):
            groups.setdefault(label, []).append(row)
    return dict(sorted(groups.items()))


if __name__ == "__main__":
    raise SystemExit(main())
