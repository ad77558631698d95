"""Rendering the leaderboard: a text table, JSON, ``README.md`` and ``index.html``.

Everything is deterministic (sorted, no render timestamps) so the generated
files only change when the records do and ``frbench leaderboard --check`` is
stable. Every string that came from a submitter is escaped for its output:
Markdown punctuation is backslash-escaped, HTML text goes through
``html.escape``, and the page's data block is JSON with ``<``, ``>`` and ``&``
written as ``\\u003c``-style escapes; the page's script only ever sets
``textContent`` and its Content-Security-Policy admits only its own script.
"""

from __future__ import annotations

import base64
import hashlib
import json
from decimal import ROUND_HALF_UP, Decimal
from typing import Iterable, Mapping, Sequence

from frbench.leaderboard.page import PAGE_SCRIPT, PAGE_STYLE, PAGE_TEMPLATE
from frbench.leaderboard.scores import aggregate, groups_of, rank_key, scored_cells
from frbench.tasks.protocol import (
    KNOWN_PROTOCOL_VERSIONS,
    STANDARD_BACKENDS,
    STANDARD_LEVELS,
    STANDARD_ROBOTS,
    STANDARD_SEEDS,
    STANDARD_TERRAINS,
)

BACKEND_LABELS = {"mujoco": "MuJoCo", "pybullet": "PyBullet"}
PROVENANCE_FIELDS = ("schema_version", "protocol_version", "frbench", "versions", "created", "policy", "config", "robots")



def _identity(record: dict) -> dict:
    """The fields that name a record on the board: id, submission fields, track."""
    sub = record["submission"]
    keys = ("name", "policy", "submitter", "description", "link", "submitted")
    return {"id": record["id"], **{key: sub[key] for key in keys}, "track": record["track"]}

def _ordered(standard: Sequence, found: Iterable) -> list:
    found = set(found)
    return [x for x in standard] + sorted(found - set(standard), key=str)


def _standard_text() -> str:
    return (
        f"{len(STANDARD_ROBOTS)} robots ({', '.join(STANDARD_ROBOTS)}) x {len(STANDARD_BACKENDS)} backends "
        f"({', '.join(STANDARD_BACKENDS)}) x {len(STANDARD_TERRAINS)} terrain families ({', '.join(STANDARD_TERRAINS)}) "
        f"x levels {'/'.join(map(str, STANDARD_LEVELS))} x seeds {'/'.join(map(str, STANDARD_SEEDS))}"
    )


def axes(records: Sequence[Mapping]) -> dict[str, list]:
    """The robots, backends, families and levels to show: the standard ones, then any others, sorted."""
    cells = [c for r in records for c in r["results"]["cells"]]
    return {
        "robots": _ordered(STANDARD_ROBOTS, (c["robot"] for c in cells)),
        "backends": _ordered(STANDARD_BACKENDS, (c["backend"] for c in cells)),
        "families": _ordered(STANDARD_TERRAINS, (c["terrain"] for c in cells)),
        "levels": sorted(set(STANDARD_LEVELS) | {c["level"] for c in cells}),
    }


def board(records: Sequence[Mapping], *, robot: str | None = None, backend: str | None = None, terrain: str | None = None) -> dict:
    """Rows of both tracks, scored on the cells matching the filters, ranked; records without such cells are left out."""
    tracks: dict[str, list[dict]] = {"main": [], "partial": []}
    for record in records:
        groups = groups_of(scored_cells(record["results"]["cells"], record["track"]))
        scores = aggregate(groups, robot=robot, backend=backend, terrain=terrain)
        if scores is None:
            continue
        tracks[record["track"]].append({
            **_identity(record),
            "protocol_version": record["results"]["protocol_version"],
            "scores": scores,
        })
    for rows in tracks.values():
        rows.sort(key=lambda row: rank_key(row["scores"], row["submitted"], row["id"]))
        for rank, row in enumerate(rows, 1):
            row["rank"] = rank
    filters = {k: v for k, v in (("robot", robot), ("backend", backend), ("terrain", terrain)) if v is not None}
    return {"filters": filters, "main": tracks["main"], "partial": tracks["partial"]}


def fmt_score(value: float | None) -> str:
    """Three decimals, ties rounded up like JavaScript's ``toFixed`` so the page and README agree."""
    if value is None:
        return "-"
    return str(Decimal(value).quantize(Decimal("0.001"), rounding=ROUND_HALF_UP))


# --------------------------------------------------------------------------- text and JSON


def render_json(records: Sequence[Mapping], **filters) -> str:
    return json.dumps(board(records, **filters), indent=2, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def _columns(families: Sequence[str], backends: Sequence[str]) -> list[tuple[str, callable]]:
    columns = [
        ("#", lambda r: str(r["rank"])),
        ("name", lambda r: r["name"]),
        ("policy", lambda r: r["policy"]),
        ("submitter", lambda r: r["submitter"]),
        ("overall", lambda r: fmt_score(r["scores"]["overall"])),
    ]
    columns += [(f, lambda r, f=f: fmt_score(r["scores"]["per_family"].get(f))) for f in families]
    columns += [(b, lambda r, b=b: fmt_score(r["scores"]["per_backend"].get(b))) for b in backends]
    columns += [
        ("gap", lambda r: fmt_score(r["scores"]["sim_to_sim_gap"])),
        ("cells", lambda r: str(r["scores"]["cells"])),
        ("id", lambda r: r["id"][:12]),
    ]
    return columns


def render_table(records: Sequence[Mapping], **filters) -> str:
    """A plain-text table per track."""
    data = board(records, **filters)
    shown = axes(records)
    families = [f for f in shown["families"] if any(f in r["scores"]["per_family"] for r in data["main"] + data["partial"])] or list(STANDARD_TERRAINS)
    columns = _columns(families, shown["backends"])
    out = []
    if data["filters"]:
        out.append("filters: " + " ".join(f"{k}={v}" for k, v in data["filters"].items()))
    titles = {
        "main": "Main board: records covering the standard grid, ranked by mean success",
        "partial": "Partial records (not ranked against the main board)",
    }
    for track in ("main", "partial"):
        rows = data[track]
        out.append(f"{titles[track]} ({len(rows)} record{'s' if len(rows) != 1 else ''})")
        if not rows:
            out.append("  (none)")
            out.append("")
            continue
        cells = [[c[0] for c in columns]] + [[get(row) for _, get in columns] for row in rows]
        widths = [max(len(line[i]) for line in cells) for i in range(len(columns))]
        for line in cells:
            out.append("  ".join(v.rjust(w) if i == 0 or v[:1].isdigit() or v == "-" else v.ljust(w)
                                 for i, (v, w) in enumerate(zip(line, widths))).rstrip())
        out.append("")
    return "\n".join(out)


# --------------------------------------------------------------------------- Markdown

_MD_SPECIAL = set("\\`*_[]<>|~&#!")


def md_escape(text: str) -> str:
    """Escape text for a Markdown table cell or paragraph (no markup, links or HTML survive)."""
    return "".join("\\" + ch if ch in _MD_SPECIAL else ch for ch in str(text))


def _md_row(values: Iterable[str]) -> str:
    return "| " + " | ".join(values) + " |"


def render_markdown(records: Sequence[Mapping]) -> str:
    """``leaderboard/README.md``."""
    data = board(records)
    shown = axes(records)
    families, backends = shown["families"], shown["backends"]
    lines = [
        "# frbench leaderboard",
        "",
        "<!-- Generated by `frbench leaderboard --format md` from records/*.json; do not edit by hand. -->",
        "",
        "Fall-recovery policies evaluated with `frbench evaluate`, submitted with",
        "`frbench submit RESULTS.json --name NAME --submitter WHO --description TEXT --link URL`.",
        "Open [index.html](index.html) for filters by robot, backend and terrain family, success-vs-level",
        "charts and each record's provenance.",
        "",
        f"Accepted protocol versions: {', '.join(KNOWN_PROTOCOL_VERSIONS)}. Records follow",
        "[schema/record-v1.schema.json](schema/record-v1.schema.json); each file in `records/` is named by the",
        "sha256 of its results. Scores are recomputed from each record's cells: the mean success rate over cells",
        "(one cell = robot x backend x terrain x level x seed), per terrain family and per backend, and the mean",
        "sim-to-sim gap |MuJoCo - PyBullet| over (robot, terrain, level) (lower is better).",
        "",
        "## Main board",
        "",
        f"Records that cover the standard grid: {_standard_text()}.",
        "Ranked by overall success, then by sim-to-sim gap.",
        "",
    ]
    header = ["#", "Name", "Policy", "Submitter", "Overall"] + [md_escape(f) for f in families] \
        + [BACKEND_LABELS.get(b, md_escape(b)) for b in backends] + ["Gap", "Record"]

    def table(rows: list[dict], ranked: bool) -> list[str]:
        if not rows:
            return ["_No records yet._" if ranked else "_None._", ""]
        head = header if ranked else header[1:4] + ["Cells"] + header[4:]
        out = [_md_row(head), _md_row(["---"] * len(head))]
        for row in rows:
            s = row["scores"]
            values = [md_escape(row["name"]), md_escape(row["policy"]), md_escape(row["submitter"])]
            if not ranked:
                values.append(str(s["cells"]))
            values += [f"**{fmt_score(s['overall'])}**" if ranked else fmt_score(s["overall"])]
            values += [fmt_score(s["per_family"].get(f)) for f in families]
            values += [fmt_score(s["per_backend"].get(b)) for b in backends]
            values += [fmt_score(s["sim_to_sim_gap"]), f"[{row['id'][:12]}](records/{row['id']}.json)"]
            out.append(_md_row(([str(row["rank"])] if ranked else []) + values))
        return out + [""]

    lines += table(data["main"], True)
    lines += [
        "## Partial records",
        "",
        "Records that do not cover the whole standard grid, scored on the cells they have; not ranked",
        "against the main board.",
        "",
    ]
    lines += table(data["partial"], False)
    by_id = {r["id"]: r for r in records}
    rows = data["main"] + data["partial"]
    lines += ["## Records", ""]
    if not rows:
        lines += ["_No records yet._", ""]
    for row in rows:
        results = by_id[row["id"]]["results"]
        fb = results["frbench"]
        commit = fb["git_commit"][:12]
        versions = ", ".join(f"{md_escape(k)} {md_escape(v)}" for k, v in sorted(results["versions"].items()) if v is not None)
        policy = results["policy"]
        checkpoint = f"checkpoint sha256 `{policy['sha256'][:16]}…`" if policy["sha256"] else "no checkpoint"
        link = f" — <{row['link']}>" if row["link"] else ""
        lines.append(f"- **{md_escape(row['name'])}** (`{row['id'][:12]}`, {row['track']}, submitted {row['submitted']} "
                     f"by {md_escape(row['submitter'])}){link}")
        if row["description"]:
            lines.append(f"  - {md_escape(row['description'])}")
        lines.append(
            f"  - Protocol {md_escape(results['protocol_version'])}, frbench {md_escape(fb['version'])} ({commit}), "
            f"{versions}; policy {md_escape(policy['name'])}, {checkpoint}; "
            f"seeds {', '.join(map(str, results['config']['seeds']))}, {results['config']['episodes']} episodes per cell, "
            f"noise {'on' if results['config']['noise'] else 'off'}."
        )
    if rows:
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------- HTML


def page_data(records: Sequence[Mapping]) -> dict:
    """The JSON embedded in ``index.html``: per record, its (robot, backend, terrain, level) aggregates and provenance."""
    entries = []
    for record in sorted(records, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"])):
        groups = groups_of(scored_cells(record["results"]["cells"], record["track"]))
        entries.append({
            **_identity(record),
            "episodes": record["scores"]["episodes"],
            "groups": [[*key, total, count] for key, (total, count) in groups.items()],
            "provenance": {k: record["results"][k] for k in PROVENANCE_FIELDS},
        })
    return {
        "page_version": 1,
        **axes(records),
        "standard": _standard_text(),
        "protocols": list(KNOWN_PROTOCOL_VERSIONS),
        "records": entries,
    }


def script_json(value: object) -> str:
    """JSON safe inside a ``<script type="application/json">`` element (no ``<``, ``>`` or ``&``)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _csp_hash(text: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def render_html(records: Sequence[Mapping]) -> str:
    """``leaderboard/index.html``: one self-contained file, no network."""
    csp = (
        f"default-src 'none'; script-src {_csp_hash(PAGE_SCRIPT)}; style-src {_csp_hash(PAGE_STYLE)}; "
        "img-src data:; base-uri 'none'; form-action 'none'"
    )
    return (
        PAGE_TEMPLATE.replace("@CSP@", csp)
        .replace("@STYLE@", PAGE_STYLE)
        .replace("@SCRIPT@", PAGE_SCRIPT)
        .replace("@DATA@", script_json(page_data(records)))
    )
