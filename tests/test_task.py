"""The per-robot task layer: episode ends, reward terms, observation layout, robot settings."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.errors import InputError
from srpb_gym.metrics import METRIC_NAMES, evaluate, evaluate_detailed
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.metrics.record import R
from srpb_gym.observation import ObservationBuilder, ObservationConfig
from srpb_gym.perception.tracker import Tracks
from srpb_gym.reward import (
    EVENT_TERMS,
    SHAPING_TERMS,
    SRPB_TERMS,
    TASK_TERMS,
    TERMS,
    approach_error,
    resolve_weights,
)
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.task import MetricSettings


def same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


def drive(env: gym.Env, seed: int, actions, options=None) -> tuple[dict, int, bool, bool]:
    """Run ``actions`` (a callable of the step number) to the episode's end."""
    env.reset(seed=seed, options=options)
    k = 0
    while True:
        env.unwrapped.set_planning_time(0.001)
        _, _, terminated, truncated, info = env.step(actions(k))
        k += 1
        if terminated or truncated:
            return info, k, terminated, truncated


def assert_metrics_of_record(info: dict, directory, env: gym.Env) -> None:
    stem = directory / env.unwrapped.episode_name()
    offline = evaluate(load_record(f"{stem}.npz"))
    truth = evaluate(load_record(f"{stem}_gt.npz"))
    for name in METRIC_NAMES:
        assert same(info[f"srpb/{name}"], offline[name]), name
        assert same(info[f"srpb_gt/{name}"], truth[name]), name


def spin(_k: int) -> np.ndarray:
    return np.array([0.0, 1.0], dtype=np.float32)  # rotates in place: no collision, no goal


# ------------------------------------------------------------------ episode ends
def test_time_limit_wrapper_truncation_has_the_metrics(tmp_path):
    env = gym.make("SRPB-Corridor-v0", max_episode_steps=50, record_dir=str(tmp_path))
    info, steps, terminated, truncated = drive(env, 3, spin)
    assert (steps, terminated, truncated) == (50, False, True)
    assert info["srpb/m_mef"] == pytest.approx(5.0)
    assert info["srpb/m_iprot"] > 50.0  # rotating in place: really computed, not a 0.0
    assert_metrics_of_record(info, tmp_path, env)


def test_scenario_time_limit_truncation_has_the_metrics(tmp_path):
    env = gym.make("SRPB-Crossing-v0", max_episode_steps=-1, record_dir=str(tmp_path))
    info, steps, _, truncated = drive(env, 0, spin)
    assert truncated and steps == 600 and info["srpb/m_mef"] == pytest.approx(60.0)
    assert_metrics_of_record(info, tmp_path, env)


def test_changed_control_step_truncates_with_the_metrics(tmp_path):
    with pytest.warns(UserWarning, match="max_episode_steps=1200"):
        env = gym.make("SRPB-Corridor-v0", sim={"control_dt": 0.05}, record_dir=str(tmp_path))
    info, steps, _, truncated = drive(env, 1, spin)
    assert truncated and steps == 600 and info["srpb/m_mef"] == pytest.approx(30.0)
    assert_metrics_of_record(info, tmp_path, env)
    whole = gym.make("SRPB-Corridor-v0", sim={"control_dt": 0.05}, max_episode_steps=1200)
    info, steps, _, truncated = drive(whole, 1, spin)
    assert truncated and steps == 1200 and info["srpb/m_mef"] == pytest.approx(60.0)


def test_metrics_only_on_the_last_step_and_final_info_says_the_parameters():
    env = gym.make("SRPB-Corridor-v0", max_episode_steps=4)
    _, info = env.reset(seed=0)
    for k in range(4):
        assert "srpb/m_psi" not in info and "srpb_params" not in info
        _, _, _, truncated, info = env.step(spin(k))
    assert truncated and info["srpb_semantics"] == "paper"
    assert info["srpb_params"]["robot_circumradius"] == 0.275
    assert info["srpb_params"]["robot_max_speed"] == 0.5


def test_step_before_reset_and_after_the_end_are_clear_errors():
    env = gym.make("SRPB-Corridor-v0", max_episode_steps=2).unwrapped
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        env.step(np.zeros(2, dtype=np.float32))
    env = gym.make("SRPB-Corridor-v0", max_episode_steps=2)
    drive(env, 0, spin)
    with pytest.raises(gym.error.ResetNeeded, match="ended"):
        env.unwrapped.step(np.zeros(2, dtype=np.float32))


# ------------------------------------------------------------------ reward
@pytest.mark.filterwarnings("ignore::srpb_gym.reward.RewardGameableWarning")
def test_every_reward_term_by_hand():
    weights = {t: float(i + 1) for i, t in enumerate(TERMS)}  # distinct, all non-zero
    env = gym.make("SRPB-FFormation-v0", reward_weights=weights, max_episode_steps=60)
    base = env.unwrapped
    env.reset(seed=2, options={"start": (1.0, 0.5, 0.0)})  # 0.5 m from the lower wall
    segments = [((1.0, 0.0), 12), ((0.0, 1.0), 10), ((-1.0, 0.0), 10), ((0.0, 0.0), 6),
                ((1.0, 0.5), 22)]  # fmt: skip
    actions = [a for a, n in segments for _ in range(n)]
    infos, rewards = [], []
    for k in range(60):
        _, reward, terminated, truncated, info = env.step(np.array(actions[k], np.float32))
        infos.append(info)
        rewards.append(reward)
        if terminated or truncated:
            break
    rec = base.task.record
    robot = rec.robot
    ev = evaluate_detailed(rec, "paper", base.params)
    p = base.params
    gx, gy = robot[0, R["goal_x"]], robot[0, R["goal_y"]]
    dist = np.hypot(gx - robot[:, R["x"]], gy - robot[:, R["y"]])
    for k, info in enumerate(infos):
        a, b = robot[k], robot[k + 1]
        dt = b[R["t"]] - a[R["t"]]
        vx, vy, w = a[R["vx"]], a[R["vy"]], a[R["omega"]]
        osc = (
            math.hypot(vx, vy) < p.osc_vel_lin_x_threshold
            and abs(vx) < p.osc_vel_x_threshold
            and abs(vy) < p.osc_vel_y_threshold
            and abs(w) < p.osc_vel_ang_z_threshold
        )
        iprot = (
            abs(vx) < p.stop_speed_tolerance
            and abs(vy) < p.stop_speed_tolerance
            and abs(w) >= p.osc_vel_ang_z_threshold
        )
        psi = ev.psi[rec.people_sample == k]
        dirv = ev.dir[rec.people_sample == k]
        fsi = ev.fsi[rec.group_sample == k]
        expected = {
            "progress": dist[k] - dist[k + 1],
            "success": float(info["is_success"]),
            "collision": float(info["collision"]),
            "time": dt,
            "approach": hand_approach_error(a, R) - hand_approach_error(b, R),
            "obs": dt * (a[R["obstacle_dist"]] < p.safety_distance),
            "vsm": math.hypot(b[R["vx"]] - vx, b[R["vy"]] - vy) / dt,
            "hsm": abs(b[R["omega"]] - w) / dt,
            "osc": dt * osc,
            "bwd": dt * (vx <= -p.osc_vel_x_threshold),
            "iprot": dt * iprot,
            "chc": abs(math.remainder(b[R["yaw"]] - a[R["yaw"]], 2 * math.pi)),
            "psi": dt * (psi.max() if psi.size else 0.0),
            "fsi": dt * (fsi.max() if fsi.size else 0.0),
            "dir": dt * (dirv.max() if dirv.size else 0.0),
        }
        for term in TERMS:
            assert info[f"reward_{term}"] == pytest.approx(
                weights[term] * expected[term], rel=1e-9, abs=1e-12
            ), (k, term)
        for term in SRPB_TERMS:
            assert info[f"srpb_step/{term}"] == pytest.approx(expected[term], rel=1e-9, abs=1e-12)
        assert rewards[k] == pytest.approx(sum(info[f"reward_{t}"] for t in TERMS), abs=1e-12)
    seen = {t for info in infos for t in TERMS if info[f"reward_{t}"] != 0.0}
    # the trajectory exercised every term but those of the episode's end, the O-space and
    # the last metres (test_approach_term_by_hand)
    assert seen >= set(TERMS) - {"success", "collision", "fsi", "approach"}, set(TERMS) - seen
    assert set(TASK_TERMS) < set(TERMS)


def social_steps(record, params) -> dict[str, np.ndarray]:
    """dt x the largest psi, fsi and dir of each sample of ``record`` but the last: the
    social terms of the step that starts at that sample."""
    ev = evaluate_detailed(record, "paper", params)
    t = record.robot[:, R["t"]]
    out = {}
    for term, values, owner in (("psi", ev.psi, record.people_sample),
                                ("dir", ev.dir, record.people_sample),
                                ("fsi", ev.fsi, record.group_sample)):  # fmt: skip
        out[term] = np.array([(t[k + 1] - t[k]) * max(values[owner == k], default=0.0)
                              for k in range(len(t) - 1)])  # fmt: skip
    return out


def test_reward_people_ground_truth_pays_the_true_peoples_social_terms():
    """The same drive with the tracked and with the privileged reward: the same world and
    observations, task terms equal, each one's social terms those of its own record."""
    envs = {people: gym.make("SRPB-FFormation-v0", reward_people=people, max_episode_steps=60)
            for people in ("tracked", "ground_truth")}  # fmt: skip
    steps = {}
    for people, env in envs.items():
        obs, _ = env.reset(seed=2, options={"start": (1.0, 0.5, 0.0)})
        observations, infos = [obs], []
        for k in range(60):
            obs, _, terminated, truncated, info = env.step(np.array((0.8, 0.1 * (k % 3 - 1)),
                                                                    np.float32))  # fmt: skip
            observations.append(obs)
            infos.append(info)
            if terminated or truncated:
                break
        steps[people] = (np.array(observations), infos)
    (obs_t, infos_t), (obs_g, infos_g) = steps["tracked"], steps["ground_truth"]
    np.testing.assert_array_equal(obs_t, obs_g)
    for a, b in zip(infos_t, infos_g):
        for term in TASK_TERMS:
            assert a[f"reward_{term}"] == b[f"reward_{term}"]
    for people, infos in (("tracked", infos_t), ("ground_truth", infos_g)):
        task = envs[people].unwrapped.task
        record = task.record if people == "tracked" else task.sim.robots[0].gt_record
        assert task.reward_record is record
        expected = social_steps(record, task.params)
        for term in ("psi", "fsi", "dir"):
            paid = np.array([info[f"srpb_step/{term}"] for info in infos])
            np.testing.assert_allclose(paid, expected[term], rtol=1e-9, atol=1e-12)
    psi_t = [info["srpb_step/psi"] for info in infos_t]
    psi_g = [info["srpb_step/psi"] for info in infos_g]
    assert sum(psi_g) > 0 and psi_t != psi_g  # the trackers' people are not the true ones


def test_reward_people_is_checked():
    with pytest.raises(InputError, match="tracked") as err:
        gym.make("SRPB-Corridor-v0", reward_people="truth")
    assert err.value.key == "reward_people"


def hand_approach_error(row: np.ndarray, R: dict[str, int]) -> float:
    """The approach error of one robot row: (distance from the goal's heading line + 0.5
    m/rad x heading error) x (1 - goal distance / 1.5 m), 0 from 1.5 m on."""
    gx, gy, gyaw = row[R["goal_x"]], row[R["goal_y"]], row[R["goal_yaw"]]
    dx, dy = row[R["x"]] - gx, row[R["y"]] - gy
    d = math.hypot(dx, dy)
    if d >= 1.5:
        return 0.0
    line = abs(dy * math.cos(gyaw) - dx * math.sin(gyaw))
    heading = abs(math.remainder(gyaw - row[R["yaw"]], 2 * math.pi))
    return (line + 0.5 * heading) * (1.0 - d / 1.5)


def test_approach_error_by_hand():
    assert approach_error(0.3, 0.0, 0.0, 0.0, 0.0, 0.0) == 0.0  # on the line, heading kept
    assert approach_error(0.0, 0.3, 0.2, 0.0, 0.0, 0.0) == pytest.approx((0.3 + 0.1) * 0.8)
    # the goal heading +y: the line is x = 1; 0.6 m off it, heading off by pi/2
    assert approach_error(1.6, 2.0, 0.0, 1.0, 2.0, math.pi / 2) == pytest.approx(
        (0.6 + 0.5 * math.pi / 2) * (1 - 0.6 / 1.5)
    )
    # headings across the wrap: 3.1 against -3.1 rad are 2 pi - 6.2 apart, not 6.2
    assert approach_error(0.5, 0.0, -3.1, 0.0, 0.0, 3.1) == pytest.approx(
        (0.5 * math.sin(3.1) + 0.5 * (2 * math.pi - 6.2)) * (1 - 0.5 / 1.5)
    )
    assert approach_error(3.0, 0.1, 1.0, 0.0, 0.0, 0.0) == 0.0  # beyond 1.5 m
    assert approach_error(1.5, 0.0, 3.0, 0.0, 0.0, 0.0) == 0.0


def test_approach_term_by_hand():
    """Near the goal the approach term pays the fall of the approach error, step by step;
    over the episode it telescopes to the first sample's error minus the last's."""
    env = gym.make("SRPB-Corridor-v0", reward_weights={"approach": 3.0}, max_episode_steps=40)
    env.reset(seed=0)
    gx, gy, gyaw = env.unwrapped.knowledge().goal
    c, s = math.cos(gyaw), math.sin(gyaw)
    start = (gx - 0.7 * c - 0.4 * s, gy - 0.7 * s + 0.4 * c, gyaw + 0.6)  # behind, beside
    env.reset(seed=0, options={"start": start, "people": False})
    terms = []
    for k in range(40):
        action = np.array([0.6, -0.5 if k < 8 else 0.2], np.float32)
        _, _, terminated, truncated, info = env.step(action)
        terms.append(info["reward_approach"])
        if terminated or truncated:
            break
    robot = env.unwrapped.task.record.robot
    errors = [hand_approach_error(row, R) for row in robot]
    assert errors[0] > 0.3
    for k, term in enumerate(terms):
        assert term == pytest.approx(3.0 * (errors[k] - errors[k + 1]), abs=1e-12), k
    assert sum(terms) == pytest.approx(3.0 * (errors[0] - errors[len(terms)]), abs=1e-9)
    assert sum(1 for t in terms if t > 0) > 5 and any(t < 0 for t in terms)


def test_approach_is_an_event_term_in_no_preset():
    assert "approach" in EVENT_TERMS and "approach" not in SHAPING_TERMS
    for preset in ("task", "srpb"):
        assert resolve_weights(preset)[TERMS.index("approach")] == 0.0


# ------------------------------------------------------------------ observation
def hand_tracks() -> Tracks:
    xy = np.array([[3.0, 4.0], [1.0, 2.5], [9.0, 1.0]])
    cov = np.array([[[0.04, 0.0], [0.0, 0.09]], [[0.01, 0.0], [0.0, 0.01]],
                    [[0.25, 0.0], [0.0, 0.25]]])  # fmt: skip
    n = xy.shape[0]
    return Tracks(np.arange(n), xy, np.array([[0.0, 1.0], [0.5, 0.0], [0.0, 0.0]]),
                  np.zeros(n), cov, np.zeros(n), np.zeros(n), np.ones(n, bool),
                  np.arange(n))  # fmt: skip


def test_every_index_of_the_flat_observation():
    cfg = ObservationConfig(lidar_bins=4, people=3)
    builder = ObservationBuilder(cfg, n_beams=8, range_max=10.0, v_scale=0.5, vy_scale=0.3,
                                 w_max=1.0)  # fmt: skip
    pose = np.array([1.0, 2.0, math.pi / 2])  # facing +y: robot x = world y, robot y = -x
    goal = np.array([1.0, 12.0, 0.0])
    velocity = np.array([0.25, 0.0, -0.5])
    scan = np.array([5.0, 2.0, 10.0, 10.0, 1.0, 3.0, 7.0, 0.5])
    obs = builder.build(pose, goal, velocity, scan, hand_tracks())
    assert obs.shape == (8 + 4 + 3 * 7,) and obs.dtype == np.float32
    expected = [
        10.0 / 20.0, 1.0, 0.0,  # distance / goal_scale, goal straight ahead
        math.cos(-math.pi / 2), math.sin(-math.pi / 2),  # goal yaw 0, robot yaw pi/2
        0.25 / 0.5, 0.0, -0.5 / 1.0,  # measured velocity
        2.0 / 10.0, 10.0 / 10.0, 1.0 / 10.0, 0.5 / 10.0,  # lidar: shortest of 2 beams each
        # nearest person (1, 2.5): relative world (0, 0.5) -> robot (0.5, 0); its velocity
        # (0.5, 0) minus the robot's (0, 0.25) world -> (0.5, -0.25) -> robot (-0.25, -0.5)
        0.5 / 8, 0.0, -0.25 / 2, -0.5 / 2, 0.1, 0.1, 1.0,
        # next (3, 4): relative (2, 2) -> robot (2, -2); velocity (0, 0.75) -> (0.75, 0)
        2.0 / 8, -2.0 / 8, 0.75 / 2, 0.0, 0.3, 0.2, 1.0,  # std along robot x = world y
        # third (9, 1): relative (8, -1) -> robot (-1, -8); velocity (0, -0.25) -> (-0.25, 0)
        -1.0 / 8, -1.0, -0.25 / 2, 0.0, 0.5, 0.5, 1.0,
    ]  # fmt: skip
    np.testing.assert_allclose(obs, np.array(expected, np.float32), atol=1e-6)
    dict_builder = ObservationBuilder(ObservationConfig(type="dict", lidar_bins=4, people=3),
                                      8, 10.0, 0.5, 0.3, 1.0)  # fmt: skip
    parts = dict_builder.build(pose, goal, velocity, scan, hand_tracks())
    people = np.column_stack([parts["people"], parts["people_mask"]]).ravel()
    flat = np.concatenate([parts["goal"], parts["velocity"], parts["lidar"], people])
    assert np.array_equal(flat, obs)
    assert dict_builder.space.contains(parts) and builder.space.contains(obs)


def test_empty_people_slots_are_zero_and_values_clip():
    builder = ObservationBuilder(ObservationConfig(lidar_bins=2, people=2), 4, 10.0, 0.5, 0.3,
                                 1.0)  # fmt: skip
    tracks = hand_tracks()._replace(xy=np.array([[40.0, 2.0]]), velocity=np.zeros((1, 2)),
                                    covariance=np.eye(2)[None] * 9.0, ids=np.zeros(1))  # fmt: skip
    obs = builder.build(np.zeros(3), np.array([100.0, 0.0, 0.0]), np.array([9.0, 0, 0]),
                        np.full(4, 10.0), tracks)  # fmt: skip
    assert obs[0] == 1.0 and obs[5] == 1.0  # clipped distance and speed
    # relative x, y; relative velocity (-9, 0) clipped; std 3 m clipped; present
    assert obs[8 + 2 : 8 + 2 + 7].tolist() == [1.0, 0.25, -1.0, 0.0, 1.0, 1.0, 1.0]
    assert obs[8 + 2 + 7 :].tolist() == [0.0] * 7


def test_goal_fade_by_hand():
    """Within ``goal_fade`` of the goal its bearing's cos and sin are scaled by distance /
    goal_fade (its direction kept); farther away, and with the default 0, nothing changes."""
    plain = ObservationBuilder(ObservationConfig(lidar_bins=2, people=1), 4, 10.0, 0.5, 0.3,
                               1.0)  # fmt: skip
    faded = ObservationBuilder(ObservationConfig(lidar_bins=2, people=1, goal_fade=0.5), 4,
                               10.0, 0.5, 0.3, 1.0)  # fmt: skip
    pose = np.array([1.0, 2.0, math.pi / 2])  # facing +y
    for goal, length in (((1.1, 2.0, 0.3), 0.2), ((0.7, 2.4, 0.3), 1.0), ((1.0, 2.5, 1.0), 1.0),
                         ((4.0, 7.0, 0.0), 1.0), ((1.0, 2.0, 2.0), 0.0)):  # fmt: skip
        goal = np.array(goal)
        args = (pose, goal, np.array([0.1, 0.0, 0.2]), np.linspace(1.0, 9.0, 4), hand_tracks())
        a, b = plain.build(*args), faded.build(*args)
        distance = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        assert length == pytest.approx(min(distance / 0.5, 1.0))
        np.testing.assert_allclose(b[1:3], length * a[1:3], atol=1e-7)
        assert np.array_equal(np.delete(a, [1, 2]), np.delete(b, [1, 2]))
    # the goal 0.1 m to the robot's right: a unit bearing (0, -1) at the default
    to_the_right = plain.build(pose, np.array([1.1, 2.0, 0.0]), np.zeros(3), np.ones(4),
                               hand_tracks())  # fmt: skip
    np.testing.assert_allclose(to_the_right[1:3], [0.0, -1.0], atol=1e-7)
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="goal_fade must be a distance >= 0"):
            ObservationConfig(goal_fade=bad)
    with pytest.raises(InputError, match="goal_fade"):
        gym.make("SRPB-Corridor-v0", observation={"goal_fade": -1.0})


def test_log_lidar_encoding_by_hand():
    """log(r / range_min) / log(range_max / range_min) of each sector's shortest range, the
    rest of the observation as with the linear encoding; readings below range_min read 0."""
    cfg = ObservationConfig(lidar_bins=4, people=3, lidar_encoding="log")
    builder = ObservationBuilder(cfg, 8, 10.0, 0.5, 0.3, 1.0, range_min=0.1)
    linear = ObservationBuilder(ObservationConfig(lidar_bins=4, people=3), 8, 10.0, 0.5, 0.3,
                                1.0, range_min=0.1)  # fmt: skip
    pose, goal, velocity = np.array([1.0, 2.0, 0.3]), np.array([4.0, 5.0, 0.0]), np.zeros(3)
    scan = np.array([5.0, 2.0, 10.0, 10.0, 1.0, 3.0, 7.0, 0.05])
    obs = builder.build(pose, goal, velocity, scan, hand_tracks())
    # shortest of two beams each: 2, 10, 1 and 0.05 (below range_min: read as 0.1)
    expected = [math.log(2.0 / 0.1) / math.log(100.0), 1.0, 0.5, 0.0]
    np.testing.assert_allclose(obs[8:12], expected, atol=1e-6)
    plain = linear.build(pose, goal, velocity, scan, hand_tracks())
    assert np.array_equal(np.delete(obs, range(8, 12)), np.delete(plain, range(8, 12)))
    # 2.5 cm at 0.3 m from a 25 m lidar: 0.001 linear, 0.013 logarithmic
    near = ObservationBuilder(ObservationConfig(lidar_bins=1, people=0, lidar_encoding="log"),
                              1, 25.0, 0.5, 0.3, 1.0)  # fmt: skip
    lo, hi = (near.build(pose, goal, velocity, np.array([r]), hand_tracks())[8]
              for r in (0.3, 0.325))  # fmt: skip
    assert 0.0125 < hi - lo < 0.0135
    with pytest.raises(ValueError, match="lidar_encoding must be one of"):
        ObservationConfig(lidar_encoding="sqrt")


def pair_tracks(centre=(5.0, 0.0), half=1.25, axis=math.pi / 2, speed=0.0, age=2.0,
                var=0.01) -> Tracks:  # fmt: skip
    """Two tracks ``2 half`` m apart along ``axis`` around ``centre``, standing (or walking
    at ``speed`` along the axis), tracked for ``age`` s, covariance ``var`` I."""
    d = half * np.array([math.cos(axis), math.sin(axis)])
    xy = np.array([np.add(centre, -d), np.add(centre, d)])
    vel = np.tile(speed * d / half, (2, 1))
    return Tracks(np.arange(2), xy, vel, np.zeros(2), np.tile(var * np.eye(2), (2, 1, 1)),
                  np.full(2, age), np.zeros(2), np.ones(2, bool), np.arange(2))  # fmt: skip


def groups_builder(level=0.01, n_beams=9, fov=math.pi / 2, **kwargs) -> ObservationBuilder:
    """A builder whose lidar sectors are single beams, ``fov`` wide, 20 m."""
    cfg = ObservationConfig(lidar_bins=n_beams, people=0, lidar_groups=level, **kwargs)
    angles = np.linspace(-fov / 2, fov / 2, n_beams)
    return ObservationBuilder(cfg, n_beams, 20.0, 0.5, 0.0, 1.0, angles=angles)


def test_o_space_contour_in_the_lidar_by_hand():
    """A standing pair 2.5 m apart across the robot's way, 5 m ahead: the beam straight
    ahead reads the distance to the contour where the pair's O-space Gaussian (the fsi
    metric's: semi-axes a = 1.25 m along the pair, b = d_ocp = 0.28 m across it, standard
    deviations a/2 and b/2, plus the members' covariance) falls to the level."""
    builder, level = groups_builder(), 0.01
    pose, goal, vel = np.array([0.0, 0.0, 0.0]), np.array([10.0, 0.0, 0.0]), np.zeros(3)
    scan = np.full(9, 20.0)
    obs = builder.build(pose, goal, vel, scan, pair_tracks())
    radius = math.sqrt(-2.0 * math.log(level))
    ahead = 5.0 - radius * math.sqrt(0.14**2 + 0.01)  # across the pair: b/2 and 0.01 m^2
    assert obs[8 + 4] == pytest.approx(ahead / 20.0, abs=1e-6)
    # the next beam to the left (11.25 degrees): solve for the contour by bisection
    theta, var_x, var_y = math.pi / 16, 0.14**2 + 0.01, 0.625**2 + 0.01
    q = lambda t: ((t * math.cos(theta) - 5.0) ** 2 / var_x  # noqa: E731
                   + (t * math.sin(theta)) ** 2 / var_y - radius**2)  # fmt: skip
    lo, hi = 0.0, 5.0 / math.cos(theta)  # outside at 0, inside at the centre's abscissa
    for _ in range(60):
        lo, hi = (lo, 0.5 * (lo + hi)) if q(0.5 * (lo + hi)) < 0 else (0.5 * (lo + hi), hi)
    assert obs[8 + 5] == pytest.approx(lo / 20.0, abs=1e-6)
    assert obs[8] == obs[8 + 8] == 1.0  # the beams at +-45 degrees pass the contour
    # a nearer wall stays; the physical scan is not changed
    scan[4] = 2.0
    assert builder.build(pose, goal, vel, scan, pair_tracks())[8 + 4] == pytest.approx(0.1)
    assert scan[4] == 2.0 and scan[0] == 20.0
    # no contour: level 0, walking or newly tracked members, members farther apart than
    # group_distance, or the robot inside the contour
    plain = ObservationBuilder(ObservationConfig(lidar_bins=9, people=0), 9, 20.0, 0.5, 0.0,
                               1.0)  # fmt: skip
    free = plain.build(pose, goal, vel, np.full(9, 20.0), pair_tracks())
    assert (free[8:] == 1.0).all()
    for tracks, b in ((pair_tracks(speed=0.5), builder), (pair_tracks(age=0.5), builder),
                      (pair_tracks(), groups_builder(group_distance=2.0)),
                      (pair_tracks(centre=(0.1, 0.0)), builder)):  # fmt: skip
        assert np.array_equal(b.build(pose, goal, vel, np.full(9, 20.0), tracks), free)


def test_o_space_contour_is_invariant_to_the_frame():
    """Moving and turning the robot, the pair and the goal together changes nothing."""
    builder = groups_builder(n_beams=31, fov=math.pi)
    pose, goal, scan = np.array([0.0, 0.0, 0.2]), np.array([10.0, 0.0, 0.0]), np.full(31, 20.0)
    base = builder.build(pose, goal, np.zeros(3), scan, pair_tracks(axis=1.3))
    assert (base[8:] < 1.0).sum() >= 3  # the contour is in view
    shift, turn = np.array([3.0, -7.0]), 2.1
    c, s = math.cos(turn), math.sin(turn)
    rot = lambda p: np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]]) + shift  # noqa: E731
    moved = builder.build(np.array([*rot(pose[:2]), pose[2] + turn]),
                          np.array([*rot(goal[:2]), turn]), np.zeros(3), scan,
                          pair_tracks(centre=rot((5.0, 0.0)), axis=1.3 + turn))  # fmt: skip
    np.testing.assert_allclose(moved, base, atol=1e-5)


def test_lidar_groups_settings_are_checked():
    for bad in (-0.1, 1.0, 2.0):
        with pytest.raises(ValueError, match=r"lidar_groups must be in \[0, 1\)"):
            ObservationConfig(lidar_groups=bad)
    with pytest.raises(ValueError, match="group_distance must be > 0"):
        ObservationConfig(group_distance=0.0)
    with pytest.raises(ValueError, match="needs the lidar's beam angles"):
        ObservationBuilder(ObservationConfig(lidar_groups=0.01), 181, 25.0, 0.5, 0.0, 1.0)


# ------------------------------------------------------------------ robot settings
def test_robot_settings_drive_the_metric_parameters():
    big = RobotConfig(radius=0.45, v_max=0.8)
    settings = MetricSettings.build(None, big, goal_tolerance=0.3)
    assert settings.params.robot_circumradius == 0.45
    assert settings.params.robot_max_speed == 0.8
    assert settings.params.goal_tolerance_xy == 0.3
    explicit = MetricSettings.build({"params": {"robot_circumradius": 0.3}}, big, 0.3)
    assert explicit.params.robot_circumradius == 0.3  # set explicitly: wins
    preset = MetricSettings.build({"preset": "srpb-code"}, RobotConfig(), 0.2)
    assert preset.params.robot_max_speed == 0.5 and preset.params.person_fov > 3.31
    holonomic = RobotConfig(kinematics="holonomic")
    assert holonomic.max_speed == pytest.approx(math.hypot(0.5, 0.3))


@pytest.mark.parametrize(
    ("metrics", "key"),
    [
        ("paper", "metrics"),
        ({"semantic": "paper"}, "metrics.semantic"),
        ({"semantics": "other"}, "metrics.semantics"),
        ({"params": [1, 2]}, "metrics.params"),
        ({"params": {"safety": 1.0}}, "metrics"),
    ],
)
def test_metric_settings_errors_name_the_key(metrics, key):
    with pytest.raises(ValueError, match=f"^{key}"):
        gym.make("SRPB-Corridor-v0", metrics=metrics)


def test_a_bigger_robot_is_bigger_everywhere():
    env = gym.make("SRPB-Corridor-v0", robot={"radius": 0.45}, max_episode_steps=40)
    base = env.unwrapped
    assert base.params.robot_circumradius == 0.45
    assert base.sim.robot_config.radius == 0.45
    for seed in range(5):
        env.reset(seed=seed)
        x, y, _ = base.sim.world.robot_pose[0]
        walls = base.sim.walls
        assert _distance_to_walls(x, y, walls) >= 0.45  # placed for its size
    # the metric's circumradius (m_dir's distance scale) is the robot's
    small = gym.make("SRPB-Crowd-v0", max_episode_steps=80)
    large = gym.make("SRPB-Crowd-v0", max_episode_steps=80, metrics={
        "params": {"robot_circumradius": 0.45}})  # fmt: skip
    forward = lambda k: np.array([0.6, 0.0], np.float32)  # noqa: E731
    info_s = drive(small, 4, forward)[0]
    info_l = drive(large, 4, forward)[0]
    assert info_l["srpb_params"]["robot_circumradius"] == 0.45
    assert info_l["srpb/m_psi"] == info_s["srpb/m_psi"]  # the same episode...
    assert info_l["srpb/m_dir"] > info_s["srpb/m_dir"] > 0.0  # ...scored for a bigger robot


def test_a_bigger_robot_collides_sooner():
    def steps_to_wall(radius: float) -> int:
        env = gym.make("SRPB-Corridor-v0", robot={"radius": radius}, max_episode_steps=200)
        env.reset(seed=0, options={"people": False, "start": (2.0, 1.1, math.pi / 2)})
        for k in range(200):
            *_, info = env.step(np.array([1.0, 0.0], np.float32))
            if info["collision"]:
                return k
        raise AssertionError("no collision")

    assert steps_to_wall(0.45) < steps_to_wall(0.275)


def _distance_to_walls(x: float, y: float, walls: np.ndarray) -> float:
    a, b = walls[:, :2], walls[:, 2:]
    d = b - a
    t = np.clip(((np.array([x, y]) - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-12), 0, 1)
    closest = a + t[:, None] * d
    return float(np.hypot(*(closest - [x, y]).T).min())


def test_no_warnings_on_a_plain_episode():
    env = gym.make("SRPB-Corridor-v0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        drive(env, 0, lambda k: np.array([1.0, 0.0], np.float32))


@pytest.mark.parametrize("semantics", ["paper", "reference"])
def test_o_space_term_equals_the_metric_code(semantics):
    """fsi per step (fallback ellipses in a compiled path, Taubin's fit in the metric
    code's) equals dt x the largest per-group value of the episode evaluation."""
    env = gym.make(
        "SRPB-FFormation-v0",
        metrics={"semantics": semantics},
        max_episode_steps=400,
        sensors={"detector": "lidar"},
    )  # sees all around: the pair stays tracked
    base = env.unwrapped
    env.reset(seed=0, options={"start": (6.0, 2.4, 0.0)})  # facing the pair, 2.6 m away
    infos = []
    for _ in range(400):
        *_, terminated, truncated, info = env.step(np.array([0.4, 0.0], np.float32))
        infos.append(info)
        if terminated or truncated:
            break
    rec = base.task.record
    ev = evaluate_detailed(rec, semantics, base.params)
    t = rec.robot_col("t")
    nonzero = 0
    for k, info in enumerate(infos):
        fsi = ev.fsi[rec.group_sample == k]
        expected = (t[k + 1] - t[k]) * (fsi.max() if fsi.size else 0.0)
        assert info["srpb_step/fsi"] == pytest.approx(expected, rel=1e-12, abs=1e-15), k
        nonzero += expected > 1e-6
    assert nonzero > 5  # the robot drove into the O-space


def test_planning_time_overrides_never_leak():
    env = gym.make("SRPB-Corridor-v0", max_episode_steps=3).unwrapped
    env.reset(seed=0)
    env.set_planning_time(7.0)
    env.reset(seed=0)  # a new episode: the override is gone
    env.step(np.zeros(2, np.float32))
    assert env.task.record.robot_col("planning_time")[0] != 7.0
    env.set_planning_time(np.float32(0.25))  # numpy scalars are fine
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([math.nan, 0.0], np.float32))  # a bad action consumes nothing
    env.step(np.zeros(2, np.float32))
    assert env.task.record.robot_col("planning_time")[1] == 0.25
    for bad in (True, -1.0, math.inf, "1"):
        with pytest.raises(ValueError, match="planning time"):
            env.set_planning_time(bad)


def test_bad_reset_options_leave_the_env_as_it_was():
    env = gym.make("SRPB-Crowd-v0").unwrapped
    env.reset(seed=4)
    state = env.np_random.bit_generator.state
    name = env.episode_name()
    for options in ({"people": "false"}, {"start": (math.nan, 0, 0)}, {"goal": (0.0, 0.0, 0.0)}):
        with pytest.raises(ValueError, match="options"):
            env.reset(seed=9, options=options)
        assert env.np_random.bit_generator.state == state and env.episode_name() == name
    env.step(np.zeros(2, np.float32))  # the episode goes on
    assert env.reset(seed=4, options={"people": False})[0].shape == env.observation_space.shape


def test_reference_semantics_time_the_planner():
    env = gym.make("SRPB-Corridor-v0", metrics={"semantics": "reference"}, max_episode_steps=5)
    info, *_ = drive(env, 0, spin)
    assert info["srpb/m_cef"] == pytest.approx(1.0) and info["srpb_gt/m_cre"] == 0.0
