"""Leaderboard records: building, validating, storing and loading them.

A record (``record_schema_version`` 1, schema ``record-v1.schema.json``) is::

    {"record_schema_version": 1, "id": <sha256 of the results' canonical JSON>,
     "submission": {name, policy, description, submitter, link, submitted},
     "track": "main" | "humanoid" | "partial", "scores": <recomputed>, "results": <the results, verbatim>}

(the track: `frbench.leaderboard.scores.track_of`; ``humanoid`` from protocol 1.3 on.)

Records keep the results verbatim, per-episode records included, so anyone can
re-check them and recompute the id. The id depends on the results only: the
same results cannot be submitted twice under another name.

Storage: one gzip file per record, ``records/<id>.json.gz`` (:func:`record_path`),
holding the record's deterministic pretty JSON (:func:`record_text`) compressed
at level 9 with no file name and modification time 0 (:func:`record_bytes`), so
the same record always gives the same bytes; ``zcat`` shows it. A full
standard-grid record is 3 MB of JSON and about 0.45 MB stored. The id is the
hash of the results, not of the file, so compressing changed no id. A record
named ``<id>.json`` (the uncompressed form frbench wrote before) is still read
when given by path (`frbench verify FILE`); inside a leaderboard folder it is
reported, with the command that compresses it. Files are created atomically
and exclusively (:func:`write_record`: a complete temporary file hard-linked to
its name, which fails if that name exists), so concurrent submissions never
overwrite or half-write a record.

The API other modules use: :func:`record_path`, :func:`write_record`,
:func:`replace_record`, :func:`read_record` (a file, or an id or id prefix in a
leaderboard folder), :func:`load_records` and :func:`record_files`.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import re
import tempfile
import unicodedata
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from frbench.errors import FrbenchError, ResultsError
from frbench.io import atomic_write_bytes, sha256_text
from frbench.leaderboard.jsonfile import (
    MAX_RESULTS_BYTES,
    canonical_json,
    gzip_bytes,
    json_object_from_bytes,
    pretty_json,
    read_file_bytes,
)
from frbench.leaderboard.paths import RECORDS
from frbench.leaderboard.results import check_results
from frbench.leaderboard.scores import record_scores, results_track
from frbench.schemas import validate

RECORD_SCHEMA_VERSION = 1
#: Largest record file read (results plus a little).
MAX_RECORD_BYTES = MAX_RESULTS_BYTES + 1024 * 1024

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
LINK_RE = re.compile(r"^https?://[A-Za-z0-9.-]+(:[0-9]{1,5})?(/[A-Za-z0-9._~:/?#\[\]@!$&()*+,;=%-]*)?$")
#: A record's file name: its id and this suffix (gzip JSON).
RECORD_SUFFIX = ".json.gz"
RECORD_FILE_RE = re.compile(r"^[0-9a-f]{64}\.json\.gz$")
#: The uncompressed name frbench wrote before; still read by path, reported inside a leaderboard folder.
UNCOMPRESSED_RECORD_RE = re.compile(r"^[0-9a-f]{64}\.json$")
#: A record id, or the first 8 or more hex digits of one.
ID_PREFIX_RE = re.compile(r"^[0-9a-f]{8,64}$")
DESCRIPTION_MAX = 280
SUBMITTER_MAX = 64
LINK_MAX = 300
DEFAULT_SUBMITTER = "anonymous"


def record_id(results: dict) -> str:
    """A record's id: the sha256 of its results' canonical JSON."""
    return sha256_text(canonical_json(results))


# --------------------------------------------------------------------------- submission fields


def check_name(value: str, label: str = "--name") -> str:
    if not NAME_RE.match(value):
        raise ResultsError(
            f"{label}: {value[:80]!r} is not allowed; use 1-64 letters, digits, '.', '_' or '-', starting with a letter or digit"
        )
    return value


def check_text(value: str, label: str, limit: int, *, required: bool = False) -> str:
    """Free text shown on the board: one line, no markup, no control or formatting characters."""
    if required and not value:
        raise ResultsError(f"{label}: must not be empty")
    if len(value) > limit:
        raise ResultsError(f"{label}: is {len(value)} characters long, above the limit of {limit}")
    for char in value:
        if unicodedata.category(char) in ("Cc", "Cf", "Zl", "Zp") or char == "\ufeff":
            raise ResultsError(f"{label}: control or formatting character U+{ord(char):04X} is not allowed (one line of plain text)")
        if char in "<>":
            raise ResultsError(f"{label}: {char!r} is not allowed (plain text only, no markup)")
    return value


def check_link(value: str | None, label: str = "--link") -> str | None:
    if value is None or value == "":
        return None
    if len(value) > LINK_MAX:
        raise ResultsError(f"{label}: is {len(value)} characters long, above the limit of {LINK_MAX}")
    if not LINK_RE.match(value):
        raise ResultsError(
            f"{label}: {value[:80]!r} is not allowed; give an http:// or https:// URL without spaces, quotes or '<', '>'"
        )
    return value


def submission_fields(
    results: dict,
    *,
    name: str | None,
    description: str | None,
    submitter: str | None,
    link: str | None,
    submitted: str,
) -> dict:
    """The record's ``submission`` block, checked (labels name the CLI options)."""
    return {
        "name": check_name(name if name is not None else results["policy"]["name"]),
        "policy": results["policy"]["name"],
        "description": check_text((description or "").strip(), "--description", DESCRIPTION_MAX),
        "submitter": check_text((submitter or DEFAULT_SUBMITTER).strip(), "--submitter", SUBMITTER_MAX, required=True),
        "link": check_link((link or "").strip() or None),
        "submitted": submitted,
    }


# --------------------------------------------------------------------------- records


def build_record(results: dict, submission: dict) -> dict:
    """A complete record for checked ``results`` (see :func:`~frbench.leaderboard.results.check_results`)."""
    track = results_track(results)
    record = {
        "record_schema_version": RECORD_SCHEMA_VERSION,
        "id": record_id(results),
        "submission": submission,
        "track": track,
        "scores": record_scores(results["cells"], track),
        "results": results,
    }
    validate(record, "record-v1")
    return record


def record_file_name(record_id: str) -> str:
    """The file name of the record with id ``record_id``: ``<id>.json.gz``."""
    return f"{record_id}{RECORD_SUFFIX}"


def record_path(root: Path, record_id: str) -> Path:
    """Where the record with id ``record_id`` is stored in the leaderboard folder ``root``."""
    return root / RECORDS / record_file_name(record_id)


def record_text(record: dict) -> str:
    """A record's JSON text (deterministic): what its file decompresses to."""
    return pretty_json(record) + "\n"


def record_bytes(record: dict) -> bytes:
    """A record's file content: :func:`record_text` gzip-compressed deterministically (same record, same bytes)."""
    return gzip_bytes(record_text(record).encode("utf-8"))


def write_record(root: Path, record: dict) -> Path:
    """Create the record's file in ``root`` atomically and exclusively; raise :class:`DuplicateRecord` if it exists."""
    path = record_path(root, record["id"])
    create_exclusive(path, record_bytes(record))
    return path


def replace_record(path: Path, record: dict) -> None:
    """Rewrite an existing record file atomically after checking the new content (its id cannot change)."""
    check_record(record, file_name=path.name)
    atomic_write_bytes(path, record_bytes(record))
    os.chmod(path, 0o644)


def _differs(stored: Any, fresh: Any) -> bool:
    if isinstance(stored, dict) and isinstance(fresh, dict):
        return stored.keys() != fresh.keys() or any(_differs(stored[k], fresh[k]) for k in stored)
    if isinstance(stored, (int, float)) and isinstance(fresh, (int, float)) and not isinstance(stored, bool):
        return not math.isclose(stored, fresh, rel_tol=1e-12, abs_tol=1e-12)
    return stored != fresh


def check_record(record: Any, *, file_name: str | None = None) -> None:
    """Raise ``ResultsError('field: problem')`` unless ``record`` is a valid record (and is named ``file_name``)."""
    if not isinstance(record, dict):
        raise ResultsError("(top level): expected a JSON object")
    if "record_schema_version" not in record:
        raise ResultsError(f"record_schema_version: required field is missing; expected {RECORD_SCHEMA_VERSION}")
    version = record["record_schema_version"]
    if isinstance(version, bool) or version != RECORD_SCHEMA_VERSION:
        raise ResultsError(f"record_schema_version: {version!r} is not supported; this frbench reads record_schema_version {RECORD_SCHEMA_VERSION}")
    validate(record, "record-v1")
    results = record["results"]
    try:
        check_results(results, schema_checked=True)
    except ResultsError as exc:
        raise ResultsError(f"results.{exc}") from None
    expected = record_id(results)
    if record["id"] != expected:
        raise ResultsError(f"id: {record['id']} is not the sha256 of the record's results ({expected}); was the record edited?")
    if file_name is not None and file_name not in (record_file_name(expected), f"{expected}.json"):
        raise ResultsError(f"file name: a record with id {expected} must be named {record_file_name(expected)}")
    submission = record["submission"]
    check_name(submission["name"], "submission.name")
    check_text(submission["description"], "submission.description", DESCRIPTION_MAX)
    check_text(submission["submitter"], "submission.submitter", SUBMITTER_MAX, required=True)
    check_link(submission["link"], "submission.link")
    if submission["policy"] != results["policy"]["name"]:
        raise ResultsError(f"submission.policy: {submission['policy']!r} but results.policy.name is {results['policy']['name']!r}")
    attached = record.get("policy_file")
    if attached is not None and results["policy"]["sha256"] not in (None, attached["sha256"]):
        raise ResultsError(f"policy_file.sha256: {attached['sha256']} is not the checkpoint the results were evaluated "
                           f"with (results.policy.sha256 {results['policy']['sha256']})")
    track = results_track(results)
    if record["track"] != track:
        raise ResultsError(f"track: {record['track']!r} but its cells put it on the {track!r} track")
    fresh = record_scores(results["cells"], track)
    if _differs(record["scores"], fresh):
        raise ResultsError(
            f"scores: differ from the scores recomputed from results.cells "
            f"(overall {record['scores']['overall']!r} recorded, {fresh['overall']!r} recomputed)"
        )


def record_file_bytes(path: Path) -> bytes:
    """The bytes of a record file, refused (one line naming it) above :data:`MAX_RECORD_BYTES`."""
    return read_file_bytes(path, limit=MAX_RECORD_BYTES)


def load_record(path: Path, data: bytes | None = None) -> dict:
    """Read (gzip or plain JSON) and fully check one record file (or its bytes ``data``, already read); errors
    name the file."""
    if data is None:
        data = record_file_bytes(path)
    record = json_object_from_bytes(data, limit=MAX_RECORD_BYTES, source=str(path))
    try:
        check_record(record, file_name=path.name)
    except ResultsError as exc:
        raise ResultsError(f"{path}: {exc}") from None
    return record


def find_record(root: Path, prefix: str) -> Path:
    """The record file in ``root`` whose id starts with ``prefix`` (8 to 64 hex digits); one line if none or several."""
    if not ID_PREFIX_RE.match(prefix):
        raise FrbenchError(f"record {prefix[:80]!r}: expected a record id, or at least its first 8 hex digits")
    matches = sorted((root / RECORDS).glob(f"{prefix}*{RECORD_SUFFIX}"))
    if len(matches) != 1:
        found = "no record" if not matches else f"{len(matches)} records"
        raise FrbenchError(f"record {prefix!r}: {found} in {root / RECORDS} with that id")
    return matches[0]


def read_record(path_or_id: str | os.PathLike, root: Path | None = None) -> dict:
    """A checked record: from a record file, or by its id (or an id prefix of 8+ hex digits) in the leaderboard
    folder ``root`` (default: `frbench.leaderboard.paths.resolve_root`)."""
    path = Path(path_or_id)
    if isinstance(path_or_id, str) and ID_PREFIX_RE.match(path_or_id) and not path.exists():
        from frbench.leaderboard.paths import resolve_root

        path = find_record(root if root is not None else resolve_root(None), path_or_id)
    return load_record(path)


def compress_hint(path: Path) -> str:
    """What to do with an uncompressed record file found in a leaderboard folder."""
    return (f"{path}: a record stored uncompressed; records are stored as <id>{RECORD_SUFFIX}: "
            f"run `gzip -9n {path}` (or submit its results again)")


def record_files(root: Path) -> tuple[list[Path], list[Path]]:
    """(record files ``<id>.json.gz``, other files) in ``root/records``; ``.gitkeep`` is neither."""
    folder = root / RECORDS
    if not folder.is_dir():
        return [], []
    records, others = [], []
    for path in sorted(folder.iterdir()):
        if path.name == ".gitkeep":
            continue
        (records if RECORD_FILE_RE.match(path.name) and path.is_file() else others).append(path)
    return records, others


def load_records(root: Path) -> list[dict]:
    """Every record in ``root/records``, checked; temporary dot-files of submissions in progress are skipped."""
    records, _ = record_files(root)
    return [load_record(path) for path in records]


# --------------------------------------------------------------------------- storage


class DuplicateRecord(ResultsError):
    """The same results were already submitted."""


@contextlib.contextmanager
def locked(root: Path) -> Iterator[None]:
    """Serialize leaderboard writers with an advisory lock on the leaderboard folder itself (no lock file)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: exclusive creation still protects records
        yield
        return
    fd = os.open(root, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def create_exclusive(path: Path, text: str | bytes) -> None:
    """Create ``path`` with ``text`` (UTF-8 text, or bytes) atomically; raise :class:`DuplicateRecord` if it exists.

    The text goes to a temporary file in the same folder, is synced, and is
    hard-linked to ``path`` (``link`` fails if ``path`` exists, and readers
    never see a partial file). On file systems without hard links it falls back
    to ``O_CREAT | O_EXCL``.
    """
    data = text if isinstance(text, bytes) else text.encode("utf-8")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".incoming-", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fchmod(handle.fileno(), 0o644)
            os.fsync(handle.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise DuplicateRecord(f"{path.name} exists") from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV, errno.EMLINK):
                raise FrbenchError(f"cannot write {path}: {exc.strerror or exc}") from exc
            try:
                out = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                raise DuplicateRecord(f"{path.name} exists") from None
            with os.fdopen(out, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
    except OSError as exc:
        raise FrbenchError(f"cannot write {path}: {exc.strerror or exc}") from exc
    finally:
        Path(tmp).unlink(missing_ok=True)
    _fsync_dir(path.parent)


@dataclass
class Submission:
    """What :func:`~frbench.leaderboard.board.submit` did."""

    record: dict
    path: Path
    written: bool
    #: The results were a record already: only its policy file was attached.
    attached_only: bool = False
