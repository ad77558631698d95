"""frbench's cache of slow, input-determined results: compiled models, feasibility answers."""

from __future__ import annotations

import numpy as np

from frbench.backends.mujoco_model import build_model, build_spec
from frbench.content_cache import cache_path, cached_bytes, content_key
from frbench.robots import get_robot
from frbench.terrains import make_terrain


def test_a_cached_model_equals_a_fresh_compile_field_by_field(tmp_path, monkeypatch):
    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path))
    spec, terrain = get_robot("go2"), make_terrain("stairs", 5, 0)
    build_model(spec, terrain)  # fills the cache
    assert len(list((tmp_path / "mujoco-models").glob("*.mjb"))) == 1
    cached, fresh = build_model(spec, terrain), build_spec(spec, terrain).compile()
    arrays = [n for n in dir(fresh) if isinstance(getattr(fresh, n, None), np.ndarray)]
    assert len(arrays) > 100
    assert [n for n in arrays if not np.array_equal(getattr(cached, n), getattr(fresh, n), equal_nan=True)] == []
    build_model(spec, terrain, friction=0.5)  # another input, another entry
    assert len(list((tmp_path / "mujoco-models").glob("*.mjb"))) == 2


def test_a_damaged_entry_is_computed_again(tmp_path, monkeypatch):
    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path))
    key = content_key("answer", 1)
    calls = []
    compute = lambda: calls.append(1) or b"42"  # noqa: E731
    assert cached_bytes("test", key, ".txt", compute, lambda b: int(b)) == 42
    assert cached_bytes("test", key, ".txt", compute, lambda b: int(b)) == 42 and len(calls) == 1
    cache_path("test", key, ".txt").write_bytes(b"not a number")
    assert cached_bytes("test", key, ".txt", compute, lambda b: int(b)) == 42 and len(calls) == 2
    assert content_key("answer", 1) != content_key("answer", 1.0) != content_key("answer", 2)


def test_feasibility_is_answered_from_the_cache_the_second_time(tmp_path, monkeypatch):
    from frbench.training import feasibility

    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path))
    spec = get_robot("go2")
    assert feasibility.can_stand(spec, 50.0, 1.0)
    monkeypatch.setattr(feasibility, "_stands", lambda *a: (_ for _ in ()).throw(AssertionError("simulated")))
    assert feasibility.can_stand(spec, 50.0, 1.0)  # no simulation: the cached answer
