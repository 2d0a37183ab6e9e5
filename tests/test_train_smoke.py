"""A short training run end to end: train, save, reload, evaluate with `srpb-gym eval`;
Ctrl-C and the wall-clock limit still save a usable model."""

from __future__ import annotations

import csv
import dataclasses
import json
import shlex
import shutil

import pytest
import yaml

pytest.importorskip("stable_baselines3")

from srpb_gym.cli import main
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.training import callbacks
from srpb_gym.training.config import resolve
from srpb_gym.training.run import train

SMALL = ["n_steps=128", "batch_size=64", "n_epochs=2", "net_arch=[32, 32]", "eval_episodes=1"]


def test_train_then_evaluate_the_run(tmp_path, capsys):
    out = tmp_path / "run"
    rc = main(["train", "--env", "SRPB-Corridor-v0", "--reward", "task", "--steps", "1024",
               "--seed", "3", "--hyperparams", *SMALL, "eval_freq=512", "--out", str(out),
               "--no-progress"])  # fmt: skip
    assert rc == 0
    captured = capsys.readouterr()
    assert "finished after 1024 steps" in captured.out
    assert "episode/s" not in captured.err  # --no-progress: no bar, evaluations included
    for name in (
        "model.zip",
        "vecnormalize.npz",
        "config.yaml",
        "command.txt",
        "run.json",
        "progress.csv",
        "evaluations.csv",
        "best/model.zip",
        "best/vecnormalize.npz",
    ):
        assert (out / name).is_file(), name  # fmt: skip
    assert list((out / "tb").iterdir()), "no TensorBoard events"
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env"] == "SRPB-Corridor-v0" and config["reward"] == "task"
    assert config["seed"] == 3 and config["hyperparams"]["n_steps"] == 128
    run = json.loads((out / "run.json").read_text())
    assert run["steps"] == 1024 and run["interrupted"] is False and "torch" in run["versions"]
    assert run["machine"]["cpu_count"] >= 1
    task = {"progress": 1.0, "success": 10.0, "collision": -25.0, "time": -0.1}
    assert run["reward_weights"] == {"corridor": task}  # the task preset: no scenario weights
    assert "--reward task" in (out / "command.txt").read_text()
    with open(out / "progress.csv", newline="") as f:
        header = next(csv.reader(f))
    assert {"reward/progress", "reward/collision", "episode/success"} <= set(header)
    # the reward as the learner sees it: never clipped, a collision beyond the shaping bound
    assert {"train/reward_clip_fraction", "train/collision_margin"} <= set(header)
    with open(out / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    fractions = [float(r["train/reward_clip_fraction"]) for r in rows
                 if r["train/reward_clip_fraction"]]  # fmt: skip
    assert fractions and set(fractions) == {0.0}
    assert all(float(r["train/collision_margin"]) > 0 for r in rows if r["train/collision_margin"])
    assert any(h.startswith("srpb/m_psi") for h in header), "episode metrics not logged"
    with open(out / "evaluations.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [512, 1024]
    assert all(r["env"] == "SRPB-Corridor-v0" and r["episodes"] == "1" for r in rows)
    assert (out / "eval" / "step_000001024" / "episodes.csv").is_file()  # the latest
    assert len(list((out / "eval").iterdir())) <= 2  # and the best

    # the command the run prints evaluates its best checkpoint
    hint = next(line for line in captured.out.splitlines() if line.startswith("evaluate it: "))
    words = shlex.split(hint.removeprefix("evaluate it: "))
    assert words == ["srpb-gym", "eval", "--env", "SRPB-Corridor-v0", "--policy", str(out / "best")]
    rc = main([*words[1:], "--episodes", "1", "--warmup", "0", "--out", str(tmp_path / "eval")])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert f"observations normalised with {out / 'best' / 'vecnormalize.npz'}" in captured.err
    with open(tmp_path / "eval" / "episodes.csv", newline="") as f:
        assert [r["planner"] for r in csv.DictReader(f)] == ["best"]


def test_ctrl_c_saves_a_usable_model(tmp_path, monkeypatch):
    stop_at = 300

    def interrupt(self):
        if self.num_timesteps >= stop_at:
            raise KeyboardInterrupt
        return True

    monkeypatch.setattr(callbacks.EpisodeStatsCallback, "_on_step",
                        lambda self: interrupt(self))  # fmt: skip
    config = resolve("SRPB-Corridor-v0", {"n_steps": 128, "batch_size": 64, "n_epochs": 1,
                                          "net_arch": [16], "eval_freq": 0})  # fmt: skip
    result = train("SRPB-Corridor-v0", config, out=str(tmp_path / "run"), progress=False,
                   log=lambda line: None)  # fmt: skip
    assert result.interrupted and stop_at <= result.steps < 400
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["interrupted"] is True and run["steps"] == result.steps
    from srpb_gym.planners.learned import LearnedPolicy

    policy = LearnedPolicy(tmp_path / "run" / "model.zip",
                           vecnormalize=tmp_path / "run" / "vecnormalize.npz")  # fmt: skip
    import gymnasium as gym

    env = gym.make("SRPB-Corridor-v0")
    obs, _ = env.reset(seed=0)
    action = policy.act(obs, env.unwrapped.knowledge())
    assert env.action_space.contains(action)
    env.close()


def test_sigterm_saves_like_ctrl_c(tmp_path, monkeypatch):
    import os
    import signal

    def terminate(self):
        if self.num_timesteps == 300:
            os.kill(os.getpid(), signal.SIGTERM)
        return True

    monkeypatch.setattr(callbacks.EpisodeStatsCallback, "_on_step",
                        lambda self: terminate(self))  # fmt: skip
    before = signal.getsignal(signal.SIGTERM)
    config = resolve("SRPB-Corridor-v0", {"n_steps": 128, "batch_size": 64, "n_epochs": 1,
                                          "net_arch": [16], "eval_freq": 0})  # fmt: skip
    result = train("SRPB-Corridor-v0", config, out=str(tmp_path / "run"), progress=False,
                   log=lambda line: None)  # fmt: skip
    assert result.interrupted and 300 <= result.steps < 400
    assert json.loads((tmp_path / "run" / "run.json").read_text())["interrupted"] is True
    assert (tmp_path / "run" / "model.zip").is_file()
    assert signal.getsignal(signal.SIGTERM) is before  # the process's own handler is back


def test_sigterm_during_a_periodic_evaluation_stops_the_run(tmp_path, monkeypatch):
    """The evaluation harness ends its run at the signal; training stops then too, saving
    the model, and the cut-short evaluation is neither recorded nor kept."""
    import os
    import signal

    from srpb_gym.evaluation import runner

    episode = runner.run_episode

    def terminated(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        return episode(*args, **kwargs)

    monkeypatch.setattr(runner, "run_episode", terminated)
    config = resolve("SRPB-Corridor-v0", {"n_steps": 128, "batch_size": 64, "n_epochs": 1,
                                          "net_arch": [16], "eval_freq": 256,
                                          "eval_episodes": 1, "n_timesteps": 2048})  # fmt: skip
    lines: list[str] = []
    result = train("SRPB-Corridor-v0", config, out=str(tmp_path / "run"), progress=False,
                   log=lines.append)  # fmt: skip
    assert result.interrupted and 256 <= result.steps < 512, (result.steps, lines)
    assert (tmp_path / "run" / "model.zip").is_file()
    assert not (tmp_path / "run" / "evaluations.csv").exists()
    assert not (tmp_path / "run" / "best").exists()
    assert not list((tmp_path / "run" / "eval").glob("step_*"))


def test_wall_clock_limit_stops_as_finished(tmp_path):
    small = {"n_steps": 64, "batch_size": 64, "n_envs": 1, "n_epochs": 1, "net_arch": [8],
             "eval_freq": 0}  # fmt: skip
    config = resolve("SRPB-Corridor-v0", small)
    result = train("SRPB-Corridor-v0", config, out=str(tmp_path / "run"), progress=False,
                   log=lambda line: None, max_minutes=1e-6)  # fmt: skip
    assert not result.interrupted and result.steps < config.n_timesteps
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["time_limit_reached"] is True
    assert (tmp_path / "run" / "model.zip").is_file()


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--env", "SRPB-Nowhere-v0"], "--env: unknown environment 'SRPB-Nowhere-v0'"),
        (["--env", "SRPB-Crowd-v0", "--reward", "fast"], "--reward: choose one of: srpb, task"),
        (
            ["--env", "SRPB-Crowd-v0", "--hyperparams", "n_stesp=3"],
            "--hyperparams: n_stesp: unknown key",
        ),
        (["--env", "SRPB-Crowd-v0", "--env-kwargs", "robot={radius: -1}"], "robot"),
        (["--env", "SRPB-Crowd-v0", "--seed", "-1"], "--seed: must be at least 0"),
        (
            ["--env", "SRPB-Crowd-v0", "--hyperparams", "gamma=0.999"],
            "--hyperparams: gamma: with gamma 0.999 the shaping of the 'srpb' reward in "
            "scenario 'crowd' can cost",
        ),
        (["--env", "SRPB-Mix-v0", "--hyperparams", "gamma=0.999"], "could learn to crash"),
        (
            ["--env", "SRPB-Crowd-v0", "--env-kwargs", "colour=1"],
            "--env-kwargs: colour: SRPB-Crowd-v0 takes no such argument",
        ),
        (
            ["--env", "SRPB-Crowd-v0", "--env-kwargs", "crowd={robot_reaction: fast}"],
            "--env-kwargs: crowd.robot_reaction: SRPB-Crowd-v0: expected a number, got 'fast'",
        ),
        (["--env", "SRPB-Crowd-v0", "--max-minutes", "0"], "--max-minutes: must be > 0"),
    ],
)
def test_bad_arguments_exit_2(args, expected, tmp_path, capsys):
    assert main(["train", *args, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("srpb-gym: error: ") and expected in err, err
    assert not (tmp_path / "run").exists()


def test_an_id_registered_elsewhere_is_refused_before_training(tmp_path, capsys):
    """The periodic evaluation runs packaged ids and scenario files: training on another
    registered SRPB id stops before the warm start, with the way out; without
    evaluations it trains."""
    import gymnasium as gym

    gym.register("SRPB-UserRoom-v0", entry_point="srpb_gym.env:SRPBNavEnv",
                 kwargs={"scenario": "corridor"}, max_episode_steps=50)  # fmt: skip
    try:
        args = ["train", "--env", "SRPB-UserRoom-v0", "--hyperparams",
                "pretrain_planner=go-to-goal"]  # fmt: skip
        assert main([*args, "--out", str(tmp_path / "run")]) == 2
        err = capsys.readouterr().err
        assert "--env: SRPB-UserRoom-v0 is not a packaged environment" in err, err
        assert "eval_freq=0" in err and "warm start" not in err, err
        assert not (tmp_path / "run").exists()
        small = {"n_timesteps": 64, "n_steps": 64, "batch_size": 64, "n_envs": 1,
                 "n_epochs": 1, "net_arch": [8], "eval_freq": 0}  # fmt: skip
        result = train("SRPB-UserRoom-v0", resolve("SRPB-UserRoom-v0", small),
                       out=str(tmp_path / "ok"), progress=False, log=lambda line: None)  # fmt: skip
        assert result.steps >= 64 and (tmp_path / "ok" / "model.zip").is_file()
    finally:
        del gym.registry["SRPB-UserRoom-v0"]


def test_warm_start_from_a_planner_is_recorded(tmp_path):
    overrides = {"n_timesteps": 256, "n_steps": 128, "batch_size": 64, "n_epochs": 1,
                 "net_arch": [32, 32], "eval_freq": 0, "pretrain_planner": "go-to-goal",
                 "pretrain_episodes": 1, "pretrain_epochs": 2}  # fmt: skip
    config = resolve("SRPB-Corridor-v0", overrides)
    lines: list[str] = []
    result = train("SRPB-Corridor-v0", config, preset="task", out=str(tmp_path / "run"),
                   progress=False, log=lines.append)  # fmt: skip
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    warm = run["warm_start"]
    assert warm["planner"] == "go-to-goal" and warm["demo_episodes"] == 1
    assert warm["demo_steps"] > 10 and 0.0 <= warm["demo_success"] <= 1.0
    assert any(line.startswith("warm start from go-to-goal") for line in lines)
    assert result.steps == 256


def test_warm_start_from_a_teacher_per_scenario_is_recorded(tmp_path):
    """Distillation: each scenario of the mixture demonstrated by its own teacher (a
    shipped model for one, a planner for the rest); a teacher that does not fit stops the
    run before training and leaves no run folder."""
    from srpb_gym.errors import InputError

    overrides = {"n_timesteps": 128, "n_steps": 128, "batch_size": 64, "n_epochs": 1,
                 "n_envs": 1, "net_arch": [16], "eval_freq": 0,
                 "pretrain_planner": "go-to-goal",
                 "pretrain_teachers": {"corridor": "ppo-corridor-srpb"},
                 "pretrain_episodes": 4, "pretrain_epochs": 1}  # fmt: skip
    kwargs = {"scenarios": ["corridor", "crossing"], "weights": [1, 1]}
    lines: list[str] = []
    train("SRPB-Mix-v0", resolve("SRPB-Mix-v0", overrides), out=str(tmp_path / "run"),
          env_kwargs=kwargs, progress=False, log=lines.append)  # fmt: skip
    warm = json.loads((tmp_path / "run" / "run.json").read_text())["warm_start"]
    assert warm["teachers"] == {"corridor": "ppo-corridor-srpb"}
    assert warm["planner"] == "go-to-goal" and warm["demo_episodes"] == 4
    by = warm["demo_by_scenario"]  # seeds 2,000,000-2,000,003 draw both scenarios
    assert by["corridor"]["teacher"] == "ppo-corridor-srpb" and by["corridor"]["episodes"] == 3
    assert by["crossing"]["teacher"] == "go-to-goal" and by["crossing"]["episodes"] == 1
    assert by["corridor"]["success"] == 1.0  # the shipped corridor model reaches its goals
    assert any(
        line.startswith(
            "warm start from corridor: ppo-corridor-srpb, crossing: go-to-goal: 4 episodes"
        )
        for line in lines
    ), lines

    with pytest.raises(InputError, match="pretrain_teachers: doorway: no scenario"):
        train("SRPB-Mix-v0", resolve("SRPB-Mix-v0", {**overrides,
                                                     "pretrain_teachers": {"doorway": "dwa"}}),
              out=str(tmp_path / "bad"), env_kwargs=kwargs, progress=False,
              log=lambda line: None)  # fmt: skip
    assert not (tmp_path / "bad").exists()


def test_init_starts_from_a_trained_model(tmp_path):
    import numpy as np
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from srpb_gym.errors import InputError
    from srpb_gym.models import OBSERVATION_RECORD, load_vecnormalize, resolve_model
    from srpb_gym.observation import ObservationConfig
    from srpb_gym.training.run import load_init, make_vec_env, read_init

    small = {"n_timesteps": 256, "n_steps": 128, "batch_size": 64, "n_epochs": 1,
             "net_arch": [16], "eval_freq": 0}  # fmt: skip
    config = resolve("SRPB-Corridor-v0", small)
    first = train("SRPB-Corridor-v0", config, preset="task", out=str(tmp_path / "a"),
                  progress=False, log=lambda line: None)  # fmt: skip
    path, stats = resolve_model(first.out, "--init")  # a run folder
    assert path.endswith("model.zip") and stats is not None and stats.endswith(".npz")
    assert resolve_model(path, "--init") == (path, stats)  # the file itself

    venv = VecNormalize(make_vec_env("SRPB-Corridor-v0", config, {"reward": "srpb"}, 1))
    model = PPO("MlpPolicy", venv, seed=1, **config.ppo_kwargs())
    load_init(model, venv, read_init(path), ObservationConfig())
    trained = PPO.load(path).policy.state_dict()
    for key, value in model.policy.state_dict().items():
        np.testing.assert_array_equal(value.numpy(), trained[key].numpy(), err_msg=key)
    np.testing.assert_array_equal(venv.obs_rms.mean, load_vecnormalize(stats).obs_rms.mean)
    venv.close()

    lines: list[str] = []
    second = train("SRPB-Corridor-v0", config, preset="srpb", out=str(tmp_path / "b"),
                   progress=False, log=lines.append, init=first.out)  # fmt: skip
    init = json.loads((tmp_path / "b" / "run.json").read_text())["init"]
    assert init["model"] == path and init["steps"] == first.steps == 256
    assert second.steps == 256 and lines[0].startswith("starting from")
    # every saved model says how it observed; a start that observed otherwise is refused
    assert getattr(PPO.load(path), OBSERVATION_RECORD) == dataclasses.asdict(ObservationConfig())
    with pytest.raises(
        InputError,
        match=r"trained with observation=\{lidar_encoding: linear\}, "
        r"this run observes with observation=\{lidar_encoding: log\} \(start "
        r"from it with --env-kwargs 'observation=\{lidar_encoding: linear\}'\)",
    ):
        train("SRPB-Corridor-v0", config, out=str(tmp_path / "f"), progress=False,
              log=lambda line: None, init=first.out,
              env_kwargs={"observation": {"lidar_encoding": "log"}})  # fmt: skip
    assert not (tmp_path / "f").exists()
    # ... unless asked to fine-tune it to the new settings: it starts from the same weights,
    # records the new settings and run.json keeps the model's
    groups = {"observation": {"lidar_groups": 0.01}}
    with pytest.raises(InputError, match="--init-new-observation fine-tunes it"):
        train("SRPB-Corridor-v0", config, out=str(tmp_path / "f"), progress=False,
              log=lambda line: None, init=first.out, env_kwargs=groups)  # fmt: skip
    train("SRPB-Corridor-v0", config, out=str(tmp_path / "h"), progress=False,
          log=lambda line: None, init=first.out, env_kwargs=groups,
          init_new_observation=True)  # fmt: skip
    init = json.loads((tmp_path / "h" / "run.json").read_text())["init"]
    assert init["observation"] == dataclasses.asdict(ObservationConfig())
    recorded = getattr(PPO.load(tmp_path / "h" / "model.zip"), OBSERVATION_RECORD)
    assert recorded == dataclasses.asdict(ObservationConfig(lidar_groups=0.01))
    # a model saved without the record (e.g. by rl_zoo3) is taken to observe as the run
    # does, and the run says so
    bare = PPO.load(path)
    delattr(bare, OBSERVATION_RECORD)
    (tmp_path / "bare").mkdir()
    bare.save(tmp_path / "bare" / "model.zip")
    shutil.copy(stats, tmp_path / "bare" / "vecnormalize.npz")
    for name, kwargs, said in (("j", {"observation": {"lidar_encoding": "log"}},
                                "{lidar_encoding: log}"), ("k", {}, "default")):  # fmt: skip
        lines = []
        train("SRPB-Corridor-v0", config, out=str(tmp_path / name), progress=False,
              log=lines.append, init=str(tmp_path / "bare"), env_kwargs=kwargs)  # fmt: skip
        assert lines[1] == (
            f"note: {tmp_path / 'bare' / 'model.zip'} records no observation settings (not "
            f"saved by srpb-gym train): taken to observe as this run does, observation={said}, "
            "and the new model records these settings"
        )
        run = json.loads((tmp_path / name / "run.json").read_text())
        assert run["init"]["observation"] is None
        recorded = getattr(PPO.load(tmp_path / name / "model.zip"), OBSERVATION_RECORD)
        assert recorded == dataclasses.asdict(ObservationConfig(**kwargs.get("observation", {})))
    with pytest.raises(InputError, match="names no model to start from"):
        train("SRPB-Corridor-v0", config, out=str(tmp_path / "i"), progress=False,
              log=lambda line: None, init_new_observation=True)  # fmt: skip
    assert not (tmp_path / "i").exists()
    (tmp_path / "bad.zip").write_text("not a model")  # named, and no run folder left
    with pytest.raises(InputError, match="not a stable-baselines3 model"):
        train("SRPB-Corridor-v0", config, out=str(tmp_path / "g"), progress=False,
              log=lambda line: None, init=str(tmp_path / "bad.zip"))  # fmt: skip
    assert not (tmp_path / "g").exists()

    with pytest.raises(InputError, match="do not fit"):
        train("SRPB-Corridor-v0", resolve("SRPB-Corridor-v0", {**small, "net_arch": [8]}),
              out=str(tmp_path / "c"), progress=False, log=lambda line: None,
              init=first.out)  # fmt: skip
    assert not (tmp_path / "c").exists()  # refused before training: no run folder left
    with pytest.raises(InputError, match="this run does not normalise"):
        train("SRPB-Corridor-v0", resolve("SRPB-Corridor-v0", {**small, "normalize": False}),
              out=str(tmp_path / "e"), progress=False, log=lambda line: None,
              init=first.out)  # fmt: skip
    with pytest.raises(InputError, match="not both"):
        train("SRPB-Corridor-v0", resolve("SRPB-Corridor-v0", {**small,
                                                               "pretrain_planner": "dwa"}),
              out=str(tmp_path / "d"), progress=False, log=lambda line: None,
              init=first.out)  # fmt: skip
    with pytest.raises(InputError, match="not both"):
        train("SRPB-Mix-v0", resolve("SRPB-Mix-v0", {**small,
                                                     "pretrain_teachers": {"crowd": "dwa"}}),
              out=str(tmp_path / "d"), progress=False, log=lambda line: None,
              init=first.out)  # fmt: skip
    with pytest.raises(InputError, match="no model file"):
        resolve_model(str(tmp_path / "nothing"), "--init")


def test_mix_draw_weights_train_with_periodic_evaluation(tmp_path, capsys):
    """`weights` of SRPB-Mix-v0 change only how often each scenario is drawn in training:
    the periodic evaluation runs the registered mixture, as the test seeds do."""
    out = tmp_path / "run"
    rc = main(["train", "--env", "SRPB-Mix-v0", "--reward", "task", "--steps", "256",
               "--hyperparams", *SMALL, "n_envs=1", "n_steps=256", "eval_freq=256",
               "--env-kwargs", "weights=[0, 1, 0, 0, 0]", "--out", str(out),
               "--no-progress"])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env_kwargs"]["weights"] == [0, 1, 0, 0, 0]
    with open(out / "evaluations.csv", newline="") as f:
        envs = [r["env"] for r in csv.DictReader(f)]
    assert envs == list(SCENARIO_IDS)  # each scenario, weight 0 or not


@pytest.mark.parametrize(
    ("env", "kwargs", "evaluated", "label"),
    [
        ("SRPB-Mix-v0", ["scenarios=[corridor, fformation]", "weights=[3, 1]"],
         ["SRPB-Corridor-v0", "SRPB-FFormation-v0"], None),
        ("SRPB-Custom-v0", ["scenario=envs/corridor.yaml", "max_episode_steps=300",
                            "metrics={semantics: reference}"], ["corridor"], "envs/corridor.yaml"),
        # a registered id made with another scenario is evaluated on that scenario
        ("SRPB-Corridor-v0", ["scenario=fformation"], ["SRPB-FFormation-v0"], None),
    ],
)  # fmt: skip
def test_periodic_evaluation_runs_the_scenarios_trained_on(
    env, kwargs, evaluated, label, tmp_path, capsys, monkeypatch
):
    """The mixture's `scenarios` and a custom env's `scenario` are what periodic evaluation
    runs (a file by its scenario's name); the time limit and metric settings of training
    stay out of it."""
    from pathlib import Path

    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    out = tmp_path / "run"
    rc = main(["train", "--env", env, "--reward", "task", "--steps", "256", "--hyperparams",
               *SMALL, "n_envs=1", "n_steps=256", "eval_freq=256", "--env-kwargs", *kwargs,
               "--out", str(out), "--no-progress"])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    with open(out / "evaluations.csv", newline="") as f:
        assert [r["env"] for r in csv.DictReader(f)] == evaluated
    stored = json.loads(next((out / "eval").glob("step_*/config.json")).read_text())
    assert stored["env_kwargs"] == {} and stored["semantics"] == "paper"
    if label is not None:
        assert stored["envs"][0]["scenario_file"] == str(Path(label).resolve())
    inline = ["train", "--env", "SRPB-Custom-v0", "--env-kwargs",
              "scenario={name: mine}", "--out", str(tmp_path / "inline")]  # fmt: skip
    capsys.readouterr()
    assert main(inline) == 2
    err = capsys.readouterr().err
    assert "srpb-gym: error: --env-kwargs: " in err and "Traceback" not in err, err


def test_periodic_evaluation_uses_the_env_kwargs(tmp_path, capsys):
    """Env kwargs that change what the policy sees (here three people slots instead of six)
    reach the periodic evaluation; `srpb-gym eval` takes them too, and without them the
    model observes with the settings it records: the same episode, said in a note."""
    out = tmp_path / "run"
    rc = main(["train", "--env", "SRPB-Corridor-v0", "--reward", "task", "--steps", "256",
               "--hyperparams", *SMALL, "n_envs=1", "n_steps=256", "eval_freq=256",
               "--env-kwargs", "observation={people: 3}", "reward_weights={time: -0.2}",
               "--out", str(out), "--no-progress"])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    stored = json.loads(next((out / "eval").glob("step_*/config.json")).read_text())
    assert stored["env_kwargs"] == {"observation": {"people": 3}}  # the reward is not used
    assert stored["envs"][0]["kwargs"]["observation"] == {"people": 3}
    model = str(out / "best" / "model.zip")
    args = ["eval", "--env", "SRPB-Corridor-v0", "--policy", model, "--episodes", "1"]
    assert main([*args, "--out", str(tmp_path / "e1"),
                 "--env-kwargs", "observation={people: 3}"]) == 0  # fmt: skip
    capsys.readouterr()
    assert main([*args, "--out", str(tmp_path / "e2")]) == 0
    assert ("it observes with its own settings observation={people: 3} (the environments': "
            "{people: 6})") in capsys.readouterr().err  # fmt: skip
    first, second = (next(csv.DictReader((tmp_path / e / "episodes.csv").open()))
                     for e in ("e1", "e2"))  # fmt: skip
    for key in ("is_success", "m_mef", "m_plin", "m_chc", "m_psi", "m_obs"):
        assert first[key] == second[key], key


def _stub_evaluations(tmp_path, monkeypatch, figures):
    """A periodic evaluation callback into ``tmp_path`` whose evaluations run nothing: each
    saves a checkpoint whose model.zip holds its own path and scores the next of
    ``figures``, (success, tracked median m_psi, ground-truth median m_psi)."""
    import os
    from types import SimpleNamespace

    from srpb_gym.training import callbacks

    def save(model, path):
        os.makedirs(path)
        (tmp_path / path).joinpath("model.zip").write_text(path)

    def run(config, log=None, progress=True):
        os.makedirs(config.out)
        return SimpleNamespace(results=None, interrupted=False)

    figures = iter(figures)

    def summarize(results):
        success, psi, gt_psi = next(figures)
        row = {k: 0.0 for k in callbacks.EVAL_COLUMNS if k not in ("step", "env")}
        return {"SRPB-Corridor-v0": {**row, "success": success, "m_psi": psi,
                                     "gt_m_psi": gt_psi}}  # fmt: skip

    monkeypatch.setattr(callbacks, "save_checkpoint", save)
    monkeypatch.setattr(callbacks, "summarize_results", summarize)
    monkeypatch.setattr("srpb_gym.evaluation.harness.run_evaluation", run)
    monkeypatch.setattr("srpb_gym.evaluation.spec.resolve_config",
                        lambda *args, **kwargs: SimpleNamespace(out=kwargs["out"]))  # fmt: skip
    cb = callbacks.PeriodicEvalCallback(str(tmp_path), ["SRPB-Corridor-v0"], 100, 1)
    cb.model = SimpleNamespace(logger=SimpleNamespace(record=lambda *args: None))
    return cb


def test_only_the_latest_and_the_best_evaluation_folders_are_kept(tmp_path, monkeypatch):
    """Each periodic evaluation writes a full evaluation folder (75 MB for the mixture):
    the folders of the latest and of the best evaluation are kept, as the checkpoints."""
    successes = [0.5, 0.9, 0.7, 0.6, 1.0, 0.8]
    cb = _stub_evaluations(tmp_path, monkeypatch, [(s, 10.0, 10.0) for s in successes])
    kept = []
    for step in range(100, 700, 100):
        cb.num_timesteps = step
        cb.evaluate()
        kept.append(sorted(p.name for p in (tmp_path / "eval").iterdir()))
    assert kept == [
        ["step_000000100"],
        ["step_000000200"],  # the new best is also the latest
        ["step_000000200", "step_000000300"],
        ["step_000000200", "step_000000400"],
        ["step_000000500"],
        ["step_000000500", "step_000000600"],
    ]
    assert sorted(p.name for p in (tmp_path / "checkpoints").iterdir()) == ["step_000000600"]
    with open(tmp_path / "evaluations.csv", newline="") as f:
        assert [r["step"] for r in csv.DictReader(f)] == [str(s) for s in range(100, 700, 100)]


def test_best_is_chosen_by_the_distance_kept_from_the_true_people(tmp_path, monkeypatch):
    """At equal success, best/ is the checkpoint with the lower median m_psi from the true
    people, where the tracked median says the opposite; the shipping script's best_step
    reads the same column back (and m_psi in a file written before gt_m_psi was kept)."""
    from training.ship import best_step

    # (success, tracked m_psi, ground-truth m_psi) of the evaluations at 100, 200, 300
    figures = [(0.9, 10.0, 30.0), (0.9, 30.0, 10.0), (0.9, 5.0, 20.0)]
    cb = _stub_evaluations(tmp_path, monkeypatch, figures)
    for step in (100, 200, 300):
        cb.num_timesteps = step
        cb.evaluate()
    assert (tmp_path / "best" / "model.zip").read_text().endswith("step_000000200")
    assert best_step(tmp_path) == 200
    with open(tmp_path / "evaluations.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["gt_m_psi"] for r in rows] == ["30", "10", "20"]
    with open(tmp_path / "evaluations.csv", "w", newline="") as f:  # as written before
        old = csv.DictWriter(f, fieldnames=["step", "env", "success", "m_psi"])
        old.writeheader()
        old.writerows({k: r[k] for k in old.fieldnames} for r in rows)
    assert best_step(tmp_path) == 300  # then best/ was chosen by the tracked median


def test_the_printed_eval_command_keeps_what_the_spaces_need(tmp_path):
    """The mixture is evaluated on its scenarios, a scenario file as a file; the env
    kwargs that evaluation needs are kept (and read back the same), training's own are
    not; without best/ the final model is evaluated."""
    from srpb_gym.training.cli import eval_command
    from srpb_gym.training.config import parse_overrides

    kwargs = {"weights": [1, 1, 3, 2, 3], "reward_weights": {"psi": -1.0},
              "observation": {"people": 4, "goal_scale": 12.5}, "time_limit": 30.0}  # fmt: skip
    words = shlex.split(eval_command("SRPB-Mix-v0", kwargs, str(tmp_path / "a b")))
    assert words[:3] == ["srpb-gym", "eval", "--env"]
    assert words[3:8] == [
        "SRPB-Corridor-v0", "SRPB-FFormation-v0", "SRPB-Crossing-v0", "SRPB-Crowd-v0",
        "SRPB-Doorway-v0",
    ]  # fmt: skip
    assert words[8:10] == ["--policy", str(tmp_path / "a b")]
    assert words[10] == "--env-kwargs"
    assert parse_overrides(words[11:], "--env-kwargs") == {
        "observation": {"people": 4, "goal_scale": 12.5}, "time_limit": 30.0
    }  # fmt: skip
    (tmp_path / "best").mkdir()
    (tmp_path / "best" / "model.zip").write_bytes(b"")
    scenario = "envs/doorway.yaml"
    assert shlex.split(eval_command("SRPB-Custom-v0", {"scenario": scenario}, str(tmp_path))) == [
        "srpb-gym", "eval", "--env", scenario, "--policy", str(tmp_path / "best")
    ]  # fmt: skip
