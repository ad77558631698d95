"""How leaderboard records are stored: gzip JSON named by the results' sha256, read back by file or id."""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

import pytest

from frbench.errors import FrbenchError, ResultsError
from frbench.leaderboard.jsonfile import gzip_bytes, read_json_object
from frbench.leaderboard.records import (
    DuplicateRecord,
    build_record,
    find_record,
    load_record,
    read_record,
    record_bytes,
    record_files,
    record_id,
    record_path,
    record_text,
    submission_fields,
    write_record,
)

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import small_results  # noqa: E402

REPO_RECORDS = Path(__file__).resolve().parents[1] / "leaderboard" / "records"


@pytest.fixture(scope="module")
def record() -> dict:
    results = small_results()
    fields = submission_fields(results, name="stored", description="", submitter=None, link=None,
                               submitted="2026-11-22T02:00:00Z")
    return build_record(results, fields)


def test_a_record_is_written_once_as_deterministic_gzip_and_read_back_by_file_or_id(tmp_path, record):
    (tmp_path / "records").mkdir()
    path = write_record(tmp_path, record)
    assert path == record_path(tmp_path, record["id"]) == tmp_path / "records" / f"{record['id']}.json.gz"
    stored = path.read_bytes()
    assert stored == record_bytes(record) == record_bytes(json.loads(record_text(record)))  # same record, same bytes
    assert stored[:2] == b"\x1f\x8b" and stored[4:8] == b"\0\0\0\0"  # gzip, modification time 0
    assert gzip.decompress(stored).decode() == record_text(record)  # `zcat` shows the pretty JSON
    assert len(stored) < len(record_text(record)) / 4
    with pytest.raises(DuplicateRecord):
        write_record(tmp_path, record)
    assert load_record(path) == record
    assert read_record(record["id"][:8], tmp_path) == read_record(str(path)) == record
    assert find_record(tmp_path, record["id"]) == path
    assert record_files(tmp_path) == ([path], [])


def test_the_uncompressed_form_is_read_by_path_and_listed_apart_in_a_folder(tmp_path, record):
    (tmp_path / "records").mkdir()
    plain = tmp_path / "records" / f"{record['id']}.json"
    plain.write_text(record_text(record))
    assert load_record(plain) == record
    assert record_files(tmp_path) == ([], [plain])
    with pytest.raises(FrbenchError, match="no record in"):
        find_record(tmp_path, record["id"][:12])


def test_an_id_prefix_must_be_8_hex_digits_and_name_one_record(tmp_path):
    (tmp_path / "records").mkdir()
    with pytest.raises(FrbenchError, match=r"record 'xyz': expected a record id, or at least its first 8 hex digits"):
        find_record(tmp_path, "xyz")
    for last in "12":
        (tmp_path / "records" / f"{'ab' * 31}a{last}.json.gz").write_bytes(b"")
    with pytest.raises(FrbenchError, match=r"record 'abababab': 2 records in .* with that id"):
        find_record(tmp_path, "abababab")


@pytest.mark.parametrize("data, message", [
    (gzip_bytes(b'{"a": "' + b"x" * 2000 + b'"}'), "decompresses to more than the 0.0 MB limit; refusing to read it"),
    (gzip_bytes(b'{"a": 1}')[:-6], "the gzip data ends early; is the file truncated?"),
    (gzip_bytes(b'{"a": 1}') + b"trailing", "8 bytes follow the gzip data; expected one gzip member"),
    (b"\x1f\x8b\x08" + b"\xff" * 30, "not a valid gzip file ("),
    (gzip_bytes(b"\xff\xfe"), "not UTF-8 text (byte 0); expected a JSON file"),
])
def test_bad_gzip_is_one_line_naming_the_file(tmp_path, data, message):
    path = tmp_path / "r.json.gz"
    path.write_bytes(data)
    with pytest.raises(ResultsError) as caught:
        read_json_object(path, limit=1000)
    assert str(caught.value).startswith(f"{path}: ") and message in str(caught.value)
    assert "\n" not in str(caught.value)


def test_the_repository_s_records_are_stored_compressed_under_their_ids():
    """Every record in leaderboard/records is ``<id>.json.gz``, its id the sha256 of its results (checked fully by
    `frbench leaderboard --check` in `make test`); here: the names, gzip with no time stamp, and no plain JSON."""
    paths = sorted(REPO_RECORDS.iterdir())
    assert not [p.name for p in paths if p.name != ".gitkeep" and not p.name.endswith(".json.gz")]
    for path in paths[:3] + paths[-3:]:
        if path.name == ".gitkeep":
            continue
        stored = path.read_bytes()
        assert stored[4:8] == b"\0\0\0\0"
        results = json.loads(gzip.decompress(stored))["results"]
        assert path.name == f"{record_id(results)}.json.gz"
