"""Small file helpers shared by every writer: atomic writes and checksums."""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

from frbench.errors import FrbenchError


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def sha256_text(text: str) -> str:
    """Hex sha256 of a string's UTF-8 bytes."""
    return hashlib.sha256(text.encode()).hexdigest()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` so that readers see the old or the new file, never half.

    The bytes go to a temporary file in the same folder, is flushed to disk and
    renamed over ``path``. On any failure the old file is left untouched and a
    `FrbenchError` names the path.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise FrbenchError(f"cannot write {path}: {exc.strerror or exc}") from exc
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the file ordinary permissions
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise FrbenchError(f"cannot write {path}: {exc.strerror or exc}") from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def check_output_path(path: str | os.PathLike, option: str = "--out", suffixes: tuple[str, ...] = (),
                      folder: bool = False) -> Path:
    """Fail fast, before any work, unless ``path`` can be written; creates and leaves nothing.

    ``path`` is a file to write (``folder=False``, its suffix one of ``suffixes`` when given) or a folder to
    write files into (``folder=True``). The nearest existing ancestor must be a folder in which a file can
    actually be created: a temporary file is made there and removed at once (permission bits alone do not
    tell, e.g. for root or under /proc).

    Raises:
        FrbenchError: one line naming ``option``, the path and what is wrong.
    """
    path = Path(path)
    label = f"{option} {path}"
    if suffixes and not folder and path.suffix.lower() not in suffixes:
        raise FrbenchError(f"{label}: expected a {' or '.join(suffixes)} file")
    if path.exists():
        if folder and not path.is_dir():
            raise FrbenchError(f"{label}: is a file, expected a folder")
        if not folder and path.is_dir():
            raise FrbenchError(f"{label}: is a folder, expected a file path")
    existing = next(p for p in [path if folder else path.parent, *path.parents] if p.exists() or p == Path(p.anchor))
    existing = existing if str(existing) else Path(".")
    if not existing.is_dir():
        raise FrbenchError(f"{label}: cannot create it, {existing} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".frbench-probe-", dir=existing)
    except OSError as exc:
        raise FrbenchError(f"{label}: cannot write in {existing} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    if path.is_file() and not os.access(path, os.W_OK):
        raise FrbenchError(f"{label}: the file exists and is not writable")
    return path
