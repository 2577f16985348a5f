"""Summary statistics shared by the benchmark commands: medians with their min–max over runs."""
from __future__ import annotations

import math
import statistics

__all__ = ["stats", "median_range"]


def stats(values) -> dict:
    """Median, min, max and count of the finite values (None and NaN are left out)."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {"median": math.nan, "min": math.nan, "max": math.nan, "n": 0}
    return {"median": statistics.median(v), "min": min(v), "max": max(v), "n": len(v)}


def median_range(s: dict, fmt: str) -> str:
    """``median (min–max)`` of a :func:`stats` result, formatted with ``fmt``."""
    if s["n"] == 0:
        return "not measured"
    return f"{format(s['median'], fmt)} ({format(s['min'], fmt)}–{format(s['max'], fmt)})"
