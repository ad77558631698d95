"""Episodes do not depend on the BLAS kernel the processor picks (`frbench.portable_products`, issue 56).

numpy's OpenBLAS picks its kernels by processor; ``OPENBLAS_CORETYPE`` forces one on any x86-64, so two fresh
processes, one with the ``SkylakeX`` kernels (AVX-512 machines) and one with the ``Haswell`` kernels (AVX2
machines, those that made the records), stand for two machines.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frbench.portable_products import dot, norm, transposed_times, unit

REPO = Path(__file__).resolve().parents[1]
KERNELS = ("SkylakeX", "Haswell")

_PRODUCTS = """
import json, sys
import numpy as np
from frbench.portable_products import dot, norm, transposed_times
rng = np.random.default_rng(3)
a, b, m = rng.standard_normal((400, 4)), rng.standard_normal((400, 4)), rng.standard_normal((400, 3, 3))
blas = [float(x @ y) for x, y in zip(a, b)] + [float(np.linalg.norm(x[:3])) for x in a]
blas += [float(v) for x, y in zip(m, b) for v in x.T @ y[:3]]
ours = [float(v) for v in dot(a, b)] + [float(v) for v in norm(a[:, :3])]
ours += [float(v) for v in transposed_times(m, b[:, :3]).ravel()]
json.dump({"blas": [v.hex() for v in blas], "ours": [v.hex() for v in ours]}, sys.stdout)
"""

#: aliengo, MuJoCo, slopes level 10, seed 1: its episode 0 differed between the two kernels (issue 56), and
#: go2 on PyBullet (the backend's state conversion); each cell's episodes run side by side, as evaluate runs them.
_EPISODES = """
import json, sys
from frbench.evaluation.runner import Cell, run_cell
cells = [Cell("aliengo", "mujoco", "slopes", 10, 1, 3), Cell("go2", "pybullet", "rough", 5, 2, 1)]
json.dump([run_cell(cell, "scripted") for cell in cells], sys.stdout)
"""


def _run(code: str, kernel: str, cache: Path) -> object:
    """Run ``code`` in a fresh process with OpenBLAS's ``kernel``; what it prints, parsed."""
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel, "FRBENCH_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)


def test_the_products_equal_the_haswell_kernel_bit_for_bit_under_either_kernel(tmp_path):
    found = {kernel: _run(_PRODUCTS, kernel, tmp_path / kernel) for kernel in KERNELS}
    assert found["SkylakeX"]["ours"] == found["Haswell"]["ours"] == found["Haswell"]["blas"]
    if found["SkylakeX"]["blas"] == found["Haswell"]["blas"]:
        pytest.skip("this numpy's BLAS gives one result under both core types (no AVX-512, or not OpenBLAS)")
    differing = sum(x != y for x, y in zip(found["SkylakeX"]["blas"], found["Haswell"]["blas"]))
    assert differing > 100  # numpy's own products do differ between the kernels: the test can fail


def test_an_episode_is_bit_identical_under_the_skylakex_and_haswell_kernels(tmp_path):
    runs = {kernel: _run(_EPISODES, kernel, tmp_path / kernel) for kernel in KERNELS}  # fresh caches: URDFs too
    assert runs["SkylakeX"] == runs["Haswell"]
    aliengo, go2 = runs["Haswell"][0][0], runs["Haswell"][1][0]
    # the record 85a8cb81ec81 (scripted, protocol 1.2) holds these, made on Haswell-kernel machines
    assert (aliengo["energy"], aliengo["final_displacement"]) == (10023.921502351805, 3.617511998235589)
    assert go2["robot"] == "go2" and go2["backend"] == "pybullet"


def test_the_products_are_the_rounded_products_added_in_index_order():
    a, b = np.array([1e16, 1.0, -1e16]), np.array([1.0, 1.0, 1.0])
    assert dot(a, b) == 0.0  # (1e16 + 1) rounds to 1e16; a sum in another order gives 1
    assert dot(np.array([[3.0, 4.0], [1.0, 0.0]]), np.array([3.0, 4.0])).tolist() == [25.0, 3.0]
    assert norm([3.0, 4.0]) == 5.0 and unit(np.array([0.0, 3.0, 4.0])).tolist() == [0.0, 0.6, 0.8]
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert transposed_times(rotation, np.array([1.0, 2.0, 3.0])).tolist() == [2.0, -1.0, 3.0]
