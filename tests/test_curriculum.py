"""Terrain curriculum: promotion, demotion, clamping, resampling, determinism, checkpoints."""

from __future__ import annotations

import io

import numpy as np
import pytest

from frbench.terrains import FAMILIES
from frbench.training.curriculum import TerrainCurriculum


def make(n: int = 14, seed: int = 0, **kwargs) -> TerrainCurriculum:
    return TerrainCurriculum(n, np.random.default_rng(seed), **kwargs)


def test_initial_state_balanced_families_start_level():
    c = make(70, start_level=3)
    assert c.family.shape == c.level.shape == (70,)
    assert np.all(c.level == 3)
    np.testing.assert_array_equal(np.bincount(c.family, minlength=7), [10] * 7)
    assert c.families == FAMILIES
    c = make(9)
    assert sorted(np.bincount(c.family, minlength=7)) == [1, 1, 1, 1, 1, 2, 2]


def test_promotion_on_success_demotion_on_failure():
    c = make(4, start_level=5)
    c.update([0, 1], [True, False])
    np.testing.assert_array_equal(c.level, [6, 4, 5, 5])
    c.update(np.array([0, 2]), np.array([True, True]))
    np.testing.assert_array_equal(c.level, [7, 4, 6, 5])


def test_clamped_at_level_one():
    c = make(2)
    c.update([0], [False])
    c.update([0], [False])
    np.testing.assert_array_equal(c.level, [1, 1])


def test_top_level_success_resamples_all_levels():
    n = 2000
    c = make(n, start_level=10)
    families = c.family.copy()
    c.update(np.arange(n), np.ones(n, dtype=bool))
    assert c.level.min() == 1 and c.level.max() == 10
    assert set(np.unique(c.level)) == set(range(1, 11))
    np.testing.assert_array_equal(c.family, families)  # families are kept
    c = make(3, start_level=10)
    c.update([0, 1], [False, False])
    np.testing.assert_array_equal(c.level, [9, 9, 10])


def test_window_rule():
    c = make(3, start_level=5, window=4, promote_threshold=0.75, demote_threshold=0.5)
    for outcome in ([True, True, False], [True, True, False], [True, False, True]):
        c.update([0, 1, 2], outcome)
        np.testing.assert_array_equal(c.level, [5, 5, 5])  # fewer than 4 episodes
    c.update([0, 1, 2], [True, False, False])
    # rates: 4/4 → up, 2/4 → stay, 1/4 → down
    np.testing.assert_array_equal(c.level, [6, 5, 4])
    c.update([0], [True])
    assert c.level[0] == 6  # a fresh block


def test_deterministic_given_rng():
    def run(seed):
        c = make(64, seed=seed, start_level=9)
        outcomes = np.random.default_rng(123)
        for _ in range(30):
            ids = np.flatnonzero(outcomes.random(64) < 0.5)
            c.update(ids, outcomes.random(ids.size) < 0.7)
        return c.family.copy(), c.level.copy()

    (fa, la), (fb, lb), (fc, lc) = run(1), run(1), run(2)
    np.testing.assert_array_equal(fa, fb)
    np.testing.assert_array_equal(la, lb)
    assert not (np.array_equal(fa, fc) and np.array_equal(la, lc))


def test_state_dict_round_trip_through_torch():
    torch = pytest.importorskip("torch")
    a = make(32, seed=5, start_level=10, window=2)
    a.update(np.arange(16), np.ones(16, dtype=bool))
    a.update(np.arange(32), np.ones(32, dtype=bool))
    buffer = io.BytesIO()
    torch.save({"curriculum": a.state_dict()}, buffer)
    buffer.seek(0)
    state = torch.load(buffer, weights_only=True)["curriculum"]
    b = make(32, seed=99, start_level=10, window=2)
    b.load_state_dict(state)
    np.testing.assert_array_equal(a.family, b.family)
    np.testing.assert_array_equal(a.level, b.level)
    # the two continue identically (block counters and rng state restored)
    for c in (a, b):
        c.update(np.arange(32), np.ones(32, dtype=bool))
        c.update(np.arange(32), np.ones(32, dtype=bool))
    np.testing.assert_array_equal(a.level, b.level)
    with pytest.raises(ValueError, match="environments"):
        make(31).load_state_dict(state)
    with pytest.raises(ValueError, match="families"):
        make(32, families=("flat", "rough")).load_state_dict(state)


def test_stats_and_cells():
    c = make(14, start_level=2)
    c.update(np.flatnonzero(c.family == 0), [True, True])
    stats = c.stats()
    assert stats[f"level/{FAMILIES[0]}"] == 3.0
    assert all(stats[f"level/{f}"] == 2.0 for f in FAMILIES[1:])
    assert stats["level/all"] == pytest.approx((2 * 3 + 12 * 2) / 14)
    assert stats["level/at_max"] == 0.0
    cells = c.cells()
    assert sum(len(v) for v in cells.values()) == 14
    np.testing.assert_array_equal(cells[(FAMILIES[0], 3)], np.flatnonzero(c.family == 0))
    assert c.family_name(int(cells[(FAMILIES[1], 2)][0])) == FAMILIES[1]


def test_bad_arguments():
    with pytest.raises(ValueError):
        make(4, start_level=11)
    with pytest.raises(ValueError):
        make(4, promote_threshold=0.3, demote_threshold=0.6)
    c = make(4)
    with pytest.raises(ValueError, match="distinct"):
        c.update([1, 1], [True, False])
    with pytest.raises(ValueError, match="lie in"):
        c.update([4], [True])
    c.update([], [])


def test_moved_levels_is_one_rule_for_numpy_and_torch():
    import torch

    from frbench.training.curriculum import moved_levels

    rng = np.random.default_rng(3)
    level = rng.integers(1, 11, 400)
    episodes = rng.integers(0, 5, 400)
    successes = np.minimum(rng.integers(0, 5, 400), episodes)
    drawn = rng.integers(1, 11, 400)

    def rule(lv, s, e, pick):
        return moved_levels(lv, s, e, lambda over: pick, promote=0.6, demote=0.3, max_level=10)

    got_np = rule(level, successes, episodes, drawn)
    got_torch = rule(*(torch.as_tensor(a) for a in (level, successes, episodes, drawn)))
    np.testing.assert_array_equal(got_torch.numpy(), got_np)
    rate = successes / np.maximum(episodes, 1)
    expected = level + (rate >= 0.6) - ((rate < 0.3) & (rate < 0.6))
    expected = np.clip(np.where(expected > 10, drawn, expected), 1, 10)
    np.testing.assert_array_equal(got_np, expected)
    assert (level + (rate >= 0.6) > 10).sum() > 0  # the redraw branch is exercised


def test_successes_from_a_device_move_the_one_curriculum_as_numpys_do_redraw_included():
    """The device trainer hands the curriculum its successes as torch tensors once per episode: the same class moves
    the same levels as with numpy successes, from the same generator (the top level's redraw included), and its
    state is the same."""
    import torch

    host, device = make(32, seed=5), make(32, seed=5)
    rng = np.random.default_rng(9)
    redrawn = 0
    for _ in range(150):  # success rate 0.7: levels reach the top and are redrawn from there
        judged = np.flatnonzero(rng.random(32) < 0.5)
        success = rng.random(judged.size) < 0.7
        at_top = host.level[judged] == host.max_level
        host.update(judged, success)
        device.update(torch.as_tensor(judged), torch.as_tensor(success))
        redrawn += int((at_top & success).sum())
        np.testing.assert_array_equal(device.level, host.level)
    assert redrawn > 10
    assert device.state_dict() == host.state_dict()
