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
from typing import Iterable, Mapping, Sequence

from frbench.evaluation.results import SIM_TO_SIM_PAIRS
from frbench.leaderboard.formatting import (
    BACKEND_LABELS,
    fmt_gap,
    fmt_generalisation,
    fmt_interval,
    fmt_verified,
    processor_bound,
    signed_gap_of,
)
from frbench.leaderboard.page import PAGE_SCRIPT, PAGE_STYLE, PAGE_TEMPLATE
from frbench.leaderboard.policy_files import policy_file_label
from frbench.leaderboard.scores import (
    aggregate,
    check_same_protocol,
    groups_of,
    overlaps,
    pair_name,
    rank_key,
    scored_cells,
)
from frbench.leaderboard.sections import SECTIONS, SIMULATOR_STATE, inputs_of, section_of, superseded, superseded_why
from frbench.leaderboard.summaries import interval_views, record_generalisation, record_intervals
from frbench.tasks.protocol import (
    HUMANOID_TERRAINS,
    KNOWN_PROTOCOL_VERSIONS,
    PROTOCOL_VERSION,
    STANDARD_BACKENDS,
    STANDARD_EPISODES,
    STANDARD_LEVELS,
    STANDARD_ROBOTS,
    STANDARD_SEEDS,
    STANDARD_TERRAINS,
    unseen_humanoids,
)

PROVENANCE_FIELDS = ("schema_version", "protocol_version", "frbench", "versions", "created", "processor", "policy", "config",
                     "robots")



def _identity(record: dict) -> dict:
    """The fields that name a record on the board: id, submission fields, track, its attached policy file
    (``policies/...`` or None) and its latest passed verification (`frbench verify --save`, or None)."""
    sub = record["submission"]
    keys = ("name", "policy", "submitter", "description", "link", "submitted")
    verified = (record.get("verifications") or [None])[-1]
    if verified is not None and processor_bound(record):
        verified = {**verified, "processor_bound": True}
    reason = humanoid_set_reason(record) if record["track"] == "humanoid" else None
    return {"id": record["id"], **{key: sub[key] for key in keys}, "track": record["track"],
            "policy_file": policy_file_label(record.get("policy_file")), "verified": verified,
            **({"humanoids_not_scored": reason} if reason else {})}


def humanoid_set_reason(record: Mapping) -> str | None:
    """Why robots of the unseen humanoid set have no score in a record (its ``config.not_scored``, one line:
    ``icub, talos: the policy does not drive this robot (...)``); None when it names none."""
    skipped = record["results"]["config"].get("not_scored", {})
    reasons: dict[str, list[str]] = {}
    for robot in unseen_humanoids():
        if robot in skipped:
            reasons.setdefault(skipped[robot], []).append(robot)
    return "; ".join(f"{', '.join(sorted(robots))}: {reason}" for reason, robots in reasons.items()) or None


def _ordered(standard: Sequence, found: Iterable) -> list:
    found = set(found)
    return [x for x in standard] + sorted(found - set(standard), key=str)


def standard_text() -> str:
    return (
        f"{len(STANDARD_ROBOTS)} robots ({', '.join(STANDARD_ROBOTS)}) x {len(STANDARD_BACKENDS)} backends "
        f"({', '.join(STANDARD_BACKENDS)}) x {len(STANDARD_TERRAINS)} terrain families ({', '.join(STANDARD_TERRAINS)}) "
        f"x levels {'/'.join(map(str, STANDARD_LEVELS))} x seeds {'/'.join(map(str, STANDARD_SEEDS))}"
        f", at least {STANDARD_EPISODES} episodes per cell"
    )


def humanoid_text() -> str:
    """The current protocol's humanoid grid in words (`frbench.evaluation.grids.grid_parts`)."""
    from frbench.evaluation.grids import grid_parts

    g1, humanoid_set = grid_parts("humanoid", PROTOCOL_VERSION)
    text = (f"the G1 ({', '.join(g1.robots)}) x {len(g1.backends)} simulators ({', '.join(g1.backends)}) x "
            f"{', '.join(g1.terrains)} x levels {'/'.join(map(str, g1.levels))} x seeds "
            f"{'/'.join(map(str, g1.seeds))}, {g1.episodes} episodes per cell ({len(g1.keys())} cells), and the "
            f"unseen humanoid set ({', '.join(humanoid_set.robots)}) x levels "
            f"{'/'.join(map(str, humanoid_set.levels))} on the same families, seeds and simulators "
            f"({len(humanoid_set.keys())} cells)")
    return text


def axes(records: Sequence[Mapping]) -> dict[str, list]:
    """The robots, backends, families and levels to show: the standard ones, then any others, sorted; and the
    pairs of grid simulators whose gaps to show (``mujoco-physx``; those of the shown backends)."""
    cells = [c for r in records for c in r["results"]["cells"]]
    backends = _ordered(STANDARD_BACKENDS, (c["backend"] for c in cells))
    return {
        "robots": _ordered(STANDARD_ROBOTS, (c["robot"] for c in cells)),
        "backends": backends,
        "pairs": [pair_name(a, b) for a, b in SIM_TO_SIM_PAIRS if a in backends and b in backends],
        "families": _ordered(STANDARD_TERRAINS, (c["terrain"] for c in cells)),
        "levels": sorted(set(STANDARD_LEVELS) | {c["level"] for c in cells}),
    }


def _rank(rows: list[dict]) -> None:
    """Rank rows of one protocol version in place; mark each row whose overall interval overlaps its upper
    neighbour's (``tied_above``: the order of the two is not established by the data)."""
    check_same_protocol(row["protocol_version"] for row in rows)
    rows.sort(key=lambda row: rank_key(row["scores"], row["submitted"], row["id"]))
    for rank, row in enumerate(rows, 1):
        row["rank"] = rank
        above = rows[rank - 2]["intervals"]["overall"] if rank > 1 else None
        row["tied_above"] = overlaps(row["intervals"]["overall"], above)


def board(records: Sequence[Mapping], *, robot: str | None = None, backend: str | None = None, terrain: str | None = None) -> dict:
    """Rows of every section, scored on the cells matching the filters, each score with its 95 % interval.

    ``main``, ``humanoid`` and ``partial``: records of the current protocol version (main and humanoid ranked,
    each on its own; `frbench.leaderboard.sections.section_of`); ``archived``: records of
    other versions, main-track ones ranked within their own version only, never against the current ones.
    Records without cells matching the filters are left out.
    """
    sections: dict[str, list[dict]] = {name: [] for name in SECTIONS}
    replaced = superseded(records)
    for record in records:
        cells = scored_cells(record["results"]["cells"], record["track"])
        scores = aggregate(groups_of(cells), robot=robot, backend=backend, terrain=terrain)
        if scores is None:
            continue
        unfiltered = robot is None and backend is None and terrain is None
        sections[section_of(record, replaced)].append({
            **_identity(record),
            **_superseded_fields(record, replaced, records),
            "inputs": inputs_of(record),
            "protocol_version": record["results"]["protocol_version"],
            "scores": scores,
            "intervals": record_intervals(record, robot=robot, backend=backend, terrain=terrain),
            "generalisation": record_generalisation(record) if unfiltered else None,
        })
    _rank(sections["main"])
    _rank(sections["humanoid"])
    sections["partial"].sort(key=lambda row: rank_key(row["scores"], row["submitted"], row["id"]))
    archived = sections["archived"]
    for version in sorted({row["protocol_version"] for row in archived}):  # ranked within their own version only
        _rank([row for row in archived if row["protocol_version"] == version and row["track"] == "main"
               and "superseded_by" not in row])
    archived.sort(key=lambda row: (row["protocol_version"], row["track"] != "main",
                                   rank_key(row["scores"], row["submitted"], row["id"])))
    filters = {k: v for k, v in (("robot", robot), ("backend", backend), ("terrain", terrain)) if v is not None}
    return {"filters": filters, "protocol_version": PROTOCOL_VERSION, **sections,
            "unseen_ranking": unseen_ranking(sections["main"])}


def unseen_ranking(main: Sequence[Mapping]) -> list[dict]:
    """The main board ranked by unseen success (higher first; ties by the board's order): name, id, board rank,
    unseen [score, low, high] and gap [point, low, high]; ``tied_above`` when the unseen intervals overlap."""
    rows = sorted((r for r in main if r.get("generalisation")), key=lambda r: (-r["generalisation"]["unseen"][0], r["rank"]))
    out = []
    for rank, row in enumerate(rows, 1):
        above = rows[rank - 2]["generalisation"]["unseen"][1:] if rank > 1 else None
        out.append({"rank": rank, "name": row["name"], "id": row["id"], "board_rank": row["rank"],
                    "unseen": row["generalisation"]["unseen"], "gap": row["generalisation"]["gap"],
                    "matched": row["generalisation"]["matched"],
                    "humanoids": row["generalisation"]["humanoids"],
                    "tied_above": overlaps(row["generalisation"]["unseen"][1:], above)})
    return out


# --------------------------------------------------------------------------- text and JSON


def render_json(records: Sequence[Mapping], track: str | None = None, **filters) -> str:
    """`board` as JSON (one key per section, ``humanoid`` among them); ``track``: that section alone (with the main
    board its ranking by unseen success)."""
    data = board(records, **filters)
    if track is not None:
        kept = {track, "filters", "protocol_version"} | ({"unseen_ranking"} if track == "main" else set())
        data = {key: value for key, value in data.items() if key in kept}
    return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def _columns(families: Sequence[str], backends: Sequence[str], pairs: Sequence[str],
             ranked: bool, humanoid: bool = False) -> list[tuple[str, callable]]:
    """The text table's (header, row -> text) columns; ``humanoid``: the humanoid set's score (or n/a) in place
    of the unseen grid's."""
    def iv(row: dict, key: str, name: str | None = None):
        value = row["scores"][key] if name is None else row["scores"][key].get(name)
        interval = row["intervals"][key] if name is None else row["intervals"][key].get(name)
        return fmt_interval(value, interval)

    columns = [("#", lambda r: (str(r["rank"]) + ("~" if r["tied_above"] else "")) if "rank" in r else "-")] if ranked else []
    columns += [
        ("name", lambda r: r["name"]),
        ("policy", lambda r: r["policy"] + (" (simulator state)" if r["inputs"] == SIMULATOR_STATE else "")),
        ("protocol", lambda r: r["protocol_version"]),
        ("overall", lambda r: iv(r, "overall")),
    ]
    columns += [(f, lambda r, f=f: iv(r, "per_family", f)) for f in families]
    columns += [(b, lambda r, b=b: iv(r, "per_backend", b)) for b in backends]
    columns += [(f"gap {p}", lambda r, p=p: fmt_gap(signed_gap_of(r["intervals"], p))) for p in pairs]
    if humanoid:
        columns += [("humanoid set", lambda r: fmt_generalisation(r, "humanoids"))]
    else:
        columns += [
            ("unseen", lambda r: fmt_generalisation(r, "unseen")),
            ("matched-unseen", lambda r: fmt_generalisation(r, "gap")),
        ]
    columns += [
        ("cells", lambda r: str(r["scores"]["cells"])),
        ("file", lambda r: "yes" if r["policy_file"] else "-"),
        ("verified", lambda r: fmt_verified(r["verified"])),
        ("id", lambda r: r["id"][:12]),
    ]
    return columns


SECTION_TITLES = {
    "main": "Main board, protocol {version}: records covering the standard grid, ranked by mean success "
            "(~: its 95 % interval overlaps the record above)",
    "humanoid": "Humanoid track, protocol {version}: records covering the humanoid grid, ranked on their own by mean "
                "G1 success (~: its 95 % interval overlaps the record above; n/a: the humanoid set is not scored, "
                "with the reason)",
    "partial": "Partial records, protocol {version} (not ranked against the main board)",
    "archived": "Archived: records of earlier protocol versions, ranked within their own version only "
                "(never against protocol {version}), and records superseded by a re-score of the same policy file "
                "in the canonical joint frame or by a record of the same policy that holds every one of their "
                "cells and more",
}


def render_table(records: Sequence[Mapping], track: str | None = None, **filters) -> str:
    """A plain-text table per section (or only the section ``track``: main, humanoid, partial, archived); scores
    with their 95 % intervals."""
    data = board(records, **filters)
    shown = axes(records)
    rows_all = [row for section in SECTIONS for row in data[section]]
    families = [f for f in shown["families"] if any(f in r["scores"]["per_family"] for r in rows_all)] or list(STANDARD_TERRAINS)
    out = []
    if data["filters"]:
        out.append("filters: " + " ".join(f"{k}={v}" for k, v in data["filters"].items()))
    for section in SECTIONS if track is None else (track,):
        rows = data[section]
        humanoid = section == "humanoid"
        chosen = [f for f in families if f in HUMANOID_TERRAINS] if humanoid else families
        columns = _columns(chosen, shown["backends"], shown["pairs"], section != "partial", humanoid)
        out.append(f"{SECTION_TITLES[section].format(version=PROTOCOL_VERSION)} ({len(rows)} record{'s' if len(rows) != 1 else ''})")
        if not rows:
            out.append("  (none)")
            out.append("")
            continue
        cells = [[c[0] for c in columns]] + [[get(row) for _, get in columns] for row in rows]
        widths = [max(len(line[i]) for line in cells) for i in range(len(columns))]
        for line in cells:
            out.append("  ".join(v.rjust(w) if v[:1].isdigit() or v[:1] in "+-" else v.ljust(w)
                                 for v, w in zip(line, widths)).rstrip())
        out.append("")
        if humanoid:
            out += [f"  {r['name']}: humanoid set n/a: {r['humanoids_not_scored']}" for r in rows
                    if r.get("humanoids_not_scored") and (r.get("generalisation") or {}).get("humanoids") is None]
            out += [""] if out[-1] else []
    return "\n".join(out)


# --------------------------------------------------------------------------- HTML


def _superseded_fields(record: Mapping, replaced: Mapping[str, str], records: Sequence[Mapping]) -> dict:
    """``superseded_by`` (the record id) and ``superseded_why`` (`superseded_why`) of a superseded record, else {}."""
    if record["id"] not in replaced:
        return {}
    by = next(r for r in records if r["id"] == replaced[record["id"]])
    return {"superseded_by": by["id"], "superseded_why": superseded_why(record, by)}


def page_data(records: Sequence[Mapping]) -> dict:
    """The JSON embedded in ``index.html``: per record, its (robot, backend, terrain, level) aggregates and provenance."""
    entries = []
    replaced = superseded(records)
    for record in sorted(records, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"])):
        groups = groups_of(scored_cells(record["results"]["cells"], record["track"]))
        entries.append({
            **_identity(record),
            "section": section_of(record, replaced),
            **_superseded_fields(record, replaced, records),
            **({"inputs": SIMULATOR_STATE} if inputs_of(record) == SIMULATOR_STATE else {}),
            "protocol_version": record["results"]["protocol_version"],
            "episodes": record["scores"]["episodes"],
            "groups": [[*key, total, count] for key, (total, count) in groups.items()],
            "generalisation": record_generalisation(record),
            "intervals": interval_views(record),
            "provenance": {k: record["results"][k] for k in PROVENANCE_FIELDS if k in record["results"]},
        })
    return {
        "page_version": 2,
        **axes(records),
        "labels": BACKEND_LABELS,
        "standard": standard_text(),
        "humanoid": {"text": humanoid_text(), "families": list(HUMANOID_TERRAINS)},
        "protocol": PROTOCOL_VERSION,
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
