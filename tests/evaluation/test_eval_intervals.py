"""Intervals, paired tests and the ground-truth columns, on hand-made episodes (no run)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from srpb_gym.cli import main
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.intervals import (
    bootstrap_median,
    holm,
    paired_rate_difference,
    wilson,
)
from srpb_gym.evaluation.paired import compare_pair, mcnemar, paired_comparisons, signed_rank
from srpb_gym.evaluation.stats import (
    COLLISION_COLUMNS,
    CSV_COLUMNS,
    GT_COLUMNS,
    PEOPLE_METRICS,
    PUSHED_BACK_LABEL,
    describe,
    read_episodes,
    summarize,
    table,
    write_episodes,
)
from srpb_gym.metrics import METRIC_NAMES

ENV = "SRPB-Corridor-v0"


def _wilson_by_hand(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return 100 * (centre - half), 100 * (centre + half)


# ---------------------------------------------------------------------------- Wilson
def test_wilson_94_of_100():
    low, high = wilson(94, 100)
    assert low == pytest.approx(87.52, abs=0.01) and high == pytest.approx(97.22, abs=0.01)
    assert (low, high) == pytest.approx(_wilson_by_hand(94, 100), abs=1e-9)


@pytest.mark.parametrize(("k", "n"), [(1, 2), (3, 7), (50, 100), (17, 20)])
def test_wilson_equals_the_formula(k, n):
    assert wilson(k, n) == pytest.approx(_wilson_by_hand(k, n), abs=1e-9)


def test_wilson_edges():
    assert wilson(0, 0) is None
    low, high = wilson(0, 6)
    assert low == 0.0 and high == pytest.approx(39.03, abs=0.01)
    low, high = wilson(6, 6)
    assert high == 100.0 and low == pytest.approx(60.97, abs=0.01)
    with pytest.raises(ValueError):
        wilson(7, 6)


# ---------------------------------------------------------------------------- bootstrap
def test_bootstrap_is_deterministic_and_holds_the_median():
    x = np.random.default_rng(5).gamma(2.0, 3.0, size=40)
    first, second = bootstrap_median(x), bootstrap_median(list(x))
    assert first == second
    low, high = first
    assert low <= np.median(x) <= high and low < high


def test_bootstrap_not_computed_and_degenerate():
    assert bootstrap_median([]) is None
    assert bootstrap_median([math.nan, math.inf]) is None
    assert bootstrap_median([3.0]) is None  # one value: no interval
    assert bootstrap_median([2.0, 2.0, 2.0]) == (2.0, 2.0)
    assert bootstrap_median([1.0, math.nan, 3.0, 2.0]) == bootstrap_median([1.0, 3.0, 2.0])


def test_describe_reports_the_interval():
    stats = describe([1.0, 2.0, 3.0, 4.0, math.nan])
    assert stats["n"] == 4 and stats["ci_low"] <= stats["median"] <= stats["ci_high"]
    none = describe([math.nan])
    assert none["n"] == 0 and none["median"] is None and none["ci_low"] is None


# ---------------------------------------------------------------------------- Newcombe
def test_paired_rate_difference():
    assert paired_rate_difference(0, 0, 0, 0) is None
    # no pair differs: the interval is not [0, 0], it is as wide as the rates' Wilson ones
    low, high = paired_rate_difference(6, 0, 0, 0)
    assert low == pytest.approx(-39.03, abs=0.01) and high == pytest.approx(39.03, abs=0.01)
    # by hand: A 3/6, B 6/6 (both 3, only B 3); phi = 0 (B's failure margin is empty)
    la, ua = (v / 100 for v in _wilson_by_hand(3, 6))
    lb = _wilson_by_hand(6, 6)[0] / 100
    low, high = paired_rate_difference(3, 0, 3, 0)
    assert low == pytest.approx(100 * (0.5 - math.sqrt((1 - lb) ** 2 + (ua - 0.5) ** 2)))
    assert high == pytest.approx(100 * (0.5 + math.sqrt((0.5 - la) ** 2)))
    # a correlated table: both 10, only A 2, only B 5, neither 3 (n = 20)
    pa, pb = 12 / 20, 15 / 20
    la, ua = (v / 100 for v in _wilson_by_hand(12, 20))
    lb, ub = (v / 100 for v in _wilson_by_hand(15, 20))
    phi = (10 * 3 - 2 * 5) / math.sqrt(12 * 8 * 15 * 5)
    d = pb - pa
    low, high = paired_rate_difference(10, 2, 5, 3)
    assert low == pytest.approx(100 * (d - math.sqrt(
        (pb - lb) ** 2 - 2 * phi * (pb - lb) * (ua - pa) + (ua - pa) ** 2)))  # fmt: skip
    assert high == pytest.approx(100 * (d + math.sqrt(
        (ub - pb) ** 2 - 2 * phi * (ub - pb) * (pa - la) + (pa - la) ** 2)))  # fmt: skip
    assert low < 100 * d < high


# ---------------------------------------------------------------------------- tests, Holm
def test_holm_by_hand():
    # sorted: 0.005 * 4 = 0.02, 0.01 * 3 = 0.03, 0.03 * 2 = 0.06, 0.04 * 1 -> max 0.06
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    # a test not computed does not count; adjusted values never exceed 1
    assert holm([0.5, None, 0.4]) == [pytest.approx(0.8), None, pytest.approx(0.8)]
    assert holm([0.9, 0.8]) == [1.0, 1.0]
    assert holm([]) == []


def test_mcnemar_and_signed_rank():
    assert mcnemar(0, 0) == 1.0
    assert mcnemar(0, 6) == pytest.approx(2 * 0.5**6)  # 0.03125
    assert mcnemar(5, 0) == pytest.approx(0.0625)
    assert signed_rank(np.array([])) is None
    assert signed_rank(np.zeros(5)) == 1.0
    assert signed_rank(np.array([1.0])) == 1.0  # one pair: reported, no crash
    assert signed_rank(np.arange(1.0, 7.0)) == pytest.approx(2 / 2**6)


# ---------------------------------------------------------------------------- episodes
def _episode(planner: str, seed: int, success: bool, psi: float, psi_gt: float,
             robot: int | None = None) -> EpisodeResult:  # fmt: skip
    metrics = dict.fromkeys(METRIC_NAMES, 1.0)
    truth = dict.fromkeys(METRIC_NAMES, 1.0)
    metrics["m_psi"], truth["m_psi"] = psi, psi_gt
    return EpisodeResult(ENV, planner, seed, success, not success, False, metrics,
                         robot=robot, scenario="corridor", ground_truth=truth)  # fmt: skip


def _runs(n: int = 10) -> list[EpisodeResult]:
    a = [_episode("a", s, s % 2 == 0, 10.0 + s, 5.0 + s) for s in range(n)]
    b = [_episode("b", s, True, 12.0 + s, 5.0 + s) for s in range(1, n + 1)]  # seed 0 missing
    return a + b


def test_pairs_tests_and_correction():
    [c] = paired_comparisons(_runs())
    assert (c["a"], c["b"], c["pairs"]) == ("a", "b", 9)
    assert c["unpaired"] == {"a": 1, "b": 1}  # a's seed 0 and b's seed 10
    tests = {t["label"]: t for t in c["tests"]}
    assert len(tests) == 1 + len(METRIC_NAMES) + len(PEOPLE_METRICS)
    success = tests["success"]
    assert (success["a_only"], success["b_only"]) == (0, 5)  # a fails on seeds 1, 3, 5, 7, 9
    assert success["difference"] == pytest.approx(100 * 5 / 9)
    assert success["p"] == pytest.approx(0.0625)
    tracked, truth = tests["m_psi (tracked)"], tests["m_psi (ground truth)"]
    assert tracked["difference"] == 2.0 and tracked["ci_low"] == tracked["ci_high"] == 2.0
    assert tracked["p"] == pytest.approx(2 / 2**9) and truth["p"] == 1.0
    assert truth["difference"] == 0.0 and tests["m_obs"]["p"] == 1.0
    # Holm over the tests of the comparison: m_psi (tracked) is the smallest of 37
    assert tracked["p_holm"] == pytest.approx(min(1.0, len(tests) * tracked["p"]))
    assert tracked["significant"] is (tracked["p_holm"] < 0.05)
    assert all(t["significant"] is False for t in c["tests"] if t["p"] == 1.0)


def test_few_pairs_and_undefined_values_do_not_crash():
    rows = [_episode("a", 0, True, 1.0, math.nan), _episode("b", 0, False, 2.0, math.nan)]
    [c] = paired_comparisons(rows)
    tests = {t["label"]: t for t in c["tests"]}
    assert c["pairs"] == 1 and tests["m_psi (tracked)"]["p"] == 1.0
    assert tests["m_psi (tracked)"]["ci_low"] is None  # one pair: no interval
    gt = tests["m_psi (ground truth)"]
    assert gt["n"] == 0 and gt["undefined"] == 1 and gt["p"] is None and gt["p_holm"] is None
    assert gt["significant"] is None
    assert compare_pair(ENV, "a", [], "b", [])["pairs"] == 0
    assert paired_comparisons(rows[:1]) == []  # one planner: nothing to compare


def test_multi_robot_pairs_are_compared_robot_by_robot():
    rows = [_episode(p, s, True, 1.0 + s, 1.0, robot=r) for p in ("a", "b") for s in range(3)
            for r in (0, 1)]  # fmt: skip
    comparisons = paired_comparisons(rows)
    assert [(c["robot"], c["pairs"]) for c in comparisons] == [(0, 3), (1, 3)]


# ---------------------------------------------------------------------------- CSV, summary
def test_ground_truth_columns_round_trip(tmp_path):
    rows = _runs(3)
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), rows)
    header = next(csv.reader(path.open()))
    assert header == list(CSV_COLUMNS)
    assert header[: 6 + len(METRIC_NAMES)] == ["env", "planner", "seed", "is_success",
                                               "collision", "timeout", *METRIC_NAMES]  # fmt: skip
    at = header.index("scenario")  # the collision attribution's columns come after it
    assert header[at + 1 :] == [*COLLISION_COLUMNS, "people_pushed_back"]
    assert header[at - len(GT_COLUMNS) : at] == list(GT_COLUMNS)
    assert GT_COLUMNS[0] == "gt_m_goal" and "gt_m_psi" in GT_COLUMNS
    back = read_episodes(str(path))
    assert [r.truth("m_psi") for r in back] == [r.truth("m_psi") for r in rows]


def test_an_older_episodes_csv_reads_as_ground_truth_not_computed(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs(3))
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if not name.startswith("gt_")]
    with path.open("w", newline="") as f:
        csv.writer(f).writerows([[r[i] for i in keep] for r in rows])
    back = read_episodes(str(path))
    assert all(math.isnan(r.truth(m)) for r in back for m in METRIC_NAMES)
    entry = summarize(back)[ENV]["a"]
    assert entry["metrics_gt"]["m_psi"]["median"] is None
    assert entry["metrics"]["m_psi"]["median"] == 11.0
    _, body = table(summarize(back)[ENV])
    labels = {r[0]: r for r in body}
    assert labels["m_psi (ground truth)"][2:] == ["n/a", "n/a"]
    assert labels["m_psi (tracked)"][2].startswith("11.0 [")
    # compare reads it too: the ground truth is n/a, the rest as before
    assert main(["compare", str(path), "--out", str(tmp_path / "merged")]) == 0
    paired = json.loads((tmp_path / "merged" / "paired.json").read_text())
    gt = next(t for t in paired["comparisons"][0]["tests"] if t["label"] == "m_psi (ground truth)")
    assert gt["n"] == 0 and gt["p"] is None


def test_summary_and_table_cells():
    summary = summarize(_runs(10))[ENV]
    a = summary["a"]
    assert a["success_rate"] == 50.0 and a["success_rate_ci"] == pytest.approx(wilson(5, 10))
    assert set(a["metrics_gt"]) == set(METRIC_NAMES)
    header, body = table(summary)
    assert header == ["metric", "unit", "a", "b"]
    labels = [r[0] for r in body]
    assert labels[:5] == ["episodes", "success", "collision", "timeout", PUSHED_BACK_LABEL]
    assert "m_psi (tracked)" in labels and "m_psi (ground truth)" in labels
    assert "m_obs" in labels and "m_obs (ground truth)" not in labels
    assert len(labels) == 5 + len(METRIC_NAMES) + len(PEOPLE_METRICS)
    low, high = wilson(5, 10)
    assert body[1][2] == f"50 [{low:.1f}-{high:.1f}]"
    m = a["metrics"]["m_psi"]
    assert body[labels.index("m_psi (tracked)")][2].startswith("14.5 [")
    assert m["ci_low"] <= m["median"] <= m["ci_high"]


def test_a_reference_planner_is_tested_against_the_others():
    [c] = paired_comparisons(_runs(), reference="b")
    assert (c["a"], c["b"]) == ("b", "a")
    tests = {t["label"]: t for t in c["tests"]}
    assert tests["m_psi (tracked)"]["difference"] == -2.0  # a minus b: the sign turns
    with pytest.raises(InputError, match="no planner 'c'") as caught:
        paired_comparisons(_runs(), reference="c")
    assert caught.value.key == "--reference"


def test_no_differing_pair_still_has_an_interval():
    # method 10 alone collapses to [0, 0] at 50/50; no pair differing bounds the
    # difference by the Wilson upper bound of 0 discordant pairs, whatever the rates
    for both, neither in ((50, 50), (100, 0), (30, 70), (0, 100)):
        low, high = paired_rate_difference(both, 0, 0, neither)
        assert low == -high and high == pytest.approx(100 * 1.959964**2 / (100 + 1.959964**2))


def test_signed_rank_is_exact_without_ties_whatever_the_zeros():
    assert signed_rank(np.array([0.0, 1, 2, 3, 4, 5])) == pytest.approx(2 / 2**5)
    assert signed_rank(np.array([0.0, 0.0])) == 1.0
