"""Fuzzing robots given by path: generated URDFs and ``<stem>.frbench.toml`` sidecars through the CLI.

URDFs: a valid primitive quadruped (the morphology generator's) with random edits: an attribute set to a
random number (NaN, infinities, huge, negative) or text, an element removed or duplicated, the text cut
short or spliced with random characters. Sidecars: random tables of the known keys (and unknown ones) with
values of every TOML type. Each goes through ``frbench robot check PATH`` (and some through ``robot add``):
a report (exit 0 or 1), or one line naming the file with exit 2.
"""

from __future__ import annotations

import copy
import math
import xml.etree.ElementTree as ET

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzz_support import FRBENCH_DIRS, assert_clean, fuzz_settings, outcome, sandbox, snapshot
from frbench.robots.sidecar import KEYS

SMOKE, SLOW_URDF, SLOW_SIDECAR = 6, 1200, 1500


def _base_urdf() -> str:
    from frbench.robots.morphology import MorphologyParams
    from frbench.robots.morphology_urdf import urdf_string

    return urdf_string(MorphologyParams(), name="fuzzdog")


BASE = _base_urdf()
ELEMENTS = [(i, el.tag, sorted(el.attrib)) for i, el in enumerate(ET.fromstring(BASE).iter())]
JOINTS = [el.get("name") for el in ET.fromstring(BASE).iter("joint")]
LINKS = [el.get("name") for el in ET.fromstring(BASE).iter("link")]

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(-10**12, 10**12),
    st.sampled_from([0, -0.0, 1e-300, 1e300, -1, 0.5]),
)
texts = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=24)
attribute_values = st.one_of(
    numbers.map(repr),
    st.lists(numbers.map(repr), min_size=0, max_size=5).map(" ".join),
    texts,
)


@st.composite
def urdf_texts(draw) -> str:
    root = ET.fromstring(BASE)
    elements = list(root.iter())
    for _ in range(draw(st.integers(1, 3))):
        index = draw(st.integers(0, len(elements) - 1))
        element = elements[index]
        action = draw(st.sampled_from(["set", "set", "set", "remove", "duplicate", "rename"]))
        if action == "set" and element.attrib:
            element.set(draw(st.sampled_from(sorted(element.attrib))), draw(attribute_values))
        elif action == "rename" and element.get("name") is not None:
            element.set("name", draw(st.sampled_from(JOINTS + LINKS + ["", "../x", "a b"])))
        elif action in ("remove", "duplicate") and index > 0:
            parent = next(p for p in elements if element in list(p))
            if action == "remove":
                parent.remove(element)
            else:
                parent.append(copy.deepcopy(element))
            elements = list(root.iter())
    text = ET.tostring(root, encoding="unicode")
    tail = draw(st.sampled_from(["keep", "keep", "keep", "cut", "splice"]))
    if tail == "cut":
        text = text[: draw(st.integers(0, len(text)))]
    elif tail == "splice":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(texts) + text[at:]
    return text


def toml_value(value) -> str:
    """A TOML rendering of a generated value (NaN and infinities as TOML writes them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.encode("unicode_escape").decode("ascii").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return "{" + ", ".join(f'"{k}" = {toml_value(v)}' for k, v in value.items()) + "}"


scalars = st.one_of(st.booleans(), numbers, texts, st.sampled_from(JOINTS + LINKS), st.sampled_from(["quadruped", "humanoid"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=5),
                                                        st.dictionaries(st.sampled_from(JOINTS + ["FL", "FR", "RL", "RR", "x"]), inner, max_size=4)),
                      max_leaves=12)
sidecars = st.dictionaries(st.sampled_from(KEYS + ("kpp", "Name")), values, max_size=4)


def _check(text: str, sidecar: str | None, add: bool) -> None:
    with sandbox() as root:
        urdf = root / "dog.urdf"
        urdf.write_text(text, encoding="utf-8")
        if sidecar is not None:
            (root / "dog.frbench.toml").write_text(sidecar, encoding="utf-8")
        before = snapshot(root, FRBENCH_DIRS)
        argv = ("robot", "add", urdf, "--name", "fuzzed", "--force") if add else ("robot", "check", urdf)
        result = outcome(*argv)
        assert_clean(result, before, root, failing=True, label=argv[1])
        if result.status == 2:
            assert str(urdf) in result.err or "dog.frbench.toml" in result.err or "fuzzed" in result.err, result.err


def _urdf_property(text, add):
    _check(text, None, add)


def _sidecar_property(table, add):
    _check(BASE, "\n".join(f'"{k}" = {toml_value(v)}' for k, v in table.items()) + "\n", add)


@fuzz_settings(SMOKE)
@given(urdf_texts(), st.booleans())
def test_generated_urdfs_smoke(text, add):
    _urdf_property(text, add)


@fuzz_settings(SMOKE)
@given(sidecars, st.booleans())
def test_generated_sidecars_smoke(table, add):
    _sidecar_property(table, add)


@pytest.mark.slow
@fuzz_settings(SLOW_URDF)
@given(urdf_texts(), st.booleans())
def test_generated_urdfs(text, add):
    _urdf_property(text, add)


@pytest.mark.slow
@fuzz_settings(SLOW_SIDECAR)
@given(sidecars, st.booleans())
def test_generated_sidecars(table, add):
    _sidecar_property(table, add)


def test_an_unstable_robot_leaves_no_mujoco_log_behind():
    """Found by the fuzzer: a hip cylinder of radius 14 m makes MuJoCo warn "Nan, Inf or huge value in QACC", and
    MuJoCo's own warning handler appended it to MUJOCO_LOG.TXT in the working directory."""
    root = ET.fromstring(BASE)
    root.find("link[@name='FR_hip']/collision/geometry/cylinder").set("radius", "14")
    _check(ET.tostring(root, encoding="unicode"), None, add=False)
