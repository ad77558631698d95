"""The style sheet of ``leaderboard/index.html`` (`frbench.leaderboard.page`); its hash is in the page's CSP."""

PAGE_STYLE = """
:root { --fg: #1d232a; --muted: #5b6570; --line: #d8dde3; --head: #f3f5f7; --sel: #fff4cc; --accent: #1f6feb; }
* { box-sizing: border-box; }
body { margin: 0; font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; color: var(--fg); background: #fff; }
header, main { max-width: 1400px; margin: 0 auto; padding: 0 20px; }
header h1 { margin: 18px 0 4px; font-size: 24px; }
header p, .note { color: var(--muted); margin: 4px 0 10px; }
h2 { font-size: 18px; margin: 22px 0 6px; }
code { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12.5px; }
#filters { display: flex; flex-wrap: wrap; gap: 14px; align-items: center; padding: 10px 12px; margin: 10px 0; background: var(--head); border: 1px solid var(--line); border-radius: 6px; }
#filters label { font-weight: 600; }
select, button { font: inherit; margin-left: 4px; padding: 2px 6px; }
.scroll { overflow-x: auto; }
table.board { border-collapse: collapse; width: 100%; font-variant-numeric: tabular-nums; }
table.board th, table.board td { border-bottom: 1px solid var(--line); padding: 5px 7px; text-align: left; white-space: nowrap; }
table.board th { background: var(--head); position: sticky; top: 0; }
table.board th button { all: unset; cursor: pointer; font-weight: 600; }
table.board th button:focus-visible { outline: 2px solid var(--accent); }
table.board th[aria-sort="ascending"] button::after { content: " \\25B2"; font-size: 10px; }
table.board th[aria-sort="descending"] button::after { content: " \\25BC"; font-size: 10px; }
table.board td.num, table.board th.num { text-align: right; }
table.board td.id { font-family: ui-monospace, "DejaVu Sans Mono", monospace; color: var(--muted); }
table.board tbody tr { cursor: pointer; }
table.board tbody tr:hover td { outline: none; filter: brightness(0.97); }
table.board tbody tr[aria-selected="true"] td { background: var(--sel) !important; }
table.board td.off { color: #aab2bb; }
.empty { color: var(--muted); font-style: italic; }
#details { border: 1px solid var(--line); border-radius: 6px; padding: 4px 16px 12px; margin: 16px 0; background: #fbfcfd; }
.details-head { display: flex; justify-content: space-between; align-items: center; }
#details dl { display: grid; grid-template-columns: max-content 1fr; gap: 3px 16px; margin: 6px 0; }
#details dt { font-weight: 600; color: var(--muted); }
#details dd { margin: 0; overflow-wrap: anywhere; }
#details pre { background: var(--head); padding: 8px; border-radius: 4px; max-height: 260px; overflow: auto; margin: 0; font-size: 12px; }
#details table { border-collapse: collapse; }
#details table td { padding: 1px 10px 1px 0; font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12px; }
#charts { display: flex; flex-wrap: wrap; gap: 12px; }
#charts figure { margin: 0; border: 1px solid var(--line); border-radius: 6px; padding: 6px; }
#charts figcaption { font-weight: 600; text-align: center; }
#charts svg text { font-size: 11px; fill: var(--muted); }
#legend { display: flex; flex-wrap: wrap; gap: 6px 16px; margin: 6px 0 10px; }
#legend span.key { display: inline-flex; align-items: center; gap: 6px; cursor: pointer; }
#legend svg { flex: none; }
"""
