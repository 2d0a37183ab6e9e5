"""EnvSettings: the one settings object the three environments are built from."""

from __future__ import annotations

import dataclasses
import pickle

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym
from srpb_gym.env import SRPBNavEnv
from srpb_gym.errors import InputError
from srpb_gym.mix import SRPBMixEnv
from srpb_gym.pettingzoo_env import SRPBParallelEnv
from srpb_gym.settings import SETTING_NAMES, EnvSettings
from tests.helpers import same


def test_defaults_are_the_documented_ones():
    s = EnvSettings.from_kwargs({})
    assert s == EnvSettings()
    assert (s.reward, s.collision, s.record_dir) == ("srpb", "terminate", None)
    assert s.observation.type == "flat" and s.robot.kinematics == "diff"
    assert (s.lidar, s.detector, s.tracker) == (None, None, None)  # the scenario's


def test_settings_are_frozen_and_copies():
    weights = {"psi": -1.0}
    s = EnvSettings.from_kwargs({"reward_weights": weights, "metrics": {"params": {}}})
    weights["psi"] = -99.0
    assert s.reward_weights["psi"] == -1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.reward = "task"  # type: ignore[misc]
    with pytest.raises(TypeError):
        s.reward_weights["psi"] = 0.0  # type: ignore[index]
    assert pickle.loads(pickle.dumps(s)) == s


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"collision": "bounce"}, "collision"),
        ({"reward": "nice"}, "reward"),
        ({"reward_weights": {"speed": 1.0}}, "reward_weights.speed"),
        ({"sensors": {"sonar": {}}}, "sensors.sonar"),
        ({"sensors": {"lidar": {"fov": "wide"}}}, "sensors.lidar.fov"),
        ({"metrics": {"semantics": "mine"}}, "metrics.semantics"),
        ({"robot": {"wheels": 3}}, "robot.wheels"),
        ({"crowd": {"anisotropy": 1.5}}, "crowd"),
        ({"record_dir": 3}, "record_dir"),
    ],
)
def test_a_bad_value_names_its_key(kwargs, key):
    with pytest.raises(InputError) as caught:
        EnvSettings.from_kwargs(kwargs)
    assert caught.value.key is not None and caught.value.key.startswith(key)


def test_an_unknown_setting_is_a_type_error_naming_it():
    with pytest.raises(TypeError, match="unexpected keyword argument 'speed'"):
        EnvSettings.from_kwargs({"speed": 1.0})
    with pytest.raises(TypeError, match=r"SRPBNavEnv.*'speed'"):
        SRPBNavEnv("corridor", speed=1.0)


def test_settings_or_keywords_not_both():
    with pytest.raises(TypeError, match="not both"):
        SRPBNavEnv("corridor", settings=EnvSettings(), reward="task")
    with pytest.raises(InputError, match="EnvSettings"):
        SRPBNavEnv("corridor", settings={"reward": "task"})  # type: ignore[arg-type]


def _rollout(env: gym.Env, seed: int = 3, steps: int = 30) -> list:
    out = [env.reset(seed=seed)]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        env.unwrapped.set_planning_time(0.001)
        out.append(env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)))
        if out[-1][2] or out[-1][3]:
            break
    return out


def test_settings_object_and_keywords_make_the_same_episodes():
    kwargs = {"observation": "dict", "reward": "task", "robot": "holonomic",
              "crowd": {"robot_reaction": 0.5}, "collision": "continue"}  # fmt: skip
    a = gym.make("SRPB-Crowd-v0", **kwargs)
    b = gym.make("SRPB-Crowd-v0", settings=EnvSettings.from_kwargs(kwargs))
    assert a.unwrapped.settings == b.unwrapped.settings
    ra, rb = _rollout(a), _rollout(b)
    assert len(ra) == len(rb)
    for x, y in zip(ra, rb):
        assert all(same(u, v) for u, v in zip(x, y))


def test_the_three_adapters_take_the_same_settings():
    settings = EnvSettings.from_kwargs({"robot": "holonomic", "observation": {"people": 4}})
    single = SRPBNavEnv("crowd", settings=settings)
    mix = SRPBMixEnv(["corridor", "crowd"], settings=settings)
    multi = SRPBParallelEnv("crowd", n_robots=2, settings=settings)
    par = srpb_gym.parallel_env(scenario="crowd", n_robots=2, robot="holonomic",
                                observation={"people": 4})  # fmt: skip
    space = single.observation_space
    assert space.shape == (8 + 30 + 7 * 4,)
    assert space == mix.observation_space == multi.observation_space("robot_1")
    assert space == par.observation_space("robot_0")
    assert single.settings is mix.settings is multi.settings is settings
    assert par.settings == settings
    assert mix.task_of("corridor").sim is not mix.task_of("crowd").sim


def test_every_adapter_documents_the_settings():
    for cls in (SRPBNavEnv, SRPBMixEnv, SRPBParallelEnv):
        doc = cls.__doc__ or ""
        assert "settings" in doc
    for name in SETTING_NAMES:
        assert f"``{name}``" in (SRPBNavEnv.__doc__ or ""), name


def test_settings_made_directly_are_checked_too():
    with pytest.raises(InputError) as caught:
        EnvSettings(collision="bounce")
    assert caught.value.key == "collision"
    with pytest.raises(InputError) as caught:
        EnvSettings(robot="holonomic")  # type: ignore[arg-type]
    assert caught.value.key == "robot" and "from_kwargs" in caught.value.message
    with pytest.raises(InputError) as caught:
        EnvSettings(reward_weights={"nope": 1.0})
    assert caught.value.key == "reward_weights.nope"
    assert hash(EnvSettings.from_kwargs({"metrics": {"params": {"person_fov": 3.0}}}))
