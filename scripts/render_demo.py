"""Render one frame of a scenario to a PNG file, for a look at the renderer.

Usage: ``python scripts/render_demo.py OUT.png [--scenario crowd] [--steps 60] [--seed 0]``

The robot drives towards its goal with a simple proportional controller; the panel shows
the time and the SRPB social metrics of the episode so far.
"""

from __future__ import annotations

import argparse
import math
import time
import warnings

import numpy as np

from srpb_gym.metrics import evaluate
from srpb_gym.render import Renderer
from srpb_gym.scenarios import load_scenario, sample
from srpb_gym.simulation import Simulation

PANEL_METRICS = ("m_psi", "m_fsi", "m_dir", "m_obs", "m_plin")


def go_to_goal(sim: Simulation) -> np.ndarray:
    """(R, 3) body-frame commands turning each robot towards its goal and driving there."""
    pose = sim.world.robot_pose
    goals = np.array([s.goal for s in sim.robots])
    heading = np.arctan2(goals[:, 1] - pose[:, 1], goals[:, 0] - pose[:, 0])
    error = np.remainder(heading - pose[:, 2] + math.pi, 2 * math.pi) - math.pi
    speed = 0.5 * np.clip(1.0 - np.abs(error) / 1.2, 0.0, 1.0)
    return np.column_stack((speed, np.zeros_like(speed), 1.5 * error))


def main(argv: list[str] | None = None) -> int:
    """Simulate ``--steps`` steps of ``--scenario`` and save the last frame to ``out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="PNG file to write")
    parser.add_argument("--scenario", default="crowd")
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--width", type=int, default=720)
    parser.add_argument("--height", type=int, default=540)
    args = parser.parse_args(argv)

    scenario = load_scenario(args.scenario)
    sim = Simulation.from_scenario(scenario)
    sim.reset(sample(scenario, np.random.default_rng(args.seed)), np.random.default_rng(args.seed))
    for _ in range(args.steps):
        sim.step(go_to_goal(sim), 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metrics = evaluate(sim.robots[0].record)
    panel = {name: metrics[name] for name in PANEL_METRICS}

    renderer = Renderer("rgb_array", args.width, args.height)
    renderer.render(sim, 0, panel)  # the first frame pays one-off compilation
    start = time.perf_counter()
    frame = renderer.render(sim, 0, panel)
    elapsed = time.perf_counter() - start
    renderer.close()

    import pygame

    surface = pygame.surfarray.make_surface(frame.transpose(1, 0, 2))
    pygame.image.save(surface, args.out)
    print(f"wrote {args.out} ({frame.shape[1]}x{frame.shape[0]}, {1e3 * elapsed:.1f} ms/frame)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
