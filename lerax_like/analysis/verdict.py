"""What a work-precision study concludes: settings that coincide, timings that say nothing, the cheapest.

Three rules keep a verdict from resting on noise:

- Settings of one solver whose errors and step counts coincide are one setting (Dopri8
  takes the same 200 steps at every `rtol` from 1e-4 to 1e-12 on CartPole: its nine
  tolerances are one point, named by their range).
- A timing is unresolved when it is within `UNRESOLVED_TIMING_FACTOR` of an empty
  compiled call or its repeats spread by more than `UNRESOLVED_SPREAD`; it is marked as
  such in the table and the figure alike.
- "Cheapest" is by vector-field evaluations, which do not change between runs; time
  serves only where some candidate's evaluations are unknown (implicit solvers), and
  then only resolved timings count and a winner within the others' spread is a tie.
"""

import math
from collections.abc import Iterable, Sequence
from typing import Any


UNRESOLVED_TIMING_FACTOR = 3.0
UNRESOLVED_SPREAD = 0.25
COINCIDING_ERROR_RTOL = 1e-9
"""Errors of one solver's settings within this relative distance, at the same step counts,
are one setting: the same steps give the same solution up to round-off."""


def timing_unresolved(row: dict[str, Any]) -> bool:
    """Whether a row's time says little: near the cost of an empty call, or noisy repeats."""
    floor = row.get("timing_floor", math.nan)
    spread = row.get("seconds_spread", math.nan)
    return bool(
        (not math.isnan(floor) and row["seconds"] < UNRESOLVED_TIMING_FACTOR * floor)
        or (not math.isnan(spread) and spread > UNRESOLVED_SPREAD)
    )


def _same(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=COINCIDING_ERROR_RTOL, abs_tol=0.0)


def _coincide(row: dict[str, Any], other: dict[str, Any]) -> bool:
    return (
        row["schedule"] == other["schedule"] and row["label"] == other["label"]
        and row["solver_ok"] == other["solver_ok"]
        and row["steps"] == other["steps"] and row.get("rejected_steps") == other.get("rejected_steps")
        and all(_same(row[key], other[key]) for key in ("error", "max_error"))
    )


def setting_name(row: dict[str, Any]) -> str:
    """A row's solver setting in words: its step (fixed steps) or its tolerances."""
    if row["controller"] == "ConstantStepSize":
        return f"dt={row['dt']:.3g} ({row['substeps']} substeps)"
    return f"rtol={row['rtol']:.0e}, atol={row['atol']:.0e}"


def _group_name(members: Sequence[dict[str, Any]]) -> str:
    if len(members) == 1:
        return setting_name(members[0])
    first, last = members[0], members[-1]
    if first["controller"] == "ConstantStepSize":
        return f"dt={first['dt']:.3g}..{last['dt']:.3g} ({first['substeps']}..{last['substeps']} substeps)"
    return f"rtol={first['rtol']:.0e}..{last['rtol']:.0e}, atol={first['atol']:.0e}..{last['atol']:.0e}"


def group_settings(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows with coinciding settings merged, in the order of their first member.

    Neighbouring settings of one sweep (same schedule and label) whose errors and
    accepted and rejected step counts coincide become one row: the first member's
    values, `setting` naming the range, `members` the count, and as its time the
    fastest member's (they ran the same steps), with `seconds_spread` the members'
    spread about it. A row on its own keeps its values and gets `setting` and
    `members = 1`.
    """
    groups: list[list[dict[str, Any]]] = []
    latest: dict[tuple[str, str], list[dict[str, Any]]] = {}  # the last group of each schedule and sweep
    for row in rows:
        key = (row["schedule"], row["label"])
        group = latest.get(key)
        if group is not None and _coincide(group[-1], row):
            group.append(row)
        else:
            latest[key] = [row]
            groups.append(latest[key])
    merged = []
    for members in groups:
        row = dict(members[0])
        row["setting"] = _group_name(members)
        row["members"] = len(members)
        if len(members) > 1:
            times = sorted(member["seconds"] for member in members)
            spreads = [member.get("seconds_spread", math.nan) for member in members]
            row["seconds"] = times[0]
            middle = times[len(times) // 2] if len(times) % 2 else 0.5 * (times[len(times) // 2 - 1] + times[len(times) // 2])
            row["seconds_spread"] = max([(middle - times[0]) / times[0]] + [s for s in spreads if not math.isnan(s)])
        merged.append(row)
    return merged


def _known(row: dict[str, Any], key: str) -> bool:
    value = row.get(key, math.nan)
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def cheapest_at(
    rows: Iterable[dict[str, Any]], target: float, *, cost: str | None = None, schedule: str | None = None
) -> dict[str, Any] | None:
    """The cheapest setting whose error is at most `target`, or None if none reaches it.

    Settings that coincide are one (`group_settings`). `cost` is the measure:
    `"vector_field_evaluations"`, `"seconds"` (resolved timings only), or None (the
    default): evaluations where every candidate has them, else resolved seconds. Equal
    evaluations go to the smaller error, then to the earlier setting, so the verdict is
    the same in every run. By seconds, a winner within the runner-up's spread is no
    clear winner: `tied_with` then names the settings it cannot be told from. Only rows
    of `schedule` count (default: the first schedule in the rows).

    Returns `{"label", "setting", "error", <cost>: value, "schedule", "measure",
    "members", "tied_with", "unmeasured"}`; `unmeasured` names the solvers that reached
    the level but whose cost is unknown (an implicit solver's evaluations), so were not
    compared.
    """
    rows = list(rows)
    if not rows:
        return None
    schedule = rows[0]["schedule"] if schedule is None else schedule
    candidates = [
        row for row in group_settings(r for r in rows if r["schedule"] == schedule)
        if row["solver_ok"] and not math.isnan(row["error"]) and row["error"] <= target
    ]
    if not candidates:
        return None
    if cost is None:
        by_work = all(_known(row, "vector_field_evaluations") for row in candidates)
        cost = "vector_field_evaluations" if by_work else "seconds"
    tied: list[dict[str, Any]] = []
    unmeasured = [row for row in candidates if not _known(row, cost)]
    if cost == "seconds":
        candidates = [row for row in candidates if not timing_unresolved(row)]
        if not candidates:
            return None
        best = min(candidates, key=lambda row: row["seconds"])
        spread = best.get("seconds_spread", math.nan)
        margin = 1.0 + (UNRESOLVED_SPREAD if math.isnan(spread) else max(UNRESOLVED_SPREAD, spread))
        tied = [row for row in candidates if row is not best and row["seconds"] <= margin * best["seconds"]]
    else:
        candidates = [row for row in candidates if _known(row, cost)]
        if not candidates:
            return None
        order = {id(row): index for index, row in enumerate(candidates)}
        best = min(candidates, key=lambda row: (row[cost], row["error"], order[id(row)]))
    return {
        "label": best["label"], "setting": best["setting"], "error": best["error"], cost: best[cost],
        "schedule": schedule, "measure": cost, "members": best["members"],
        "tied_with": [f"{row['label']} at {row['setting']}" for row in tied],
        "unmeasured": list(dict.fromkeys(row["label"] for row in unmeasured)),
    }


def order_disagreements(orders: Iterable[dict[str, Any]]) -> list[str]:
    """A verdict on the fitted orders: one line per solver and schedule whose fitted order
    disagrees with its declared one (`convergence.ORDER_DISAGREEMENT`), none if all agree."""
    return [
        f"{entry['solver']} ({entry['schedule']} actions): fitted order {entry['order']:.2f} over "
        f"{entry['points']} points, declared {entry['method_order']:g}: the method or its declared order is wrong, "
        "or the steps miss the asymptotic range"
        for entry in orders if entry.get("disagrees")
    ]


def failures(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The failed settings (coinciding ones merged): label, setting, schedule and why, in row order."""
    return [
        {"schedule": row["schedule"], "label": row["label"], "setting": row["setting"],
         "failure": row.get("failure") or "unknown"}
        for row in group_settings(rows) if not row["solver_ok"]
    ]


def verdict_line(best: dict[str, Any] | None) -> str:
    """A verdict of `cheapest_at` in words."""
    if best is None:
        return "none reached it"
    if best["measure"] == "seconds":
        text = f"{best['label']} at {best['setting']} ({best['seconds']:.2e} s, resolved timings only)"
        if best["tied_with"]:
            text += "; within timing noise of " + ", ".join(best["tied_with"])
        return text
    text = f"{best['label']} at {best['setting']} ({best[best['measure']]:.0f} {best['measure'].replace('_', ' ')})"
    if best["unmeasured"]:
        text += "; not compared (evaluations unknown): " + ", ".join(best["unmeasured"])
    return text
