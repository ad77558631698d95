"""``frbench spec``: the observation/action contract as data; layouts read back, bound to robots, refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from frbench.cli import main
from frbench.errors import PolicyError
from frbench.policies.contract import (
    LayoutInput,
    ObservationTerm,
    PolicyLayout,
    contract_for,
    read_layout,
)
from frbench.robots import get_robot
from frbench.tasks.observations import flatten


def _spec_json(capsys, *args) -> dict:
    assert main(["spec", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_spec_prints_the_go2_contract_with_frbench_s_numbers(capsys):
    go2 = get_robot("go2")
    data = _spec_json(capsys, "--robot", "go2")
    assert data["protocol_version"] == "1.4" and data["control_dt"] == 0.02 and data["physics_dt"] == 0.005
    assert data["robot"]["joint_names"] == list(go2.joint_names) and data["robot"]["joint_names"][0] == "FL_hip_joint"
    assert data["robot"]["default_pose"] == list(go2.default_pose) and data["robot"]["kp"] == [40.0] * 12
    assert [(t["name"], t["size"], t["unit"]) for t in data["frame"]] == [
        ("base_angvel", 3, "rad/s"), ("projected_gravity", 3, "-"), ("joint_pos", 12, "rad"), ("joint_vel", 12, "rad/s"),
        ("previous_action", 12, "action")]
    assert data["frame_size"] == 42 and data["input_sizes"] == {"obs": 42}
    assert data["layout"]["action"] == "normalised" and data["layout"]["action_scale"] == 1.0
    assert data["layout"]["action_clip"] == 10.0
    assert main(["spec", "--robot", "go2"]) == 0
    text = capsys.readouterr().out
    assert "50 Hz" in text and "[  6: 18] joint_pos" in text and "q* = q_default + 1 * a" in text


def test_spec_of_frnet_names_its_history_input_and_a_humanoid_frame_has_93_values(capsys):
    frnet = _spec_json(capsys, "--robot", "go1", "--policy", "frnet")
    assert frnet["input_sizes"] == {"obs": 42, "history": 210}
    assert frnet["layout"]["inputs"] == [{"name": "obs", "frames": 1}, {"name": "history", "frames": 5}]
    assert _spec_json(capsys, "--robot", "g1")["frame_size"] == 6 + 3 * 29
    assert main(["spec", "--robot", "go2", "--policy", "scripted"]) == 2
    assert "has no layout" in capsys.readouterr().err
    assert main(["spec", "--robot", "g1", "--policy", "frnet"]) == 2
    assert "policy 'frnet' does not support robot 'g1' (humanoid)" in capsys.readouterr().err


def test_the_spec_output_is_a_layout_file_and_layouts_round_trip(tmp_path, capsys):
    path = tmp_path / "go2.json"
    path.write_text(json.dumps(_spec_json(capsys, "--robot", "go2", "--policy", "frnet")))
    assert read_layout(path).input_sizes(12) == {"obs": 42, "history": 210}
    layout = PolicyLayout(observation=(ObservationTerm("base_angvel", 0.25), ObservationTerm("constant", 1.0, 3, 0.0),
                                       ObservationTerm("joint_vel", 0.05)),
                          inputs=(LayoutInput("policy", 3),), action_scale=0.25, action_clip=None,
                          joint_names=tuple(reversed(get_robot("go2").joint_names)))
    assert PolicyLayout.from_dict(json.loads(json.dumps(layout.to_dict()))) == layout
    assert layout.frame_size(12) == 18 and layout.input_sizes(12) == {"policy": 54}


def test_a_layout_in_another_joint_order_maps_onto_the_canonical_one():
    go2 = get_robot("go2")
    by_type = tuple(f"{leg}_{part}_joint" for part in ("hip", "thigh", "calf") for leg in ("FL", "FR", "RL", "RR"))
    contract = contract_for(go2, PolicyLayout(joint_names=by_type))
    assert contract.order[:4] == (0, 3, 6, 9) and contract.order[4] == 1  # FL hip, FR hip, ..., then FL thigh
    assert contract.policy_default_pose[:4] == (0.1, -0.1, 0.1, -0.1)
    np.testing.assert_array_equal(np.asarray(go2.default_pose)[list(contract.order)], contract.policy_default_pose)


def test_frbench_s_layout_gives_the_paper_s_o_t():
    from frbench.policies.layout_policy import LayoutPolicy

    go2 = get_robot("go2")
    rng = np.random.default_rng(0)
    obs = {"base_angvel": rng.normal(size=(3, 3)), "projected_gravity": rng.normal(size=(3, 3)),
           "joint_pos": rng.normal(size=(3, 12)), "joint_vel": rng.normal(size=(3, 12)),
           "previous_action": np.tile(go2.default_pose, (3, 1))}
    policy = LayoutPolicy("probe", None, PolicyLayout(inputs=(LayoutInput("obs"), LayoutInput("history", 5))))
    policy.reset(go2, 3)
    inputs = policy.model_inputs(obs)
    np.testing.assert_allclose(inputs["obs"], flatten(obs, np.asarray(go2.default_pose)), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(inputs["history"].reshape(3, 5, 42)[:, 0], inputs["obs"])  # filled with frame 0


@pytest.mark.parametrize("layout, message", [
    ({"observation": ["base_angvel", "height_scan"]}, "observation[1]: term 'height_scan'"),
    ({"action": "torques"}, "action 'torques', expected one of normalised, targets"),
    ({"action_scale": -0.25}, "action_scale: -0.25, expected a positive finite number"),
    ({"inputs": [{"name": "obs", "frames": 0}]}, "inputs[0]: frames: 0"),
    ({"inputs": [{"name": "obs"}, {"name": "obs"}]}, "names repeat"),
    ({"observation": [{"name": "constant", "value": 1.0}]}, "observation[0]: size: None"),
    ({"action_scale": 0.5, "actionscale": 0.25}, "unknown field 'actionscale'"),
    ({"joint_names": ["FL_hip_joint"] * 12}, "joint_names: expected distinct joint names"),
    ({"joint_names": ["a", "b"], "default_pose": [0.0]}, "default_pose has 1 values, joint_names 2"),
    ([1, 2], "expected a JSON object"),
])
def test_bad_layout_files_are_one_line_errors(tmp_path, capsys, layout, message):
    path = tmp_path / "layout.json"
    path.write_text(json.dumps(layout))
    assert main(["spec", "--robot", "go2", "--spec", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and str(path) in err and err.count("\n") == 1


def test_a_layout_for_other_joints_is_refused_naming_the_robot_s():
    with pytest.raises(PolicyError, match="expected a permutation of FL_hip_joint"):
        contract_for(get_robot("go2"), PolicyLayout(joint_names=tuple(f"j{k}" for k in range(12))))
    with pytest.raises(PolicyError, match="default_pose has 3 values, robot 'go2' has 12 joints"):
        contract_for(get_robot("go2"), PolicyLayout(default_pose=(0.0, 0.0, 0.0)))


def test_the_layouts_in_docs_own_policy_read_and_fit_go2_with_48_values():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "own-policy.md").read_text()
    blocks = re.findall(r"```json\n(.*?)```", text, re.S)
    assert len(blocks) == 2
    isaac, legged = (PolicyLayout.from_dict(json.loads(block), "docs/own-policy.md") for block in blocks)
    go2 = get_robot("go2")
    for layout in (isaac, legged):
        assert layout.frame_size(12) == 48 and layout.action_scale == 0.25
    assert contract_for(go2, isaac).order == (0, 3, 6, 9, 1, 4, 7, 10, 2, 5, 8, 11) and isaac.action_clip is None
    assert contract_for(go2, legged).order == tuple(range(12)) and legged.observation[1].scale == 0.25
