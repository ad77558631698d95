"""Shared fixtures: an isolated cache and config per test session, and URDF builders."""

from __future__ import annotations

import os

import pytest

# headless rendering: MuJoCo reads this when first imported, which a test may do before `frbench render` runs
os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Generated simulation URDFs go to a per-session cache (unless FRBENCH_CACHE is set)."""
    os.environ.setdefault("FRBENCH_CACHE", str(tmp_path_factory.mktemp("cache")))
    yield


@pytest.fixture(autouse=True)
def _isolated_config(tmp_path, monkeypatch):
    """Each test sees an empty user config (robots added with ``frbench robot add``)."""
    monkeypatch.setenv("FRBENCH_CONFIG", str(tmp_path / "config"))
    yield


@pytest.fixture
def quadruped_urdf_text() -> str:
    """A valid primitive quadruped URDF (the morphology generator's Go2-like default)."""
    from frbench.robots.morphology import MorphologyParams
    from frbench.robots.morphology_urdf import urdf_string

    return urdf_string(MorphologyParams(), name="testdog")
