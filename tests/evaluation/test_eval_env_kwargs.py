"""``eval --env-kwargs``: keyword arguments of every environment, checked before the first
episode, stored in ``config.json``, and part of what ``--resume`` and ``compare`` check."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from srpb_gym.cli import main

ROOT = Path(__file__).resolve().parents[2]
ENV = "SRPB-Corridor-v0"
BASE = ["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "1"]
SLOW = "robot={v_max: 0.25}"


def _row(out: Path) -> dict[str, str]:
    with open(out / "episodes.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    return row


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("env_kwargs")
    outs = {"plain": root / "plain", "slow": root / "slow"}
    assert main([*BASE, "--out", str(outs["plain"])]) == 0
    assert main([*BASE, "--out", str(outs["slow"]), "--env-kwargs", SLOW]) == 0
    return outs


def test_the_kwargs_reach_the_environment_and_config_json(runs):
    config = json.loads((runs["slow"] / "config.json").read_text())
    assert config["env_kwargs"] == {"robot": {"v_max": 0.25}}
    env = config["envs"][0]
    assert env["kwargs"]["robot"] == {"v_max": 0.25}
    # the robot's settings feed the metric parameters, so the run says what it scored with
    assert env["metric_params"]["robot_max_speed"] == 0.25
    plain = json.loads((runs["plain"] / "config.json").read_text())
    assert plain["env_kwargs"] == {} and plain["envs"][0]["metric_params"]["robot_max_speed"] == 0.5
    # go-to-goal reaches the goal in both, at most half as fast with v_max 0.25
    slow, fast = _row(runs["slow"]), _row(runs["plain"])
    assert slow["is_success"] == fast["is_success"] == "1"
    assert float(slow["m_mef"]) > 1.8 * float(fast["m_mef"])


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        (["metrics={semantics: reference}"],
         "--env-kwargs: metrics: set by --semantics and --preset, not here"),
        (["render_mode=human"], "--env-kwargs: render_mode: set by --video, not here"),
        (["scenario=crowd"], "--env-kwargs: scenario: set by --env with a scenario file, not here"),
        (["colour=red"], f"--env-kwargs: colour: {ENV} takes no such argument"),
        (["robot={v_max: -1}"], f"--env-kwargs: robot: {ENV}: "),
        (["observation={people: many}"],
         f"--env-kwargs: observation.people: {ENV}: expected an integer, got 'many'"),
        (["robot"], "--env-kwargs: expected KEY=VALUE, got 'robot'"),
        (["max_episode_steps=5"], "--env-kwargs: max_episode_steps: set by the scenario's "
         "time_limit (a scenario file as --env), not here"),
        # an error located in the scenario file names the file, the line and its key
        (["robot={radius: 3}"], f"--env-kwargs: {ENV}: {ROOT / 'envs' / 'corridor.yaml'}:19: "
         "robot.start.position: a robot of radius 3 m"),
    ],
)  # fmt: skip
def test_bad_kwargs_are_one_line_before_any_episode(kwargs, expected, tmp_path, capsys):
    out = tmp_path / "o"
    assert main([*BASE, "--out", str(out), "--env-kwargs", *kwargs]) == 2
    line = _error(capsys)
    assert line.startswith(f"srpb-gym: error: {expected}"), line
    assert not (out / "episodes.csv").exists()


def _mef(out: Path) -> dict[str, float]:
    with open(out / "episodes.csv", newline="") as f:
        return {r["robot"]: float(r["m_mef"]) for r in csv.DictReader(f)}


def test_the_multi_robot_environment_takes_them(tmp_path, capsys):
    out, plain = tmp_path / "two", tmp_path / "plain"
    assert main([*BASE, "--robots", "2", "--out", str(out), "--env-kwargs", SLOW]) == 0
    assert main([*BASE, "--robots", "2", "--out", str(plain)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["envs"][0]["kwargs"]["robot"] == {"v_max": 0.25}
    assert config["envs"][0]["metric_params"]["robot_max_speed"] == 0.25
    slow, fast = _mef(out), _mef(plain)
    # go-to-goal drives the two robots into each other: later, at most half as fast
    assert set(slow) == set(fast) == {"0", "1"}
    assert all(slow[r] > 1.5 * fast[r] for r in slow), (slow, fast)
    capsys.readouterr()
    assert main([*BASE, "--robots", "2", "--out", str(tmp_path / "bad"),
                 "--env-kwargs", "colour=red"]) == 2  # fmt: skip
    assert "colour" in _error(capsys)


def test_resume_and_compare_check_them(runs, tmp_path, capsys):
    again = [*BASE, "--out", str(runs["slow"]), "--resume"]
    assert main([*again, "--env-kwargs", "robot={v_max: 0.3}"]) == 2
    line = _error(capsys)
    assert "--resume: the run was made with another configuration" in line
    assert "env_kwargs.robot.v_max (0.25 in the run, 0.3 now)" in line
    assert main([*again, "--env-kwargs", SLOW]) == 0  # nothing left to run
    capsys.readouterr()
    assert main(["compare", str(runs["plain"]), str(runs["slow"])]) == 2
    line = _error(capsys)
    assert "made with other settings" in line and "env_kwargs.robot" in line, line
    assert main(["compare", str(runs["plain"]), str(runs["slow"]), "--separate",
                 "--out", str(tmp_path / "cmp")]) == 0  # fmt: skip
    settings = 'slow: semantics paper, preset paper, robots 1, env kwargs {"robot": {"v_max": 0.2'
    assert settings in capsys.readouterr().out
