"""Shipping a policy shared by several robots: its figures, its card, its recipe."""

from __future__ import annotations

import json
import math
import shlex
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from srpb_gym.evaluation.data import EpisodeResult  # noqa: E402
from srpb_gym.models import card, model_names, model_path  # noqa: E402
from srpb_gym.sim.contact import Collision  # noqa: E402
from training import select_checkpoint, ship_multi  # noqa: E402
from training.retrain_models import MODELS, MULTI_RECIPES, commands, waves  # noqa: E402

MULTI = [name for name in model_names() if name in MULTI_RECIPES]
#: the metrics of a row besides m_psi (m_dir not defined in any)
OTHER = {"m_fsi": 0.0, "m_dir": math.nan, "m_mef": 1.0}


def row(robot: int, success: bool, hit: str = "", by: str = "robot", psi: float = 0.0,
        gt_psi: float = 0.0) -> EpisodeResult:  # fmt: skip
    first = Collision(hit, by, 0.5, 0.5, 0.5, 0.0) if hit else None
    return EpisodeResult(env="SRPB-Crowd-v0", planner="p", seed=0, is_success=success,
                         collision=bool(hit), timeout=not success and not hit,
                         metrics={**OTHER, "m_psi": psi}, robot=robot,
                         ground_truth={**OTHER, "m_psi": gt_psi},
                         first_collision=first)  # fmt: skip


def test_the_figures_of_robot_episodes():
    rows = [row(0, True, psi=10.0, gt_psi=8.0), row(1, False, "robot", psi=20.0, gt_psi=4.0),
            row(2, False, "person", "person", psi=30.0, gt_psi=6.0),
            row(0, True, psi=40.0, gt_psi=2.0), row(1, True), row(2, False)]  # fmt: skip
    f = ship_multi.summarize(rows)
    assert (f["episodes"], f["robots"]) == (6, 3)
    assert f["success"] == 3 / 6 and f["collision"] == 2 / 6 and f["timeout"] == 1 / 6
    assert f["robot_collision"] == 1 / 6  # the first collision was with a robot
    assert f["caused_collision"] == 1 / 6  # the person walked into robot 2
    assert f["success_by_robot"] == [1.0, 0.5, 0.0]
    low, high = f["success_ci"]
    assert 0.18 < low < 0.19 and 0.81 < high < 0.82  # Wilson, 3 of 6
    assert f["gt_m_psi"] == 3.0 and f["m_psi"] == 15.0  # medians of 0, 0, 2, 4, 6, 8 / ...
    assert math.isnan(f["m_dir"])  # no episode has it


def test_a_name_names_the_runs_robots():
    assert ship_multi.check_name("ppo-crowd-srpb-3robots", 3).name == "ppo-crowd-srpb-3robots"
    bad = (("ppo-crowd-srpb-3robots", 2), ("ppo-crowd-srpb", 3),
           ("ppo-nowhere-srpb-3robots", 3), ("../ppo-crowd-srpb-3robots", 3))  # fmt: skip
    for name, robots in bad:
        with pytest.raises(ValueError, match="--name: "):
            ship_multi.check_name(name, robots)


def test_ship_packages_a_run_whose_card_command_reproduces_it(tmp_path, monkeypatch, capsys):
    from srpb_gym.cli import main as cli_main
    from srpb_gym.evaluation.stats import read_episodes
    from training import multi_robot

    run = tmp_path / "run"
    multi_robot.train("corridor", 2, 1, 64, str(run), reward="task",
                      hyperparams={"n_steps": 32, "batch_size": 64},
                      env_kwargs={"reward_people": "ground_truth"},
                      log=lambda line: None)  # fmt: skip
    monkeypatch.setattr(ship_multi, "MODELS_DIR", tmp_path / "models")
    facts = ship_multi.ship(run, "ppo-corridor-task-2robots", episodes=2, seed=7,
                            baselines=["dwa"])  # fmt: skip
    target = tmp_path / "models" / "ppo-corridor-task-2robots"
    assert {p.name for p in target.iterdir()} == {"model.zip", "vecnormalize.npz", "card.json",
                                                  "card.md"}  # fmt: skip
    assert json.loads((target / "card.json").read_text()) == json.loads(json.dumps(facts))
    assert (target / "card.md").read_text() == ship_multi.card_markdown(facts["name"], facts)
    test = facts["test"]
    assert list(test["results"]) == ["dwa", "ppo-corridor-task-2robots"]
    # a test evaluation that stopped half way continues (here: every episode was done)
    rows = (run / "test" / "episodes.csv").read_text().splitlines()
    (run / "test" / "episodes.csv").write_text("\n".join(rows[:3]) + "\n")  # 1 episode of 4
    again = ship_multi.ship(run, "ppo-corridor-task-2robots", episodes=2, seed=7,
                            baselines=["dwa"], resume=True, candidates=2,
                            side_by_side=3)  # fmt: skip
    assert again["test"]["results"] == test["results"]
    # the card states the candidates tested on these seeds and the runs sharing the cores
    assert (again["test"]["candidates"], again["training"]["side_by_side"]) == (2, 3)
    text = (target / "card.md").read_text()
    assert "2 candidate runs were trained for this slot and tested on these seeds" in text
    assert "min; 3 runs side by side on the machine's cores" in text
    assert "1 candidate run was trained" in ship_multi.card_markdown(facts["name"], facts)
    assert "side by side" not in ship_multi.card_markdown(facts["name"], facts)
    with pytest.raises(ValueError, match="candidates: at least 1"):
        ship_multi.ship(run, "ppo-corridor-task-2robots", episodes=2, seed=7, candidates=0)
    assert len((run / "test" / "episodes.csv").read_text().splitlines()) == 1 + 4 * 2
    assert test["env_kwargs"] == {}  # reward_people is the reward's, not the evaluation's
    assert facts["env_kwargs"]["reward_people"] == "ground_truth"
    assert test["seed_range"] == "training" and test["episodes"] == 2  # seeds 7 and 8
    # the card's command, the model by its file, gives the card's figures
    words = shlex.split(test["command"])
    words[words.index("--policy") + 1] = str(target / "model.zip")
    assert words[:2] == ["srpb-gym", "eval"] and "--robots" in words
    out = tmp_path / "again"
    assert cli_main([*words[1:], "--out", str(out)]) == 0, capsys.readouterr().err
    again = read_episodes(str(out / "episodes.csv"))
    for planner, label in (("dwa", "dwa"), ("ppo-corridor-task-2robots", "model")):
        figures = ship_multi.summarize([r for r in again if r.planner == label])
        for key in ("success", "collision", "robot_collision", "success_by_robot", "gt_m_psi"):
            assert figures[key] == test["results"][planner][key], (planner, key)


def test_the_recipe_starts_from_the_crowd_specialist_after_it_is_retrained():
    name = "ppo-crowd-srpb-3robots"
    routes, train, select, ship = commands(name, [4], 1, root="runs/x")
    assert routes[1:4] == ["-m", "srpb_gym", "train"] and ship[1:3] == [
        "-m",
        "training.ship_multi",
    ]
    assert train[1:3] == ["-m", "training.multi_robot"]
    # first alone on every route of the scenario, then among the other robots from there
    route = "route=[0, 1, 2, 2]"  # the 3 robots' routes, robot 2's twice as often
    assert routes[routes.index("--init") + 1] == "ppo-crowd-srpb" and route in routes
    first = routes[routes.index("--out") + 1]
    assert train[train.index("--init") + 1] == f"{first}/best" and "--seed" in train
    # every checkpoint kept, one chosen on checkpoint-selection seeds, that one shipped
    run = train[train.index("--out") + 1]
    assert "--keep-checkpoints" in train and train[train.index("--save-every") + 1] == "200000"
    assert select[1:4] == ["-m", "training.select_checkpoint", run]
    assert "--seed" not in select and "--episodes" not in select  # the defaults
    assert ship[ship.index("training.ship_multi") + 1] == run
    crowd = commands("ppo-crowd-srpb", [4], 1, ship=False)[0]
    kwargs = crowd[crowd.index("--env-kwargs") + 1 : crowd.index("--hyperparams")]
    assert train[train.index("--env-kwargs") + 1 : train.index("--hyperparams")] == kwargs
    assert routes[routes.index("--env-kwargs") + 1 : routes.index("--hyperparams")] == [
        *kwargs,
        route,
    ]
    assert routes[routes.index("--hyperparams") :] == train[train.index("--hyperparams") :]
    assert waves([name, "ppo-crowd-srpb"], []) == [["ppo-crowd-srpb"], [name]]
    assert waves([name], ["ppo-crowd-srpb"]) == [[name]]
    with pytest.raises(ValueError, match=r"its teacher ppo-crowd-srpb \(crowd\) is not shipped"):
        waves([name], [])
    assert MULTI_RECIPES[name].init in MODELS


@pytest.mark.parametrize("name", MULTI)
def test_a_shipped_multi_robot_model_acts_for_every_robot(name):
    import srpb_gym
    from srpb_gym.planners.learned import LearnedPolicy
    from srpb_gym.registration import SCENARIO_IDS

    facts = card(name)
    target = model_path(name)
    assert target is not None
    assert (target.parent / "card.md").read_text() == ship_multi.card_markdown(name, facts)
    policy = LearnedPolicy(target, vecnormalize=str(target.parent / "vecnormalize.npz"))
    kwargs = {k: v for k, v in facts["env_kwargs"].items() if k == "observation"}
    par = srpb_gym.parallel_env(scenario=SCENARIO_IDS[facts["env"]], n_robots=facts["robots"],
                                **kwargs)  # fmt: skip
    obs, _ = par.reset(seed=0)
    for _ in range(5):
        actions = {a: policy.act(obs[a], par.knowledge(a)) for a in par.agents}
        assert all(par.action_space(a).contains(v) for a, v in actions.items())
        obs, *_ = par.step(actions)
    par.close()


def test_the_card_names_the_run_its_initial_model_comes_from(tmp_path):
    run = tmp_path / "routes"
    (run / "best").mkdir(parents=True)
    (run / "command.txt").write_text("srpb-gym train --env SRPB-Crowd-v0 --init ppo-crowd-srpb\n")
    info = {"steps": 1007616, "wall_time_s": 874.4, "init": {"model": "/x/ppo/model.zip"}}
    (run / "run.json").write_text(json.dumps(info))
    for model in (run / "best" / "model.zip", run / "model.zip"):  # best/ or the final one
        stage = ship_multi.first_stage(model)
        assert stage == {
            "command": "srpb-gym train --env SRPB-Crowd-v0 --init ppo-crowd-srpb",
            "steps": 1007616,
            "wall_time_s": 874.4,
            "init": "/x/ppo/model.zip",
        }
    assert ship_multi.first_stage(tmp_path / "shipped" / "model.zip") is None
    init = {"model": "routes/best/model.zip", "steps": 700000, "run": stage}
    assert ship_multi._start_text(init) == (
        "the trained model `routes/best/model.zip` after 700,000 steps, of the run `srpb-gym "
        "train --env SRPB-Crowd-v0 --init ppo-crowd-srpb` (1,007,616 steps in 14.6 min, from "
        "`/x/ppo/model.zip`)"
    )
    assert ship_multi._start_text({**init, "run": None}).endswith("after 700,000 steps")
    assert ship_multi._start_text(None) == "random"


def test_the_task_twin_of_the_shared_policy_differs_in_its_reward_and_start_only():
    srpb = commands("ppo-crowd-srpb-3robots", [1], 1, ship=False)
    task = commands("ppo-crowd-task-3robots", [1], 1, ship=False)
    assert len(srpb) == len(task) == 3
    assert [c[2] for c in srpb[2:]] == [c[2] for c in task[2:]] == ["training.select_checkpoint"]
    for a, b in zip(srpb[:2], task[:2]):
        # the same stages, budgets and hyperparameters
        assert a[a.index("--steps") + 1] == b[b.index("--steps") + 1]
        assert a[a.index("--hyperparams") :] == b[b.index("--hyperparams") :]
        assert a[a.index("--reward") + 1] == "srpb" and b[b.index("--reward") + 1] == "task"
    # each from the crowd specialist of its own preset, paid as that specialist is
    assert task[0][task[0].index("--init") + 1] == "ppo-crowd-task"
    single = commands("ppo-crowd-task", [1], 1, ship=False)[0]
    kwargs = single[single.index("--env-kwargs") + 1 : single.index("--hyperparams")]
    train = task[1]
    assert train[train.index("--env-kwargs") + 1 : train.index("--hyperparams")] == kwargs
    assert not any("psi" in k for k in kwargs)


def test_retraining_runs_the_seeds_of_every_model_side_by_side(monkeypatch):
    import subprocess
    import threading

    from training import retrain_models as rm

    names = ["ppo-crowd-srpb-3robots", "ppo-crowd-task-3robots"]
    # the six first stages wait for each other: they must all be running at once
    barrier = threading.Barrier(6, timeout=20)
    ran, lock = [], threading.Lock()

    def run(cmd, check):
        stage = cmd[cmd.index("-m") + 1]
        seed = cmd[cmd.index("--seed") + 1] if "--seed" in cmd else None
        if stage == "srpb_gym":
            barrier.wait()
        with lock:
            ran.append((stage, cmd[cmd.index("--reward") + 1] if "--reward" in cmd else None,
                        seed))  # fmt: skip
        failing = stage == "srpb_gym" and seed == "1" and "srpb" in cmd
        return subprocess.CompletedProcess(cmd, 1 if failing else 0)

    monkeypatch.setattr(rm.subprocess, "run", run)
    monkeypatch.setattr(rm.sys, "argv", ["retrain_models", *names, "--seeds", "0", "1", "2",
                                         "--jobs", "6", "--no-ship"])  # fmt: skip
    assert rm.main() == 1  # one run failed
    firsts = [r for r in ran if r[0] == "srpb_gym"]
    seconds = [r for r in ran if r[0] == "training.multi_robot"]
    # each second stage's checkpoint is chosen after it
    assert len([r for r in ran if r[0] == "training.select_checkpoint"]) == len(seconds) == 5
    assert len(firsts) == 6
    # each run's second stage after its first; not after a failed first
    assert sorted(seconds) == sorted(
        ("training.multi_robot", reward, seed) for reward in ("srpb", "task")
        for seed in "012" if (reward, seed) != ("srpb", "1")
    )  # fmt: skip
    for stage in seconds:
        assert ran.index(("srpb_gym", *stage[1:])) < ran.index(stage)
    # the chains are a model's commands by seed, the shipping command left out
    plan = rm.commands(names[0], [0, 1, 2], 1)
    chains = rm.seed_chains(plan, [0, 1, 2])
    assert [len(c) for c in chains] == [3, 3, 3]
    assert [c[-1][2:4] for c in chains] == [
        ["training.select_checkpoint", c[1][c[1].index("--out") + 1]] for c in chains
    ]
    assert all(plan[-1] not in chain for chain in chains)


def test_the_recipe_reproduces_the_shipped_policy_stage_by_stage():
    """Both stages of the shipped 3-robot policy ran the recipe's commands (but for the
    output folders and the torch threads of runs side by side), and the checkpoint shipped
    is the one the recipe's selection chose."""
    name = "ppo-crowd-srpb-3robots"
    facts = card(name)
    routes, train, _, _ = commands(name, [facts["seed"]], 1)

    def options(command: list[str] | str) -> list[str]:
        words = shlex.split(command) if isinstance(command, str) else command
        words = words[next(i for i, w in enumerate(words) if w.startswith("--")) :]
        paths = {words.index(k) + 1 for k in ("--out", "--init")}
        return [w for i, w in enumerate(words) if i not in paths and not w.startswith("torch_")]

    shipped = facts["training"]
    assert options(shipped["init"]["run"]["command"]) == options(routes)
    assert options(shipped["command"]) == options(train)
    assert facts["checkpoint"] == facts["selection"]["chosen"] != "final"
    # the recipe's selection command takes the defaults
    assert (facts["selection"]["seed"], facts["selection"]["episodes"]) == (
        select_checkpoint.SELECTION_SEED,
        select_checkpoint.SELECTION_EPISODES,
    )
