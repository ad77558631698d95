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

from frbench.evaluation.provenance import processor_label
from frbench.leaderboard.page import PAGE_SCRIPT, PAGE_STYLE, PAGE_TEMPLATE
from frbench.leaderboard.policy_files import MAX_POLICY_BYTES, policy_file_label
from frbench.leaderboard.records import record_file_name
from frbench.leaderboard.scores import (
    aggregate,
    check_same_protocol,
    groups_of,
    overlaps,
    rank_key,
    needs_unseen_grid,
    scored_cells,
)
from frbench.leaderboard.sections import SIMULATOR_STATE, inputs_of, section_of, superseded
from frbench.leaderboard.summaries import interval_views, record_generalisation, record_intervals
from frbench.leaderboard.verify import RELATIVE_TOLERANCE, REPRODUCED_TOLERANCE
from frbench.tasks.protocol import (
    KNOWN_PROTOCOL_VERSIONS,
    PROTOCOL_VERSION,
    STANDARD_BACKENDS,
    STANDARD_EPISODES,
    STANDARD_LEVELS,
    STANDARD_ROBOTS,
    STANDARD_SEEDS,
    STANDARD_TERRAINS,
)

BACKEND_LABELS = {"mujoco": "MuJoCo", "pybullet": "PyBullet"}
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
    return {"id": record["id"], **{key: sub[key] for key in keys}, "track": record["track"],
            "policy_file": policy_file_label(record.get("policy_file")), "verified": verified}


def processor_bound(record: Mapping) -> bool:
    """Whether a verification of the record holds only on the processor that ran it: a learned policy (one with
    a checkpoint) evaluated before protocol 1.2, whose float32 inference depends on the CPU's vector kernels."""
    results = record["results"]
    return results["policy"].get("sha256") is not None and not needs_unseen_grid(results["protocol_version"])


#: The note on a processor-bound verification (`processor_bound`), marked with a dagger.
PROCESSOR_BOUND_NOTE = (
    "† verified on the verifying machine's processor only: the policy is learned and ran float32 inference, whose "
    "last bits depend on the CPU's vector kernels (on an AVX-512 machine `frbench verify f3a8b4dd2ded --sample 4 "
    "--seed 1` fails 4/4; so do dreamriser-3m and frnet-no-stability-15m). Protocol 1.2 infers in float64 with "
    "float32-rounded actions, so its records verify on any x86-64 machine (docs/protocol.md).")


def fmt_verified(verified: Mapping | None) -> str:
    """``16 exact``: the episodes a passed verification reproduced and its tier (``exact`` / ``reproduced``;
    a verification saved before tiers: how it compared them, ``exact`` / ``tolerance``) (``†``: on its
    processor only, `processor_bound`); ``-`` if none."""
    if not verified:
        return "-"
    return f"{verified['sample']} {verified.get('tier', verified['mode'])}" + (" †" if verified.get("processor_bound") else "")


def _how_reproduced(check: Mapping) -> str:
    """How a saved verification reproduced the episodes: its tier, or (saved before tiers) its mode."""
    tier = check.get("tier")
    if tier == "exact" or (tier is None and check["mode"] == "exact"):
        return "bit-identical"
    if tier is None:
        return "within tolerance"
    return (f"tier reproduced: outcomes equal, metrics within {check['tolerance']:g} relative, largest deviation "
            f"{check['largest_deviation']:.2g}")


def fmt_generalisation(row: Mapping, key: str) -> str:
    """A row's unseen score (``unseen``), matched standard score (``matched``), gap (``gap``) or humanoid score
    (``humanoids``: n/a when the policy drives none) with its interval; ``-`` for a record without the unseen grid."""
    g = row.get("generalisation")
    if g is None:
        return "-"
    if key == "gap":
        return fmt_gap(g["gap"])
    value = g[key]
    return "n/a" if value is None else fmt_interval(value[0], value[1:])


def _ordered(standard: Sequence, found: Iterable) -> list:
    found = set(found)
    return [x for x in standard] + sorted(found - set(standard), key=str)


def _standard_text() -> str:
    return (
        f"{len(STANDARD_ROBOTS)} robots ({', '.join(STANDARD_ROBOTS)}) x {len(STANDARD_BACKENDS)} backends "
        f"({', '.join(STANDARD_BACKENDS)}) x {len(STANDARD_TERRAINS)} terrain families ({', '.join(STANDARD_TERRAINS)}) "
        f"x levels {'/'.join(map(str, STANDARD_LEVELS))} x seeds {'/'.join(map(str, STANDARD_SEEDS))}"
        f", at least {STANDARD_EPISODES} episodes per cell"
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

    ``main`` and ``partial``: records of the current protocol version (main ranked); ``archived``: records of
    other versions, main-track ones ranked within their own version only, never against the current ones.
    Records without cells matching the filters are left out.
    """
    sections: dict[str, list[dict]] = {"main": [], "partial": [], "archived": []}
    replaced = superseded(records)
    for record in records:
        cells = scored_cells(record["results"]["cells"], record["track"])
        scores = aggregate(groups_of(cells), robot=robot, backend=backend, terrain=terrain)
        if scores is None:
            continue
        unfiltered = robot is None and backend is None and terrain is None
        sections[section_of(record, replaced)].append({
            **_identity(record),
            **({"superseded_by": replaced[record["id"]]} if record["id"] in replaced else {}),
            "inputs": inputs_of(record),
            "protocol_version": record["results"]["protocol_version"],
            "scores": scores,
            "intervals": record_intervals(record, robot=robot, backend=backend, terrain=terrain),
            "generalisation": record_generalisation(record) if unfiltered else None,
        })
    _rank(sections["main"])
    sections["partial"].sort(key=lambda row: rank_key(row["scores"], row["submitted"], row["id"]))
    archived = sections["archived"]
    for version in sorted({row["protocol_version"] for row in archived}):  # ranked within their own version only
        _rank([row for row in archived if row["protocol_version"] == version and row["track"] == "main"])
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


def fmt_score(value: float | None) -> str:
    """Three decimals, ties rounded up like JavaScript's ``toFixed`` so the page and README agree."""
    if value is None:
        return "-"
    return str(Decimal(value).quantize(Decimal("0.001"), rounding=ROUND_HALF_UP))


def fmt_interval(value: float | None, interval: Sequence[float] | None) -> str:
    """``0.354 (0.343-0.365)``: a score and its 95 % interval; ``-`` when there is no score."""
    if value is None:
        return "-"
    if interval is None:
        return fmt_score(value)
    return f"{fmt_score(value)} ({fmt_score(interval[0])}-{fmt_score(interval[1])})"


def fmt_gap(interval: Sequence[float] | None) -> str:
    """The signed gap MuJoCo − PyBullet with its interval, ``+0.012 (-0.004-+0.027)``; ``-`` without both."""
    if interval is None:
        return "-"
    sign = lambda v: ("+" if v >= 0 else "-") + fmt_score(abs(v))  # noqa: E731
    return f"{sign(interval[0])} ({sign(interval[1])}..{sign(interval[2])})"


# --------------------------------------------------------------------------- text and JSON


def render_json(records: Sequence[Mapping], **filters) -> str:
    return json.dumps(board(records, **filters), indent=2, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def _columns(families: Sequence[str], backends: Sequence[str], ranked: bool) -> list[tuple[str, callable]]:
    def iv(row: dict, key: str, name: str | None = None):
        value = row["scores"][key] if name is None else row["scores"][key].get(name)
        interval = row["intervals"][key] if name is None else row["intervals"][key].get(name)
        return fmt_interval(value, interval)

    columns = [("#", lambda r: (str(r["rank"]) + ("~" if r["tied_above"] else "")) if "rank" in r else "-")] if ranked else []
    columns += [
        ("name", lambda r: r["name"]),
        ("policy", lambda r: r["policy"]),
        ("protocol", lambda r: r["protocol_version"]),
        ("overall", lambda r: iv(r, "overall")),
    ]
    columns += [(f, lambda r, f=f: iv(r, "per_family", f)) for f in families]
    columns += [(b, lambda r, b=b: iv(r, "per_backend", b)) for b in backends]
    columns += [
        ("gap mj-pb", lambda r: fmt_gap(r["intervals"]["signed_gap"])),
        ("unseen", lambda r: fmt_generalisation(r, "unseen")),
        ("matched-unseen", lambda r: fmt_generalisation(r, "gap")),
        ("cells", lambda r: str(r["scores"]["cells"])),
        ("file", lambda r: "yes" if r["policy_file"] else "-"),
        ("verified", lambda r: fmt_verified(r["verified"])),
        ("id", lambda r: r["id"][:12]),
    ]
    return columns


SECTION_TITLES = {
    "main": "Main board, protocol {version}: records covering the standard grid, ranked by mean success "
            "(~: its 95 % interval overlaps the record above)",
    "partial": "Partial records, protocol {version} (not ranked against the main board)",
    "archived": "Archived: records of earlier protocol versions, ranked within their own version only "
                "(never against protocol {version}), and records superseded by a re-score of the same policy file "
                "in the canonical joint frame",
}


def render_table(records: Sequence[Mapping], **filters) -> str:
    """A plain-text table per section; scores with their 95 % intervals."""
    data = board(records, **filters)
    shown = axes(records)
    rows_all = data["main"] + data["partial"] + data["archived"]
    families = [f for f in shown["families"] if any(f in r["scores"]["per_family"] for r in rows_all)] or list(STANDARD_TERRAINS)
    out = []
    if data["filters"]:
        out.append("filters: " + " ".join(f"{k}={v}" for k, v in data["filters"].items()))
    for section in ("main", "partial", "archived"):
        rows = data[section]
        columns = _columns(families, shown["backends"], section != "partial")
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
    return "\n".join(out)


# --------------------------------------------------------------------------- Markdown

_MD_SPECIAL = set("\\`*_[]<>|~&#!")


def md_escape(text: str) -> str:
    """Escape text for a Markdown table cell or paragraph (no markup, links or HTML survive)."""
    return "".join("\\" + ch if ch in _MD_SPECIAL else ch for ch in str(text))


def _md_row(values: Iterable[str]) -> str:
    return "| " + " | ".join(values) + " |"


def _unseen_text() -> str:
    from frbench.evaluation.grids import unseen_part

    part = unseen_part()
    return (f"{len(part.robots)} real quadrupeds no policy trains on ({', '.join(part.robots)}) x both backends x "
            f"{', '.join(part.terrains)} x levels {'/'.join(map(str, part.levels))} x seeds "
            f"{'/'.join(map(str, part.seeds))}, {part.episodes} episodes per cell")


def unseen_table(ranking: Sequence[Mapping]) -> list[str]:
    """The Markdown table of `unseen_ranking`."""
    if not ranking:
        return ["_No record has the unseen grid yet._", ""]
    out = [_md_row(["#", "Name", "Unseen", "Matched std", "Matched − unseen", "Humanoids", "Main-board rank", "Record"]),
           _md_row(["---"] * 8)]
    for row in ranking:
        out.append(_md_row([
            str(row["rank"]) + (" ~" if row["tied_above"] else ""), md_escape(row["name"]),
            f"**{fmt_interval(row['unseen'][0], row['unseen'][1:])}**",
            fmt_interval(row["matched"][0], row["matched"][1:]), fmt_gap(row["gap"]),
            "n/a" if row["humanoids"] is None else fmt_interval(row["humanoids"][0], row["humanoids"][1:]),
            str(row["board_rank"]), f"[{row['id'][:12]}](records/{record_file_name(row['id'])})",
        ]))
    return out + [""]


def render_markdown(records: Sequence[Mapping]) -> str:
    """``leaderboard/README.md``."""
    data = board(records)
    shown = axes(records)
    families, backends = shown["families"], shown["backends"]
    lines = [
        "# frbench leaderboard",
        "",
        "<!-- Generated by `frbench leaderboard --format md` from records/*.json.gz; do not edit by hand. -->",
        "",
        "Fall-recovery policies evaluated with `frbench evaluate`, submitted with",
        "`frbench submit RESULTS.json --name NAME --submitter WHO --description TEXT --link URL [--policy-file FILE]`.",
        "",
        f"*Policy file*: the record carries the policy that produced it (`--policy-file`, at most "
        f"{MAX_POLICY_BYTES // 2**20} MiB, stored as",
        "`policies/<sha256><suffix>`; a checkpoint shipped in frbench is referred to by its sha256). `frbench verify RECORD [--sample N] [--seed S]` re-runs a seeded random",
        "sample of a record's episodes from its provenance with that policy (or with the shipped checkpoint of the",
        "same sha256, or a built-in policy by name, re-run with the checkout's code) and compares them episode by",
        "episode, naming the tier reached and the processors that made and re-ran the record: *exact* (bit-identical),",
        "*reproduced* (the same success, rollover, divergence, initial pose and start redraws, time to recover within",
        f"one control period and the other metrics within {REPRODUCED_TOLERANCE:g} relative where the library versions "
        f"match, else within {RELATIVE_TOLERANCE:g}),",
        "*consistent* (a foreign policy's successes pass a statistical check; verifies nothing) or *failed*, when it",
        "exits 1 and lists the differences (docs/protocol.md). *Verified*: episodes reproduced by `frbench verify --save`,",
        "and the tier (saved before tiers: *exact* or *tolerance*, how they were compared).",
        "Open [index.html](index.html) for filters by robot, backend and terrain family, success-vs-level",
        "charts and each record's provenance.",
        "",
        f"Current protocol: {PROTOCOL_VERSION} ([docs/protocol.md](../docs/protocol.md)); accepted versions: "
        f"{', '.join(KNOWN_PROTOCOL_VERSIONS)}. Records follow",
        "[schema/record-v1.schema.json](schema/record-v1.schema.json); each file in `records/` is named by the",
        "sha256 of its results. Scores are recomputed from each record's cells: the mean success rate over cells",
        "(one cell = robot x backend x terrain x level x seed), per terrain family and per backend. Beside each",
        "score, in parentheses, its 95 % interval from a stratified bootstrap over cells and episodes (rliable's",
        "procedure, `frbench/evaluation/intervals.py`). *Gap* is the signed sim-to-sim gap MuJoCo - PyBullet",
        "(mean over robot x terrain x level) with its interval. Records of different protocol versions are never",
        "ranked together: only the current version is ranked; earlier versions are archived below.",
        "",
        f"## Main board (protocol {PROTOCOL_VERSION})",
        "",
        f"Records that cover the standard grid: {_standard_text()}; from protocol 1.2 on also the unseen grid",
        "(below; a 1.2 record without it is partial). *Overall* and the columns up to *Gap* are the standard grid's.",
        "Ranked by overall success, then by sim-to-sim gap. A `~` after a rank: the record's overall interval",
        "overlaps the one of the record above it, so their order is not established by the data.",
        "",
    ]
    header = ["Name", "Policy", "Submitter", "Overall"] + [md_escape(f) for f in families] \
        + [BACKEND_LABELS.get(b, md_escape(b)) for b in backends] \
        + ["Gap", "Matched std", "Unseen", "Matched − unseen", "Humanoids", "Policy file", "Verified", "Record"]

    def table(rows: list[dict], ranked: bool, protocol: bool = False) -> list[str]:
        if not rows:
            return ["_No records yet._" if ranked and not protocol else "_None._", ""]
        head = (["#"] if ranked else []) + header[:3] + (["Protocol"] if protocol else []) + (["Cells"] if protocol or not ranked else []) + header[3:]
        out = [_md_row(head), _md_row(["---"] * len(head))]
        for row in rows:
            s, iv = row["scores"], row["intervals"]
            state = " (simulator state)" if row["inputs"] == SIMULATOR_STATE else ""
            later = f" (superseded by {row['superseded_by'][:12]})" if row.get("superseded_by") else ""
            values = [md_escape(row["name"]) + later, md_escape(row["policy"]) + state, md_escape(row["submitter"])]
            if protocol:
                values.append(md_escape(row["protocol_version"]))
            if protocol or not ranked:
                values.append(str(s["cells"]))
            overall = fmt_interval(s["overall"], iv["overall"])
            values += [f"**{overall}**" if ranked else overall]
            values += [fmt_interval(s["per_family"].get(f), iv["per_family"].get(f)) for f in families]
            values += [fmt_interval(s["per_backend"].get(b), iv["per_backend"].get(b)) for b in backends]
            file = (f"[{row['policy_file'][9:21]}]({row['policy_file']})" if row["policy_file"].startswith("policies/")
                    else md_escape(row["policy_file"])) if row["policy_file"] else "-"
            values += [fmt_gap(iv["signed_gap"]), fmt_generalisation(row, "matched"), fmt_generalisation(row, "unseen"),
                       fmt_generalisation(row, "gap"),
                       fmt_generalisation(row, "humanoids"), file, fmt_verified(row["verified"]),
                       f"[{row['id'][:12]}](records/{record_file_name(row['id'])})"]
            rank = [(str(row["rank"]) + (" ~" if row["tied_above"] else "")) if "rank" in row else "-"] if ranked else []
            out.append(_md_row(rank + values))
        return out + [""]

    lines += table(data["main"], True)
    lines += [
        f"### Ranked by unseen success (protocol {PROTOCOL_VERSION})",
        "",
        f"The main board by mean success on the unseen grid: {_unseen_text()}. *Matched std*: the standard grid's",
        "cells on the same families and levels (the five training-distribution robots, 320 cells); *Matched − unseen*:",
        "their difference with its 95 % interval (both resampled): what the policy loses on bodies it never trained on,",
        "terrain held equal. *Humanoids*: the unseen humanoid set (Talos, iCub) for a policy that drives humanoids, n/a",
        "for the others.",
        "",
    ]
    lines += unseen_table(data["unseen_ranking"])
    lines += [
        f"## Partial records (protocol {PROTOCOL_VERSION})",
        "",
        "Records that do not cover the whole standard grid, scored on the cells they have; not ranked",
        "against the main board.",
        "",
    ]
    lines += table(data["partial"], False)
    lines += [
        "## Archived records (earlier protocol versions, superseded records)",
        "",
        "Records evaluated under an earlier protocol. Their numbers mean something else (docs/protocol.md lists",
        f"what changed), so they are never ranked against protocol {PROTOCOL_VERSION}; records that covered that",
        "version's standard grid are ranked among themselves (`~`: interval overlaps the one above), the rest (`-`) not.",
        f"A protocol {PROTOCOL_VERSION} record *superseded by* another ran a learned policy in each robot's own joint",
        "convention; the record named re-scores the same policy file in the canonical joint frame (docs/protocol.md,",
        "\"The joint frame\"). Each record id keeps meaning its own results.",
        "",
    ]
    lines += table(data["archived"], True, protocol=True)
    if any((row.get("verified") or {}).get("processor_bound") for row in data["archived"]):
        lines += [PROCESSOR_BOUND_NOTE, ""]
    by_id = {r["id"]: r for r in records}
    rows = data["main"] + data["partial"] + data["archived"]
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
        section = section_of(by_id[row["id"]])
        lines.append(f"- **{md_escape(row['name'])}** (`{row['id'][:12]}`, {section}, submitted {row['submitted']} "
                     f"by {md_escape(row['submitter'])}){link}")
        if row["description"]:
            lines.append(f"  - {md_escape(row['description'])}")
        lines.append(
            f"  - Protocol {md_escape(results['protocol_version'])}, frbench {md_escape(fb['version'])} ({commit}), "
            f"{versions}; policy {md_escape(policy['name'])}, {checkpoint}; "
            f"seeds {', '.join(map(str, results['config']['seeds']))}, {results['config']['episodes']} episodes per cell, "
            f"noise {'on' if results['config']['noise'] else 'off'}."
        )
        record = by_id[row["id"]]
        if "policy_file" in record:
            attached = record["policy_file"]
            if "shipped" in attached:
                lines.append(f"  - Policy file: the checkpoint shipped in frbench as {md_escape(attached['shipped'])} "
                             f"(sha256 {attached['sha256'][:12]}), {attached['bytes']} bytes.")
            else:
                lines.append(f"  - Policy file attached: [{attached['file']}]({attached['file']}), {attached['bytes']} bytes.")
        if "processor" in results:
            lines.append(f"  - Evaluated on {md_escape(processor_label(results['processor']))}.")
        for check in record.get("verifications", []):
            lines.append(
                f"  - Verified {check['verified']}: `frbench verify --sample {check['sample']} --seed {check['seed']}` re-ran "
                f"{check['sample']} episodes in {check['cells']} cells with the {check['policy']} policy at frbench "
                f"{check['frbench_commit'][:12]} and reproduced them ({_how_reproduced(check)})"
                + (f" on {md_escape(processor_label(check['processor']))}" if "processor" in check else "")
                + (" on that machine's processor only †." if processor_bound(record) else ".")
            )
    if rows:
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------- HTML


def page_data(records: Sequence[Mapping]) -> dict:
    """The JSON embedded in ``index.html``: per record, its (robot, backend, terrain, level) aggregates and provenance."""
    entries = []
    replaced = superseded(records)
    for record in sorted(records, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"])):
        groups = groups_of(scored_cells(record["results"]["cells"], record["track"]))
        entries.append({
            **_identity(record),
            "section": section_of(record, replaced),
            **({"superseded_by": replaced[record["id"]]} if record["id"] in replaced else {}),
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
        "standard": _standard_text(),
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
