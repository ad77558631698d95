"""The ``mujoco-warp`` backend (the ``gpu`` extra) against MuJoCo C, on Warp's CPU device here: the same model,
actuation, contacts and per-world parameters; divergence and buffer overflows flagged. Few worlds, few steps
(Warp's kernels compile once per machine, ≈ 40 s, then come from its cache)."""

from __future__ import annotations

import json
import logging
import re
import sys

import numpy as np
import pytest

pytest.importorskip("mujoco_warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")

from frbench.backends import BACKENDS, make_backend, training_backend_names  # noqa: E402
from frbench.backends.base import PhysicsParams, RobotState  # noqa: E402
from frbench.robots import get_robot  # noqa: E402
from frbench.terrains import make_terrain  # noqa: E402

N = 4
#: Base position [m] and joint angle [rad] agreement after `SHORT_STEPS` control steps from settled starts on
#: flat ground (measured: ≈ 1e-7 m and 1e-6 rad; float32 against float64).
SHORT_STEPS = 5
POSITION_TOLERANCE = 1e-5
JOINT_TOLERANCE = 1e-4


@pytest.fixture(scope="module")
def go2():
    return get_robot("go2")


@pytest.fixture(scope="module")
def settled(go2) -> RobotState:
    """N of the protocol's fallen starts on flat ground, settled in MuJoCo C (velocities included)."""
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask

    terrain = make_terrain("flat", 1, 0)
    mujoco = make_backend("mujoco", go2, N, terrain=terrain)
    task = RecoveryTask(go2, mujoco, terrain, N)
    task.reset(draw_starts(go2, terrain, "flat", 1, 0, range(N)))
    state = task.state.copy()
    mujoco.close()
    return state


@pytest.fixture(scope="module")
def warp(go2):
    """One Warp backend of N Go2 worlds on flat ground on Warp's CPU device (the default whether or not the machine
    has a GPU), handing out host arrays; shared by the tests (each resets what it uses)."""
    backend = make_backend("mujoco-warp", go2, N)
    yield backend
    backend.close()


def _targets(pose: np.ndarray, steps: int) -> list[np.ndarray]:
    """A smooth sweep of joint targets (0.3 rad) around ``pose`` (N, J) [rad], different in every world."""
    pose = np.broadcast_to(pose, (N, np.shape(pose)[-1]))
    phase = np.arange(N)[:, None] + np.arange(pose.shape[1])[None, :]
    return [pose + 0.3 * np.sin(0.2 * t + phase) for t in range(steps)]


def _run(backend, state: RobotState, targets: list[np.ndarray], params: PhysicsParams | None = None) -> RobotState:
    backend.set_params(params if params is not None else PhysicsParams.nominal(backend.spec, backend.num_envs))
    backend.reset(np.arange(backend.num_envs), state)
    for target in targets:
        backend.step(target)
    return backend.state()


def test_mujoco_warp_is_a_registered_simulator():
    assert "mujoco-warp" in BACKENDS and "mujoco-warp" in training_backend_names()


def test_a_missing_gpu_extra_is_one_error_with_the_install_command(go2, monkeypatch):
    from frbench.errors import FrbenchError

    monkeypatch.setitem(sys.modules, "mujoco_warp", None)  # what an installation without the extra sees
    with pytest.raises(FrbenchError, match=re.escape("install it with pip install 'frbench[gpu]'")):
        make_backend("mujoco-warp", go2, 1)


def test_warp_follows_mujoco_c_over_five_control_steps_from_settled_starts(go2, settled, warp):
    assert warp.device == "cpu" and warp.substeps == 4 and warp.physics_dt == pytest.approx(0.005)
    # around the default pose: the legs fold from the settled pose, one calf onto another leg's thigh (a box-box
    # self-contact, 4 contact points in both simulators)
    targets = _targets(np.asarray(go2.default_pose), SHORT_STEPS)
    want = _run(make_backend("mujoco", go2, N), settled, targets)
    got = _run(warp, settled, targets)
    assert not warp.diverged.any() and not warp.overflow.any()
    assert np.abs(got.base_pos - want.base_pos).max() < POSITION_TOLERANCE
    assert np.abs(got.q - want.q).max() < JOINT_TOLERANCE
    assert np.abs(got.base_quat - want.base_quat).max() < 1e-4
    assert np.abs(got.tau - want.tau).max() < 1e-2 * np.abs(want.tau).max()


def test_box_box_contacts_are_the_ones_mujoco_c_makes(go2):
    """On stairs, from settled starts, every touching geom pair has as many contacts in Warp as in MuJoCo C (Warp's
    general convex path gave another count for 7 of 35 pairs; `warp_model.put_batched_model`)."""
    import mujoco

    from frbench.backends.mujoco_backend import write_state
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask

    terrain = make_terrain("stairs", 1, 0)
    mujoco_c = make_backend("mujoco", go2, N, terrain=terrain)
    task = RecoveryTask(go2, mujoco_c, terrain, N)
    task.reset(draw_starts(go2, terrain, "stairs", 1, 0, range(N)))
    settled = task.state.copy()
    warp = make_backend("mujoco-warp", go2, N, terrain=terrain)
    warp.reset(np.arange(N), settled)
    model, data = warp.model, warp.warp_data
    count = int(data.nacon.numpy()[0])
    warp_pairs = [tuple(map(int, pair)) for pair in data.contact.geom.numpy()[:count]]
    worlds = data.contact.worldid.numpy()[:count]
    boxes = 0
    for i in range(N):
        single = mujoco.MjData(model)
        qpos, qvel = model.qpos0[None].copy(), np.zeros((1, model.nv))
        write_state(qpos, qvel, settled.take([i]), warp._qadr, warp._dadr)
        single.qpos[:], single.qvel[:] = qpos[0], qvel[0]
        mujoco.mj_forward(model, single)
        want = sorted(zip(single.contact.geom1[: single.ncon].tolist(), single.contact.geom2[: single.ncon].tolist()))
        got = sorted(pair for pair, world in zip(warp_pairs, worlds) if world == i)
        assert got == want
        box = int(mujoco.mjtGeom.mjGEOM_BOX)
        boxes += sum(model.geom_type[a] == box and model.geom_type[b] == box for a, b in want)
    assert boxes >= 10  # box-box pairs were among them
    mujoco_c.close()
    warp.close()


def test_contacts_masses_and_centre_of_mass_match_mujoco_c_at_rest(go2, warp):
    standing = RobotState.standing(go2, N)
    hold = [np.tile(go2.default_pose, (N, 1))] * 25
    mujoco = make_backend("mujoco", go2, N)
    _run(mujoco, standing, hold)
    _run(warp, standing, hold)
    want, got = mujoco.contacts(), warp.contacts()
    weight = 9.81 * mujoco.mass_properties()[0]
    vertical = got.link_force[:, :, 2].sum(axis=1)
    assert np.allclose(vertical, weight, rtol=0.05)  # the feet carry the robot (still settling after 0.5 s)
    assert np.allclose(vertical, want.link_force[:, :, 2].sum(axis=1), rtol=1e-4)
    assert np.allclose(got.foot_force, want.foot_force, atol=1e-2)
    assert (got.foot_contact == want.foot_contact).all() and got.foot_contact.all()
    mass_c, com_c = mujoco.mass_properties()
    mass_w, com_w = warp.mass_properties()
    assert np.allclose(mass_w, mass_c, rtol=1e-6) and np.abs(com_w - com_c).max() < 1e-5


def test_per_world_gains_strength_friction_payload_and_base_force_match_mujoco_c(go2, settled):
    params = PhysicsParams.nominal(go2, N, friction=0.6)
    params.kp = params.kp * np.array([0.8, 1.0, 1.2, 1.4])[:, None]
    params.kd = params.kd * np.array([1.3, 1.0, 0.7, 1.1])[:, None]
    params.motor_strength = np.full((N, go2.n_joints), 0.9)
    params.friction = np.array([0.4, 0.8, 1.0, 1.5])
    params.payload = np.array([0.0, 2.0, -1.0, 3.5])
    params.motor_friction = np.full((N, go2.n_joints), 0.2)
    force = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 40.0], [10.0, 0.0, 20.0], [0.0, -5.0, 0.0]])
    targets = _targets(settled.q, 10)
    states = {}
    for name in ("mujoco", "mujoco-warp"):
        backend = make_backend(name, go2, N)
        backend.set_base_force(force)
        states[name] = (_run(backend, settled, targets, params), backend.mass_properties(), backend.contacts())
        if name == "mujoco-warp":
            assert backend.warp_model.body_mass.shape == (N, backend.model.nbody)
            assert backend.warp_model.actuator_gainprm.shape == (N, backend.model.nu)
        backend.close()
    (want, (mass_c, com_c), contacts_c), (got, (mass_w, com_w), contacts_w) = states.values()
    assert np.abs(got.base_pos - want.base_pos).max() < 1e-4
    assert np.abs(got.q - want.q).max() < 1e-3
    assert np.allclose(mass_w, mass_c, rtol=1e-6) and np.abs(com_w - com_c).max() < 1e-4
    assert np.allclose(contacts_w.link_force.sum(axis=1), contacts_c.link_force.sum(axis=1), atol=1.0)


def test_morphology_variants_are_per_world_model_fields_that_match_mujoco_c(settled):
    from frbench.training.randomization import morphology_specs, sample_morphologies

    specs = morphology_specs(sample_morphologies(2, np.random.default_rng(5)))
    variants = (specs, np.array([1, 0, 1, 0]), np.array([0.7, 1.2]), np.array([1.5, -0.5]))
    standing = RobotState.standing(specs[0], N, clearance=0.05)
    targets = _targets(np.asarray(specs[0].default_pose), 10)
    runs = {}
    for name in ("mujoco", "mujoco-warp"):
        backend = make_backend(name, specs[0], N, variants=variants)
        runs[name] = (_run(backend, standing, targets), backend.mass_properties())
        if name == "mujoco-warp":
            sizes = backend.warp_model.geom_size.numpy()
            assert sizes.shape[0] == N and not np.allclose(sizes[0], sizes[1]) and np.allclose(sizes[0], sizes[2])
        backend.close()
    (want, (mass_c, com_c)), (got, (mass_w, com_w)) = runs.values()
    assert np.allclose(mass_w, mass_c, rtol=1e-6) and not np.isclose(mass_c[0], mass_c[1])
    assert np.abs(com_w - com_c).max() < 1e-4
    assert np.abs(got.base_pos - want.base_pos).max() < 1e-5 and np.abs(got.q - want.q).max() < 1e-4


def test_a_diverged_world_is_flagged_held_and_leaves_the_others_alone(go2, settled, warp):
    bad = settled.copy()
    bad.base_linvel[1] = [np.nan, 0.0, 0.0]
    targets = _targets(settled.q, 3)
    want = _run(make_backend("mujoco", go2, N), settled, targets)
    got = _run(warp, bad, targets)
    assert warp.diverged.tolist() == [False, True, False, False]
    assert np.isnan(got.base_linvel[1, 0]) and np.allclose(got.base_pos[1], settled.base_pos[1])  # as placed
    keep = [0, 2, 3]
    assert np.abs(got.base_pos[keep] - want.base_pos[keep]).max() < POSITION_TOLERANCE
    assert np.isfinite(warp.contacts().link_force).all()
    warp.reset(np.array([1]), settled.take([1]))
    assert not warp.diverged.any()


def test_a_buffer_overflow_flags_the_world_and_is_logged(go2, settled, caplog):
    from frbench.backends.mujoco_warp_backend import MujocoWarpBackend

    backend = MujocoWarpBackend(go2, N, njmax=8)  # too few constraint rows for a robot lying on the ground
    with caplog.at_level(logging.WARNING, logger="frbench.warp"):
        _run(backend, settled, _targets(settled.q, 2))
    assert backend.diverged.all() and (backend.overflow != 0).all()
    assert "NEFC overflow" in caplog.text and "njmax 8" in caplog.text
    backend.close()


def test_device_arrays_are_torch_on_the_device_with_the_host_numbers(go2, settled, warp):
    """The same worlds handing out torch tensors on Warp's device (training) give the numbers the host copies give
    (evaluation), and take torch targets and states."""
    torch = pytest.importorskip("torch")
    targets = _targets(settled.q, 3)
    want = _run(warp, settled, targets)
    want_contacts, want_com = warp.contacts(), warp.whole_body_com()
    device = make_backend("mujoco-warp", go2, N, device="cpu", device_arrays=True)
    try:
        device.reset(torch.arange(N), RobotState(**{k: torch.as_tensor(getattr(settled, k), dtype=torch.float32)
                                                    for k in ("base_pos", "base_quat", "base_linvel",
                                                              "base_angvel", "q", "qd")}))
        for target in targets:
            device.step(torch.as_tensor(target, dtype=torch.float32))
        got = device.state()
        assert isinstance(got.q, torch.Tensor) and got.q.dtype == torch.float32 and got.q.device.type == "cpu"
        assert isinstance(device.diverged, torch.Tensor) and not bool(device.diverged.any())
        assert np.abs(got.base_pos.numpy() - want.base_pos).max() < 1e-6
        assert np.abs(got.q.numpy() - want.q).max() < 1e-5
        contacts = device.contacts()
        assert isinstance(contacts.group_contact, torch.Tensor)
        np.testing.assert_array_equal(contacts.group_contact.numpy(), want_contacts.group_contact)
        np.testing.assert_allclose(contacts.foot_force.numpy(), want_contacts.foot_force, rtol=1e-4, atol=1e-3)
        np.testing.assert_allclose(device.whole_body_com().numpy(), want_com, atol=1e-6)
    finally:
        device.close()


def test_the_device_is_one_validated_value():
    from frbench.backends.devices import parse_device
    from frbench.errors import FrbenchError

    assert parse_device("cpu") == "cpu" and parse_device(" CPU ") == "cpu"
    for bad in ("gpu", "cuda:x", "cpu:1", "", None):
        with pytest.raises(FrbenchError, match=re.escape("expected cpu, cuda or cuda:N")):
            parse_device(bad)
    with pytest.raises(FrbenchError, match=re.escape("--device cuda:99: torch sees")):  # none, or fewer than 100
        parse_device("cuda:99")
    with pytest.raises(ValueError, match="runs on the CPU"):
        make_backend("mujoco", get_robot("go2"), 1, device="cuda:0")


@pytest.mark.cuda
def test_worlds_and_tensors_share_the_named_cuda_device(go2, settled):
    """On a machine with CUDA: the worlds of --device cuda:N and the tensors they hand out lie on GPU N (the last
    one the machine has), and a period on the GPU follows the CPU device's."""
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    from frbench.backends.devices import parse_device

    device = parse_device(f"cuda:{torch.cuda.device_count() - 1}")
    backend = make_backend("mujoco-warp", go2, N, device=device, device_arrays=True)
    try:
        assert backend.warp_model.body_mass.device.alias == device
        backend.reset(np.arange(N), settled)
        backend.step(_targets(settled.q, 1)[0])
        state = backend.state()
        assert str(state.q.device) == device and str(backend.diverged.device) == device
    finally:
        backend.close()


def test_the_gym_env_runs_on_mujoco_warp():
    import gymnasium

    import frbench.gym  # noqa: F401  (registers the env)

    env = gymnasium.make_vec("frbench/FallRecovery-v1", num_envs=2, vectorization_mode="vector_entry_point",
                             backend="mujoco-warp")
    obs, _ = env.reset(seed=0)
    obs, reward, _, _, info = env.step(np.zeros((2, env.single_action_space.shape[0]), dtype=np.float32))
    assert obs.shape == (2, env.single_observation_space.shape[0]) and np.isfinite(reward).all()
    assert not info["diverged"].any()
    env.close()


def test_evaluate_takes_the_device_and_names_a_bad_one(tmp_path, capsys):
    from frbench.cli import main

    out = tmp_path / "warp.json"
    base = ["evaluate", "--policy", "scripted", "--robots", "go2", "--terrains", "flat", "--levels", "1", "--seeds",
            "0", "--episodes", "1", "--jobs", "1"]
    for flags, message in ((["--backends", "mujoco-warp", "--device", "gpu"], "--device 'gpu': expected cpu, cuda"),
                           (["--backends", "mujoco", "--device", "cuda:99"], "--device cuda:99: torch sees")):
        assert main([*base, *flags, "--out", str(tmp_path / "never.json")]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert main([*base, "--backends", "mujoco-warp", "--device", "cpu", "--out", str(out)]) == 0
    results = json.loads(out.read_text())
    assert [e["backend"] for e in results["episodes"]] == ["mujoco-warp"] and "device" not in results["config"]
