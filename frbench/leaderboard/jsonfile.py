"""Strict JSON reading and deterministic JSON writing for results and records.

Reading refuses, with one line naming the file: files above a size limit (by
``stat`` before reading, and by never reading more than the limit), bytes that
are not UTF-8, malformed or truncated JSON, duplicate keys, and a top level
that is not an object. A gzip file (recognised by its magic bytes, whatever
its name: leaderboard records are stored as ``<id>.json.gz``) is read
decompressed, the limit applying to the compressed and to the decompressed
bytes, so a small file that inflates without bound is refused too. ``NaN``/``Infinity`` are read as
:class:`~frbench.schemas.NonFinite` markers so schema validation can name the
field that holds them.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from frbench.errors import ResultsError
from frbench.schemas import NonFinite

#: Largest results file ``frbench submit`` reads (a full standard grid is a few MB).
MAX_RESULTS_BYTES = 50 * 1024 * 1024
#: Deepest nesting of objects and arrays accepted (results need 4).
MAX_DEPTH = 32


def _megabytes(size: int) -> str:
    return f"{size / (1024 * 1024):.1f} MB"


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict:
    result: dict = {}
    for key, value in pairs:
        if key in result:
            raise _DuplicateKey(key)
        result[key] = value
    return result


class _DuplicateKey(Exception):
    pass


def parse_json_text(text: str, source: str) -> Any:
    """Parse JSON text strictly; errors name ``source`` and the line and column."""
    if not text.strip():
        raise ResultsError(f"{source}: file is empty; expected a JSON object")
    try:
        return json.loads(text, parse_constant=NonFinite, object_pairs_hook=_no_duplicates)
    except _DuplicateKey as exc:
        raise ResultsError(f"{source}: not valid: the key {exc.args[0]!r} appears twice in one object") from None
    except RecursionError:
        raise ResultsError(f"{source}: not valid: JSON nested too deeply") from None
    except json.JSONDecodeError as exc:
        if _ends_early(text, exc):
            end = text.rstrip()
            line = end.count("\n") + 1
            column = len(end) - (end.rfind("\n") + 1) + 1
            raise ResultsError(
                f"{source}: not valid JSON: the text ends early at line {line} column {column} "
                f"with a string, object or array still open; is the file truncated?"
            ) from None
        raise ResultsError(f"{source}: not valid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None


def _ends_early(text: str, exc: json.JSONDecodeError) -> bool:
    """Does the text stop inside a value (a truncated file) rather than break a rule midway?

    ``json`` reports "Unterminated string" only when a string runs to the end of
    the text (a raw line break inside a string is an "Invalid control character").
    """
    return exc.pos >= len(text.rstrip()) or exc.msg.startswith("Unterminated string")


def read_capped(path: Path, limit: int, source: str, too_big) -> bytes:
    """The bytes of ``path``, refused by ``stat`` before reading when above ``limit`` and never reading more
    than ``limit`` + 1 bytes; ``too_big(size)`` words the refusal (``size`` None: the file grew while read)."""
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise ResultsError(f"{source}: no such file") from None
    except OSError as exc:
        raise ResultsError(f"{source}: cannot read: {exc.strerror or exc}") from None
    if size > limit:
        raise ResultsError(too_big(size))
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise ResultsError(f"{source}: cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:  # grew after stat, or a device/pipe
        raise ResultsError(too_big(None))
    return data


#: The first two bytes of every gzip file.
GZIP_MAGIC = b"\x1f\x8b"


def gunzip_capped(data: bytes, limit: int, source: str) -> bytes:
    """The decompressed bytes of the gzip ``data``, refused (one line naming ``source``) when corrupt, truncated,
    followed by other bytes, or above ``limit`` bytes once decompressed (never inflating more than ``limit`` + 1)."""
    import zlib

    inflater = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)  # gzip header and trailer
    try:
        out = inflater.decompress(data, limit + 1)
    except zlib.error as exc:
        raise ResultsError(f"{source}: not a valid gzip file ({exc})") from None
    if len(out) > limit:
        raise ResultsError(f"{source}: decompresses to more than the {_megabytes(limit)} limit; refusing to read it")
    if not inflater.eof:
        raise ResultsError(f"{source}: the gzip data ends early; is the file truncated?")
    if inflater.unused_data:
        raise ResultsError(f"{source}: {len(inflater.unused_data)} bytes follow the gzip data; expected one gzip member")
    return out


def gzip_bytes(data: bytes) -> bytes:
    """``data`` gzip-compressed deterministically: level 9, no file name, modification time 0."""
    import gzip

    return gzip.compress(data, compresslevel=9, mtime=0)


def read_json_object(path: str | os.PathLike, *, limit: int = MAX_RESULTS_BYTES, source: str | None = None) -> dict:
    """Read a JSON object from ``path`` (plain or gzip), refusing files above ``limit`` bytes before reading them."""
    source = source or str(path)
    return json_object_from_bytes(read_file_bytes(path, limit=limit, source=source), limit=limit, source=source)


def read_file_bytes(path: str | os.PathLike, *, limit: int, source: str | None = None) -> bytes:
    """The bytes of the file ``path`` (a JSON file, plain or gzip), refused by size before reading (`read_capped`)."""
    path = Path(path)
    source = source or str(path)
    if path.is_dir():
        raise ResultsError(f"{source}: is a directory, not a JSON file")
    return read_capped(path, limit, source, lambda size: f"{source}: file is {'' if size is None else _megabytes(size) + ', '}"
                       f"above the {_megabytes(limit)} limit; refusing to read it")


def json_object_from_bytes(data: bytes, *, limit: int, source: str) -> dict:
    """The JSON object in a file's bytes ``data`` (plain or gzip), with the checks of :func:`read_json_object`."""
    if data.startswith(GZIP_MAGIC):
        data = gunzip_capped(data, limit, source)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ResultsError(f"{source}: not UTF-8 text (byte {exc.start}); expected a JSON file") from None
    value = parse_json_text(text, source)
    if _depth(value) > MAX_DEPTH:
        raise ResultsError(f"{source}: not valid: JSON nested deeper than {MAX_DEPTH} levels")
    if not isinstance(value, dict):
        kind = "array" if isinstance(value, list) else type(value).__name__
        raise ResultsError(f"{source}: expected a JSON object at the top level, got {kind}")
    return value


def _depth(value: Any) -> int:
    """How deeply containers nest (iteratively, so deep input cannot exhaust the stack)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, depth)
            if depth <= MAX_DEPTH:
                stack.extend((child, depth + 1) for child in (node.values() if isinstance(node, dict) else node))
    return deepest


def canonical_json(value: Any) -> str:
    """The text hashed for a record id: sorted keys, no spaces, ASCII only, finite numbers."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def _is_flat(value: Any) -> bool:
    items = value.values() if isinstance(value, dict) else value
    return all(not isinstance(item, (dict, list)) or not item for item in items)


def pretty_json(value: Any, indent: int = 1, _level: int = 0) -> str:
    """Deterministic, diff-friendly JSON: sorted keys; containers holding only scalars on one line.

    A cell or episode is then one line, so a record of thousands of episodes
    stays small and reviewable. Parsing the output gives back ``value``.
    """
    if not isinstance(value, (dict, list)) or not value or _is_flat(value):
        return json.dumps(value, sort_keys=True, separators=(", ", ": "), ensure_ascii=True, allow_nan=False)
    pad = " " * (indent * (_level + 1))
    end = " " * (indent * _level)
    if isinstance(value, dict):
        parts = [f"{pad}{json.dumps(k, ensure_ascii=True)}: {pretty_json(value[k], indent, _level + 1)}" for k in sorted(value)]
        return "{\n" + ",\n".join(parts) + "\n" + end + "}"
    parts = [f"{pad}{pretty_json(item, indent, _level + 1)}" for item in value]
    return "[\n" + ",\n".join(parts) + "\n" + end + "]"
