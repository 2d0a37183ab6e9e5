"""Hand-computed values of every metric, and each place where `paper` and `reference`
semantics differ (METRICS.md, "`reference` semantics")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import person, record_with, robot_rows

from srpb_gym.metrics import SRPBMetricWarning, evaluate, evaluate_detailed

PAPER, REF = "paper", "reference"


def both(record, **kw):
    return evaluate(record, PAPER, **kw), evaluate(record, REF, **kw)


# ----------------------------------------------------------------------------- task metrics
@pytest.mark.parametrize(
    ("pos", "yaw", "goal_yaw", "expected"),
    [
        ((0.1, 0.1), -math.pi + 0.05, math.pi - 0.05, 1.0),  # yaw error wraps to -0.1
        ((0.2, 0.0), 0.0, 0.0, 1.0),  # distance == tolerance counts
        ((0.15, 0.15), 0.0, 0.0, 0.0),  # 0.212 m away
        ((0.0, 0.0), 0.0, 0.25, 0.0),  # heading off by 0.25 rad
    ],
)
def test_goal(pos, yaw, goal_yaw, expected):
    rec = record_with(
        robot_rows([0, 1], x=[5, pos[0]], y=[5, pos[1]], yaw=yaw, goal=(0, 0, goal_yaw))
    )
    assert evaluate(rec)["m_goal"] == expected


def test_obstacle_time_runs():
    # close at samples 0, 3, 4 (sample 5 is the last one and has no step)
    rec = record_with(robot_rows(np.arange(6.0), obstacle_dist=[0.5, 0.6, 0.6, 0.5, 0.5, 0.6]))
    paper, ref = both(rec)
    assert paper["m_obs"] == pytest.approx(100 * 3 / 5)
    # reference: the lone sample 0 leaves its start behind; the run 3-4 closes at 5: 4 - 0
    assert ref["m_obs"] == pytest.approx(100 * 4 / 5)


def test_duration_path_heading_change():
    rec = record_with(robot_rows([0, 1, 2], x=[0, 3, 3], y=[0, 4, 4], yaw=[3.0, -3.0, -3.0]))
    paper, ref = both(rec)
    assert paper["m_mef"] == ref["m_mef"] == 2.0
    assert paper["m_plin"] == ref["m_plin"] == 5.0
    assert paper["m_chc"] == pytest.approx(2 * math.pi - 6.0)  # shortest way across +-pi
    assert ref["m_chc"] == pytest.approx(6.0)


def test_computation_time():
    rec = record_with(robot_rows([0, 1, 2], planning_time=[0.01, 0.03, 0.02]))
    for m in both(rec):
        assert m["m_cef"] == pytest.approx(20.0)
        assert m["m_cre"] == pytest.approx(math.sqrt(200 / 3))  # population std [ms]


def test_computation_time_skips_samples_without_decision():
    rec = record_with(robot_rows([0, 1, 2], planning_time=[0.01, 0.03, math.nan]))
    paper, ref = both(rec)
    assert paper["m_cef"] == pytest.approx(20.0) and paper["m_cre"] == pytest.approx(10.0)
    # the reference tool's own logs never hold a NaN; ours mark the final sample with one,
    # which both semantics skip
    assert ref["m_cef"] == pytest.approx(20.0) and ref["m_cre"] == pytest.approx(10.0)
    nothing = record_with(robot_rows([0, 1], planning_time=math.nan))
    with pytest.warns(SRPBMetricWarning, match="no planning time"):
        assert math.isnan(evaluate(nothing)["m_cef"])


def test_smoothness():
    rec = record_with(
        robot_rows([0, 0.1, 0.2], vx=[0, 0.1, 0.3], vy=[0, 0, 0.1], omega=[0, 0.2, 0.1])
    )
    for m in both(rec):
        assert m["m_vsm"] == pytest.approx((1 + math.sqrt(5)) / 2)
        assert m["m_hsm"] == pytest.approx(1.5)


def test_smoothness_zero_length_step():
    rec = record_with(robot_rows([0, 0.1, 0.1, 0.2], vx=[0, 0.1, 0.2, 0.2]))
    paper, ref = both(rec)
    assert paper["m_vsm"] == pytest.approx(0.5)  # (1 + 0) / 2 over the two real steps
    assert paper["m_hsm"] == 0.0
    assert ref["m_vsm"] == math.inf  # 0.1 / 0
    assert math.isnan(ref["m_hsm"])  # 0 / 0


def test_oscillation_tests_lateral_speed_only_in_paper():
    rec = record_with(robot_rows([0, 1], vx=0.01, vy=0.03))
    paper, ref = both(rec, osc_vel_lin_x_threshold=1.0)
    assert paper["m_osc"] == 0.0  # |vy| = 0.03 >= 0.025
    assert ref["m_osc"] == 100.0  # |vx| is compared with both thresholds


def test_backward_threshold_inclusive_in_paper():
    rec = record_with(robot_rows([0, 1], vx=-0.025))
    paper, ref = both(rec)
    assert paper["m_bwd"] == 100.0
    assert ref["m_bwd"] == 0.0


def test_rotation_in_place():
    rec = record_with(robot_rows([0, 1, 3], vx=[0.0, 0.3, 0.0], omega=[0.05, 0.05, 0.0]))
    for m in both(rec):
        assert m["m_iprot"] == pytest.approx(100 / 3)
        assert m["m_osc"] == 0.0
        assert m["m_bwd"] == 0.0


def test_share_metrics_weight_by_step_length():
    rec = record_with(robot_rows([0, 1, 4, 5], vx=[0.0, 0.3, -0.2, 0.0]))
    paper = evaluate(rec)
    assert paper["m_osc"] == pytest.approx(100 * 1 / 5)
    assert paper["m_bwd"] == pytest.approx(100 * 1 / 5)


# ----------------------------------------------------------------------------- social
def psi_of(robot_xy, p, semantics=PAPER, **kw):
    rec = record_with(robot_rows([0, 1], x=robot_xy[0], y=robot_xy[1]), {0: [(1, p)]})
    return evaluate(rec, semantics, **kw)["m_psi"] / 100


def test_psi_front_side_rear():
    # standing person at the origin facing +x: var_front 0.5, var_side 1/3, var_rear 0.25
    assert psi_of((1.0, 0.1), person(0, 0)) == pytest.approx(math.exp(-0.5 * (1 / 0.5 + 0.03)))
    assert psi_of((-1.0, 0.1), person(0, 0)) == pytest.approx(math.exp(-0.5 * (1 / 0.25 + 0.03)))


def test_psi_rear_on_both_sides():
    behind_right = (-1.0, -0.1)  # delta close to -pi
    assert psi_of(behind_right, person(0, 0)) == pytest.approx(math.exp(-0.5 * (4 + 0.03)))
    # the reference's signed test takes the front variance there
    assert psi_of(behind_right, person(0, 0), REF) == pytest.approx(math.exp(-0.5 * (2 + 0.03)))


def test_psi_speed_and_rotation():
    walking = person(0, 0, vx=0.5)  # var_front = max(2 * 0.5, 0.5) = 1
    assert psi_of((2.0, 0.0), walking) == pytest.approx(math.exp(-2.0))
    facing_y = person(0, 0, yaw=math.pi / 2)
    assert psi_of((0.0, 1.0), facing_y) == pytest.approx(math.exp(-1.0))
    assert psi_of((1.0, 0.0), facing_y) == pytest.approx(math.exp(-0.5 * 3.0))  # side


def test_psi_covariance_symmetrised_in_paper():
    p = person(0, 0, cov=(0.1, 0.08, 0.0, 0.1))
    sxx, syy = 0.5 + 0.1, 1 / 3 + 0.1
    c = 0.04  # (0.08 + 0.0) / 2
    q_paper = (syy - 2 * c + sxx) / (sxx * syy - c * c)
    q_ref = (syy - 0.08 + sxx) / (sxx * syy)  # [[xx, xy], [yx, yy]] as logged
    assert psi_of((1.0, 1.0), p) == pytest.approx(math.exp(-0.5 * q_paper))
    assert psi_of((1.0, 1.0), p, REF) == pytest.approx(math.exp(-0.5 * q_ref))


def dir_of(p, yaw=0.0, vx=0.5, semantics=PAPER, **kw):
    rec = record_with(robot_rows([0, 1], yaw=yaw, vx=vx), {0: [(1, p)]})
    return evaluate(rec, semantics, **kw)["m_dir"] / 100


def test_dir_heading_at_person():
    facing_robot = person(2.0, 0.0, yaw=math.pi)
    expected = 1.0 * 1.0 * (0.5 / 0.5) / (2.0 / (0.275 + 0.28))
    assert dir_of(facing_robot) == pytest.approx(expected)
    assert dir_of(facing_robot, vx=0.25) == pytest.approx(expected / 2)


def test_dir_ray_versus_line():
    behind = person(2.0, 0.0, yaw=math.pi)
    assert dir_of(behind, yaw=math.pi) == 0.0  # driving away: the ray misses
    assert dir_of(behind, yaw=math.pi, semantics=REF) == pytest.approx(0.555 / 2)


def test_dir_field_of_view_and_offset():
    side_on = person(2.0, 0.0, yaw=math.pi / 2)  # robot seen at delta = pi/2 from the person
    sigma = 3.3 / 4
    expected = math.exp(-((math.pi / 2) ** 2) / (2 * sigma**2)) * 0.555 / 2
    assert dir_of(side_on) == pytest.approx(expected)
    # heading 0.5 m beside the person: intersection 0.5 m off, covariance (d_ocp/2)^2 I
    offset = person(2.0, 0.5, yaw=math.pi)
    d = math.hypot(2.0, 0.5)
    phi = math.atan2(0.5, 2.0)
    t = d / math.cos(phi)
    miss = math.hypot(t - 2.0, 0.5)
    delta = math.atan2(-0.5, -2.0) - math.pi + 2 * math.pi  # wrapped into (-pi, pi]
    fov = math.exp(-(delta**2) / (2 * sigma**2))
    cc = math.exp(-0.5 * miss**2 / 0.14**2)
    assert dir_of(offset) == pytest.approx(cc * fov * 0.555 / d)


def test_dir_clipped_and_contact():
    close = person(0.3, 0.0, yaw=math.pi)
    assert dir_of(close) == 1.0
    assert dir_of(close, semantics=REF) == pytest.approx(0.555 / 0.3)
    on_top = person(0.0, 0.0, yaw=math.pi)
    assert dir_of(on_top) == 1.0
    assert dir_of(on_top, semantics=REF) == math.inf


def test_last_sample_entry():
    rec = record_with(robot_rows([0, 1, 3]), {2: [(1, person(0.5, 0.0))]})
    paper, ref = both(rec)
    expected_psi = math.exp(-0.5 * 0.25 / 0.25)  # robot behind: rear variance
    assert paper["m_psi"] == 0.0 and paper["m_psi_max"] == 0.0
    assert ref["m_psi"] == pytest.approx(100 * expected_psi)


def test_last_sample_entry_merges_previous_sample():
    near, far = person(0.5, 0.0, yaw=math.pi), person(2.0, 0.0, yaw=math.pi)
    rec = record_with(robot_rows([0, 1, 3]), {1: [(1, far)], 2: [(1, near)]})
    psi_far, psi_near = math.exp(-0.5 * 4 / 0.5), math.exp(-0.5 * 0.25 / 0.5)
    paper, ref = both(rec)
    assert paper["m_psi"] == pytest.approx(100 * psi_far)
    # reference: (2 * psi_far + 2 * max(psi_far, psi_near)) / 4, values far, far, near
    assert ref["m_psi"] == pytest.approx(100 * (psi_far + psi_near) / 2)
    assert ref["m_psi_max"] == pytest.approx(100 * psi_near)
    assert ref["m_psi_viol"] == pytest.approx(100 / 3)


def test_aggregation_takes_max_per_sample_weighted_by_dt():
    near, far = person(0.5, 0.0, yaw=math.pi), person(2.0, 0.0, yaw=math.pi)
    rec = record_with(robot_rows([0, 1, 4, 5]), {0: [(1, near), (2, far)], 2: [(2, far)]})
    psi_far, psi_near = math.exp(-0.5 * 4 / 0.5), math.exp(-0.5 * 0.25 / 0.5)
    m = evaluate(rec)
    assert m["m_psi"] == pytest.approx(100 * (1 * psi_near + 1 * psi_far) / 2)
    assert m["m_psi_min"] == pytest.approx(100 * psi_far)
    assert m["m_psi_max"] == pytest.approx(100 * psi_near)
    assert m["m_psi_viol"] == pytest.approx(100 / 3)  # 0.78 > 0.5 once of three values


def test_violation_threshold_is_strict():
    rec = record_with(robot_rows([0, 1], vx=0.5), {0: [(1, person(0.3, 0.0, yaw=math.pi))]})
    assert evaluate(rec, heading_disturbance_threshold=1.0)["m_dir_viol"] == 0.0
    assert evaluate(rec, heading_disturbance_threshold=0.99)["m_dir_viol"] == 100.0


# ----------------------------------------------------------------------------- groups
def group_record(members, robot_xy, covs=None):
    covs = covs or [(0.0, 0.0, 0.0, 0.0)] * len(members)
    people = [(i + 1, person(x, y, cov=c)) for i, ((x, y), c) in enumerate(zip(members, covs))]
    groups = [(7, list(range(len(members))))]
    return record_with(robot_rows([0, 1], x=robot_xy[0], y=robot_xy[1]), {0: people}, {0: groups})


def test_fsi_two_members_fallback():
    rec = group_record([(-0.6, 0.0), (0.6, 0.0)], (0.0, 0.5))
    # a = 0.6 along x, b = d_ocp = 0.28: S = diag(0.3^2, 0.14^2)
    ev = evaluate_detailed(rec)
    assert np.allclose(ev.ellipses[0], [0.0, 0.0, 0.6, 0.28, 0.0])
    assert ev.metrics["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * 0.25 / 0.14**2))


def test_fsi_three_members_fallback_minor_axis():
    rec = group_record([(-1.0, 0.0), (1.0, 0.0), (0.0, 0.6)], (0.5, 0.2))
    ev = evaluate_detailed(rec)
    # centre (0, 0.2); projections on the normal: -0.2, -0.2, 0.4 -> b = (0.4 + 0.2) / 2
    assert np.allclose(ev.ellipses[0], [0.0, 0.2, 1.0, 0.3, 0.0])
    assert ev.metrics["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * 0.25 / 0.25))


def test_fsi_single_member_circle():
    rec = group_record([(0.0, 0.0)], (0.3, 0.0))
    paper, ref = both(rec, person_occupancy_radius=0.5)
    assert paper["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * 0.09 / 0.25**2))
    assert ref["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * 0.09 / 0.14**2))  # 0.28 m


def test_fsi_five_members_taubin():
    angles = np.array([0.3, 1.5, 2.6, 3.9, 5.2])
    members = list(zip(1.1 * np.cos(angles) + 2.0, 0.8 * np.sin(angles) - 1.0))
    rec = group_record(members, (2.3, -0.8))
    ev = evaluate_detailed(rec)
    assert ev.fit_taubin[0]
    cx, cy, a, b, theta = ev.ellipses[0]
    assert (cx, cy) == pytest.approx((2.0, -1.0), abs=1e-9)
    assert abs(math.sin(theta)) < 1e-9 or abs(math.cos(theta)) < 1e-9
    along_x = a if abs(math.cos(theta)) > 0.5 else b
    assert sorted((a, b)) == pytest.approx([0.8, 1.1]) and along_x == pytest.approx(1.1)
    q = 0.3**2 / 0.55**2 + 0.2**2 / 0.4**2
    assert ev.metrics["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * q))


def test_fsi_group_covariance_elementwise_max():
    covs = [(0.01, 0.0, 0.0, 0.04), (0.03, 0.0, 0.0, 0.02)]
    rec = group_record([(-0.6, 0.0), (0.6, 0.0)], (0.2, 0.3), covs)
    q = 0.2**2 / (0.09 + 0.03) + 0.3**2 / (0.14**2 + 0.04)
    assert evaluate(rec)["m_fsi"] == pytest.approx(100 * math.exp(-0.5 * q))


# ----------------------------------------------------------------------------- degenerate
def test_single_sample_paper():
    rec = record_with(
        robot_rows([0.0], x=3.0, goal=(0, 0, 0), planning_time=0.02), {0: [(1, person(0, 0))]}
    )
    with pytest.warns(SRPBMetricWarning):
        m = evaluate(rec)
    assert m["m_goal"] == 0.0 and m["m_cef"] == pytest.approx(20.0) and m["m_cre"] == 0.0
    assert m["m_mef"] == m["m_plin"] == m["m_chc"] == 0.0
    assert m["m_psi"] == m["m_fsi"] == m["m_dir"] == 0.0
    for k in ("m_obs", "m_vsm", "m_hsm", "m_osc", "m_bwd", "m_iprot"):
        assert math.isnan(m[k]), k


def test_single_sample_reference():
    rec = record_with(robot_rows([0.0], x=3.0, goal=(0, 0, 0), planning_time=0.02))
    m = evaluate(rec, REF)
    assert m["m_goal"] == 1.0 and m["m_cef"] == 0.0 and math.isnan(m["m_cre"])
    for k in ("m_obs", "m_vsm", "m_hsm", "m_osc", "m_bwd", "m_iprot"):
        assert math.isnan(m[k]), k


def test_zero_duration():
    rec = record_with(robot_rows([1.0, 1.0], vx=[0.0, 0.1]), {0: [(1, person(1, 0))]})
    with pytest.warns(SRPBMetricWarning):
        m = evaluate(rec)
    for k in ("m_obs", "m_osc", "m_bwd", "m_iprot", "m_vsm", "m_hsm", "m_psi"):
        assert math.isnan(m[k]), k
    assert m["m_mef"] == 0.0
    ref = evaluate(rec, REF)
    assert math.isnan(ref["m_obs"]) and ref["m_vsm"] == math.inf


def test_no_people_and_no_samples():
    m = evaluate(record_with(robot_rows([0, 1, 2], vx=0.3)))
    for k in ("m_psi", "m_psi_min", "m_psi_max", "m_psi_viol", "m_fsi", "m_dir_viol"):
        assert m[k] == 0.0
    with pytest.raises(ValueError, match="no robot sample"):
        evaluate(record_with(np.empty((0, 12))))


def test_decreasing_time_is_an_error():
    with pytest.raises(ValueError, match=r"robot row 2: t = 0\.5 is earlier than the previous"):
        evaluate(record_with(robot_rows([0, 1, 0.5])))


def test_unknown_names_are_errors():
    rec = record_with(robot_rows([0, 1]))
    with pytest.raises(KeyError, match="unknown metric parameter 'safety'"):
        evaluate(rec, safety=0.3)
    with pytest.raises(KeyError, match="unknown preset"):
        evaluate(rec, preset="nope")
    with pytest.raises(ValueError, match="unknown semantics"):
        evaluate(rec, semantics="nope")
    with pytest.raises(ValueError, match="expected a finite number"):
        evaluate(rec, safety_distance=float("nan"))


def test_override_changes_the_value():
    rec = record_with(robot_rows([0, 1, 2], obstacle_dist=[0.5, 0.7, 0.7]))
    assert evaluate(rec)["m_obs"] == pytest.approx(50.0)
    assert evaluate(rec, safety_distance=0.8)["m_obs"] == pytest.approx(100.0)
    assert evaluate(rec, preset="srpb-code", safety_distance=0.4)["m_obs"] == 0.0


def test_a_record_with_values_that_cannot_be_right_is_not_scored():
    rows = robot_rows([0, 1, 2])
    rows[1][1] = math.nan
    with pytest.raises(ValueError, match="robot row 1: x is nan"):
        evaluate(record_with(rows, {}))
    bad = person(1.0, 0.0, cov=(-0.1, 0.0, 0.0, 0.1))
    with pytest.raises(ValueError, match="people row 0: cov_xx"):
        evaluate(record_with(robot_rows([0, 1]), {0: [(1, bad)]}))
