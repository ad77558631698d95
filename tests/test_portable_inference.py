"""Protocol 1.2: a learned policy's episodes do not depend on the processor's vector kernels or thread count.

Each run is a fresh process (torch reads ``ATEN_CPU_CAPABILITY`` once, at import), so the kernels really
differ between the runs: ``default`` is ATen's portable scalar code, the others its AVX2 / AVX-512 code.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frbench.policies.learned import portable_actions
from frbench.policies.registry import shipped_checkpoint

ROOT = Path(__file__).resolve().parents[1]
#: A chaotic cell (Go2 on level-5 stairs in PyBullet) where a last-bit difference in an action changed outcomes.
CELL = ("go2", "pybullet", "stairs", 5, 1)
EPISODES = 3
RUN = """
import hashlib, json, sys
import torch
torch.set_num_threads(int(sys.argv[2]))
from frbench.evaluation.runner import Cell, run_cell
episodes = run_cell(Cell(*json.loads(sys.argv[3]), int(sys.argv[4])), sys.argv[1])
print(json.dumps({"capability": torch.backends.cpu.get_cpu_capability(),
                  "digest": hashlib.sha256(json.dumps(episodes, sort_keys=True).encode()).hexdigest(),
                  "energy": [e["energy"] for e in episodes]}))
"""


def _environment(capability: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("ATEN_CPU_CAPABILITY", "MKL_CBWR", "ONEDNN_MAX_CPU_ISA")}
    if capability is not None:
        env["ATEN_CPU_CAPABILITY"] = capability
    return env


def _run(policy: Path, capability: str | None, threads: int = 1) -> dict:
    done = subprocess.run([sys.executable, "-c", RUN, str(policy), str(threads), json.dumps(CELL), str(EPISODES)],
                          env=_environment(capability), capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_actions_are_rounded_to_float32_values():
    actions = np.array([[0.1, -1.0 / 3.0, 2.0 ** -30]])
    out = portable_actions(actions)
    assert out.dtype == np.float64 and np.array_equal(out, actions.astype(np.float32).astype(np.float64))
    # values a float64 kernel may return for the same sum, a few ulps apart, round to the same action
    ulps = np.nextafter(actions, 1.0), np.nextafter(actions, -1.0)
    assert all(np.array_equal(portable_actions(u), out) for u in ulps)


def test_learned_episodes_are_bit_identical_under_every_kernel_setting_and_thread_count():
    policy = shipped_checkpoint("frnet-3m")
    here = _run(policy, None)
    portable = _run(policy, "default")
    assert portable["capability"] == "DEFAULT" and here["capability"] != "DEFAULT"
    assert portable["digest"] == here["digest"], (portable["energy"], here["energy"])
    assert _run(policy, "avx2")["digest"] == here["digest"]
    assert _run(policy, None, threads=2)["digest"] == here["digest"]


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> Path:
    """A 1.2 record of the frnet-3m checkpoint on one chaotic cell, its policy attached, on a fresh board."""
    from frbench.evaluation.grid import EvaluationRequest, build_results, run_grid, validate
    from frbench.leaderboard import board as lb

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from results_factory import empty_board_copy

    folder = tmp_path_factory.mktemp("portable")
    policy = folder / "frnet-3m.pt"
    policy.write_bytes(shipped_checkpoint("frnet-3m").read_bytes())
    robot, backend, terrain, level, seed = CELL
    request = EvaluationRequest(policy=str(policy), robots=[robot], backends=[backend], terrains=[terrain],
                                levels=[level], seeds=[seed], episodes=EPISODES, jobs=1)
    results = build_results(request, validate(request), run_grid(request))
    results_file = folder / "results.json"
    results_file.write_text(json.dumps(results))
    root = empty_board_copy(ROOT / "leaderboard", folder / "leaderboard")
    return lb.submit(results_file, root, name="portable", policy_file=policy).path


@pytest.mark.parametrize("capability", ["default", "avx2", None])
def test_a_record_verifies_in_a_fresh_process_under_each_kernel_setting(record, capability):
    done = subprocess.run([sys.executable, "-m", "frbench.cli", "verify", str(record), "--sample", str(EPISODES)],
                          env=_environment(capability), capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "compared bit-identical" in done.stdout and f"{EPISODES} of {EPISODES} sampled episodes reproduced" in done.stdout
