"""The packaged scenarios tell a social planner from a plain one.

In ``fformation`` (the SRPB paper's static scenario) the human-unaware ``dwa`` drives
through the standing pair's O-space on its way to the goal and the ``social-dwa`` goes
around the pair; both reach the goal. The seeds are typical ones: over seeds 0-49 ``dwa``
enters the O-space in 47 episodes (median m_fsi 5.5 %, median peak m_fsi_max 97 %) and
``social-dwa`` in none (m_fsi below 0.005 % and m_fsi_max below 0.3 % in every episode).

Also: a planner-driven episode of ``fformation`` and of ``crowd`` is the same, step for
step and metric for metric, when run twice with the same seed (tests/scenarios checks the
sampled layouts; tests/test_env.py a rollout of random actions).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.planners import make_planner

FFORMATION = "SRPB-FFormation-v0"
SEEDS = (0, 1, 2)
PLANNING_TIME = 1e-3  # s, every step: m_cef and m_cre are deterministic too

# m_fsi [%]: dwa crosses the O-space (5.6-5.7 % on these seeds), social-dwa stays out of
# it (below 0.001 % on these seeds: only the far tail of the O-space Gaussian)
DWA_FSI_AT_LEAST = 2.0
SOCIAL_FSI_AT_MOST = 0.1
# m_fsi_max [%]: the peak O-space value, 94-99 % when the robot drives through the pair
DWA_FSI_MAX_AT_LEAST = 50.0
SOCIAL_FSI_MAX_AT_MOST = 5.0


def run(env: gym.Env, planner_name: str, seed: int) -> tuple[dict, np.ndarray]:
    """The last info and the robot poses (N, 3) of one episode driven by the planner."""
    base = env.unwrapped
    obs, _ = env.reset(seed=seed)
    planner = make_planner(planner_name)
    planner.reset(base.knowledge())
    poses = [base.knowledge().pose.copy()]
    while True:
        action = planner.act(obs, base.knowledge())
        base.set_planning_time(PLANNING_TIME)
        obs, _, terminated, truncated, info = env.step(action)
        poses.append(base.knowledge().pose.copy())
        if terminated or truncated:
            return info, np.array(poses)


@pytest.fixture(scope="module")
def fformation() -> gym.Env:
    env = gym.make(FFORMATION)
    yield env
    env.close()


@pytest.mark.parametrize("seed", SEEDS)
def test_dwa_drives_through_the_o_space(fformation, seed):
    info, _ = run(fformation, "dwa", seed)
    assert info["is_success"] and not info["collision"]
    assert info["srpb/m_fsi"] >= DWA_FSI_AT_LEAST, info["srpb/m_fsi"]
    assert info["srpb/m_fsi_max"] >= DWA_FSI_MAX_AT_LEAST, info["srpb/m_fsi_max"]


@pytest.mark.parametrize("seed", SEEDS)
def test_social_dwa_goes_around_the_pair(fformation, seed):
    info, _ = run(fformation, "social-dwa", seed)
    assert info["is_success"] and not info["collision"]
    assert info["srpb/m_fsi"] <= SOCIAL_FSI_AT_MOST, info["srpb/m_fsi"]
    assert info["srpb/m_fsi_max"] <= SOCIAL_FSI_MAX_AT_MOST, info["srpb/m_fsi_max"]


@pytest.mark.parametrize("env_id", [FFORMATION, "SRPB-Crowd-v0"])
def test_same_seed_same_episode(env_id):
    env = gym.make(env_id)
    first_info, first_poses = run(env, "dwa", 3)
    again_info, again_poses = run(env, "dwa", 3)  # the same environment, reset again
    other = gym.make(env_id)
    fresh_info, fresh_poses = run(other, "dwa", 3)  # a new environment
    for info, poses in ((again_info, again_poses), (fresh_info, fresh_poses)):
        np.testing.assert_array_equal(poses, first_poses)
        for name in METRIC_NAMES:
            np.testing.assert_equal(info[f"srpb/{name}"], first_info[f"srpb/{name}"], name)
            np.testing.assert_equal(info[f"srpb_gt/{name}"], first_info[f"srpb_gt/{name}"], name)
    env.close()
    other.close()
