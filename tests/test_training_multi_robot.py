"""The shared-policy training adapter over the multi-robot environment, and a smoke run."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import srpb_gym  # noqa: E402
from srpb_gym.cli import main as cli_main  # noqa: E402
from srpb_gym.training.shared_policy import SharedPolicyVecEnv  # noqa: E402


def make() -> srpb_gym.pettingzoo_env.SRPBParallelEnv:
    return srpb_gym.parallel_env(scenario="corridor", n_robots=2, reward="task")


def test_one_robot_leaving_ends_the_episode_for_its_environment():
    venv = SharedPolicyVecEnv([make, make])
    venv.seed(0)
    obs = venv.reset()
    assert obs.shape == (4, *venv.observation_space.shape) and venv.num_envs == 4
    # robot 1 of environment 0 turns to the side wall and drives into it; the rest stand
    for _ in range(200):
        actions = np.zeros((4, 2), np.float32)
        yaw = venv.envs[0].sim.world.robot_pose[1, 2]
        err = math.remainder(math.pi / 2 - yaw, 2 * math.pi)
        actions[1] = [1.0 if abs(err) < 0.1 else 0.0, np.clip(2 * err, -1, 1)]
        obs, _, dones, infos = venv.step(actions)
        if dones.any():
            break
    else:
        raise AssertionError("nobody left")
    assert dones.tolist() == [True, True, False, False]  # environment 0 only, both slots
    assert infos[1]["collision"] and infos[1]["TimeLimit.truncated"] is False
    assert infos[0]["TimeLimit.truncated"] is True  # cut short by robot 1: bootstrapped
    assert "srpb/m_psi" in infos[1] and "srpb/m_psi" not in infos[0]
    for i in (0, 1):
        assert infos[i]["terminal_observation"].shape == venv.observation_space.shape
        assert not np.array_equal(infos[i]["terminal_observation"], obs[i])  # reset since
    assert venv.envs[0].agents == ["robot_0", "robot_1"]  # a new episode
    assert venv.get_attr("n_robots") == [2, 2, 2, 2]


def test_train_then_evaluate(tmp_path, capsys):
    out = tmp_path / "ppo"
    run = subprocess.run(
        [sys.executable, "-m", "training.multi_robot", "--scenario", "corridor", "--robots",
         "2", "--envs", "2", "--steps", "64", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert {p.name for p in out.iterdir()} == {"model.zip", "vecnormalize.npz", "run.json"}
    record = json.loads((out / "run.json").read_text())
    # the steps the model took: whole rollouts of 4 slots x 512 steps, not the 64 asked
    assert record["steps"] == 2048 and record["steps_asked"] == 64
    from stable_baselines3.common.save_util import load_from_zip_file

    from srpb_gym.models import OBSERVATION_RECORD

    data = load_from_zip_file(out / "model.zip", load_data=True)[0]
    assert data[OBSERVATION_RECORD]["lidar_encoding"] == "linear"  # what the robots observed
    code = cli_main(["eval", "--env", "SRPB-Corridor-v0", "--robots", "2", "--policy",
                     str(out / "model.zip"), "--episodes", "2", "--warmup", "5", "--out",
                     str(tmp_path / "eval")])  # fmt: skip
    assert code == 0
    assert "observations normalised with" in capsys.readouterr().err
    with open(tmp_path / "eval" / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted((r["seed"], r["robot"]) for r in rows) == [
        ("0", "0"), ("0", "1"), ("1", "0"), ("1", "1")]  # fmt: skip


def test_kept_checkpoints_are_each_a_policy_to_evaluate(tmp_path):
    """With --keep-checkpoints every model --save-every writes stays, in its own folder,
    with the statistics it observed with; the last is the final model."""
    from training import multi_robot

    out = tmp_path / "ppo"
    assert multi_robot.main(["--scenario", "corridor", "--robots", "2", "--envs", "1",
                             "--steps", "64", "--hyperparams", "n_steps=256", "batch_size=64",
                             "--save-every", "256", "--keep-checkpoints", "--out",
                             str(out)]) == 0  # fmt: skip
    kept = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert kept == ["step_000000256", "step_000000512"]  # one rollout of 2 slots x 256
    for name in kept:
        assert {p.name for p in (out / "checkpoints" / name).iterdir()} == {
            "model.zip", "vecnormalize.npz"}  # fmt: skip
    last = out / "checkpoints" / kept[-1]
    assert (last / "vecnormalize.npz").read_bytes() == (out / "vecnormalize.npz").read_bytes()
    first = out / "checkpoints" / kept[0]
    assert (first / "model.zip").read_bytes() != (last / "model.zip").read_bytes()


@pytest.mark.parametrize(("argv", "message"), [
    (["--steps", "-5"], "--steps: must be at least 1, got -5"),
    (["--envs", "0"], "--envs: must be at least 1, got 0"),
    (["--robots", "0"], "--robots: must be at least 1, got 0"),
    (["--scenario", "crowd", "--robots", "9"],
     "--robots: scenario 'crowd' has places for at most 8 robots, got 9"),
    (["--reward", "bogus"], "--reward: unknown reward preset 'bogus'; choose one of: "),
    (["--hyperparams", "n_envs=3"], "--hyperparams: n_envs is not used by this recipe"),
    (["--hyperparams", "n_epochs=0"], "--hyperparams: n_epochs: "),
    (["--env-kwargs", "n_robots=2"], "--env-kwargs: n_robots is set by --robots"),
    (["--env-kwargs", "reward_people=nobody"], "--env-kwargs: "),
    (["--save-every", "-1"], "--save-every: must be at least 0, got -1"),
    (["--keep-checkpoints"], "--keep-checkpoints: needs --save-every N"),
    (["--init", "no-such-model"], "--init: "),
    # a model that observed otherwise: refused after the folder was made, which goes again
    (["--scenario", "corridor", "--robots", "2", "--init", "ppo-crowd-srpb"],
     "--init: "),
])  # fmt: skip
def test_bad_arguments_leave_nothing_behind(tmp_path, capsys, argv, message):
    from training import multi_robot

    out = tmp_path / "run"
    assert multi_robot.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith(f"training.multi_robot: error: {message}")
    assert not out.exists()


def test_an_existing_run_is_never_overwritten(tmp_path, capsys):
    from training import multi_robot

    out = tmp_path / "run"
    out.mkdir()
    (out / "model.zip").write_text("a model trained before")
    assert multi_robot.main(["--steps", "64", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"training.multi_robot: error: --out: {out} is not empty (holds "
                          "model.zip); choose a new or empty folder")  # fmt: skip
    assert (out / "model.zip").read_text() == "a model trained before"


def test_init_starts_every_robot_from_a_single_robot_model(tmp_path, monkeypatch):
    """Without PPO's updates the shared policy keeps the single-robot model's weights."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.save_util import load_from_zip_file

    from srpb_gym.models import model_path
    from training import multi_robot

    monkeypatch.setattr(PPO, "train", lambda self: None)  # rollouts collected, no update
    out = tmp_path / "run"
    multi_robot.train("corridor", 2, 1, 64, str(out), reward="task", init="ppo-corridor-task",
                      hyperparams={"n_steps": 32, "batch_size": 64},
                      log=lambda line: None)  # fmt: skip
    trained = load_from_zip_file(out / "model.zip", device="cpu")[1]["policy"]
    start = load_from_zip_file(model_path("ppo-corridor-task"), device="cpu")[1]["policy"]
    assert trained.keys() == start.keys()
    for key, tensor in start.items():
        assert (trained[key] == tensor).all(), key
    record = json.loads((out / "run.json").read_text())
    assert record["init"]["model"] == str(model_path("ppo-corridor-task"))
    assert record["hyperparams"]["n_steps"] == 32 and record["steps"] == 64


def test_a_robot_at_its_goal_turns_back_while_the_others_drive_on():
    venv = SharedPolicyVecEnv([make])
    venv.seed(3)
    venv.reset()
    env = venv.envs[0]
    start = env.sim.layout.robots[1].start
    goal = env.sim.layout.robots[1].goal
    # robot 1 stands at its goal: put the goal where it stands
    env.sim.robots[1].goal[:] = env.sim.world.robot_pose[1]
    obs, _, dones, infos = venv.step(np.zeros((2, 2), np.float32))
    assert dones.tolist() == [False, True]
    assert infos[1]["is_success"] and infos[1]["TimeLimit.truncated"] is False
    assert "srpb/m_psi" in infos[1] and "srpb/m_psi" not in infos[0]
    assert env.agents == ["robot_0", "robot_1"]  # the episode goes on, robot 1 in it again
    # its new task: back to its start (where it stands: it has not moved), heading there,
    # its record starting at this step with the new goal
    back = env.sim.robots[1].goal
    heading = math.atan2(start[1] - goal[1], start[0] - goal[0])
    assert back.tolist() == [start[0], start[1], heading]
    record = env.sim.robots[1].record
    assert record.counts[0] == 1 and record.robot[0, 7:10].tolist() == back.tolist()
    yaw = env.sim.world.robot_pose[1, 2]
    assert math.isclose(obs[1][3], math.cos(heading - yaw), abs_tol=1e-6)  # the new goal's
    assert obs[1][3] < -0.9  # it faces away from the way back
    assert not np.array_equal(infos[1]["terminal_observation"], obs[1])
    for _ in range(3):  # the new task pays and records from here on
        obs, rewards, dones, infos = venv.step(np.zeros((2, 2), np.float32))
        assert not dones.any() and np.isfinite(rewards).all()
    assert record.counts[0] == 4
    # at the start again: the next trip is to the goal
    env.sim.robots[1].goal[:] = env.sim.world.robot_pose[1]
    _, _, dones, infos = venv.step(np.zeros((2, 2), np.float32))
    assert dones.tolist() == [False, True] and infos[1]["is_success"]
    assert env.sim.robots[1].goal.tolist() == list(goal)
    with pytest.raises(ValueError, match="only right after reaching its goal"):
        env.return_trip("robot_0")


def test_keep_last_leaves_the_last_sample_as_the_first():
    from srpb_gym.metrics.record import EpisodeRecord

    rec = EpisodeRecord()
    for t in range(3):
        people = np.arange(27, dtype=float).reshape(3, 9) + t
        rec.append([t, *range(11)], [0, 1, 2], people, [7], [2], [0, 2])
    last = [a.copy() for a in rec.latest()]
    rec.keep_last()
    assert rec.counts[:4].tolist() == [1, 3, 1, 2]
    for a, b in zip(rec.latest(), last):
        np.testing.assert_array_equal(a, b)
    assert rec.people_sample.tolist() == [0, 0, 0] and rec.group_sample.tolist() == [0]
    rec.validate()
