"""The backends: conventions, cross-simulator agreement, standing, determinism, divergence (PhysX's own tests:
tests/test_physx_backend.py)."""

from __future__ import annotations

import importlib.util
import re

import numpy as np
import pytest

from frbench.backends import make_backend
from frbench.backends.base import PhysicsParams, RobotState
from frbench.robots import get_robot, ground_truth
from frbench.robot_checks.check import check_robot, random_configurations, stand_test

BUILTIN = ("go2", "go1", "aliengo", "spot_like", "lite3_like", "g1")
BACKENDS = ("mujoco", "pybullet")
#: The backends the protocol's convention tests run on: PhysX too where the physx extra is installed.
PROTOCOL_BACKENDS = BACKENDS + (("physx",) if importlib.util.find_spec("sapien") else ())


@pytest.mark.parametrize("name", BUILTIN)
def test_mass_and_com_agree_across_pinocchio_mujoco_pybullet(name):
    report = check_robot(get_robot(name), n_random=3, stand=False)
    assert report.max_mass_error < 1e-6
    assert report.max_com_error < 1e-4
    assert set(report.mass) == {"pinocchio", "mujoco", "pybullet"}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", BUILTIN)
def test_robot_stands_on_its_pd_for_two_seconds(name, backend):
    result = stand_test(get_robot(name), backend)
    assert abs(result["height"] - result["nominal_height"]) <= 0.10 * result["nominal_height"], result
    assert abs(result["force_z"] - result["weight"]) <= 0.05 * result["weight"], result
    assert result["ok"], result["reason"]


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_state_round_trips_through_reset(backend):
    """Root frame pose, world linear and body angular velocity come back as they were set.

    (PyBullet passes orientations through single precision, PhysX its whole state: 1e-6.)
    """
    ATOL = 1e-6
    spec = get_robot("go2")
    rng = np.random.default_rng(3)
    pos, quat, q = random_configurations(spec, rng, 3)
    state = RobotState.at_rest(pos, quat, q)
    state.base_linvel = rng.normal(size=(3, 3))
    state.base_angvel = rng.normal(size=(3, 3))
    state.qd = rng.normal(size=(3, 12))
    sim = make_backend(backend, spec, 3)
    sim.reset(np.arange(3), state)
    out = sim.state()
    sim.close()
    np.testing.assert_allclose(out.base_pos, state.base_pos, atol=ATOL)
    sign = np.sign(np.sum(out.base_quat * state.base_quat, axis=1, keepdims=True))
    np.testing.assert_allclose(out.base_quat * sign, state.base_quat, atol=ATOL)
    np.testing.assert_allclose(out.base_linvel, state.base_linvel, atol=ATOL)
    np.testing.assert_allclose(out.base_angvel, state.base_angvel, atol=ATOL)
    np.testing.assert_allclose(out.q, state.q, atol=ATOL)
    np.testing.assert_allclose(out.qd, state.qd, atol=ATOL)


def _rollout(backend: str, spec, steps: int = 25) -> np.ndarray:
    rng = np.random.default_rng(11)
    sim = make_backend(backend, spec, 2)
    pos, quat, q = random_configurations(spec, rng, 2)
    pos[:, 2] = 0.5
    sim.reset(np.arange(2), RobotState.at_rest(pos, quat, q))
    trace = []
    for _ in range(steps):
        sim.step(rng.uniform(spec.joint_lower, spec.joint_upper, size=(2, spec.n_joints)))
        s = sim.state()
        trace.append(np.concatenate([s.base_pos, s.base_quat, s.q, s.qd], axis=1))
    sim.close()
    return np.array(trace)


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_same_inputs_give_identical_trajectories(backend):
    spec = get_robot("go1")
    first, second = _rollout(backend, spec), _rollout(backend, spec)
    assert np.array_equal(first, second)
    assert np.abs(first[-1] - first[0]).max() > 0.1  # it did move


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_contacts_of_a_robot_lying_on_its_back(backend):
    spec = get_robot("go2")
    sim = make_backend(backend, spec, 1)
    state = RobotState.at_rest([[0, 0, 0.12]], [0.0, 1.0, 0.0, 0.0], [spec.default_pose])  # upside down
    sim.reset([0], state)
    for _ in range(40):
        sim.step(np.asarray(spec.default_pose)[None])
    contacts = sim.contacts()
    sim.close()
    assert contacts.group_contact[0, 0]  # the base touches the ground
    assert not contacts.foot_contact[0].any()
    weight = ground_truth.total_mass(spec) * 9.81
    assert contacts.link_force[0, :, 2].sum() == pytest.approx(weight, rel=0.05)
    assert contacts.body_force_max[0] > 0.5 * weight


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_a_diverging_simulation_does_not_stop_the_others(backend):
    spec = get_robot("go2")
    sim = make_backend(backend, spec, 2)
    state = RobotState.standing(spec, 2)
    state.qd[1, 0] = np.nan  # a simulation gone bad
    sim.reset(np.arange(2), state)
    for _ in range(5):
        sim.step(np.tile(spec.default_pose, (2, 1)))
    assert sim.diverged.tolist() == [False, True]
    assert np.all(np.isfinite(sim.state().base_pos[0]))
    sim.reset([1], RobotState.standing(spec, 1))
    assert not sim.diverged[1]
    sim.close()


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_per_simulation_friction_gains_and_payload(backend):
    spec = get_robot("go2")
    sim = make_backend(backend, spec, 2)
    params = PhysicsParams.nominal(spec, 2)
    params.payload = np.array([0.0, 2.0])
    params.friction = np.array([1.0, 0.05])
    sim.set_params(params)
    state = RobotState.standing(spec, 2)
    sim.reset(np.arange(2), state)
    masses, _ = sim.mass_properties()
    np.testing.assert_allclose(masses, [16.085, 18.085], atol=2e-6 if backend == "physx" else 1e-9)  # float32
    state.base_linvel[:, 0] = 1.0  # slide forward
    sim.reset(np.arange(2), state)
    for _ in range(10):
        sim.step(np.tile(spec.default_pose, (2, 1)))
    x = sim.state().base_pos[:, 0]
    sim.close()
    assert x[1] > x[0] + 0.02  # the slippery one slides further


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_wrong_target_shape_is_refused(backend):
    sim = make_backend(backend, get_robot("go2"), 2)
    with pytest.raises(ValueError, match=re.escape("joint targets of shape (2, 11), expected (2, 12)")):
        sim.step(np.zeros((2, 11)))
    sim.close()


def test_pd_torque_is_clipped_to_the_effort_limit():
    spec = get_robot("go2")
    for backend in PROTOCOL_BACKENDS:
        sim = make_backend(backend, spec, 1)
        sim.reset([0], RobotState.at_rest([[0, 0, 1.0]], [1, 0, 0, 0], [spec.default_pose]))
        sim.step(np.asarray(spec.joint_upper)[None])  # far from every joint
        tau = sim.state().tau[0]
        sim.close()
        assert np.all(np.abs(tau) <= np.asarray(spec.torque_limits) + 1e-9), backend
        assert np.any(np.isclose(np.abs(tau), spec.torque_limits)), backend


def test_actuator_torque_with_motor_friction_by_hand():
    from frbench.backends.base import MOTOR_FRICTION_VELOCITY, actuator_torque

    spec = get_robot("go2")
    params = PhysicsParams.nominal(spec, 2)
    params.kp[:] = 40.0
    params.kd[:] = 1.0
    params.motor_friction = np.full((2, 12), 0.5)
    q, qd, target = np.zeros((2, 12)), np.full((2, 12), 0.2), np.full((2, 12), 0.1)
    limits = np.asarray(spec.torque_limits)
    # 40·0.1 − 1·0.2 = 3.8 N·m, minus 0.5·clip(0.2 / 0.1, ±1) = 0.5 N·m (saturated)
    expected = 3.8 - 0.5 * np.clip(0.2 / MOTOR_FRICTION_VELOCITY, -1, 1)
    assert expected == pytest.approx(3.3)
    np.testing.assert_allclose(actuator_torque(params, limits, target, q, qd), expected)
    np.testing.assert_allclose(actuator_torque(params, limits, target, q, qd / 4), 4.0 - 0.05 - 0.25)  # linear below v_f
    np.testing.assert_allclose(actuator_torque(params, limits, target[1], q[1], qd[1], 1), expected)
    params.motor_friction = None
    np.testing.assert_allclose(actuator_torque(params, limits, target, q, qd), 3.8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_motor_friction_slows_a_limp_robot_collapsing(backend):
    spec = get_robot("go2")
    sim = make_backend(backend, spec, 2)
    params = PhysicsParams.nominal(spec, 2)
    params.kp[:], params.kd[:] = 0.0, 0.0  # limp: the standing robot folds under its weight
    # 2 N·m (training draws 0.2-1.25): the explicit friction's slope f / v_f = 20 N·m·s/rad is near what the
    # lightest joints bear at dt 5 ms; at 5 N·m the calves chatter (in MuJoCo after 2 control steps)
    params.motor_friction = np.array([np.zeros(12), np.full(12, 2.0)])
    sim.set_params(params)
    sim.reset(np.arange(2), RobotState.standing(spec, 2, clearance=0.0))
    for _ in range(3):
        sim.step(np.tile(spec.default_pose, (2, 1)))
    speed = np.abs(sim.state().qd).mean(axis=1)
    sim.close()
    assert speed[1] < 0.8 * speed[0], speed  # 2 N·m of friction per joint holds the fold back


def _numpy_pd_reference(spec, params, targets, start, steps):
    """The same fall with the PD of `actuator_torque` in numpy, fed to MuJoCo as raw motor torques at every
    physics step (MuJoCo computing no actuation of its own): joint positions (steps, N, J)."""
    import mujoco

    from frbench.backends.base import actuator_torque
    from frbench.backends.mujoco_model import build_model, joint_addresses
    from frbench.terrains import make_terrain

    model = build_model(spec, make_terrain("flat", 1, 0))
    j = spec.n_joints
    model.actuator_gainprm[:] = 0.0
    model.actuator_biasprm[:] = 0.0
    model.actuator_gainprm[:j, 0] = 1.0  # force = ctrl
    model.actuator_forcerange[:] = [-1e9, 1e9]
    qadr, dadr = joint_addresses(model, spec)
    limits = np.asarray(spec.torque_limits)
    out = np.zeros((steps, len(targets), j))
    for i in range(len(targets)):
        data = mujoco.MjData(model)
        data.qpos[0:3], data.qpos[3:7], data.qpos[qadr] = start.base_pos[i], start.base_quat[i], start.q[i]
        for k in range(steps):
            for _ in range(4):
                data.ctrl[:j] = actuator_torque(params, limits, targets[i], data.qpos[qadr], data.qvel[dadr], i)
                mujoco.mj_step(model, data)
            out[k, i] = data.qpos[qadr]
    return out


def test_native_actuators_match_the_numpy_pd_in_a_contact_free_fall():
    """MuJoCo's own PD + motor-friction actuators, per-simulation gains, strength and friction, one batch call
    per control step, against the explicit numpy PD at every physics step: equal to ~1e-9 over 10 steps."""
    spec, n = get_robot("go2"), 3
    rng = np.random.default_rng(0)
    params = PhysicsParams.nominal(spec, n)
    params.kp, params.kd = rng.uniform(20, 80, (n, 12)), rng.uniform(0.5, 2.0, (n, 12))
    params.motor_strength, params.motor_friction = rng.uniform(0.9, 1.1, (n, 12)), rng.uniform(0.2, 1.25, (n, 12))
    start = RobotState.at_rest(np.tile([0.0, 0.0, 1.5], (n, 1)), [1, 0, 0, 0], np.tile(spec.default_pose, (n, 1)))
    targets = start.q + rng.uniform(-0.5, 0.5, (n, 12))  # a big step: some torques clip
    sim = make_backend("mujoco", spec, n)
    sim.set_params(params)
    sim.reset(np.arange(n), start)
    q = []
    for _ in range(10):
        sim.step(targets)
        q.append(sim.state().q)
    assert not sim.contacts().group_contact.any()  # still in the air
    sim.close()
    reference = _numpy_pd_reference(spec, params, targets, start, 10)
    assert np.abs(np.array(q) - reference).max() < 1e-8
    assert np.abs(np.array(q)[-1] - start.q).max() > 0.1  # the joints did move


@pytest.mark.parametrize("backend", PROTOCOL_BACKENDS)
def test_whole_body_com_matches_pinocchio_along_a_motion(backend):
    spec, n = get_robot("go2"), 3
    rng = np.random.default_rng(2)
    quat = rng.normal(size=(n, 4))
    sim = make_backend(backend, spec, n)
    params = PhysicsParams.nominal(spec, n)
    params.payload = np.array([0.0, 1.5, -1.0])
    sim.set_params(params)
    sim.reset(np.arange(n), RobotState.at_rest(np.tile([0.0, 0.0, 0.5], (n, 1)), quat,
                                               spec.default_pose + rng.uniform(-0.4, 0.4, (n, 12))))
    import pinocchio

    robot = ground_truth.load(spec)
    data = robot.model.createData()
    total = sum(ground_truth.group_masses(spec))

    for _ in range(3):
        sim.step(np.tile(spec.default_pose, (n, 1)))
        s = sim.state()
        com = sim.whole_body_com()
        for i in range(n):
            config = ground_truth.configuration(robot, s.base_pos[i], s.base_quat[i], s.q[i])
            expected = np.asarray(pinocchio.centerOfMass(robot.model, data, config))
            if params.payload[i]:  # the payload sits at the root link's CoM
                base_com = data.oMi[1].act(robot.model.inertias[1].lever)
                expected = (expected * total + params.payload[i] * base_com) / (total + params.payload[i])
            np.testing.assert_allclose(com[i], expected, atol=1e-6)
    sim.close()


def test_morphology_variants_run_as_if_built_alone():
    """Variants as expanded fields of one batch: bit-identical to each robot's own backend, gains and all."""
    from frbench.training.randomization import morphology_specs, sample_morphologies

    specs = morphology_specs(sample_morphologies(2, np.random.default_rng(3)))
    assignment = np.array([1, 0, 1])
    sim = make_backend("mujoco", specs[0], 3, variants=(specs, assignment, np.ones(2), np.zeros(2)))
    params = PhysicsParams.nominal(specs[0], 3)
    params.kp[:] = np.array([[50.0], [60.0], [70.0]])
    params.motor_friction = np.full((3, 12), 0.5)
    sim.set_params(params)
    starts = [RobotState.standing(specs[k], 1) for k in assignment]
    sim.reset(np.arange(3), RobotState(**{f: np.concatenate([getattr(s, f) for s in starts])
                                          for f in ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")}))
    masses, _ = sim.mass_properties()
    np.testing.assert_allclose(masses, [sum(ground_truth.group_masses(specs[k])) for k in assignment], rtol=1e-9)
    targets = np.tile(specs[0].default_pose, (3, 1)) + 0.2
    for _ in range(5):
        sim.step(targets)
    together = sim.state()
    sim.close()
    for i, k in enumerate(assignment):
        alone = make_backend("mujoco", specs[k], 1)
        row = slice(i, i + 1)
        alone.set_params(PhysicsParams(params.kp[row], params.kd[row], params.motor_strength[row],
                                       params.friction[row], params.payload[row], params.motor_friction[row]))
        alone.reset([0], starts[i])
        for _ in range(5):
            alone.step(targets[i:i + 1])
        np.testing.assert_array_equal(alone.state().q[0], together.q[i])
        np.testing.assert_array_equal(alone.state().base_pos[0], together.base_pos[i])
        alone.close()


@pytest.mark.parametrize("variants", [False, True])
def test_mujoco_whole_body_com_is_the_batch_position_stage_bit_for_bit(variants):
    """The robot-only batch (`frbench.backends.mujoco_com`) gives the simulation batch's own ``subtree_com`` at the
    current state, with morphology variants, their payloads and frictions, or payloads set per episode."""
    import mujoco

    from frbench.terrains import make_terrain
    from frbench.training.randomization import morphology_specs, sample_morphologies

    n = 4
    if variants:
        specs = morphology_specs(sample_morphologies(2, np.random.default_rng(5)))
        variant = (specs, np.array([1, 0, 1, 0]), np.array([0.7, 1.2]), np.array([1.5, -0.5]))
        sim = make_backend("mujoco", specs[0], n, terrain=make_terrain("stairs", 3, 0), variants=variant)
        spec = specs[0]
    else:
        spec = get_robot("go2")
        sim = make_backend("mujoco", spec, n, terrain=make_terrain("rough", 4, 0))
        params = PhysicsParams.nominal(spec, n)
        params.payload = np.array([0.0, 2.0, -1.0, 0.5])
        sim.set_params(params)
    rng = np.random.default_rng(6)
    sim.reset(np.arange(n), RobotState.at_rest(np.tile([0.0, 0.0, 0.6], (n, 1)), rng.normal(size=(n, 4)),
                                               spec.default_pose + rng.uniform(-0.4, 0.4, (n, 12))))
    subtree_com = sim.batch.bind("subtree_com")
    for _ in range(4):
        sim.step(np.tile(spec.default_pose, (n, 1)))
        com = sim.whole_body_com()
        sim.batch.forward(stage=mujoco.mjtStage.mjSTAGE_POS)  # the batch's own position stage at this state
        assert com.tobytes() == subtree_com[:, sim._root_body].tobytes()
    sim.close()
