"""The script of ``leaderboard/index.html`` (`frbench.leaderboard.page`): filters, recomputed scores and
intervals, the ranked tables (main board, humanoid track, partial, archived), sorting, the success-vs-level
charts and the provenance panel; its hash is in the page's CSP."""

PAGE_SCRIPT = r"""
(function () {
  "use strict";
  var DATA = JSON.parse(document.getElementById("leaderboard-data").textContent);
  var COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"];
  var LABELS = DATA.labels;
  var HUMANOID_DROPS = ["unseen", "matched", "gengap"];  // the unseen grid's columns, not the humanoid track's
  var SVGNS = "http://www.w3.org/2000/svg";
  var state = {robot: "", backend: "", family: "", sort: "rank", dir: "asc", record: ""};

  function el(tag, attrs, text) {
    var node = document.createElement(tag);
    if (attrs) { Object.keys(attrs).forEach(function (k) { node.setAttribute(k, attrs[k]); }); }
    if (text !== undefined && text !== null) { node.textContent = String(text); }
    return node;
  }
  function svg(tag, attrs, text) {
    var node = document.createElementNS(SVGNS, tag);
    Object.keys(attrs || {}).forEach(function (k) { node.setAttribute(k, attrs[k]); });
    if (text !== undefined) { node.textContent = String(text); }
    return node;
  }
  function fmt(x) { return (x === null || x === undefined) ? "\u2013" : x.toFixed(3); }
  function fmtIv(x, iv) { return (x === null || x === undefined || !iv) ? fmt(x) : fmt(x) + " (" + fmt(iv[0]) + "\u2013" + fmt(iv[1]) + ")"; }
  var PROCESSOR_BOUND = "on the verifying machine's processor only: this learned policy ran float32 inference, whose last bits depend on the CPU's vector kernels (protocol 1.2 makes them portable)";
  function signed(x) { return (x < 0 ? "\u2212" : "+") + Math.abs(x).toFixed(3); }
  // Intervals of one record for the current filters: precomputed for no filter and for each single filter.
  function intervals(rec) {
    var active = ["robot", "backend", "family"].filter(function (k) { return state[k]; });
    if (active.length > 1) { return null; }
    var key = active.length ? active[0] + "=" + state[active[0]] : "";
    return rec.intervals[key] || null;
  }
  function overlaps(a, b) { return !!(a && b && a[0] <= b[1] && b[0] <= a[1]); }
  function mean(acc) { return acc && acc[1] ? acc[0] / acc[1] : null; }
  function add(map, key, sum, count) {
    var acc = map[key] || (map[key] = [0, 0]);
    acc[0] += sum; acc[1] += count;
  }

  // Scores of one record under the current filters (same rules as frbench/leaderboard/scores.py).
  function scores(rec) {
    var total = [0, 0], fam = {}, back = {}, famLevel = {}, pairs = {};
    rec.groups.forEach(function (g) {
      var robot = g[0], backend = g[1], terrain = g[2], level = g[3], sum = g[4], count = g[5];
      if ((state.robot && robot !== state.robot) || (state.backend && backend !== state.backend) ||
          (state.family && terrain !== state.family)) { return; }
      total[0] += sum; total[1] += count;
      add(fam, terrain, sum, count);
      add(back, backend, sum, count);
      add(famLevel, terrain + "|" + level, sum, count);
      var key = robot + "|" + terrain + "|" + level;
      (pairs[key] || (pairs[key] = {}))[backend] = sum / count;
    });
    if (!total[1]) { return null; }
    var gaps = [];
    Object.keys(pairs).forEach(function (k) {
      var p = pairs[k];
      if (p.mujoco !== undefined && p.pybullet !== undefined) { gaps.push(Math.abs(p.mujoco - p.pybullet)); }
    });
    var out = {overall: mean(total), cells: total[1], family: {}, backend: {}, famLevel: {},
               gap: gaps.length ? gaps.reduce(function (a, b) { return a + b; }, 0) / gaps.length : null};
    Object.keys(fam).forEach(function (k) { out.family[k] = mean(fam[k]); });
    Object.keys(back).forEach(function (k) { out.backend[k] = mean(back[k]); });
    Object.keys(famLevel).forEach(function (k) { out.famLevel[k] = mean(famLevel[k]); });
    return out;
  }

  function rankCompare(a, b) {
    if (a.s.overall !== b.s.overall) { return b.s.overall - a.s.overall; }
    var ga = a.s.gap, gb = b.s.gap;
    if ((ga === null) !== (gb === null)) { return ga === null ? 1 : -1; }
    if (ga !== gb) { return ga - gb; }
    if (a.r.submitted !== b.r.submitted) { return a.r.submitted < b.r.submitted ? -1 : 1; }
    return a.r.id < b.r.id ? -1 : (a.r.id > b.r.id ? 1 : 0);
  }

  function rows(section) {
    var list = [];
    DATA.records.forEach(function (r) {
      if (r.section !== section) { return; }
      var s = scores(r);
      if (s) { list.push({r: r, s: s, iv: intervals(r)}); }
    });
    list.sort(function (a, b) {
      if (a.r.protocol_version !== b.r.protocol_version) { return a.r.protocol_version < b.r.protocol_version ? -1 : 1; }
      return rankCompare(a, b);
    });
    var previous = null;
    list.forEach(function (row, i) {
      row.rank = i + 1;
      var ranked = section === "main" || section === "humanoid" || (section === "archived" && row.r.track === "main");
      var same = previous && previous.r.protocol_version === row.r.protocol_version;
      row.tied = ranked && !!same && overlaps(row.iv && row.iv.overall, previous.iv && previous.iv.overall);
      if (ranked) { previous = row; }
    });
    return list;
  }

  function columns() {
    var cols = [
      {key: "rank", label: "#", num: true, dir: "asc", get: function (x) { return x.rank; },
       show: function (x) { return String(x.rank) + (x.tied ? " ~" : ""); }},
      {key: "name", label: "Name", dir: "asc", get: function (x) { return x.r.name; }},
      {key: "policy", label: "Policy", dir: "asc", get: function (x) {
        return x.r.policy + (x.r.inputs === "simulator-state" ? " (simulator state)" : ""); }},
      {key: "submitter", label: "Submitter", dir: "asc", get: function (x) { return x.r.submitter; }},
      {key: "protocol", label: "Protocol", dir: "asc", get: function (x) { return x.r.protocol_version; }},
      {key: "overall", label: "Overall", num: true, score: true, dir: "desc", get: function (x) { return x.s.overall; },
       iv: function (x) { return x.iv && x.iv.overall; }}
    ];
    DATA.families.forEach(function (f) {
      cols.push({key: "family:" + f, label: f, num: true, score: true, dir: "desc", family: f,
                 get: function (x) { var v = x.s.family[f]; return v === undefined ? null : v; },
                 iv: function (x) { return x.iv && x.iv.per_family[f]; }});
    });
    DATA.backends.forEach(function (b) {
      cols.push({key: "backend:" + b, label: LABELS[b] || b, num: true, score: true, dir: "desc",
                 get: function (x) { var v = x.s.backend[b]; return v === undefined ? null : v; },
                 iv: function (x) { return x.iv && x.iv.per_backend[b]; }});
    });
    DATA.pairs.forEach(function (p, i) {
      var names = p.split("-"), label = (LABELS[names[0]] || names[0]) + " \u2212 " + (LABELS[names[1]] || names[1]);
      var gapOf = function (x) {  // signed_gaps per pair with PhysX on the board, signed_gap for MuJoCo - PyBullet alone
        if (!x.iv) { return null; }
        if (x.iv.signed_gaps) { return x.iv.signed_gaps[p] || null; }
        return p === "mujoco-pybullet" ? x.iv.signed_gap : null;
      };
      cols.push({key: i ? "gap:" + p : "gap", label: DATA.pairs.length > 1 ? "Gap " + label : "Gap",
                 title: "Signed sim-to-sim gap " + label + " with its 95 % interval", num: true, dir: "asc",
                 get: function (x) { var g = gapOf(x); return g ? g[0] : null; },
                 show: function (x) { var g = gapOf(x); return g ? signed(g[0]) + " (" + signed(g[1]) + ".." + signed(g[2]) + ")" : "\u2013"; }});
    });
    cols.push({key: "unseen", label: "Unseen", title: "Mean success on the unseen grid (real quadrupeds no policy trains on; protocol 1.2) with its 95 % interval; sort by it for the ranking by unseen success",
               num: true, score: true, dir: "desc",
               get: function (x) { var g = x.r.generalisation; return g && g.unseen ? g.unseen[0] : null; },
               iv: function (x) { var g = x.r.generalisation; return g && g.unseen ? [g.unseen[1], g.unseen[2]] : null; }});
    cols.push({key: "matched", label: "Matched std", title: "Mean success of the standard grid's cells on the unseen grid's families and levels, with its 95 % interval",
               num: true, score: true, dir: "desc",
               get: function (x) { var g = x.r.generalisation; return g && g.matched ? g.matched[0] : null; },
               iv: function (x) { var g = x.r.generalisation; return g && g.matched ? [g.matched[1], g.matched[2]] : null; }});
    cols.push({key: "gengap", label: "Matched \u2212 unseen", title: "Matched standard success minus unseen success with its 95 % interval: the loss on bodies never trained on, terrain held equal", num: true, dir: "asc",
               get: function (x) { var g = x.r.generalisation; return g && g.gap ? g.gap[0] : null; },
               show: function (x) { var g = x.r.generalisation; return g && g.gap ? signed(g.gap[0]) + " (" + signed(g.gap[1]) + ".." + signed(g.gap[2]) + ")" : "\u2013"; }});
    cols.push({key: "humanoids", label: "Humanoids", title: "Mean success on the unseen humanoid set (Talos, iCub); n/a: the policy does not drive humanoids", num: true, dir: "desc",
               get: function (x) { var g = x.r.generalisation; return g && g.humanoids ? g.humanoids[0] : null; },
               show: function (x) { var g = x.r.generalisation; return g ? (g.humanoids ? g.humanoids[0].toFixed(3) + " (" + g.humanoids[1].toFixed(3) + "-" + g.humanoids[2].toFixed(3) + ")"
                 : "n/a" + (x.r.humanoids_not_scored ? ": " + x.r.humanoids_not_scored : "")) : "\u2013"; }});
    cols.push({key: "cells", label: "Cells", num: true, dir: "desc", get: function (x) { return x.s.cells; }});
    cols.push({key: "file", label: "Policy file", title: "the policy file attached to the record", dir: "asc",
               get: function (x) { return x.r.policy_file ? "attached" : null; }});
    cols.push({key: "verified", label: "Verified", title: "episodes re-run by frbench verify and reproduced", num: true, dir: "desc",
               get: function (x) { return x.r.verified ? x.r.verified.sample : null; },
               show: function (x) { var v = x.r.verified; return v ? "\u2713 " + v.sample + " (" + (v.tier || v.mode) + ")" + (v.processor_bound ? " \u2020" : "") : "\u2013"; }});
    cols.push({key: "submitted", label: "Submitted", dir: "asc", get: function (x) { return x.r.submitted.slice(0, 10); }});
    cols.push({key: "id", label: "Record", dir: "asc", id: true, get: function (x) { return x.r.id.slice(0, 12); }});
    return cols;
  }

  function sortRows(list, cols) {
    var col = cols.filter(function (c) { return c.key === state.sort; })[0] || cols[0];
    var sign = state.dir === "desc" ? -1 : 1;
    list.sort(function (a, b) {
      var va = col.get(a), vb = col.get(b);
      if (va === null || vb === null) {
        if (va === null && vb === null) { return a.rank - b.rank; }
        return va === null ? 1 : -1;  // missing values last in both directions
      }
      if (va < vb) { return -sign; }
      if (va > vb) { return sign; }
      return a.rank - b.rank;
    });
  }

  function shade(value) {
    // light green proportional to success; CSSOM styles are allowed by the page's CSP
    var alpha = (0.08 + 0.42 * value).toFixed(3);
    return "rgba(46, 160, 67, " + alpha + ")";
  }

  function renderTable(track) {
    var table = document.getElementById(track + "-table");
    var empty = document.getElementById(track + "-empty");
    var list = rows(track), cols = columns();
    if (track !== "archived") { cols = cols.filter(function (c) { return c.key !== "protocol"; }); }
    if (track === "humanoid") {  // the G1 grid's families, and the humanoid set in place of the unseen grid
      cols = cols.filter(function (c) {
        return HUMANOID_DROPS.indexOf(c.key) < 0 && (!c.family || DATA.humanoid.families.indexOf(c.family) >= 0);
      });
    }
    sortRows(list, cols);
    table.textContent = "";
    empty.hidden = list.length > 0;
    table.hidden = list.length === 0;
    if (!DATA.records.some(function (r) { return r.section === track; })) {
      empty.textContent = track === "main" ? "No records yet: submit one with frbench submit RESULTS.json."
        : track === "humanoid" ? "No records yet." : "None.";
    } else {
      empty.textContent = "No records match these filters.";
    }
    if (!list.length) { return list; }
    var thead = el("thead"), headRow = el("tr");
    cols.forEach(function (c) {
      var th = el("th", {scope: "col", "data-key": c.key, "class": c.num ? "num" : ""});
      if (state.sort === c.key) { th.setAttribute("aria-sort", state.dir === "asc" ? "ascending" : "descending"); }
      var button = el("button", {type: "button", title: "Sort by " + (c.title || c.label)}, c.label);
      button.addEventListener("click", function () {
        if (state.sort === c.key) { state.dir = state.dir === "asc" ? "desc" : "asc"; }
        else { state.sort = c.key; state.dir = c.dir; }
        update();
      });
      th.appendChild(button);
      headRow.appendChild(th);
    });
    thead.appendChild(headRow);
    table.appendChild(thead);
    var tbody = el("tbody");
    list.forEach(function (x) {
      var tr = el("tr", {tabindex: "0", "data-id": x.r.id, "aria-selected": String(state.record === x.r.id)});
      cols.forEach(function (c) {
        var v = c.get(x), td;
        if (c.show) {
          td = el("td", {"class": "num" + (v === null ? " off" : "")}, c.show(x));
        } else if (c.score) {
          td = el("td", {"class": "num" + (v === null ? " off" : "")}, fmtIv(v, c.iv(x)));
          if (c.score && v !== null) { td.style.backgroundColor = shade(v); }
        } else if (c.key === "name") {
          td = el("td", {title: x.r.description || x.r.name}, v);
        } else {
          td = el("td", {"class": (c.num ? "num" : "") + (c.id ? " id" : "")}, v);
        }
        tr.appendChild(td);
      });
      tr.addEventListener("click", function () { select(x.r.id); });
      tr.addEventListener("keydown", function (e) { if (e.key === "Enter" || e.key === " ") { e.preventDefault(); select(x.r.id); } });
      tbody.appendChild(tr);
    });
    table.appendChild(tbody);
    return list;
  }

  function select(id) {
    state.record = state.record === id ? "" : id;
    update();
    if (state.record) { document.getElementById("details").scrollIntoView({block: "nearest"}); }
  }

  function dlRow(dl, term, value) {
    dl.appendChild(el("dt", null, term));
    var dd = el("dd");
    if (value instanceof Node) { dd.appendChild(value); } else { dd.textContent = value === null || value === undefined || value === "" ? "\u2013" : String(value); }
    dl.appendChild(dd);
  }

  function keyTable(obj, fn) {
    var table = el("table");
    Object.keys(obj).sort().forEach(function (k) {
      var tr = el("tr");
      tr.appendChild(el("td", null, k));
      tr.appendChild(el("td", null, fn(obj[k])));
      table.appendChild(tr);
    });
    return table;
  }

  function renderDetails() {
    var section = document.getElementById("details"), body = document.getElementById("details-body");
    var rec = DATA.records.filter(function (r) { return r.id === state.record; })[0];
    body.textContent = "";
    section.hidden = !rec;
    if (!rec) { return; }
    var p = rec.provenance;
    document.getElementById("details-title").textContent = "Provenance: " + rec.name;
    var dl = el("dl");
    dlRow(dl, "Record", rec.id);
    dlRow(dl, "Track", rec.superseded_by ? "archived (superseded by record " + rec.superseded_by.slice(0, 12) + ": " + rec.superseded_why + ")"
                       : rec.section === "archived" ? "archived (protocol " + rec.protocol_version + ", not ranked against " + DATA.protocol + ")"
                       : rec.track === "main" ? "main board (standard grid)"
                       : rec.track === "humanoid" ? "humanoid track (the G1 grid and the humanoid set)" : "partial");
    dlRow(dl, "Policy", rec.policy + (rec.inputs === "simulator-state"
      ? " (reads the simulator's state and the terrain: not a blind policy, never ranked with them)" : ""));
    dlRow(dl, "Submitter", rec.submitter);
    dlRow(dl, "Submitted", rec.submitted);
    dlRow(dl, "Description", rec.description);
    if (rec.link && /^https?:\/\//.test(rec.link)) {
      var a = el("a", {href: rec.link, rel: "noopener noreferrer nofollow"}, rec.link);
      dlRow(dl, "Link", a);
    } else { dlRow(dl, "Link", null); }
    dlRow(dl, "Protocol version", p.protocol_version);
    dlRow(dl, "frbench", p.frbench.version + " (commit " + p.frbench.git_commit + ")");
    dlRow(dl, "Results created", p.created);
    dlRow(dl, "Versions", keyTable(p.versions, function (v) { return v === null ? "\u2013" : v; }));
    if (p.processor) dlRow(dl, "Processor", p.processor.vendor + " " + p.processor.model + " (" + p.processor.architecture + "; " +
                              p.processor.vector_extensions.join(", ") + ")");
    dlRow(dl, "Checkpoint", p.policy.checkpoint === null ? "none (" + p.policy.name + ")" : p.policy.checkpoint);
    dlRow(dl, "Checkpoint sha256", p.policy.sha256);
    dlRow(dl, "Policy file", rec.policy_file ? rec.policy_file + (rec.policy_file.startsWith("policies/") ? " (attached)" : "") : "none attached");
    var v = rec.verified;
    dlRow(dl, "Verified", v ? v.sample + " episodes in " + v.cells + " cells re-run and reproduced (" + (v.tier || v.mode) +
          (v.tier === "reproduced" ? " within " + v.tolerance + " relative, largest deviation " + v.largest_deviation.toPrecision(2) : "") +
          ", sample seed " + v.seed + ", " + v.policy + " policy, frbench " + v.frbench_commit.slice(0, 12) + ", " + v.verified +
          (v.processor ? ", on " + v.processor.vendor + " " + v.processor.model + " (" + v.processor.architecture + "; " +
           v.processor.vector_extensions.join(", ") + ")" : "") + ")" +
          (v.processor_bound ? " \u2020 " + PROCESSOR_BOUND : "") : "not verified");
    dlRow(dl, "Robots (URDF sha256, source)", keyTable(p.robots, function (v) { return v.urdf_sha256 + "  " + v.source; }));
    dlRow(dl, "Seeds", p.config.seeds.join(", "));
    dlRow(dl, "Episodes", p.config.episodes + " per cell, " + rec.episodes + " scored");
    dlRow(dl, "Config", el("pre", null, JSON.stringify(p.config, null, 2)));
    body.appendChild(dl);
  }

  function renderCharts(mainRows, partialRows) {
    var charts = document.getElementById("charts"), legend = document.getElementById("legend");
    charts.textContent = ""; legend.textContent = "";
    var series = mainRows.concat(partialRows).slice(0, 10);
    var chartsEmpty = document.getElementById("charts-empty");
    chartsEmpty.hidden = series.length > 0;
    chartsEmpty.textContent = DATA.records.length ? "No data for these filters." : "No records yet.";
    if (!series.length) { return; }
    series.forEach(function (x, i) {
      var key = el("span", {"class": "key", "data-id": x.r.id, title: "Show provenance"});
      var sw = svg("svg", {width: "22", height: "10", "aria-hidden": "true"});
      sw.appendChild(svg("line", {x1: "0", y1: "5", x2: "22", y2: "5", stroke: COLORS[i], "stroke-width": "3"}));
      key.appendChild(sw);
      key.appendChild(document.createTextNode(x.r.name + (x.r.track === "partial" ? " (partial)" : "")));
      key.addEventListener("click", function () { select(x.r.id); });
      legend.appendChild(key);
    });
    var levels = DATA.levels, lo = Math.min.apply(null, levels), hi = Math.max.apply(null, levels);
    if (hi === lo) { hi = lo + 1; }
    var W = 260, H = 180, L = 38, R = 12, T = 10, B = 30;
    function X(level) { return L + (W - L - R) * (level - lo) / (hi - lo); }
    function Y(rate) { return T + (H - T - B) * (1 - rate); }
    var families = state.family ? [state.family] : DATA.families;
    families.forEach(function (f) {
      var fig = el("figure", {"data-family": f});
      fig.appendChild(el("figcaption", null, f));
      var chart = svg("svg", {width: String(W), height: String(H), viewBox: "0 0 " + W + " " + H, role: "img",
                              "aria-label": "Success rate versus level on " + f});
      [0, 0.25, 0.5, 0.75, 1].forEach(function (t) {
        chart.appendChild(svg("line", {x1: String(L), x2: String(W - R), y1: String(Y(t)), y2: String(Y(t)),
                                       stroke: t === 0 ? "#9aa4ae" : "#e3e7eb", "stroke-width": "1"}));
        chart.appendChild(svg("text", {x: String(L - 6), y: String(Y(t) + 4), "text-anchor": "end"}, t.toFixed(2)));
      });
      levels.forEach(function (level) {
        chart.appendChild(svg("line", {x1: String(X(level)), x2: String(X(level)), y1: String(H - B), y2: String(H - B + 4), stroke: "#9aa4ae"}));
        chart.appendChild(svg("text", {x: String(X(level)), y: String(H - B + 15), "text-anchor": "middle"}, level));
      });
      chart.appendChild(svg("text", {x: String((L + W - R) / 2), y: String(H - 2), "text-anchor": "middle"}, "level"));
      series.forEach(function (x, i) {
        var pts = [];
        levels.forEach(function (level) {
          var v = x.s.famLevel[f + "|" + level];
          if (v !== undefined) { pts.push([X(level), Y(v), level, v]); }
        });
        if (!pts.length) { return; }
        var chosen = state.record === x.r.id, dim = state.record && !chosen;
        var g = svg("g", {"data-id": x.r.id, opacity: dim ? "0.35" : "1"});
        g.appendChild(svg("title", {}, x.r.name));
        g.appendChild(svg("polyline", {points: pts.map(function (p) { return p[0].toFixed(1) + "," + p[1].toFixed(1); }).join(" "),
                                       fill: "none", stroke: COLORS[i], "stroke-width": chosen ? "3.5" : "2"}));
        pts.forEach(function (p) {
          var c = svg("circle", {cx: p[0].toFixed(1), cy: p[1].toFixed(1), r: chosen ? "4" : "3", fill: COLORS[i]});
          c.appendChild(svg("title", {}, x.r.name + ": level " + p[2] + ", success " + p[3].toFixed(3)));
          g.appendChild(c);
        });
        g.addEventListener("click", function () { select(x.r.id); });
        chart.appendChild(g);
      });
      fig.appendChild(chart);
      charts.appendChild(fig);
    });
  }

  function fillSelect(id, values, labels) {
    var select = document.getElementById(id);
    values.forEach(function (v) { select.appendChild(el("option", {value: v}, labels[v] || v)); });
    select.addEventListener("change", function () { state[select.name] = select.value; update(); });
  }

  function readHash() {
    var params = new URLSearchParams(location.hash.replace(/^#/, ""));
    ["robot", "backend", "family", "sort", "dir", "record"].forEach(function (k) {
      if (params.has(k)) { state[k] = params.get(k); }
    });
    if (state.robot && DATA.robots.indexOf(state.robot) < 0) { state.robot = ""; }
    if (state.backend && DATA.backends.indexOf(state.backend) < 0) { state.backend = ""; }
    if (state.family && DATA.families.indexOf(state.family) < 0) { state.family = ""; }
    if (state.dir !== "asc" && state.dir !== "desc") { state.dir = "asc"; }
  }

  function writeHash() {
    var params = new URLSearchParams();
    ["robot", "backend", "family", "record"].forEach(function (k) { if (state[k]) { params.set(k, state[k]); } });
    if (state.sort !== "rank" || state.dir !== "asc") { params.set("sort", state.sort); params.set("dir", state.dir); }
    var hash = params.toString();
    try { history.replaceState(null, "", hash ? "#" + hash : location.pathname + location.search); } catch (e) { /* file:// quirks */ }
  }

  function update() {
    ["robot", "backend", "family"].forEach(function (k) { document.getElementById("filter-" + k).value = state[k]; });
    var mainRows = renderTable("main"), partialRows = renderTable("partial");
    renderTable("humanoid");
    renderTable("archived");
    renderDetails();
    renderCharts(mainRows.slice().sort(function (a, b) { return a.rank - b.rank; }),
                 partialRows.slice().sort(function (a, b) { return a.rank - b.rank; }));
    writeHash();
  }

  document.getElementById("standard-note").textContent =
    "Protocol " + DATA.protocol + ". Records that cover the standard grid: " + DATA.standard +
    ". Ranked by overall success, then by sim-to-sim gap; \u201c~\u201d after a rank: its overall interval overlaps the record above.";
  document.getElementById("humanoid-note").textContent =
    "Protocol " + DATA.protocol + ". Records that cover the humanoid grid: " + DATA.humanoid.text +
    ". Ranked on their own by overall G1 success, then by sim-to-sim gap; the humanoid set's score beside it, or " +
    "n/a with the reason. A policy that reads the simulator's state is ranked here, marked (simulator state).";
  document.getElementById("archived-note").textContent =
    "Records evaluated under an earlier protocol version; never ranked against protocol " + DATA.protocol + ".";
  fillSelect("filter-robot", DATA.robots, {});
  fillSelect("filter-backend", DATA.backends, LABELS);
  fillSelect("filter-family", DATA.families, {});
  document.getElementById("filter-reset").addEventListener("click", function () {
    state.robot = state.backend = state.family = ""; update();
  });
  document.getElementById("details-close").addEventListener("click", function () { state.record = ""; update(); });
  readHash();
  update();
  document.body.setAttribute("data-ready", "true");
})();
"""
