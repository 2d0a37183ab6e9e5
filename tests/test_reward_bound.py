"""The reward presets cannot be gamed by crashing: the worst (discounted) shaping of the
rest of any episode costs less than a collision, and the per-step bound behind that claim
holds. Nor by waiting: driving to the goal is worth more than standing still."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.reward import (
    PRESET_GAMMA,
    SHAPING_TERMS,
    TERMS,
    RewardGameableWarning,
    preset_names,
    shaping_bound,
    step_bounds,
)
from srpb_gym.scenarios import load_scenario
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.training.config import load_entries, resolve


@pytest.mark.parametrize("preset", ["srpb", "task"])
@pytest.mark.parametrize("env_id", SCENARIO_IDS)
def test_worst_case_shaping_costs_less_than_a_collision(preset: str, env_id: str) -> None:
    """The invariant: for a learner discounting as every training configuration does, the
    worst shaping of the rest of any episode costs less than a collision (with the weights
    each scenario pays)."""
    env = gym.make(env_id, reward=preset)
    weights = dict(zip(TERMS, env.unwrapped.task.reward_fn.weights.tolist()))
    env.close()
    limit = load_scenario(SCENARIO_IDS[env_id]).time_limit
    gammas = {resolve(env_id).gamma for env_id in load_entries()[0] if env_id != "default"}
    assert gammas == {PRESET_GAMMA}
    bound = shaping_bound(weights, limit, 0.1, RobotConfig(), PRESET_GAMMA)
    assert 0.0 < bound < -weights["collision"]


def test_discounted_bound_by_hand() -> None:
    # psi -2: at most 0.2 per step; discounted by 0.5 over all steps to come: 0.2 / (1 - 0.5)
    assert shaping_bound({"psi": -2.0}, 0.3, 0.1, RobotConfig(), 0.5) == pytest.approx(0.4)
    assert shaping_bound({"psi": -2.0}, 0.3, 0.1, RobotConfig()) == pytest.approx(0.6)
    with pytest.raises(ValueError, match="gamma"):
        shaping_bound({"psi": -2.0}, 0.3, 0.1, RobotConfig(), 0.0)


def test_every_packaged_preset_is_checked() -> None:
    assert set(preset_names()) == {"srpb", "task"}


def test_shaping_bound_by_hand() -> None:
    # 10 steps of 0.1 s: psi at most 0.1 s per step, chc at most w_max * dt rad per step (+1 %)
    robot = RobotConfig()
    bound = shaping_bound({"psi": -2.0, "chc": -1.0, "progress": -5.0, "time": 3.0}, 1.0, 0.1,
                          robot)  # fmt: skip
    assert bound == pytest.approx(10 * (2.0 * 0.1 + 1.0 * 1.01 * robot.w_max * 0.1))


def test_holonomic_robot_bounds_both_axes() -> None:
    diff, holo = RobotConfig(), RobotConfig(kinematics="holonomic")
    assert step_bounds(0.1, diff)["vsm"] == pytest.approx(1.01 * diff.acc_lin)
    assert step_bounds(0.1, holo)["vsm"] == pytest.approx(1.01 * np.hypot(1.0, 1.0) * holo.acc_lin)


@pytest.mark.parametrize("env_id", ["SRPB-Crowd-v0", "SRPB-Corridor-v0"])
def test_per_step_values_stay_within_their_bounds(env_id: str) -> None:
    """Jerky random driving (full reversals of both commands) never exceeds a term's bound
    on a step without a contact."""
    env = gym.make(env_id)
    bounds = step_bounds(0.1, RobotConfig())
    time_weight = env.unwrapped.task.reward_fn.weights[TERMS.index("time")]  # no srpb_step/
    rng = np.random.default_rng(3)
    seen = dict.fromkeys(SHAPING_TERMS, 0.0)
    for episode in range(3):
        env.reset(seed=episode)
        for _ in range(300):
            action = rng.choice([-1.0, 1.0], size=2).astype(np.float32)
            _, _, terminated, truncated, info = env.step(action)
            if info["collision"]:
                break
            for term in SHAPING_TERMS:
                key = f"srpb_step/{term}" if f"srpb_step/{term}" in info else None
                value = info[key] if key else info[f"reward_{term}"] / time_weight
                assert value <= bounds[term] * (1 + 1e-9) + 1e-12, (term, value)
                seen[term] = max(seen[term], value)
            if terminated or truncated:
                break
    env.close()
    assert seen["vsm"] > 0.5 * bounds["vsm"] and seen["hsm"] > 0.5 * bounds["hsm"]


def test_gameable_weights_warn_once() -> None:
    env = gym.make("SRPB-Crowd-v0", reward_weights={"psi": -4.0})
    with pytest.warns(RewardGameableWarning, match="collision penalty"):
        env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RewardGameableWarning)
        env.reset(seed=1)  # the same time limit: said once
    env.close()


@pytest.mark.parametrize("preset", ["srpb", "task"])
def test_packaged_presets_do_not_warn(preset: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", RewardGameableWarning)
        for env_id in SCENARIO_IDS:
            env = gym.make(env_id, reward=preset)
            env.reset(seed=0)
            env.close()


def test_continuing_collisions_are_not_checked() -> None:
    env = gym.make("SRPB-Crowd-v0", reward_weights={"psi": -4.0}, collision="continue")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RewardGameableWarning)
        env.reset(seed=0)
    env.close()


def _discounted_return(env_id: str, planner: str | None, seed: int) -> float:
    """The return of one episode from its first state, discounted by PRESET_GAMMA per step,
    driven by a classical planner (``None``: a stop command on every step)."""
    from srpb_gym.planners import make_planner

    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    knowledge = env.unwrapped.knowledge()
    policy = None if planner is None else make_planner(planner)
    if policy is not None:
        policy.reset(knowledge)
    total, discount, done = 0.0, 1.0, False
    while not done:
        action = (np.zeros(env.action_space.shape, np.float32) if policy is None
                  else policy.act(obs, env.unwrapped.knowledge()))  # fmt: skip
        obs, reward, terminated, truncated, info = env.step(action)
        total += discount * reward
        discount *= PRESET_GAMMA
        done = terminated or truncated
    env.close()
    assert planner is None or info["is_success"], (env_id, planner, seed)
    return total


@pytest.mark.parametrize("env_id", SCENARIO_IDS)
def test_going_to_the_goal_pays_more_than_waiting(env_id: str) -> None:
    """With the `srpb` preset each scenario pays by default, a learner that discounts by
    PRESET_GAMMA values driving to the goal (`dwa`, which reaches it on these seeds) above
    standing still until the time limit. Five times the social and obs weights break this
    among crossing walkers (crossing, crowd, doorway; docs/training.md): the penalties of
    personal-space intrusions the robot meets on its way then cost more than its progress
    earns, and a trained agent learns to wait."""
    seeds = (0, 1, 2)
    going = np.mean([_discounted_return(env_id, "dwa", s) for s in seeds])
    waiting = np.mean([_discounted_return(env_id, None, s) for s in seeds])
    assert going > waiting, (going, waiting)
