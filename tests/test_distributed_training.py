"""Training across processes (`frbench.training.distributed`): 2 CPU processes (gloo) keep identical models,
resume, and count env steps over both ranks."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from frbench.cli import main

WORKER = Path(__file__).with_name("distributed_train_worker.py")
ROOT = Path(__file__).resolve().parents[1]
TINY = ["--method", "frnet", "--envs", "8", "--set", "episode_steps=5", "--set", "settle_steps=2",
        "--set", "num_morphologies=2", "--terrains", "flat,rough"]
STEPS_PER_ITERATION = 8 * 24 * 2  # envs x steps per env x ranks


def _env() -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1", FRBENCH_MUJOCO_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return env


def _two_ranks(tmp_path: Path, *flags: str) -> list[dict]:
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node=2", str(WORKER),
               str(tmp_path), "3", *flags]
    done = subprocess.run(command, env=_env(), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return torch.load(tmp_path / "ranks.pt", weights_only=False)


def test_two_processes_keep_identical_models_and_resume(tmp_path):
    rank0, rank1 = _two_ranks(tmp_path)
    groups = {"actor", "estimator", "critic", "actor_normalizer", "critic_normalizer"}
    assert set(rank0["trained"]) == groups
    assert not torch.equal(rank0["masses"], rank1["masses"])  # each rank its own robots ...
    assert not torch.equal(rank0["before"]["actor"], rank1["before"]["actor"])  # ... and own initial draws
    for stage in ("trained", "resumed"):
        for group in groups:
            assert torch.equal(rank0[stage][group], rank1[stage][group]), (stage, group)
    for group in ("actor", "estimator", "critic"):  # trained: rank 0's initial weights moved
        assert (rank0["trained"][group] - rank0["before"][group]).abs().max() > 1e-4, group
    count = rank0["trained"]["actor_normalizer"][-1]  # the normaliser's sample count: both ranks' rollouts
    assert count == 3 * STEPS_PER_ITERATION
    assert rank0["iteration"] == rank1["iteration"] == 4 and rank0["env_steps"] == 4 * STEPS_PER_ITERATION
    state = torch.load(tmp_path / "run" / "state.pt", weights_only=False)
    assert state["env_steps"] == 4 * STEPS_PER_ITERATION and len(state["ranks"]) == 2
    progress = json.loads((tmp_path / "run" / "progress.json").read_text())
    assert [row["env_steps"] for row in progress] == [3 * STEPS_PER_ITERATION, 4 * STEPS_PER_ITERATION]


@pytest.mark.slow
def test_without_the_estimators_all_reduce_its_weights_drift_apart(tmp_path):
    rank0, rank1 = _two_ranks(tmp_path, "--no-estimator-reduce")
    assert torch.equal(rank0["trained"]["actor"], rank1["trained"]["actor"])
    assert not torch.equal(rank0["trained"]["estimator"], rank1["trained"]["estimator"])


@pytest.mark.slow
def test_frbench_train_nproc_2_trains_and_resumes_from_the_command_line(tmp_path):
    out = tmp_path / "run"
    frbench = [sys.executable, "-m", "frbench", "train"]
    first = subprocess.run([*frbench, *TINY, "--nproc", "2", "--steps", str(2 * STEPS_PER_ITERATION),
                            "--checkpoint-every", "1", "--out", str(out)], env=_env(), capture_output=True, text=True)
    assert first.returncode == 0, first.stderr[-3000:]
    assert first.stdout.count("trained ") == 1  # one line, from rank 0
    again = subprocess.run([*frbench, "--resume", str(out), "--nproc", "2", "--steps", str(3 * STEPS_PER_ITERATION)],
                           env=_env(), capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-3000:]
    progress = json.loads((out / "progress.json").read_text())
    assert [row["env_steps"] for row in progress] == [STEPS_PER_ITERATION * i for i in (1, 2, 3)]
    assert json.loads((out / "config.json").read_text())["processes"] == 2


def test_a_multi_process_run_resumes_only_on_as_many_processes(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps({"method": "frnet", "processes": 2}))
    assert main(["train", "--resume", str(run), "--nproc", "3"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"frbench train: error: --resume {run}: the run trained on 2 process(es); resume it with --nproc 2 (got 3)"]


@pytest.mark.slow
def test_a_bad_input_on_2_processes_is_one_line_and_status_2(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text("{}")
    done = subprocess.run([sys.executable, "-m", "frbench", "train", *TINY, "--nproc", "2", "--out", str(out)],
                          env=_env(), capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"frbench train: error: --out {out}: a run is already there; use --resume {out} or another name"]
