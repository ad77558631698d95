"""Results that are slow to compute and fixed by their inputs, kept in frbench's cache folder.

A cached file is named by `content_key` of everything it depends on: the
inputs' ``repr`` (frozen dataclasses print every field, floats exactly), file
texts, the source text of the modules that compute it and library versions, so
that a change of any of them computes and stores a new entry rather than
reading a stale one. Entries are written atomically (`frbench.io.atomic_write_bytes`);
a damaged or unreadable entry is computed again. Folder: ``$FRBENCH_CACHE/<kind>/``.
"""

from __future__ import annotations

import hashlib
import inspect
from functools import lru_cache
from pathlib import Path
from typing import Callable


from frbench.errors import FrbenchError
from frbench.io import atomic_write_bytes
from frbench.robots.paths import cache_dir
#: Memo of `object_key` by object identity (the object is kept so that its id stays unique).
_OBJECT_KEYS: dict[int, tuple[object, str]] = {}


def content_key(*parts) -> str:
    """A 24-hex-digit SHA-256 key of ``parts`` (bytes as they are, anything else by its ``repr``)."""
    digest = hashlib.sha256()
    for part in parts:
        data = part if isinstance(part, bytes) else repr(part).encode()
        digest.update(len(data).to_bytes(8, "little"))
        digest.update(data)
    return digest.hexdigest()[:24]


def object_key(obj) -> str:
    """`content_key` of one large immutable object (e.g. a terrain of 70 k boxes), computed once per object."""
    held = _OBJECT_KEYS.get(id(obj))
    if held is None or held[0] is not obj:
        held = (obj, content_key(obj))
        _OBJECT_KEYS[id(obj)] = held
    return held[1]


@lru_cache(maxsize=None)
def source_key(*modules: str) -> str:
    """`content_key` of the source text of the named modules (a code change invalidates their entries)."""
    import importlib

    return content_key(*(inspect.getsource(importlib.import_module(name)) for name in modules))


def cache_path(kind: str, key: str, suffix: str) -> Path:
    """Where the entry ``key`` of ``kind`` lives: ``$FRBENCH_CACHE/<kind>/<key><suffix>``."""
    return cache_dir() / kind / f"{key}{suffix}"


def cached_bytes(kind: str, key: str, suffix: str, compute: Callable[[], bytes],
                 load: Callable[[bytes], object]):
    """``load`` of the stored entry, or of ``compute()`` stored first; a failing load computes it again."""
    path = cache_path(kind, key, suffix)
    if path.is_file():
        try:
            return load(path.read_bytes())
        except Exception:  # a damaged entry (e.g. another version's format): compute it again
            pass
    data = compute()
    try:
        atomic_write_bytes(path, data)
    except FrbenchError:
        pass  # a read-only cache only costs the time
    return load(data)
