"""Ctrl-C with worker processes: the parent handles it alone, in one line, and stops the workers.

Workers started inside `children_ignore_sigint` ignore SIGINT from their first instruction on (an ignored
signal stays ignored across ``exec``, and Python leaves an ignored SIGINT alone at start-up), so a Ctrl-C at
the terminal, which reaches every process of the foreground group, raises `KeyboardInterrupt` in the parent
only; the parent then calls `terminate_pool` and the CLI prints "interrupted" and exits with 130.
"""

from __future__ import annotations

import signal
from contextlib import contextmanager


@contextmanager
def children_ignore_sigint():
    """SIGINT ignored while the block runs (start worker processes inside it), restored afterwards."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def terminate_pool(pool) -> None:
    """Cancel a ``ProcessPoolExecutor``'s pending work and terminate its worker processes now."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=5)
