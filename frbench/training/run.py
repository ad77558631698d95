"""A training run: rsl-rl's `OnPolicyRunner` on the recovery env, checkpointed and resumable.

A run folder ``runs/NAME/`` holds:

* ``config.json``: method, env config, rsl-rl config, step budget, seed, command;
* ``runner.pt``: rsl-rl's full training state (models, optimisers) — for ``--resume`` (a run kept in the
  tree holds it without the optimisers, `keep_without_optimisers`, and resumes with fresh Adam moments);
* ``state.pt``: frbench's state (iterations, env steps, wall-clock, curriculum,
  random generator) — for ``--resume``;
* ``policy.pt``: the frbench policy checkpoint (`frbench-policy-v1`, loads with
  ``torch.load(weights_only=True)``): actor weights incl. normalisers and the
  estimator, the resolved configs, the robot/action conventions;
* ``snapshots/policy_<env steps>.pt``: a copy of ``policy.pt`` every
  ``SNAPSHOT_EVERY_STEPS`` env steps (≈ 0.9 MB each), so that success can be
  measured with ``frbench evaluate`` along the run (steps to a target);
* ``progress.json`` and ``curve.csv``: the learning curve, one row per checkpoint
  (env steps, wall-clock, success rates, mean losses; `frbench.training.curves`),
  from which ``curve.png`` is drawn;
* TensorBoard event files of the same rows (frbench writes them: rsl-rl's runner
  gets no log folder, so it writes no ``model_*.pt`` files of its own).

Every file is written atomically, so a run killed at any point resumes from
its last checkpoint: ``frbench train --resume runs/NAME``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import time
from pathlib import Path

import torch
from tqdm import tqdm

from frbench.errors import FrbenchError
from frbench.io import atomic_write_text
from frbench.policies.checkpoint import CHECKPOINT_FORMAT
from frbench.robots.joint_frame import learner_joint_frame
from frbench.robots.morphology import morphology_ranges
from frbench.training import distributed
from frbench.training.config import TrainEnvConfig
from frbench.training.curves import PROGRESS_FILE, LossLog, TensorBoardCurve, plot_training, write_curve_csv
from frbench.training.env import RecoveryTrainingEnv
from frbench.training.methods import make_rma_adaptation_cfg, make_train_cfg
from frbench.training.rewards import check_weights

RUNNER_FILE, STATE_FILE, POLICY_FILE, CONFIG_FILE = "runner.pt", "state.pt", "policy.pt", "config.json"
SNAPSHOT_DIR = "snapshots"
#: Env steps between policy snapshots.
SNAPSHOT_EVERY_STEPS = 1_000_000


#: The entries of ``runner.pt`` that hold optimiser states (PPO's, the estimator's).
OPTIMISER_KEYS = ("optimizer_state_dict", "estimator_optimizer_state_dict")


def keep_without_optimisers(runner_file: Path, kept_file: Path) -> None:
    """Write ``runner_file`` (a run's ``runner.pt``) to ``kept_file`` without its optimiser states (`OPTIMISER_KEYS`,
    about 70 % of the file), with PPO's current learning rate as ``learning_rate``: the run then fits in a folder
    that is kept in the tree, and ``--resume`` goes on from it with fresh Adam moments at that rate."""
    saved = torch.load(runner_file, weights_only=False, map_location="cpu")
    kept = {key: value for key, value in saved.items() if key not in OPTIMISER_KEYS}
    kept["learning_rate"] = float(saved["optimizer_state_dict"]["param_groups"][0]["lr"])
    _atomic_torch_save(kept, Path(kept_file))


def _atomic_torch_save(obj, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def env_cfg_from_dict(data: dict, source: str = "config.json"):
    """A `TrainEnvConfig` from its JSON form (``source`` names the file in the error of a bad one)."""
    try:
        return TrainEnvConfig.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise FrbenchError(f"{source}: env: {exc}") from None


#: RMA's phase 2 as a method name (`frbench train --method rma-adaptation --teacher runs/rma`).
ADAPTATION_METHOD = "rma-adaptation"


def _adaptation_setup(teacher: Path | None):
    """(env config, train config) of an RMA phase-2 run from its phase-1 ``teacher`` run folder."""
    if teacher is None:
        raise FrbenchError(f"--method {ADAPTATION_METHOD} needs --teacher RUN, a finished 'rma' run folder")
    config_path = Path(teacher) / CONFIG_FILE
    if not config_path.is_file() or not (Path(teacher) / RUNNER_FILE).is_file():
        raise FrbenchError(f"--teacher {teacher}: expected a training run folder with {CONFIG_FILE} and {RUNNER_FILE}")
    teacher_config = json.loads(config_path.read_text())
    if teacher_config["method"] != "rma":
        raise FrbenchError(f"--teacher {teacher}: a {teacher_config['method']!r} run; RMA's phase 2 needs an 'rma' run")
    train_cfg = make_rma_adaptation_cfg()
    frames = int(train_cfg["actor"]["adaptation_frames"])
    env_cfg = dataclasses.replace(env_cfg_from_dict(teacher_config["env"], str(config_path)), long_history=frames)
    return env_cfg, train_cfg


def _bundle_parts(bundle: Path | None, env_cfg, device: str | None):
    """The `TrainingParts` of the device bundle in folder ``bundle`` (None: none, the env builds its own), checked
    against the run's config; a `FrbenchError` naming the flag when the run's simulator takes no device or bundle."""
    from frbench.backends.simulators import DEVICE_SIMULATORS

    if env_cfg.backend not in DEVICE_SIMULATORS and (bundle is not None or device not in (None, "cpu")):
        flag = f"--device {device}" if device not in (None, "cpu") else f"--bundle {bundle}"
        raise FrbenchError(f"{flag}: this run trains in {env_cfg.backend}, which runs on the CPU and builds its own "
                           f"parts; devices and bundles are for {', '.join(DEVICE_SIMULATORS)}")
    if bundle is None:
        return None
    from frbench.training.device_bundle import bundle_parts, check_bundle_config, load_bundle

    loaded = load_bundle(bundle)
    check_bundle_config(loaded, env_cfg, bundle)
    return bundle_parts(loaded)


def estimator_sized_for(train_cfg: dict, num_masses: int, num_contacts: int, nominal_masses) -> dict:
    """``train_cfg`` with the estimator's mass and contact heads sized for a robot whose labels have
    ``num_masses`` mass groups and ``num_contacts`` contact groups (unchanged when they already match).

    A new mass width gets divisors of one nominal group mass [kg] rounded up to 5 kg (the paper's
    15/5/5/5 kg for the quadruped's trunk/legs play the same role)."""
    estimator = train_cfg.get("actor", {}).get("estimator")
    if not estimator:
        return train_cfg
    changes = {}
    if estimator.get("num_masses", 4) != num_masses:
        changes["num_masses"] = int(num_masses)
        changes["mass_scale"] = [float(5.0 * max(1, math.ceil(m / 5.0))) for m in nominal_masses]
    if estimator.get("num_contacts", 13) != num_contacts:
        changes["num_contacts"] = int(num_contacts)
    if not changes:
        return train_cfg
    out = json.loads(json.dumps(train_cfg))
    out["actor"]["estimator"].update(changes)
    return out


class TrainingRun:
    """Create or resume a run and train it to its step budget."""

    def __init__(self, out: Path, method: str | None = None, env_cfg=None, total_steps: int | None = None,
                 checkpoint_every: int = 20, command: str = "", resume: bool = False, teacher: Path | None = None,
                 reward_stage: dict[str, float] | None = None, morphology_stage: dict | None = None,
                 train_overrides: dict | None = None, backend_stage: str | None = None,
                 algorithm_stage: dict[str, float] | None = None, device: str | None = None,
                 bundle: Path | None = None, field_stage: dict | None = None):
        """``method="rma-adaptation"`` is RMA's phase 2: ``teacher`` is a finished ``rma`` run folder whose
        policy is frozen while the adaptation module learns; its env config is reused (with a 50-frame
        long history), ``env_cfg`` is ignored.

        ``reward_stage`` (with ``resume``), reward term → new weight, starts a new reward stage from the run's
        current env step (e.g. the motion penalties at the paper's weights once the policy gets up). The
        changes and ``command`` are appended to ``config["stages"]``, so the checkpoint says which reward
        trained which steps. ``morphology_stage`` (with ``resume``), field → (low, high), likewise replaces rows
        of the morphology table: the run's robots are redrawn from the new table. ``backend_stage`` (with
        ``resume``), a backend name, continues the run in that simulator (e.g. ``mujoco+pybullet``: a MuJoCo-trained
        policy fine-tuned in both), recorded as a stage too. ``algorithm_stage`` (with ``resume``), PPO setting →
        value (``entropy_coef``), changes rsl-rl's algorithm config from the run's current step, recorded the
        same way. ``field_stage`` (with ``resume``), env config field → value (`config.STAGE_FIELDS`, e.g.
        ``{"bodies": "wide"}``), likewise: the run's robots are redrawn under the new value. ``device`` (`frbench.backends.devices.parse_device`'s value): where a device simulator runs and
        the run's tensors live; ``bundle``: a device bundle folder (`frbench.training.device_bundle`) whose parts
        the env is built from, built for this run's config. ``train_overrides`` (new runs)
        are merged into the method's rsl-rl config (e.g. ``{"actor": {"distribution_cfg": {"init_std": 0.2}}}``)
        and saved with it."""
        torch.set_num_threads(1)
        distributed.init_process_group()
        self.ranks = ranks = distributed.ranks()
        if ranks.world_size > 1 and method == ADAPTATION_METHOD:
            raise FrbenchError(f"--method {ADAPTATION_METHOD} trains on one process (without --nproc)")
        self.out = Path(out)
        if resume:
            config_path = self.out / CONFIG_FILE
            if not config_path.is_file():
                raise FrbenchError(f"--resume {self.out}: no {CONFIG_FILE} there; is it a training run folder?")
            config = json.loads(config_path.read_text())
            written = json.loads(json.dumps(config))
            distributed.check_resume_processes(config.get("processes", 1), self.out)
            method, env_cfg = config["method"], env_cfg_from_dict(config["env"], str(config_path))
            total_steps = total_steps or config["total_steps"]
            train_cfg = config["train_cfg"]
            new_backend = backend_stage if backend_stage and backend_stage != env_cfg.backend else None
            fields = {k: v for k, v in (field_stage or {}).items() if getattr(env_cfg, k) != v}
            if reward_stage or morphology_stage or new_backend or algorithm_stage or fields:
                env_cfg = self._new_stage(config, env_cfg, reward_stage or {}, morphology_stage or {}, command,
                                          new_backend, algorithm_stage or {}, fields)
                train_cfg = config["train_cfg"]
        else:
            if (self.out / CONFIG_FILE).exists():
                raise FrbenchError(f"--out {self.out}: a run is already there; use --resume {self.out} or another name")
            if method == ADAPTATION_METHOD:
                env_cfg, train_cfg = _adaptation_setup(teacher)
            else:
                train_cfg = make_train_cfg(method, train_overrides)
            config = {"method": method, "env": env_cfg.to_dict(), "train_cfg": train_cfg,
                      "total_steps": total_steps, "command": command}
            if teacher is not None:
                config["teacher"] = str(teacher)
            if ranks.world_size > 1:
                config["processes"] = ranks.world_size
            distributed.barrier()  # every rank has checked that the folder is free before rank 0 writes
        self.config, self.method, self.total_steps = config, method, int(total_steps)
        self.checkpoint_every = checkpoint_every
        seed = distributed.rank_seed(env_cfg.seed, ranks.rank)  # each rank its own environments and draws
        torch.manual_seed(seed)
        env_cfg = env_cfg if seed == env_cfg.seed else dataclasses.replace(env_cfg, seed=seed)
        self.env = RecoveryTrainingEnv(env_cfg, device, _bundle_parts(bundle, env_cfg, device))
        sized = estimator_sized_for(train_cfg, self.env.env_masses.shape[1], len(self.env.spec.contact_groups),
                                    self.env.env_masses[0])
        if sized != train_cfg:  # e.g. the G1: 3 mass groups and 10 contact groups instead of 4 and 13
            train_cfg = config["train_cfg"] = sized
        if ranks.is_main and (not resume or config != written):  # once, complete: a new run, a new stage, a resize
            self.out.mkdir(parents=True, exist_ok=True)
            atomic_write_text(self.out / CONFIG_FILE, json.dumps(config, indent=1) + "\n")
        self.runner = distributed.runner_class()(self.env, json.loads(json.dumps(train_cfg)), log_dir=None,
                                                 device=(self.env.device if self.env.device_arrays
                                                         else distributed.training_device()))
        self.losses = LossLog()  # the updates' losses in each logging window, for the learning curve
        self.tensorboard = TensorBoardCurve(self.out)
        self.policy_stats = LossLog(prefix="policy_")  # the action std and learning rate after each update
        logging_updates(self.runner.alg, self.losses, self.policy_stats)
        # control steps per iteration, summed over the ranks: each decision holds its action for `action_hold` steps
        self.steps_per_iteration = (self.env.num_envs * train_cfg["num_steps_per_env"] * self.env.cfg_obj.action_hold
                                    * ranks.world_size)
        self.iteration, self.env_steps, self.wall = 0, 0, 0.0
        self.progress: list[dict] = []
        if resume and (self.out / RUNNER_FILE).is_file():
            self._load_state()
        elif env_cfg.base_controller:
            zero_output_layer(self.runner.alg.actor)
        elif method == ADAPTATION_METHOD:
            self.runner.load(str(Path(config["teacher"]) / RUNNER_FILE))  # π, μ and normalisers, then frozen

    # ------------------------------------------------------------------ persistence
    def _new_stage(self, config: dict, env_cfg, weights: dict[str, float], morphology: dict, command: str,
                   backend: str | None = None, algorithm: dict[str, float] | None = None, fields: dict | None = None):
        """The env config with the reward ``weights``, ``morphology`` ranges, ``backend`` (None: unchanged) and
        config ``fields`` changed; ``algorithm`` settings set in ``config["train_cfg"]["algorithm"]``; records the
        stage in ``config`` (``__init__`` writes config.json)."""
        check_weights(weights)
        morphology_ranges(morphology)  # validates names and values before anything is written
        state_path = self.out / STATE_FILE
        steps = int(torch.load(state_path, weights_only=False)["env_steps"]) if state_path.is_file() else 0
        reward = env_cfg.reward
        for term, weight in weights.items():
            reward = reward.with_weight(term, weight, f"reward stage from {steps} env steps ({command or 'resume'})")
        ranges = {**env_cfg.morphology_ranges, **{k: tuple(map(float, v)) for k, v in morphology.items()}}
        try:
            env_cfg = dataclasses.replace(env_cfg, reward=reward, morphology_ranges=ranges,
                                          backend=backend or env_cfg.backend, **(fields or {}))
        except ValueError as exc:
            raise FrbenchError(f"--resume {self.out}: {exc}") from None
        config["env"] = env_cfg.to_dict()
        stage = {"from_env_steps": steps, "weights": dict(weights), "command": command}
        if backend:
            stage["backend"] = backend
        if morphology:
            stage["morphology_ranges"] = {k: list(map(float, v)) for k, v in morphology.items()}
        if fields:
            stage["fields"] = dict(fields)
        if algorithm:
            config["train_cfg"]["algorithm"].update(algorithm)
            stage["algorithm"] = dict(algorithm)
        config.setdefault("stages", []).append(stage)
        return env_cfg

    def _load_state(self) -> None:
        path = self.out / RUNNER_FILE
        saved = torch.load(path, weights_only=False, map_location="cpu")
        if "optimizer_state_dict" in saved:
            self.runner.load(str(path))
        else:  # a run kept without its optimiser states (`keep_without_optimisers`): fresh moments, its last rate
            self.runner.load(str(path), load_cfg={"actor": True, "critic": True, "iteration": True})
            algorithm = self.runner.alg
            algorithm.learning_rate = float(saved.get("learning_rate", algorithm.learning_rate))
            for group in algorithm.optimizer.param_groups:
                group["lr"] = algorithm.learning_rate
        state = torch.load(self.out / STATE_FILE, weights_only=False)
        self.iteration, self.env_steps, self.wall = state["iteration"], state["env_steps"], state["wall"]
        own = state["ranks"][self.ranks.rank] if "ranks" in state else state  # a multi-process run's per-rank state
        self.env.curriculum.load_state_dict(own["curriculum"])
        self.env.env_steps = self.env_steps
        self.env.rng.bit_generator.state = own["rng"]
        self.progress = json.loads((self.out / PROGRESS_FILE).read_text()) if (self.out / PROGRESS_FILE).is_file() else []
        self.runner.current_learning_iteration = self.iteration

    def save(self) -> None:
        """Write runner, state, policy and progress (each atomically; rank 0 only, with every rank's state)."""
        rank_states = distributed.gather_objects({"curriculum": self.env.curriculum.state_dict(),
                                                  "rng": self.env.rng.bit_generator.state})
        if not self.ranks.is_main:
            return
        self.runner.current_learning_iteration = self.iteration
        tmp = self.out / f".{RUNNER_FILE}.tmp"
        self.runner.save(str(tmp))
        os.replace(tmp, self.out / RUNNER_FILE)
        _atomic_torch_save({"iteration": self.iteration, "env_steps": self.env_steps, "wall": self.wall,
                            **rank_states[0], **({"ranks": rank_states} if len(rank_states) > 1 else {})},
                           self.out / STATE_FILE)
        actor = self.runner.alg.get_policy()
        _atomic_torch_save(policy_checkpoint(self.method, self.config, actor, self.iteration, self.env_steps, self.wall,
                                             self.env.num_actions, self.env.spec.kind),
                           self.out / POLICY_FILE)
        atomic_write_text(self.out / PROGRESS_FILE, json.dumps(self.progress, indent=1) + "\n")
        write_curve_csv(self.progress, self.out)
        self._snapshot()

    def _snapshot(self) -> None:
        """Copy policy.pt to snapshots/ when the run has crossed another ``SNAPSHOT_EVERY_STEPS`` env steps."""
        folder = self.out / SNAPSHOT_DIR
        taken = sorted(int(p.stem.split("_")[1]) for p in folder.glob("policy_*.pt")) if folder.is_dir() else []
        last = taken[-1] if taken else 0
        if self.env_steps // SNAPSHOT_EVERY_STEPS > last // SNAPSHOT_EVERY_STEPS:
            folder.mkdir(exist_ok=True)
            tmp = folder / f".policy_{self.env_steps}.pt.tmp"
            shutil.copyfile(self.out / POLICY_FILE, tmp)
            os.replace(tmp, folder / f"policy_{self.env_steps}.pt")

    # ------------------------------------------------------------------ training
    def train(self, progress_bar: bool = True) -> None:
        """Train until ``total_steps`` env steps, checkpointing every ``checkpoint_every`` iterations."""
        total_iterations = math.ceil(self.total_steps / self.steps_per_iteration)
        bar = tqdm(total=total_iterations, initial=self.iteration, unit="it", disable=not (progress_bar and self.ranks.is_main),
                   dynamic_ncols=True)
        while self.iteration < total_iterations:
            chunk = min(self.checkpoint_every, total_iterations - self.iteration)
            start = time.time()
            self.runner.current_learning_iteration = self.iteration
            self.runner.learn(chunk)
            self.iteration += chunk
            self.env_steps = self.iteration * self.steps_per_iteration
            self.wall += time.time() - start
            stats = distributed.mean_over_ranks(self.env.last_episode_stats)
            if self.ranks.world_size > 1:
                self.env.env_steps = self.env_steps  # schedules (demo starts, assist force) follow the run's steps
            self.progress.append({"iteration": self.iteration, "env_steps": self.env_steps, "wall_s": round(self.wall, 1),
                                  **stats, **distributed.mean_over_ranks(self.env.last_curriculum_stats),
                                  **self.losses.means(), **self.policy_stats.means(),
                                  **self.env.reward_means.means()})
            if self.ranks.is_main:
                self.tensorboard.add(self.progress[-1])
            self.save()
            bar.update(chunk)
            bar.set_postfix(steps=f"{self.env_steps / 1e6:.2f}M", success=stats.get("success_flat"))
        bar.close()
        self.tensorboard.close()
        if self.ranks.is_main:
            plot_training([self.out], self.out / "curve.png", labels=[f"{self.method} ({self.out.name})"])


def logging_updates(algorithm, log: LossLog, policy_log: LossLog | None = None) -> None:
    """Make every ``algorithm.update()`` (rsl-rl's: it returns a dict of mean losses) also add them to ``log``, and
    the policy's mean action std and learning rate after it to ``policy_log`` (rsl-rl's public
    ``get_policy().output_std`` and ``learning_rate``)."""
    update = algorithm.update

    def update_and_log():
        losses = update()
        log.add(losses or {})
        if policy_log is not None and hasattr(algorithm, "get_policy"):  # RMA's adaptation phase has no policy std
            policy_log.add({"std": float(algorithm.get_policy().output_std.detach().mean()),
                            "learning_rate": float(algorithm.learning_rate)})
        return losses

    algorithm.update = update_and_log


def zero_output_layer(actor) -> None:
    """Zero the weights and bias of the actor network's last linear layer, so that a new residual policy's mean
    action is 0 for every observation: it starts as its base controller exactly, and moves away only where
    the policy gradient says so (residual policy learning, Silver et al. 2018). A random initial layer adds
    about 0.01 rad of state-dependent offsets to key frames whose own search put them at an optimum."""
    last = [m for m in actor.mlp.modules() if isinstance(m, torch.nn.Linear)][-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.zero_()


def policy_checkpoint(method: str, config: dict, actor, iteration: int, env_steps: int, wall: float,
                      num_actions: int = 12, robot_kind: str = "quadruped") -> dict:
    """The frbench policy checkpoint: plain tensors and JSON-able values only (``weights_only`` loadable); its
    ``joint_frame`` is the one the trainers observe and act in (`frbench.robots.joint_frame.learner_joint_frame`)."""
    env = config["env"]
    return {
        "format": CHECKPOINT_FORMAT,
        "method": method,
        "config_json": json.dumps(config),
        "actor_state_dict": {k: v.detach().cpu().clone() for k, v in actor.state_dict().items()},
        "action_scale": float(env["action_scale"]),
        "history": int(env["history"]),
        "num_actions": int(num_actions),
        "robot_kind": robot_kind,
        "joint_frame": learner_joint_frame(robot_kind, bool(env.get("base_controller"))),
        "iteration": int(iteration),
        "env_steps": int(env_steps),
        "wall_s": float(wall),
    }
