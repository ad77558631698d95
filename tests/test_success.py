"""The success test and every metric on hand-made trajectories."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.tasks.protocol import CONTROL_DT
from frbench.tasks.success import EpisodeMetrics, StepSignals, SuccessTracker

NOMINAL = 0.30


def _signals(n=1, gz=-1.0, height=NOMINAL, contact=False, displacement=0.0):
    return StepSignals(
        gravity_z=np.full(n, gz), height=np.full(n, height),
        body_contact=np.full(n, contact), displacement=np.full(n, displacement),
    )


def _run(steps: list[StepSignals], kind="quadruped", nominal=NOMINAL) -> SuccessTracker:
    tracker = SuccessTracker(1, kind, nominal)
    for s in steps:
        tracker.update(s)
    return tracker


def test_upright_for_0_4_s_is_not_a_success():
    fallen = [_signals(gz=0.9, height=0.1)] * 10
    tracker = _run(fallen + [_signals()] * 20 + [_signals(gz=0.9, height=0.1)] * 5)
    assert not tracker.success[0]


def test_upright_for_0_5_s_is_a_success_timed_from_the_start_of_the_hold():
    tracker = _run([_signals(gz=0.9, height=0.1)] * 10 + [_signals()] * 25)
    assert tracker.success[0]
    assert tracker.time_to_recover[0] == pytest.approx(11 * CONTROL_DT)


def test_displacement_of_1_01_m_fails_and_0_99_passes():
    assert not _run([_signals(displacement=1.01)] * 40).success[0]
    assert _run([_signals(displacement=0.99)] * 40).success[0]


@pytest.mark.parametrize("broken", [
    dict(gz=-np.cos(np.radians(31))),  # tilted 31°
    dict(height=0.74 * NOMINAL),  # too low
    dict(contact=True),  # a knee on the ground
])
def test_each_condition_is_required(broken):
    assert not _run([_signals(**broken)] * 40).success[0]


def test_tilt_of_29_degrees_and_height_of_76_percent_pass():
    assert _run([_signals(gz=-np.cos(np.radians(29)), height=0.76 * NOMINAL)] * 30).success[0]


def test_a_break_in_the_hold_restarts_it():
    steps = [_signals()] * 20 + [_signals(contact=True)] + [_signals()] * 24
    assert not _run(steps).success[0]
    assert _run(steps + [_signals()]).success[0]


def test_a_diverged_episode_cannot_succeed():
    tracker = SuccessTracker(2, "quadruped", NOMINAL)
    for _ in range(30):
        tracker.update(_signals(n=2), alive=np.array([True, False]))
    assert tracker.success.tolist() == [True, False]


G1 = 0.78
HOLD = 25  # control steps in 0.5 s


def _humanoid(gz=-1.0, torso_gz=-1.0, height=0.76, contact=False, displacement=0.0):
    return StepSignals(
        gravity_z=np.full(1, gz), height=np.full(1, height), body_contact=np.full(1, contact),
        displacement=np.full(1, displacement), torso_gravity_z=np.full(1, torso_gz),
    )


def test_humanoid_standing_upright_for_the_hold_is_a_success():
    lying = [_humanoid(gz=0.0, torso_gz=0.0, height=0.12, contact=True)] * 10
    tracker = _run(lying + [_humanoid()] * HOLD, "humanoid", G1)
    assert tracker.success[0]
    assert tracker.time_to_recover[0] == pytest.approx(11 * CONTROL_DT)


def test_humanoid_head_stand_fails():
    # pelvis upside down 0.75 m above the ground, torso inverted, head and hands on the ground
    head_stand = [_humanoid(gz=0.98, torso_gz=0.95, height=0.75, contact=True)] * 100
    assert not _run(head_stand, "humanoid", G1).success[0]
    # even without the head contact being seen, the inverted pelvis alone fails it
    assert not _run([_humanoid(gz=0.98, torso_gz=0.95, height=0.75)] * 100, "humanoid", G1).success[0]


def test_humanoid_kneel_fails():
    # upright trunk, pelvis 0.5 m up on the shins: too low, and the knees touch the ground
    kneel = [_humanoid(gz=-1.0, torso_gz=-1.0, height=0.50, contact=True)] * 100
    assert not _run(kneel, "humanoid", G1).success[0]
    assert not _run([_humanoid(height=0.50)] * 100, "humanoid", G1).success[0]


def test_humanoid_sit_fails():
    # sitting on the ground: pelvis 0.15 m up, trunk leaning back 35°, pelvis on the ground
    sit = [_humanoid(gz=-np.cos(np.radians(35)), torso_gz=-np.cos(np.radians(35)), height=0.15, contact=True)] * 100
    assert not _run(sit, "humanoid", G1).success[0]


def test_humanoid_torso_bent_over_fails_and_pelvis_alone_is_not_enough():
    bowing = [_humanoid(gz=-1.0, torso_gz=-np.cos(np.radians(50)))] * 100
    assert not _run(bowing, "humanoid", G1).success[0]
    assert _run([_humanoid(torso_gz=-np.cos(np.radians(29)))] * HOLD, "humanoid", G1).success[0]


def test_humanoid_hold_and_displacement_are_required():
    assert not _run([_humanoid()] * (HOLD - 1) + [_humanoid(height=0.3)], "humanoid", G1).success[0]
    assert not _run([_humanoid(displacement=1.2)] * 60, "humanoid", G1).success[0]
    # thresholds scale with the robot's height: a 0.39 m humanoid needs 0.35 m
    assert _run([_humanoid(height=0.36)] * HOLD, "humanoid", 0.39).success[0]
    assert not _run([_humanoid(height=0.34)] * HOLD, "humanoid", 0.39).success[0]


def test_torso_frame_follows_the_waist_pitch():
    from frbench.robots import get_robot
    from frbench.tasks.success import TorsoFrame

    spec = get_robot("g1")
    frame = TorsoFrame(spec)
    q = np.tile(np.asarray(spec.default_pose), (2, 1))
    q[:, spec.joint_names.index("waist_pitch_joint")] = [0.0, 0.6]
    upright = np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))
    gz = frame.gravity_z(upright, q)
    assert gz[0] == pytest.approx(-1.0, abs=1e-6)
    assert gz[1] == pytest.approx(-np.cos(0.6), abs=1e-6)
    lying = np.tile([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0], (2, 1))  # pelvis pitched 90°
    assert frame.gravity_z(lying, q)[0] == pytest.approx(0.0, abs=1e-6)


def _surface(family, level, xy_start, xy_now):
    from frbench.tasks.success import StartSurface
    from frbench.terrains import make_terrain

    surface = StartSurface(make_terrain(family, level, 0), np.array([xy_start]))
    return float(surface.drop(np.array([xy_now]))[0])


def test_standing_in_a_pit_is_not_on_the_surface_fallen_on():
    from frbench.terrains import height_at, make_terrain

    terrain = make_terrain("gaps", 10, 0)
    edge = min(b.center[0] + b.half_extents[0] for b in terrain.boxes if b.center[0] + b.half_extents[0] > 0)
    in_gap = (edge + 0.4, 0.0)
    assert height_at(terrain, np.array([in_gap]))[0] == pytest.approx(terrain.floor_z)
    assert _surface("gaps", 10, terrain.spawn_xy, in_gap) == pytest.approx(1.0)  # the level-10 pit depth
    assert _surface("gaps", 10, terrain.spawn_xy, (edge - 0.1, 0.0)) == pytest.approx(0.0)
    tracker = SuccessTracker(1, "quadruped", NOMINAL)
    in_pit = StepSignals(np.full(1, -1.0), np.full(1, NOMINAL), np.full(1, False), np.full(1, 0.5), np.full(1, 1.0))
    for _ in range(60):
        tracker.update(in_pit)
    assert not tracker.success[0]


def test_one_step_down_the_stairs_counts_and_an_incline_is_one_surface():
    assert _surface("stairs", 10, (0.1, 0.0), (-0.2, 0.0)) == pytest.approx(0.25)  # one step down: within bound
    assert _surface("stairs", 10, (0.1, 0.0), (-0.5, 0.0)) == pytest.approx(0.5)  # two steps down: below it
    assert _surface("slopes", 10, (0.0, 0.0), (-0.9, 0.0)) == 0.0


def test_metrics_on_a_hand_made_trajectory():
    metrics = EpisodeMetrics(1, 2)
    qs = [np.array([[0.0, 0.0]]), np.array([[0.1, 0.0]]), np.array([[0.3, 0.0]]), np.array([[0.6, 0.0]])]
    tau, qd = np.array([[2.0, -1.0]]), np.array([[0.5, 3.0]])
    for k, q in enumerate(qs):
        metrics.update(q, qd, tau, angvel_x=np.array([60.0]), body_force_max=np.array([10.0 * k]),
                       displacement=np.array([[0.2, 0.5, 0.3, 0.1][k]]), diverged=np.array([False]))
    assert metrics.energy[0] == pytest.approx(4 * (2.0 * 0.5 + 1.0 * 3.0) * CONTROL_DT)
    # second differences of joint 0: 0.1, 0.1 -> mean over joints 0.05, over time 0.05
    assert metrics.smoothness[0] == pytest.approx(0.05)
    assert metrics.peak_contact_force[0] == 30.0
    assert metrics.max_displacement[0] == 0.5 and metrics.final_displacement[0] == 0.1
    assert metrics.roll[0] == pytest.approx(4 * 60.0 * CONTROL_DT)  # 4.8 rad > π
    assert metrics.rolled_over[0]


def test_half_a_turn_is_not_rolling_over():
    metrics = EpisodeMetrics(1, 1)
    for _ in range(10):  # 10 × 0.02 s × 15 rad/s = 3.0 rad < π
        metrics.update(np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), np.array([15.0]),
                       np.zeros(1), np.zeros(1), np.array([False]))
    assert not metrics.rolled_over[0]
