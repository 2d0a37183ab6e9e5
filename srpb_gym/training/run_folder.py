"""The files of a training run's folder that srpb-gym writes itself: ``config.yaml`` (every
resolved setting), ``command.txt`` (the command line) and ``run.json`` (reward weights,
seed, versions, machine, then steps and wall time), and the folder's default place; and
the checkpoint a multi-robot run's ``selection.json`` chose
(``python -m training.select_checkpoint``)."""

from __future__ import annotations

import json
import os
import platform
import shlex
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from srpb_gym.errors import InputError
from srpb_gym.evaluation.harness import versions
from srpb_gym.training.config import TrainConfig

#: the file a multi-robot run's choice of checkpoint is written to, in the run folder
SELECTION_FILE = "selection.json"
#: the candidate name of a run's final model in that file
FINAL = "final"


def default_out(env_id: str, preset: str, now: float | None = None) -> str:
    """``runs/train/<env_id>-<preset>-<time>``."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    return os.path.join("runs", "train", f"{env_id}-{preset}-{stamp}")


def write_run_files(out: str, env_id: str, preset: str, env_kwargs: Mapping[str, Any],
                    seed: int, config: TrainConfig, argv: Sequence[str],
                    weights: Mapping[str, Mapping[str, float]]) -> None:  # fmt: skip
    """``config.yaml``, ``command.txt`` and the first facts of ``run.json``."""
    doc = {"algo": "PPO", "env": env_id, "reward": preset, "env_kwargs": dict(env_kwargs),
           "seed": seed, "hyperparams": config.as_dict()}  # fmt: skip
    with open(os.path.join(out, "config.yaml"), "w", encoding="utf-8") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    with open(os.path.join(out, "command.txt"), "w", encoding="utf-8") as f:
        f.write(shlex.join(["srpb-gym", *argv]) + "\n")
    run = {"env": env_id, "reward": preset, "reward_weights": weights, "seed": seed,
           "versions": versions(), "machine": machine(),
           "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}  # fmt: skip
    with open(os.path.join(out, "run.json"), "w", encoding="utf-8") as f:
        json.dump(run, f, indent=2)


def finish_run_json(out: str, steps: int, wall: float, interrupted: bool,
                    time_limit_reached: bool) -> None:  # fmt: skip
    """The last facts of ``run.json``: steps, wall time and how the run ended."""
    update_run_json(out, {"steps": int(steps), "wall_time_s": round(wall, 1),
                          "interrupted": interrupted,
                          "time_limit_reached": time_limit_reached})  # fmt: skip


def update_run_json(out: str, values: Mapping[str, Any]) -> None:
    """Add ``values`` to ``run.json``."""
    path = os.path.join(out, "run.json")
    with open(path, encoding="utf-8") as f:
        run = json.load(f)
    run |= dict(values)
    with open(path, "w", encoding="utf-8") as f:
        json.dump(run, f, indent=2)


def machine() -> dict[str, Any]:
    """The machine a run trained on: processor, logical cores, operating system."""
    import torch

    return {"processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(), "system": platform.platform(),
            "torch_threads": torch.get_num_threads()}  # fmt: skip


def read_selection(run: Path) -> dict[str, Any] | None:
    """The selection written for ``run`` (``None`` when it has none); an
    :class:`InputError` when its chosen candidate is not in the run."""
    path = run / SELECTION_FILE
    if not path.is_file():
        return None
    try:
        selection = json.loads(path.read_text(encoding="utf-8"))
        chosen = selection["chosen"]
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(
            f"not a selection of training.select_checkpoint ({exc})", str(path)
        ) from None
    if not (chosen_model(run, selection) / "model.zip").is_file():
        raise InputError(f"the chosen candidate {chosen!r} has no model.zip", str(path))
    return selection


def chosen_model(run: Path, selection: dict[str, Any] | None) -> Path:
    """The folder of the model to ship: the chosen candidate, or the run's final model."""
    if selection is None or selection["chosen"] == FINAL:
        return run
    return run / "checkpoints" / str(selection["chosen"])
