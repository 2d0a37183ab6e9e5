"""scripts/last_metres.py: the time over the last metres and where failures end, by hand
and on a real eval output."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from scripts import last_metres as lm
from srpb_gym.cli import main as cli
from srpb_gym.errors import InputError
from srpb_gym.metrics.io_npz import save_record
from srpb_gym.metrics.record import ROBOT_FIELDS, EpisodeRecord


def write(path, xs, yaw_end, dt=0.5, goal=(0.0, 0.0, math.pi)):
    """A record of a robot along x = ``xs`` (y = 0) every ``dt``, its last yaw ``yaw_end``."""
    robot = np.zeros((len(xs), len(ROBOT_FIELDS)))
    robot[:, 0] = np.arange(len(xs)) * dt
    robot[:, 1] = xs
    robot[-1, 3] = yaw_end
    robot[:, 7:10] = goal
    robot[:, 10] = 1.0
    save_record(EpisodeRecord.from_arrays(robot), path)


def test_last_metres_by_hand(tmp_path):
    write(tmp_path / "a.npz", [3.0, 2.0, 1.0, 0.45, 0.3, 0.1, 0.05], math.pi - 0.1)
    spent, distance, heading = lm.last_metres(str(tmp_path / "a.npz"), radius=0.5)
    assert spent == pytest.approx(3 * 0.5)  # first within 0.5 m at x = 0.45, 3 samples later
    assert distance == pytest.approx(0.05) and heading == pytest.approx(0.1)
    write(tmp_path / "b.npz", [3.0, 2.0, 1.0], -math.pi + 0.2)  # never near; heading wraps
    spent, distance, heading = lm.last_metres(str(tmp_path / "b.npz"), radius=0.5)
    assert math.isnan(spent) and distance == 1.0 and heading == pytest.approx(0.2)


def test_summary_of_a_multi_robot_eval(tmp_path, capsys):
    out = tmp_path / "eval"
    assert cli(["eval", "--env", "SRPB-Crowd-v0", "--robots", "3", "--planner", "go-to-goal",
                "--episodes", "2", "--seed", "3000000", "--warmup", "0", "--workers", "1",
                "--out", str(out)]) == 0  # fmt: skip
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    lines = lm.summarise(str(out), 0.5, 0.2)
    assert len(lines) == 3
    for robot, line in enumerate(lines):
        wins = sum(r["is_success"] == "1" for r in rows if r["robot"] == str(robot))
        assert line.startswith(f"SRPB-Crowd-v0 go-to-goal robot {robot}: {wins}/2 at the goal")
    capsys.readouterr()
    assert lm.main([str(out), "--radius", "1.0"]) == 0
    assert capsys.readouterr().out.count("within 1 m of the goal") == 3


def test_bad_folders_are_clear_errors(tmp_path, capsys):
    assert lm.main([str(tmp_path)]) == 2
    assert "episodes.csv" in capsys.readouterr().err
    header = "env,planner,seed,is_success,collision,timeout\n"
    (tmp_path / "episodes.csv").write_text(header + "SRPB-Crowd-v0,dwa,x,1,0,0\n")
    with pytest.raises(InputError, match=r"episodes.csv:2: column seed is 'x'"):
        lm.summarise(str(tmp_path), 0.5, 0.2)
    (tmp_path / "episodes.csv").write_text(header + "SRPB-Crowd-v0,dwa,5,1,0,0\n")
    with pytest.raises(InputError, match="records are needed"):
        lm.summarise(str(tmp_path), 0.5, 0.2)
    with pytest.raises(SystemExit):
        lm.main([str(tmp_path), "--radius", "0"])
