"""scripts/collisions.py: what a collision was, its speed and the rate per 100 s."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from scripts import collisions


def _info(kind="person", by="person", other_speed=0.5, closing=(0.1, 0.4)):
    return {"collision_kind": kind, "collision_by": by, "collision_other_speed": other_speed,
            "collision_robot_closing": closing[0],
            "collision_other_closing": closing[1]}  # fmt: skip


def test_a_collision_says_what_was_hit_who_caused_it_and_how_fast_the_robot_drove():
    path = [np.array([0.05 * k, 0.0]) for k in range(8)]  # 0.5 m/s at 0.1 s per step
    path[1] = np.array([9.0, 9.0])  # before the 5-step window (path[2:]): does not count
    c = collisions._collision(_info(), 7, path, lag=5, dt=0.1)
    assert (c.seed, c.kind, c.by, c.closing) == (7, "person", "person", (0.1, 0.4))
    assert c.time == pytest.approx(0.7)
    assert c.robot_speed == pytest.approx(0.5)  # 0.25 m over the last 5 steps
    assert c.other_speed == 0.5  # the touched person's, from the environment
    wall = collisions._collision(_info("wall", "robot", 0.0, (0.5, 0.0)), 8, path[2:4], lag=5,
                                 dt=0.1)  # fmt: skip
    assert (wall.kind, wall.by, wall.other_speed) == ("wall", "robot", 0.0)
    assert wall.robot_speed == pytest.approx(0.5)  # a window longer than the episode so far


def test_the_report_counts_by_kind_and_speed():
    summary = collisions.Summary("p", episodes=4, time=200.0, collisions=[
        collisions.Collision(1, 3.0, "person", 0.45, 0.2, "crowd", "robot", (0.44, -0.1)),
        collisions.Collision(2, 4.0, "person", 0.05, 1.0, "crowd", "person", (0.0, 0.9)),
        collisions.Collision(3, 5.0, "wall", 0.4, 0.0, "crowd", "robot", (0.3, 0.0)),
    ])  # fmt: skip
    assert summary.rate() == pytest.approx(1.5)
    lines = collisions.report(summary, fast=0.3, stopped=0.1)
    assert lines[0] == "p: 4 episodes, 200 s, 3 collisions, 1.500 per 100 s"
    assert lines[1] == ("  seed 1 (crowd): 3.0 s, person, by robot, robot 0.45 m/s, person "
                        "0.20 m/s, closing 0.44 + -0.10 m/s")  # fmt: skip
    assert lines[3] == ("  seed 3 (crowd): 5.0 s, wall, by robot, robot 0.40 m/s, closing 0.30 "
                        "+ 0.00 m/s")  # fmt: skip
    assert lines[4] == "  by kind: person 2, wall 1"
    assert lines[5] == "  caused by: person 1, robot 2"
    assert lines[6] == ("  with people: 1 at 0.3 m/s or faster, 1 below 0.1 m/s "
                        "(robot speeds 0.05, 0.45)")  # fmt: skip
    assert collisions.report(collisions.Summary("q", 1, 10.0), 0.3, 0.1)[1] == "  no collisions"


def _contacts(seed: int) -> tuple[list[int], list[int], int]:
    """go-to-goal in crowd with collision="continue": the steps with a contact, those on
    which a collision began, and the steps."""
    import srpb_gym  # noqa: F401
    from srpb_gym.planners import make_planner

    env = gym.make("SRPB-Crowd-v0", collision="continue")
    planner, base = make_planner("go-to-goal"), env.unwrapped
    obs, _ = env.reset(seed=seed)
    planner.reset(base.knowledge())
    touching, began, step = [], [], 0
    while True:
        obs, _, terminated, truncated, info = env.step(planner.act(obs, base.knowledge()))
        step += 1
        if info["collision"]:
            touching.append(step)
        if info.get("collision_kind"):
            began.append(step)
        if terminated or truncated:
            env.close()
            return touching, began, step


def test_the_script_runs_the_episodes_eval_runs(capsys):
    # go-to-goal, crowd, seed 10048: srpb-gym eval records a collision after 2.3 s
    args = ["--planner", "go-to-goal", "--episodes", "1", "--seed", "10048"]
    assert collisions.main(args) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "go-to-goal: 1 episodes, 2 s, 1 collisions, 43.478 per 100 s"  # 23 steps
    assert out[1] == ("  seed 10048 (crowd): 2.3 s, person, by robot, robot 0.49 m/s, person "
                      "0.15 m/s, closing 0.48 + -0.00 m/s")  # fmt: skip
    # going on through contacts, a collision is where a contact with a body starts: every
    # step after one without contacts, and a body touched while touching another
    touching, began, steps = _contacts(10048)
    starts = [s for s in touching if s - 1 not in touching]
    assert touching[0] == 23 and len(touching) > len(began)  # contacts last several steps
    assert set(starts) <= set(began) <= set(touching)
    assert collisions.main([*args, "--env-kwargs", "collision=continue"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"go-to-goal: 1 episodes, {steps * 0.1:.0f} s, {len(began)} "
                             "collisions")  # fmt: skip
    assert [line.split(": ")[1].split(" s,")[0] for line in out[1 : 1 + len(began)]] == [
        f"{s * 0.1:.1f}" for s in began
    ]
    assert collisions.main(["--planner", "nope"]) == 2
    assert "unknown planner 'nope'" in capsys.readouterr().err
    assert collisions.main([]) == 2
