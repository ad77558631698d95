"""Where the leaderboard lives.

The leaderboard folder is, in order of precedence:

1. the ``--root`` option of ``frbench submit`` / ``frbench leaderboard``;
2. the environment variable ``FRBENCH_LEADERBOARD_DIR``;
3. the repository's ``leaderboard/`` when frbench runs from a source checkout
   (an editable install: the folder above the ``frbench`` package holds
   ``pyproject.toml`` and ``leaderboard/``);
4. otherwise ``./leaderboard`` in the current working directory (a regular,
   non-editable install: run frbench from a clone of the repository).

Layout: ``records/<id>.json.gz`` (one gzip JSON file per submission), ``schema/`` (copies of
the record and results JSON Schemas), ``README.md`` and ``index.html``
(generated from the records).
"""

from __future__ import annotations

import os
from pathlib import Path

from frbench.errors import FrbenchError

ENV_VAR = "FRBENCH_LEADERBOARD_DIR"
RECORDS = "records"
SCHEMA = "schema"
README = "README.md"
INDEX = "index.html"


def default_root() -> Path:
    """The leaderboard folder when no ``--root`` is given (see the module doc)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env)
    checkout = Path(__file__).resolve().parents[2]
    if (checkout / "pyproject.toml").is_file() and (checkout / "leaderboard").is_dir():
        return checkout / "leaderboard"
    return Path.cwd() / "leaderboard"


def resolve_root(root: str | os.PathLike | None) -> Path:
    """The leaderboard folder to use; it must exist (frbench never creates it silently)."""
    path = Path(root) if root else default_root()
    if not path.is_dir():
        raise FrbenchError(
            f"leaderboard folder {path} does not exist; run frbench from a clone of the frbench repository, "
            f"pass --root DIR or set {ENV_VAR}"
        )
    return path
