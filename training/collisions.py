"""How planners collide: every collision of their episodes, with what the robot hit and how
fast it drove just before, and each planner's collisions per 100 s of driving.

    python -m training.collisions --env SRPB-Crowd-v0 --planner dwa \\
        --policy ppo-crowd-task ppo-crowd-srpb --episodes 100 --seed 10000

Planners, policies (files or shipped names) and ``--env-kwargs`` are resolved as ``srpb-gym
eval`` resolves them, and the episodes are the same (``env.reset(seed=...)``, seeds from
``--seed``, the planner's warm-up left out: it changes nothing the episode sees). A
collision ends its episode (``collision="terminate"``, the default), so an episode has at
most one. Each line names the seed, the time, what the robot touched (``person``, ``wall``
or ``robot``), its mean speed over the ``--window`` before (the distance its pose moved,
over that time) and, for a person, that person's speed. The summary gives the driving
time (the episodes' steps times the control step), the collisions per 100 s of it, and
how many collisions with people found the robot at ``--fast`` m/s or faster and how many
below ``--stopped`` m/s. Where it comes from: ``docs/training.md``, "Seeds and collisions".
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from srpb_gym.errors import InputError

KINDS = ("wall", "person", "robot")  # the columns of the world's collision flags


@dataclass
class Collision:
    seed: int
    time: float  # s from the episode's start
    kind: str  # what the robot touched first: KINDS
    robot_speed: float  # m/s, mean over the window before
    person_speed: float  # m/s, the nearest person's (nan for a wall or a robot)


@dataclass
class Summary:
    planner: str
    episodes: int = 0
    driving_time: float = 0.0  # s
    collisions: list[Collision] = field(default_factory=list)

    def rate(self) -> float:
        """Collisions per 100 s of driving."""
        return 100.0 * len(self.collisions) / self.driving_time if self.driving_time else 0.0


def run_planner(config: Any, env_id: str, spec: Any, window: float) -> Summary:
    """The episodes of ``spec`` in ``env_id``, as ``config`` (an ``EvalConfig``) has them."""
    env = config.make_env(env_id, spec.name, render=False)
    planner = spec.build()
    base = env.unwrapped
    dt = float(base.task.sim.config.control_dt)
    lag = max(1, round(window / dt))
    out = Summary(spec.name)
    for seed in range(config.seed, config.seed + config.episodes):
        obs, _ = env.reset(seed=seed)
        planner.reset(base.knowledge())
        world = base.task.sim.world
        path = [world.robot_pose[0, :2].copy()]
        while True:
            obs, _, terminated, truncated, info = env.step(planner.act(obs, base.knowledge()))
            path.append(world.robot_pose[0, :2].copy())
            if info["collision"]:
                out.collisions.append(_collision(world, seed, path, lag, dt))
            if terminated or truncated:
                break
        out.episodes += 1
        out.driving_time += (len(path) - 1) * dt
    env.close()
    return out


def _collision(world: Any, seed: int, path: list[Any], lag: int, dt: float) -> Collision:
    flags = world.collisions[0]
    kind = KINDS[int(np.argmax(flags))] if flags.any() else "unknown"
    back = min(lag, len(path) - 1)
    speed = float(np.linalg.norm(path[-1] - path[-1 - back])) / (back * dt)
    person = float("nan")
    if kind == "person" and len(world.people_xy):
        nearest = int(np.argmin(np.hypot(*(world.people_xy - path[-1]).T)))
        person = float(np.linalg.norm(world.people_velocity[nearest]))
    return Collision(seed, (len(path) - 1) * dt, kind, speed, person)


def report(summary: Summary, fast: float, stopped: float) -> list[str]:
    lines = [f"{summary.planner}: {summary.episodes} episodes, {summary.driving_time:.0f} s "
             f"of driving, {len(summary.collisions)} collisions, {summary.rate():.3f} per "
             "100 s"]  # fmt: skip
    for c in summary.collisions:
        person = "" if np.isnan(c.person_speed) else f", person {c.person_speed:.2f} m/s"
        lines.append(f"  seed {c.seed}: {c.time:.1f} s, {c.kind}, robot "
                     f"{c.robot_speed:.2f} m/s{person}")  # fmt: skip
    kinds = {k: sum(c.kind == k for c in summary.collisions) for k in (*KINDS, "unknown")}
    people = [c.robot_speed for c in summary.collisions if c.kind == "person"]
    lines.append("  by kind: " + ", ".join(f"{k} {n}" for k, n in kinds.items() if n)
                 if summary.collisions else "  no collisions")  # fmt: skip
    if people:
        lines.append(
            f"  with people: {sum(s >= fast for s in people)} at {fast:g} m/s or "
            f"faster, {sum(s < stopped for s in people)} below {stopped:g} m/s "
            f"(robot speeds {', '.join(f'{s:.2f}' for s in sorted(people))})"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    from srpb_gym.config import parse_overrides
    from srpb_gym.evaluation.spec import resolve_config

    parser = argparse.ArgumentParser(prog="python -m training.collisions",
                                     description=__doc__.split("\n\n")[0])  # fmt: skip
    parser.add_argument("--env", default="SRPB-Crowd-v0", help="a registered id or scenario file")
    parser.add_argument("--planner", nargs="*", default=[], help="registered planners")
    parser.add_argument("--policy", nargs="*", default=[], help="model files or shipped names")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=10000, help="first seed (test: 10000)")
    parser.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--window", type=float, default=0.5, help="s, for the robot's speed")
    parser.add_argument("--fast", type=float, default=0.3, help="m/s")
    parser.add_argument("--stopped", type=float, default=0.1, help="m/s")
    args = parser.parse_args(argv)
    try:
        if not args.planner and not args.policy:
            raise InputError("name a planner or a policy", key="--planner/--policy")
        if args.window <= 0:
            raise InputError(f"must be > 0, got {args.window!r}", key="--window")
        with tempfile.TemporaryDirectory() as tmp:
            kwargs = parse_overrides(args.env_kwargs, "--env-kwargs")
            config = resolve_config([args.env], args.planner, args.policy,
                                    episodes=args.episodes, seed=args.seed, out=tmp,
                                    log=None, env_kwargs=kwargs)  # fmt: skip
            for spec in config.planners:
                summary = run_planner(config, config.envs[0], spec, args.window)
                print("\n".join(report(summary, args.fast, args.stopped)), flush=True)
    except InputError as exc:
        print(f"python -m training.collisions: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
