"""How the leaderboard writes a number, an interval, a gap, a verification or a submitter's text: the helpers that
the text table, ``README.md`` and the page's data share, so the three agree to the last digit."""

from __future__ import annotations

from decimal import ROUND_HALF_UP, Decimal
from typing import Iterable, Mapping, Sequence

from frbench.evaluation.results import SIM_TO_SIM_PAIRS
from frbench.leaderboard.scores import needs_unseen_grid, pair_name

BACKEND_LABELS = {"mujoco": "MuJoCo", "pybullet": "PyBullet", "physx": "PhysX"}
#: The first pair of grid simulators (`frbench.evaluation.results.SIM_TO_SIM_PAIRS`): its gap is ``signed_gap``.
FIRST_PAIR = pair_name(*SIM_TO_SIM_PAIRS[0])


def pair_label(pair: str) -> str:
    """``MuJoCo − PhysX`` for the pair ``mujoco-physx`` (`frbench.leaderboard.scores.pair_name`)."""
    first, second = pair.split("-")
    return f"{BACKEND_LABELS.get(first, first)} − {BACKEND_LABELS.get(second, second)}"


def signed_gap_of(intervals: Mapping, pair: str) -> Sequence[float] | None:
    """The signed gap [point, low, high] of one pair of simulators (``mujoco-physx``) in a record's intervals
    (`frbench.leaderboard.scores.score_intervals`): ``signed_gaps[pair]``, or ``signed_gap`` for MuJoCo −
    PyBullet in a record of those two alone; None when the pair did not both run."""
    gaps = intervals.get("signed_gaps")
    if gaps is not None:
        return gaps.get(pair)
    return intervals.get("signed_gap") if pair == FIRST_PAIR else None


def gap_headers(pairs: Sequence[str]) -> list[str]:
    """The gap columns' headers: ``Gap`` when the board has the one pair MuJoCo − PyBullet, else ``Gap`` and the
    pair per column (``Gap MuJoCo − PhysX``)."""
    return ["Gap"] if list(pairs) == [FIRST_PAIR] else [f"Gap {pair_label(p)}" for p in pairs]


def processor_bound(record: Mapping) -> bool:
    """Whether a verification of the record holds only on the processor that ran it: a learned policy (one with
    a checkpoint) evaluated before protocol 1.2, whose float32 inference depends on the CPU's vector kernels."""
    results = record["results"]
    return results["policy"].get("sha256") is not None and not needs_unseen_grid(results["protocol_version"])


#: The note on a processor-bound verification (`processor_bound`), marked with a dagger.
PROCESSOR_BOUND_NOTE = (
    "† verified on the verifying machine's processor only: the policy is learned and ran float32 inference, whose "
    "last bits depend on the CPU's vector kernels (on an AVX-512 machine frnet-3m's 1.1 record f3a8b4dd2ded failed "
    "`--sample 4 --seed 1` 4/4; so did dreamriser-3m and frnet-no-stability-15m). Protocol 1.2 infers in float64 with "
    "float32-rounded actions, so its records verify on any x86-64 machine (docs/protocol.md).")


def fmt_verified(verified: Mapping | None) -> str:
    """``16 exact``: the episodes a passed verification reproduced and its tier (``exact`` / ``reproduced``;
    a verification saved before tiers: how it compared them, ``exact`` / ``tolerance``) (``†``: on its
    processor only, `processor_bound`); ``-`` if none."""
    if not verified:
        return "-"
    return f"{verified['sample']} {verified.get('tier', verified['mode'])}" + (" †" if verified.get("processor_bound") else "")


def how_reproduced(check: Mapping) -> str:
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
    (``humanoids``: n/a when the policy drives none) with its interval; ``-`` for a record without the unseen grid
    (a humanoid-track record has the humanoid set's score only)."""
    g = row.get("generalisation")
    if g is None or key not in g:
        return "-"
    if key == "gap":
        return fmt_gap(g["gap"])
    value = g[key]
    return "n/a" if value is None else fmt_interval(value[0], value[1:])


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


_MD_SPECIAL = set("\\`*_[]<>|~&#!")


def md_escape(text: str) -> str:
    """Escape text for a Markdown table cell or paragraph (no markup, links or HTML survive)."""
    return "".join("\\" + ch if ch in _MD_SPECIAL else ch for ch in str(text))


def md_row(values: Iterable[str]) -> str:
    return "| " + " | ".join(values) + " |"
