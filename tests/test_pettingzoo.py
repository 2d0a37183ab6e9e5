"""The PettingZoo multi-robot environment: API conformance, equivalence with the Gymnasium
environment, agents leaving, robots being real to each other."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test

import srpb_gym
from srpb_gym.metrics import METRIC_NAMES, evaluate
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.pettingzoo_env import SRPBParallelEnv, env, parallel_env, raw_env
from srpb_gym.registration import SCENARIO_IDS

SCENARIOS = list(SCENARIO_IDS.values())


def quiet(fn, *args, **kwargs):
    """PettingZoo's tests pass a reset option of their own, which the env warns about."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="options.options")
        return fn(*args, **kwargs)


@pytest.mark.parametrize("n_robots", [2, 3])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_pettingzoo_conformance(scenario, n_robots):
    make = lambda: parallel_env(scenario=scenario, n_robots=n_robots, max_steps=60)  # noqa: E731
    quiet(parallel_api_test, make(), num_cycles=80)
    quiet(parallel_seed_test, make)
    quiet(api_test, env(scenario=scenario, n_robots=n_robots, max_steps=30), num_cycles=40)
    rendered = parallel_env(scenario=scenario, n_robots=n_robots, max_steps=5,
                            render_mode="rgb_array")  # fmt: skip
    quiet(
        render_test,
        lambda render_mode: raw_env(
            scenario=scenario, n_robots=n_robots, max_steps=5, render_mode=render_mode
        ),
    )
    rendered.reset(seed=0)
    frame = rendered.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8


def test_package_level_functions():
    par = srpb_gym.parallel_env(scenario="corridor", n_robots=2)
    assert isinstance(par, SRPBParallelEnv) and par.possible_agents == ["robot_0", "robot_1"]
    aec = srpb_gym.aec_env(scenario="corridor", n_robots=2)
    aec.reset(seed=0)
    assert aec.agent_selection == "robot_0"


def test_spaces_equal_the_gymnasium_envs():
    single = gym.make("SRPB-Crowd-v0", observation="dict")
    par = parallel_env(scenario="crowd", n_robots=3, observation="dict")
    for agent in par.possible_agents:
        assert par.observation_space(agent) == single.observation_space
        assert par.action_space(agent) == single.action_space
        assert par.observation_space(agent) is par.observation_space(agent)
    assert par.observation_config == single.unwrapped.observation_config
    assert par.observation_config.type == "dict"


@pytest.mark.parametrize("scenario", ["crowd", "fformation"])
def test_one_robot_reproduces_the_gymnasium_env(scenario):
    single = gym.make(f"srpb_gym:{_id(scenario)}")
    par = parallel_env(scenario=scenario, n_robots=1)
    o1, i1 = single.reset(seed=3)
    o2, i2 = par.reset(seed=3)
    assert np.array_equal(o1, o2["robot_0"]) and i1 == i2["robot_0"]
    rng = np.random.default_rng(0)
    for _ in range(2000):
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        single.unwrapped.set_planning_time(0.001)
        par.set_planning_time(0.001)
        o1, r1, te1, tr1, i1 = single.step(action)
        o2, r2, te2, tr2, i2 = par.step({"robot_0": action})
        assert np.array_equal(o1, o2["robot_0"]) and r1 == r2["robot_0"]
        assert (te1, tr1) == (te2["robot_0"], tr2["robot_0"])
        assert _same(i1, i2["robot_0"])
        if te1 or tr1:
            assert "srpb/m_psi" in i1 and par.agents == []
            return
    raise AssertionError("the episode did not end")


def test_agents_leave_with_their_metrics_and_the_rest_go_on(tmp_path):
    par = parallel_env(scenario="corridor", n_robots=2, record_dir=str(tmp_path),
                       sensors={"detector": "lidar"})  # fmt: skip
    par.reset(seed=0, options={"people": False})
    # robot_1 turns to the side wall and drives into it; robot_0 drives to its goal
    left: dict[str, dict] = {}
    for _ in range(600):
        actions = {}
        for agent in par.agents:
            k = par.knowledge(agent)
            actions[agent] = _into_side_wall(k) if agent == "robot_1" else _go_to_goal(k)
        _, _, terms, truncs, infos = par.step(actions)
        for agent in list(infos):
            if terms[agent] or truncs[agent]:
                left[agent] = infos[agent]
        if not par.agents:
            break
    assert set(left) == {"robot_0", "robot_1"}
    assert left["robot_0"]["is_success"] and not left["robot_0"]["collision"]
    assert left["robot_1"]["collision"] and not left["robot_1"]["is_success"]
    assert left["robot_1"]["t"] < left["robot_0"]["t"]  # it left first; robot_0 went on
    for agent, info in left.items():
        r = int(agent[-1])
        stem = tmp_path / par.episode_name(r)
        offline = evaluate(load_record(f"{stem}.npz"))
        for name in METRIC_NAMES:
            assert _eq(info[f"srpb/{name}"], offline[name]), (agent, name)


def test_robots_are_real_to_each_other():
    par = parallel_env(scenario="corridor", n_robots=2, sensors={"detector": "lidar"})
    par.reset(seed=1, options={"people": False})
    sim = par.sim
    a, b = sim.world.robot_pose[0, :2], sim.world.robot_pose[1, :2]
    # each robot is in the other's lidar (a beam hits near the other robot's footprint)
    for me, other in ((0, 1), (1, 0)):
        state = sim.robots[me]
        x, y, yaw = sim.world.robot_pose[me]
        hits = np.column_stack([x + state.scan * np.cos(yaw + state.lidar.angles),
                                y + state.scan * np.sin(yaw + state.lidar.angles)])  # fmt: skip
        gap = np.hypot(*(hits - sim.world.robot_pose[other, :2]).T).min()
        assert gap < sim.robot_config.radius + 0.05 or abs(a[0] - b[0]) > 25
        assert len(state.tracker.tracks().ids) == 0  # a robot is never a tracked person
    # and they collide: drive them at each other
    for _ in range(300):
        _, _, terms, _, infos = par.step({ag: _towards(par, ag) for ag in par.agents})
        if any(info["collision"] for info in infos.values()):
            break
    else:
        raise AssertionError("no collision")
    assert all(terms.values())


def test_too_many_robots_names_the_limit():
    with pytest.raises(ValueError, match=r"n_robots: scenario 'doorway' has places for at most"):
        parallel_env(scenario="doorway", n_robots=50)
    with pytest.raises(ValueError, match="n_robots"):
        parallel_env(scenario="doorway", n_robots=0)


def test_step_checks_the_actions():
    par = parallel_env(scenario="corridor", n_robots=2)
    with pytest.raises(gym.error.ResetNeeded):
        par.step({})
    par.reset(seed=0)
    with pytest.raises(ValueError, match="no action for robot_1"):
        par.step({"robot_0": np.zeros(2, np.float32)})
    with pytest.raises(ValueError, match="finite"):
        par.step({"robot_0": np.zeros(2, np.float32), "robot_1": np.array([math.nan, 0.0])})


def _id(scenario: str) -> str:
    return next(k for k, v in SCENARIO_IDS.items() if v == scenario)


def _eq(a, b) -> bool:
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return a == b


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(_eq(a[k], b[k]) for k in a)


def _go_to_goal(k) -> np.ndarray:
    x, y, yaw = k.pose
    gx, gy, gyaw = k.goal
    dist = math.hypot(gx - x, gy - y)
    target = math.atan2(gy - y, gx - x) if dist > 0.1 else gyaw
    err = math.remainder(target - yaw, 2 * math.pi)
    speed = 0.0 if dist <= 0.1 else min(1.0, dist) * max(0.0, math.cos(err)) ** 4
    return np.array([speed, np.clip(2.0 * err, -1, 1)], dtype=np.float32)


def _into_side_wall(k) -> np.ndarray:
    err = math.remainder(math.pi / 2 - k.pose[2], 2 * math.pi)
    speed = 1.0 if abs(err) < 0.1 else 0.0
    return np.array([speed, np.clip(2.0 * err, -1, 1)], dtype=np.float32)


def _towards(par: SRPBParallelEnv, agent: str) -> np.ndarray:
    sim, r = par.sim, int(agent[-1])
    x, y, yaw = sim.world.robot_pose[r]
    ox, oy = sim.world.robot_pose[1 - r, :2]
    err = math.remainder(math.atan2(oy - y, ox - x) - yaw, 2 * math.pi)
    return np.array([max(0.0, math.cos(err)), np.clip(2.0 * err, -1, 1)], dtype=np.float32)


def test_planning_times_are_checked_and_do_not_leak():
    par = parallel_env(scenario="corridor", n_robots=2, max_steps=3)
    with pytest.raises(gym.error.ResetNeeded):
        par.set_planning_time(0.1)
    par.reset(seed=0)
    par.set_planning_time({"robot_0": 5.0})
    par.reset(seed=0)  # a new episode: the override is gone
    with pytest.raises(ValueError, match="finite"):  # a bad action consumes nothing
        par.step({"robot_0": np.zeros(2, np.float32), "robot_1": np.array([math.nan, 0.0])})
    par.set_planning_time({"robot_1": np.float64(0.5)})
    par.step({a: np.zeros(2, np.float32) for a in par.agents})
    times = [par.sim.robots[r].record.robot_col("planning_time")[0] for r in (0, 1)]
    assert times[0] != 5.0 and times[1] == 0.5
    with pytest.raises(ValueError, match="not in the episode"):
        par.set_planning_time({"robot_7": 0.1})
