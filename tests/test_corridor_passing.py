"""scripts/corridor_passing.py: the scripted drivers keep their lanes and their figures add up."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from scripts import corridor_passing as cp


def drive(driver: cp.LaneDriver, seed: int) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    env = gym.make("SRPB-Corridor-v0")
    obs, _ = env.reset(seed=seed)
    task = env.unwrapped
    driver.reset(task.knowledge(ground_truth=True))
    poses, people = [], []
    while True:
        knowledge = task.knowledge(ground_truth=True)
        poses.append(knowledge.pose.copy())
        people.append(knowledge.tracks.xy.copy())
        obs, _, terminated, truncated, info = env.step(driver.act(obs, knowledge))
        if terminated or truncated:
            env.close()
            return poses, people, info


def test_a_lane_driver_holds_its_lane_and_reaches_the_goal():
    poses, _, info = drive(cp.LaneDriver(0.7), seed=20_000_000)
    assert info["is_success"]
    xy = np.array(poses)[:, :2]
    cruise = (xy[:, 0] > 4.0) & (xy[:, 0] < 11.0)  # between the lane change and the goal
    assert cruise.any() and np.all(np.abs(xy[cruise, 1] - 0.7) < 0.1)


def test_a_waiting_driver_stays_until_everyone_is_behind_it():
    poses, people, info = drive(cp.LaneDriver(0.45, wait=True), seed=20_000_001)
    assert info["is_success"]
    x = np.array(poses)[:, 0]
    # a metre along the corridor from its start, every person is behind it already
    set_off = next(k for k in range(len(x)) if x[k] > x[0] + 1.0)
    assert np.all(people[set_off][:, 0] < x[set_off])
    assert set_off * 0.1 > 15.0  # it waited: the people need longer than that to pass


def test_the_figures_of_a_driver():
    f = cp.run(cp.LaneDriver(0.7), episodes=3, seed=20_000_000)
    assert f["success"] == 100.0 and f["m_obs"] == 0.0  # 0.425 m from the wall: no m_obs
    assert f["ci"][0] <= f["m_psi"] <= f["ci"][1]
    # the intrusion integral is m_psi over the time someone is present, under the episode
    assert 0.0 < f["integral"] < f["m_psi"] / 100.0 * f["m_mef"] + 0.2


def test_the_corridor_is_symmetric_for_the_drivers():
    low = cp.run(cp.LaneDriver(0.7), episodes=2, seed=20_000_000)
    high = cp.run(cp.LaneDriver(2.2 - 0.7), episodes=2, seed=20_000_000)
    assert high["m_psi"] == pytest.approx(low["m_psi"], rel=0.1)
