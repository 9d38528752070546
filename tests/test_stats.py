"""The statistics every reported success rate carries: Wilson intervals and the pushed/unpushed split."""

from __future__ import annotations

import math

import pytest

from multiform.stats import evaluation_split, rate, wilson


def _wilson_by_hand(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


@pytest.mark.parametrize("k, n", [(197, 200), (29, 40), (50, 100), (1, 3), (391, 416)])
def test_wilson_matches_the_formula(k, n):
    assert wilson(k, n) == pytest.approx(_wilson_by_hand(k, n), abs=1e-9)


def test_wilson_known_values_and_edges():
    assert wilson(197, 200) == pytest.approx((0.957, 0.995), abs=5e-4)    # the main job's 98.5 %
    lo, hi = wilson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-4)
    lo, hi = wilson(10, 10)
    assert hi == 1.0 and lo == pytest.approx(0.7225, abs=1e-4)
    assert wilson(0, 0) == (0.0, 1.0)
    narrow, wide = wilson(50, 100, 0.5), wilson(50, 100, 0.99)
    assert wide[0] < narrow[0] < 0.5 < narrow[1] < wide[1]


def test_rate_and_evaluation_split():
    assert rate(3, 4) == {"successes": 3, "trials": 4, "rate": 0.75, "low": wilson(3, 4)[0], "high": wilson(3, 4)[1]}
    assert rate(0, 0)["rate"] == 0.0
    detail = [{"success": True, "self_success": True, "pushed": True},
              {"success": False, "self_success": True, "pushed": True},
              {"success": True, "self_success": False, "pushed": False},
              {"success": False, "self_success": False}]
    split = evaluation_split(detail)
    assert (split["pushed"]["successes"], split["pushed"]["trials"]) == (1, 2)
    assert (split["unpushed"]["successes"], split["unpushed"]["trials"]) == (1, 2)
    assert split["verdicts"] == {"both_success": 1, "robot_only": 1, "check_only": 1, "both_failure": 1}
    assert evaluation_split([{"success": True, "self_success": True}])["pushed"] is None
