"""tools/average_snapshots.py: the mean of snapshots' actor tensors, refusals with exit status 2."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from frbench.policies.checkpoint import CHECKPOINT_FORMAT  # noqa: E402
from tools.average_snapshots import main  # noqa: E402


def snapshot(path, weight: list[float], steps: int, method: str = "frnet", count: int = 7):
    torch.save({"format": CHECKPOINT_FORMAT, "method": method, "env_steps": steps,
                "actor_state_dict": {"mlp.0.weight": torch.tensor(weight), "obs_normalizer.count": torch.tensor(count)}},
               path)
    return path


def test_the_floating_tensors_are_averaged_and_the_rest_is_the_last_snapshot(tmp_path, capsys):
    paths = [snapshot(tmp_path / "a.pt", [1.0, -2.0], 100, count=3), snapshot(tmp_path / "b.pt", [2.0, 0.0], 200),
             snapshot(tmp_path / "c.pt", [6.0, 5.0], 300, count=9)]
    assert main([*map(str, paths), "--out", str(tmp_path / "avg.pt")]) == 0
    data = torch.load(tmp_path / "avg.pt", weights_only=True)
    assert data["actor_state_dict"]["mlp.0.weight"].tolist() == [3.0, 1.0]
    assert data["actor_state_dict"]["obs_normalizer.count"].item() == 9  # an integer tensor: the last snapshot's
    assert data["env_steps"] == 300 and data["averaged_env_steps"] == [100, 200, 300]
    assert data["format"] == CHECKPOINT_FORMAT
    assert "mean of 3 snapshots" in capsys.readouterr().out


@pytest.mark.parametrize("second, message", [
    (dict(weight=[1.0, 2.0, 3.0], steps=2), "has shape (3,), expected (2,)"),
    (dict(weight=[1.0, 2.0], steps=2, method="ppo"), "method 'ppo' differs"),
])
def test_snapshots_that_do_not_match_are_refused_in_one_line_and_nothing_is_written(tmp_path, capsys, second, message):
    first = snapshot(tmp_path / "a.pt", [1.0, 2.0], 1)
    other = snapshot(tmp_path / "b.pt", **second)
    assert main([str(first), str(other), "--out", str(tmp_path / "avg.pt")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "avg.pt").exists()


def test_one_snapshot_is_not_an_average(tmp_path, capsys):
    assert main([str(snapshot(tmp_path / "a.pt", [1.0], 1)), "--out", str(tmp_path / "avg.pt")]) == 2
    assert "at least two snapshots, got 1" in capsys.readouterr().err
