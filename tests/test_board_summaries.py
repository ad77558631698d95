"""The board reads each record's summary, made once per record file content (`frbench.leaderboard.summaries`)."""

from __future__ import annotations

import gzip
import json
import shutil
import sys
from pathlib import Path

import pytest

from frbench.cli import main
from frbench.leaderboard import board as lb
from frbench.leaderboard import summaries
from frbench.leaderboard.records import load_records
from frbench.leaderboard.markdown import render_markdown
from frbench.leaderboard.render import render_html, render_json, render_table

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import empty_board_copy, make_results, small_results, write_results  # noqa: E402

REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """A board with a main record holding the unseen grid and a partial one."""
    folder = tmp_path_factory.mktemp("summaries")
    root = empty_board_copy(REPO_BOARD, folder / "leaderboard")
    lb.submit(write_results(folder / "main.json", make_results(episodes=3, skill=0.9, salt=1)), root, name="main-one")
    lb.submit(write_results(folder / "small.json", small_results()), root, name="tiny")
    return root


@pytest.fixture
def root(template, tmp_path, monkeypatch) -> Path:
    """A copy of the template board and an empty cache folder of its own."""
    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path / "cache"))
    return Path(shutil.copytree(template, tmp_path / "leaderboard"))


def _cached(tmp_path: Path) -> list[Path]:
    return sorted((tmp_path / "cache" / summaries.CACHE_KIND).glob("*.json"))


def _cli(capsys, *args) -> tuple[int, str, str]:
    status = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return status, out, err


def test_every_rendering_from_summaries_equals_the_one_from_full_records(root):
    full, light = load_records(root), summaries.load_summaries(root)
    assert [r["id"] for r in light] == [r["id"] for r in full]
    for record, summary in zip(full, light):
        assert "episodes" in record["results"] and "episodes" not in summary["results"]
        assert {k: v for k, v in summary.items() if k not in ("results", summaries.BOARD_FIELD)} == \
            {k: v for k, v in record.items() if k != "results"}
    main_one = next(summary for summary in light if summary["submission"]["name"] == "main-one")
    assert main_one[summaries.BOARD_FIELD]["generalisation"] is not None  # the main record has the unseen grid
    tiny = next(summary for summary in light if summary["submission"]["name"] == "tiny")
    assert tiny[summaries.BOARD_FIELD]["generalisation"] is None  # the partial one has not
    assert render_markdown(light) == render_markdown(full) and render_html(light) == render_html(full)
    for filters in ({}, {"robot": "go2"}, {"terrain": "stairs"}, {"backend": "pybullet", "terrain": "flat"},
                    {"robot": "a1"}, {"robot": "nothing"}):
        assert render_json(light, **filters) == render_json(full, **filters), filters
        assert render_table(light, **filters) == render_table(full, **filters), filters


def test_a_second_read_checks_nothing_and_a_damaged_entry_is_made_again(root, tmp_path, monkeypatch):
    first = summaries.load_summaries(root)
    assert len(_cached(tmp_path)) == 2

    def refuse(*args, **kwargs):
        raise AssertionError("a record was checked again")

    monkeypatch.setattr(summaries, "load_record", refuse)
    assert summaries.load_summaries(root) == first
    monkeypatch.undo()
    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path / "cache"))
    damaged = _cached(tmp_path)[0]
    damaged.write_text('{"cut short')
    assert summaries.load_summaries(root) == first
    assert json.loads(damaged.read_text())["id"] in {r["id"] for r in first}


def test_an_edited_record_is_checked_in_full_again_and_refused(root, tmp_path, capsys):
    assert _cli(capsys, "leaderboard", "--root", root)[0] == 0  # the summaries are cached
    [path] = [p for p in (root / "records").iterdir() if b'"tiny"' in gzip.decompress(p.read_bytes())]
    text = gzip.decompress(path.read_bytes()).decode()
    path.write_bytes(gzip.compress(text.replace('"overall": 0.5625', '"overall": 0.9', 1).encode(), mtime=0))
    status, out, err = _cli(capsys, "leaderboard", "--root", root)
    assert (status, out) == (2, "")
    assert err == (f"frbench leaderboard: error: {path}: scores: differ from the scores recomputed from results.cells "
                   "(overall 0.9 recorded, 0.5625 recomputed)\n")
    status, _, err = _cli(capsys, "submit", write_results(tmp_path / "b.json", small_results(seeds=(7,))), "--root", root)
    assert status == 2 and "cannot add a record while the leaderboard holds an invalid one" in err


def test_check_reads_no_summary_and_finds_pages_made_from_a_forged_one(root, tmp_path, capsys):
    assert _cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0  # checks in full, leaves the summaries
    entries = _cached(tmp_path)
    assert len(entries) == 2
    for entry in entries:  # a cache entry forged to show another name
        summary = json.loads(entry.read_text())
        summary["submission"]["name"] = "forged"
        entry.write_text(json.dumps(summary))
    status, out, _ = _cli(capsys, "leaderboard", "--root", root)
    assert status == 0 and "forged" in out  # the table trusts the cache ...
    assert _cli(capsys, "leaderboard", "--format", "md", "--root", root)[0] == 0
    status, _, err = _cli(capsys, "leaderboard", "--check", "--root", root)
    assert status == 1 and f"{root / 'README.md'} is out of date with the records" in err  # ... --check does not


def test_a_submission_stores_its_summary_and_reads_the_others_from_the_cache(root, tmp_path, capsys, monkeypatch):
    assert _cli(capsys, "leaderboard", "--root", root)[0] == 0
    monkeypatch.setattr(summaries, "load_record", lambda *a, **k: pytest.fail("an existing record was checked again"))
    status, out, err = _cli(capsys, "submit", write_results(tmp_path / "c.json", small_results(seeds=(3,))),
                            "--root", root, "--name", "third")
    assert status == 0, err
    assert len(_cached(tmp_path)) == 3
    status, out, _ = _cli(capsys, "leaderboard", "--root", root)
    assert status == 0 and "third" in out
