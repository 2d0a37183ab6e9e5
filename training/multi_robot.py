"""Training one policy shared by every robot of the PettingZoo environment, with SB3.

:class:`~srpb_gym.training.shared_policy.SharedPolicyVecEnv` turns K multi-robot
environments of N robots each into an SB3 ``VecEnv`` of K x N slots, one per robot; the
episode of an environment ends for all its robots as soon as one of them leaves (the
others' slots are truncated, so PPO bootstraps their value). Episodes in training are then
shorter than in evaluation (they end at the first robot's end), which an evaluation with
``srpb-gym eval --robots N --policy model.zip`` does not share.

    python -m training.multi_robot --scenario crowd --robots 3 --envs 2 --steps 200000 \\
        --out runs/ppo-multi
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import srpb_gym
from srpb_gym.models.normalization import save_vecnormalize
from srpb_gym.models.record import record_observation
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.training.config import vecnormalize_kwargs
from srpb_gym.training.shared_policy import SharedPolicyVecEnv

#: PPO's discount here (stable-baselines3's default), which the return statistics share
GAMMA = 0.99


def train(
    scenario: str, robots: int, envs: int, steps: int, out: str, seed: int = 0,
    reward: str = "task",
) -> Path:  # fmt: skip
    """Train PPO shared by every robot; writes ``model.zip``, ``vecnormalize.npz`` (where
    ``srpb-gym eval --policy`` looks) and ``run.json`` into ``out``; returns ``out``."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    fns = [lambda: srpb_gym.parallel_env(scenario=scenario, n_robots=robots, reward=reward)
           for _ in range(envs)]  # fmt: skip
    venv = SharedPolicyVecEnv(fns)
    venv.seed(seed)
    venv = VecNormalize(VecMonitor(venv), **vecnormalize_kwargs(GAMMA))  # reward unclipped
    model = PPO("MlpPolicy", venv, n_steps=max(64, 2048 // venv.num_envs), batch_size=64,
                gamma=GAMMA, seed=seed, verbose=0)  # fmt: skip
    record_observation(model, venv.unwrapped.envs[0].observation_config)
    started = time.perf_counter()
    model.learn(total_timesteps=steps)
    model.save(folder / "model.zip")
    save_vecnormalize(venv, folder / "vecnormalize.npz")
    record = {"scenario": scenario, "robots": robots, "envs": envs, "steps": steps,
              "seed": seed, "reward": reward, "wall_time_s": time.perf_counter() - started,
              "command": " ".join(sys.argv)}  # fmt: skip
    (folder / "run.json").write_text(json.dumps(record, indent=1) + "\n")
    return folder


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="crowd")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--envs", type=int, default=2, help="multi-robot environments")
    ap.add_argument("--steps", type=int, default=200_000, help="robot-steps in total")
    ap.add_argument("--reward", default="task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="runs/ppo-multi")
    args = ap.parse_args(argv)
    folder = train(args.scenario, args.robots, args.envs, args.steps, args.out, args.seed,
                   args.reward)  # fmt: skip
    env_id = next((k for k, v in SCENARIO_IDS.items() if v == args.scenario), args.scenario)
    print(
        f"saved {folder / 'model.zip'}; evaluate with: srpb-gym eval --env {env_id} "
        f"--robots {args.robots} --policy {folder / 'model.zip'}"
    )


if __name__ == "__main__":
    main()
