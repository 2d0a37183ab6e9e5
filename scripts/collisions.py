"""How planners collide: every collision of their episodes, with what the robot touched, how
fast it drove just before, who caused it, and each planner's collisions per 100 s of
episode time.

    python scripts/collisions.py --env SRPB-Crowd-v0 --planner dwa \\
        --policy ppo-crowd-task ppo-crowd-srpb --episodes 100 --seed 3000000

Planners, policies (files or shipped names) and ``--env-kwargs`` are resolved as ``srpb-gym
eval`` resolves them, and the episodes are the same (``env.reset(seed=...)``, seeds from
``--seed``; the planner's warm-up is left out, as it changes nothing the episode sees). One
robot per episode, as in the Gymnasium environment. A collision is the environment's: a
step on which the robot touches a body (a person, a robot, a wall: every wall is one) it
did not touch on the step before, attributed by the environment (``info["collision_*"]``,
:mod:`srpb_gym.sim.contact`; with the default ``collision="terminate"`` it ends the
episode, so an episode has at most one; a step on which two begin shows the one closing
faster). Each line names the seed and the scenario (for ``SRPB-Mix-v0`` the one drawn),
the time, what the robot touched (``person``, ``wall`` or ``robot``), who caused it
(``by robot``, ``by person``: who closed the gap faster; a wall is the robot's), the
robot's mean speed over the ``--window`` up to the end of that step (the distance its
pose moved, over that time), the speed of the person it touched and the closing speeds
of both (the robot's + the other's, along the line between them) just before the contact.
The summary gives the episode time (steps times the control step, standing still
included), the collisions per 100 s of it, how many collisions each kind and each cause
had, and how many collisions with people found the robot at ``--fast`` m/s or faster and
how many below ``--stopped`` m/s. What it showed in ``crowd``: ``docs/training.md``,
section "Standing groups in the lidar".
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.config import parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.evaluation.spec import resolve_config, stderr_log
from srpb_gym.seeds import RETIRED_TEST, VALIDATION


@dataclass
class Collision:
    seed: int
    time: float  # s from the episode's start
    kind: str  # what the robot touched: wall, person or robot
    robot_speed: float  # m/s, mean over the window up to the end of that step
    other_speed: float  # m/s, the touched person's or robot's just before (0 for a wall)
    scenario: str = ""  # the scenario drawn (SRPB-Mix-v0)
    by: str = "robot"  # who caused it: robot, person or other_robot
    closing: tuple[float, float] = (0.0, 0.0)  # m/s, the robot's and the other's closing speed


@dataclass
class Summary:
    planner: str
    episodes: int = 0
    time: float = 0.0  # s, the episodes' steps times the control step
    collisions: list[Collision] = field(default_factory=list)

    def rate(self) -> float:
        """Collisions per 100 s of episode time."""
        return 100.0 * len(self.collisions) / self.time if self.time > 0 else 0.0


def run_planner(config: Any, env_id: str, spec: Any, window: float) -> Summary:
    """The episodes of ``spec`` in ``env_id``, as ``config`` (an ``EvalConfig``) has them."""
    env = config.make_env(env_id, render=False)  # no planner: no records written
    try:
        planner = spec.build()
        out = Summary(spec.name)
        for seed in range(config.seed, config.seed + config.episodes):
            _episode(env, planner, seed, window, out)
        return out
    finally:
        env.close()


def _episode(env: Any, planner: Any, seed: int, window: float, out: Summary) -> None:
    """One episode, driven as ``srpb-gym eval`` drives it (``run_episode``)."""
    from srpb_gym.evaluation.runner import run_episode

    base = env.unwrapped
    dt = float(base.task.sim.config.control_dt)
    lag = max(1, round(window / dt))

    def on_step(info: dict[str, Any]) -> None:
        if info.get("collision_kind"):
            out.collisions.append(_collision(info, seed, _path(base.task.record), lag, dt,
                                             base.scenario.name))  # fmt: skip

    steps = run_episode(env, planner, seed, on_step=on_step)["steps"]
    out.episodes += 1
    out.time += steps * dt


def _path(record: Any) -> NDArray[np.float64]:
    """(N, 2) the robot's positions so far, one per sample from the reset (its record)."""
    return np.column_stack([record.robot_col("x"), record.robot_col("y")])


def _collision(info: dict[str, Any], seed: int, path: Sequence[Any], lag: int, dt: float,
               scenario: str = "") -> Collision:  # fmt: skip
    """The collision that began on the step of ``info`` (its ``collision_*`` keys), with the
    robot's mean speed over the last ``lag`` steps of ``path``."""
    back = min(lag, len(path) - 1)
    speed = float(np.linalg.norm(path[-1] - path[-1 - back])) / (back * dt)
    closing = (float(info["collision_robot_closing"]), float(info["collision_other_closing"]))
    return Collision(seed, (len(path) - 1) * dt, str(info["collision_kind"]), speed,
                     float(info["collision_other_speed"]), scenario, str(info["collision_by"]),
                     closing)  # fmt: skip


def report(summary: Summary, fast: float, stopped: float) -> list[str]:
    lines = [f"{summary.planner}: {summary.episodes} episodes, {summary.time:.0f} s, "
             f"{len(summary.collisions)} collisions, {summary.rate():.3f} per 100 s"]  # fmt: skip
    for c in summary.collisions:
        where = f" ({c.scenario})" if c.scenario else ""
        other = "" if c.kind == "wall" else f", {c.kind} {c.other_speed:.2f} m/s"
        lines.append(f"  seed {c.seed}{where}: {c.time:.1f} s, {c.kind}, by "
                     f"{c.by.replace('_', ' ')}, robot {c.robot_speed:.2f} m/s{other}, closing "
                     f"{c.closing[0]:.2f} + {c.closing[1]:.2f} m/s")  # fmt: skip
    kinds = Counter(c.kind for c in summary.collisions)
    causes = Counter(c.by.replace("_", " ") for c in summary.collisions)
    people = [c.robot_speed for c in summary.collisions if c.kind == "person"]
    if summary.collisions:
        lines.append("  by kind: " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
        lines.append("  caused by: " + ", ".join(f"{k} {n}" for k, n in sorted(causes.items())))
    else:
        lines.append("  no collisions")
    if people:
        lines.append(
            f"  with people: {sum(s >= fast for s in people)} at {fast:g} m/s or "
            f"faster, {sum(s < stopped for s in people)} below {stopped:g} m/s "
            f"(robot speeds {', '.join(f'{s:.2f}' for s in sorted(people))})"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/collisions.py",
                                     description=__doc__.split("\n\n")[0])  # fmt: skip
    parser.add_argument("--env", default="SRPB-Crowd-v0", help="a registered id or scenario file")
    parser.add_argument("--planner", nargs="*", default=[], help="registered planners")
    parser.add_argument("--policy", nargs="*", default=[], help="model files or shipped names")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=VALIDATION.start,
                        help=f"first seed (default: the {VALIDATION.text()}, which an "
                        "analysis that informs a choice should use; the figures in "
                        "docs/training.md were measured on the retired test seeds: --seed "
                        f"{RETIRED_TEST.start})")  # fmt: skip
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
                                    log=stderr_log, env_kwargs=kwargs)  # fmt: skip
            for spec in config.planners:
                summary = run_planner(config, config.envs[0], spec, args.window)
                print("\n".join(report(summary, args.fast, args.stopped)), flush=True)
    except InputError as exc:
        print(f"python scripts/collisions.py: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
