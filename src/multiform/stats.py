"""Small statistics the run reports: the Wilson score interval for a success rate."""

from __future__ import annotations

from scipy.stats import binomtest


def wilson(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for ``successes`` out of ``trials`` (SciPy's); (0, 1) without trials."""
    if trials <= 0:
        return 0.0, 1.0
    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def rate(successes: int, trials: int) -> dict[str, float | int]:
    """``{successes, trials, rate, low, high}`` with the Wilson interval."""
    lo, hi = wilson(successes, trials)
    return {"successes": successes, "trials": trials, "rate": successes / trials if trials else 0.0,
            "low": lo, "high": hi}


def evaluation_split(detail: list[dict]) -> dict[str, object]:
    """From evaluation trial records (``success``, ``self_success``, ``pushed``): the rates of pushed
    and unpushed trials (None when there are none) and how the robot's own verdict met the physical
    check (``both_success``, ``robot_only``, ``check_only``, ``both_failure``)."""
    pushed = [r for r in detail if r.get("pushed")]
    plain = [r for r in detail if not r.get("pushed")]
    count = lambda rows: rate(sum(bool(r["success"]) for r in rows), len(rows)) if rows else None  # noqa: E731
    v = {"both_success": 0, "robot_only": 0, "check_only": 0, "both_failure": 0}
    for r in detail:
        key = {(True, True): "both_success", (True, False): "robot_only", (False, True): "check_only",
               (False, False): "both_failure"}[(bool(r["self_success"]), bool(r["success"]))]
        v[key] += 1
    return {"pushed": count(pushed), "unpushed": count(plain), "verdicts": v}
