"""Leaderboard operations: submit a results file, regenerate the rendered files, check everything.

A submission is checked completely before anything is written, so a refused
submission leaves the leaderboard folder byte-for-byte unchanged. Writers hold
an exclusive lock on the folder while they list the records, create the new
record and regenerate ``README.md`` and ``index.html``: two submissions at the
same moment both land, and whichever regenerates last sees both records.

Writers and the pages read the records' summaries (`frbench.leaderboard.summaries`: each record file checked
in full once per content, then read from the cache); :func:`check` checks every file in full and never reads
the cache.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from frbench.errors import FrbenchError, ResultsError
from frbench.io import atomic_write_text
from frbench.leaderboard.jsonfile import MAX_RESULTS_BYTES, read_json_object
from frbench.leaderboard.paths import INDEX, README, RECORDS, SCHEMA
from frbench.leaderboard.policy_files import check_attachable, read_policy_file, store, stored_problems, stray_files
from frbench.leaderboard.records import (
    DuplicateRecord,
    Submission,
    build_record,
    UNCOMPRESSED_RECORD_RE,
    compress_hint,
    load_record,
    locked,
    record_file_bytes,
    record_file_name,
    record_files,
    record_path,
    replace_record,
    submission_fields,
    write_record,
)
from frbench.leaderboard.markdown import render_markdown
from frbench.leaderboard.render import render_html
from frbench.leaderboard.reuse import check_board_reuse
from frbench.leaderboard.summaries import load_summaries, remember
from frbench.leaderboard.results import check_results
from frbench.policies.references import split_reference
from frbench.schemas import SCHEMA_NAMES, schema_text


def _utc_now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def generated_files(records: Sequence[dict]) -> dict[str, str]:
    """Relative path -> text of every file generated from the records."""
    files = {README: render_markdown(records), INDEX: render_html(records)}
    for name in SCHEMA_NAMES:
        files[f"{SCHEMA}/{name}.schema.json"] = schema_text(name)
    return files


def _write(root: Path, relative: str, text: str) -> bool:
    """Write one generated file if its content changed; True if written."""
    path = root / relative
    try:
        if path.read_text(encoding="utf-8") == text:
            return False
    except (FileNotFoundError, UnicodeDecodeError):
        pass
    atomic_write_text(path, text)
    os.chmod(path, 0o644)
    return True


def _write_generated(root: Path, records: Sequence[dict], only: Sequence[str] | None = None) -> list[str]:
    files = generated_files(records)
    wanted = [p for p in files if only is None or p in only or p.startswith(SCHEMA + "/")]
    return [p for p in wanted if _write(root, p, files[p])]


def regenerate(root: Path, *, only: Sequence[str] | None = None) -> list[str]:
    """Rewrite the generated files (all, or those in ``only``, plus the schema copies) from the records.

    Returns the relative paths that changed. Refuses (writing nothing) if a record is invalid.
    """
    with locked(root):
        return _write_generated(root, load_summaries(root), only)


def read_results(path: str | os.PathLike) -> dict:
    """Read and check a results file; errors are one line naming the file and the field."""
    source = os.fspath(path)
    results = read_json_object(path, limit=MAX_RESULTS_BYTES, source=source)
    try:
        check_results(results)
    except ResultsError as exc:
        raise ResultsError(f"{source}: {exc}") from None
    return results


def submit(
    results_path: str | os.PathLike,
    root: Path,
    *,
    name: str | None = None,
    description: str | None = None,
    submitter: str | None = None,
    link: str | None = None,
    submitted: str | None = None,
    dry_run: bool = False,
    policy_file: str | os.PathLike | None = None,
) -> Submission:
    """Check ``results_path`` and add it to the leaderboard at ``root`` as a new record.

    ``policy_file``: the policy that produced the results, stored as ``policies/<sha256><suffix>``
    (`frbench.leaderboard.policy_files`). If these results are already a record that carries no
    policy, the file is attached to that record (its other fields stay as they are).
    """
    results = read_results(results_path)
    fields = submission_fields(
        results, name=name, description=description, submitter=submitter, link=link,
        submitted=submitted or _utc_now(),
    )
    record = build_record(results, fields)
    attached = None
    if policy_file is not None:
        attached = read_policy_file(policy_file, layout=split_reference(results["config"]["policy"])[1])
        check_attachable(attached, results, os.fspath(policy_file))
        record["policy_file"] = attached.entry()
    path = record_path(root, record["id"])
    if dry_run:
        return Submission(record, path, written=False)
    short = record["id"][:12]
    folder = root / RECORDS
    if folder.exists() and not folder.resolve().is_relative_to(root.resolve()):
        raise FrbenchError(f"{folder} leads outside the leaderboard folder {root}; refusing to write there")
    duplicate = (f"{os.fspath(results_path)}: these results were already submitted as record {short} ({path}); "
                 "identical resubmissions are refused")
    with locked(root):
        try:
            existing = load_summaries(root)
        except ResultsError as exc:
            raise ResultsError(f"cannot add a record while the leaderboard holds an invalid one: {exc}") from None
        if path.exists():
            current = load_record(path) if any(r["id"] == record["id"] for r in existing) else None
            if attached is None or current is None or "policy_file" in current:
                raise ResultsError(duplicate + ("" if attached is None else " (it carries a policy file already)"))
            record = {**current, "policy_file": attached.entry()}
            store(root, attached)
            replace_record(path, record)
            summary = remember(record)
            _write_generated(root, [r if r["id"] != record["id"] else summary for r in existing])
            return Submission(record, path, written=True, attached_only=True)
        if attached is not None:
            store(root, attached)
        try:
            write_record(root, record)
        except DuplicateRecord:
            raise ResultsError(duplicate) from None
        try:
            _write_generated(root, [*existing, remember(record)])
        except FrbenchError as exc:
            raise FrbenchError(f"record {short} was written to {path}, but {exc}; run `frbench leaderboard --format md` and `--format html`") from None
    return Submission(record, path, written=True)


def add_verification(root: Path, path: Path, entry: dict) -> dict:
    """Append a passed verification (`frbench verify --save`) to the record at ``path``; regenerate the pages."""
    with locked(root):
        records = load_summaries(root)
        if not any(record_file_name(r["id"]) == path.name for r in records):
            raise FrbenchError(f"{path}: not a record of the leaderboard {root}; --save writes only into a leaderboard folder")
        current = load_record(path)
        record = {**current, "verifications": [*current.get("verifications", []), entry]}
        replace_record(path, record)
        summary = remember(record)
        _write_generated(root, [r if r["id"] != record["id"] else summary for r in records])
    return record


@dataclass
class CheckReport:
    """What :func:`check` found."""

    records: list[dict] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def check(root: Path) -> CheckReport:
    """Validate every record file and that the generated files match them."""
    report = CheckReport()
    paths, others = record_files(root)
    for other in others:
        report.problems.append(compress_hint(other) if UNCOMPRESSED_RECORD_RE.match(other.name) else
                               f"{other}: not a record: record files are named <64 hex digits>.json.gz (a leftover temporary file?)")
    read = []
    for path in paths:
        try:
            data = record_file_bytes(path)
            report.records.append(load_record(path, data))
            read.append(data)
        except ResultsError as exc:
            report.problems.append(str(exc))
    for record in report.records:
        if "policy_file" in record:
            report.problems += [f"record {record['id'][:12]}: {p}" for p in stored_problems(root, record["policy_file"])]
    try:  # a record that reuses another's episodes holds that record's episodes, when both are here
        check_board_reuse(report.records)
    except ResultsError as exc:
        report.problems.append(str(exc))
    for stray in stray_files(root, report.records):
        report.problems.append(f"{stray}: no record attaches this file (a leftover of a failed submission?)")
    if report.problems:
        report.problems.append(f"{root / README} and {root / INDEX} were not compared because of the problems above")
        return report
    for relative, text in generated_files(report.records).items():
        path = root / relative
        try:
            current = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            current = None
        except (OSError, UnicodeDecodeError):
            current = ""
        if current != text:
            how = {README: "--format md", INDEX: "--format html"}.get(relative, "--format md")
            state = "is missing" if current is None else "is out of date with the records"
            report.problems.append(f"{path} {state}; run `frbench leaderboard {how}` and commit the result")
    for record, data in zip(report.records, read):  # every file passed the full check: later reads need not repeat it
        remember(record, data)
    return report
