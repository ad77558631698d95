"""Layers point down: robots/ runs no simulator, policies/ loads no training code, the networks sit below both."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from rsl_rl.utils import resolve_callable

from frbench.networks.models import EstimatorActor, RMAActor
from frbench.policies.learned import current_class_path
from frbench.robot_checks.lookup import get_robot as simulated_robot
from frbench.robot_checks.standing import measured_height
from frbench.robots import get_robot
from frbench.robots.paths import example_robot_data


def _loaded_after(code: str, prefixes: tuple[str, ...], cache=None) -> list[str]:
    """The modules starting with any of ``prefixes`` that a fresh interpreter has loaded after running ``code``
    (with frbench's cache in ``cache``, if given)."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    env = dict(os.environ, **({"FRBENCH_CACHE": str(cache)} if cache else {}))
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True, env=env).stdout
    return [m for m in json.loads(out.splitlines()[-1]) if m.startswith(prefixes)]


def test_the_robots_package_imports_and_runs_no_simulator_and_no_layer_above_it(tmp_path):
    urdf = str(example_robot_data("solo_description/robots/solo12.urdf"))
    code = ("import pkgutil, importlib, frbench.robots\n"
            "for m in pkgutil.iter_modules(frbench.robots.__path__): importlib.import_module('frbench.robots.' + m.name)\n"
            f"frbench.robots.get_robot({urdf!r})")
    # MuJoCo's compiler fits primitives to meshes for the simulation URDF (`frbench.robots.sim_urdf`): it may load
    above = ("frbench.backends", "frbench.tasks", "frbench.robot_checks", "frbench.policies", "frbench.training",
             "frbench.evaluation", "pybullet")
    assert _loaded_after(code, above, tmp_path) == []  # an empty cache: no standing height measured before
    assert "frbench.robots.infer" in _loaded_after(code, ("frbench.robots.",), tmp_path)


def test_policies_and_networks_load_no_training_code():
    code = "import frbench.policies.learned, frbench.policies.registry, frbench.policies.checkpoint, frbench.networks.models"
    assert _loaded_after(code, ("frbench.training", "frbench.evaluation", "frbench.commands")) == []


def test_run_configs_naming_the_former_actor_module_still_resolve():
    assert current_class_path("frbench.training.models:EstimatorActor") == "frbench.networks.models:EstimatorActor"
    assert current_class_path("rsl_rl.models:MLPModel") == "rsl_rl.models:MLPModel"
    assert resolve_callable("frbench.training.models:EstimatorActor") is EstimatorActor  # rsl-rl on --resume
    assert resolve_callable(current_class_path("frbench.training.models:RMAActor")) is RMAActor


def test_a_robot_by_path_gets_its_measured_height_above_the_backends(tmp_path):
    urdf = str(example_robot_data("solo_description/robots/solo12.urdf"))
    derived = get_robot(urdf)
    assert dict(derived.extra)["height_source"] == "kinematic"
    assert derived.nominal_height == pytest.approx(float(dict(derived.extra)["kinematic_height"]), abs=1e-6)
    simulated = simulated_robot(urdf)
    settled = measured_height(derived)
    assert dict(simulated.extra)["height_source"] == "measured"
    assert json.loads(dict(simulated.extra)["standing"]) == settled
    assert simulated.nominal_height == settled["nominal_height"]
    assert abs(simulated.nominal_height - derived.nominal_height) > 1e-3  # solo12 settles 9 mm above its kinematic height
    assert simulated_robot("go2") == get_robot("go2")


def test_a_sidecar_height_is_kept_without_measuring(tmp_path, quadruped_urdf_text):
    path = tmp_path / "dog.urdf"
    path.write_text(quadruped_urdf_text)
    (tmp_path / "dog.frbench.toml").write_text("nominal_height = 0.31\n")
    spec = simulated_robot(str(path))
    assert spec.nominal_height == 0.31 and dict(spec.extra)["height_source"] == "sidecar"
    assert "standing" not in dict(spec.extra)
