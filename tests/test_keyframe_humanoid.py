"""The ``keyframe-humanoid`` controller: its shipped parameters, its actions, one real prone episode (slow)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from frbench.policies.keyframe_humanoid import (
    INITIAL,
    LOWER,
    PARAMETER_NAMES,
    PARAMS_FILE,
    UPPER,
    KeyframeHumanoidPolicy,
    decode,
    load_parameters,
)
from frbench.policies.registry import load_policy
from frbench.robots import get_robot
from frbench.backends import make_backend
from tests.test_scripted import _obs
from tools.keyframe_search import (
    episode_scores,
    non_prone_starts,
    roll_scores,
    starts_of_kind,
    upright_success,
)


def test_parameter_file_loads_and_is_within_bounds():
    params = load_parameters()
    assert params.shape == (len(PARAMETER_NAMES),) and np.isfinite(params).all()
    assert (params >= LOWER).all() and (params <= UPPER).all()
    assert np.allclose(decode(np.zeros_like(INITIAL)), INITIAL)
    assert "command" in json.loads(PARAMS_FILE.read_text())


def test_registered_and_acts_within_the_joint_limits():
    spec = get_robot("g1")
    lower, upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    policy = load_policy("keyframe-humanoid")
    assert isinstance(policy, KeyframeHumanoidPolicy) and policy.supports(spec)
    assert not policy.supports(get_robot("go2"))
    gravity = [(1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)]
    policy.reset(spec, len(gravity))
    q = np.tile(spec.default_pose, (len(gravity), 1))
    visited = set()
    for _ in range(250):
        targets = policy.act(_obs(spec, gravity, q=q))
        assert targets.shape == (len(gravity), spec.n_joints) and np.isfinite(targets).all()
        assert (targets >= lower - 1e-9).all() and (targets <= upper + 1e-9).all()
        q = targets
        visited.update(policy.phase.tolist())
    assert len(visited) > 4  # the prone environment goes through the key frames


def test_one_parameter_row_per_environment():
    spec = get_robot("g1")
    rows = np.stack([INITIAL, decode(np.ones_like(INITIAL))])
    policy = KeyframeHumanoidPolicy(rows)
    policy.reset(spec, 2)
    assert not np.allclose(policy.env_poses[max(policy.env_poses)][0], policy.env_poses[max(policy.env_poses)][1])


def test_initial_roll_parameters_reproduce_the_scripted_roll_and_tuned_ones_change_it():
    from frbench.policies.scripted_humanoid import HumanoidScriptedPolicy

    spec = get_robot("g1")
    scripted = HumanoidScriptedPolicy()
    scripted.reset(spec, 1)
    tuned = INITIAL.copy()
    tuned[PARAMETER_NAMES.index("roll.waist_yaw")] = 0.4
    policy = KeyframeHumanoidPolicy(np.stack([INITIAL, tuned]))
    policy.reset(spec, 2)
    yaw = spec.joint_names.index("waist_yaw_joint")
    for direction in (-1, 1):
        for stage in (0, 1):
            assert np.allclose(policy.env_roll[direction, stage][0], scripted.roll_pose(direction, stage))
            assert policy.env_roll[direction, stage][1][yaw] == pytest.approx(0.4 * direction)
    assert policy.ramp[0, 1] == 30  # ramp.roll (ROLL is phase 1)


def test_roll_score_prefers_an_early_roll_that_stays_face_down():
    from frbench.policies.scripted_humanoid import LIE, PUSH_A, ROLL

    steps = 120
    phases = np.full((steps, 4), ROLL)
    phases[:10] = LIE
    phases[30:, 0] = PUSH_A  # face down early
    phases[90:, 1] = PUSH_A  # face down late
    phases[30:, 3] = PUSH_A  # face down early, then tips back onto the side
    gravity_x = np.zeros((steps, 4))
    gravity_x[30:, 0] = gravity_x[90:, 1] = 0.9
    gravity_x[30:60, 3] = 0.9
    scores = roll_scores(phases, gravity_x)
    assert scores[0] == pytest.approx(2 + (1 - 30 / 120) + 0.45 + 0.45)
    assert scores[2] == 0.0  # never left ROLL, never face down
    assert scores[0] > scores[3] > scores[1] > scores[2]


def test_roll_starts_are_the_non_prone_ones():
    starts = non_prone_starts([4], episodes=8)
    assert (4, 1) not in starts and len(starts) == 7  # seed 4 episode 1 is the only prone start of the eight


def test_prone_starts_are_the_rest():
    assert starts_of_kind([4], ("prone",), episodes=8) == [(4, 1)]


def test_a_prone_stage_search_tunes_only_the_way_into_the_crouch_in_both_backends(tmp_path):
    """Two generations of two candidates, 5 control steps in MuJoCo and PyBullet from one prone start: the file
    it writes keeps every parameter outside `PRONE_PARAMETERS` at ``--init`` and names both backends' starts."""
    from tools.keyframe_search import PRONE_PARAMETERS, main

    assert len(PRONE_PARAMETERS) == 30 and "ramp.lift" in PRONE_PARAMETERS and "ramp.rise" not in PRONE_PARAMETERS
    assert not any(n.startswith(("roll", "fb.", "stand.")) for n in PRONE_PARAMETERS)
    out = tmp_path / "prone.json"
    main(["--stage", "prone", "--prone-seeds", "4", "--backends", "mujoco,pybullet", "--steps", "5",
          "--deadline", "3", "--popsize", "2", "--generations", "2", "--sigma", "0.5", "--init", str(PARAMS_FILE),
          "--out", str(out)])
    found, init = json.loads(out.read_text()), dict(zip(PARAMETER_NAMES, load_parameters(PARAMS_FILE)))
    assert len(found["successes"]) == 2 and not any(found["successes"])  # one start per backend, 5 steps: down
    changed = {n for n in PARAMETER_NAMES if abs(found["parameters"][n] - init[n]) > 1e-6}
    assert changed and changed <= set(PRONE_PARAMETERS)


def test_sit_up_parameters_set_the_tuck_prop_rock_poses_ramps_and_tries():
    from frbench.policies.scripted_humanoid import (
        PROP,
        ROCK,
        TUCK,
        HumanoidScriptedPolicy,
    )

    spec = get_robot("g1")
    scripted = HumanoidScriptedPolicy()
    scripted.reset(spec, 1)
    tuned = INITIAL.copy()
    for name, value in (("prop.knee", 1.1), ("ramp.rock", 12), ("situp.tries", 2)):
        tuned[PARAMETER_NAMES.index(name)] = value
    policy = KeyframeHumanoidPolicy(np.stack([INITIAL, tuned]))
    policy.reset(spec, 2)
    for phase in (TUCK, PROP, ROCK):  # the initial values are the scripted key poses
        assert np.allclose(policy.env_poses[phase][0], scripted.poses[phase])
    knees = [spec.joint_names.index(f"{s}_knee_joint") for s in ("left", "right")]
    assert np.allclose(policy.env_poses[PROP][1][knees], 1.1)
    assert policy.ramp[1, ROCK] == 12 and policy.ramp[0, ROCK] == 25
    assert [policy._situp_tries(i) for i in (0, 1)] == [0, 2]


def test_after_a_sit_up_the_crouch_rise_and_feedback_are_the_sit_up_paths_own():
    """``sit_*`` parameters act only on an environment whose way to the crouch was a sit-up (entered ``TUCK``);
    entering ``PUSH_A`` switches it back to the belly path's crouch, stand pose, ramps and feedback."""
    from frbench.policies.scripted_humanoid import CROUCH, PUSH_A, RISE, TUCK

    spec = get_robot("g1")
    row = INITIAL.copy()
    for name, value in (("sit_stand.knee", 1.2), ("stand.knee", 0.4), ("ramp.sit_rise", 33), ("ramp.rise", 11),
                        ("sit_fb.kp_hip", 0.7), ("fb.kp_hip", -0.2), ("sit_crouch.knee", 2.5)):
        row[PARAMETER_NAMES.index(name)] = value
    policy = KeyframeHumanoidPolicy(row)
    policy.reset(spec, 1)
    policy.act(_obs(spec, [(-1.0, 0.0, 0.0)]))  # sets the starting targets
    knee = spec.joint_names.index("left_knee_joint")
    for way, (stand_knee, rise_ramp, kp_hip) in ((TUCK, (1.2, 33, 0.7)), (PUSH_A, (0.4, 11, -0.2))):
        policy._enter(0, way)
        policy._enter(0, RISE)
        assert policy.goal[0, knee] == pytest.approx(stand_knee) and policy.ramp[0, RISE] == rise_ramp
        assert policy._feedback()["fb.kp_hip"][0] == pytest.approx(kp_hip)
    policy._enter(0, TUCK)
    policy._enter(0, CROUCH)
    assert policy.goal[0, knee] == pytest.approx(2.5)


def test_entering_the_gate_restores_the_recorded_way_to_the_crouch():
    """A crouch recorded after a sit-up (`gate_paths` 1) restarts on the sit-up path's crouch pose, ramps and
    feedback; one recorded after the belly path (0), or with no paths given, on the belly path's."""
    from frbench.policies.scripted_humanoid import CROUCH, RISE

    spec = get_robot("g1")
    row = INITIAL.copy()
    for name, value in (("sit_crouch.knee", 2.5), ("crouch.knee", 1.9), ("ramp.sit_crouch", 21), ("ramp.crouch", 37),
                        ("ramp.sit_rise", 33), ("ramp.rise", 11)):
        row[PARAMETER_NAMES.index(name)] = value
    policy = KeyframeHumanoidPolicy(row)
    policy.reset(spec, 3)
    q = np.tile(spec.default_pose, (3, 1))
    policy.enter_gate(np.array([0, 1]), q[:2], q, paths=np.array([1, 0]))
    policy.enter_gate(np.array([2]), q[:1], q)
    knee = spec.joint_names.index("left_knee_joint")
    assert policy.phase.tolist() == [CROUCH] * 3
    assert policy.gate_paths().tolist() == [1, 0, 0]
    assert policy.goal[:, knee].tolist() == pytest.approx([2.5, 1.9, 1.9])
    assert policy.ramp[:, CROUCH].tolist() == [21, 37, 37] and policy.ramp[:, RISE].tolist() == [33, 11, 11]
    assert policy._feedback()["fb.kp_hip"].tolist() == pytest.approx(
        [row[PARAMETER_NAMES.index("sit_fb.kp_hip")], *[row[PARAMETER_NAMES.index("fb.kp_hip")]] * 2])


def test_the_residual_gate_opens_in_the_named_phases_only():
    from frbench.policies.scripted_humanoid import (
        CROUCH,
        HOLD,
        LIE,
        PROP,
        RISE,
        ROCK,
        TUCK,
        gate_phase_ids,
    )

    policy = KeyframeHumanoidPolicy()
    policy.reset(get_robot("g1"), 7)
    policy.phase[:] = [LIE, TUCK, PROP, ROCK, CROUCH, RISE, HOLD]
    assert policy.residual_gate().tolist() == [0, 0, 0, 0, 1, 1, 1]
    assert policy.residual_gate(("prop", "rock", "hold")).tolist() == [0, 0, 1, 1, 0, 0, 1]
    assert gate_phase_ids(("tuck", "rise")) == (TUCK, RISE)
    for bad in (("stand",), ()):
        with pytest.raises(ValueError, match=r"gate phases .*expected one or more of lie, roll"):
            gate_phase_ids(bad)


def test_a_supine_stage_search_tunes_only_the_sit_up_with_one_try(tmp_path):
    """Two generations of two candidates, 5 control steps in MuJoCo from the supine starts of seed 4: the file
    keeps every parameter outside `SUPINE_PARAMETERS` at ``--init`` except ``situp.tries``, which is 1."""
    from tools.keyframe_search import SUPINE_PARAMETERS, main

    assert len(SUPINE_PARAMETERS) == 48 and {"ramp.tuck", "sit_fb.kc_hip", "ramp.sit_rise"} <= set(SUPINE_PARAMETERS)
    assert not {"situp.tries", "fb.kc_hip", "stand.knee", "ramp.rise"} & set(SUPINE_PARAMETERS)
    out = tmp_path / "supine.json"
    main(["--stage", "supine", "--supine-seeds", "4", "--steps", "5", "--popsize", "2", "--generations", "2",
          "--init", str(PARAMS_FILE), "--out", str(out)])
    found, init = json.loads(out.read_text()), load_parameters(PARAMS_FILE)
    assert found["starts"] == [[4, 0], [4, 5]]  # seed 4's supine starts
    changed = {n for i, n in enumerate(PARAMETER_NAMES) if abs(found["parameters"][n] - init[i]) > 1e-6}
    assert changed - {"situp.tries"} and changed <= set(SUPINE_PARAMETERS) | {"situp.tries"}
    assert found["parameters"]["situp.tries"] == 1
    main(["--stage", "supine", "--supine-seeds", "4", "--steps", "5", "--popsize", "2", "--generations", "1",
          "--init", str(PARAMS_FILE), "--only", "sit_stand.", "--out", str(out)])
    found = json.loads(out.read_text())["parameters"]
    changed = {n for i, n in enumerate(PARAMETER_NAMES) if abs(found[n] - init[i]) > 1e-6}
    assert changed - {"situp.tries"} and changed <= {"sit_stand.hip_pitch", "sit_stand.knee", "sit_stand.ankle_pitch",
                                                     "situp.tries"}


def test_extra_parameters_by_name_or_prefix_and_a_clear_error_otherwise():
    from tools.keyframe_search import SUPINE_PARAMETERS, extra_parameters

    assert extra_parameters("stand.,ramp.rise", SUPINE_PARAMETERS) == (
        "stand.hip_pitch", "stand.knee", "stand.ankle_pitch", "ramp.rise")
    assert extra_parameters("ramp.tuck", SUPINE_PARAMETERS) == ()  # already tuned by the stage
    for bad in ("stand", "nope.", "situp.tries"):
        with pytest.raises(SystemExit, match=f"--extra: '{bad}' names no tunable parameter"):
            extra_parameters(bad, SUPINE_PARAMETERS)
    with pytest.raises(SystemExit, match="--only: 'stand' names no tunable parameter"):
        extra_parameters("stand", (), "--only")


def test_shaped_score_ranks_upright_success_first():
    up, floor = 0.7, 0.5
    t = np.arange(250)[:, None]
    stays = np.where(t > 200, 0.75, 0.2)  # gets up late and stays
    falls = np.where((t > 100) & (t < 120), 0.8, 0.2)  # gets up and falls
    low = np.full((250, 1), 0.45)
    heights = np.hstack([stays, falls, low, stays])
    gravity_z = np.full_like(heights, -1.0)
    gravity_z[:, 3] = 1.0  # the same heights upside down: a hand stand, not up
    success = np.array([True, False, False, True])  # the task's height-only test
    scores = episode_scores(heights, gravity_z, success, up, floor)
    assert scores[0] > scores[1] > scores[2] and scores[0] > 100 > scores[3]
    assert upright_success(heights, gravity_z, success, up, floor).tolist() == [True, False, False, False]


def _phases_and_success(level: int, seed: int, episode: int) -> tuple[str, list[str], bool]:
    """The start kind of g1/flat/``level``/``seed`` episode ``episode`` in MuJoCo, the key frames' phases in order
    and the task's success over a whole episode with the shipped parameters."""
    from frbench.policies.scripted_humanoid import PHASE_NAMES
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import EPISODE_STEPS, RecoveryTask
    from frbench.terrains import make_terrain

    spec, terrain = get_robot("g1"), make_terrain("flat", level, seed)
    starts = draw_starts(spec, terrain, "flat", level, seed, range(episode + 1))
    task = RecoveryTask(spec, make_backend("mujoco", spec, episode + 1, terrain=terrain), terrain, episode + 1)
    obs, policy, phases = task.reset(starts), KeyframeHumanoidPolicy(), []
    policy.reset(spec, episode + 1)
    for _ in range(EPISODE_STEPS):
        obs = task.step(policy.act(obs))
        if not phases or phases[-1] != PHASE_NAMES[policy.phase[episode]]:
            phases.append(PHASE_NAMES[policy.phase[episode]])
    success = bool(task.success.success[episode])
    task.backend.close()
    return starts.kinds[episode], phases, success


@pytest.mark.slow
def test_a_side_start_tries_the_belly_route_then_sits_up_in_mujoco():
    """Seed 3, episode 3 of g1/flat/level 5 (a right-side start, held out from the grid's seeds 0-1): the roll and
    push-up do not bring the robot up, it lies back and gets up by the sit-up. Under protocol 1.1 no prone start
    gets up by the belly route (docs/results.md)."""
    kind, phases, success = _phases_and_success(5, 3, 3)
    assert kind == "right_side" and success
    assert phases == ["lie", "roll", "push_a", "lie", "tuck", "prop", "rock", "crouch", "rise", "hold"]


@pytest.mark.slow
def test_a_supine_start_gets_up_in_mujoco():
    from frbench.evaluation.runner import Cell, run_cell

    # seed 2, episode 2 of g1/flat/level 1 is a supine start (held out from the grid's seeds 0-1)
    record = run_cell(Cell("g1", "mujoco", "flat", 1, 2, 3), "keyframe-humanoid")[2]
    assert record["initial_pose"] == "supine"
    assert record["success"] and not record["diverged"] and 3.0 < record["time_to_recover"] < 4.0  # 3.48 s


@pytest.mark.slow
def test_a_supine_start_sits_up_and_is_up_within_four_seconds_in_mujoco():
    """Seed 0, episode 2 of g1/flat/level 5 (a supine start of the grid) with the shipped parameters: LIE → TUCK →
    PROP → ROCK → CROUCH → RISE → HOLD, no roll, and the task's success; the evaluator's time to stand (the start
    of protocol 1.1's hold) 3.84 s, under the 4.5 s that the belly route took under 1.0."""
    from frbench.evaluation.runner import Cell, run_cell

    kind, phases, success = _phases_and_success(5, 0, 2)
    assert kind == "supine" and success
    assert phases == ["lie", "tuck", "prop", "rock", "crouch", "rise", "hold"]
    record = run_cell(Cell("g1", "mujoco", "flat", 5, 0, 3), "keyframe-humanoid")[2]
    assert record["success"] and record["time_to_recover"] < 4.0


def test_results_carry_the_parameter_files_checksum():
    import hashlib

    from frbench.evaluation.grid import EvaluationRequest, build_results

    policy = load_policy("keyframe-humanoid")
    assert policy.checkpoint == PARAMS_FILE
    assert KeyframeHumanoidPolicy(INITIAL).checkpoint is None  # explicit parameters: no file behind them
    request = EvaluationRequest(policy="keyframe-humanoid", robots=["g1"], backends=["mujoco"], terrains=["flat"],
                                levels=[1], seeds=[0], episodes=1)
    results = build_results(request, policy, [])
    assert results["policy"]["checkpoint"] == str(PARAMS_FILE)
    assert results["policy"]["sha256"] == hashlib.sha256(PARAMS_FILE.read_bytes()).hexdigest()


def test_crouch_states_are_recorded_where_the_gate_opens(tmp_path):
    from tools.keyframe_states import MIN_CROUCH_HEIGHT, main, parse_seeds

    assert parse_seeds("4-6,9") == [4, 5, 6, 9]
    out = tmp_path / "crouch.npz"
    assert main(["--backend", "mujoco", "--seeds", "7", "--out", str(out)]) == 0
    states = np.load(out)
    n = len(states["q"])
    assert n >= 1 and states["targets"].shape == states["q"].shape == (n, 29)
    assert (states["base_pos"][:, 2] >= MIN_CROUCH_HEIGHT).all() and (states["seed"] == 7).all()
    assert ((states["step"] > 0) & (states["step"] < 250)).all()
    assert np.allclose(np.linalg.norm(states["base_quat"], axis=1), 1.0)


def test_parameter_files_from_before_the_balance_gains_load_without_them(tmp_path):
    from frbench.policies.keyframe_humanoid import ADDED_LATER

    values = {name: float(v) for name, v in zip(PARAMETER_NAMES, INITIAL) if name not in ADDED_LATER}
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"parameters": values}))
    loaded = load_parameters(old)
    assert np.allclose(loaded, INITIAL)
    assert all(loaded[PARAMETER_NAMES.index(n)] == 0.0 for n in ADDED_LATER if n.startswith("fb.k"))  # gains off
    assert loaded[PARAMETER_NAMES.index("situp.tries")] == 0  # and no sit-up: the file's motion is unchanged
    del values["ramp.rise"]
    old.write_text(json.dumps({"parameters": values}))
    with pytest.raises(ValueError, match=r"old\.json: missing parameters \['ramp\.rise'\]"):
        load_parameters(old)


def test_the_centre_of_mass_feedback_acts_only_while_rising_and_with_a_gain():
    spec = get_robot("g1")
    gains = INITIAL.copy()
    gains[PARAMETER_NAMES.index("fb.kc_ankle")] = 1.0  # rad/m
    plain, balanced = KeyframeHumanoidPolicy(INITIAL), KeyframeHumanoidPolicy(gains)
    lean = 0.2
    obs = _obs(spec, [(np.sin(lean), 0.0, -np.cos(lean))] * 2, q=np.tile(spec.default_pose, (2, 1)))
    for policy in (plain, balanced):
        policy.reset(spec, 2)
        policy.act(obs)
    assert np.allclose(plain.act(obs), balanced.act(obs))  # in LIE: no feedback
    from frbench.policies.scripted_humanoid import HOLD

    for policy in (plain, balanced):
        policy.phase[:] = HOLD
    ankle = spec.joint_names.index("left_ankle_pitch_joint")
    hip = spec.joint_names.index("left_hip_pitch_joint")
    difference = balanced.act(obs) - plain.act(obs)
    offset = balanced.balance.offset(obs["projected_gravity"][:1], obs["joint_pos"][:1])[0]
    assert offset > 0.1  # leaning forward: the CoM is ahead of the feet
    # the ankle target moves by the gain times the error; the hips have no CoM gain
    assert np.isclose(difference[0, ankle], 1.0 * (offset - INITIAL[PARAMETER_NAMES.index("fb.com_ref")]))
    assert difference[0, hip] == 0.0


def test_an_up_after_the_deadline_does_not_count():
    t = np.arange(150)[:, None]
    heights = np.hstack([np.where(t > 30, 0.8, 0.3), np.where(t > 60, 0.8, 0.3)])  # up at step 31 / 61, stays
    gravity_z, success = np.full_like(heights, -1.0), np.array([True, True])
    assert upright_success(heights, gravity_z, success, 0.7, 0.5).tolist() == [True, True]
    assert upright_success(heights, gravity_z, success, 0.7, 0.5, deadline=45).tolist() == [True, False]
    early, late = episode_scores(heights, gravity_z, success, 0.7, 0.5, deadline=45)
    assert early > 150 and late < 20


def test_late_ups_earn_less_the_later_they_are():
    t = np.arange(150)[:, None]
    ups = (40, 50, 60, 70, 100)  # deadline 45, late window 30: in time, 6, 16 and 26 steps late, too late
    heights = np.hstack([np.where(t >= u, 0.8, 0.3) for u in ups])
    gravity_z, success = np.full_like(heights, -1.0), np.ones(len(ups), bool)
    scores = episode_scores(heights, gravity_z, success, 0.7, 0.5, deadline=45, late=30)
    base = episode_scores(heights, gravity_z, success, 0.7, 0.5, deadline=45)
    assert scores[0] == pytest.approx(base[0]) and base[0] > 150  # in time: unchanged, with the success bonus
    assert scores[1:4] - base[1:4] == pytest.approx([50 * (1 - 6 / 31), 50 * (1 - 16 / 31), 50 * (1 - 26 / 31)])
    assert scores[4] == pytest.approx(base[4])  # after the window: no up credit


def test_a_pooled_rise_search_scores_the_mean_over_backends():
    from tools.keyframe_search import PooledEvaluator

    class Fake:
        def __init__(self, score, n):
            self.kinds, self.score, self.n, self.closed = ["recorded"] * n, score, n, False

        def run(self, parameters):
            k = len(parameters)
            return np.full(k, self.score), np.ones((k, self.n), bool), np.full((k, self.n), self.score / 100)

        def close(self):
            self.closed = True

    parts = [Fake(10.0, 2), Fake(40.0, 3)]
    pooled = PooledEvaluator(parts)
    scores, successes, heights = pooled.run(np.zeros((4, len(INITIAL))))
    assert np.allclose(scores, 25.0) and successes.shape == heights.shape == (4, 5) and len(pooled.kinds) == 5
    pooled.close()
    assert all(p.closed for p in parts)
