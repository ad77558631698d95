"""The per-step summaries rewritten for speed give the numbers of the straightforward code they replace, bit for bit:
contact summaries, projected gravity, the training env's height lookups and its observation clean-up."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.backends.base import CONTACT_FORCE_THRESHOLD, summarize_contacts
from frbench.backends.contact_layout import as_slice, vector_norm
from frbench.robots import get_robot
from frbench.robots.sim_urdf import sim_robot_file
from frbench.tasks.observations import cross_rows, projected_gravity, rotate_to_body


def _forces(rng, n: int, links: int) -> np.ndarray:
    """Net link forces with exact zeros, negative zeros, forces at the contact threshold and large ones."""
    force = rng.normal(scale=30.0, size=(n, links, 3))
    force[rng.random((n, links)) < 0.3] = 0.0
    force[rng.random((n, links)) < 0.1] = -0.0
    force[0, 0] = [CONTACT_FORCE_THRESHOLD, 0.0, 0.0]
    return force


def _reference_contacts(spec, link_names, link_force):
    """The per-group loops `summarize_contacts` replaced."""
    where = {name: i for i, name in enumerate(link_names)}
    norm = np.linalg.norm(link_force, axis=-1)
    touching = norm > CONTACT_FORCE_THRESHOLD
    groups = [np.array([where[l] for l in g.links]) for g in spec.contact_groups]
    knees = [np.array([where[l] for l in g.links]) for g in spec.knee_groups]
    feet = np.array([link_names.index(f) for f in spec.foot_links])
    rest = np.setdiff1d(np.arange(len(link_names)), feet)
    knee = np.stack([link_force[:, idx].sum(axis=1) for idx in knees], axis=1)
    return {
        "group_contact": np.stack([touching[:, idx].any(axis=1) for idx in groups], axis=1),
        "foot_force": norm[:, feet],
        "foot_contact": norm[:, feet] > CONTACT_FORCE_THRESHOLD,
        "knee_force_xy": np.linalg.norm(knee[..., :2], axis=-1),
        "body_force_max": norm[:, rest].max(axis=1),
    }


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("robot", ["go2", "g1"])
def test_contact_summaries_equal_the_per_group_loops(robot):
    spec = get_robot(robot)
    links = sim_robot_file(spec).links
    force = _forces(np.random.default_rng(3), 64, len(links))
    contacts = summarize_contacts(spec, links, force)
    for name, wanted in _reference_contacts(spec, links, force).items():
        assert _same_bits(getattr(contacts, name), wanted), name


def test_vector_norm_and_index_runs():
    x = np.random.default_rng(0).normal(size=(50, 7, 3))
    assert _same_bits(vector_norm(x), np.linalg.norm(x, axis=-1))
    assert as_slice(np.array([3, 4, 5])) == slice(3, 6)
    assert isinstance(as_slice(np.array([3, 5])), np.ndarray)
    assert isinstance(as_slice(np.array([], dtype=int)), np.ndarray)


def test_rotations_equal_numpy_cross_products_bit_for_bit():
    rng = np.random.default_rng(1)
    quat = rng.normal(size=(200, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    quat[:5] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1], [-0.0, 0.0, 1.0, -0.0], [0.5, -0.5, 0.5, -0.5]]
    vectors = rng.normal(size=(200, 3))
    a, b = quat[:, 1:], vectors
    assert _same_bits(cross_rows(a, b), np.cross(a, b))
    w, xyz = quat[:, :1], quat[:, 1:]
    t = 2.0 * np.cross(xyz, vectors)
    assert _same_bits(rotate_to_body(quat, vectors), vectors - w * t + np.cross(xyz, t))
    down = np.zeros((200, 3))
    down[:, 2] = -1.0
    t = 2.0 * np.cross(xyz, down)
    assert _same_bits(projected_gravity(quat), down - w * t + np.cross(xyz, t))
    assert np.allclose(projected_gravity(quat[:1]), [[0.0, 0.0, -1.0]])


def test_raster_lookups_equal_the_clipped_nearest_cell_rule():
    from frbench.terrains import SCAN_POINTS
    from frbench.training.height_raster import HALF_SIZE, RESOLUTION, HeightRaster
    from frbench.training.terrain_grid import build_grid

    grid = build_grid(("flat", "stairs", "gaps"))
    raster = HeightRaster(grid, sorted(grid.tiles))
    rng = np.random.default_rng(2)
    n = 40
    tile = rng.integers(0, len(raster.tile_keys), size=n)
    xy = raster.centres[tile][:, None, :] + rng.uniform(-4.5, 4.5, size=(n, 30, 2))  # points on and off the raster

    def reference(tile, xy):
        ij = np.rint((xy - raster.centres[tile][:, None, :] + HALF_SIZE) / RESOLUTION).astype(np.int64)
        inside = np.all((ij >= 0) & (ij < raster.n), axis=-1)
        ij = np.clip(ij, 0, raster.n - 1)
        return np.where(inside, raster.heights[tile[:, None], ij[..., 0], ij[..., 1]], raster.floor)

    assert _same_bits(raster.lookup(tile, xy), reference(tile, xy))
    base = np.concatenate([raster.centres[tile] + rng.uniform(-3, 3, size=(n, 2)), rng.uniform(0, 1, (n, 1))], 1)
    yaw = rng.uniform(-np.pi, np.pi, size=n)
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    px, py = SCAN_POINTS[:, 0][None], SCAN_POINTS[:, 1][None]
    points = np.stack([base[:, :1] + c * px - s * py, base[:, 1:2] + s * px + c * py], axis=-1)
    assert _same_bits(raster.scan(tile, base, yaw), base[:, 2:3] - reference(tile, points))


def test_observation_groups_zero_only_what_is_invalid():
    from frbench.tasks.core_env import zero_invalid as _zero_invalid

    value = np.arange(12.0).reshape(4, 3)
    assert _zero_invalid(value, None) is value
    bad = value.copy()
    bad[1, 2], bad[2, 0] = np.nan, np.inf
    alive = np.array([True, True, True, False])
    cleaned = _zero_invalid(bad, alive)
    wanted = np.where(alive[:, None], np.nan_to_num(bad, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
    assert _same_bits(cleaned, wanted)
    assert cleaned[1, 2] == 0.0 and cleaned[2, 0] == 0.0 and not cleaned[3].any()


@pytest.mark.parametrize("robot", ["go2", "g1", "spot_like"])
def test_start_geometry_equals_the_kinematics_module_bit_for_bit(robot):
    from frbench.portable_products import norm
    from frbench.robots.kinematics import link_poses, lowest_point
    from frbench.robots.urdf_tree import parse_urdf
    from frbench.tasks.initial_states import lowest_offset_and_reach, quat_to_matrix

    spec = get_robot(robot)
    tree = parse_urdf(sim_robot_file(spec).path)
    kinds = {c.kind for link in tree.links.values() for c in link.collisions}
    assert kinds & {"sphere", "box", "cylinder"}
    rng = np.random.default_rng(4)
    for _ in range(40):
        quat = rng.normal(size=4)
        q = rng.uniform(spec.joint_lower, spec.joint_upper)
        rotation = np.eye(4)
        rotation[:3, :3] = quat_to_matrix(quat)
        world = {name: rotation @ pose for name, pose in link_poses(tree, dict(zip(spec.joint_names, q))).items()}
        lowest = lowest_point(tree, world, tree.links)
        # the reach is a norm of 2 numbers, summed in one fixed order on every processor (portable_products)
        reach = max(norm(pose[:2, 3]) for pose in world.values()) + 0.15
        got = lowest_offset_and_reach(spec, quat, q)
        assert _same_bits(np.float64(got[0]), np.float64(lowest)) and _same_bits(np.float64(got[1]), np.float64(reach))


class _SequentialSuccess:
    """The per-step success test `SuccessTracker.update_steps` replaced (one step at a time)."""

    def __init__(self, tracker):
        self.t = tracker
        self.success = tracker.success.copy()
        self.time_to_recover = tracker.time_to_recover.copy()
        self.streak, self.step = tracker._streak.copy(), tracker._step

    def update(self, s, alive):
        from frbench.tasks.success import HOLD_STEPS, MAX_DISPLACEMENT
        from frbench.tasks.protocol import CONTROL_DT

        self.step += 1
        up = self.t.upright(s) & alive
        self.streak = np.where(up, self.streak + 1, 0)
        done = (self.streak >= HOLD_STEPS) & ~self.success & (s.displacement < MAX_DISPLACEMENT)
        self.time_to_recover[done] = (self.step - HOLD_STEPS + 1) * CONTROL_DT
        self.success |= done
        self.success &= alive


def _random_signals(rng, k, n):
    from frbench.tasks.success import StepSignals

    upright = rng.random((k, n)) < 0.9  # long upright runs, broken now and then
    return StepSignals(
        gravity_z=np.where(upright, -0.99, -0.2), height=np.full((k, n), 0.3),
        body_contact=rng.random((k, n)) < 0.02, displacement=rng.uniform(0.0, 1.3, (k, n)),
        surface_drop=np.where(rng.random((k, n)) < 0.02, 0.5, 0.0),
    )


@pytest.mark.parametrize("chunks", [[1] * 90, [90], [7, 50, 1, 32], [25, 25, 40]])
def test_success_steps_at_once_equal_one_step_at_a_time(chunks):
    from frbench.tasks.success import StepSignals, SuccessTracker

    rng = np.random.default_rng(7)
    k, n = sum(chunks), 24
    signals = _random_signals(rng, k, n)
    alive = np.ones((k, n), dtype=bool)
    alive[60:, 3] = False  # diverged late
    alive[rng.integers(0, k, size=4), rng.integers(0, n, size=4)] = False  # and single dead steps
    tracker = SuccessTracker(n, "quadruped", 0.3)
    reference = _SequentialSuccess(tracker)
    start = 0
    for size in chunks:
        part = StepSignals(*(getattr(signals, f)[start:start + size] for f in
                             ("gravity_z", "height", "body_contact", "displacement", "surface_drop")))
        tracker.update_steps(part, alive[start:start + size])
        for t in range(start, start + size):
            reference.update(StepSignals(*(getattr(signals, f)[t] for f in
                                           ("gravity_z", "height", "body_contact", "displacement", "surface_drop"))),
                             alive[t])
        start += size
        assert np.array_equal(tracker.success, reference.success)
        assert _same_bits(tracker.time_to_recover, reference.time_to_recover)
        assert np.array_equal(tracker._streak, reference.streak) and tracker._step == reference.step
    assert 0 < tracker.success.sum() < n and not tracker.success[3]


def _sequential_metrics(n, j, steps):
    """The per-step metrics `EpisodeMetrics.update_steps` replaced."""
    from frbench.tasks.protocol import CONTROL_DT

    energy, peak, most, final, roll = (np.zeros(n) for _ in range(5))
    rolled, diverged_any, second, count, prev, prev2 = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n), 0, None, None
    for q, qd, tau, ang, force, disp, diverged in steps:
        ok = ~diverged
        energy += np.where(ok, np.abs(tau * qd).sum(axis=1) * CONTROL_DT, 0.0)
        peak = np.maximum(peak, np.where(ok, force, 0.0))
        most = np.maximum(most, np.where(ok, disp, 0.0))
        final = np.where(ok, disp, final)
        roll += np.where(ok, ang * CONTROL_DT, 0.0)
        rolled |= np.abs(roll) > np.pi
        diverged_any |= diverged
        if prev2 is not None:
            second += np.where(ok, np.abs(q - 2 * prev + prev2).mean(axis=1), 0.0)
            count += 1
        prev2, prev = prev, q.copy()
    return dict(energy=energy, peak_contact_force=peak, max_displacement=most, final_displacement=final, roll=roll,
                rolled_over=rolled, diverged=diverged_any, smoothness=second / max(count, 1))


@pytest.mark.parametrize("chunks", [[1] * 40, [40], [1, 1, 30, 8], [2, 38]])
def test_metrics_steps_at_once_equal_one_step_at_a_time(chunks):
    from frbench.tasks.success import EpisodeMetrics

    rng = np.random.default_rng(8)
    n, j = 10, 12
    steps = []
    for t in range(sum(chunks)):
        diverged = np.zeros(n, dtype=bool)
        diverged[2] = t >= 25
        q, qd, tau = (rng.normal(size=(n, j)) for _ in range(3))
        steps.append((q, qd, tau, rng.normal(scale=40.0, size=n), rng.uniform(0, 300, n), rng.uniform(0, 2, n),
                      diverged))
    steps[30][2][4, 0] = np.nan  # a NaN torque in a valid row propagates as before
    metrics, start = EpisodeMetrics(n, j), 0
    for size in chunks:
        metrics.update_steps(*(np.stack([s[i] for s in steps[start:start + size]]) for i in range(7)))
        start += size
    for name, wanted in _sequential_metrics(n, j, steps).items():
        assert _same_bits(getattr(metrics, name), wanted), name
    assert metrics.rolled_over.any() and metrics.diverged[2]
