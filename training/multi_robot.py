"""Training one policy shared by every robot of the PettingZoo environment, with SB3.

:class:`~srpb_gym.training.shared_policy.SharedPolicyVecEnv` turns K multi-robot
environments of N robots each into an SB3 ``VecEnv`` of K x N slots, one per robot; the
episode of an environment ends for all its robots as soon as one of them leaves (the
others' slots are truncated, so PPO bootstraps their value). Episodes in training are then
shorter than in evaluation (they end at the first robot's end), which an evaluation with
``srpb-gym eval --robots N --policy model.zip`` does not share.

    python -m training.multi_robot --scenario crowd --robots 3 --envs 2 --steps 200000 \\
        --out runs/ppo-multi

Run it from the repository's root: the ``training/`` scripts are not installed with the
package. ``--out`` must be a new or empty folder; every argument is checked before it is
made (a bad one is one line on stderr, exit status 2).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import srpb_gym
from srpb_gym.errors import InputError
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.models.normalization import save_vecnormalize
from srpb_gym.models.record import record_observation
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.reward_terms import preset_names
from srpb_gym.scenarios import load_scenario
from srpb_gym.training.config import vecnormalize_kwargs
from srpb_gym.training.shared_policy import SharedPolicyVecEnv

#: PPO's discount here (stable-baselines3's default), which the return statistics share
GAMMA = 0.99
PROG = "training.multi_robot"


def check_arguments(scenario: str, robots: int, envs: int, steps: int, seed: int,
                    reward: str) -> None:  # fmt: skip
    """Refuse a bad argument before anything is made: an :class:`InputError` naming the
    option. ``robots`` must fit the scenario's places, ``reward`` be a preset."""
    for value, option, least in ((steps, "--steps", 1), (envs, "--envs", 1),
                                 (robots, "--robots", 1), (seed, "--seed", 0)):  # fmt: skip
        if value < least:
            raise InputError(f"must be at least {least}, got {value}", key=option)
    if reward not in preset_names():
        raise InputError(f"unknown reward preset {reward!r}; choose one of: "
                         f"{', '.join(preset_names())}", key="--reward")  # fmt: skip
    try:
        load_scenario(scenario).robot_specs(robots)
    except InputError as exc:
        key = "--robots" if exc.key == "n_robots" else "--scenario"
        raise InputError(exc.message if exc.key == "n_robots" else str(exc), key=key) from None


def train(
    scenario: str, robots: int, envs: int, steps: int, out: str, seed: int = 0,
    reward: str = "task",
) -> Path:  # fmt: skip
    """Train PPO shared by every robot; writes ``model.zip``, ``vecnormalize.npz`` (where
    ``srpb-gym eval --policy`` looks) and ``run.json`` (``steps``: the steps the model
    took, a whole number of rollouts, at least ``steps``) into ``out``, which must be new
    or empty (a folder holding anything is refused, as by ``srpb-gym train``); returns
    ``out``. Every argument is checked before the folder is made."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    check_arguments(scenario, robots, envs, steps, seed, reward)
    folder = Path(check_out_dir(out))
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
    record = {"scenario": scenario, "robots": robots, "envs": envs,
              "steps": int(model.num_timesteps), "steps_asked": steps, "seed": seed,
              "reward": reward, "wall_time_s": time.perf_counter() - started,
              "command": " ".join(sys.argv)}  # fmt: skip
    (folder / "run.json").write_text(json.dumps(record, indent=1) + "\n")
    return folder


def main(argv: list[str] | None = None) -> int:
    """The command line; 0 when trained, 2 (one line on stderr) for a bad argument."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="crowd")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--envs", type=int, default=2, help="multi-robot environments")
    ap.add_argument("--steps", type=int, default=200_000, help="robot-steps in total")
    ap.add_argument("--reward", default="task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="runs/ppo-multi",
                    help="run folder, new or empty (default: runs/ppo-multi)")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        folder = train(args.scenario, args.robots, args.envs, args.steps, args.out, args.seed,
                       args.reward)  # fmt: skip
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    env_id = next((k for k, v in SCENARIO_IDS.items() if v == args.scenario), args.scenario)
    print(
        f"saved {folder / 'model.zip'}; evaluate with: srpb-gym eval --env {env_id} "
        f"--robots {args.robots} --policy {folder / 'model.zip'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
