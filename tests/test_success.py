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


def test_humanoid_uses_hosts_rule():
    g1 = 0.78
    up_then_stays = [_signals(height=0.3)] * 5 + [_signals(height=0.75)] + [_signals(height=0.55)] * 10
    up_then_falls = [_signals(height=0.75)] + [_signals(height=0.49)]
    never_up = [_signals(height=0.69)] * 20
    assert _run(up_then_stays, "humanoid", g1).success[0]
    assert _run(up_then_stays, "humanoid", g1).time_to_recover[0] == pytest.approx(6 * CONTROL_DT)
    assert not _run(up_then_falls, "humanoid", g1).success[0]
    assert not _run(never_up, "humanoid", g1).success[0]
    # thresholds scale with the robot's height: a 0.39 m humanoid needs 0.35 m
    assert _run([_signals(height=0.36)] * 3, "humanoid", 0.39).success[0]


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
