"""Learning-curve benchmark: does a training recipe learn in every seed, and how soon?

Trains one recipe (``--preset`` plus ``--set FIELD=VALUE`` fields, ``--method``) with several seeds to a fixed
env-step budget, each seed in its own run folder ``OUT/seed<S>`` (``frbench train``: resumable, so a killed
benchmark continues where its checkpoints stopped when started again with the same arguments), then prints each
seed's *training* success at fixed step marks: flat ground and all terrains, read from the run's learning curve
(``progress.json``: the rate over the episodes that ended in the logging window, actions sampled with the
policy's exploration noise, starts of every kind the recipe draws; the first logged point at or after each mark).

The recipes' defaults: randomised morphologies of the paper's table on every terrain family, 256 envs, the
curriculum from level 1: the runs of the shipped FR-Net. The target of the FR-Net recipe work is
``>= 0.6`` flat training success at 3 M env steps in each of 3 seeds.

Run (three seeds side by side; ``--jobs 1`` trains them one after another)::

    python benchmarks/learning_curve.py --preset symmetry --out runs/lc-symmetry --seeds 0,1,2 --steps 3.07e6
    python benchmarks/learning_curve.py --out runs/lc-symmetry --report     # the table of existing runs only

``--stage AT:ARGS`` makes the recipe a schedule: each seed trains to AT env steps, resumes once with the
``frbench train`` arguments ARGS (a new reward or morphology stage, recorded in the run's config.json), and
trains on to ``--steps``. The calmed ``symmetry-assist`` campaign (the shipped FR-Net's motion-penalty and
action-smoothing stage with the old entropy coefficient, docs/training.md, "Past 3 M env steps")::

    python benchmarks/learning_curve.py --out runs/lc-symmetry-assist --seeds 1,2 --steps 10e6 \
        --stage "7.5e6:--motion-penalties 0.3 --reward-weight action_smoothing=-0.2 --entropy-coef 0.005"

Prints one row per seed and mark, then per mark the mean and the minimum over the seeds, then
``reached target: K/N seeds`` (flat success >= ``--target`` at the last mark).

The logged rate mixes in the exploration noise and holds about 30 flat episodes per logged row.
``--deterministic R`` also runs each seed's final policy with its mean action in its own training env for R
rounds (`frbench.analysis.training_env.training_env_success`, the env seeded with the run's seed: its robots,
R x 256 episodes) and prints the same flat / all success, its mean and minimum and the seeds at the target::

    python benchmarks/learning_curve.py --out runs/lc-symmetry --report --deterministic 2

Training success is measured on the training env's sampled morphologies and gains, not on the benchmark's
robots. ``--evaluate E`` also scores each seed's final policy with ``frbench evaluate`` on Go2, flat level 1,
evaluation seeds 0-3 × E episodes per simulator (protocol 1.1; the results beside the run,
``OUT/seed<S>/eval-go2-flat.json``) and prints the successes per simulator::

    python benchmarks/learning_curve.py --out runs/lc-symmetry --report --evaluate 8

``--evaluate-marks E`` scores, the same way, the policy snapshot (``snapshots/``, one per million env steps)
nearest each of ``--marks``: how the carry-over to Go2 grows with training
(``OUT/seed<S>/eval-go2-flat-<env steps>.json``, reused on a second report)::

    python benchmarks/learning_curve.py --out runs/lc-symmetry-assist --report --marks 3e6,6e6,9e6 --evaluate-marks 8

``--evaluate-robots go2,go1,aliengo`` scores other benchmark robots the same way, each on flat level 1
(``eval-<robot>-flat[-<env steps>].json``): a recipe can hold Go2 and lose the others (docs/training.md,
"`symmetry-assist-steady` to 15 M env steps")::

    python benchmarks/learning_curve.py --out runs/lc-symmetry-assist-steady --report --marks 6e6,15e6 \
        --evaluate-marks 8 --evaluate-robots go2,go1

``--subset-every STEPS`` makes each seed's curve a standard-grid estimate: the seed trains in chunks of STEPS env
steps (``frbench train --resume --steps``), and after each chunk its policy plays the fixed subset
``standard-seed0`` of the protocol's standard grid (`SUBSET`: every standard cell of evaluation seed 0, the five
quadrupeds x both simulators x seven families x levels 1, 5, 10 x 3 episodes: 210 cells, 630 episodes, a
quarter of the grid; ``OUT/seed<S>/subset-<env steps>.json``, kept). The report prints per seed and checkpoint
the subset's success rate, its 95 % Wilson interval and the imitation weight of the training rows there (a
kickstarting run's ``loss_imitation_weight``), the policy ``scripted`` on the same subset
(``OUT/subset-scripted.json``), and the stop rule (above ``--stop-at`` at half the budget).
The ``kickstart-scripted`` recipe (docs/training.md, "Learning from scripted")::

    nice -n 10 python benchmarks/learning_curve.py --preset kickstart-scripted --out runs/kickstart --seeds 0 \
        --steps 24e6 --subset-every 2e6 --jobs 1
    python benchmarks/learning_curve.py --out runs/kickstart --seeds 0 --steps 24e6 --subset-every 2e6 --report

``--unseen-subset`` (with ``--subset-every``) also scores the policy snapshot at each subset checkpoint on
``unseen-seed0`` (`unseen_subset`: the unseen grid's quadruped cells of evaluation seed 0 in both simulators, 432
episodes; ``OUT/seed<S>/unseen-<env steps>.json``, kept) and ``scripted`` on the same cells: the unseen-grid
curve, which the issue's second target (unseen >= 50 %) is read from.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

MARKS = (0.5e6, 1.0e6, 1.5e6, 2.0e6, 2.5e6, 3.0e6)
#: ``standard-seed0``: the standard grid's cells of evaluation seed 0 (``frbench evaluate`` arguments).
SUBSET_NAME = "standard-seed0"
SUBSET = {"robots": "go2,go1,aliengo,spot_like,lite3_like", "backends": "mujoco,pybullet",
          "terrains": "flat,rough,slopes,stairs,stones,gaps,beams", "levels": "1,5,10", "seeds": "0", "episodes": "3"}
#: ``unseen-seed0``: the unseen grid's quadruped cells of evaluation seed 0 (`unseen_subset`).
UNSEEN_SUBSET_NAME = "unseen-seed0"
#: The evaluation seeds of the Go2 flat scores (``frbench evaluate --seeds``).
EVALUATION_SEEDS = (0, 1, 2, 3)


def trained_steps(folder: Path) -> int:
    """The env steps of a run's last checkpoint (0 for none)."""
    path = folder / "progress.json"
    progress = json.loads(path.read_text()) if path.is_file() else []
    return progress[-1]["env_steps"] if progress else 0


def stage_recorded(folder: Path, stage_args: list[str]) -> bool:
    """Whether the run's config records a stage started with ``stage_args`` (`frbench train --resume`)."""
    config = json.loads((folder / "config.json").read_text())
    return any(shlex.join(stage_args) in stage.get("command", "") for stage in config.get("stages", []))


def next_train_command(args, seed: int, folder: Path) -> list[str] | None:
    """The next ``frbench train`` command of one seed (None: it is done): a new run, or the run's resumption
    when its folder exists. With ``--stage AT:ARGS`` the run first trains to AT env steps, then resumes once
    with ARGS (a new stage, recorded in its config.json), then trains on to the budget."""
    frbench = [sys.executable, "-m", "frbench"]
    stage_at, stage_args = args.stage if args.stage else (None, [])
    staged = bool(stage_args) and (folder / "config.json").is_file() and stage_recorded(folder, stage_args)
    budget = stage_at if stage_args and not staged else args.steps
    steps = trained_steps(folder)
    if getattr(args, "subset_every", 0):  # train to the next checkpoint of the subset's curve
        budget = min(budget, (steps // args.subset_every + 1) * args.subset_every)
    if not (folder / "config.json").is_file():
        fields = [x for item in args.fields for x in ("--set", item)]
        return [*frbench, "train", "--method", args.method, "--preset", args.preset, "--envs", str(args.envs),
                "--steps", str(budget), "--set", f"seed={seed}", *fields, "--out", str(folder)]
    if stage_args and not staged and steps >= stage_at:  # the stage's first leg ends at the next subset checkpoint
        target = args.steps
        if getattr(args, "subset_every", 0):
            target = min(args.steps, (steps // args.subset_every + 1) * args.subset_every)
        return [*frbench, "train", "--resume", str(folder), "--steps", str(target), *stage_args]
    if steps < budget:
        return [*frbench, "train", "--resume", str(folder), "--steps", str(budget)]
    return None


def train_seed(args, seed: int) -> None:
    """Run one seed's ``frbench train`` commands one after another, logging beside its run (``OUT/seed<S>.log``)."""
    folder = args.out / f"seed{seed}"
    with open(args.out / f"seed{seed}.log", "a") as log:
        while True:
            if getattr(args, "subset_every", 0):
                evaluate_subset_checkpoint(folder, args.subset_every, log)
            command = next_train_command(args, seed, folder)
            if command is None:
                break
            log.write("$ " + shlex.join(command) + "\n")
            log.flush()
            finished = subprocess.run(command, stdout=log, stderr=subprocess.STDOUT)
            if finished.returncode != 0:
                print(f"seed {seed}: frbench train exited {finished.returncode} (log: {log.name})", file=sys.stderr)
                return


def unseen_subset() -> dict[str, str]:
    """``unseen-seed0`` as ``frbench evaluate`` arguments: the nine unseen quadrupeds x both simulators x the unseen
    grid's families and levels x evaluation seed 0 x 3 episodes (144 cells, 432 episodes, a quarter of the unseen
    grid's two-simulator part)."""
    from frbench.tasks import protocol

    return {"robots": ",".join(protocol.unseen_quadrupeds()), "backends": "mujoco,pybullet",
            "terrains": ",".join(protocol.UNSEEN_TERRAINS), "levels": ",".join(map(str, protocol.UNSEEN_LEVELS)),
            "seeds": "0", "episodes": str(protocol.UNSEEN_EPISODES)}


def evaluate_subset(policy: str, result: Path, log=None, subset: dict | None = None) -> dict:
    """``frbench evaluate`` of ``policy`` on ``subset`` (default `SUBSET`), written to ``result`` (kept when it
    exists); its results."""
    if not result.is_file():
        cells = SUBSET if subset is None else subset
        command = [sys.executable, "-m", "frbench", "evaluate", "--policy", str(policy), "--jobs", "1",
                   "--out", str(result), *[x for k, v in cells.items() for x in (f"--{k}", v)]]
        if log is not None:
            log.write("$ " + shlex.join(command) + "\n")
            log.flush()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=log or subprocess.DEVNULL)
    return json.loads(result.read_text())


def subset_results(folder: Path) -> dict[int, Path]:
    """The run's subset results by env steps (``subset-<env steps>.json``)."""
    return {int(p.stem.split("-")[1]): p for p in folder.glob("subset-*.json")}


def evaluate_subset_checkpoint(folder: Path, every: float, log) -> None:
    """Score the run's current policy on `SUBSET` when it is the first checkpoint at or past a multiple of
    ``every`` env steps that has no subset result yet; a run kept without its policy (tools/keep_run.py) is
    skipped, its checkpoint having been scored before it was kept."""
    steps = trained_steps(folder)
    mark = int(steps // every)
    if mark < 1 or any(int(s // every) == mark for s in subset_results(folder)):
        return
    if not (folder / "policy.pt").is_file():  # a run kept by tools/keep_run.py: scored before it was kept
        log.write(f"no policy.pt at {steps} env steps (a kept run): its subset score is in the kept run's README\n")
        return
    evaluate_subset(str(folder / "policy.pt"), folder / f"subset-{steps}.json", log)


def subset_rate(results: dict) -> tuple[int, int]:
    """(successes, episodes) of a results file."""
    episodes = results["episodes"]
    return sum(bool(e["success"]) for e in episodes), len(episodes)


def family_level_table(results: dict, reference: dict) -> list[str]:
    """Lines of successes per terrain family (rows) and level (columns) on the subset, ``results`` against
    ``reference`` (``scripted``'s), each cell "learned/reference of n"; a trailing ``+`` marks a cell where the
    learned policy got more episodes up, ``-`` fewer."""
    def counts(run: dict) -> dict:
        table = {}
        for e in run["episodes"]:
            wins, n = table.get((e["terrain"], e["level"]), (0, 0))
            table[(e["terrain"], e["level"])] = (wins + bool(e["success"]), n + 1)
        return table

    mine, theirs = counts(results), counts(reference)
    levels = sorted({level for _, level in mine})
    lines = [f"{'family':8s}" + "".join(f"{f'level {level}':>16s}" for level in levels)]
    for family in dict.fromkeys(terrain for terrain, _ in mine):
        row = f"{family:8s}"
        for level in levels:
            (wins, n), (ref, _) = mine[(family, level)], theirs.get((family, level), (0, 0))
            mark = "+" if wins > ref else "-" if wins < ref else " "
            row += f"{f'{wins}/{ref} of {n}{mark}':>16s}"
        lines.append(row)
    return lines


def report_subset(out: Path, seeds: list[int], budget: float, stop_at: float) -> None:
    """Print each seed's standard-grid estimate on `SUBSET` at its checkpoints with the imitation weight there,
    ``scripted`` on the same cells, and the stop rule (the first checkpoint at or past half the budget above
    ``stop_at``)."""
    from frbench.evaluation.intervals import wilson_interval

    def cell(results: dict) -> str:
        wins, n = subset_rate(results)
        low, high = wilson_interval(wins, n)
        return f"{wins / n:.3f} [{low:.3f}, {high:.3f}] ({wins}/{n})"

    print(f"standard-grid estimate on the subset {SUBSET_NAME} ({', '.join(f'{k} {v}' for k, v in SUBSET.items())})")
    scripted = evaluate_subset('scripted', out / 'subset-scripted.json')
    print(f"scripted: {cell(scripted)}")
    for seed in seeds:
        folder = out / f"seed{seed}"
        path = folder / "progress.json"
        progress = json.loads(path.read_text()) if path.is_file() else []
        half = None
        for steps, result in sorted(subset_results(folder).items()):
            row = at_mark(progress, steps) or {}
            weight = row.get("loss_imitation_weight", float("nan"))
            results = json.loads(result.read_text())
            print(f"seed {seed}  {steps / 1e6:6.2f} M  {cell(results)}  imitation weight {weight:.3f}")
            if half is None and steps >= budget / 2:
                half = subset_rate(results)
        if subset_results(folder):
            last_steps, last = max(subset_results(folder).items())
            print(f"seed {seed} at {last_steps / 1e6:.2f} M against scripted, successes per family and level "
                  "(learned/scripted of episodes):")
            print("\n".join(family_level_table(json.loads(last.read_text()), scripted)))
        if half is None:
            print(f"seed {seed}: stop rule: not yet at half the budget ({budget / 2e6:g} M)")
        else:
            verdict = "go on" if half[0] / half[1] > stop_at else "stop"
            print(f"seed {seed}: stop rule at half the budget: {half[0] / half[1]:.3f} vs {stop_at:g}: {verdict}")


def report_unseen_subset(out: Path, seeds: list[int]) -> None:
    """Print each seed's unseen-grid estimate on ``unseen-seed0`` (`unseen_subset`) at its standard-subset
    checkpoints: the policy snapshot there plays it (``OUT/seed<S>/unseen-<env steps>.json``, kept), beside
    ``scripted`` on the same cells (``OUT/unseen-scripted.json``)."""
    from frbench.evaluation.intervals import wilson_interval

    def cell(results: dict) -> str:
        wins, n = subset_rate(results)
        low, high = wilson_interval(wins, n)
        return f"{wins / n:.3f} [{low:.3f}, {high:.3f}] ({wins}/{n})"

    cells = unseen_subset()
    print(f"unseen-grid estimate on the subset {UNSEEN_SUBSET_NAME} ({', '.join(f'{k} {v}' for k, v in cells.items())})")
    print(f"scripted: {cell(evaluate_subset('scripted', out / 'unseen-scripted.json', subset=cells))}")
    for seed in seeds:
        folder = out / f"seed{seed}"
        for steps in sorted(subset_results(folder)):
            snapshot = snapshot_at(folder, steps)
            if snapshot is None:
                print(f"seed {seed}  {steps / 1e6:6.2f} M  no snapshot")
                continue
            at, policy = snapshot
            results = evaluate_subset(str(policy), folder / f"unseen-{at}.json", subset=cells)
            print(f"seed {seed}  {at / 1e6:6.2f} M  {cell(results)}")


def train_all(args, seeds: list[int]) -> None:
    """Train the seeds, ``args.jobs`` at a time (`train_seed`)."""
    args.out.mkdir(parents=True, exist_ok=True)
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        list(pool.map(lambda seed: train_seed(args, seed), seeds))


def parse_stage(text: str) -> tuple[float, list[str]]:
    """``AT:ARGS`` of ``--stage``: env steps and the ``frbench train --resume`` arguments of the new stage."""
    at, _, rest = text.partition(":")
    try:
        return float(at), shlex.split(rest)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--stage {text!r}: expected AT:ARGS, e.g. '7.5e6:--motion-penalties 0.3'")


def at_mark(progress: list[dict], mark: float) -> dict | None:
    """The first logged point at or after ``mark`` env steps (None: the run has not got there)."""
    return next((row for row in progress if row["env_steps"] >= mark), None)


def report(out: Path, seeds: list[int], target: float, marks=MARKS) -> int:
    """Print the per-seed table; the number of seeds whose flat success at the last mark is >= ``target``."""
    rows: dict[int, list] = {}
    for seed in seeds:
        path = out / f"seed{seed}" / "progress.json"
        progress = json.loads(path.read_text()) if path.is_file() else []
        rows[seed] = [at_mark(progress, m) for m in marks]
    header = "seed  " + "  ".join(f"{m / 1e6:>9.3g}M" for m in marks)
    print(f"training success, flat / all terrains, at env-step marks ({out})")
    print(header)
    for seed, points in rows.items():
        cells = [f"{p['success_flat']:.2f}/{p['success_all']:.2f}" if p else "    -    " for p in points]
        print(f"{seed:>4}  " + "  ".join(f"{c:>10}" for c in cells))
    for name, reduce in (("mean", lambda v: sum(v) / len(v)), ("min", min)):
        cells = []
        for i in range(len(marks)):
            points = [rows[s][i] for s in seeds]
            if all(points):
                cells.append(f"{reduce([p['success_flat'] for p in points]):.2f}/"
                             f"{reduce([p['success_all'] for p in points]):.2f}")
            else:
                cells.append("    -    ")
        print(f"{name:>4}  " + "  ".join(f"{c:>10}" for c in cells))
    last = [rows[s][-1] for s in seeds]
    reached = sum(1 for p in last if p and p["success_flat"] >= target)
    walls = [p["wall_s"] / 60 for p in last if p]
    if walls:
        print(f"wall-clock to the last mark: {', '.join(f'{w:.1f}' for w in walls)} min")
    print(f"reached target: {reached}/{len(seeds)} seeds (flat >= {target:g} at {marks[-1] / 1e6:g} M)")
    return reached


def report_deterministic(out: Path, seeds: list[int], target: float, rounds: int) -> int:
    """Print each seed's final policy's flat / all success with its mean action in its training env (``rounds``
    rounds); returns how many seeds reach ``target`` on flat ground."""
    from frbench.analysis.training_env import training_env_success

    flat, overall = [], []
    print(f"deterministic policy in its training env, {rounds} round(s) (success flat / all)")
    for seed in seeds:
        rates = training_env_success(out / f"seed{seed}", episodes=rounds, seed=seed)
        flat.append(rates.get("success_flat", float("nan")))
        overall.append(rates["success_all"])
        print(f"{seed:>4}   {flat[-1]:.3f}/{overall[-1]:.3f}")
    print(f"mean   {sum(flat) / len(flat):.3f}/{sum(overall) / len(overall):.3f}")
    print(f" min   {min(flat):.3f}/{min(overall):.3f}")
    reached = sum(f >= target for f in flat)
    print(f"reached target (deterministic): {reached}/{len(seeds)} seeds (flat >= {target:g})")
    return reached


def evaluate_flat(policy: Path, robot: str, result: Path, episodes: int, reuse: bool) -> list[dict]:
    """``frbench evaluate`` of ``policy`` on ``robot``, flat level 1, evaluation seeds 0-3 × ``episodes`` per
    simulator, written to ``result`` (kept when ``reuse`` and it holds that many episodes); its episodes."""
    if reuse and result.is_file():
        kept = json.loads(result.read_text())["episodes"]
        if len(kept) == len(EVALUATION_SEEDS) * episodes * 2:  # two simulators
            return kept
    command = [sys.executable, "-m", "frbench", "evaluate", "--policy", str(policy), "--robots", robot,
               "--terrains", "flat", "--levels", "1", "--seeds", ",".join(map(str, EVALUATION_SEEDS)), "--episodes", str(episodes),
               "--jobs", "1", "--out", str(result)]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return json.loads(result.read_text())["episodes"]


def evaluation_cells(episodes_run: list[dict]) -> str:
    """Successes per simulator and on both together, with a 95 % Wilson interval."""
    from frbench.evaluation.intervals import wilson_interval

    cells = []
    for backend in ("mujoco", "pybullet"):
        mine = [e["success"] for e in episodes_run if e["backend"] == backend]
        cells.append(f"{backend} {sum(mine)}/{len(mine)}")
    wins = sum(e["success"] for e in episodes_run)
    low, high = wilson_interval(wins, len(episodes_run))
    return f"{', '.join(cells)}; both {wins / len(episodes_run):.3f} [{low:.3f}, {high:.3f}]"


def report_evaluation(out: Path, seeds: list[int], episodes: int, robots: list[str]) -> None:
    """Print each seed's final policy's successes on each robot, flat level 1 (`evaluate_flat`; results in
    ``OUT/seed<S>/eval-<robot>-flat.json``), per simulator and with a 95 % Wilson interval on both together."""
    for robot in robots:
        print(f"frbench evaluate, {robot}, flat level 1, seeds 0-3 x {episodes} episodes (successes per simulator)")
        for seed in seeds:
            folder = out / f"seed{seed}"
            run = evaluate_flat(folder / "policy.pt", robot, folder / f"eval-{robot}-flat.json", episodes, reuse=False)
            print(f"{seed:>4}   {evaluation_cells(run)}")


def snapshot_at(folder: Path, mark: float) -> tuple[int, Path] | None:
    """(env steps, path) of the run's policy snapshot (``snapshots/policy_<env steps>.pt``) nearest to ``mark``
    env steps, within half the snapshot interval; None when the run has none there."""
    from frbench.training.run import SNAPSHOT_DIR, SNAPSHOT_EVERY_STEPS

    snapshots = {int(p.stem.split("_")[1]): p for p in (folder / SNAPSHOT_DIR).glob("policy_*.pt")}
    if not snapshots:
        return None
    steps = min(snapshots, key=lambda s: abs(s - mark))
    return (steps, snapshots[steps]) if abs(steps - mark) <= SNAPSHOT_EVERY_STEPS / 2 else None


def report_evaluation_at_marks(out: Path, seeds: list[int], episodes: int, marks: tuple[float, ...],
                               robots: list[str]) -> None:
    """Print, per robot, seed and mark, the flat level-1 successes of the policy snapshot nearest the mark
    (`evaluate_flat`; results in ``OUT/seed<S>/eval-<robot>-flat-<env steps>.json``, reused when present)."""
    for robot in robots:
        print(f"frbench evaluate of the snapshots, {robot}, flat level 1, seeds 0-3 x {episodes} episodes")
        for seed in seeds:
            folder = out / f"seed{seed}"
            for mark in marks:
                snapshot = snapshot_at(folder, mark)
                if snapshot is None:
                    print(f"{seed:>4}  {mark / 1e6:6.2f} M  no snapshot")
                    continue
                steps, policy = snapshot
                run = evaluate_flat(policy, robot, folder / f"eval-{robot}-flat-{steps}.json", episodes, reuse=True)
                print(f"{seed:>4}  {steps / 1e6:6.2f} M  {evaluation_cells(run)}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="folder of the seeds' run folders")
    parser.add_argument("--method", default="frnet")
    parser.add_argument("--preset", default="demo-starts")
    parser.add_argument("--set", action="append", default=[], dest="fields", metavar="FIELD=VALUE")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--steps", type=float, default=3.07e6)
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--jobs", type=int, default=3, help="seeds trained at once")
    parser.add_argument("--stage", type=parse_stage, metavar="AT:ARGS",
                        help="at AT env steps resume once with these frbench train arguments (a new stage)")
    parser.add_argument("--target", type=float, default=0.6)
    parser.add_argument("--subset-every", type=float, default=0, metavar="STEPS",
                        help=f"train in chunks of STEPS env steps and score each on the subset {SUBSET_NAME}")
    parser.add_argument("--stop-at", type=float, default=0.35,
                        help="the stop rule: the subset estimate at half the budget must be above this")
    parser.add_argument("--unseen-subset", action="store_true",
                        help=f"with --subset-every: also score each subset checkpoint's snapshot on {UNSEEN_SUBSET_NAME}")
    parser.add_argument("--report", action="store_true", help="print the table of the existing runs only")
    parser.add_argument("--marks", default=",".join(f"{m:g}" for m in MARKS),
                        help="env-step marks of the table (comma-separated), the last one the target's")
    parser.add_argument("--deterministic", type=int, default=0, metavar="ROUNDS",
                        help="also run each seed's final policy without exploration noise for ROUNDS rounds")
    parser.add_argument("--evaluate", type=int, default=0, metavar="EPISODES",
                        help="also score each seed's final policy on flat level 1 (EPISODES per cell and robot)")
    parser.add_argument("--evaluate-marks", type=int, default=0, metavar="EPISODES",
                        help="also score each seed's policy snapshot nearest each mark on flat level 1")
    parser.add_argument("--evaluate-robots", default="go2", metavar="ROBOTS",
                        help="robots (comma-separated) that --evaluate and --evaluate-marks score (default go2)")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    if not args.report:
        train_all(args, seeds)
    marks = tuple(float(m) for m in args.marks.split(","))
    report(args.out, seeds, args.target, marks)
    if args.subset_every:
        report_subset(args.out, seeds, args.steps, args.stop_at)
        if args.unseen_subset:
            report_unseen_subset(args.out, seeds)
    if args.deterministic:
        report_deterministic(args.out, seeds, args.target, args.deterministic)
    robots = args.evaluate_robots.split(",")
    if args.evaluate:
        report_evaluation(args.out, seeds, args.evaluate, robots)
    if args.evaluate_marks:
        report_evaluation_at_marks(args.out, seeds, args.evaluate_marks, marks, robots)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
