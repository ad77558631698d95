"""The board's view of each record, checked and computed once per record file content, then cached.

Checking a record in full (`frbench.leaderboard.records.check_record`: its JSON Schema over thousands of
episodes, its self-consistency) and bootstrapping its score intervals take about a second per record; a
board of 74 records took 84 s to print on 2 cores when every read did both again. A record file's bytes fix
everything the board shows, so the board reads *summaries* instead:

* a summary is the checked record without ``results.episodes`` (the per-episode list, about 85 % of its
  bytes; the cells keep their counts, rates and means), plus the field :data:`BOARD_FIELD` holding what
  the board and the page compute from it that is slow: the 95 % intervals of its scores unfiltered and per
  robot, backend and terrain family (`interval_views`) and its generalisation scores;
* it is made only from a record that passed the full check, and stored in frbench's cache folder
  (`frbench.content_cache`, kind ``board-summaries``) under `summary_key`: the sha256 of the record file's
  bytes, the file's name, the source of the modules that check and score records, the schemas' texts and
  the versions of numpy and jsonschema. An edited file, a renamed one, another schema or other checking
  or scoring code is a cache miss: that record is read and checked in full again, and refused if invalid.

The cache serves `frbench leaderboard` (table, json, md, html) and `frbench submit`. `frbench leaderboard
--check` never reads it: it checks every file in full (`frbench.leaderboard.board.check`), and `frbench
verify` reads the whole record. Filters of more than one axis (``--robot R --backend B``) compute their
intervals from the summary's cells at each read.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path
from typing import Mapping

from frbench.leaderboard.records import load_record, record_bytes, record_file_bytes, record_file_name, record_files
from frbench.leaderboard.scores import generalisation, score_intervals, scored_cells

#: The summary's field holding its precomputed intervals and generalisation scores (never a record field).
BOARD_FIELD = "board"
#: ``frbench.content_cache`` kind of the stored summaries.
CACHE_KIND = "board-summaries"
#: The modules whose source decides whether a record is valid and what its summary holds.
CODE_MODULES = (
    "frbench.leaderboard.summaries", "frbench.leaderboard.records", "frbench.leaderboard.results",
    "frbench.leaderboard.scores", "frbench.leaderboard.jsonfile", "frbench.schemas", "frbench.schemas.validator",
    "frbench.evaluation.intervals", "frbench.evaluation.grids", "frbench.evaluation.results", "frbench.tasks.protocol",
    "frbench.leaderboard.reuse",
)
#: Filter name -> the key prefix in `interval_views` (the page's names).
VIEW_PREFIX = {"robot": "robot", "backend": "backend", "terrain": "family"}


def interval_views(record: Mapping) -> dict[str, dict | None]:
    """`score_intervals` of the record's scored cells unfiltered (key ``""``) and per value of each axis
    (``robot=go2``, ``backend=mujoco``, ``family=flat``): from its summary when it is one."""
    held = record.get(BOARD_FIELD)
    if held is not None:
        return held["intervals"]
    cells = scored_cells(record["results"]["cells"], record["track"])
    views = {"": score_intervals(cells)}
    for field, prefix in VIEW_PREFIX.items():
        for value in sorted({c[field] for c in cells}, key=str):
            views[f"{prefix}={value}"] = score_intervals(cells, **{field: value})
    return views


def record_intervals(record: Mapping, *, robot: str | None = None, backend: str | None = None,
                     terrain: str | None = None) -> dict | None:
    """`score_intervals` of the record's scored cells matching the filters (None if none match): read from
    its summary for no filter or one, computed for more."""
    given = [(VIEW_PREFIX[name], value) for name, value in (("robot", robot), ("backend", backend), ("terrain", terrain))
             if value is not None]
    held = record.get(BOARD_FIELD)
    if held is not None and len(given) <= 1:
        return held["intervals"].get("" if not given else f"{given[0][0]}={given[0][1]}")
    cells = scored_cells(record["results"]["cells"], record["track"])
    return score_intervals(cells, robot=robot, backend=backend, terrain=terrain)


def record_generalisation(record: Mapping) -> dict | None:
    """`generalisation` of the record's cells: from its summary when it is one."""
    held = record.get(BOARD_FIELD)
    if held is not None:
        return held["generalisation"]
    return generalisation(record["results"]["cells"], record["track"])


def summary_of(record: Mapping) -> dict:
    """The summary of a checked record (the module docstring)."""
    full = {key: value for key, value in record.items() if key != BOARD_FIELD}
    full["results"] = {key: value for key, value in record["results"].items() if key != "episodes"}
    full[BOARD_FIELD] = {"intervals": interval_views(record), "generalisation": record_generalisation(record)}
    return full


@lru_cache(maxsize=1)
def code_key() -> str:
    """What, besides a record file's bytes, decides its summary: the checking and scoring code, the schemas and
    the libraries that validate and resample."""
    import jsonschema  # noqa: F401  (its version below)
    import numpy

    from importlib.metadata import version

    from frbench.content_cache import content_key, source_key
    from frbench.schemas import SCHEMA_NAMES, schema_text

    return content_key(source_key(*CODE_MODULES), *(schema_text(name) for name in SCHEMA_NAMES),
                       numpy.__version__, version("jsonschema"))


def summary_key(name: str, data: bytes) -> str:
    """The cache key of the summary of the record file named ``name`` holding ``data``."""
    from frbench.content_cache import content_key

    return content_key(hashlib.sha256(data).digest(), name, code_key())


def _encode(summary: Mapping) -> bytes:
    return json.dumps(summary, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("utf-8")


def load_summary(path: Path) -> dict:
    """The summary of the record file ``path``: from the cache, else by checking the file in full (a
    `ResultsError` naming the file if it is invalid) and storing its summary."""
    from frbench.content_cache import cached_bytes

    data = record_file_bytes(path)
    return cached_bytes(CACHE_KIND, summary_key(path.name, data), ".json",
                        lambda: _encode(summary_of(load_record(path, data))), json.loads)


def load_summaries(root: Path) -> list[dict]:
    """The summaries of every record in ``root/records`` (`frbench.leaderboard.records.record_files`)."""
    paths, _ = record_files(root)
    return [load_summary(path) for path in paths]


def remember(record: Mapping, data: bytes | None = None) -> dict:
    """The summary of a checked ``record`` whose file holds ``data`` (default: `record_bytes`, what frbench
    writes), stored so that the next read finds it."""
    from frbench.content_cache import cached_bytes

    key = summary_key(record_file_name(record["id"]), record_bytes(record) if data is None else data)
    return cached_bytes(CACHE_KIND, key, ".json", lambda: _encode(summary_of(record)), json.loads)
