"""Run the cells of an evaluation grid as Ray tasks, on this machine or on a Ray cluster.

``frbench evaluate --executor ray``: each cell is one Ray task that reserves the
one CPU it uses (one MuJoCo thread, one torch thread). Ray reuses its worker
processes between tasks, and `frbench.evaluation.runner` caches the loaded
policy per process, so a policy is loaded once per worker, not once per cell.
A worker that dies during a cell (killed, out of memory, a lost node) is
replaced and the cell runs again from its start (``max_retries``): a cell is a
pure function of (cell, policy, noise), so the rerun gives the same episodes.

Where the cluster comes from: ``address`` (``--address``), else the
``RAY_ADDRESS`` environment variable, else a local instance of
``num_cpus`` CPUs that is started here and shut down when the grid is done,
failed or interrupted (a cluster frbench connected to is left running; its
unfinished tasks are cancelled).

Workers need frbench and the same package versions as the driver. Relative
paths (a policy's run folder, a robot's URDF) resolve against the driver's
working folder where that folder exists on the worker's node (always for a
local instance; on a cluster, a shared file system).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable

from frbench.errors import FrbenchError
from frbench.evaluation.runner import Cell, run_cell
from frbench.tasks.protocol import PROTOCOL_VERSION

#: Times a cell is run again after its worker died before the grid fails.
MAX_RETRIES = 3
#: Object store of a local instance [bytes]: cells return a few kB of episode records.
LOCAL_OBJECT_STORE_BYTES = 100 * 1024 * 1024
#: Environment variables the driver passes on to every worker (caches and user registries).
PASSED_ENV = ("FRBENCH_CACHE", "FRBENCH_CONFIG")


def _import_ray():
    try:
        import ray
    except ImportError:
        raise FrbenchError("--executor ray: Ray is not installed; install it with pip install 'frbench[ray]'") from None
    return ray


def _run_cell_in_worker(cell: Cell, policy_reference: str, noise: bool, driver_cwd: str,
                        device: str | None = None, protocol_version: str = PROTOCOL_VERSION) -> list[dict]:
    """The body of a cell's Ray task: one MuJoCo and one torch thread, the driver's folder for relative paths."""
    os.environ["FRBENCH_MUJOCO_THREADS"] = "1"
    if os.path.isdir(driver_cwd) and os.getcwd() != driver_cwd:
        os.chdir(driver_cwd)

    return run_cell(cell, policy_reference, noise, device=device, protocol_version=protocol_version)


def _connect(ray, address: str | None, num_cpus: int) -> bool:
    """Connect to ``address`` / ``RAY_ADDRESS`` or start a local instance; True when frbench started it."""
    if ray.is_initialized():
        return False
    env_vars = {name: os.environ[name] for name in PASSED_ENV if name in os.environ}
    address = address or os.environ.get("RAY_ADDRESS") or None
    common = {"include_dashboard": False, "log_to_driver": False, "logging_level": "WARNING",
              "runtime_env": {"env_vars": env_vars} if env_vars else None}
    if address:
        try:
            ray.init(address=address, **common)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise FrbenchError(f"--address {address}: cannot connect to a Ray cluster there ({exc})") from None
        return False
    # "local": always a new instance, never another user's cluster on this machine. Its notice that token
    # authentication is on (the secure default) would land in the middle of the progress bar.
    notice = logging.getLogger("ray._private.authentication.authentication_token_setup")
    level = notice.level
    notice.setLevel(logging.ERROR)
    try:
        ray.init(address="local", num_cpus=num_cpus, object_store_memory=LOCAL_OBJECT_STORE_BYTES, **common)
    finally:
        notice.setLevel(level)
    return True


def run_cells_on_ray(cells: list[Cell], policy_reference: str, noise: bool = False,
                     progress: Callable[[Cell], None] | None = None, address: str | None = None,
                     num_cpus: int = 0, device: str | None = None,
                     protocol_version: str = PROTOCOL_VERSION) -> list[dict]:
    """Run ``cells`` as Ray tasks; returns their episode records (in completion order, unsorted); ``device``: where
    a device simulator runs, ``protocol_version``: whose starts the cells draw (`run_cell`).

    ``progress(cell)`` is called on the driver as each cell finishes. ``num_cpus`` (0: this machine's
    cores) sizes a local instance; a cluster brings its own CPUs. On any exception (including
    KeyboardInterrupt) the unfinished tasks are cancelled and a local instance is shut down before
    the exception propagates, so the caller writes no results.
    """
    ray = _import_ray()
    started = _connect(ray, address, num_cpus or os.cpu_count() or 1)
    task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=False)(_run_cell_in_worker)
    pending: dict = {}
    try:
        cwd = os.getcwd()
        pending = {task.remote(cell, policy_reference, noise, cwd, device, protocol_version): cell for cell in cells}
        records: list[dict] = []
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                try:
                    records += ray.get(ref)
                except ray.exceptions.RayTaskError as exc:  # the cell itself raised: re-raise its own error
                    raise (exc.cause if exc.cause is not None else exc) from None
                cell = pending.pop(ref)
                if progress:
                    progress(cell)
        return records
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()
