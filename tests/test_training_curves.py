"""A run's learning curve as CSV (env steps, wall-clock, success per family, losses) and `frbench plot-training`."""

import csv

from frbench.cli import main
from frbench.training.config import TrainEnvConfig
from frbench.training.curves import LossLog, curve_csv_text
from frbench.training.run import TrainingRun


def test_a_run_keeps_its_learning_curve_as_csv_with_losses_and_plot_training_draws_two_runs(tmp_path, capsys):
    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat", "stairs"))
    for seed in (0, 1):
        run = TrainingRun(tmp_path / f"seed{seed}", "ppo", TrainEnvConfig(**{**cfg.to_dict(), "reward": None, "seed": seed}),
                          total_steps=4 * 24 * 2, checkpoint_every=1)
        run.train(progress_bar=False)
    rows = list(csv.DictReader(open(tmp_path / "seed0" / "curve.csv")))
    assert [int(r["env_steps"]) for r in rows] == [96, 192]
    assert list(rows[0])[:5] == ["iteration", "env_steps", "wall_s", "success_all", "success_flat"]
    assert {"success_stairs", "loss_surrogate", "loss_value"} <= set(rows[0])
    assert all(float(r["loss_value"]) >= 0 for r in rows)
    assert all(0.0 < float(r["policy_std"]) < 2.0 and 1e-6 <= float(r["policy_learning_rate"]) <= 1e-2 for r in rows)
    assert float(rows[0]["reward_upright_orientation"]) > 0 > float(rows[0]["reward_joint_torques"])
    out = tmp_path / "curves.png"
    assert main(["plot-training", str(tmp_path / "seed0"), str(tmp_path / "seed1"), "--out", str(out)]) == 0
    assert out.stat().st_size > 10_000
    assert main(["plot-training", str(tmp_path / "seed0"), "--out", str(out), "--metrics", "nonsense"]) == 2
    assert main(["plot-training", str(tmp_path), "--out", str(out)]) == 2  # not a run folder
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("frbench plot-training: error: --metrics 'nonsense': expected columns")
    assert "no progress.json; expected a training run folder" in err[1]


def test_losses_are_averaged_over_the_updates_of_a_logging_window_and_the_csv_leaves_missing_cells_empty():
    log = LossLog()
    log.add({"value": 1.0, "surrogate": -0.5, "rnd": None})
    log.add({"value": 3.0, "surrogate": 0.5})
    assert log.means() == {"loss_value": 2.0, "loss_surrogate": 0.0}
    assert log.means() == {}
    text = curve_csv_text([{"env_steps": 1, "success_all": 0.5}, {"env_steps": 2, "loss_value": 1.0}])
    assert text.splitlines() == ["env_steps,success_all,loss_value", "1,0.5,", "2,,1.0"]



def test_a_run_writes_no_rsl_rl_model_files_and_its_curve_reaches_tensorboard(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    TrainingRun(tmp_path / "run", "frnet", cfg, total_steps=4 * 24 * 2, checkpoint_every=1).train(progress_bar=False)
    assert not list((tmp_path / "run").glob("model_*.pt"))
    events = EventAccumulator(str(tmp_path / "run"))
    events.Reload()
    steps = [e.step for e in events.Scalars("train/success_flat")]
    assert steps == [96, 192] and "loss/loss_value" in events.Tags()["scalars"]


def test_runs_that_share_a_folder_name_are_labelled_with_their_parent():
    from pathlib import Path

    from frbench.training.curves import run_labels

    assert run_labels([Path("a/seed0"), Path("a/seed1")]) == ["seed0", "seed1"]
    assert run_labels([Path("x/lc-a/seed0"), Path("x/lc-b/seed0")]) == ["lc-a/seed0", "lc-b/seed0"]
