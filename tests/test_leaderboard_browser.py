"""`leaderboard/index.html` in a real headless browser (Debian's chromium), opened from disk.

Run with ``pytest -m browser tests/test_leaderboard_browser.py`` (``make
test-browser``). The page is driven by a test script appended to a copy of it
(its Content-Security-Policy is widened by exactly that script's hash); the
script clicks headers, changes filters, opens a record's provenance and writes
what it saw into the DOM, which ``chromium --dump-dom`` returns. A screenshot
of the page with a record's provenance open is saved to /tmp/leaderboard.png.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from frbench.leaderboard import board as lb
from frbench.leaderboard.records import build_record, load_records, submission_fields
from frbench.leaderboard.render import render_html

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import empty_board_copy, make_results, small_results, write_results  # noqa: E402

pytestmark = pytest.mark.browser

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
SCREENSHOT = Path(os.environ.get("FRBENCH_SCREENSHOT", "/tmp/leaderboard.png"))

if not Path(CHROMIUM).exists():
    pytest.skip("needs Debian's chromium at /usr/bin/chromium (apt-get install -y chromium; `make test-browser` does)",
                allow_module_level=True)


def chromium(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    profile = tmp_path / "chromium-profile"
    command = [
        CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
        "--disable-extensions", "--disable-background-networking", "--hide-scrollbars", "--enable-logging=stderr",
        "--v=0", f"--user-data-dir={profile}", "--virtual-time-budget=5000", *args,
    ]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


def console_errors(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "CONSOLE" in line or "Refused to" in line or "Uncaught" in line]


@pytest.fixture(scope="module")
def board_dir(tmp_path_factory) -> Path:
    """A leaderboard with three main records and two partial ones, written by `frbench submit`."""
    folder = tmp_path_factory.mktemp("browser")
    root = folder / "leaderboard"
    empty_board_copy(REPO_BOARD, root)
    entries = [
        ("scripted-baseline", make_results(episodes=3), "frbench team", "The scripted stand-up controller shipped with frbench.", "https://example.org/frbench"),
        ("ppo-rough-v2", make_results(episodes=3, skill=0.95, salt=1, policy="ppo", checkpoint="runs/ppo/model.pt"), "A. Researcher", "PPO with a rough-terrain curriculum & domain randomization", None),
        ("sac-flat", make_results(episodes=3, skill=0.6, salt=2, policy="sac", checkpoint="runs/sac/model.pt"), "B. Student", "", None),
        ("go2-probe", small_results(), "tester", "Partial run on two families", None),
        ("mujoco-only", small_results(backends=("mujoco",), salt=5), "tester", "", None),
    ]
    for name, results, submitter, description, link in entries:
        lb.submit(write_results(folder / f"{name}.json", results), root, name=name, submitter=submitter,
                  description=description, link=link, submitted="2026-11-22T02:00:00Z")
    return root


#: The end of each harness: what it saw (``out``, or the error that stopped it) as JSON in ``<pre id="test-output">``.
REPORT = r"""
  } catch (e) {
    out.error = String(e && e.stack || e);
  }
  var pre = document.createElement("pre");
  pre.id = "test-output";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
"""

HARNESS = r"""
(function () {
  var out = {};
  function q(s) { return document.querySelector(s); }
  function col(track, index) {
    return Array.prototype.map.call(document.querySelectorAll("#" + track + "-table tbody tr"),
                                    function (tr) { return tr.children[index].textContent; });
  }
  function header(track) {
    return Array.prototype.map.call(document.querySelectorAll("#" + track + "-table thead th"), function (th) { return th.dataset.key; });
  }
  function cell(track, name, key) {
    var keys = header(track), i = keys.indexOf(key);
    var row = Array.prototype.filter.call(document.querySelectorAll("#" + track + "-table tbody tr"),
                                          function (tr) { return tr.children[1].textContent === name; })[0];
    return row ? row.children[i].textContent : null;
  }
  function choose(id, value) { var s = q(id); s.value = value; s.dispatchEvent(new Event("change")); }
  function sortBy(key) { q('#main-table th[data-key="' + key + '"] button').click(); }
  try {
    out.ready = document.body.getAttribute("data-ready");
    out.main = col("main", 1);
    out.partial = col("partial", 1);
    out.mainHeader = header("main");
    out.probeOverall = cell("partial", "go2-probe", "overall");
    out.probeGap = cell("partial", "go2-probe", "gap");
    out.charts = Array.prototype.map.call(document.querySelectorAll("#charts figure"), function (f) { return f.dataset.family; });
    out.linesPerChart = document.querySelectorAll("#charts figure")[0].querySelectorAll("polyline").length;
    out.legend = Array.prototype.map.call(document.querySelectorAll("#legend .key"), function (k) { return k.textContent; });
    sortBy("name"); out.byNameAsc = col("main", 1); out.ariaSort = q('#main-table th[data-key="name"]').getAttribute("aria-sort");
    sortBy("name"); out.byNameDesc = col("main", 1);
    sortBy("overall"); out.byOverall = col("main", 1);
    sortBy("overall"); out.byOverallAsc = col("main", 1);
    sortBy("rank");
    choose("#filter-backend", "mujoco");
    out.mujocoProbeOverall = cell("partial", "go2-probe", "overall");
    out.mujocoProbeGap = cell("partial", "go2-probe", "gap");
    out.mujocoPartial = col("partial", 1);
    choose("#filter-backend", "");
    choose("#filter-family", "stairs");
    out.stairsCharts = Array.prototype.map.call(document.querySelectorAll("#charts figure"), function (f) { return f.dataset.family; });
    out.stairsProbeOverall = cell("partial", "go2-probe", "overall");
    out.stairsProbeFlat = cell("partial", "go2-probe", "family:flat");
    choose("#filter-family", "");
    choose("#filter-robot", "aliengo");
    out.aliengoPartialHidden = q("#partial-table").hidden;
    out.aliengoPartialEmpty = q("#partial-empty").textContent;
    out.aliengoMain = col("main", 1);
    q("#filter-reset").click();
    out.afterReset = col("partial", 1);
    out.detailsHiddenBefore = q("#details").hidden;
    document.querySelectorAll("#main-table tbody tr")[0].click();
    out.detailsHidden = q("#details").hidden;
    out.detailsTitle = q("#details-title").textContent;
    out.details = q("#details-body").textContent;
    out.selected = q('#main-table tbody tr[aria-selected="true"]').dataset.id;
    out.hash = location.hash;
    out.links = Array.prototype.map.call(document.querySelectorAll("#details a"), function (a) { return a.getAttribute("href"); });
    q("#details-close").click();
    out.detailsHiddenAfterClose = q("#details").hidden;
    var hostile = Array.prototype.filter.call(document.querySelectorAll("tbody tr"), function (tr) { return tr.children[1].textContent.indexOf("pwn") >= 0; })[0];
    if (hostile) {
      hostile.click();
      out.hostileName = hostile.children[1].textContent;
      out.hostileDetails = q("#details-body").textContent;
      out.hostileLinks = document.querySelectorAll("#details a").length;
    }
    out.pwned = window.__pwned || null;
    out.images = document.querySelectorAll("img").length;
    out.scripts = document.querySelectorAll("script").length;
""" + REPORT


def drive(page: Path, tmp_path: Path, harness: str = HARNESS) -> tuple[dict, list[str]]:
    """Open a copy of ``page`` with the ``harness`` appended; return what the harness saw and console errors."""
    text = page.read_text(encoding="utf-8")
    digest = base64.b64encode(hashlib.sha256(harness.encode()).digest()).decode()
    text, count = re.subn(r"script-src ('sha256-[^']+')", rf"script-src \1 'sha256-{digest}'", text)
    assert count == 1
    text = text.replace("</body>", f"<script>{harness}</script>\n</body>")
    copy = tmp_path / "driven.html"
    copy.write_text(text, encoding="utf-8")
    done = chromium(tmp_path, "--dump-dom", copy.as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    found = re.search(r'<pre id="test-output">(.*?)</pre>', done.stdout, re.S)
    assert found, done.stdout[-2000:] + done.stderr[-2000:]
    out = json.loads(html.unescape(found.group(1)))
    print(json.dumps(out, indent=1, sort_keys=True))  # visible with pytest -s
    return out, console_errors(done.stderr)


def test_page_sorts_filters_charts_and_shows_provenance(board_dir, tmp_path):
    out, errors = drive(board_dir / "index.html", tmp_path)
    assert "error" not in out, out.get("error")
    assert errors == []
    assert out["ready"] == "true"
    assert out["main"] == ["ppo-rough-v2", "scripted-baseline", "sac-flat"]
    assert out["partial"] == ["mujoco-only", "go2-probe"]  # 0.625 before 0.5625
    assert out["mainHeader"][:5] == ["rank", "name", "policy", "submitter", "overall"]
    assert out["probeOverall"].startswith("0.563 (") and out["probeGap"].startswith("+0.125 (")  # as the README
    assert out["charts"] == ["flat", "rough", "slopes", "stairs", "stones", "gaps", "beams"]
    assert out["linesPerChart"] == 5 and len(out["legend"]) == 5
    assert out["byNameAsc"] == ["ppo-rough-v2", "sac-flat", "scripted-baseline"] and out["ariaSort"] == "ascending"
    assert out["byNameDesc"] == ["scripted-baseline", "sac-flat", "ppo-rough-v2"]
    assert out["byOverall"] == ["ppo-rough-v2", "scripted-baseline", "sac-flat"]
    assert out["byOverallAsc"] == ["sac-flat", "scripted-baseline", "ppo-rough-v2"]
    assert out["mujocoProbeOverall"].startswith("0.625 (") and out["mujocoProbeGap"] == "\u2013"
    assert set(out["mujocoPartial"]) == {"go2-probe", "mujoco-only"}
    assert out["stairsCharts"] == ["stairs"]
    assert out["stairsProbeOverall"].startswith("0.313 (") and out["stairsProbeFlat"] == "\u2013"
    assert out["aliengoPartialHidden"] is True and out["aliengoPartialEmpty"] == "No records match these filters."
    assert len(out["aliengoMain"]) == 3
    assert len(out["afterReset"]) == 2
    assert out["detailsHiddenBefore"] is True and out["detailsHidden"] is False
    assert out["detailsTitle"] == "Provenance: ppo-rough-v2"
    records = {r["submission"]["name"]: r for r in load_records(board_dir)}
    ppo = records["ppo-rough-v2"]
    for expected in (ppo["id"], "0123456789abcdef0123456789abcdef01234567", "runs/ppo/model.pt", "ab" * 32,
                     "example-robot-data 6.0.0", "2.13.0+cpu", "Protocol version1.4", "domain randomization"):
        assert expected in out["details"], expected
    assert out["selected"] == ppo["id"] and out["hash"] == f"#record={ppo['id']}"
    assert out["detailsHiddenAfterClose"] is True
    assert out["scripts"] == 3 and out["images"] == 0


def test_submitted_markup_stays_inert(board_dir, tmp_path):
    records = load_records(board_dir)
    results = small_results(salt=9, seeds=(5,))
    hostile = build_record(results, submission_fields(
        results, name="ok", description="", submitter=None, link=None, submitted="2026-11-22T03:00:00Z"))
    # bypass submit's refusals on purpose: the page must stay inert even for a hand-made record
    hostile["submission"].update(
        name='pwn</script><script>window.__pwned=1</script>',
        description='<img src=x onerror="window.__pwned=2"><b>bold</b>',
        submitter="<svg onload=window.__pwned=3>",
        link="javascript:window.__pwned=4",
    )
    page = tmp_path / "index.html"
    page.write_text(render_html([*records, hostile]), encoding="utf-8")
    out, errors = drive(page, tmp_path)
    assert "error" not in out, out.get("error")
    assert errors == []
    assert out["pwned"] is None and out["images"] == 0 and out["scripts"] == 3
    assert out["hostileName"] == 'pwn</script><script>window.__pwned=1</script>'
    assert '<img src=x onerror="window.__pwned=2"><b>bold</b>' in out["hostileDetails"]
    assert out["hostileLinks"] == 0  # a javascript: link is shown as no link


HUMANOID_HARNESS = r"""
(function () {
  var out = {};
  function q(s) { return document.querySelector(s); }
  function texts(selector) { return Array.prototype.map.call(document.querySelectorAll(selector), function (n) { return n.textContent; }); }
  try {
    out.keys = Array.prototype.map.call(document.querySelectorAll("#humanoid-table thead th"), function (th) { return th.dataset.key; });
    out.rows = Array.prototype.map.call(document.querySelectorAll("#humanoid-table tbody tr"), function (tr) {
      return Array.prototype.map.call(tr.children, function (td) { return td.textContent; });
    });
    out.note = q("#humanoid-note").textContent;
    out.mainEmpty = q("#main-empty").textContent;
    out.partial = texts("#partial-table tbody tr td:nth-child(2)");
    document.querySelectorAll("#humanoid-table tbody tr")[0].click();
    out.details = q("#details-body").textContent;
""" + REPORT


def test_the_humanoid_track_is_ranked_in_its_own_table(tmp_path, monkeypatch):
    from frbench.leaderboard import render, sections
    from test_humanoid_track import NOT_DRIVEN, humanoid_results, record_of

    for module in (sections, render):
        monkeypatch.setattr(module, "PROTOCOL_VERSION", "1.3")
    records = [record_of(humanoid_results("mpc-distilled-g1", with_set=False)),
               record_of(humanoid_results("mpc", with_set=True, better=True, inputs="simulator-state"))]
    page = tmp_path / "index.html"
    page.write_text(render_html(records), encoding="utf-8")
    out, errors = drive(page, tmp_path, HUMANOID_HARNESS)
    assert "error" not in out, out.get("error")
    assert errors == []
    keys, rows = out["keys"], out["rows"]
    assert keys[:5] == ["rank", "name", "policy", "submitter", "overall"]
    assert [k for k in keys if k.startswith("family:")] == ["family:flat", "family:rough", "family:slopes", "family:stairs"]
    assert "unseen" not in keys and "humanoids" in keys and "backend:physx" in keys
    assert [row[1] for row in rows] == ["mpc", "mpc-distilled-g1"] and rows[0][2] == "mpc (simulator state)"
    assert rows[0][keys.index("overall")].startswith("0.750 (") and rows[1][keys.index("overall")].startswith("0.500 (")
    assert rows[0][keys.index("humanoids")].startswith("0.111 (")
    assert rows[1][keys.index("humanoids")] == f"n/a: icub, talos: {NOT_DRIVEN}"
    assert "flat, rough, slopes, stairs" in out["note"] and "144 cells" in out["note"] and "(simulator state)" in out["note"]
    assert out["mainEmpty"].startswith("No records yet") and out["partial"] == []
    assert "humanoid track (the G1 grid and the humanoid set)" in out["details"]


def test_empty_board_page(tmp_path):
    done = chromium(tmp_path, "--dump-dom", (REPO_BOARD / "index.html").as_uri())
    assert done.returncode == 0 and console_errors(done.stderr) == []
    assert 'data-ready="true"' in done.stdout
    if not list((REPO_BOARD / "records").glob("*.json.gz")):
        assert "No records yet: submit one with frbench submit RESULTS.json." in done.stdout


def test_screenshot(board_dir, tmp_path):
    records = {r["submission"]["name"]: r for r in load_records(board_dir)}
    url = board_dir.joinpath("index.html").as_uri() + f"#record={records['scripted-baseline']['id']}"
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    SCREENSHOT.unlink(missing_ok=True)
    done = chromium(tmp_path, "--window-size=1400,2200", f"--screenshot={SCREENSHOT}", url)
    assert done.returncode == 0 and SCREENSHOT.exists(), done.stderr[-2000:]
    assert console_errors(done.stderr) == []
    from PIL import Image

    with Image.open(SCREENSHOT) as image:
        assert image.size == (1400, 2200)
        colors = image.convert("RGB").resize((140, 220)).getcolors(maxcolors=1 << 16)
        assert colors is not None and len(colors) > 50  # not a blank page


def _main_table(dom: str, table_id: str = "main-table") -> tuple[list[str], list[list[str]]]:
    """(column keys, rows of cell texts) of the rendered main board's table (or the table ``table_id``) in a
    dumped DOM."""
    table = dom[dom.index(f'id="{table_id}"'):]
    table = table[:table.index("</table>")]
    keys = re.findall(r'<th scope="col" data-key="([^"]+)"', table)
    body = table[table.index("<tbody"):]
    rows = [[html.unescape(re.sub(r"<[^>]+>", "", cell)) for cell in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]
            for row in re.findall(r"<tr[^>]*>(.*?)</tr>", body, re.S)]
    return keys, rows


def _repository_rows(tmp_path, section: str) -> tuple[list[dict], dict[str, list[str]], list[str]]:
    """The repository board's records ranked in ``section`` (``main`` or ``humanoid``; the test is skipped where
    there is none), and its table on the page (row cell texts by record name, column keys)."""
    from frbench.leaderboard.sections import section_of, superseded

    records = load_records(REPO_BOARD)
    replaced = superseded(records)
    ranked = [r for r in records if section_of(r, replaced) == section]
    if not ranked:
        pytest.skip(f"no {section} record of the current protocol")
    done = chromium(tmp_path, "--dump-dom", (REPO_BOARD / "index.html").as_uri())
    assert done.returncode == 0 and console_errors(done.stderr) == []
    keys, rows = _main_table(done.stdout, f"{section}-table")
    assert len(rows) == len(ranked)
    return ranked, {row[keys.index("name")]: row for row in rows}, keys


def test_the_repository_page_shows_standard_and_unseen_success_of_every_main_record(tmp_path):
    from frbench.leaderboard.scores import generalisation

    main, by_name, keys = _repository_rows(tmp_path, "main")
    for record in main:
        row = by_name[record["submission"]["name"]]
        unseen = generalisation(record["results"]["cells"], "main")["unseen"]
        assert row[keys.index("unseen")].startswith(f"{unseen[0]:.3f} ({unseen[1]:.3f}")
        assert re.fullmatch(r"0\.\d{3} \(0\.\d{3}–[01]\.\d{3}\)", row[keys.index("overall")])
        assert re.fullmatch(r"[−+]0\.\d{3} \([−+]0\.\d{3}\.\.[−+]0\.\d{3}\)", row[keys.index("gengap")])
        assert row[keys.index("humanoids")] == "n/a"  # no main-board policy drives humanoids


def test_the_repository_page_shows_the_humanoid_track_with_each_records_humanoid_set(tmp_path):
    from frbench.leaderboard.scores import generalisation

    track, by_name, keys = _repository_rows(tmp_path, "humanoid")
    for record in track:
        shown = by_name[record["submission"]["name"]][keys.index("humanoids")]
        humanoids = generalisation(record["results"]["cells"], "humanoid")["humanoids"]
        if humanoids is None:
            assert shown.startswith("n/a: "), shown  # with the reason
        else:
            assert shown.startswith(f"{humanoids[0]:.3f} ({humanoids[1]:.3f}"), shown
