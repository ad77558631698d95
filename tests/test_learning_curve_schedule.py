"""benchmarks/learning_curve.py's schedule: which ``frbench train`` command a seed runs next, and a kept run."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tests.scripts import load_script as load

def load_script():
    return load("benchmarks/learning_curve.py", "learning_curve_script")


def run_folder(tmp_path: Path, env_steps: int, stages: list[str] = ()) -> Path:
    folder = tmp_path / "seed0"
    folder.mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps({"stages": [{"command": c} for c in stages]}))
    (folder / "progress.json").write_text(json.dumps([{"env_steps": env_steps}]))
    return folder


def arguments(**overrides) -> argparse.Namespace:
    values = dict(method="frnet", preset="kickstart-scripted", envs=256, fields=[], steps=24e6, subset_every=2e6,
                  stage=(10e6, ["--set", "bodies=wide"]))
    values.update(overrides)
    return argparse.Namespace(**values)


def steps_of(command: list[str]) -> float:
    return float(command[command.index("--steps") + 1])


def test_a_stage_starts_at_its_step_and_trains_only_to_the_next_subset_checkpoint(tmp_path):
    lc = load_script()
    folder = run_folder(tmp_path, 10_002_432)
    command = lc.next_train_command(arguments(), 0, folder)
    assert command[command.index("--resume") + 1] == str(folder)
    assert command[-2:] == ["--set", "bodies=wide"]
    assert steps_of(command) == 12e6  # not the 24 M budget: the subset scores the stage's first checkpoint
    assert steps_of(lc.next_train_command(arguments(subset_every=0), 0, folder)) == 24e6


def test_before_its_stage_a_run_trains_to_the_stage_and_after_it_on_to_the_budget(tmp_path):
    lc = load_script()
    before = lc.next_train_command(arguments(subset_every=0), 0, run_folder(tmp_path, 8_005_632))
    assert steps_of(before) == 10e6 and "bodies=wide" not in before
    staged = run_folder(tmp_path / "staged", 12_001_280, stages=["frbench train --resume x --set bodies=wide"])
    after = lc.next_train_command(arguments(), 0, staged)
    assert steps_of(after) == 14e6 and "bodies=wide" not in after


def test_a_kept_run_without_its_policy_is_not_scored_again(tmp_path):
    lc = load_script()
    folder = run_folder(tmp_path, 8_005_632)
    log = (tmp_path / "seed0.log").open("w")
    lc.evaluate_subset_checkpoint(folder, 2e6, log)  # would run frbench evaluate on a missing policy.pt
    log.close()
    assert "no policy.pt at 8005632 env steps" in (tmp_path / "seed0.log").read_text()
    assert not list(folder.glob("subset-*.json"))


def test_the_unseen_subset_is_the_unseen_grids_quadruped_cells_of_seed_0_in_two_simulators():
    from frbench.tasks import protocol

    cells = load_script().unseen_subset()
    robots = cells["robots"].split(",")
    assert set(robots) == set(protocol.unseen_quadrupeds()) and len(robots) == 9
    assert not set(robots) & set(protocol.STANDARD_ROBOTS)
    episodes = (len(robots) * len(cells["backends"].split(",")) * len(cells["terrains"].split(","))
                * len(cells["levels"].split(",")) * len(cells["seeds"].split(",")) * int(cells["episodes"]))
    assert episodes == 432
