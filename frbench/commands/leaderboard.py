"""``frbench submit`` and ``frbench leaderboard``: the shared leaderboard under ``leaderboard/``.

``frbench submit RESULTS.json [--name N --description D --submitter S --link URL --policy-file FILE]``
checks a results file written by ``frbench evaluate`` (schema, self-consistency,
known protocol version), recomputes its scores and adds it as
``leaderboard/records/<id>.json.gz`` (gzip JSON, `frbench.leaderboard.records`), then
regenerates ``README.md`` and ``index.html``. ``--policy-file`` stores the policy that produced the results
beside the record, or refers to it by sha256 when it is a checkpoint shipped in frbench
(`frbench.leaderboard.policy_files`). Bad input: one line on
stderr naming the file and field, exit 2, nothing written.

``frbench leaderboard [--format table|md|html|json] [--robot R --backend B --terrain T] [--track T]``
prints the ranking (table, json; ``--track humanoid``: the humanoid track alone) or regenerates
``leaderboard/README.md`` (md) or ``leaderboard/index.html`` (html). ``frbench leaderboard --check`` validates
every record and that the generated files are up to date; it exits 1 with one
line per problem (for CI). Reading the board (and submitting) checks a record file in full once per content
and keeps the board's summary of it in frbench's cache folder (`frbench.leaderboard.summaries`), so a read
after the first takes about a second; ``--check`` checks every file in full at every run.

The leaderboard folder is ``--root``, else ``$FRBENCH_LEADERBOARD_DIR``, else the
repository's ``leaderboard/`` for a source checkout, else ``./leaderboard``.
"""

from __future__ import annotations

import argparse
import sys

from frbench.errors import FrbenchError, unknown_name

#: ``--track``'s values: the board's sections (`frbench.leaderboard.sections.SECTIONS`; a test keeps them equal).
SECTION_CHOICES = ("main", "humanoid", "partial", "archived")


def register(subparsers: argparse._SubParsersAction) -> None:
    submit = subparsers.add_parser(
        "submit",
        help="add a results file to the leaderboard",
        description="Check a results file from `frbench evaluate` and add it to the leaderboard as a new record.",
    )
    submit.add_argument("results", metavar="RESULTS.json", help="results file written by `frbench evaluate`")
    submit.add_argument("--name", help="entry name: 1-64 of A-Z a-z 0-9 . _ - (default: the results' policy name)")
    submit.add_argument("--description", default="", help="one line of plain text, at most 280 characters")
    submit.add_argument("--submitter", default=None, help="who submits (default: anonymous), at most 64 characters")
    submit.add_argument("--link", default=None, help="http(s) URL of a paper, code or model card")
    submit.add_argument("--root", default=None, help="leaderboard folder (default: see `frbench leaderboard --help`)")
    submit.add_argument("--dry-run", action="store_true", help="check and score the results without writing anything")
    submit.add_argument("--policy-file", default=None, metavar="FILE",
                        help="attach the policy that produced the results (at most 16 MiB; stored as policies/<sha256><suffix>, "
                             "with its FILE.json sidecar if present); results already on the board get it attached")
    submit.set_defaults(func=run_submit)

    board = subparsers.add_parser(
        "leaderboard",
        help="print the leaderboard or regenerate README.md / index.html",
        description=(
            "Print the leaderboard ranking, regenerate leaderboard/README.md (--format md) or leaderboard/index.html "
            "(--format html), or check the records and generated files (--check). The leaderboard folder is --root, "
            "else $FRBENCH_LEADERBOARD_DIR, else the repository's leaderboard/ when frbench runs from a source "
            "checkout, else ./leaderboard."
        ),
    )
    board.add_argument("--format", choices=("table", "md", "html", "json"), default=None,
                       help="table or json print the ranking; md and html regenerate README.md and index.html (default: table)")
    board.add_argument("--robot", help="score only this robot's cells (table and json)")
    board.add_argument("--backend", help="score only this backend's cells (table and json)")
    board.add_argument("--terrain", help="score only this terrain family's cells (table and json)")
    board.add_argument("--track", choices=SECTION_CHOICES, default=None,
                       help="print one section of the board alone: main, humanoid (the humanoid track), partial or "
                            "archived (table and json)")
    board.add_argument("--root", default=None, help="leaderboard folder")
    board.add_argument("--check", action="store_true",
                       help="validate every record and that README.md and index.html are up to date; exit 1 if not")
    board.set_defaults(func=run_leaderboard)


def run_submit(args: argparse.Namespace) -> int:
    from frbench.leaderboard.board import submit
    from frbench.leaderboard.paths import resolve_root
    from frbench.leaderboard.policy_files import policy_file_label

    root = resolve_root(args.root)
    outcome = submit(
        args.results, root, name=args.name, description=args.description, submitter=args.submitter,
        link=args.link, dry_run=args.dry_run, policy_file=args.policy_file,
    )
    from frbench.leaderboard.formatting import fmt_score

    record = outcome.record
    entry = record.get("policy_file")
    if outcome.attached_only:
        stored = "shipped" not in entry
        print(f"attached {policy_file_label(entry)} to record {record['id'][:12]} ({record['submission']['name']}); "
              f"wrote {outcome.path}; commit it" + (f" with {root / entry['file']}" if stored else ""))
        return 0
    scores = record["scores"]
    verb = "would add" if args.dry_run else "added"
    print(
        f"{verb} record {record['id'][:12]} ({record['submission']['name']}, {record['track']} track): "
        f"overall success {fmt_score(scores['overall'])}, sim-to-sim gap {fmt_score(scores['sim_to_sim_gap'])}, "
        f"{scores['cells']} cells"
    )
    if record["track"] == "partial":
        from frbench.leaderboard.scores import humanoid_track_shortfall, main_track_shortfall
        from frbench.tasks.protocol import HUMANOID_ROBOTS

        results = record["results"]
        print(f"partial, not ranked on the main board: {main_track_shortfall(results['cells'], results['protocol_version'])}")
        if any(c["robot"] in HUMANOID_ROBOTS for c in results["cells"]):
            reason = humanoid_track_shortfall(results["cells"], results["protocol_version"],
                                              results["config"].get("not_scored", {}))
            print(f"not on the humanoid track: {reason}")
    elif record["track"] == "humanoid":
        print("humanoid track: ranked with the other humanoid-track records of its protocol version")
    if entry is not None:
        how = " (a checkpoint shipped in frbench: referred to by its sha256, not stored again)" if "shipped" in entry else ""
        print(f"{'would attach' if args.dry_run else 'attached'} policy file {policy_file_label(entry)} "
              f"({entry['bytes']} bytes){how}")
    if outcome.written:
        print(f"wrote {outcome.path}; commit it with {root / 'README.md'} and {root / 'index.html'}")
    return 0


def run_leaderboard(args: argparse.Namespace) -> int:
    from frbench.leaderboard.board import check, regenerate
    from frbench.leaderboard.paths import INDEX, README, resolve_root
    from frbench.leaderboard.render import axes, render_json, render_table

    root = resolve_root(args.root)
    filters = {"robot": args.robot, "backend": args.backend, "terrain": args.terrain}
    given = [f"--{k}" for k, v in filters.items() if v is not None]
    if args.check:
        if args.format or given or args.track:
            raise FrbenchError("--check takes no --format, --robot, --backend, --terrain or --track")
        report = check(root)
        if not report.ok:
            for problem in report.problems:
                print(f"frbench leaderboard --check: {problem}", file=sys.stderr)
            return 1
        from collections import Counter

        from frbench.leaderboard.render import section_of
        from frbench.tasks.protocol import PROTOCOL_VERSION

        sections = Counter(section_of(r) for r in report.records)
        print(f"leaderboard {root} is valid and up to date: {len(report.records)} records (protocol {PROTOCOL_VERSION}: "
              f"{sections['main']} main, {sections['humanoid']} humanoid, {sections['partial']} partial; "
              f"{sections['archived']} archived)")
        return 0
    fmt = args.format or "table"
    if fmt in ("md", "html"):
        if given or args.track:
            given += ["--track"] if args.track else []
            raise FrbenchError(
                f"{', '.join(given)}: filters apply to --format table and json; README.md and index.html always show "
                "the whole board (the page has its own filters)"
            )
        target = README if fmt == "md" else INDEX
        changed = regenerate(root, only=[target])
        state = "wrote" if target in changed else "up to date:"
        print(f"{state} {root / target}")
        for other in changed:
            if other != target:
                print(f"wrote {root / other}")
        return 0
    from frbench.leaderboard.summaries import load_summaries

    records = load_summaries(root)
    known = axes(records)
    for key, listing in (("robot", "robots"), ("backend", "backends"), ("terrain", "families")):
        if filters[key] is not None and filters[key] not in known[listing]:
            raise unknown_name(key, filters[key], known[listing])
    render = render_table if fmt == "table" else render_json
    sys.stdout.write(render(records, track=args.track, **filters))
    return 0
