"""The tracked tree stays light: every clone carries it, and a lent GPU machine receives at most 64 MiB of it.

The budget is 40 MiB (README.md, "Size of a clone"); this test fails above it, naming the largest folders, so that a
growing tree is noticed well before it reaches the limit of a machine it must be sent to. Measured: the sum of the
sizes of the files ``git ls-files`` lists (as they are in the working tree), not the git history.
"""

from __future__ import annotations

import shutil
import subprocess
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The tree's budget [MiB], where this test fails.
BUDGET_MIB = 40


def tracked_sizes(root: Path) -> dict[str, int]:
    """Path -> size [bytes] of every file git tracks below ``root`` (files deleted in the working tree left out)."""
    listed = subprocess.run(["git", "-C", str(root), "ls-files", "-z"], capture_output=True, check=True).stdout
    sizes = {}
    for name in listed.decode().split("\0"):
        path = root / name
        if name and path.is_file() and not path.is_symlink():
            sizes[name] = path.stat().st_size
    return sizes


def largest_folders(sizes: dict[str, int], depth: int = 2, most: int = 8) -> list[tuple[str, int]]:
    """The ``most`` largest folders, ``depth`` levels deep (a file at the top counts as ``.``), largest first."""
    totals: Counter[str] = Counter()
    for name, size in sizes.items():
        parts = name.split("/")[:-1]
        totals["/".join(parts[:depth]) or "."] += size
    return totals.most_common(most)


def mib(size: int) -> str:
    return f"{size / 2**20:.1f} MiB"


def test_largest_folders_are_summed_to_the_requested_depth():
    sizes = {"a/b/c/x.pt": 3 * 2**20, "a/b/y.json": 2**20, "a/z.md": 10, "top.txt": 5, "d/e/f.bin": 2 * 2**20}
    assert largest_folders(sizes) == [("a/b", 4 * 2**20), ("d/e", 2 * 2**20), ("a", 10), (".", 5)]
    assert largest_folders(sizes, depth=1, most=2) == [("a", 4 * 2**20 + 10), ("d", 2 * 2**20)]
    assert mib(40 * 2**20) == "40.0 MiB"


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_the_tracked_tree_stays_within_its_budget():
    sizes = tracked_sizes(ROOT)
    total = sum(sizes.values())
    if total > BUDGET_MIB * 2**20:
        folders = ", ".join(f"{name} {mib(size)}" for name, size in largest_folders(sizes))
        pytest.fail(f"the tracked files total {mib(total)}, above the {BUDGET_MIB} MiB budget; "
                    f"largest folders: {folders}. Keep generated bulk, logs and resumable training states out of the "
                    f"tree (README.md, \"Size of a clone\")")
    assert len(sizes) > 100  # the listing found the tree
