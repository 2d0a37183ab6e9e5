"""Training one policy shared by every robot of the PettingZoo environment, with SB3.

:class:`~srpb_gym.training.shared_policy.SharedPolicyVecEnv` turns K multi-robot
environments of N robots each into an SB3 ``VecEnv`` of K x N slots, one per robot: a
robot that reaches its goal turns back while the others drive on (a return trip); a
collision that ends a robot's task, or the time limit, ends the episode for all its
robots (the others' slots are truncated, so PPO bootstraps their value). An evaluation
with ``srpb-gym eval --robots N --policy model.zip`` has no return trips.

    python -m training.multi_robot --scenario crowd --robots 3 --envs 2 --steps 200000 \\
        --out runs/ppo-multi

The hyperparameters are those of ``srpb-gym train`` (``configs/train/ppo.yaml``, the
scenario's entry, then ``--hyperparams``): the PPO keys, ``net_arch``, ``activation_fn``
and ``torch_threads``; ``n_steps`` is per robot slot. ``--env-kwargs`` are the
environment's arguments (``observation``, ``reward_weights``, ``reward_people``, ...), as
for ``srpb-gym train``. ``--init MODEL`` starts from a trained model (a single-robot one
too: the robots observe as one robot does), its weights and normalisation statistics,
which must have observed with the run's observation settings. ``--save-every N`` writes
the model and its statistics every N robot-steps, so that a stopped run leaves one;
with ``--keep-checkpoints`` each of those is also kept, in ``checkpoints/step_<N>/``
(``model.zip`` and ``vecnormalize.npz``: ``srpb-gym eval --policy`` takes the folder), to
choose one on the checkpoint-selection seeds instead of taking the last.

Run it from the repository's root: the ``training/`` scripts are not installed with the
package. ``--out`` must be a new or empty folder; every argument is checked before it is
made (a bad one is one line on stderr, exit status 2).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import srpb_gym
from srpb_gym.config import parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.models.normalization import save_vecnormalize
from srpb_gym.models.record import record_observation
from srpb_gym.registration import ENV_IDS
from srpb_gym.reward_terms import preset_names
from srpb_gym.scenarios import load_scenario
from srpb_gym.training.config import PPO_KEYS, TrainConfig, resolve
from srpb_gym.training.shared_policy import SharedPolicyVecEnv

PROG = "training.multi_robot"
#: the --hyperparams this recipe uses (the rest of srpb-gym train's are refused)
USED_KEYS = frozenset({*PPO_KEYS, "net_arch", "activation_fn", "torch_threads"})


def env_id_of(scenario: str) -> str:
    """The Gymnasium id of a packaged scenario (its configuration entry), else the name."""
    return ENV_IDS.get(scenario, scenario)


def check_arguments(scenario: str, robots: int, envs: int, steps: int, seed: int,
                    reward: str, hyperparams: Mapping[str, Any] | None = None,
                    env_kwargs: Mapping[str, Any] | None = None) -> TrainConfig:  # fmt: skip
    """Refuse a bad argument before anything is made: an :class:`InputError` naming the
    option. ``robots`` must fit the scenario's places, ``reward`` be a preset, the
    hyperparameters keys this recipe uses, and the env kwargs make an environment.
    Returns the resolved configuration."""
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
    unused = sorted(set(hyperparams or {}) - USED_KEYS)
    if unused:
        raise InputError(f"{unused[0]} is not used by this recipe (it takes "
                         f"{', '.join(sorted(USED_KEYS))})", key="--hyperparams")  # fmt: skip
    for key in ("scenario", "n_robots", "reward"):
        if key in (env_kwargs or {}):
            raise InputError(f"{key} is set by --{'robots' if key == 'n_robots' else key}",
                             key="--env-kwargs")  # fmt: skip
    try:
        srpb_gym.parallel_env(**_env_kwargs(scenario, robots, reward, env_kwargs)).close()
    except InputError as exc:
        raise InputError(str(exc), key="--env-kwargs") from None
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), key="--env-kwargs") from None
    return resolve(env_id_of(scenario), dict(hyperparams or {}))


def _env_kwargs(scenario: str, robots: int, reward: str,
                env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:  # fmt: skip
    return {"scenario": scenario, "n_robots": robots, "reward": reward, **(env_kwargs or {})}


def train(
    scenario: str, robots: int, envs: int, steps: int, out: str, seed: int = 0,
    reward: str = "task", hyperparams: Mapping[str, Any] | None = None,
    env_kwargs: Mapping[str, Any] | None = None, init: str | None = None,
    save_every: int = 0, log: Any = print, new_observation: bool = False,
    keep_checkpoints: bool = False,
) -> Path:  # fmt: skip
    """Train PPO shared by every robot; writes ``model.zip``, ``vecnormalize.npz`` (where
    ``srpb-gym eval --policy`` looks) and ``run.json`` (``steps``: the steps the model
    took, a whole number of rollouts, at least ``steps``) into ``out``, which must be new
    or empty (a folder holding anything is refused, as by ``srpb-gym train``); returns
    ``out``. Every argument is checked, and ``init`` read, before the folder is made; a
    failure after leaves the folder as it was. ``new_observation``: start from ``init``
    although it observed with other settings of the same shape. ``keep_checkpoints``: keep
    each model saved every ``save_every`` robot-steps in ``checkpoints/step_<N>/``."""
    from srpb_gym.training.run import discard_run, load_init, read_init  # deferred: torch

    config = check_arguments(scenario, robots, envs, steps, seed, reward, hyperparams,
                             env_kwargs)  # fmt: skip
    start = read_init(init) if init else None
    existed = os.path.exists(out)
    folder = Path(check_out_dir(out))
    try:
        model = _build(scenario, robots, reward, env_kwargs, envs, seed, config)
        started_from = None
        if start is not None:
            load_init(model, model.get_env(), start, model.get_env().unwrapped.envs[0]
                      .observation_config, new_observation)  # fmt: skip
            started_from = {"model": start.path, "vecnormalize": start.vecnormalize,
                            "steps": start.steps}  # fmt: skip
            log(f"starting from {start.path}")
    except InputError:
        discard_run(out, existed)
        raise
    started = time.perf_counter()
    model.learn(
        total_timesteps=steps, callback=progress_callback(folder, save_every, log, keep_checkpoints)
    )
    _save(model, folder)
    record = {"scenario": scenario, "robots": robots, "envs": envs,
              "steps": int(model.num_timesteps), "steps_asked": steps, "seed": seed,
              "reward": reward, "env_kwargs": dict(env_kwargs or {}),
              "hyperparams": {k: v for k, v in config.as_dict().items() if k in USED_KEYS},
              "init": started_from, "wall_time_s": time.perf_counter() - started,
              "command": shlex.join(["python", "-m", PROG, *sys.argv[1:]])}  # fmt: skip
    (folder / "run.json").write_text(json.dumps(record, indent=1) + "\n")
    return folder


def _build(scenario: str, robots: int, reward: str, env_kwargs: Mapping[str, Any] | None,
           envs: int, seed: int, config: TrainConfig) -> Any:  # fmt: skip
    """PPO on ``envs`` normalised shared-policy environments, recording what they observe."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    kwargs = _env_kwargs(scenario, robots, reward, env_kwargs)
    shared = SharedPolicyVecEnv([lambda: srpb_gym.parallel_env(**kwargs) for _ in range(envs)])
    shared.seed(seed)
    venv = VecNormalize(VecMonitor(shared), **config.vecnormalize_kwargs())  # reward unclipped
    if config.torch_threads:
        torch.set_num_threads(config.torch_threads)
    model = PPO("MlpPolicy", venv, seed=seed, verbose=0, **config.ppo_kwargs())
    record_observation(model, shared.envs[0].observation_config)
    return model


def _save(model: Any, folder: Path) -> None:
    model.save(folder / "model.zip")
    save_vecnormalize(model.get_env(), folder / "vecnormalize.npz")


def progress_callback(folder: Path, save_every: int, log: Any, keep: bool = False) -> Any:
    """An SB3 callback that counts the robots that left by their own end (goal or
    collision, not cut short) and, every ``save_every`` robot-steps (0: never), logs their
    success and collision rates and saves the model and its statistics into ``folder``
    (with ``keep``, also into ``folder/checkpoints/step_<N>``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Progress(BaseCallback):
        def _on_training_start(self) -> None:
            self.counts = [0, 0, 0]  # left, reached the goal, collided
            self.next_at = save_every
            self.started = time.perf_counter()

        def _on_step(self) -> bool:
            for done, info in zip(self.locals["dones"], self.locals["infos"]):
                if done and not info.get("TimeLimit.truncated", False):
                    self.counts[0] += 1
                    self.counts[1] += bool(info.get("is_success"))
                    self.counts[2] += bool(info.get("collision"))
            if save_every and self.num_timesteps >= self.next_at:
                self.next_at += save_every
                left, goal, hit = self.counts
                rate = self.num_timesteps / (time.perf_counter() - self.started)
                log(f"{self.num_timesteps} robot-steps ({rate:.0f}/s): {left} robots left, "
                    f"{goal / max(left, 1):.1%} at the goal, {hit / max(left, 1):.1%} "
                    "collided")  # fmt: skip
                self.counts = [0, 0, 0]
                _save(self.model, folder)
                if keep:
                    checkpoint = folder / "checkpoints" / f"step_{self.num_timesteps:09d}"
                    checkpoint.mkdir(parents=True, exist_ok=True)
                    _save(self.model, checkpoint)
            return True

    return Progress()


def main(argv: Sequence[str] | None = None) -> int:
    """The command line; 0 when trained, 2 (one line on stderr) for a bad argument."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="crowd")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--envs", type=int, default=2, help="multi-robot environments")
    ap.add_argument("--steps", type=int, default=200_000, help="robot-steps in total")
    ap.add_argument("--reward", default="task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hyperparams", nargs="+", default=[], metavar="KEY=VALUE",
                    help="PPO keys, net_arch, activation_fn, torch_threads (n_steps per "
                    "robot slot), e.g. learning_rate=1e-4")  # fmt: skip
    ap.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                    help="the environment's arguments, e.g. 'observation={lidar_encoding: "
                    "log}' reward_people=ground_truth")  # fmt: skip
    ap.add_argument("--init", metavar="MODEL",
                    help="start from a trained model (model.zip, its run folder or a "
                    "shipped model's name), a single-robot one too")  # fmt: skip
    ap.add_argument("--init-new-observation", action="store_true",
                    help="start from --init although it observed with other settings of the "
                    "same shape")  # fmt: skip
    ap.add_argument("--save-every", type=int, default=0, metavar="N",
                    help="log progress and save the model every N robot-steps (0: at the "
                    "end only)")  # fmt: skip
    ap.add_argument("--keep-checkpoints", action="store_true",
                    help="keep each model --save-every writes, in "
                    "checkpoints/step_<N>/")  # fmt: skip
    ap.add_argument("--out", default="runs/ppo-multi",
                    help="run folder, new or empty (default: runs/ppo-multi)")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        if args.save_every < 0:
            raise InputError(f"must be at least 0, got {args.save_every}", key="--save-every")
        if args.keep_checkpoints and not args.save_every:
            raise InputError("needs --save-every N: the robot-steps between checkpoints",
                             key="--keep-checkpoints")  # fmt: skip
        folder = train(args.scenario, args.robots, args.envs, args.steps, args.out, args.seed,
                       args.reward, parse_overrides(args.hyperparams),
                       parse_overrides(args.env_kwargs, "--env-kwargs"), args.init,
                       args.save_every, log=lambda line: print(line, flush=True),
                       new_observation=args.init_new_observation,
                       keep_checkpoints=args.keep_checkpoints)  # fmt: skip
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(
        f"saved {folder / 'model.zip'}; evaluate with: srpb-gym eval --env "
        f"{env_id_of(args.scenario)} --robots {args.robots} --policy {folder / 'model.zip'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
