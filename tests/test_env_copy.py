"""A deep-copied or pickled environment goes on bit for bit like the original."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the environments)
from tests.helpers import same

COPIES = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
    "copy of a copy": lambda env: copy.deepcopy(pickle.loads(pickle.dumps(env))),
}


@pytest.mark.parametrize("how", list(COPIES))
@pytest.mark.parametrize("steps", [0, 5])
@pytest.mark.parametrize("env_id", ["SRPB-Crowd-v0", "SRPB-Corridor-v0"])
def test_a_copy_goes_on_like_the_original(env_id, steps, how):
    env = gym.make(env_id)
    env.reset(seed=1)
    for _ in range(steps):
        env.unwrapped.set_planning_time(0.001)
        env.step(np.array([0.5, 0.1], np.float32))
    clone = COPIES[how](env)
    rng = np.random.default_rng(0)
    for _ in range(50):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        for e in (env, clone):
            e.unwrapped.set_planning_time(0.001)
        a, b = env.step(action), clone.step(action)
        for x, y in zip(a, b):
            assert same(x, y)
        if a[2] or a[3]:
            break
    assert clone.unwrapped.sim.steps == env.unwrapped.sim.steps


@pytest.mark.parametrize("vector", ["sync", "async"])
def test_vector_envs_of_copies(vector):
    """Vector envs run copies (the async one pickles them into its workers) like fresh
    environments."""
    base = gym.make("SRPB-Crowd-v0")
    base.reset(seed=5)
    cls = gym.vector.SyncVectorEnv if vector == "sync" else gym.vector.AsyncVectorEnv
    copies = cls([lambda: copy.deepcopy(base) for _ in range(2)])
    fresh = gym.vector.SyncVectorEnv([lambda: gym.make("SRPB-Crowd-v0") for _ in range(2)])
    for envs in (copies, fresh):
        envs.reset(seed=[0, 1])
    rng = np.random.default_rng(0)
    for _ in range(10):
        actions = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        for envs in (copies, fresh):
            envs.call("set_planning_time", 0.001)
        a, b = copies.step(actions), fresh.step(actions)
        assert a[0].shape == (2, *copies.single_observation_space.shape)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    copies.close()
    fresh.close()
