"""DAgger of the ``mpc`` planner into an MLP that observes only proprioception (``frbench distill``).

The rounds follow frbench's DAgger rule (`frbench.training.dagger`, shared with the teacher that labels
inside the training env). Round 0 is behaviour cloning: the teacher acts and labels every step with its own
action. Each later round r is DAgger: the student trained on rounds 0..r−1 acts (a fraction ``beta`` of the
episodes, drawn from a seeded generator, is still acted by the teacher), and the teacher labels every visited state,
planning from that step's simulator state (it gets it through the episode runner's hooks, as in
evaluation). After each round the student is retrained from scratch on all the data gathered so far.

Episodes run in batches of ``batch`` episodes in one simulator (batches alternate between
``simulators``; the teacher plans on MuJoCo either way) from the protocol's fallen starts of
(robot, terrain, level) with start seeds ``start_seed + 1000·r + b``, away from the evaluation seeds.
A run folder holds:

* ``config.json``: the `DistillConfig` (a resumed run must match it);
* ``data/round<r>/batch<b>-ep<i>.npz``: one shard per episode (`frbench.training.distill_data`);
* ``checkpoints/round<r>.pt`` and ``round<r>.config.json``: the student after round r, a frbench policy
  checkpoint (method ``mpc-distill``) that `frbench.policies.learned.LearnedPolicy` loads;
* ``progress.json``: per round the dataset size (episodes, samples), its CPU cost [s], the successes of
  the acting policy (per simulator and start kind) and the training loss.

A killed run resumes where it stopped: batches whose shards all exist are not rerun. When the training
settings (`TRAINING_FIELDS`) change on resume, only the students still to act (the last round with data,
and the final one) are retrained; earlier ones stay as the students that collected the next round.
``extra_data`` names run folders of earlier distillations (same teacher, robot and history frames) whose
shards, all rounds, join every student's training set; it is a training setting. Batches run in ``jobs``
processes.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from frbench.errors import FrbenchError
from frbench.evaluation.episodes import run_episodes
from frbench.io import atomic_write_text
from frbench.policies.checkpoint import read_checkpoint
from frbench.robot_checks.lookup import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain
from frbench.training.dagger import teacher_acts, teacher_label
from frbench.training.distill_data import ObservationHistory, load_rounds, read_meta, shard_path, write_shard
from frbench.training.distill_student import (STUDENTS, build_actor, mixture_fit, save_student, student_actions,
                                              train_student)

#: The teachers `frbench distill` knows.
TEACHERS = ("mpc",)


@dataclass(frozen=True)
class DistillConfig:
    """A distillation run. Compute: rounds × episodes_per_round teacher episodes of `steps` control steps."""

    teacher: str = "mpc"
    teacher_settings: str = ""  # the teacher planner's overrides, ``$FRBENCH_MPC`` syntax ("" = defaults)
    robot: str = "g1"
    terrain: str = "flat"
    level: int = 1
    simulators: tuple[str, ...] = ("mujoco", "pybullet")
    rounds: int = 3
    episodes_per_round: int = 32
    batch: int = 2  # episodes per simulator batch
    steps: int = 250  # control steps per episode (0.02 s each)
    start_seed: int = 1000
    beta: float = 0.0  # DAgger rounds: fraction of episodes acted by the teacher
    frames: int = 3  # history frames the student sees
    hidden: tuple[int, ...] = (256, 256, 128)
    epochs: int = 30
    minibatch: int = 512
    learning_rate: float = 1e-3
    weight_decay: float = 0.0
    input_noise: float = 0.0  # training: input noise, a fraction of each input's spread in the dataset
    blind_to_previous_action: bool = False  # training: the normaliser hides a_{t−1} from the student
    extra_data: tuple[str, ...] = ()  # training: other distillation run folders whose shards join the training set
    student: str = "mse"  # training: "mse" (an MLP, MSE) or "mdn" (a mixture density network, NLL)
    components: int = 5  # training: the "mdn" student's Gaussian components
    seed: int = 0

    def __post_init__(self):
        if self.teacher not in TEACHERS:
            raise FrbenchError(f"--teacher: unknown teacher {self.teacher!r} (known: {', '.join(TEACHERS)})")
        if self.student not in STUDENTS:
            raise FrbenchError(f"--student: unknown student {self.student!r} (known: {', '.join(STUDENTS)})")
        for name in ("rounds", "episodes_per_round", "batch", "steps", "frames", "epochs", "minibatch", "components"):
            if int(getattr(self, name)) < 1:
                raise FrbenchError(f"{name}: expected a positive integer, got {getattr(self, name)!r}")
        if not 0.0 <= self.beta <= 1.0:
            raise FrbenchError(f"beta: expected a fraction in [0, 1], got {self.beta!r}")
        if not self.simulators:
            raise FrbenchError("simulators: expected at least one of mujoco, pybullet")

    def as_dict(self) -> dict:
        """Plain values (tuples as lists), as stored in ``config.json``."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> "DistillConfig":
        """The config stored in a run's ``config.json``."""
        tuples = {f.name for f in fields(cls) if "tuple" in str(f.type)}
        return cls(**{k: tuple(v) if k in tuples else v for k, v in data.items()})

    def batches(self) -> int:
        """Batches per round."""
        return math.ceil(self.episodes_per_round / self.batch)

    def batch_size(self, b: int) -> int:
        """Episodes of batch ``b`` (the last one may be short)."""
        return min(self.batch, self.episodes_per_round - b * self.batch)


class DAggerActor:
    """The acting policy of one batch: teacher or student per episode; the teacher labels every step.

    It declares ``uses_simulator_state`` so that the episode runner hands the teacher its state; the student
    part sees only `ObservationHistory`'s proprioception. ``records`` holds per step (o_t, history, label).
    """

    uses_simulator_state = True
    inputs = "simulator-state"
    checkpoint = None
    name = "dagger"

    def __init__(self, teacher, student, teacher_acts: np.ndarray, frames: int):
        self.teacher, self.student = teacher, student
        self.teacher_acts = np.asarray(teacher_acts, dtype=bool)
        self.frames = frames

    def supports(self, spec) -> bool:
        return self.teacher.supports(spec)

    def reset(self, spec, num_envs: int) -> None:
        self.default_pose = np.asarray(spec.default_pose, dtype=float)
        self.teacher.reset(spec, num_envs)
        self.tracker = ObservationHistory(self.default_pose, num_envs, self.frames)
        self.records: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def reset_episode(self, terrain, seed: int) -> None:
        self.teacher.reset_episode(terrain, seed)

    def observe_state(self, state) -> None:
        self.teacher.observe_state(state)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, J) [rad]: the teacher's where it acts, the student's elsewhere."""
        o_t, history = self.tracker.observe(obs)
        label = teacher_label(self.teacher.act(obs), self.default_pose)
        action = label.copy()
        if self.student is not None and not self.teacher_acts.all():
            student = student_actions(self.student, o_t, history)
            action[~self.teacher_acts] = student[~self.teacher_acts]
        self.records.append((o_t, history, label))
        self.tracker.acted(action)
        return self.default_pose + self.tracker.previous


def _teacher(config: DistillConfig):
    from frbench.policies.mpc import MpcPolicy, config_from_text

    planner, _ = config_from_text(config.teacher_settings)
    return MpcPolicy(planner)


def collect_batch(run: Path, config: DistillConfig, round_index: int, b: int) -> list[dict]:
    """Run batch ``b`` of round ``round_index`` and write its episodes' shards; their metas."""
    import torch

    torch.set_num_threads(1)
    cpu = time.process_time()
    n = config.batch_size(b)
    simulator = config.simulators[b % len(config.simulators)]
    start_seed = config.start_seed + 1000 * round_index + b
    spec = get_robot(config.robot)
    terrain = make_terrain(config.terrain, config.level, start_seed)
    starts = draw_starts(spec, terrain, config.terrain, config.level, start_seed, range(n))
    acting = teacher_acts(config.seed, round_index, b, n, config.beta)
    student = (None if round_index == 0 else
               build_actor(read_checkpoint(Path(run) / "checkpoints" / f"round{round_index - 1}.pt")))
    actor = DAggerActor(_teacher(config), student, acting, config.frames)
    task = run_episodes(spec, simulator, terrain, starts, actor, seed=start_seed, steps=config.steps)
    diverged = task.metrics.diverged | task.settle_diverged
    success = task.success.success & ~diverged
    obs, history, labels = (np.stack([r[k] for r in actor.records], axis=1) for k in range(3))
    cpu_each = (time.process_time() - cpu) / n
    metas = []
    for i in range(n):
        meta = {"round": round_index, "batch": b, "episode": i, "simulator": simulator, "start_seed": start_seed,
                "start": starts.kinds[i], "acted_by": "teacher" if acting[i] else "student",
                "success": bool(success[i]), "samples": int(obs.shape[1]), "cpu_s": round(cpu_each, 3)}
        write_shard(shard_path(run, round_index, b, i), obs[i], history[i], labels[i], meta)
        metas.append(meta)
    return metas


def _pending(run: Path, config: DistillConfig, round_index: int) -> list[int]:
    """Batches of a round with a shard missing."""
    return [b for b in range(config.batches())
            if not all(shard_path(run, round_index, b, i).is_file() for i in range(config.batch_size(b)))]


def _collect_round(run: Path, config: DistillConfig, round_index: int, jobs: int, log) -> None:
    pending = _pending(run, config, round_index)
    if jobs <= 1 or len(pending) <= 1:
        for b in pending:
            _log_batch(log, round_index, b, collect_batch(run, config, round_index, b))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {pool.submit(collect_batch, run, config, round_index, b): b for b in pending}
        for future in as_completed(futures):
            _log_batch(log, round_index, futures[future], future.result())


def _log_batch(log, round_index: int, b: int, metas: list[dict]) -> None:
    up = sum(m["success"] for m in metas)
    log(f"round {round_index} batch {b}: {metas[0]['simulator']}, {up}/{len(metas)} up "
        f"({', '.join(m['start'] for m in metas)}), {sum(m['cpu_s'] for m in metas):.0f} CPU s")


def _round_summary(run: Path, round_index: int) -> dict:
    """Dataset and acting-policy numbers of one round, from its shards."""
    metas = [read_meta(p) for p in sorted((Path(run) / "data" / f"round{round_index}").glob("*.npz"))]
    summary = {"round": round_index, "episodes": len(metas), "samples": sum(m["samples"] for m in metas),
               "cpu_s": round(sum(m["cpu_s"] for m in metas), 1)}
    for actor in ("teacher", "student"):
        acted = [m for m in metas if m["acted_by"] == actor]
        cells: dict[str, list[int]] = {}
        for m in acted:
            for key in (m["simulator"], m["start"]):
                cells.setdefault(key, [0, 0])
                cells[key][0] += m["success"]
                cells[key][1] += 1
        summary[actor] = {"episodes": len(acted), "successes": sum(m["success"] for m in acted),
                          "by": {k: f"{v[0]}/{v[1]}" for k, v in sorted(cells.items())}}
    return summary


def _write_progress(run: Path, config: DistillConfig, trained: dict) -> dict:
    rounds = [_round_summary(run, r) for r in range(config.rounds)
              if (Path(run) / "data" / f"round{r}").is_dir()]
    for summary in rounds:
        summary["training"] = trained.get(summary["round"])
    progress = {"config": config.as_dict(), "rounds": rounds,
                "dataset": {"episodes": sum(r["episodes"] for r in rounds),
                            "samples": sum(r["samples"] for r in rounds),
                            "cpu_s": round(sum(r["cpu_s"] for r in rounds), 1)}}
    atomic_write_text(Path(run) / "progress.json", json.dumps(progress, indent=1) + "\n")
    return progress


#: Fields that change only the student's training: a resumed run may change them (its students are retrained).
TRAINING_FIELDS = ("rounds", "hidden", "epochs", "minibatch", "learning_rate", "weight_decay", "input_noise",
                   "blind_to_previous_action", "extra_data", "student", "components")


def _training_settings(config: DistillConfig) -> dict:
    return {k: v for k, v in config.as_dict().items() if k in TRAINING_FIELDS and k != "rounds"}


def _stale(stored: dict | None, config: DistillConfig) -> bool:
    """Whether a student trained with the ``stored`` training settings differs from ``config``'s (a setting
    the stored ones lack, from a run older than it, counts as its default)."""
    if stored is None:
        return True
    defaults = _training_settings(DistillConfig())
    return any(stored.get(k, defaults[k]) != v for k, v in _training_settings(config).items())


def _check_config(run: Path, config: DistillConfig) -> None:
    """Store the config in a new run; refuse a resumed run whose data settings differ (`TRAINING_FIELDS` may)."""
    path = Path(run) / "config.json"
    if path.is_file():
        stored = json.loads(path.read_text())
        changed = sorted(k for k, v in config.as_dict().items() if k not in TRAINING_FIELDS and stored.get(k) != v)
        if changed:
            raise FrbenchError(f"{path}: the run was made with other settings ({', '.join(changed)}); "
                               "use a new --out or the same settings")
    for other in config.extra_data:
        if Path(other).resolve() == Path(run).resolve():
            raise FrbenchError(f"--extra-data {other}: that is this run's own folder")
        _extra_rounds(Path(other), config)
    atomic_write_text(path, json.dumps(config.as_dict(), indent=1) + "\n")


#: Settings an extra run (`DistillConfig.extra_data`) must share with the run it joins.
SHARED_FIELDS = ("teacher", "robot", "frames")


def _extra_rounds(other: Path, config: DistillConfig) -> int:
    """The last round with data of the run folder ``other``; a FrbenchError when it is not a distillation run
    of the same teacher, robot and history frames, or has no shards."""
    path = other / "config.json"
    if not path.is_file():
        raise FrbenchError(f"--extra-data {other}: no distillation run there (expected {path})")
    try:
        stored = json.loads(path.read_text())
    except ValueError as error:
        raise FrbenchError(f"--extra-data {path}: not a JSON run config ({error})") from None
    for name in SHARED_FIELDS:
        if stored.get(name) != getattr(config, name):
            raise FrbenchError(f"--extra-data {path}: {name} is {stored.get(name)!r}, this run's is "
                               f"{getattr(config, name)!r}")
    rounds = [r for r in range(int(stored.get("rounds", 0))) if any((other / "data" / f"round{r}").glob("*.npz"))]
    if not rounds:
        raise FrbenchError(f"--extra-data {other}: no dataset shards under {other / 'data'}")
    return max(rounds)


def _training_data(run: Path, config: DistillConfig, round_index: int):
    """Rounds 0..``round_index`` of ``run`` and every round of the ``extra_data`` runs: (obs, history, actions,
    metas) as `load_rounds` returns them, this run's first."""
    parts = [load_rounds(run, round_index)]
    parts += [load_rounds(Path(other), _extra_rounds(Path(other), config)) for other in config.extra_data]
    return (*(np.concatenate([part[k] for part in parts]) for k in range(3)), [m for part in parts for m in part[3]])


def run_distillation(run: Path, config: DistillConfig, jobs: int = 1, log=print) -> dict:
    """Run (or resume) the distillation into the folder ``run``; returns the progress dict."""
    run = Path(run)
    _check_config(run, config)
    trained_path = run / "training.json"
    trained = {int(k): v for k, v in json.loads(trained_path.read_text()).items()} if trained_path.is_file() else {}
    for r in range(config.rounds):
        _collect_round(run, config, r, jobs, log)
        checkpoint = run / "checkpoints" / f"round{r}.pt"
        stale = _stale(trained.get(r, {}).get("settings"), config)
        # a student whose successor round is complete is kept as it was: it collected that round's data
        if not checkpoint.is_file() or (stale and (r == config.rounds - 1 or _pending(run, config, r + 1))):
            obs, history, actions, metas = _training_data(run, config, r)
            cpu = time.process_time()
            actor, loss = train_student(obs, history, actions, config, r)
            dataset = {"episodes": len(metas), "samples": int(len(obs)),
                       "cpu_s": round(sum(m["cpu_s"] for m in metas), 1)}
            save_student(checkpoint, actor, config, r, dataset)
            trained[r] = {"samples": int(len(obs)), "loss": loss, "cpu_s": round(time.process_time() - cpu, 1),
                          "checkpoint": str(checkpoint), "settings": _training_settings(config)}
            fit = f"MSE {loss:.4f} rad²"
            if config.student == "mdn":  # its own objective; the MSE of what it acts compares with the MLP's
                trained[r].update(mixture_fit(actor, obs, history, actions))
                fit = (f"objective {loss:.3f}, NLL {trained[r]['nll']:.3f} nats, MSE of its actions "
                       f"{trained[r]['mse']:.4f} rad²")
            atomic_write_text(trained_path, json.dumps(trained, indent=1) + "\n")
            log(f"round {r}: student trained on {len(obs)} samples of {len(metas)} episodes, {fit}")
        _write_progress(run, config, trained)
    return _write_progress(run, config, trained)
