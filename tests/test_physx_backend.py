"""The ``physx`` backend (PhysX 5 through SAPIEN, the ``physx`` extra): the self-collision groups, the scene's
settings, velocities, mass properties against Pinocchio, agreement with MuJoCo (drops, motor friction),
determinism, the base force, and the commands that take it (evaluate, robot check, the Gymnasium env). The
protocol's convention tests that every backend passes (state round trip, contacts, divergence, friction and
payload, torque limits, whole-body CoM) run on PhysX in tests/test_backends.py."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("sapien") is None,
                                reason="the physx extra (sapien) is not installed")

from frbench.backends import make_backend  # noqa: E402
from frbench.backends.base import PhysicsParams, RobotState  # noqa: E402
from frbench.backends.hold import DROP_TESTS, drop_height  # noqa: E402
from frbench.cli import main  # noqa: E402
from frbench.robot_checks.check import check_robot, stand_test  # noqa: E402
from frbench.robots import get_robot, ground_truth  # noqa: E402
from frbench.robots.sim_urdf import SimRobotFile  # noqa: E402

BUILTIN = ("go2", "go1", "aliengo", "spot_like", "lite3_like", "g1")


@pytest.fixture(scope="module")
def go2():
    return get_robot("go2")


def _tree(parent: dict[str, str | None]) -> SimRobotFile:
    return SimRobotFile(path=Path("tree.urdf"), sha256="", source_sha256="", links=tuple(parent),
                        parent=tuple(parent.items()), masses=tuple((link, 1.0) for link in parent))


def test_collision_bits_ignore_exactly_the_ancestor_and_excluded_pairs():
    from frbench.backends.physx_scene import collision_bits

    sim = _tree({"base": None, "a1": "base", "a2": "a1", "a3": "a2", "b1": "base", "b2": "b1", "c1": "base"})
    excluded = {("a1", "b1"), ("a2", "base")}  # one pair across chains, one ancestor pair (already covered)
    bits, used = collision_bits(sim, sorted(excluded))
    assert used == 3 + 1  # three leaves, one pair across chains
    for a in sim.links:
        for b in sim.links:
            if a < b:
                related = a in sim.ancestors(b) or b in sim.ancestors(a) or (a, b) in excluded or (b, a) in excluded
                assert bool(bits[a] & bits[b]) == related, (a, b)


def test_a_robot_needing_more_collision_groups_than_sapien_has_is_refused(monkeypatch, go2):
    from frbench.backends import physx_scene
    from frbench.errors import FrbenchError

    star = _tree({"base": None, **{f"leg{k}": "base" for k in range(40)}})
    assert physx_scene.collision_bits(star, [])[1] == 40 > physx_scene.COLLISION_BITS
    assert physx_scene.physx_refusal(go2) is None  # Go2: 4 legs + 1 pair of rear hips = 5 groups
    monkeypatch.setattr(physx_scene, "COLLISION_BITS", 4)
    assert physx_scene.physx_refusal(go2) == ("robot 'go2' needs 5 self-collision groups (one per root-to-leaf chain "
                                              "and per excluded link pair that is not an ancestor pair); SAPIEN's "
                                              "collision filter has 4")
    with pytest.raises(FrbenchError, match="backend physx: robot 'go2' needs 5 self-collision groups"):
        make_backend("physx", go2, 1)


def test_the_scene_is_deterministic_tgs_4_0_and_leaves_sapiens_global_config_as_it_was(go2):
    from frbench.backends.physx_scene import import_sapien

    sapien = import_sapien()
    before = sapien.physx.get_scene_config().enable_enhanced_determinism
    sim = make_backend("physx", go2, 1)
    config = sim.sims[0].scene.physx_system.config
    assert config.enable_enhanced_determinism and config.enable_tgs
    assert sim.sims[0].robot.get_solver_position_iterations() == 4  # legged_gym's TGS 4 / 0
    assert sim.sims[0].robot.get_solver_velocity_iterations() == 0
    assert sapien.physx.get_scene_config().enable_enhanced_determinism == before
    sim.close()


def test_velocities_are_the_root_origins_in_world_and_body_frames(go2):
    """A pitched robot spinning about its body x axis in free fall: after one control step PhysX's base velocities
    (converted from its CoM's, world-frame ones) are MuJoCo's (the root origin's in the world frame, the angular
    one in the body frame) to 5 mm/s; reading PhysX's CoM velocity unconverted would be 60 mm/s off."""
    quat = np.array([np.cos(0.4), 0.0, np.sin(0.4), 0.0])  # pitched 0.8 rad
    state = RobotState.at_rest([[0.0, 0.0, 3.0]], quat, [go2.default_pose])
    state.base_angvel[0] = [3.0, 0.0, 0.0]
    state.base_linvel[0] = [0.5, 0.0, 0.0]
    after = {}
    for name in ("physx", "mujoco"):
        sim = make_backend(name, go2, 1)
        sim.reset([0], state)
        sim.step(np.asarray(go2.default_pose)[None])
        after[name] = sim.state()
        sim.close()
    np.testing.assert_allclose(after["physx"].base_linvel, after["mujoco"].base_linvel, atol=0.005)
    np.testing.assert_allclose(after["physx"].base_angvel, after["mujoco"].base_angvel, atol=0.005)
    assert np.abs(after["physx"].base_angvel[0] - [3.0, 0.0, 0.0]).max() < 0.05


@pytest.mark.parametrize("name", BUILTIN)
def test_mass_and_com_agree_with_pinocchio(name):
    report = check_robot(get_robot(name), n_random=3, stand=False, backends=("physx",))
    assert report.max_mass_error < 1e-6  # float32 masses: 4.8e-7 kg on the G1
    assert report.max_com_error < 1e-6
    assert set(report.mass) == {"pinocchio", "physx"}


@pytest.mark.parametrize("name", ("go2", "g1"))
def test_robot_stands_on_its_pd_for_two_seconds(name):
    result = stand_test(get_robot(name), "physx")
    assert abs(result["height"] - result["nominal_height"]) <= 0.05 * result["nominal_height"], result
    assert abs(result["force_z"] - result["weight"]) <= 0.02 * result["weight"], result
    assert result["ok"], result["reason"]


@pytest.mark.parametrize("drop", DROP_TESTS)
def test_drops_settle_where_the_other_simulators_settle(go2, drop):
    """Go2 holding its default pose, dropped; the base height after 2 s: PhysX within 5 mm of PyBullet (the other
    rigid-contact engine) and 1.5 cm of MuJoCo (soft contacts: it sinks further into the step's edge). Measured
    PhysX / MuJoCo / PyBullet: 0.311 / 0.305 / 0.309, 0.168 / 0.168 / 0.168, 0.354 / 0.343 / 0.352 m
    (benchmarks/physx_agreement.py, docs/physx.md)."""
    heights = {name: drop_height(go2, name, drop) for name in ("physx", "mujoco", "pybullet")}
    assert abs(heights["physx"] - heights["pybullet"]) < 0.005, heights
    assert abs(heights["physx"] - heights["mujoco"]) < 0.015, heights
    assert heights["physx"] > 0.15, heights


def test_a_cell_runs_bit_identically_twice():
    """What ``frbench verify`` relies on: the same cell (policy, robot, terrain, level, seed) gives identical
    episode records, continuous metrics included."""
    from frbench.evaluation.runner import Cell, run_cell

    cell = Cell("go1", "physx", "rough", 5, 0, 2)
    first, second = run_cell(cell, "scripted"), run_cell(cell, "scripted")
    assert first == second
    assert all(episode["max_displacement"] > 0.01 for episode in first)  # the robots did move


def test_motor_friction_brakes_spinning_joints_as_in_mujoco(go2):
    """A limp robot in the air with its joints spinning at 2 rad/s, 0.5 N·m of motor friction on one: after a
    control step its joint speeds are MuJoCo's (the actuator formula is every backend's) to 5e-3 rad/s, and the
    friction took up to 1.9 rad/s off."""
    qd = {}
    for name in ("physx", "mujoco"):
        sim = make_backend(name, go2, 2)
        params = PhysicsParams.nominal(go2, 2)
        params.kp[:], params.kd[:] = 0.0, 0.0
        params.motor_friction = np.array([np.zeros(12), np.full(12, 0.5)])
        sim.set_params(params)
        start = RobotState.standing(go2, 2, clearance=1.0)
        start.qd[:] = 2.0
        sim.reset(np.arange(2), start)
        sim.step(np.tile(go2.default_pose, (2, 1)))
        qd[name] = sim.state().qd
        sim.close()
    np.testing.assert_allclose(qd["physx"], qd["mujoco"], atol=5e-3)
    assert (qd["physx"][0] - qd["physx"][1]).max() > 1.8


def test_base_force_carries_the_robots_weight(go2):
    """An upward base force of m·g holds a robot in the air: its whole-body CoM stays within 2 mm over 0.2 s
    while the other falls 0.2 m; the force is no contact."""
    sim = make_backend("physx", go2, 2)
    weight = ground_truth.total_mass(go2) * 9.81
    sim.set_base_force(np.array([[0.0, 0.0, weight], [0.0, 0.0, 0.0]]))
    sim.reset(np.arange(2), RobotState.at_rest(np.tile([0.0, 0.0, 2.0], (2, 1)), [1, 0, 0, 0],
                                               np.tile(go2.default_pose, (2, 1))))
    before = sim.whole_body_com()
    for _ in range(10):
        sim.step(np.tile(go2.default_pose, (2, 1)))
    drop = before[:, 2] - sim.whole_body_com()[:, 2]
    assert not sim.contacts().group_contact.any() and not sim.contacts().foot_contact.any()
    sim.close()
    assert abs(drop[0]) < 0.002 and drop[1] == pytest.approx(0.5 * 9.81 * 0.2**2, abs=0.01), drop


def test_evaluate_scores_physx_beside_mujoco(tmp_path, capsys):
    from frbench.schemas import validate

    out = tmp_path / "r.json"
    assert main(["evaluate", "--policy", "scripted", "--robots", "go2", "--terrains", "flat", "--levels", "1",
                 "--seeds", "0", "--episodes", "2", "--backends", "mujoco,physx", "--jobs", "1",
                 "--out", str(out)]) == 0
    results = json.loads(out.read_text())
    validate(results, "results-v1")
    assert {c["backend"] for c in results["cells"]} == {"mujoco", "physx"}
    assert "refused" not in results["config"]
    assert results["versions"]["sapien"] == "3.0.3"
    physx = [e for e in results["episodes"] if e["backend"] == "physx"]
    assert len(physx) == 2 and not any(e["diverged"] for e in physx)


def test_a_robot_physx_refuses_loses_its_physx_cells_only_and_exits_2(tmp_path, capsys, monkeypatch):
    from frbench.backends import physx_scene
    from frbench.schemas import validate

    monkeypatch.setattr(physx_scene, "COLLISION_BITS", 4)  # Go2 needs 5
    out = tmp_path / "r.json"
    argv = ["evaluate", "--policy", "zero", "--robots", "go2", "--terrains", "flat", "--levels", "1", "--seeds", "0",
            "--episodes", "1", "--jobs", "1", "--out", str(out)]
    assert main([*argv, "--backends", "mujoco,physx"]) == 2
    err = capsys.readouterr().err
    assert "frbench evaluate: robot 'go2' does not run in physx: robot 'go2' needs 5 self-collision groups" in err
    results = json.loads(out.read_text())
    validate(results, "results-v1")
    assert [c["backend"] for c in results["cells"]] == ["mujoco"]
    assert "needs 5 self-collision groups" in results["config"]["refused"]["physx"]["go2"]
    out.unlink()
    assert main([*argv, "--backends", "physx"]) == 2  # nothing can run: a one-line error, nothing written
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("frbench evaluate: error: no cell of the grid can run: physx: robot")
    assert not out.exists()


def test_robot_check_in_physx(capsys):
    assert main(["robot", "check", "go2", "--backends", "physx"]) == 0
    out = capsys.readouterr().out
    assert "total mass  physx" in out and "standing    physx" in out and "OK" in out
    assert main(["robot", "check", "go2", "--backends", "physics"]) == 2


def test_a_robot_by_path_runs_in_physx(tmp_path, quadruped_urdf_text):
    urdf = tmp_path / "testdog.urdf"
    urdf.write_text(quadruped_urdf_text)
    spec = get_robot(str(urdf))
    result = stand_test(spec, "physx")
    assert result["ok"], result["reason"]


def test_the_gymnasium_env_steps_in_physx():
    import gymnasium

    import frbench.gym  # noqa: F401  (registers)
    from frbench.gym import ENV_ID

    env = gymnasium.make(ENV_ID, robot="go2", backend="physx")
    try:
        obs, _ = env.reset(seed=0)
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    finally:
        env.close()
