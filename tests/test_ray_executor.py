"""``frbench evaluate --executor ray``: the local executor's episodes, a killed worker's cell rerun, no results
when interrupted. The default tests share one 2-CPU local Ray instance (≈ 10 s to start, ≈ 770 MB), shut down
after them; the slow test lets ``frbench evaluate`` start (and stop) its own."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest

ray = pytest.importorskip("ray")

from frbench.cli import main  # noqa: E402
from frbench.evaluation.grid import EvaluationRequest, run_grid  # noqa: E402

#: 4 cells x 2 episodes (≈ 1 s per cell on a warm worker).
GRID = ["--policy", "scripted", "--robots", "go2", "--backends", "mujoco,pybullet", "--terrains", "flat,gaps",
        "--levels", "1", "--seeds", "0", "--episodes", "2"]
#: The process title Ray gives a worker while it runs a cell (an idle worker's is ``ray::IDLE``).
CELL_TITLE = b"ray::_run_cell_in_worker"


def _request(**kw) -> EvaluationRequest:
    return EvaluationRequest(policy="scripted", robots=["go2"], backends=["mujoco", "pybullet"],
                             terrains=["flat", "gaps"], levels=[1], seeds=[0], episodes=2, **kw)


@pytest.fixture(scope="module")
def local_results(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("local") / "local.json"
    assert main(["evaluate", *GRID, "--jobs", "1", "--out", str(out)]) == 0
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def ray_instance():
    """A 2-CPU local Ray instance for this module's tests, shut down after them."""
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             object_store_memory=100 * 1024 * 1024, logging_level="ERROR")
    yield
    ray.shutdown()


def _same_results(results: dict, local: dict) -> None:
    assert len(results["episodes"]) == 8
    assert results["episodes"] == local["episodes"]
    assert {k for k in results if results[k] != local[k]} <= {"created"}  # the same second gives the same stamp
    assert "executor" not in results["config"] and "jobs" not in results["config"]


def test_ray_executor_writes_the_local_results_episode_by_episode(ray_instance, tmp_path, local_results, capsys):
    out = tmp_path / "ray.json"
    assert main(["evaluate", *GRID, "--executor", "ray", "--out", str(out)]) == 0
    assert ray.is_initialized()  # a cluster it connected to is left running
    _same_results(json.loads(out.read_text()), local_results)

    def policy_loads() -> tuple[int, int, int]:  # nested: sent by value (workers cannot import a test module)
        """(pid, policy loads, cached uses) of the Ray worker that runs this."""
        from frbench.evaluation import runner

        info = runner._policy.cache_info()
        return os.getpid(), info.misses, info.hits

    probe = ray.remote(num_cpus=1)(policy_loads)
    workers = {pid: (loads, uses) for pid, loads, uses in ray.get([probe.remote() for _ in range(40)])}
    ran_cells = {pid: counts for pid, counts in workers.items() if counts[0]}
    assert ran_cells and all(loads == 1 for loads, _ in ran_cells.values())  # the policy loaded once per worker
    assert sum(loads + uses for loads, uses in ran_cells.values()) <= 4
    assert any(uses >= 1 for _, uses in ran_cells.values())  # ... and reused for the worker's next cell


def _kill_first_cell_worker(killed: list[int], stop: threading.Event) -> None:
    """SIGKILL the first Ray worker seen running a cell; its pid goes to ``killed``."""
    while not stop.is_set() and not killed:
        for proc in Path("/proc").iterdir():
            if not proc.name.isdigit():
                continue
            try:
                if (proc / "cmdline").read_bytes().startswith(CELL_TITLE):
                    os.kill(int(proc.name), signal.SIGKILL)
                    killed.append(int(proc.name))
                    return
            except (OSError, ProcessLookupError):
                continue
        time.sleep(0.05)


def test_a_worker_killed_during_a_cell_is_replaced_and_the_cell_rerun(ray_instance, local_results):
    killed: list[int] = []
    stop = threading.Event()
    killer = threading.Thread(target=_kill_first_cell_worker, args=(killed, stop), daemon=True)
    killer.start()
    finished = []
    try:
        episodes = run_grid(_request(executor="ray"), progress=finished.append)
    finally:
        stop.set()
        killer.join()
    assert len(killed) == 1  # a worker died in the middle of a cell ...
    assert len(finished) == 4 and episodes == local_results["episodes"]  # ... and every cell still came back the same


def test_an_interrupted_ray_run_writes_no_results_and_cancels_its_cells(ray_instance, tmp_path, monkeypatch):
    real_wait, calls = ray.wait, []

    def wait_then_interrupt(refs, **kwargs):
        calls.append(list(refs))
        if len(calls) == 2:  # Ctrl-C after the first cell
            raise KeyboardInterrupt
        return real_wait(refs, **kwargs)

    monkeypatch.setattr(ray, "wait", wait_then_interrupt)
    out = tmp_path / "ray.json"
    assert main(["evaluate", *GRID, "--executor", "ray", "--out", str(out)]) != 0
    assert not out.exists() and not list(tmp_path.iterdir())
    assert ray.is_initialized()  # a cluster frbench connected to is left running, its unfinished cells cancelled
    unfinished = calls[1]
    assert len(unfinished) == 3
    cancelled = 0
    for ref in unfinished:
        try:
            ray.get(ref, timeout=60)
        except ray.exceptions.TaskCancelledError:
            cancelled += 1
    # Both CPUs may have picked up a cell before the cancel arrives (the first cell's CPU takes the next queued
    # one), so up to two of the three can finish; the third never started and must be cancelled.
    assert cancelled >= 1


def test_executor_names_are_checked(tmp_path, capsys):
    assert main(["evaluate", *GRID, "--executor", "dask", "--out", str(tmp_path / "r.json")]) == 2
    assert "unknown executor 'dask'" in capsys.readouterr().err


@pytest.mark.slow
def test_ray_executor_starts_and_stops_its_own_local_instance(tmp_path, local_results, capsys):
    if ray.is_initialized():  # the default tests' shared instance (the last test of the module)
        ray.shutdown()
    out = tmp_path / "ray.json"
    assert main(["evaluate", *GRID, "--executor", "ray", "--jobs", "2", "--out", str(out)]) == 0
    assert not ray.is_initialized()  # the instance it started is shut down
    _same_results(json.loads(out.read_text()), local_results)
