"""The static ``leaderboard/index.html`` page: template, style and script.

The page works opened from disk, with no network: data is embedded as JSON,
the script recomputes scores for the chosen filters from per-(robot, backend,
terrain, level) aggregates, shows each score's 95 % interval (precomputed by
frbench for no filter and for each single filter), marks ranked neighbours whose
intervals overlap, ranks the humanoid track in its own table (the G1 grid's scores and
the humanoid set's, or n/a with the reason), keeps records of earlier protocol versions in an archived
table that is never ranked against the current one, sorts the tables, draws one SVG success-vs-level
chart per terrain family and shows a record's provenance on click. It builds
the DOM with ``textContent`` and attributes only (never ``innerHTML``), so
submitted text stays text. State lives in the URL hash, e.g.
``index.html#robot=go2&backend=mujoco&family=stairs&sort=gap&dir=asc&record=<id>``.
"""

from frbench.leaderboard.page_script import PAGE_SCRIPT
from frbench.leaderboard.page_style import PAGE_STYLE

__all__ = ["PAGE_SCRIPT", "PAGE_STYLE", "PAGE_TEMPLATE"]

PAGE_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta http-equiv="Content-Security-Policy" content="@CSP@">
<meta name="generator" content="frbench leaderboard --format html">
<title>frbench leaderboard</title>
<style>@STYLE@</style>
</head>
<body>
<header>
<h1>frbench leaderboard</h1>
<p>Fall-recovery policies evaluated with <code>frbench evaluate</code> and submitted with <code>frbench submit</code>.
Scores are recomputed from each record's cells for the chosen filters: mean success rate, per terrain family and backend,
and the signed sim-to-sim gap MuJoCo &minus; PyBullet. In parentheses: the 95 % interval of each score (stratified bootstrap over
cells and episodes; shown with no filter or one filter). Click a row for its provenance.</p>
</header>
<main>
<form id="filters" aria-label="Filters">
<label>Robot <select id="filter-robot" name="robot"><option value="">all robots</option></select></label>
<label>Backend <select id="filter-backend" name="backend"><option value="">every backend</option></select></label>
<label>Family <select id="filter-family" name="family"><option value="">all families</option></select></label>
<button type="button" id="filter-reset">Reset</button>
</form>
<section id="main-board">
<h2>Main board</h2>
<p class="note" id="standard-note"></p>
<div class="scroll"><table id="main-table" class="board"></table></div>
<p class="empty" id="main-empty" hidden>No records yet.</p>
</section>
<section id="humanoid-board">
<h2>Humanoid track</h2>
<p class="note" id="humanoid-note"></p>
<div class="scroll"><table id="humanoid-table" class="board"></table></div>
<p class="empty" id="humanoid-empty" hidden>No records yet.</p>
</section>
<section id="partial-board">
<h2>Partial records</h2>
<p class="note">Records that do not cover the whole standard grid, scored on the cells they have; not ranked against the main board.</p>
<div class="scroll"><table id="partial-table" class="board"></table></div>
<p class="empty" id="partial-empty" hidden>None.</p>
</section>
<section id="archived-board">
<h2>Archived records (earlier protocol versions)</h2>
<p class="note" id="archived-note"></p>
<div class="scroll"><table id="archived-table" class="board"></table></div>
<p class="empty" id="archived-empty" hidden>None.</p>
</section>
<section id="details" hidden aria-live="polite">
<div class="details-head"><h2 id="details-title">Provenance</h2><button type="button" id="details-close">Close</button></div>
<div id="details-body"></div>
</section>
<section id="charts-section">
<h2>Success vs level</h2>
<p class="note">Mean success rate per level for each terrain family (main-board records first, at most ten).</p>
<div id="legend"></div>
<div id="charts"></div>
<p class="empty" id="charts-empty" hidden>No data for these filters.</p>
</section>
</main>
<noscript><p>This page needs JavaScript; <a href="README.md">README.md</a> has the same ranking.</p></noscript>
<script type="application/json" id="leaderboard-data">@DATA@</script>
<script>@SCRIPT@</script>
</body>
</html>
"""
