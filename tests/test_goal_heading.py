"""scripts/goal_heading.py: the drawn episode with only the goal's heading turned."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

from scripts import goal_heading as gh
from srpb_gym.models.shipped import model_path
from srpb_gym.planners.learned import LearnedPolicy


class Recorder(LearnedPolicy):
    """The shipped policy, keeping the knowledge it was reset with."""

    def reset(self, knowledge):
        self.first = knowledge
        super().reset(knowledge)


def test_the_episode_is_the_drawn_one_with_the_goal_turned():
    policy = Recorder(model_path("ppo-crowd-srpb-3robots"))
    env = gym.make("SRPB-Crowd-v0", route=2)
    plain = gym.make("SRPB-Crowd-v0", route=2).unwrapped
    plain.reset(seed=3_000_004)
    drawn = plain.sim.layout
    ok, ended, distance = gh.run(policy, env, 3_000_004, 0.0)
    assert env.unwrapped.sim.layout.people == drawn.people  # the same people
    assert env.unwrapped.sim.layout.robots == drawn.robots
    assert ok == (ended == "success") and (distance <= 0.2 or not ok)
    gh.run(policy, env, 3_000_004, -math.pi / 2)
    turned = env.unwrapped.sim.layout.robots[0]
    assert turned.start == drawn.robots[0].start
    assert turned.goal[:2] == drawn.robots[0].goal[:2]
    assert turned.goal[2] == pytest.approx(drawn.robots[0].goal[2] - math.pi / 2)
    assert policy.first.goal[2] == pytest.approx(turned.goal[2])
