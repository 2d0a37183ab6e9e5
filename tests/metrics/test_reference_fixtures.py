"""`reference` semantics reproduces the reference SRPB tool on its own episodes.

Each fixture holds an episode as native logs and the values the reference implementation
computed for it, with both parameter presets.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.metrics import METRIC_NAMES, PRESETS, evaluate_detailed, kernels
from srpb_gym.metrics.episode import aggregate_social
from srpb_gym.metrics.io_native import read_native

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
EPISODES = sorted(p.name for p in FIXTURES.iterdir() if (p / "srpb_log").is_dir())
PRESET_FILES = {"srpb-code": "reference_code_defaults.json", "paper": "reference_paper_table3.json"}
RTOL = 1e-9


def _num(v) -> float:
    return float({"NaN": "nan", "Infinity": "inf", "-Infinity": "-inf"}.get(v, v))


def _close(a: float, b: float, rtol: float = RTOL) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b or abs(a - b) <= rtol * max(abs(a), abs(b))


def _load(name: str):
    log = FIXTURES / name / "srpb_log"
    return read_native(log / "log_robot.txt", log / "log_people.txt", log / "log_groups.txt")


def _expected(name: str, preset: str) -> dict:
    return json.loads((FIXTURES / name / PRESET_FILES[preset]).read_text())


CASES = [(e, p) for e in EPISODES for p in PRESET_FILES]


def test_fixtures_present():
    assert len(EPISODES) == 5


@pytest.mark.parametrize("preset", PRESET_FILES)
def test_presets_match_reference_parameters(preset):
    expected = _expected(EPISODES[0], preset)["params"]
    ours = PRESETS[preset].as_dict()
    shared = set(expected) & set(ours)
    assert len(shared) >= 14
    for key in shared:
        assert ours[key] == pytest.approx(expected[key], rel=1e-12), key


@pytest.mark.parametrize(("episode", "preset"), CASES)
def test_episode_metrics(episode, preset):
    expected = _expected(episode, preset)["metrics"]
    got = evaluate_detailed(_load(episode), "reference", preset).metrics
    checked = [k for k in expected if not k.startswith("m_psd")]
    assert set(checked) == set(METRIC_NAMES)
    wrong = {
        k: (got[k], _num(expected[k])) for k in checked if not _close(got[k], _num(expected[k]))
    }
    assert not wrong


def _person_keys(record, ev):
    t = record.robot_col("t")[record.people_sample]
    return {(round(float(ti), 6), record.person_label(int(i))): k
            for k, (ti, i) in enumerate(zip(t, record.people_id))}  # fmt: skip


@pytest.mark.parametrize(("episode", "preset"), CASES)
def test_person_traces(episode, preset):
    record = _load(episode)
    ev = evaluate_detailed(record, "reference", preset)
    trace = _expected(episode, preset)["person_trace"]
    rows = _person_keys(record, ev)
    assert len(trace) == record.people.shape[0]
    for entry in trace:
        k = rows[(round(float(entry["t"]), 6), str(entry["id"]))]
        assert _close(ev.psi[k], _num(entry["psi"])), entry
        assert _close(ev.dir[k], _num(entry["dir"])), entry


@pytest.mark.parametrize(("episode", "preset"), CASES)
def test_dir_factors(episode, preset):
    """The heading-disturbance value is the product of the four traced factors."""
    for entry in _expected(episode, preset)["person_trace"]:
        product = entry["dir_direction"] * entry["dir_fov"] * entry["dir_speed"] / entry["dir_dist"]
        assert _close(product, _num(entry["dir"]), 1e-9)


def _group_rows(record):
    t = record.robot_col("t")[record.group_sample]
    return {(round(float(ti), 6), record.group_label(int(g))): k
            for k, (ti, g) in enumerate(zip(t, record.group_id))}  # fmt: skip


def _fsi_with(record, ellipses, params, reference):
    """fsi of every group row for the given (G, 5) ellipses."""
    g = record.group_sample.shape[0]
    cov = [record.person_col(c) for c in ("cov_xx", "cov_xy", "cov_yx", "cov_yy")]
    sxx, sxy, syy, fsi = np.empty(g), np.empty(g), np.empty(g), np.empty(g)
    kernels.group_covariances(*cov, record.group_members, record.group_start,
                              record.group_size, reference, sxx, sxy, syy)  # fmt: skip
    e = np.ascontiguousarray(np.asarray(ellipses, dtype=float).T)
    kernels.group_terms(record.robot_col("x"), record.robot_col("y"), record.group_sample,
                        e[0], e[1], e[2], e[3], e[4], sxx, sxy, syy, fsi)  # fmt: skip
    return fsi


def _fallback(record, params, reference):
    g = record.group_sample.shape[0]
    out = np.empty((5, g))
    kernels.fallback_ellipses(
        record.person_col("x"), record.person_col("y"), record.group_members,
        record.group_start, record.group_size, params.person_occupancy_radius, reference,
        np.zeros(g, dtype=np.bool_), out[0], out[1], out[2], out[3], out[4],
    )  # fmt: skip
    return out.T


GROUP_CASES = [
    c for c in CASES if json.loads((FIXTURES / c[0] / "meta.json").read_text())["n_group_rows"]
]


@pytest.mark.parametrize(("episode", "preset"), GROUP_CASES)
def test_group_traces(episode, preset):
    """fsi for the reference's own ellipse, our fallback ellipse, and (where the reference
    fit is well posed) our ellipse and fsi."""
    record = _load(episode)
    data = _expected(episode, preset)
    ev = evaluate_detailed(record, "reference", preset)
    rows = _group_rows(record)
    trace = data["group_trace"]
    assert len(trace) == record.group_sample.shape[0]
    recorded = np.empty((len(trace), 5))
    for entry in trace:
        k = rows[(round(float(entry["t"]), 6), str(entry["id"]))]
        recorded[k] = (entry["center_x"], entry["center_y"], entry["span_x"] / 2,
                       entry["span_y"] / 2, entry["orientation"])  # fmt: skip
    fsi_recorded = _fsi_with(record, recorded, ev.params, True)
    fsi_fallback = _fsi_with(record, _fallback(record, ev.params, True), ev.params, True)
    for entry in trace:
        k = rows[(round(float(entry["t"]), 6), str(entry["id"]))]
        assert _close(fsi_recorded[k], _num(entry["fsi"])), entry
        assert _close(fsi_fallback[k], _num(entry["fsi_fallback_ellipse"])), entry
        if entry["fit_stable"]:
            assert ev.fit_taubin[k] == (entry["fit_method"] == "taubin"), entry
            assert _close(ev.fsi[k], _num(entry["fsi"])), entry
            assert np.allclose(ev.ellipses[k], recorded[k], rtol=1e-9, atol=1e-12), entry


@pytest.mark.parametrize(("episode", "preset"), GROUP_CASES)
def test_small_groups_fallback_value(episode, preset):
    """m_fsi with the fallback ellipse for groups under 5 members (the paper's ellipse
    rule), everything else as in the reference."""
    record = _load(episode)
    data = _expected(episode, preset)
    ev = evaluate_detailed(record, "reference", preset)
    ellipses = np.where((record.group_size < 5)[:, None], _fallback(record, ev.params, True),
                        ev.ellipses)  # fmt: skip
    fsi = _fsi_with(record, ellipses, ev.params, True)
    dt = np.diff(record.robot_col("t"))
    got = aggregate_social("m_fsi", fsi, record.group_sample, dt, record.n_samples,
                           ev.params.group_space_threshold, True)["m_fsi"]  # fmt: skip
    assert _close(got, _num(data["fsi_analysis"]["m_fsi_small_groups_fallback"]))


@pytest.mark.parametrize(("episode", "preset"), CASES)
def test_aggregation_entries(episode, preset):
    """Our aggregation of the reference's own entries gives the reference's values, and
    our entries have the same weights and per-sample maxima."""
    record = _load(episode)
    data = _expected(episode, preset)
    ev = evaluate_detailed(record, "reference", preset)
    t = record.robot_col("t")
    dt = np.diff(t)
    for name, values, sample in (("psi", ev.psi, record.people_sample),
                                 ("dir", ev.dir, record.people_sample)):  # fmt: skip
        entries = data["aggregation_entries"][name]
        present = np.unique(sample)
        n_expected = np.count_nonzero(present < record.n_samples - 1)
        n_expected += int(record.n_samples - 1 in present)
        assert len(entries) == n_expected
        for i, entry in enumerate(entries):
            n = present[i] if i < len(present) and present[i] < record.n_samples - 1 else None
            weight = dt[n] if n is not None else dt[-1]
            assert _close(float(entry["dt"]), float(weight))
            if n is not None:
                assert _close(max(map(_num, entry["values"])), float(values[sample == n].max()))
