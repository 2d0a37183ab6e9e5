"""The shipped models load by their short names, match the current spaces and act."""

from __future__ import annotations

import csv

import gymnasium as gym
import pytest

import srpb_gym  # noqa: F401
from srpb_gym.models import card, model_names, model_path
from srpb_gym.training.run import eval_env_ids
from training.retrain_models import MODELS

CARD_KEYS = {"name", "algo", "env", "reward", "seed", "hyperparams", "training", "test"}


def test_every_shipped_model_can_be_retrained():
    assert set(model_names()) <= set(MODELS)


def test_unknown_names_are_not_models():
    assert model_path("ppo-nowhere-srpb") is None
    assert model_path("../models") is None
    with pytest.raises(KeyError, match="no shipped model"):
        card("ppo-nowhere-srpb")


@pytest.mark.parametrize("name", model_names())
def test_model_loads_matches_spaces_and_acts(name):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.planners.learned import LearnedPolicy, find_vecnormalize

    facts = card(name)
    assert set(facts) >= CARD_KEYS and facts["name"] == name
    assert (facts["env"], facts["reward"]) == MODELS[name]
    assert facts["training"]["steps"] > 0 and facts["training"]["wall_time_s"] <= 3600 + 60
    path = model_path(name)
    vecnormalize = find_vecnormalize(path)
    assert vecnormalize is not None, "normalisation statistics missing"
    policy = LearnedPolicy(path, vecnormalize=vecnormalize)
    for env_id in eval_env_ids(facts["env"]):
        env = gym.make(env_id)
        policy.check_spaces(env.observation_space, env.action_space)
        obs, _ = env.reset(seed=0)
        for _ in range(5):
            action = policy.act(obs, env.unwrapped.knowledge())
            assert env.action_space.contains(action)
            obs, *_ = env.step(action)
        env.close()


@pytest.mark.parametrize("name", model_names()[:1])
def test_eval_takes_a_short_name(name, tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.cli import main

    env_id = eval_env_ids(card(name)["env"])[0]
    rc = main(["eval", "--env", env_id, "--policy", name, "--episodes", "1", "--warmup", "0",
               "--out", str(tmp_path / "eval")])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    with open(tmp_path / "eval" / "episodes.csv", newline="") as f:
        assert [r["planner"] for r in csv.DictReader(f)] == [name]
