"""Paired comparisons of planners: the same episodes, planner B against planner A.

Episodes are paired by (scenario, seed) within one environment: the same seed gives both
planners the same start, goal and people, so their differences measure the planner, not
the draw. In a multi-robot run the pairs are of the same robot (index) of the same episode,
and each robot is compared on its own: the robots of one episode share it, so pooled pairs
would not be independent. Every planner is compared with the first of its environment
(``B minus A``, A the first), on:

* success: the difference of the success rates over the pairs [percentage points] with
  Newcombe's paired score 95 % interval, and the exact McNemar test (a two-sided binomial
  test of the discordant pairs, ``scipy.stats.binomtest``);
* every metric, tracked and (those computed from the people) from ground truth, over the
  pairs where both values are defined: the median of the differences with its percentile
  bootstrap 95 % interval (:mod:`~srpb_gym.evaluation.intervals`), and the Wilcoxon
  signed-rank test (``scipy.stats.wilcoxon``; zero differences left out, all of them zero:
  p = 1);
* Holm's correction over the tests of one comparison; a difference is significant when its
  corrected p-value is below :data:`ALPHA`.

Episodes without a partner are left out and counted. With fewer than
:data:`MIN_DIFFERING` pairs that differ no test here can reach p < 0.05.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.evaluation import stats
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.intervals import bootstrap_median, holm, paired_rate_difference
from srpb_gym.evaluation.outdir import write_json
from srpb_gym.metrics import METRIC_UNITS

ALPHA = 0.05
#: pairs up to which the signed-rank test is exact (every sign assignment enumerated)
EXACT_PAIRS = 16
MIN_DIFFERING = 6
"""Pairs that differ below which neither test can reach p < 0.05 (two-sided, exact: the
smallest p of 5 pairs is 2 / 2^5 = 0.0625)."""
METHOD = {
    "pairs": "each planner against the first of its environment (B minus A), episodes "
    "paired by (scenario, seed), and in a multi-robot run by robot: each robot compared on "
    "its own",
    "difference": "median of the paired differences with its percentile bootstrap 95 % "
    "interval (10000 resamples of the pairs, numpy default_rng(0)); success: difference of "
    "the rates over the pairs, percentage points, with Newcombe's paired score 95 % interval "
    "(method 10)",
    "test": "Wilcoxon signed-rank (zero differences left out; all zero: p = 1; exact up to "
    "16 pairs, ties with average ranks, else the normal approximation); success: "
    "exact McNemar (two-sided binomial test of the discordant pairs)",
    "correction": "Holm, over the tests of one comparison",
    "alpha": ALPHA,
}


# ---------------------------------------------------------------------------- tests
def mcnemar(a_only: int, b_only: int) -> float:
    """The exact McNemar p-value (two-sided) of ``a_only`` pairs where only A succeeded and
    ``b_only`` where only B did; 1 when none differ."""
    from scipy.stats import binomtest

    n = a_only + b_only
    return 1.0 if n == 0 else float(binomtest(b_only, n, 0.5).pvalue)


def signed_rank(differences: np.ndarray) -> float | None:
    """The Wilcoxon signed-rank p-value (two-sided) of the paired ``differences``; 1 when
    every one is zero, ``None`` (not computed) without any."""
    from scipy.stats import rankdata, wilcoxon

    if differences.size == 0:
        return None
    nonzero = differences[differences != 0]
    if nonzero.size == 0:
        return 1.0
    # zeros left out here and the method fixed, so that every supported scipy gives the
    # same p: up to EXACT_PAIRS pairs the exact distribution over every sign assignment
    # (ties keep their average ranks), else the normal approximation
    if nonzero.size <= EXACT_PAIRS:
        ranks = rankdata(np.abs(nonzero))
        signs = (np.arange(2**nonzero.size)[:, None] >> np.arange(nonzero.size)) & 1
        null = signs @ ranks  # the positive rank sum of every assignment
        centre = ranks.sum() / 2.0
        observed = abs(float(ranks[nonzero > 0].sum()) - centre)
        return float(np.mean(np.abs(null - centre) >= observed - 1e-9))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = float(wilcoxon(nonzero, method="approx").pvalue)
    return p if math.isfinite(p) else None


def _test_success(a: list[EpisodeResult], b: list[EpisodeResult]) -> dict[str, Any]:
    sa = np.array([r.is_success for r in a], dtype=np.float64)
    sb = np.array([r.is_success for r in b], dtype=np.float64)
    a_only, b_only = int(np.sum((sa == 1) & (sb == 0))), int(np.sum((sa == 0) & (sb == 1)))
    n = sa.size
    both = int(np.sum((sa == 1) & (sb == 1)))
    ci = paired_rate_difference(both, a_only, b_only, n - both - a_only - b_only)
    return {"metric": "success", "label": "success", "ground_truth": False, "unit": "%",
            "n": n, "differing": a_only + b_only,
            "a": 100.0 * sa.mean() if n else None, "b": 100.0 * sb.mean() if n else None,
            "difference": 100.0 * (sb.mean() - sa.mean()) if n else None,
            "ci_low": ci[0] if ci else None, "ci_high": ci[1] if ci else None,
            "test": "McNemar", "a_only": a_only, "b_only": b_only,
            "p": mcnemar(a_only, b_only) if n else None}  # fmt: skip


def _test_metric(
    a: list[EpisodeResult], b: list[EpisodeResult], label: str, metric: str, gt: bool
) -> dict[str, Any]:
    va = np.array([r.value(metric, gt) for r in a], dtype=np.float64)
    vb = np.array([r.value(metric, gt) for r in b], dtype=np.float64)
    both = np.isfinite(va) & np.isfinite(vb)
    va, vb = va[both], vb[both]
    d = vb - va
    ci = bootstrap_median(d)
    n = int(d.size)
    return {"metric": metric, "label": label, "ground_truth": gt, "unit": METRIC_UNITS[metric],
            "n": n, "undefined": int(both.size - n), "differing": int(np.count_nonzero(d)),
            "a": float(np.median(va)) if n else None, "b": float(np.median(vb)) if n else None,
            "difference": float(np.median(d)) if n else None,
            "ci_low": ci[0] if ci else None, "ci_high": ci[1] if ci else None,
            "test": "Wilcoxon", "p": signed_rank(d)}  # fmt: skip


def compare_pair(
    env: str, a: str, a_rows: Sequence[EpisodeResult], b: str, b_rows: Sequence[EpisodeResult],
    robot: int | None = None,
) -> dict[str, Any]:  # fmt: skip
    """The paired comparison of planner ``b`` against ``a`` (rows of one environment and,
    with ``robot``, of that robot): the pairs, the episodes left out, and every test with
    its Holm-corrected p-value and whether it is significant."""
    by_a = {(r.scenario, r.seed): r for r in a_rows}
    by_b = {(r.scenario, r.seed): r for r in b_rows}
    common = [k for k in by_a if k in by_b]
    pa, pb = [by_a[k] for k in common], [by_b[k] for k in common]
    tests = [_test_success(pa, pb)]
    tests += [_test_metric(pa, pb, label, m, gt) for label, m, gt in stats.metric_rows()]
    for test, adjusted in zip(tests, holm([t["p"] for t in tests])):
        test["p_holm"] = adjusted
        test["significant"] = None if adjusted is None else bool(adjusted < ALPHA)
    return {"env": env, "robot": robot, "a": a, "b": b, "pairs": len(common),
            "unpaired": {"a": len(by_a) - len(common), "b": len(by_b) - len(common)},
            "tests": tests}  # fmt: skip


def paired_comparisons(
    results: Iterable[EpisodeResult], reference: str | None = None
) -> list[dict[str, Any]]:
    """Every planner against the first of its environment, or against ``reference`` where
    an environment has it (each robot on its own in a multi-robot run): one
    :func:`compare_pair` each; none with one planner. A ``reference`` no environment has
    is an :class:`~srpb_gym.errors.InputError` naming ``--reference``."""
    out = []
    grouped = stats.group(results)
    if reference is not None and not any(reference in p for p in grouped.values()):
        names = sorted({name for p in grouped.values() for name in p})
        raise InputError(f"no planner {reference!r} in the runs; choose one of: "
                         f"{', '.join(names)}", key="--reference")  # fmt: skip
    for env, planners in grouped.items():
        robots = list(dict.fromkeys(r.robot for rows in planners.values() for r in rows))
        for robot in sorted(robots, key=lambda r: -1 if r is None else r):
            cols = {p: [r for r in rows if r.robot == robot] for p, rows in planners.items()}
            names = [p for p, rows in cols.items() if rows]
            if reference in names:
                names.remove(reference)
                names.insert(0, reference)
            out += [compare_pair(env, names[0], cols[names[0]], b, cols[b], robot)
                    for b in names[1:]]  # fmt: skip
    return out


def paired_doc(comparisons: list[dict[str, Any]]) -> dict[str, Any]:
    """The content of ``paired.json``."""
    return {"method": METHOD, "comparisons": comparisons}


# ---------------------------------------------------------------------------- text
def p_value(p: float | None) -> str:
    """``0.031``, ``<0.001``, ``n/a``."""
    return "n/a" if p is None else ("<0.001" if p < 0.001 else f"{p:.3f}")


def signed(value: float | None, fmt: Any = stats.number) -> str:
    """A difference with its sign: ``+2.1``, ``-0.5``, ``0``."""
    if value is None:
        return "n/a"
    return f"+{fmt(value)}" if value > 0 else fmt(value)


def _row(test: dict[str, Any]) -> list[str]:
    fmt = stats.rate if test["metric"] == "success" else stats.number
    a = "n/a" if test["a"] is None else fmt(test["a"])
    b = "n/a" if test["b"] is None else fmt(test["b"])
    ci = stats.interval(test["ci_low"], test["ci_high"], fmt=fmt)
    mark = "*" if test["significant"] else ""
    diff = f"{signed(test['difference'], fmt)} {ci}" if test["difference"] is not None else "n/a"
    return [test["label"], test["unit"], str(test["n"]), a, b, diff, test["test"],
            p_value(test["p"]), p_value(test["p_holm"]), mark]  # fmt: skip


def _title(c: dict[str, Any]) -> str:
    robot = "" if c["robot"] is None else f", robot {c['robot']}"
    return f"{c['env']}{robot}: {c['b']} minus {c['a']}"


def _subtitle(c: dict[str, Any]) -> str:
    by = "scenario, seed" + ("" if c["robot"] is None else ", robot")
    left = c["unpaired"]
    tested = sum(t["p"] is not None for t in c["tests"])
    significant = sum(bool(t["significant"]) for t in c["tests"])
    few = ""
    if c["pairs"] < MIN_DIFFERING:
        few = f"; fewer than {MIN_DIFFERING} pairs: no test can reach p < {ALPHA}"
    pairs = f"{c['pairs']} pair{'' if c['pairs'] == 1 else 's'}"
    return (f"{pairs} by ({by}); episodes without a partner, left out: {left['a']} of "
            f"{c['a']}, {left['b']} of {c['b']}; {significant} of {tested} tests significant "
            f"after Holm's correction{few}")  # fmt: skip


HEADER = ["metric", "unit", "pairs", "A", "B", "B-A [95 % CI]", "test", "p", "p (Holm)", "sig."]
LEGEND = (
    "A, B: median over the pairs (success: rate, %); B-A: median of the paired differences "
    "[percentile bootstrap 95 % CI] (success: difference of the rates, points [Newcombe's "
    "paired score 95 % CI]); p: Wilcoxon "
    "signed-rank, success: exact McNemar; p (Holm): corrected over the tests of one "
    f"comparison; sig. *: below {ALPHA} after correction"
)


def _header(c: dict[str, Any]) -> list[str]:
    return [*HEADER[:3], f"A: {c['a']}", f"B: {c['b']}", *HEADER[5:]]


def paired_text(comparisons: list[dict[str, Any]]) -> str:
    """The comparisons as aligned text tables, after a legend; empty without any."""
    if not comparisons:
        return ""
    parts = [f"Paired comparisons. {LEGEND}."]
    parts += [stats.format_text(f"{_title(c)}\n{_subtitle(c)}", _header(c),
                                [_row(t) for t in c["tests"]]) for c in comparisons]  # fmt: skip
    return "\n\n".join(parts)


def paired_markdown(comparisons: list[dict[str, Any]]) -> str:
    """``paired.md``: the comparisons as Markdown tables."""
    parts = ["# Paired comparisons", "", f"{LEGEND}.", ""]
    for c in comparisons:
        table = stats.format_markdown(_title(c), _header(c), [_row(t) for t in c["tests"]])
        head, _, rest = table.partition("\n\n")
        parts += [head, "", _subtitle(c) + ".", "", rest]
    return "\n".join(parts)


def write_paired(comparisons: list[dict[str, Any]], out: str) -> list[str]:
    """Write ``paired.json`` and ``paired.md`` into ``out`` (nothing without a comparison);
    returns the paths."""
    if not comparisons:
        return []
    paths = [os.path.join(out, "paired.json"), os.path.join(out, "paired.md")]
    write_json(paths[0], paired_doc(comparisons))
    with open(paths[1], "w", encoding="utf-8") as f:
        f.write(paired_markdown(comparisons))
    return paths
