"""training/collisions.py: what a collision was, its speed and the rate per 100 s."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from training import collisions


def _world(flags, people_xy=((1.0, 0.0), (5.0, 5.0)), people_velocity=((0.3, 0.4), (0, 0))):
    return SimpleNamespace(collisions=np.array([flags], dtype=bool),
                           people_xy=np.array(people_xy, dtype=float),
                           people_velocity=np.array(people_velocity, dtype=float))  # fmt: skip


def test_a_collision_says_what_was_hit_and_how_fast_the_robot_drove():
    path = [np.array([0.05 * k, 0.0]) for k in range(8)]  # 0.5 m/s at 0.1 s per step
    c = collisions._collision(_world([False, True, False]), 7, path, lag=5, dt=0.1)
    assert (c.seed, c.kind) == (7, "person")
    assert c.time == pytest.approx(0.7)
    assert c.robot_speed == pytest.approx(0.5)  # 0.25 m over the last 5 steps
    assert c.person_speed == pytest.approx(0.5)  # the nearest person, (0.3, 0.4) m/s
    wall = collisions._collision(_world([True, False, False]), 8, path[:3], lag=5, dt=0.1)
    assert wall.kind == "wall" and np.isnan(wall.person_speed)
    assert wall.robot_speed == pytest.approx(0.5)  # a window longer than the episode so far


def test_the_report_counts_by_kind_and_speed():
    summary = collisions.Summary("p", episodes=4, driving_time=200.0, collisions=[
        collisions.Collision(1, 3.0, "person", 0.45, 0.2),
        collisions.Collision(2, 4.0, "person", 0.05, 1.0),
        collisions.Collision(3, 5.0, "wall", 0.4, float("nan")),
    ])  # fmt: skip
    assert summary.rate() == pytest.approx(1.5)
    lines = collisions.report(summary, fast=0.3, stopped=0.1)
    assert lines[0] == "p: 4 episodes, 200 s of driving, 3 collisions, 1.500 per 100 s"
    assert lines[1] == "  seed 1: 3.0 s, person, robot 0.45 m/s, person 0.20 m/s"
    assert lines[3] == "  seed 3: 5.0 s, wall, robot 0.40 m/s"
    assert lines[4] == "  by kind: wall 1, person 2"
    assert lines[5].startswith("  with people: 1 at 0.3 m/s or faster, 1 below 0.1 m/s")
    assert collisions.report(collisions.Summary("q", 1, 10.0), 0.3, 0.1)[1] == "  no collisions"


def test_the_script_runs_an_episode_as_eval_does(capsys):
    # dwa, crowd, seed 10019: a walker meets the robot after 21.5 s (as srpb-gym eval sees it)
    assert collisions.main(["--planner", "dwa", "--episodes", "1", "--seed", "10019"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("dwa: 1 episodes, 22 s of driving, 1 collisions")
    assert out[1].startswith("  seed 10019: 21.5 s, person, robot ")
    assert collisions.main(["--planner", "nope"]) == 2
    assert "unknown planner 'nope'" in capsys.readouterr().err
    assert collisions.main([]) == 2
