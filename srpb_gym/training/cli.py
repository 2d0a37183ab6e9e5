"""``srpb-gym train``: the command line of a PPO training run (also ``python -m
training.train``). stable-baselines3 and torch are imported only when it runs."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.evaluation.ray_pool import check_installed
from srpb_gym.evaluation.spec import BACKENDS
from srpb_gym.models.shipped import MODEL_FILE
from srpb_gym.training.config import DEFAULT_VALIDATION_EPISODES, parse_overrides, resolve
from srpb_gym.training.run_folder import default_out
from srpb_gym.training.targets import eval_command as command_line
from srpb_gym.training.targets import eval_setup

INSTALL_HINT = (
    'training needs stable-baselines3, torch and tensorboard: pip install "srpb-gym[train]"'
)


def add_train_command(subparsers: Any) -> None:
    """Register ``train``: PPO on one environment id (or the mixture SRPB-Mix-v0)."""
    p = subparsers.add_parser(
        "train",
        help="train a PPO policy",
        description=(
            "Train PPO (stable-baselines3) on a registered id or SRPB-Mix-v0, with the "
            "hyperparameters of configs/train/ppo.yaml for that id (its 'default' entry "
            "first), overridden by --hyperparams. The run folder gets model.zip, "
            "vecnormalize.npz, best/ (the best periodic evaluation), config.yaml, "
            "command.txt, run.json (seed, versions, machine, wall time), progress.csv and "
            "TensorBoard logs (tb/: every reward term, every srpb/* metric, eval/*). "
            "Ctrl-C or SIGTERM saves the model and stops. At the end it prints the "
            "`srpb-gym eval` command of the run's best checkpoint (`--policy RUN/best`)."
        ),
    )
    p.add_argument("--env", required=True, metavar="ID", help="environment id, e.g. SRPB-Crowd-v0")
    p.add_argument("--reward", default="srpb", metavar="PRESET",
                   help="reward preset: srpb (default) or task")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="seed of the run (default 0)")
    p.add_argument("--steps", type=int, metavar="N", help="environment steps (n_timesteps)")
    p.add_argument("--hyperparams", nargs="+", default=[], metavar="KEY=VALUE",
                   help="override hyperparameters: n_steps=1024 'net_arch=[64, 64]'")  # fmt: skip
    p.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                   help="gym.make arguments: 'crowd={robot_reaction: 0.0}', SRPB-Mix-v0's "
                   "'weights=[1, 1, 1, 2, 3]'; periodic evaluation takes them but the "
                   "reward, the time limit and the mixture's draws")  # fmt: skip
    p.add_argument("--config", metavar="FILE", help="hyperparameter file (default: the packaged "
                   "configs/train/ppo.yaml)")  # fmt: skip
    p.add_argument("--out", metavar="DIR", help="run folder (default runs/train/ID-PRESET-TIME)")
    p.add_argument("--max-minutes", type=float, metavar="M",
                   help="stop after M minutes of wall time (the model is saved)")  # fmt: skip
    p.add_argument("--init", metavar="MODEL",
                   help="start from a trained model (model.zip, its run folder or a shipped "
                   "model's name, e.g. ppo-crowd-task) instead of random weights")  # fmt: skip
    p.add_argument("--init-new-observation", action="store_true",
                   help="start from --init although it observed with other settings of the "
                   "same shape, to fine-tune it to this run's (e.g. --env-kwargs "
                   "'observation={lidar_groups: 0.01}'); without it such a model is "
                   "refused")  # fmt: skip
    p.add_argument("--trust-pickle", action="store_true",
                   help="let the pickles of --init and of the warm start's teachers run: a "
                   "vecnormalize.pkl and a model.zip's pickled attributes (a pickle is "
                   "code; without it a .pkl is refused)")  # fmt: skip
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    ray = p.add_argument_group(
        "several seeds or a grid on Ray Tune",
        "each trial is one run folder <out>/<trial>, as a single run writes it; the best "
        "trial is chosen on the validation seeds (docs: training/README.md)",
    )
    ray.add_argument("--backend", choices=BACKENDS, default="process",
                     help="process: one run here (default); ray: --seeds x --grid as Ray "
                     "Tune trials (pip install \"srpb-gym[ray]\")")  # fmt: skip
    ray.add_argument("--seeds", type=int, nargs="+", metavar="S",
                     help="seeds of the trials (with --backend ray; default: --seed)",
                     )  # fmt: skip
    ray.add_argument("--grid", nargs="+", default=[], metavar="KEY=[V1, V2]",
                     help="hyperparameter values to try (with --backend ray), e.g. "
                     "'learning_rate=[0.0003, 0.001]'; every combination with every seed",
                     )  # fmt: skip
    ray.add_argument("--validation-episodes", type=int, default=DEFAULT_VALIDATION_EPISODES,
                     metavar="N", help="episodes per environment on the validation seeds "
                     "that choose the best trial (default: "
                     f"{DEFAULT_VALIDATION_EPISODES})")  # fmt: skip
    ray.add_argument("--address", metavar="ADDR",
                     help="the Ray cluster (with --backend ray; default: Ray on this "
                     "machine); --out must then be on a file system every node sees",
                     )  # fmt: skip
    p.set_defaults(func=run_train)


def run_train(args: argparse.Namespace) -> int:
    """Resolve the configuration, train, say where the run is."""
    for option, given in (("--seeds", args.seeds), ("--grid", args.grid),
                          ("--address", args.address)):  # fmt: skip
        if given and args.backend != "ray":
            raise InputError("runs trials on Ray Tune: add --backend ray", key=option)
    if args.backend == "ray":
        return run_sweep(args)
    overrides = parse_overrides(args.hyperparams)
    if args.steps is not None:
        overrides["n_timesteps"] = args.steps
    config = resolve(args.env, overrides, args.config)
    env_kwargs = parse_overrides(args.env_kwargs, "--env-kwargs")
    if args.seed < 0:
        raise InputError(f"must be at least 0, got {args.seed}", key="--seed")
    if args.max_minutes is not None and not args.max_minutes > 0:
        raise InputError(f"must be > 0, got {args.max_minutes}", key="--max-minutes")
    try:
        # deferred: run imports stable_baselines3 and torch (the train extra), optional here
        from srpb_gym.training.run import train
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc})") from None
    result = train(args.env, config, preset=args.reward, seed=args.seed, out=args.out,
                   env_kwargs=env_kwargs, progress=not args.no_progress,
                   argv=getattr(args, "argv", ()), max_minutes=args.max_minutes,
                   init=args.init, init_new_observation=args.init_new_observation,
                   trust_pickle=args.trust_pickle,
                   log=lambda line: print(f"srpb-gym: {line}", file=sys.stderr))  # fmt: skip
    state = "interrupted" if result.interrupted else "finished"
    print(f"{state} after {result.steps} steps in {result.wall_time:.0f} s; run in {result.out}")
    print(f"evaluate it: {eval_command(args.env, env_kwargs, result.out)}")
    return 130 if result.interrupted else 0


def run_sweep(args: argparse.Namespace) -> int:
    """``--backend ray``: the seeds and grid points as Ray Tune trials."""
    if args.init is not None or args.init_new_observation:
        raise InputError("trials start from random weights here", key="--init")
    overrides = parse_overrides(args.hyperparams)
    if args.steps is not None:
        overrides["n_timesteps"] = args.steps
    resolve(args.env, overrides, args.config)  # every key checked before Ray starts
    grid = parse_overrides(args.grid, "--grid")
    check_installed()
    try:
        # deferred: tune imports run, which imports stable_baselines3 and torch (train extra)
        from srpb_gym.training import tune
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc})") from None
    out = args.out or default_out(args.env, args.reward).replace("train", "tune", 1)
    sweep = tune.SweepSpec(
        args.env, overrides, None if args.config is None else os.path.abspath(args.config),
        args.reward, parse_overrides(args.env_kwargs, "--env-kwargs"), out, os.getcwd(),
        args.validation_episodes, args.max_minutes, tuple(getattr(args, "argv", ())),
    )  # fmt: skip
    outcome = tune.run_sweep(sweep, args.seeds or [args.seed], grid, args.address,
                             log=lambda line: print(f"srpb-gym: {line}",
                                                    file=sys.stderr))  # fmt: skip
    failed = [t["trial"] for t in outcome.trials if t["error"]]
    if outcome.best is not None:
        print(f"best trial on the validation seeds: {outcome.best} "
              f"({os.path.join(outcome.out, outcome.best)})")  # fmt: skip
    print(f"{len(outcome.trials) - len(failed)} of {len(outcome.trials)} trials finished; "
          f"trials.csv and best.json in {outcome.out}")  # fmt: skip
    return 1 if failed else 0


def eval_command(env_id: str, env_kwargs: dict[str, Any], out: str) -> str:
    """The ``srpb-gym eval`` command of a run: its best checkpoint (``best/``, or the final
    model when there is none) on what its periodic evaluations run (the mixture's
    scenarios, a scenario file, the id itself), with the environment's keyword arguments
    that are not training's alone."""
    env_ids, kwargs = eval_setup(env_id, env_kwargs)
    best = os.path.join(out, "best")
    policy = best if os.path.isfile(os.path.join(best, MODEL_FILE)) else out
    return command_line(env_ids, kwargs, policy)
