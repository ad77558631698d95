"""FR-Net reward terms on hand-made states with hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from frbench.training import rewards as R

J = 12


def make_inputs(n: int = 1, **overrides) -> R.RewardInputs:
    """An upright robot at rest in its standing pose, at its start, feet down, nothing else touching."""
    q_stand = np.linspace(-1.0, 1.0, J)
    values = dict(
        projected_gravity=np.tile([0.0, 0.0, -1.0], (n, 1)),
        q=np.tile(q_stand, (n, 1)),
        qd=np.zeros((n, J)),
        qd_prev=np.zeros((n, J)),
        tau=np.zeros((n, J)),
        action=np.zeros((n, J)),
        action_prev=np.zeros((n, J)),
        q_stand=q_stand,
        q_lower=np.full(J, -2.0),
        q_upper=np.full(J, 2.0),
        foot_contact=np.ones((n, 4), dtype=bool),
        body_contact=np.zeros(n, dtype=bool),
        knee_force_xy=np.zeros((n, 4)),
        base_xy=np.zeros((n, 2)),
        init_xy=np.zeros((n, 2)),
    )
    values.update(overrides)
    return R.RewardInputs(**values)


def test_paper_weights_exactly_the_table():
    assert R.PAPER_WEIGHTS == {
        "base_orientation": -0.5,
        "upright_orientation": 6.0,
        "target_posture": 4.0,
        "feet_contact": 0.3,
        "body_contact": -0.2,
        "safety_force": -0.01,
        "body_bias": -0.1,
        "position_limits": -1.0,
        "velocity_limit": -0.1,
        "joint_acceleration": -2.5e-6,
        "joint_velocity": -0.01,
        "action_smoothing": -0.01,
        "joint_torques": -5e-4,
    }
    # frbench's additions: a base-height term for every robot, four humanoid terms
    assert set(R.REWARD_TERMS) == set(R.PAPER_WEIGHTS) | {"base_height", "head_height", "feet_on_ground",
                                                          "upper_body_posture", "action_jerk"}
    assert R.RewardConfig().weights == R.PAPER_WEIGHTS
    assert R.stability_terms == ("safety_force", "body_bias")


def test_orientation_terms_upright_supine_side():
    eps = 0.4
    g = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.6, 0.0, -0.8]])
    x = make_inputs(4, projected_gravity=g)
    np.testing.assert_allclose(R.upright_orientation(x, eps), [1.0, math.exp(-4 / (2 * eps**2)), math.exp(-1 / (2 * eps**2)), math.exp(-0.04 / 0.32)])
    np.testing.assert_allclose(R.base_orientation(x), [0.0, 0.0, 1.0, 0.36])


def test_target_posture_gated_off_on_the_back():
    n = 3
    x = make_inputs(n, projected_gravity=np.array([[0, 0, -1.0], [0, 0, 1.0], [0, 0.866, -0.5]]))
    x.q[0, :2] += [0.3, 0.4]  # Σ(q − q_stand)² = 0.25
    np.testing.assert_allclose(R.target_posture(x, 0.4), [math.exp(-0.25), 0.0, 0.0])  # |−0.5 + 1| = 0.5, not < 0.4
    np.testing.assert_allclose(R.target_posture(x, 0.51), [math.exp(-0.25), 0.0, 1.0])
    # per-env targets (N, J) work too
    x.q_stand = np.tile(x.q_stand, (n, 1))
    np.testing.assert_allclose(R.target_posture(x, 0.51), [math.exp(-0.25), 0.0, 1.0])


def test_contact_terms():
    feet = np.array([[True, False, True, True], [False] * 4])
    x = make_inputs(2, foot_contact=feet, body_contact=np.array([False, True]))
    np.testing.assert_array_equal(R.feet_contact(x), [3.0, 0.0])
    np.testing.assert_array_equal(R.body_contact(x), [0.0, 1.0])


def test_stability_terms():
    x = make_inputs(
        3,
        knee_force_xy=np.array([[3.0, 4.0, 0.0, 0.0], [5.0, 0.0, 0.0, 0.0], [0.0] * 4]),
        base_xy=np.array([[3.0, 4.0], [1.0, 1.0], [4.0, 6.0]]),
        init_xy=np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 2.0]]),
    )
    np.testing.assert_allclose(R.safety_force(x), [7.0, 5.0, 0.0])
    np.testing.assert_allclose(R.body_bias(x), [4.0, 0.0, 4.0])  # 5 m clipped to 4; 0; 5 m clipped
    x.base_xy[2] = [1.0 + 0.6, 2.0 + 0.8]
    assert R.body_bias(x)[2] == pytest.approx(1.0)


def test_position_limits_counts_joints_outside():
    x = make_inputs(2)
    x.q[0, 0] = 2.1  # 0.1 rad past the upper limit
    x.q[1, 3] = -2.5
    x.q[1, 4] = 2.0  # on the limit: inside
    x.q[1, 5] = 3.0
    np.testing.assert_array_equal(R.position_limits(x), [1.0, 2.0])


def test_velocity_limit_literal_and_per_joint():
    qd = np.zeros((1, J))
    qd[0, :3] = [1.0, -2.0, 0.5]
    x = make_inputs(1, qd=qd)
    np.testing.assert_allclose(R.velocity_limit(x), [0.2 + 1.2])
    thresholds = np.full(J, 1.5)
    np.testing.assert_allclose(R.velocity_limit(x, thresholds), [0.5])


def test_joint_acceleration_velocity_smoothing_torques():
    qd, qd_prev = np.zeros((1, J)), np.zeros((1, J))
    qd[0, 0], qd_prev[0, 0] = 1.0, 0.8  # 0.2 rad/s over 0.02 s = 10 rad/s²
    qd[0, 1], qd_prev[0, 1] = -0.5, 0.1  # −30 rad/s²
    a, a_prev = np.zeros((1, J)), np.zeros((1, J))
    a[0, 2], a_prev[0, 2] = 0.5, 0.2
    tau = np.zeros((1, J))
    tau[0, :2] = [3.0, -4.0]
    x = make_inputs(1, qd=qd, qd_prev=qd_prev, action=a, action_prev=a_prev, tau=tau)
    np.testing.assert_allclose(R.joint_acceleration(x), [100.0 + 900.0])
    np.testing.assert_allclose(R.joint_velocity(x), [1.25])
    np.testing.assert_allclose(R.action_smoothing(x), [0.09])
    np.testing.assert_allclose(R.joint_torques(x), [25.0])
    x.dt = 0.01
    np.testing.assert_allclose(R.joint_acceleration(x), [4000.0])


def test_every_term_returns_float_n():
    x = make_inputs(5)
    x.base_height, x.nominal_height = np.full(5, 0.2), 0.3
    x.head_height, x.nominal_head_height = np.full(5, 0.5), 1.2
    x.action_prev2, x.upper_body = np.zeros((5, J)), np.arange(J) >= 8
    for name, fn in R.REWARD_TERMS.items():
        value = fn(x)
        assert value.shape == (5,), name
        assert value.dtype == np.float64, name


def test_total_is_sum_of_weighted_terms():
    rng = np.random.default_rng(0)
    n = 6
    x = make_inputs(
        n,
        projected_gravity=rng.normal(size=(n, 3)),
        q=rng.normal(size=(n, J)),
        qd=rng.normal(size=(n, J)) * 3,
        qd_prev=rng.normal(size=(n, J)),
        tau=rng.normal(size=(n, J)) * 10,
        action=rng.normal(size=(n, J)),
        action_prev=rng.normal(size=(n, J)),
        foot_contact=rng.random((n, 4)) < 0.5,
        body_contact=rng.random(n) < 0.5,
        knee_force_xy=rng.random((n, 4)) * 50,
        base_xy=rng.normal(size=(n, 2)) * 3,
    )
    for scale_by_dt in (False, True):
        config = R.RewardConfig(scale_by_dt=scale_by_dt)
        total, terms = R.compute_rewards(x, config)
        assert set(terms) == set(R.PAPER_WEIGHTS)
        np.testing.assert_allclose(total, sum(terms.values()))
        factor = x.dt if scale_by_dt else 1.0
        for name, weighted in terms.items():
            kwargs = {"epsilon": config.epsilon} if name in ("upright_orientation", "target_posture") else {}
            np.testing.assert_allclose(weighted, R.PAPER_WEIGHTS[name] * R.REWARD_TERMS[name](x, **kwargs) * factor)


def test_upright_standing_robot_total_by_hand():
    x = make_inputs(1)  # upright, at the standing pose, 4 feet down, at rest
    total, _ = R.compute_rewards(x, R.RewardConfig(scale_by_dt=False))
    assert total[0] == pytest.approx(6.0 + 4.0 + 4 * 0.3)
    total, _ = R.compute_rewards(x)
    assert total[0] == pytest.approx((6.0 + 4.0 + 4 * 0.3) * 0.02)


def test_config_without_stability_terms():
    x = make_inputs(2, knee_force_xy=np.full((2, 4), 10.0), base_xy=np.ones((2, 2)))
    config = R.RewardConfig().without(R.stability_terms, reason="ablation: no stability reward")
    total, terms = R.compute_rewards(x, config)
    assert not set(R.stability_terms) & set(terms)
    full_total, full_terms = R.compute_rewards(x)
    np.testing.assert_allclose(total, full_total - full_terms["safety_force"] - full_terms["body_bias"])
    assert config.deviations() == {
        "safety_force": (-0.01, None, "ablation: no stability reward"),
        "body_bias": (-0.1, None, "ablation: no stability reward"),
    }


def test_config_deviations_need_a_reason():
    with pytest.raises(ValueError, match="give a reason"):
        R.RewardConfig(weights={**R.PAPER_WEIGHTS, "joint_torques": -1e-4})
    with pytest.raises(ValueError, match="equal the paper"):
        R.RewardConfig(overrides_reason={"joint_torques": "no change"})
    with pytest.raises(ValueError, match="unknown"):
        R.RewardConfig(weights={**R.PAPER_WEIGHTS, "walking": 1.0})
    config = R.RewardConfig().with_weight("joint_torques", -1e-4, "heavier robots")
    assert config.weights["joint_torques"] == -1e-4
    assert config.deviations() == {"joint_torques": (-5e-4, -1e-4, "heavier robots")}
    assert config.with_weight("joint_torques", -5e-4, "back").deviations() == {}


def test_epsilon_and_threshold_reach_the_terms():
    x = make_inputs(1, projected_gravity=np.array([[0.0, 0.6, -0.8]]), qd=np.full((1, J), 1.0))
    config = R.RewardConfig(epsilon=0.1, velocity_threshold=(0.5,) * J, scale_by_dt=False)
    _, terms = R.compute_rewards(x, config)
    assert terms["upright_orientation"][0] == pytest.approx(6.0 * math.exp(-0.04 / 0.02))
    assert terms["target_posture"][0] == 0.0  # |−0.8 + 1| = 0.2 ≥ 0.1
    assert terms["velocity_limit"][0] == pytest.approx(-0.1 * 12 * 0.5)


def test_shape_errors_name_the_field():
    x = make_inputs(2)
    x.tau = np.zeros((2, J + 1))
    with pytest.raises(ValueError, match="tau"):
        R.compute_rewards(x)


def test_base_height_term_is_height_over_nominal_clipped():
    n = 3
    x = R.RewardInputs(
        projected_gravity=np.tile([0.0, 0.0, -1.0], (n, 1)), q=np.zeros((n, 2)), qd=np.zeros((n, 2)),
        qd_prev=np.zeros((n, 2)), tau=np.zeros((n, 2)), action=np.zeros((n, 2)), action_prev=np.zeros((n, 2)),
        q_stand=np.zeros(2), q_lower=-np.ones(2), q_upper=np.ones(2), foot_contact=np.zeros((n, 4), bool),
        body_contact=np.zeros(n, bool), knee_force_xy=np.zeros((n, 4)), base_xy=np.zeros((n, 2)),
        init_xy=np.zeros((n, 2)), base_height=np.array([0.15, 0.45, -0.1]), nominal_height=0.3,
    )
    np.testing.assert_allclose(R.base_height(x), [0.5, 1.0, 0.0])


# --------------------------------------------------------------------------- humanoid terms


def test_head_height_is_height_over_nominal_clipped():
    x = make_inputs(3, head_height=np.array([0.3, 1.2, 2.0]), nominal_head_height=1.2)
    np.testing.assert_allclose(R.head_height(x), [0.25, 1.0, 1.0])
    with pytest.raises(ValueError, match="head_height needs RewardInputs.head_height"):
        R.head_height(make_inputs())


def test_feet_on_ground_counts_only_once_risen():
    feet = np.array([[True, True], [True, False], [True, True]])
    x = make_inputs(3, foot_contact=feet, base_height=np.array([0.7, 0.7, 0.3]), nominal_height=0.78)
    # half-height gate at 0.39 m: the third robot lies with its soles down and earns nothing
    np.testing.assert_allclose(R.feet_on_ground(x), [1.0, 0.5, 0.0])


def test_upper_body_posture_reads_only_the_masked_joints_and_is_gated():
    mask = np.zeros(J, dtype=bool)
    mask[-4:] = True
    q_stand = np.linspace(-1.0, 1.0, J)
    q = np.tile(q_stand, (3, 1))
    q[1, -1] += 0.5  # an arm joint 0.5 rad off: exp(-0.25)
    q[:, 0] += 1.0  # a leg joint off: not read
    gravity = np.array([[0, 0, -1.0], [0, 0, -1.0], [0, 0, 1.0]])
    x = make_inputs(3, q=q, projected_gravity=gravity, upper_body=mask)
    np.testing.assert_allclose(R.upper_body_posture(x), [1.0, math.exp(-0.25), 0.0])


def test_action_jerk_is_the_second_difference():
    a2, a1, a0 = np.zeros((1, J)), np.full((1, J), 0.1), np.full((1, J), 0.5)
    x = make_inputs(action=a0, action_prev=a1, action_prev2=a2)
    # (0.5 - 0.2 + 0)^2 = 0.09 per joint
    np.testing.assert_allclose(R.action_jerk(x), [J * 0.09])
    constant_velocity = make_inputs(action=np.full((1, J), 0.2), action_prev=a1, action_prev2=a2)
    np.testing.assert_allclose(R.action_jerk(constant_velocity), [0.0], atol=1e-15)
