"""Which points to run: the whole grid, or a bisection on the one budget axis.

Both work on "decisions" (``pass``/``fail``/``undecided`` per point, from
:func:`chiptwin.detection.stats.decide`) and share the monotonicity check and the answer rule.

**The monotonicity assumption.** Along a budget axis (cheapest value first) a point that meets
the requirement is assumed to be followed by no point that fails it: more ADC bits, more memory
or more DNA never make the chip worse (an undecided point, whose interval allows a pass, breaks
nothing). Bisection relies on it to skip points; both searches check it on every point they
visited, and report a violation (a pass followed by a fail further along the axis, or a metric
significantly worse at a costlier point), never hide it. A bisection also re-checks ``verify``
points between its answer and the costliest passing point; a failure found there moves the
search above it. A bisection's midpoint that is undecided counts as not meeting the
requirement (the search goes above it), so a bisection may answer above a cheaper point that a
grid would show to pass.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

#: Statuses of a point that does not meet the requirement (an undecided one counts as not).
NOT_MET = ("fail", "undecided", "invalid")

UNDECIDED_IS_FAIL = "an undecided point (its interval straddles a threshold at the cap) counts " \
                    "as not meeting the requirement"


def bisect(n: int, decide: Callable[[int], str], verify: int = 1) -> dict[str, Any]:
    """Bisection over indices ``0 … n-1`` of a monotone pass/fail axis.

    Parameters
    ----------
    n : number of points on the axis, cheapest first
    decide : ``index -> "pass" | "fail" | "undecided"`` (undecided counts as fail); called at
        most once per index
    verify : points above the answer re-checked for monotonicity

    Returns
    -------
    dict with ``answer`` (index or None), ``visited`` ({index: decision}) and ``violations``
    (list of ``{"pass_at", "fail_at"}`` index pairs).
    """
    visited: dict[int, str] = {}

    def ok(i: int) -> bool:
        if i not in visited:
            visited[i] = decide(i)
        return visited[i] == "pass"

    if not ok(n - 1):
        return {"answer": None, "visited": visited, "violations": violations(visited)}
    lo, hi = -1, n - 1  # lo: highest known not-pass (or -1); hi: lowest known pass
    if ok(0):
        hi = 0
    checks = verify
    while True:
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if ok(mid):
                hi = mid
            else:
                lo = mid
        top = max(i for i, d in visited.items() if d == "pass")
        unvisited = [i for i in range(hi + 1, top) if i not in visited]
        if checks <= 0 or not unvisited:
            break
        checks -= 1
        probe = min(unvisited, key=lambda i: abs(i - (hi + top) // 2))  # halfway to the top
        ok(probe)
        # a failing probe is a violation: the answer cannot be at or below it. An undecided one
        # is none (its interval allows a pass; the summary's answer rule, which counts only a
        # decided failure above a pass against it, keeps the answer where it is)
        if visited[probe] == "fail":
            lo = probe
            hi = min(i for i, d in visited.items() if i > probe and d == "pass")
    return {"answer": hi, "visited": visited, "violations": violations(visited)}


def violations(decisions: dict[int, str]) -> list[dict[str, int]]:
    """Pairs (pass at i, not-pass at j > i) along one axis: each breaks monotonicity."""
    out = []
    order = sorted(i for i, d in decisions.items() if d in ("pass", "fail"))
    for a, i in enumerate(order):
        if decisions[i] != "pass":
            continue
        for j in order[a + 1:]:
            if decisions[j] == "fail":
                out.append({"pass_at": i, "fail_at": j})
    return out


def cheapest(costs: Sequence[tuple[int, ...]], decisions: Sequence[str]) -> int | None:
    """Index of the passing point with the smallest cost (lexicographic: the first budget axis
    is the most significant), or None."""
    passing = [i for i, d in enumerate(decisions) if d == "pass"]
    return min(passing, key=lambda i: costs[i]) if passing else None


def least_value(values: Sequence[Any], statuses: Sequence[str], answer: int | None,
                floor: float | None = None) -> dict[str, Any] | None:
    """The least value of one budget axis that meets the requirement, as far as the points run
    along it (the other axes at the answer's values) can tell.

    Parameters
    ----------
    values : the axis' values, cheapest first
    statuses : each value's point status (``pass``, ``fail``, ``undecided``, ``invalid``,
        ``not_visited``)
    answer : index of the answer's value, or None (nothing meets the requirement)
    floor : the least value the key allows (its schema's range), if any

    Returns
    -------
    None without an answer; else ``{"least", "between", "resolved", "text"}``: ``between`` is
    ``[below, answer]`` where ``below`` is the value under the answer that does not meet the
    requirement (None: the cheapest value tried passes, the need may lie below it);
    ``resolved`` when nothing lies between them (consecutive integers), and then ``least`` is
    the answer's value, else None.
    """
    if answer is None:
        return None
    top = values[answer]
    if answer == 0 and floor is not None and top == floor:
        return {"least": top, "between": [None, top], "resolved": True,
                "text": f"{_fmt(top)}: the least value the key allows"}
    if answer == 0:
        return {"least": None, "between": [None, top], "resolved": False,
                "text": f"at most {_fmt(top)}: the cheapest value tried meets it, the least "
                        "value may lie below"}
    below, status = values[answer - 1], statuses[answer - 1]
    if status not in NOT_MET:  # not run (a bisection's gap) or passing below a violation
        return {"least": None, "between": [None, top], "resolved": False,
                "text": f"at most {_fmt(top)}: the value below ({_fmt(below)}) is {status}"}
    whole = all(isinstance(v, int) and not isinstance(v, bool) for v in (below, top))
    if whole and top - below == 1:
        return {"least": top, "between": [below, top], "resolved": True,
                "text": f"{_fmt(top)} ({_fmt(below)} {status})"}
    return {"least": None, "between": [below, top], "resolved": False,
            "text": f"between {_fmt(below)} ({status}) and {_fmt(top)} (pass): the grid does "
                    "not resolve it"}


def _fmt(v: Any) -> str:
    """``262144`` → ``262,144``; a float in 4 significant digits."""
    if isinstance(v, int) and not isinstance(v, bool):
        return f"{v:,}"
    return f"{v:.4g}" if isinstance(v, float) else str(v)
