"""Policy files attached to leaderboard records: content-addressed, size-capped, beside the records.

``frbench submit RESULTS --policy-file FILE`` stores ``FILE`` as
``policies/<sha256><suffix>`` in the leaderboard folder (one copy however many
records attach it) and writes into the record::

    "policy_file": {"sha256": <hex>, "bytes": <size>, "file": "policies/<sha256><suffix>"}

The suffix is kept because it tells ``load_policy`` what the file is (``.pt``,
``.onnx``, ...). The policy's layout (its observation and action conventions)
is attached with it as its sidecar, stored as ``policies/<sha256><suffix>.json``
with its own hash (``sidecar_sha256``), where ``load_policy`` looks for it: the
``--spec`` file the results were evaluated with, else ``<FILE>.json`` beside
the file (an ONNX export's sidecar) when present.
The policy file and its sidecar together may hold at most
:data:`MAX_POLICY_BYTES` (16 MiB): a larger file is refused before it is read.

A file whose hash differs from the checkpoint the results were evaluated with
(``results.policy.sha256``) is refused: the record must carry the policy that
produced it.

A file that is a checkpoint shipped inside the frbench package (the
``SHIPPED_CHECKPOINTS`` of `frbench.policies.registry`, same sha256, no
sidecar) is not stored again: the record refers to it by hash::

    "policy_file": {"sha256": <hex>, "bytes": <size>, "shipped": <the name it is shipped under>}

and `frbench verify` and ``frbench leaderboard --check`` find it among the
shipped checkpoints by that hash (:func:`policy_path`); the name is for people.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from frbench.errors import FrbenchError, ResultsError
from frbench.io import sha256_file
from frbench.leaderboard.jsonfile import read_capped
from frbench.leaderboard.records import DuplicateRecord, create_exclusive
from frbench.policies.contract import sidecar_path
from frbench.policies.registry import BUILTIN_POLICIES, SHIPPED_CHECKPOINTS, shipped_checkpoint

#: Largest policy file (with its sidecar) a record may carry [bytes]: 16 MiB.
MAX_POLICY_BYTES = 16 * 1024 * 1024
#: Folder of the attached policy files inside the leaderboard folder.
POLICIES = "policies"
SUFFIX_RE = re.compile(r"^(\.[A-Za-z0-9_-]{1,16})?$")
STORED_RE = re.compile(r"^[0-9a-f]{64}(\.[A-Za-z0-9_-]{1,16})?(\.json)?$")


def _mib(size: int) -> str:
    return f"{size / (1024 * 1024):.1f} MiB"


@lru_cache(maxsize=64)
def _file_sha256(path: Path, mtime_ns: int, size: int) -> str:
    return sha256_file(path)


def shipped_with_hash(sha256: str) -> str | None:
    """The name of the checkpoint shipped inside the frbench package whose sha256 is ``sha256`` (None if none)."""
    for name in SHIPPED_CHECKPOINTS:
        path = shipped_checkpoint(name)
        if path.is_file():
            stat = path.stat()
            if _file_sha256(path, stat.st_mtime_ns, stat.st_size) == sha256:
                return name
    return None


@dataclass(frozen=True)
class PolicyFile:
    """A policy file read for attaching: its bytes and stored name, its sidecar's bytes (or None), and the name
    of the shipped checkpoint it is (None: not one, or it has a sidecar; then it is stored)."""

    data: bytes
    sha256: str
    suffix: str
    sidecar: bytes | None = None
    shipped: str | None = None

    @property
    def file(self) -> str:
        """Its path inside the leaderboard folder."""
        return f"{POLICIES}/{self.sha256}{self.suffix}"

    def entry(self) -> dict:
        """The record's ``policy_file`` field: a reference by hash to a shipped checkpoint, else the stored file."""
        if self.shipped is not None:
            return {"sha256": self.sha256, "bytes": len(self.data), "shipped": self.shipped}
        entry = {"sha256": self.sha256, "bytes": len(self.data), "file": self.file}
        if self.sidecar is not None:
            entry["sidecar_sha256"] = _sha256(self.sidecar)
        return entry


def _sha256(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


def _read_capped(path: Path, label: str, budget: int) -> bytes:
    """The bytes of ``path``, refused by size before reading (and never reading more than ``budget`` + 1)."""
    if path.is_dir():
        raise ResultsError(f"{label}: {path} is a directory; attach the policy file itself (a run folder's policy.pt)")
    data = read_capped(path, budget, f"{label}: {path}", lambda size: f"{label}: {path} is "
                       f"{'' if size is None else _mib(size) + ', '}above the {_mib(MAX_POLICY_BYTES)} limit of an attached policy")
    if not data:
        raise ResultsError(f"{label}: {path} is empty; expected a policy file")
    return data


def read_policy_file(path: str | os.PathLike, label: str = "--policy-file", layout: str | None = None) -> PolicyFile:
    """Read a policy file for attaching, with its layout as the sidecar: ``layout`` (the ``--spec`` file the results
    were evaluated with) if given, else ``<file>.json`` if present; errors name ``label`` and the file."""
    path = Path(path)
    if not SUFFIX_RE.match(path.suffix):
        raise ResultsError(f"{label}: {path}: the file name's suffix {path.suffix[:40]!r} is not allowed; "
                           "use at most 16 letters, digits, '_' or '-' after the dot (e.g. .pt, .onnx, .zip)")
    data = _read_capped(path, label, MAX_POLICY_BYTES)
    sidecar = Path(layout) if layout is not None else sidecar_path(path)
    if layout is not None and not sidecar.is_file():
        raise ResultsError(f"{label}: the results were evaluated with the layout file {layout} (--spec), which cannot be "
                           "read here; submit where it is, so that it is attached with the policy")
    sidecar = _read_capped(sidecar, label, MAX_POLICY_BYTES - len(data)) if sidecar.is_file() else None
    sha = _sha256(data)
    return PolicyFile(data, sha, path.suffix, sidecar, shipped_with_hash(sha) if sidecar is None else None)


def check_attachable(policy_file: PolicyFile, results: dict, source: str) -> None:
    """Refuse a file that cannot be the policy of ``results``: not its checkpoint, or results of a built-in policy."""
    recorded = results["policy"]["sha256"]
    if recorded is not None and recorded != policy_file.sha256:
        raise ResultsError(
            f"--policy-file {source}: its sha256 {policy_file.sha256[:16]}... is not the checkpoint these results were "
            f"evaluated with (results.policy.sha256 {recorded[:16]}...)"
        )
    if recorded is None and results["policy"]["name"] in BUILTIN_POLICIES:
        raise ResultsError(
            f"--policy-file {source}: these results are of the built-in policy {results['policy']['name']!r}, which is "
            "code in frbench, not a file; `frbench verify` re-runs it by name"
        )


def store(root: Path, policy_file: PolicyFile) -> None:
    """Write the policy file (and sidecar) under ``root/policies`` unless an identical copy is there already, or
    it is a shipped checkpoint (referred to by hash, stored nowhere)."""
    if policy_file.shipped is not None:
        return
    folder = root / POLICIES
    if folder.exists() and not folder.resolve().is_relative_to(root.resolve()):
        raise FrbenchError(f"{folder} leads outside the leaderboard folder {root}; refusing to write there")
    parts = [(root / policy_file.file, policy_file.data)]
    if policy_file.sidecar is not None:
        parts.append((root / (policy_file.file + ".json"), policy_file.sidecar))
    for path, data in parts:
        try:
            create_exclusive(path, data)
        except DuplicateRecord:
            if sha256_file(path) != _sha256(data):
                raise FrbenchError(f"{path} exists with other content than its name says; remove it and submit again") from None


def policy_path(root: Path, entry: dict) -> Path | None:
    """Where a record's policy file is: ``root/policies/...``, or the shipped checkpoint with its sha256 (None if
    no shipped checkpoint has it)."""
    if "shipped" in entry:
        name = shipped_with_hash(entry["sha256"])
        return None if name is None else shipped_checkpoint(name)
    return root / entry["file"]


def policy_file_label(entry: dict | None) -> str | None:
    """How the board shows a record's policy file: ``policies/<sha256><suffix>`` (stored), ``shipped: <name>``
    (a shipped checkpoint, by hash), or None."""
    if entry is None:
        return None
    return f"shipped: {entry['shipped']}" if "shipped" in entry else entry["file"]


def stored_problems(root: Path, entry: dict) -> list[str]:
    """What is wrong with a record's attached policy file in ``root`` (empty: present and unchanged)."""
    if "shipped" in entry:
        if shipped_with_hash(entry["sha256"]) is None:
            return [f"policy file: no checkpoint shipped with this frbench has the record's sha256 "
                    f"{entry['sha256'][:16]}... (it was shipped as {entry['shipped']!r})"]
        return []
    path = root / entry["file"]
    if not entry["file"].split("/")[-1].startswith(entry["sha256"]):
        return [f"policy_file.file: {entry['file']} is not named by its sha256 {entry['sha256']}"]
    wanted = [(path, entry["sha256"], "policy file")]
    if "sidecar_sha256" in entry:
        wanted.append((path.with_name(path.name + ".json"), entry["sidecar_sha256"], "policy sidecar"))
    problems = []
    for file, sha, what in wanted:
        if not file.is_file():
            problems.append(f"attached {what} {file} is missing")
        elif file.stat().st_size > MAX_POLICY_BYTES:
            problems.append(f"attached {what} {file} is above the {_mib(MAX_POLICY_BYTES)} limit")
        elif sha256_file(file) != sha:
            problems.append(f"attached {what} {file} does not have the record's sha256 {sha[:16]}...: it was replaced")
    return problems


def stray_files(root: Path, records: list[dict]) -> list[Path]:
    """Files in ``root/policies`` that no record attaches (``.gitkeep`` aside)."""
    folder = root / POLICIES
    if not folder.is_dir():
        return []
    used = set()
    for record in records:
        entry = record.get("policy_file")
        if entry and "file" in entry:
            used.add(entry["file"].split("/")[-1])
            if "sidecar_sha256" in entry:
                used.add(entry["file"].split("/")[-1] + ".json")
    return [p for p in sorted(folder.iterdir()) if p.name != ".gitkeep" and (p.name not in used or not STORED_RE.match(p.name))]
