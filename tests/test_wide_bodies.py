"""The wide training bodies (``TrainEnvConfig.bodies="wide"``, `frbench.training.bodies`): 2-60 kg, knees backward,
forward or forward on one pair, flipped joint axes and legs folded at joint zero, each normalised by the
canonical joint frame; the paper's population unchanged."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math

import numpy as np
import pytest
import torch

from frbench.backends import make_backend
from frbench.backends.base import torque_limit_rows
from frbench.cli import main
from frbench.robots import morphology as M
from frbench.robots.batch_frame import BatchJointFrame, batch_joint_frame
from frbench.robots.joint_frame import JointFrameError, joint_frame
from frbench.robots.morphology_urdf import urdf_string
from frbench.robots.sim_urdf import crossing_links
from frbench.tasks.initial_states import draw_starts
from frbench.tasks.recovery import RecoveryTask
from frbench.terrains import make_terrain
from frbench.training.bodies import BODIES, WideBodies
from frbench.training.config import TrainEnvConfig
from frbench.training.feasibility import can_stand
from frbench.training.population import TrainingRobots
from frbench.training.presets import KICKSTART_SCRIPTED, PRESETS
from frbench.training.randomization import morphology_spec, params_hash
from frbench.training.turned_groups import turned_groups

WIDE = WideBodies()
FOLDED = (math.pi / 2, -math.pi)
#: (knees, joint axes, zero pose) → (canonical sign of one leg's hip, thigh, calf per leg FL, FR, RL, RR; offset
#: (hip, thigh, calf) of every leg; turned): read from the robots' real files' analogues (Mini Cheetah's flipped
#: axes (1, -1, -1), ANYmal's turned frame of signs -1, Spirit 40's folded zero (pi/2, -pi)).
FRAMES = {
    (("backward", "backward"), (1.0, -1.0, -1.0), (0.0, 0.0)): ([(1, -1, -1)] * 4, (0.0, 0.0, 0.0), False),
    (("forward", "forward"), (1.0, 1.0, 1.0), (0.0, 0.0)): ([(-1, -1, -1)] * 4, (0.0, 0.0, 0.0), True),
    (("forward", "forward"), (1.0, -1.0, -1.0), FOLDED): ([(-1, 1, 1)] * 4, (0.0, *FOLDED), True),
    (("backward", "forward"), (1.0, 1.0, 1.0), (0.0, 0.0)): ([(1, 1, 1)] * 2 + [(1, -1, -1)] * 2, (0.0, 0.0, 0.0), False),
    (("forward", "backward"), (1.0, -1.0, -1.0), FOLDED): ([(1, 1, 1)] * 2 + [(1, -1, -1)] * 2, (0.0, *FOLDED), False),
    (("backward", "backward"), (1.0, 1.0, 1.0), FOLDED): ([(1, 1, 1)] * 4, (0.0, *FOLDED), False),
}


def _paper_draw(seed: int = 3) -> M.MorphologyParams:
    return M.sample(np.random.default_rng(seed))


def _go2_convention(params: M.MorphologyParams) -> M.MorphologyParams:
    return dataclasses.replace(params, knees=("backward", "backward"), joint_axes=(1.0, 1.0, 1.0), zero_pose=(0.0, 0.0))


def test_64_wide_draws_span_2_to_60_kg_with_every_knee_layout_and_convention():
    rng = np.random.default_rng(0)
    bodies = [WIDE.draw(M.sample(rng), rng) for _ in range(64)]
    masses = np.array([M.total_mass(b) for b, _ in bodies])
    assert masses.min() < 4.0 and masses.max() > 45.0 and np.all((masses >= 2.0) & (masses <= 60.0))
    assert {b.knees for b, _ in bodies} == set(WIDE.knee_layouts) and len(WIDE.knee_layouts) == 4
    assert {b.joint_axes for b, _ in bodies} == {(1.0, 1.0, 1.0), (1.0, -1.0, -1.0)}
    assert {b.zero_pose for b, _ in bodies} == {(0.0, 0.0), FOLDED}
    # log-uniform in mass: about a quarter of the draws in each quarter of log(2)..log(60)
    quarters = np.histogram(np.log(masses), bins=np.linspace(np.log(2.0), np.log(60.0), 5))[0]
    assert quarters.min() >= 8, quarters


def test_a_scaled_body_is_the_draw_geometrically_similar_with_torques_and_gains_by_their_exponents():
    p = dataclasses.replace(_paper_draw(), trunk_com_shift=(0.01, -0.02, 0.0))
    big = WIDE.scaled(p, 2.0)
    assert M.total_mass(big) == pytest.approx(8.0 * M.total_mass(p), rel=1e-12)
    assert M.nominal_height(big) == pytest.approx(2.0 * M.nominal_height(p), rel=1e-12)
    assert M.hip_position(big) == pytest.approx(tuple(2.0 * v for v in M.hip_position(p)), rel=1e-12)
    assert big.calf_torque == pytest.approx(16.0 * p.calf_torque) and big.kp == pytest.approx(16.0 * p.kp)
    assert big.kd == pytest.approx(2.0 ** 4.5 * p.kd) and big.trunk_com_shift == pytest.approx((0.02, -0.04, 0.0))
    assert big.calf_velocity == p.calf_velocity and big.stand_calf == p.stand_calf
    factors = WIDE.factors([0.5, 2.0])
    assert factors["kp"] == pytest.approx([1 / 16, 16]) and factors["mass"] == pytest.approx([1 / 8, 8])


@pytest.mark.parametrize("convention", sorted(FRAMES), ids=lambda c: "-".join(map(str, c[0])) + str(c[1][1]) + str(c[2][0]))
def test_joint_frame_of_each_generated_file_and_its_canonical_standing_pose(convention, tmp_path):
    knees, axes, zero = convention
    legs, offset, turned = FRAMES[convention]
    p = dataclasses.replace(_paper_draw(), knees=knees, joint_axes=axes, zero_pose=zero)
    spec = morphology_spec(p, "conv", cache_dir=tmp_path)
    frame = joint_frame(spec)
    assert frame.sign == tuple(float(s) for leg in legs for s in leg) and frame.turned is turned
    assert np.abs(np.subtract(frame.offset, offset * 4)).max() < 1e-9
    expected_knees = ("forward",) * 4 if turned else tuple(k for k in knees for _ in range(2))
    assert frame.knees == expected_knees
    # the canonical standing pose and limits are the Go2-convention ones of the same morphology
    go2 = morphology_spec(_go2_convention(p), "conv", cache_dir=tmp_path)
    canonical = frame.canonical_spec(spec)
    for name in ("default_pose", "joint_lower", "joint_upper"):
        assert np.abs(np.subtract(getattr(canonical, name), getattr(go2, name))).max() < 1e-9, name
    assert spec.default_pose != go2.default_pose  # the file's own convention differs
    assert frame.to_canonical(np.asarray(spec.default_pose)) == pytest.approx(go2.default_pose, abs=1e-9)


def test_go2_convention_files_are_the_bytes_and_cache_keys_they_were():
    assert hashlib.sha256(urdf_string(M.MorphologyParams()).encode()).hexdigest() == \
        "9893cf5d05a3a4da3eff7d959ecc7874ab76b005a371e02dfba1b2c9259ba0f5"
    assert params_hash(M.MorphologyParams()) == "7cb9030441bd6538"
    p = _paper_draw()
    assert hashlib.sha256(urdf_string(p, "x").encode()).hexdigest() == \
        "b01d3e7a3af85a4b25116e62bac0dfd8ca1c1159ec3d09743176236855bc3aa1"
    assert params_hash(p) == "bf8d6c7191e10306"
    assert params_hash(dataclasses.replace(p, knees=("forward", "forward"))) != params_hash(p)


def test_the_paper_population_draws_what_it_drew():
    cfg = TrainEnvConfig(num_envs=8, num_morphologies=4, population_seed=7)
    assert cfg.bodies == "paper"
    robots = TrainingRobots.drawn(cfg, np.random.default_rng(0))
    assert [M.total_mass(m) for m in robots.morphologies] == [24.62337732259605, 26.301014721253615,
                                                              28.55696121287334, 15.742239291052167]
    assert robots.morphologies[1].trunk_com_shift[0] == -0.028494222036190644
    assert robots.rejected == 19 and robots.assignment.tolist() == [1, 0, 0, 2, 3, 1, 2, 3]
    assert robots.variant_payload[0] == 0.23329383237344858 and robots.variant_friction[0] == 1.114187480539202
    assert [s.urdf_path.parent.name for s in robots.specs] == ["addfdbf8351ae04f", "ee1c50e1e845c881",
                                                               "c66f479300527596", "4694457b7574dbd5"]
    assert robots.scales.tolist() == [1.0] * 4 and robots.bodies is None


def test_every_wide_body_of_a_small_population_stands_and_its_physics_scale_with_it():
    cfg = TrainEnvConfig(num_envs=8, num_morphologies=4, bodies="wide", population_seed=0)
    robots = TrainingRobots.drawn(cfg, np.random.default_rng(0))
    kp, kd = cfg.gain_ranges["kp"][0], cfg.gain_ranges["kd"][0]
    factors = WIDE.factors(robots.scales)
    masses = [M.total_mass(m) for m in robots.morphologies]
    assert min(masses) < 5.0 and max(masses) > 20.0
    assert {m.knees for m in robots.morphologies} >= {("forward", "forward"), ("forward", "backward")}
    for i, spec in enumerate(robots.specs):
        assert crossing_links(spec) == ()
        assert can_stand(spec, kp * factors["kp"][i], kd * factors["kd"][i])
    params = robots.episode_params()
    env_factors = {k: v[robots.assignment] for k, v in factors.items()}
    kp_paper = params.kp[:, 0] / env_factors["kp"]
    assert np.all((kp_paper >= 50.0 - 1e-9) & (kp_paper <= 80.0 + 1e-9)) and np.ptp(params.kp[:, 0]) > 10.0
    friction = params.motor_friction / env_factors["torque"][:, None]
    assert friction.min() >= 0.2 - 1e-9 and friction.max() <= 1.25 + 1e-9
    payload = robots.variant_payload / factors["mass"]
    assert np.all(np.abs(payload) <= 2.0 + 1e-9)


def test_bad_bodies_values_are_one_line_errors_naming_the_field(capsys):
    with pytest.raises(ValueError, match=r"^bodies 'huge': expected one of paper, wide$"):
        TrainEnvConfig(bodies="huge")
    with pytest.raises(ValueError, match=r"^bodies 'wide': expected 'paper' with a named robot"):
        TrainEnvConfig(bodies="wide", robot="go2")
    with pytest.raises(ValueError, match=r"^demo_start_fraction 0.5: expected 0 with bodies 'wide'"):
        TrainEnvConfig(bodies="wide", demo_start_fraction=0.5)
    assert main(["train", "--set", "bodies=huge", "--steps", "100", "--out", "/nonexistent/x"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "bodies 'huge'" in err


def test_batch_joint_frame_maps_each_environment_through_its_robots_frame(tmp_path):
    p = _paper_draw()
    conventions = [(("backward", "backward"), (1.0, 1.0, 1.0), (0.0, 0.0)),
                   (("forward", "forward"), (1.0, -1.0, -1.0), FOLDED), (("backward", "forward"), (1.0, 1.0, 1.0), (0.0, 0.0))]
    specs = [morphology_spec(dataclasses.replace(p, knees=k, joint_axes=a, zero_pose=z), f"b{i}", cache_dir=tmp_path)
             for i, (k, a, z) in enumerate(conventions)]
    assignment = np.array([0, 1, 2, 1, 0])
    batch = batch_joint_frame(specs, assignment)
    assert isinstance(batch, BatchJointFrame) and batch.turned.tolist() == [False, True, False, True, False]
    frames = [joint_frame(s) for s in specs]
    q = np.random.default_rng(0).uniform(-1.0, 1.0, (5, 12))
    canonical = batch.to_canonical(q)
    for i, k in enumerate(assignment):
        assert canonical[i] == pytest.approx(frames[k].to_canonical(q[i]), abs=1e-12)
        assert batch.velocities(q)[i] == pytest.approx(frames[k].velocities(q[i]), abs=1e-12)
    assert batch.to_joints(canonical) == pytest.approx(q, abs=1e-12)
    g = np.tile([0.1, 0.2, -0.9], (5, 1))
    assert batch.body_vectors(g)[1] == pytest.approx([-0.1, -0.2, -0.9]) and batch.body_vectors(g)[0] == pytest.approx(g[0])
    tensor = torch.as_tensor(q)
    assert batch.to_canonical(tensor).numpy() == pytest.approx(canonical, abs=1e-12)
    assert batch.targets(torch.as_tensor(canonical)).numpy() == pytest.approx(q, abs=1e-12)
    assert BatchJointFrame.from_dict(batch.to_dict()) == batch
    # one convention: the robots' one JointFrame, as before
    assert batch_joint_frame([specs[0], specs[0]], [0, 1]) == frames[0]
    other = morphology_spec(dataclasses.replace(p, knees=("forward", "forward"), stand_thigh_rear=1.2), "o",
                            cache_dir=tmp_path)
    with pytest.raises(JointFrameError, match="different canonical poses"):
        batch_joint_frame([specs[0], other], [0, 1])


def test_turned_rows_of_the_privileged_groups_are_seen_from_the_canonical_front():
    n_priv = 42 + 187 + 4 + 12 + 12 + 2 + 13 + 4 + 1
    groups = {"privileged": np.tile(np.arange(n_priv, dtype=float), (2, 1)),
              "contact": np.tile(np.arange(13, dtype=float), (2, 1)), "velocity": np.array([[1.0, 2.0, 3.0]] * 2),
              "extrinsics": np.tile(np.arange(11, dtype=float), (2, 1)), "mass": np.ones((2, 4))}
    out = turned_groups(groups, np.array([True, False]), 42, 4, 12)
    assert out["contact"][0].tolist() == [0, 10, 11, 12, 7, 8, 9, 4, 5, 6, 1, 2, 3]
    assert out["velocity"][0].tolist() == [-1.0, -2.0, 3.0] and out["extrinsics"][0][-2:].tolist() == [-9.0, -10.0]
    privileged = out["privileged"][0]
    assert privileged[:42].tolist() == list(range(42)) and privileged[42:229].tolist() == list(range(228, 41, -1))
    com = 42 + 187 + 4 + 24
    assert privileged[com:com + 2].tolist() == [-com, -(com + 1)]
    for name in groups:  # the rows of robots that are not turned stay
        assert out[name][1].tolist() == groups[name][1].tolist()
    as_torch = turned_groups({k: torch.as_tensor(v) for k, v in groups.items()}, np.array([True, False]), 42, 4, 12)
    assert all(np.array_equal(as_torch[k].numpy(), out[k]) for k in groups)


def test_each_simulation_runs_its_robots_torque_limits_and_joint_limits(tmp_path):
    # a folded joint zero adds only ancestor pairs to the self-collision exclusions: the variants still batch
    small = dataclasses.replace(WIDE.scaled(_paper_draw(), 0.5), knees=("forward", "forward"), zero_pose=FOLDED)
    specs = [morphology_spec(_paper_draw(), "a", cache_dir=tmp_path), morphology_spec(small, "b", cache_dir=tmp_path)]
    variants = (specs, np.array([0, 1]), np.ones(2), np.zeros(2))
    limits = torque_limit_rows(specs[0], 2, variants)
    assert limits.shape == (2, 12) and limits[1, 2] == pytest.approx(specs[0].torque_limits[2] / 16)
    assert torque_limit_rows(specs[0], 2, (specs[:1], np.array([0, 0]), np.ones(1), np.zeros(1))).shape == (12,)
    terrain = make_terrain("flat", 1, 0)
    backend = make_backend("mujoco", specs[0], 2, terrain=terrain, variants=variants)
    try:
        assert backend._force_range[:, :12, 1] == pytest.approx(limits)
        task = RecoveryTask(specs[0], backend, terrain, 2, env_specs=specs)
        assert task.lower.shape == (2, 12) and task.lower[1] == pytest.approx(specs[1].joint_lower)
        starts = draw_starts(specs[0], terrain, "flat", 1, 0, range(2))
        starts.q[1] = specs[1].default_pose
        task.reset(starts)
        assert task.previous_action == pytest.approx(np.array([specs[0].default_pose, specs[1].default_pose]))
        task.advance(np.full((2, 12), 10.0))
        assert task.previous_action == pytest.approx(np.array([specs[0].joint_upper, specs[1].joint_upper]))
    finally:
        backend.close()


def test_a_wide_training_batch_maps_the_teachers_label_back_to_its_targets():
    from frbench.training.env import RecoveryTrainingEnv

    cfg = TrainEnvConfig(num_envs=8, num_morphologies=4, bodies="wide", population_seed=0, families=("flat",),
                         episode_steps=20, **KICKSTART_SCRIPTED)
    env = RecoveryTrainingEnv(cfg)
    try:
        frame = env.core.frame
        assert isinstance(frame, BatchJointFrame) and frame.turned.any() and not frame.turned.all()
        teacher = env.teacher
        for _ in range(5):
            obs, reward, _, _ = env.step(torch.zeros(8, 12))
            assert torch.isfinite(obs["policy"]).all() and torch.isfinite(reward).all()
        observation = env._host_observation()
        targets = np.zeros((8, 12))
        for controller, ids in zip(teacher.controllers, teacher.groups):
            if len(ids):
                targets[ids] = controller.to_joints(controller.target)  # this step's targets, robot joints
        label_targets = frame.targets(env.core.policy_default_pose + cfg.action_scale * teacher.label)
        assert label_targets == pytest.approx(targets, abs=1e-9)
        assert observation["joint_pos"].shape == (8, 12)
    finally:
        env.close()


def test_a_resumed_run_switches_to_wide_bodies_as_a_new_stage(tmp_path, capsys):
    out = tmp_path / "run"
    base = ["train", "--preset", "kickstart-scripted", "--envs", "4", "--set", "num_morphologies=2",
            "--checkpoint-every", "1", "--out", str(out)]
    assert main([*base, "--steps", "96"]) == 0
    assert main(["train", "--resume", str(out), "--steps", "192", "--set", "bodies=wide"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["env"]["bodies"] == "wide" and config["stages"][-1]["fields"] == {"bodies": "wide"}
    assert config["stages"][-1]["from_env_steps"] == 96
    capsys.readouterr()
    assert main(["train", "--resume", str(out), "--steps", "288", "--set", "seed=2"]) == 2
    assert "--set changes only bodies" in capsys.readouterr().err


def test_the_wide_preset_is_kickstart_scripted_on_wide_bodies_and_kickstart_scripted_is_unchanged():
    assert dict(PRESETS["kickstart-scripted"].env) == dict(KICKSTART_SCRIPTED) and "bodies" not in KICKSTART_SCRIPTED
    wide = PRESETS["kickstart-scripted-wide"]
    assert dict(wide.env) == {**KICKSTART_SCRIPTED, "bodies": "wide"}
    assert wide.train_overrides() == PRESETS["kickstart-scripted"].train_overrides()
    floor = PRESETS["kickstart-scripted-wide-floor"]
    assert dict(floor.env) == {**KICKSTART_SCRIPTED, "bodies": "wide", "imitation_floor": 0.1}
    assert floor.train_overrides() == wide.train_overrides()
    assert set(BODIES) == {"paper", "wide"} and BODIES["paper"] is None


def test_inward_knees_on_a_short_trunk_pass_through_each_other_and_are_not_drawn(tmp_path):
    p = dataclasses.replace(_paper_draw(), trunk_length=0.40, thigh_length=0.30, calf_length=0.28)
    inward = morphology_spec(dataclasses.replace(p, knees=("backward", "forward")), "in", cache_dir=tmp_path)
    assert ("FL_thigh", "RL_thigh") in crossing_links(inward) and ("FR_calf", "RR_calf") in crossing_links(inward)
    for knees in (("backward", "backward"), ("forward", "backward"), ("forward", "forward")):
        assert crossing_links(morphology_spec(dataclasses.replace(p, knees=knees), "ok", cache_dir=tmp_path)) == ()
    folded = morphology_spec(dataclasses.replace(p, zero_pose=FOLDED), "fold", cache_dir=tmp_path)
    assert crossing_links(folded) == ()  # the calf folded onto its own hip is an ancestor pair
