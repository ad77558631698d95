"""A training run writes its config.json once, complete (estimator sizing included), and resumes without rewriting."""

import json

from frbench.training import run as run_module
from frbench.training.config import TrainEnvConfig
from frbench.training.run import CONFIG_FILE, TrainingRun


def _count_config_writes(monkeypatch) -> list:
    writes = []
    original = run_module.atomic_write_text

    def counting(path, text):
        if path.name == CONFIG_FILE:
            writes.append(json.loads(text))
        return original(path, text)

    monkeypatch.setattr(run_module, "atomic_write_text", counting)
    return writes


def test_config_json_is_written_once_per_run_and_not_again_on_resume(tmp_path, monkeypatch):
    writes = _count_config_writes(monkeypatch)
    cfg = TrainEnvConfig(num_envs=2, robot="g1", randomize=False, families=("flat",), episode_steps=3, settle_steps=2)
    run = TrainingRun(tmp_path / "g1", "frnet", cfg, total_steps=2 * 24, checkpoint_every=1)
    assert len(writes) == 1
    estimator = writes[0]["train_cfg"]["actor"]["estimator"]
    assert (estimator["num_masses"], estimator["num_contacts"]) == (3, 10)  # the G1's groups, sized before writing
    run.train(progress_bar=False)
    TrainingRun(tmp_path / "g1", resume=True, total_steps=3 * 24)
    assert len(writes) == 1
    TrainingRun(tmp_path / "g1", resume=True, reward_stage={"action_smoothing": -0.2}, command="stage")
    assert len(writes) == 2 and writes[1]["stages"][0]["weights"] == {"action_smoothing": -0.2}


def test_set_values_are_parsed_by_the_field_types_not_their_text():
    import pytest

    from frbench.training.config import parse_field

    assert parse_field("seed", "3") == 3 and isinstance(parse_field("seed", "3"), int)
    assert parse_field("demo_start_until", "5e6") == 5e6
    assert parse_field("families", "flat, stairs") == ("flat", "stairs")
    assert parse_field("base_controller", "none") is None and parse_field("base_controller", "scripted") == "scripted"
    assert parse_field("curriculum", "false") is False and parse_field("randomize", "1") is True
    with pytest.raises(ValueError, match=r"--set seed=x: expected a number \(int\)"):
        parse_field("seed", "x")
    with pytest.raises(ValueError, match="--set reward: not a settable field"):
        parse_field("reward", "1")
    with pytest.raises(ValueError, match="--set curriculum=maybe: expected true or false"):
        parse_field("curriculum", "maybe")


def test_population_seed_draws_the_robots_of_that_seed_and_leaves_the_default_unchanged():
    import numpy as np

    from frbench.training.config import parse_field
    from frbench.training.population import TrainingRobots

    small = dict(num_envs=4, num_morphologies=2, families=("flat",))

    def robots(**fields):
        cfg = TrainEnvConfig(**small, **fields)
        return TrainingRobots.drawn(cfg, np.random.default_rng(cfg.seed))

    seed1, swapped, seed0 = robots(seed=1), robots(seed=0, population_seed=1), robots(seed=0)
    assert swapped.morphologies == seed1.morphologies != seed0.morphologies
    assert swapped.assignment.tolist() == seed1.assignment.tolist()
    assert parse_field("population_seed", "1") == 1 and parse_field("population_seed", "none") is None
    assert TrainEnvConfig.from_dict({k: v for k, v in TrainEnvConfig(**small).to_dict().items()
                                     if k != "population_seed"}).population_seed is None  # older runs' config.json
