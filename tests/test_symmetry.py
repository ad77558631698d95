"""The left/right mirror used for rsl-rl's symmetry augmentation, checked against frbench's own observations."""

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from frbench.backends.base import RobotState
from frbench.robots import get_robot
from frbench.tasks.observations import flatten, proprioception
from frbench.training.symmetry import JOINTS, O_T, PRIVILEGED, group_mirrors, mirror_group, mirror_quadruped


def _mirrored_state(state: RobotState, spec) -> RobotState:
    """The mirror image (y → −y) of ``state``, joints mapped by name: FL ↔ FR, RL ↔ RR, hip angles negated."""
    names = list(spec.joint_names)
    swap = {"FL": "FR", "FR": "FL", "RL": "RR", "RR": "RL"}
    index = [names.index(swap[n[:2]] + n[2:]) for n in names]
    sign = np.array([-1.0 if "hip" in n else 1.0 for n in names])
    w, x, y, z = state.base_quat.T
    return RobotState(base_pos=state.base_pos * [1, -1, 1], base_quat=np.stack([w, -x, y, -z], axis=1),
                      base_linvel=state.base_linvel * [1, -1, 1], base_angvel=state.base_angvel * [-1, 1, -1],
                      q=state.q[:, index] * sign, qd=state.qd[:, index] * sign)


def test_the_mirror_of_a_state_gives_the_mirrored_observation_for_go2():
    spec = get_robot("go2")
    rng = np.random.default_rng(0)
    n = 16
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    state = RobotState(base_pos=rng.normal(size=(n, 3)), base_quat=quat, base_linvel=rng.normal(size=(n, 3)),
                       base_angvel=rng.normal(size=(n, 3)), q=rng.normal(size=(n, 12)), qd=rng.normal(size=(n, 12)))
    default = np.asarray(spec.default_pose)
    assert np.allclose(JOINTS(torch.tensor(default)).numpy(), default)  # the standing pose is its own mirror
    previous = default + rng.normal(size=(n, 12))
    mirror = _mirrored_state(state, spec)
    o_t = flatten(proprioception(state, previous), default)
    o_mirror = flatten(proprioception(mirror, default + JOINTS(torch.tensor(previous - default)).numpy()), default)
    np.testing.assert_allclose(O_T(torch.tensor(o_t)).numpy(), o_mirror, atol=1e-12)


def test_every_training_group_is_mirrored_and_the_mirror_is_its_own_inverse():
    from frbench.training.config import TrainEnvConfig
    from frbench.training.env import RecoveryTrainingEnv

    env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=4, episode_steps=4, settle_steps=2, num_morphologies=2,
                                             families=("flat", "stairs"), long_history=3))
    try:
        obs = env.get_observations()
        assert PRIVILEGED.index.shape == (277,)
        assert sorted(PRIVILEGED.index.tolist()) == list(range(277))  # a permutation
        actions = torch.randn(4, 12)
        augmented, mirrored_actions = mirror_quadruped(env, obs, actions)
        assert augmented.batch_size[0] == 8 and mirrored_actions.shape == (8, 12)
        for key in obs.keys():
            assert torch.equal(augmented[key][:4], obs[key])
            again = mirror_group(key, augmented[key][4:], group_mirrors())
            torch.testing.assert_close(again, obs[key])
        # hip actions flip sign and the legs swap: FL hip of the mirror is minus the FR hip
        assert torch.equal(mirrored_actions[4:, 0], -actions[:, 3])
        assert torch.equal(mirrored_actions[4:, 4], actions[:, 1])
        # the critic's CoM y (index 42 + 187 + 4 + 24 + 1) changes sign, the friction (last) does not
        com_y = 42 + 187 + 4 + 24 + 1
        assert torch.equal(augmented["privileged"][4:, com_y], -obs["privileged"][:, com_y])
        assert torch.equal(augmented["privileged"][4:, -1], obs["privileged"][:, -1])
    finally:
        env.close()


def test_the_height_scan_row_reverses_its_lateral_points():
    scan = torch.arange(187, dtype=torch.float32)
    privileged = torch.zeros(277)
    privileged[42:42 + 187] = scan
    mirrored = PRIVILEGED(privileged)[42:42 + 187].reshape(17, 11)
    assert torch.equal(mirrored[0], torch.arange(10, -1, -1, dtype=torch.float32))


def test_an_unknown_group_or_a_humanoid_is_refused():
    with pytest.raises(ValueError, match="no left/right mirror for observation group 'scan'"):
        mirror_quadruped(None, TensorDict({"scan": torch.zeros(2, 3)}, batch_size=[2]))

    class Humanoid:
        num_actions = 29

    with pytest.raises(ValueError, match="a quadruped with 12 actions"):
        mirror_quadruped(Humanoid(), None, torch.zeros(2, 29))


def test_a_quadruped_whose_joints_are_in_another_order_is_refused():
    from types import SimpleNamespace

    from frbench.training.symmetry import check_joint_order

    check_joint_order(SimpleNamespace(num_actions=12, spec=get_robot("go2")))
    names = [f"{leg}_{part}_joint" for leg in ("FR", "FL", "RR", "RL") for part in ("hip", "thigh", "calf")]
    with pytest.raises(ValueError, match="not in the order FL, FR, RL, RR"):
        check_joint_order(SimpleNamespace(num_actions=12, spec=SimpleNamespace(joint_names=names)))


def test_the_symmetry_preset_trains_frnet_with_mirrored_mini_batches(tmp_path):
    from frbench.training.config import TrainEnvConfig
    from frbench.training.presets import PRESETS
    from frbench.training.run import TrainingRun

    overrides = PRESETS["symmetry"].train_overrides()
    assert overrides["algorithm"]["symmetry_cfg"]["data_augmentation_func"] == "frbench.training.symmetry:mirror_quadruped"
    assert PRESETS["demo-starts"].train_overrides() is None
    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    run = TrainingRun(tmp_path / "run", "frnet", cfg, total_steps=4 * 24, checkpoint_every=1,
                      train_overrides=overrides)
    seen = []
    augment = run.runner.alg.symmetry.augment_batch
    run.runner.alg.symmetry.augment_batch = lambda batch, size: (augment(batch, size),
                                                                 seen.append(batch.observations.batch_size[0] / size))
    run.train(progress_bar=False)
    assert seen and set(seen) == {2.0}  # every mini-batch doubled by its mirror
    assert run.env_steps == 96


def test_a_preset_s_algorithm_values_reach_the_rsl_rl_config_beside_the_mirror():
    from frbench.training.methods import make_train_cfg
    from frbench.training.presets import PRESETS

    cfg = make_train_cfg("frnet", PRESETS["symmetry-entropy"].train_overrides())
    assert cfg["algorithm"]["entropy_coef"] == 0.01
    assert cfg["algorithm"]["symmetry_cfg"]["use_data_augmentation"] is True
    assert make_train_cfg("frnet", PRESETS["symmetry"].train_overrides())["algorithm"]["entropy_coef"] == 0.005
    steady = make_train_cfg("frnet", PRESETS["symmetry-assist-steady"].train_overrides())
    assert steady["algorithm"]["entropy_coef"] == 0.005 and steady["algorithm"]["symmetry_cfg"]["use_data_augmentation"]
    assert PRESETS["symmetry-assist-steady"].env["assist_force"] == 0.4
