"""Render one frame of every registered environment for the documentation site.

Usage: ``python scripts/render_env_figures.py [--out docs/figures/envs] [--steps 80]``

Each environment id (and the PettingZoo environment with three robots in ``crowd``) is
made with ``render_mode="rgb_array"``, reset with seed 0 and driven by ``dwa`` for
``--steps`` steps; the last frame is written to ``OUT/<id>.png``. The pictures are
committed; rerun this after a change to the scenarios or the renderer.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pygame

import srpb_gym
from srpb_gym.planners import make_planner
from srpb_gym.registration import MIX_ID, SCENARIO_IDS

#: the PettingZoo environment's picture: three robots in the crowd
PARALLEL_NAME = "srpb_v0-parallel"


def save_png(frame: np.ndarray, path: Path) -> None:
    """Write an (H, W, 3) uint8 frame to ``path``."""
    surface = pygame.surfarray.make_surface(np.ascontiguousarray(frame.transpose(1, 0, 2)))
    pygame.image.save(surface, str(path))


def render_single(env_id: str, steps: int) -> np.ndarray:
    """The frame of ``env_id`` after ``steps`` steps of ``dwa`` from ``reset(seed=0)``."""
    env = gym.make(env_id, render_mode="rgb_array")
    planner = make_planner("dwa")
    obs, _ = env.reset(seed=0)
    planner.reset(env.unwrapped.knowledge())
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(planner.act(obs, env.unwrapped.knowledge()))
        if terminated or truncated:
            break
    frame = env.render()
    env.close()
    return frame


def render_parallel(steps: int) -> np.ndarray:
    """The frame of three robots in ``crowd`` after ``steps`` steps of ``dwa`` each."""
    env = srpb_gym.parallel_env(scenario="crowd", n_robots=3, render_mode="rgb_array")
    observations, _ = env.reset(seed=0)
    planners = {agent: make_planner("dwa") for agent in env.agents}
    for agent, planner in planners.items():
        planner.reset(env.knowledge(agent))
    for _ in range(steps):
        if not env.agents:
            break
        actions = {a: planners[a].act(observations[a], env.knowledge(a)) for a in env.agents}
        observations, *_ = env.step(actions)
    frame = env.render()
    env.close()
    return frame


def main(argv: list[str] | None = None) -> int:
    """Render every picture into ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/figures/envs", help="folder to write into")
    parser.add_argument("--steps", type=int, default=80, help="steps before the frame")
    args = parser.parse_args(argv)
    if args.steps < 0:
        print(f"render_env_figures: error: --steps must be >= 0, got {args.steps}",
              file=sys.stderr)  # fmt: skip
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for env_id in (*SCENARIO_IDS, MIX_ID):
        save_png(render_single(env_id, args.steps), out / f"{env_id}.png")
        print(out / f"{env_id}.png")
    save_png(render_parallel(args.steps), out / f"{PARALLEL_NAME}.png")
    print(out / f"{PARALLEL_NAME}.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
