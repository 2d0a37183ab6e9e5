"""Retrain and re-package every shipped model (or those named), one after the other.

    python -m training.retrain_models                 # the shipped ones, at most 1 h each
    python -m training.retrain_models ppo-crowd-srpb  # one (also one not shipped yet)
    python -m training.retrain_models --dry-run       # print the commands only

Each model: ``srpb-gym train`` with its env id, reward preset, seed 0 and the steps of
configs/train/ppo.yaml, stopped after at most ``--max-minutes`` (60) of wall time, into
``runs/train/<name>-<time>``; then ``python -m training.ship`` tests its best checkpoint on 100
unseen seeds (from 10000) and writes ``srpb_gym/models/<name>/`` with its model card.
On a 2-core machine two runs side by side (``--jobs 2``, one torch thread each) finish
sooner than one after the other.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from srpb_gym.models import model_names

#: name -> (environment id, reward preset)
MODELS: dict[str, tuple[str, str]] = {
    "ppo-corridor-task": ("SRPB-Corridor-v0", "task"),
    "ppo-corridor-srpb": ("SRPB-Corridor-v0", "srpb"),
    "ppo-fformation-task": ("SRPB-FFormation-v0", "task"),
    "ppo-fformation-srpb": ("SRPB-FFormation-v0", "srpb"),
    "ppo-crowd-task": ("SRPB-Crowd-v0", "task"),
    "ppo-crowd-srpb": ("SRPB-Crowd-v0", "srpb"),
    "ppo-mix-srpb": ("SRPB-Mix-v0", "srpb"),
}
#: name -> seed and hyperparameter overrides of the run that made the shipped model, where
#: they differ from seed 0 and configs/train/ppo.yaml (the model card has the command)
WARM_START = ("pretrain_planner=dwa", "pretrain_episodes=150")
RUN_SETTINGS: dict[str, tuple[int, tuple[str, ...]]] = {
    "ppo-fformation-srpb": (0, WARM_START),
    "ppo-crowd-srpb": (0, WARM_START),
    "ppo-mix-srpb": (0, WARM_START),
}


def commands(name: str, max_minutes: float, threads: int) -> list[list[str]]:
    env_id, preset = MODELS[name]
    seed, overrides = RUN_SETTINGS.get(name, (0, ()))
    run = f"runs/train/{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    train = ["srpb-gym", "train", "--env", env_id, "--reward", preset, "--seed", str(seed),
             "--max-minutes", f"{max_minutes:g}", "--out", run, "--no-progress"]  # fmt: skip
    hyperparams = [*overrides, *([f"torch_threads={threads}"] if threads else [])]
    if hyperparams:
        train += ["--hyperparams", *hyperparams]
    return [train, [sys.executable, "-m", "training.ship", run, "--name", name]]


def main() -> int:
    parser = argparse.ArgumentParser(description="retrain the shipped models")
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"of: {', '.join(MODELS)}")
    parser.add_argument("--max-minutes", type=float, default=60.0)
    parser.add_argument("--jobs", type=int, default=1, help="runs side by side")
    parser.add_argument("--dry-run", action="store_true")
    args = parser.parse_args()
    unknown = [n for n in args.names if n not in MODELS]
    if unknown:
        parser.error(f"unknown model {unknown[0]!r}; choose from {', '.join(MODELS)}")
    names = args.names or [n for n in MODELS if n in model_names()]
    threads = 1 if args.jobs > 1 else 0

    def one(name: str) -> int:
        for cmd in commands(name, args.max_minutes, threads):
            print("+ " + shlex.join(cmd), flush=True)
            if not args.dry_run and subprocess.run(cmd, check=False).returncode != 0:
                return 1
        return 0

    with ThreadPoolExecutor(max(1, args.jobs)) as pool:
        return max(pool.map(one, names), default=0)


if __name__ == "__main__":
    sys.exit(main())
