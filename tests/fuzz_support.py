"""What every fuzz case of tests/test_fuzz_*.py must satisfy, and a sandbox to run it in.

A case calls the CLI in-process (`frbench.cli.main`) inside :func:`sandbox`: a fresh temporary folder that is
the working directory and ``HOME``, with frbench's own folders (``FRBENCH_CACHE``, ``FRBENCH_CONFIG``,
``FRBENCH_LEADERBOARD_DIR``) inside it. :func:`outcome` runs the command; :func:`assert_clean` then asks for
a valid result (exit 0, or 1 where the command reports a failed check) or one line on stderr with exit 2, never a
traceback, and that nothing outside frbench's folders and the command's own outputs changed.

Budgets: ``SMOKE`` examples per property in `make test` (seconds in all), ``SLOW`` under ``pytest -m slow``
(at least 10,000 generated cases over all properties). Examples are derandomized (the same cases every run)
and no example database is written.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from hypothesis import HealthCheck, event, settings
from hypothesis.control import currently_in_test_context

from frbench.cli import main

#: Frbench's folders inside a sandbox: writes there are frbench's own.
FRBENCH_DIRS = ("cache", "config", "leaderboard")
SHARED_CACHE = Path(tempfile.gettempdir()) / "frbench-fuzz-cache"


def fuzz_settings(examples: int) -> settings:
    """Hypothesis settings for a property: ``examples`` cases, deterministic, no database, no deadline."""
    return settings(max_examples=examples, deadline=None, derandomize=True, database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much,
                                           HealthCheck.function_scoped_fixture])


@dataclass
class Outcome:
    """A finished command: exit status, stdout, stderr."""

    status: int
    out: str
    err: str


def outcome(*argv) -> Outcome:
    """Run ``frbench ARGV`` in-process; argparse's exits are statuses, any other exception propagates."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main([str(a) for a in argv])
        except SystemExit as exc:
            status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    return Outcome(int(status), out.getvalue(), err.getvalue())


def snapshot(folder: Path, skip: tuple[str, ...]) -> dict[str, bytes | None]:
    """Every path below ``folder`` except the top-level names in ``skip``, with file bytes (folders: None)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        relative = path.relative_to(folder)
        if relative.parts[0] in skip:
            continue
        found[str(relative)] = path.read_bytes() if path.is_file() and not path.is_symlink() else None
    return found


@contextlib.contextmanager
def sandbox(board_from: Path | None = None):
    """A fresh working directory and HOME with frbench's folders inside (``board_from``: a leaderboard to copy)."""
    saved_cwd, saved_env = os.getcwd(), dict(os.environ)
    with tempfile.TemporaryDirectory(prefix="frbench-fuzz-") as name:
        root = Path(name)
        SHARED_CACHE.mkdir(exist_ok=True)
        (root / "cache").symlink_to(SHARED_CACHE)  # simulation URDFs and models: reused across cases
        if board_from is not None:
            shutil.copytree(board_from, root / "leaderboard")
        os.environ.update(HOME=str(root), FRBENCH_CACHE=str(SHARED_CACHE), FRBENCH_CONFIG=str(root / "config"),
                          FRBENCH_LEADERBOARD_DIR=str(root / "leaderboard"))
        os.chdir(root)
        try:
            yield root
        finally:
            os.chdir(saved_cwd)
            os.environ.clear()
            os.environ.update(saved_env)


def assert_clean(result: Outcome, before: dict, root: Path, *, outputs: tuple[str, ...] = (), failing: bool = False,
                 label: str = "") -> None:
    """A valid result (0; 1 too when ``failing``: a check that reports failure) or one line with exit 2; no traceback;
    nothing changed in ``root`` outside frbench's folders and ``outputs`` (top-level names the command may write).
    The exit status is counted per ``label`` in Hypothesis's statistics (``--hypothesis-show-statistics``)."""
    if currently_in_test_context():
        event(f"{label} exit {result.status}".strip())
    assert "Traceback" not in result.err and "Traceback" not in result.out, result.err
    allowed = (0, 1) if failing else (0,)
    if result.status == 2:
        assert result.err.count("\n") == 1 and result.err.startswith("frbench") and ": error: " in result.err, result.err
    else:
        assert result.status in allowed, (result.status, result.err[-2000:])
    assert snapshot(root, FRBENCH_DIRS + outputs) == before
