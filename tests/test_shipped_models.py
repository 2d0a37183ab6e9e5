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
    training = facts["training"]
    warm = training.get("warm_start") or {"wall_time_s": 0.0}
    assert training["steps"] > 0
    assert training["wall_time_s"] + warm["wall_time_s"] <= 3600 + 60  # the 1-hour budget
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


def test_retraining_commands_follow_each_model_recipe():
    from training.retrain_models import commands

    plain = commands("ppo-crowd-task", 60, 0)
    assert len(plain) == 2 and "--init" not in plain[0]
    assert plain[0][plain[0].index("--hyperparams") + 1 :] == ["learning_rate=1e-4"]
    warm = commands("ppo-mix-srpb", 60, 1)[0]
    hyper = warm[warm.index("--hyperparams") + 1 :]
    assert "pretrain_planner=dwa" in hyper and "torch_threads=1" in hyper
    start, fine, ship = commands("ppo-crowd-srpb", 60, 0)
    assert start[start.index("--reward") + 1] == "task"
    assert fine[fine.index("--reward") + 1] == "srpb"
    first = start[start.index("--out") + 1]
    assert fine[fine.index("--init") + 1] == f"{first}/best"
    minutes = float(start[start.index("--max-minutes") + 1])
    assert minutes + float(fine[fine.index("--max-minutes") + 1]) == 60
    assert ship[-1] == "ppo-crowd-srpb"
