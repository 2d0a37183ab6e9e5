"""The shipped models load by their short names, match the current spaces and act."""

from __future__ import annotations

import csv
import dataclasses
import itertools
import sys

import gymnasium as gym
import pytest
import yaml

import srpb_gym  # noqa: F401
from srpb_gym.models import card, model_names, model_path
from srpb_gym.reward_terms import TASK_TERMS
from srpb_gym.training.targets import eval_env_ids
from training.retrain_models import MODELS, MULTI_RECIPES, recipe_of
from training.ship import _trained_weights

CARD_KEYS = {
    "name", "algo", "env", "reward", "reward_weights", "seed", "hyperparams", "training", "test",
}  # fmt: skip


#: the shipped single-robot models (a policy shared by several robots has its own tests:
#: tests/test_ship_multi.py)
SINGLE = [name for name in model_names() if name not in MULTI_RECIPES]


def test_every_shipped_model_can_be_retrained():
    assert set(model_names()) <= set(MODELS) | set(MULTI_RECIPES)


def test_unknown_names_are_not_models():
    assert model_path("ppo-nowhere-srpb") is None
    assert model_path("../models") is None
    with pytest.raises(KeyError, match="no shipped model"):
        card("ppo-nowhere-srpb")


@pytest.mark.parametrize("name", SINGLE)
def test_model_loads_matches_spaces_and_acts(name):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.models import find_vecnormalize, observation_config_of, recorded_observation
    from srpb_gym.observation import ObservationConfig
    from srpb_gym.planners.learned import LearnedPolicy

    facts = card(name)
    assert set(facts) >= CARD_KEYS and facts["name"] == name
    assert (facts["env"], facts["reward"]) == (recipe_of(name).env_id, MODELS[name][1])
    # trained with the weights the environment pays now (a scenario re-weighted since, or a
    # preset changed, needs the model retrained)
    assert facts["reward_weights"] == _trained_weights(facts), name
    training = facts["training"]
    warm = training.get("warm_start") or {"wall_time_s": 0.0}
    assert training["steps"] > 0
    text = (model_path(name).parent / "card.md").read_text(encoding="utf-8")
    if training.get("side_by_side", 1) == 1:  # the 1-hour budget of a run alone
        assert training["wall_time_s"] + warm["wall_time_s"] <= 3600 + 60
    else:  # trained beside other runs: the card says its time is not that of a run alone
        assert "runs side by side on the machine's cores, the time of one run alone not " in text
    path = model_path(name)
    vecnormalize = find_vecnormalize(path)
    assert vecnormalize is not None, "normalisation statistics missing"
    policy = LearnedPolicy(path, vecnormalize=vecnormalize)
    # the model records how it observed, and its card's env kwargs say the same (a record
    # saved before a setting existed reads as that setting's default)
    observation = facts["env_kwargs"].get("observation")
    config = ObservationConfig.from_spec(observation)
    assert recorded_observation(policy.trained_observation) == config
    trained = dataclasses.asdict(config)
    row = next(line for line in text.splitlines() if line.startswith("| observation |"))
    assert ("lidar_encoding: log" in row) == (trained["lidar_encoding"] == "log"), row
    assert ("lidar_groups" in row) == (trained["lidar_groups"] > 0), row
    kwargs = {} if observation is None else {"observation": observation}
    for env_id in eval_env_ids(facts["env"]):
        env = gym.make(env_id, **kwargs)
        policy.check_spaces(env.observation_space, env.action_space)
        assert policy.observation_config == observation_config_of(env)
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


def _reward_weights(options: dict[str, list[str]]) -> dict[str, float]:
    """The ``reward_weights`` env kwarg of a command's options ({} without one)."""
    for item in options.get("--env-kwargs", []):
        key, _, value = item.partition("=")
        if key == "reward_weights":
            return yaml.safe_load(value)
    return {}


def test_twins_differ_in_the_reward_alone():
    from training.retrain_models import RECIPES, train_command

    def parts(cmd):
        """The command's options by name (the values after each ``--name``)."""
        out, key = {}, None
        assert cmd[1:4] == ["-m", "srpb_gym", "train"]  # the venv's own, not one on PATH
        for word in cmd[4:]:
            if word.startswith("--"):
                key = word
                out[key] = []
            else:
                out[key].append(word)
        return out

    for scenario in RECIPES:
        srpb = parts(train_command(f"ppo-{scenario}-srpb", 1, "runs/x", 1))
        task = parts(train_command(f"ppo-{scenario}-task", 1, "runs/x", 1))
        assert srpb["--reward"] == ["srpb"] and task["--reward"] == ["task"]
        assert srpb["--seed"] == task["--seed"] == ["1"]
        for option in ("--env", "--steps", "--hyperparams", "--out"):
            assert srpb[option] == task[option], (scenario, option)
        kw_srpb = [k for k in srpb.get("--env-kwargs", []) if not k.startswith("reward_weights")]
        kw_task = [k for k in task.get("--env-kwargs", []) if not k.startswith("reward_weights")]
        assert kw_srpb == kw_task, scenario
        # the task twin pays the srpb model's task-term weights (its collision penalty
        # among them), and none of its SRPB weights
        weights = {name: _reward_weights(cmd) for name, cmd in (("srpb", srpb), ("task", task))}
        task_part = {k: v for k, v in weights["srpb"].items() if k in TASK_TERMS}
        assert weights["task"] == task_part, scenario
        assert weights["srpb"].get("collision", -25.0) == RECIPES[scenario].collision
    assert set(MODELS) == {f"ppo-{s}-{p}" for s in RECIPES for p in ("srpb", "task")}


def test_retraining_commands_follow_each_model_recipe(monkeypatch):
    from training.retrain_models import RECIPES, commands

    crowd = commands("ppo-crowd-srpb", [0, 1, 2], 1)
    assert len(crowd) == 4 and [c[c.index("--seed") + 1] for c in crowd[:3]] == ["0", "1", "2"]
    train, ship = crowd[0], crowd[-1]
    assert train[train.index("--steps") + 1] == "3000000" and "--max-minutes" not in train
    hyper = train[train.index("--hyperparams") + 1 :]
    assert "pretrain_planner=social-dwa" in hyper and "learning_rate=1e-4" in hyper
    assert "n_epochs=5" in hyper and "clip_range=0.1" in hyper and "gamma=0.995" in hyper
    assert hyper[-1] == "torch_threads=1"
    kwargs = train[train.index("--env-kwargs") + 1 : train.index("--hyperparams")]
    assert kwargs == ["observation={lidar_encoding: log, lidar_groups: 0.0001}",
                      "reward_weights={psi: -2.0, fsi: -3.0, collision: -120.0}",
                      "reward_people=ground_truth"]  # fmt: skip
    # the first seed's run is shipped, chosen between best/ and final on validation seeds
    assert ship[ship.index("training.ship") + 1] == train[train.index("--out") + 1]
    assert ship[ship.index("--name") + 1] == "ppo-crowd-srpb"
    assert ship[ship.index("--validate") + 1] == "100"
    assert len(commands("ppo-crowd-srpb", [0, 1], 0, ship=False)) == 2
    plain = commands("ppo-crossing-task", [0], 0)[0]
    kwargs = plain[plain.index("--env-kwargs") + 1 : plain.index("--hyperparams")]
    assert kwargs == ["reward_people=ground_truth"]
    assert "--hyperparams" in plain and "torch_threads=1" not in plain
    mix = commands("ppo-mix-srpb", [0], 1)[0]
    hyper = mix[mix.index("--hyperparams") + 1 :]
    assert "pretrain_episodes=1000" in hyper
    teachers = next(h for h in hyper if h.startswith("pretrain_teachers="))
    assert teachers.startswith("pretrain_teachers={corridor: ppo-corridor-srpb, ")
    kwargs = mix[mix.index("--env-kwargs") + 1 : mix.index("--hyperparams")]
    assert kwargs == ["observation={lidar_encoding: log}", "weights=[1, 1, 3, 2, 3]",
                      "reward_people=ground_truth"]  # fmt: skip
    tracked = dataclasses.replace(RECIPES["crowd"], reward_people="tracked")
    monkeypatch.setitem(RECIPES, "crowd", tracked)
    train = commands("ppo-crowd-task", [0], 0)[0]
    assert not any(word.startswith("reward_people") for word in train)  # the env's default


def test_a_taught_model_is_retrained_after_its_teachers(monkeypatch, capsys):
    import subprocess

    from training import retrain_models as rm

    pairs = (("crowd", "ppo-crowd-task"), ("corridor", "ppo-corridor-srpb"))
    monkeypatch.setitem(rm.RECIPES, "mix", dataclasses.replace(rm.RECIPES["mix"], teachers=pairs))
    hyper = rm.commands("ppo-mix-srpb", [0], 1)[0]
    hyper = hyper[hyper.index("--hyperparams") + 1 :]
    assert "pretrain_teachers={crowd: ppo-crowd-task, corridor: ppo-corridor-srpb}" in hyper
    shipped = ["ppo-crowd-task", "ppo-corridor-srpb"]
    everything = ["ppo-mix-srpb", "ppo-crowd-task", "ppo-fformation-task"]
    assert rm.waves(everything, shipped) == [
        ["ppo-crowd-task", "ppo-fformation-task"], ["ppo-mix-srpb"]
    ]  # fmt: skip
    assert rm.waves(["ppo-mix-srpb"], shipped) == [["ppo-mix-srpb"]]  # the shipped ones teach
    with pytest.raises(ValueError, match=r"its teacher ppo-crowd-task \(crowd\) is not shipped"):
        rm.waves(["ppo-mix-srpb"], ["ppo-corridor-srpb"])
    monkeypatch.setitem(rm.MODELS, "ppo-crowd-mix", ("mix", "task"))
    taught = (("crowd", "ppo-crowd-mix"),)
    monkeypatch.setitem(rm.RECIPES, "mix", dataclasses.replace(rm.RECIPES["mix"], teachers=taught))
    with pytest.raises(ValueError, match=r"its teacher ppo-crowd-mix \(crowd\) is taught too"):
        rm.waves(["ppo-mix-srpb"], shipped)
    planner = (("crowd", "dwa"),)
    monkeypatch.setitem(rm.RECIPES, "mix", dataclasses.replace(rm.RECIPES["mix"], teachers=planner))
    with pytest.raises(ValueError, match=r"its teacher dwa \(crowd\) is no model of this script"):
        rm.waves(["ppo-mix-srpb"], shipped)
    monkeypatch.setitem(rm.RECIPES, "mix", dataclasses.replace(rm.RECIPES["mix"], teachers=pairs))

    # a failed teacher: its student is not trained; the other models of the wave are
    ran = []

    def trained():
        return [c[c.index("--out") + 1].split("/")[-1].rsplit("-", 3)[0] for c in ran
                if c[3:4] == ["train"]]  # fmt: skip

    def run(cmd, check):
        ran.append(cmd)
        failing = cmd[3:4] == ["train"] and "ppo-crowd-task" in cmd[cmd.index("--out") + 1]
        return subprocess.CompletedProcess(cmd, 1 if failing else 0)

    monkeypatch.setattr(rm.subprocess, "run", run)
    monkeypatch.setattr(rm.sys, "argv", ["retrain_models", *everything])
    assert rm.main() == 1
    assert trained() == ["ppo-crowd-task", "ppo-fformation-task"]
    err = capsys.readouterr().err
    assert "ppo-mix-srpb: not retrained, its teacher ppo-crowd-task failed" in err
    ran.clear()
    monkeypatch.setattr(rm.sys, "argv", ["retrain_models", "--jobs", "2", *everything])
    monkeypatch.setattr(rm.subprocess, "run", lambda cmd, check: ran.append(cmd) or
                        subprocess.CompletedProcess(cmd, 0))  # fmt: skip
    assert rm.main() == 0
    assert set(trained()[:2]) == {"ppo-crowd-task", "ppo-fformation-task"}
    assert trained()[2:] == ["ppo-mix-srpb"]  # the student after both teachers' wave
    # the cards of the runs trained two at a time say so; the student trained alone
    sides = {c[c.index("--name") + 1]: c[c.index("--side-by-side") + 1] if "--side-by-side"
             in c else "1" for c in ran if c[1:3] == ["-m", "training.ship"]}  # fmt: skip
    assert sides == {"ppo-crowd-task": "2", "ppo-fformation-task": "2", "ppo-mix-srpb": "1"}


@pytest.mark.parametrize(("best", "final", "chosen"), [
    ((0.80, 20.0), (0.90, 25.0), "final"),  # higher success wins
    ((0.90, 25.0), (0.90, 20.0), "final"),  # equal success: lower GT m_psi wins
    ((0.90, 20.0), (0.90, 20.0), "best"),  # a tie keeps best/
    ((0.95, 30.0), (0.90, 10.0), "best"),
])  # fmt: skip
def test_ship_validate_takes_the_better_checkpoint(tmp_path, monkeypatch, best, final, chosen):
    """By success, then by the median m_psi from the true people: the tracked one (here
    ordered the other way round) does not decide."""
    from training import ship

    run = tmp_path / "run"
    (run / "best").mkdir(parents=True)
    seen = []

    def evaluate(
        model, env_ids, episodes, seed, out, env_kwargs=None, workers=1, trust_pickle=False
    ):
        seen.append((model, episodes, seed))
        success, psi = best if model.parent.name == "best" else final
        return {env: {"success": success, "gt_m_psi": psi, "m_psi": 100.0 - psi}
                for env in env_ids}  # fmt: skip

    monkeypatch.setattr(ship, "evaluate", evaluate)
    folder, validation = ship.choose(run, ["SRPB-Crowd-v0"], 100)
    assert folder == (run / "best" if chosen == "best" else run)
    assert validation["chosen"] == chosen and validation["seed"] == ship.VALIDATION_SEED
    assert [s[1:] for s in seen] == [(100, ship.VALIDATION_SEED)] * 2  # never the test seeds
    from srpb_gym.training.callbacks import EVAL_SEED
    from srpb_gym.training.pretrain import DEMO_SEED

    # apart from the seeds that chose best/ (and from the demonstrations and test seeds)
    starts = sorted([ship.VALIDATION_SEED, EVAL_SEED, DEMO_SEED, ship.TEST_SEED])
    assert all(b - a >= 100_000 for a, b in itertools.pairwise(starts))
    text = ship._validation(validation)
    rates = {"best": best[0], "final": final[0]}
    other = "the final model" if chosen == "best" else "the best periodic evaluation's"
    assert f"chosen over {other}" in text and "on 100 validation seeds from 3000000" in text
    psis = {"best": best[1], "final": final[1]}
    loser = "final" if chosen == "best" else "best"
    assert (f"mean success {100 * rates[chosen]:.0f} % against {100 * rates[loser]:.0f} %, "
            f"median m_psi from ground truth {psis[chosen]:.3g} % against "
            f"{psis[loser]:.3g} %") in text  # fmt: skip
    # a card chosen before the rule (no "by") reads the tracked median it was chosen on
    del validation["by"]
    tracked = {k: 100.0 - v for k, v in psis.items()}
    assert (f"median m_psi {tracked[chosen]:.3g} % against "
            f"{tracked[loser]:.3g} %)") in ship._validation(validation)  # fmt: skip


def test_ship_validate_tests_best_once_when_it_is_the_final_model(tmp_path, monkeypatch):
    """best/ holding the final weights (saved at another time) is evaluated once."""
    import time

    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from training import ship

    run = tmp_path / "run"
    (run / "best").mkdir(parents=True)

    def tiny(seed: int) -> PPO:
        return PPO("MlpPolicy", gym.make("SRPB-Corridor-v0"), n_steps=64, batch_size=32,
                   policy_kwargs={"net_arch": [8]}, seed=seed)  # fmt: skip

    model = tiny(0)
    model.save(run / "best" / "model.zip")
    time.sleep(2.1)  # zip time stamps have a resolution of 2 s
    model.save(run / "model.zip")
    assert (run / "model.zip").read_bytes() != (run / "best" / "model.zip").read_bytes()
    for folder in (run, run / "best"):
        (folder / "vecnormalize.npz").write_bytes(b"the same statistics")
    seen = []

    def evaluate(
        model, env_ids, episodes, seed, out, env_kwargs=None, workers=1, trust_pickle=False
    ):
        seen.append(model)
        return {env: {"success": 0.9, "m_psi": 10.0, "gt_m_psi": 9.0} for env in env_ids}

    monkeypatch.setattr(ship, "evaluate", evaluate)
    folder, validation = ship.choose(run, ["SRPB-Crowd-v0"], 100)
    assert seen == [run / "best" / "model.zip"]
    results = validation["results"]
    assert folder == run / "best" and results["final"] == results["best"]
    (run / "vecnormalize.npz").write_bytes(b"other statistics")  # same weights, other statistics
    seen.clear()
    ship.choose(run, ["SRPB-Crowd-v0"], 100)
    assert seen == [run / "best" / "model.zip", run / "model.zip"]
    (run / "vecnormalize.npz").write_bytes(b"the same statistics")
    tiny(1).save(run / "model.zip")  # other weights
    seen.clear()
    ship.choose(run, ["SRPB-Crowd-v0"], 100)
    assert seen == [run / "best" / "model.zip", run / "model.zip"]


def _fake_run(run, best: bool, interrupted: bool = False, weights=None, kwargs="{}"):
    """A run folder as srpb-gym train leaves it, with placeholder model files (``weights``:
    the reward weights its run.json records; ``None``: a run made before they were;
    ``kwargs``: its env kwargs, YAML)."""
    (run / "best").mkdir(parents=True) if best else run.mkdir(parents=True)
    for folder in (run, run / "best") if best else (run,):
        (folder / "model.zip").write_text(f"model in {folder.name}")
        (folder / "vecnormalize.npz").write_text("statistics")
    (run / "config.yaml").write_text(
        "env: SRPB-Corridor-v0\nreward: srpb\nseed: 0\nhyperparams: {eval_episodes: 20}\n"
        f"env_kwargs: {kwargs}\n"
    )
    machine = {"cpu_count": 2, "processor": "x", "system": "y", "torch_threads": 1}
    info = {"steps": 1000, "wall_time_s": 60.0, "machine": machine,
            "versions": {"srpb-gym": "0"}, "interrupted": interrupted}  # fmt: skip
    if weights is not None:
        info["reward_weights"] = weights
    (run / "run.json").write_text(__import__("json").dumps(info))
    (run / "command.txt").write_text("srpb-gym train --env SRPB-Corridor-v0\n")


def test_ship_packages_the_chosen_checkpoint(tmp_path, monkeypatch, capsys):
    from srpb_gym.observation import ObservationConfig
    from training import ship

    workers_seen = []

    def evaluate(
        model, env_ids, episodes, seed, out, env_kwargs=None, workers=1, trust_pickle=False
    ):
        workers_seen.append(workers)
        good = model.parent.name == "run"  # the final model is the better one here
        return {env: {"success": 1.0 if good else 0.5, "collision": 0.0, "timeout": 0.0,
                      "m_psi": 10.0, "m_fsi": 0.0, "m_dir": 0.0, "m_mef": 20.0,
                      "gt_m_psi": 9.0, "gt_m_fsi": 0.0, "gt_m_dir": 0.0,
                      "caused_collision": 0.0} for env in env_ids}  # fmt: skip

    stamped = []
    monkeypatch.setattr(ship, "evaluate", evaluate)
    monkeypatch.setattr(ship, "MODELS_DIR", tmp_path / "models")
    monkeypatch.setattr(ship, "stamp_observation", lambda *args: stamped.append(args))
    _fake_run(tmp_path / "run", best=True, interrupted=True,
              kwargs="{observation: {lidar_encoding: log}, reward_weights: {obs: -1.0, "
                     "psi: -5.0, fsi: -3.0, dir: -1.0, collision: -110.0}}")  # fmt: skip
    card = ship.ship(tmp_path / "run", "ppo-corridor-srpb", 100, 10_000, False, validate=50,
                     workers=2)  # fmt: skip
    assert workers_seen == [2, 2, 2]  # validation of best/ and of the final model, the test
    shipped = tmp_path / "models" / "ppo-corridor-srpb"
    # the chosen model is given the observation settings of the run's env kwargs
    assert stamped == [(tmp_path / "run" / "model.zip", ObservationConfig(lidar_encoding="log"))]
    assert (
        "| observation | `{lidar_encoding: log}`, the rest the defaults;"
        in (shipped / "card.md").read_text()
    )
    assert (shipped / "model.zip").read_text() == "model in run"  # the final model
    assert card["checkpoint"] == "final" and card["validation"]["chosen"] == "final"
    text = (shipped / "card.md").read_text()
    assert "final, chosen over the best periodic evaluation's checkpoint on 50" in text
    assert "stopped by hand" in text
    # the processor of the test figures
    processor = card["test"]["machine"]["cpu"]
    assert processor and f"Measured on {processor}" in text
    # not recorded by the run: those the environment pays now, said so
    assert card["reward_weights"]["corridor"]["psi"] == -5.0
    assert "| reward weights | corridor: `progress` 1, `success` 10, `collision` -110, " in text
    assert "does not record the reward weights" in capsys.readouterr().err
    with pytest.raises(ValueError, match="exclude each other"):
        ship.ship(tmp_path / "run", "ppo-corridor-srpb", 100, 10_000, True, validate=50)
    # no best/: the final model, said so, and no validation
    _fake_run(tmp_path / "plain", best=False)
    card = ship.ship(tmp_path / "plain", "ppo-corridor-srpb", 100, 10_000, False, validate=50)
    assert card["checkpoint"] == "final" and card["validation"] is None
    assert "no best/" in capsys.readouterr().err
    assert "stopped by hand" not in (shipped / "card.md").read_text()
    # recorded by the run: the card keeps them
    recorded = {"corridor": {"progress": 1.0, "psi": -2.0}}
    _fake_run(tmp_path / "recorded", best=False, weights=recorded)
    card = ship.ship(tmp_path / "recorded", "ppo-corridor-srpb", 100, 10_000, False)
    assert card["reward_weights"] == recorded
    assert (
        "| reward weights | corridor: `progress` 1, `psi` -2 |" in (shipped / "card.md").read_text()
    )
    assert "does not record" not in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "message"), [
    (["--final", "--validate", "100"], "--final and --validate exclude each other"),
    (["--workers", "0"], "--workers must be at least 1, got 0"),
])  # fmt: skip
def test_ship_refuses_bad_options(monkeypatch, capsys, argv, message):
    from training import ship

    monkeypatch.setattr(sys, "argv", ["ship", "runs/train/none", "--name", "x", *argv])
    with pytest.raises(SystemExit) as exc:
        ship.main()
    assert exc.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("name", ["", "..", ".", "x", "ppo-corridor-srpb/..",
                                  "../ppo-corridor-srpb", "ppo-nowhere-srpb",
                                  "ppo-corridor-bogus", "/tmp"])  # fmt: skip
def test_ship_takes_only_a_shipped_models_name(tmp_path, monkeypatch, capsys, name):
    """The folder of --name is replaced: only a name of the shipped form is taken, so no
    other folder (the models folder itself, the package) is ever removed."""
    from training import ship

    models = tmp_path / "models"
    (models / "ppo-crowd-srpb").mkdir(parents=True)
    (models / "ppo-crowd-srpb" / "model.zip").write_text("kept")
    monkeypatch.setattr(ship, "MODELS_DIR", models)
    monkeypatch.setattr(ship, "evaluate", lambda *a, **k: pytest.fail("evaluated"))
    with pytest.raises(ValueError, match="is not a shipped model's name"):
        ship.ship(tmp_path / "run", name, 100, 10_000, False)
    with pytest.raises(SystemExit) as exc:
        ship.main([str(tmp_path / "run"), "--name", name, "--candidates", "1"])
    assert exc.value.code == 2 and "is not a shipped model's name" in capsys.readouterr().err
    assert (models / "ppo-crowd-srpb" / "model.zip").read_text() == "kept"
    assert ship.check_name("ppo-mix-srpb") == models / "ppo-mix-srpb"


def test_learning_curves_start_where_the_initial_model_stopped(tmp_path):
    """A fine-tuned model's curve continues from its initial model's steps, labelled by the
    name of that model (a shipped model's folder, or a run for a run's best/)."""
    import json

    from training.plot_curves import MODELS_DIR, start

    folder = tmp_path / "ppo-crowd-srpb"
    folder.mkdir()
    assert start(folder) == (0, None)  # no card
    for model, name in (("srpb_gym/models/ppo-crowd-task/model.zip", "ppo-crowd-task"),
                        ("runs/train/crowd-social/best/model.zip", "crowd-social/best"),
                        (None, None)):  # fmt: skip
        init = None if model is None else {"model": model, "steps": 1_100_000}
        (folder / "card.json").write_text(json.dumps({"training": {"init": init}}))
        assert start(folder) == ((0, None) if model is None else (1_100_000, name))
    for name in model_names():  # the shipped models, as their cards say
        init = card(name)["training"].get("init")
        steps, label = start(MODELS_DIR / name)
        assert (steps, label is None) == ((0, True) if init is None else (init["steps"], False))


def test_the_card_names_each_scenario_teacher_of_a_distillation():
    from training import ship

    # the hyperparameters as --hyperparams takes them
    assert ship._flow({"crowd": "dwa", "corridor": "ppo-corridor-srpb"}) == (
        "{crowd: dwa, corridor: ppo-corridor-srpb}"
    )
    assert ship._flow([256, 256]) == "[256, 256]" and ship._flow(5e-5) == "5e-05"

    single = {"planner": "dwa", "demo_episodes": 150, "demo_steps": 12345,
              "demo_success": 0.7, "action_mse": 0.0123}  # fmt: skip
    assert ship._start({"warm_start": single}) == (
        "behaviour cloning of `dwa`: 150 episodes, 12,345 steps (70 % success), action MSE 0.012"
    )
    by = {"corridor": {"teacher": "ppo-corridor-srpb", "episodes": 2, "success": 1.0},
          "crowd": {"teacher": "dwa", "episodes": 4, "success": 0.25}}  # fmt: skip
    text = ship._start({"warm_start": {**single, "demo_episodes": 6, "demo_success": 0.5,
                                       "teachers": {"corridor": "ppo-corridor-srpb"},
                                       "demo_by_scenario": by}})  # fmt: skip
    assert text == ("behaviour cloning of a teacher per scenario (corridor: "
                    "`ppo-corridor-srpb`, 2 episodes (100 % success); crowd: `dwa`, 4 "
                    "episodes (25 % success)): 6 episodes, 12,345 steps (50 % success), "
                    "action MSE 0.012")  # fmt: skip
    rounds = [{"episodes": 300, "steps": 81234, "success": 0.8},
              {"episodes": 300, "steps": 80000, "success": 0.875}]  # fmt: skip
    assert ship._start({"warm_start": {**single, "dagger": rounds}}) == (
        "behaviour cloning of `dwa`: 150 episodes, 12,345 steps (70 % success); DAgger round 1: "
        "the clone drove 300 episodes, 81,234 steps (80 % success), labelled by `dwa`; "
        "DAgger round 2: the clone drove 300 episodes, 80,000 steps (88 % success), labelled "
        "by `dwa`, action MSE 0.012"
    )


def test_the_card_names_the_processor_of_its_test_figures():
    from training.ship import _cpu_text

    assert _cpu_text({"cpu": "Xeon"}) == "Xeon"
    assert _cpu_text({"cpu": "Xeon", "torch_cpu_capability": "AVX512", "MKL_CBWR": "AVX2"}) == (
        "Xeon, torch kernels AVX512, MKL_CBWR=AVX2"
    )


@pytest.mark.parametrize("name", SINGLE)
def test_the_card_text_is_the_card_data_and_its_hyperparameters_retrain(name):
    import dataclasses
    import json

    from srpb_gym.training.config import parse_overrides, resolve
    from training.ship import _flow, card_markdown

    folder = model_path(name).parent
    facts = json.loads((folder / "card.json").read_text(encoding="utf-8"))
    assert (folder / "card.md").read_text(encoding="utf-8") == card_markdown(name, facts)
    # the hyperparameters as the card prints them, given to --hyperparams, resolve to the
    # hyperparameters the model was trained with
    hyper = facts["hyperparams"]
    config = resolve(facts["env"], parse_overrides([f"{k}={_flow(v)}" for k, v in hyper.items()]))
    resolved = {k: list(v) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(config).items() if k in hyper}  # fmt: skip
    assert resolved == hyper


def test_the_card_reports_the_true_people_beside_the_tracked():
    import math

    from srpb_gym.evaluation.data import EpisodeResult
    from srpb_gym.sim.contact import Collision
    from srpb_gym.training.callbacks import EVAL_METRICS, summarize_results
    from training.ship import _truth_table, with_caused

    def row(psi, gt_psi, hit=""):
        metrics = dict.fromkeys(EVAL_METRICS, 1.0)
        first = Collision("person", hit, 0.5, 0.5, 0.5, 0.0) if hit else None
        return EpisodeResult(env="SRPB-Crowd-v0", planner="p", seed=0, is_success=not hit,
                             collision=bool(hit), timeout=False,
                             metrics={**metrics, "m_psi": psi},
                             ground_truth={**metrics, "m_psi": gt_psi, "m_dir": math.nan},
                             first_collision=first)  # fmt: skip

    rows = [row(10.0, 20.0), row(30.0, 40.0, "robot"), row(50.0, 60.0, "person"), row(0, 0)]
    f = with_caused(summarize_results(rows), rows)["SRPB-Crowd-v0"]
    assert (f["m_psi"], f["gt_m_psi"]) == (20.0, 30.0)  # medians of each
    assert math.isnan(f["gt_m_dir"]) and f["m_dir"] == 1.0
    assert f["collision"] == 0.5 and f["caused_collision"] == 0.25  # the person hit the other
    table = _truth_table({"SRPB-Crowd-v0": f})
    assert table[-1].startswith("| SRPB-Crowd-v0 | 50.0% | 50.0% (25.0%) | 0.0% | 30 / 20 |")
