"""frbench.schemas.validator: the jsonschema library's errors as one-line ``path: problem`` messages."""

from __future__ import annotations

import copy
import json
import re
import sys
from pathlib import Path

import pytest

from frbench.errors import ResultsError
from frbench.leaderboard.jsonfile import parse_json_text
from frbench.schemas import NonFinite, validate
from frbench.schemas.validator import Validator, find_non_finite, inline_refs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_factory import small_results  # noqa: E402


def _edited(edit) -> dict:
    results = copy.deepcopy(small_results())
    edit(results)
    return results


MESSAGES = [
    (lambda r: r["versions"].__setitem__("../bad", "1"),
     "versions['../bad']: field name '../bad' does not match the pattern ^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"),
    (lambda r: r["policy"].__setitem__("sha256", "xyz"), "policy.sha256: 'xyz' does not match the pattern ^[0-9a-f]{64}$"),
    (lambda r: r["cells"][0].__setitem__("mean_time_to_recover", "a"),
     "cells[0].mean_time_to_recover: expected number or null, got string"),
    (lambda r: r["config"].__setitem__("backends", ["mujoco", "ode"]), "config.backends[1]: 'ode' is not one of 'mujoco', 'pybullet', 'mujoco-warp', 'physx'"),
    (lambda r: r.__setitem__("schema_version", 2), "schema_version: must be 1, got 2"),
    (lambda r: r["config"].__setitem__("extra", float("inf")), "config.extra: inf is not allowed (numbers must be finite)"),
    (lambda r: r["config"].__setitem__("robots", []), "config.robots: has 0 items, fewer than the minimum 1"),
    (lambda r: r.__setitem__("robots", {}), "robots: has 0 fields, fewer than the minimum 1"),
    (lambda r: r["config"].__setitem__("policy", ""), "config.policy: '' is shorter than 1 characters"),
    (lambda r: r["config"].__setitem__("policy", "a" * 2000), "config.policy: is 2000 characters long, above the limit of 1024"),
    (lambda r: r["episodes"][5].pop("success"), "episodes[5].success: required field is missing"),
]


@pytest.mark.parametrize("edit, message", MESSAGES)
def test_one_line_messages_name_the_field(edit, message):
    with pytest.raises(ResultsError) as caught:
        validate(_edited(edit), "results-v1")
    assert str(caught.value) == message


def test_non_finite_numbers_are_refused_wherever_they_are():
    text = json.dumps(small_results()).replace('"noise": false', '"noise": false, "extra": [1, -Infinity]')
    results = parse_json_text(text, "r.json")
    assert results["config"]["extra"][1] == NonFinite("-Infinity")
    assert str(find_non_finite(results)) == "config.extra[1]: -Infinity is not allowed (numbers must be finite)"
    with pytest.raises(ResultsError, match=re.escape("config.extra[1]: -Infinity is not allowed")):
        validate(results, "results-v1")
    assert find_non_finite(small_results()) is None


def test_refs_are_inlined_and_the_library_agrees():
    schema = {"$defs": {"rate": {"type": "number", "maximum": 1}},
              "properties": {"a": {"$ref": "#/$defs/rate"}, "b": {"$ref": "#/$defs/rate", "minimum": 0.5}}}
    assert inline_refs(schema, schema, {}) == {"properties": {"a": {"type": "number", "maximum": 1},
                                                              "b": {"minimum": 0.5, "allOf": [{"type": "number", "maximum": 1}]}}}
    validator = Validator(schema)
    validator.validate({"a": 1, "b": 0.7})
    with pytest.raises(ResultsError, match=re.escape("b: 0.2 is below the minimum 0.5")):
        validator.validate({"a": 1, "b": 0.2})
    with pytest.raises(ResultsError, match=re.escape("a: 2 is above the maximum 1")):
        validator.validate({"a": 2})
