"""Pretrained policies shipped with srpb-gym, loadable by their short names.

Each model is a folder ``srpb_gym/models/<name>/`` holding ``model.zip`` (a
stable-baselines3 PPO model), ``vecnormalize.pkl`` (its observation statistics),
``card.md`` (its model card: environment id and version, reward preset and the weights
of each scenario, steps, wall time, machine, seed, command, results) and ``card.json``
(the same facts as data). Names follow ``ppo-<scenario>-<preset>``, e.g.
``ppo-corridor-srpb`` (``ppo-mix-srpb`` for a model trained on ``SRPB-Mix-v0``).
:func:`model_names` lists those shipped.

``srpb-gym eval --policy ppo-corridor-srpb`` takes a short name wherever it takes a model
file; ``srpb-gym models`` lists them. Loading a model needs the ``train`` extra
(stable-baselines3 and torch); listing does not.
"""

from __future__ import annotations

import json
import os
from importlib.resources import files
from pathlib import Path
from typing import Any

__all__ = ["card", "find_model", "model_names", "model_path"]

MODEL_FILE = "model.zip"


def _root() -> Any:
    return files("srpb_gym.models")


def model_names() -> list[str]:
    """Short names of the shipped models (folders holding a ``model.zip``)."""
    return sorted(p.name for p in _root().iterdir()
                  if p.is_dir() and (p / MODEL_FILE).is_file())  # fmt: skip


def model_path(name: str) -> Path | None:
    """The ``model.zip`` of the shipped model ``name``, or ``None`` if there is none."""
    if not isinstance(name, str) or "/" in name or "\\" in name or name.startswith("."):
        return None
    path = _root() / name / MODEL_FILE
    return Path(str(path)) if path.is_file() else None


def find_model(given: str) -> str | None:
    """The ``model.zip`` that ``given`` names: a model file, a run folder holding
    ``model.zip``, or a shipped model's name; ``None`` if it names none."""
    path = os.path.join(given, MODEL_FILE) if os.path.isdir(given) else given
    if os.path.isfile(path):
        return path
    shipped = model_path(given)
    return None if shipped is None else str(shipped)


def card(name: str) -> dict[str, Any]:
    """The facts of a shipped model's card (``card.json``); ``KeyError`` for an unknown name."""
    if name not in model_names():
        raise KeyError(f"no shipped model {name!r}; shipped: {', '.join(model_names()) or 'none'}")
    return json.loads((_root() / name / "card.json").read_text(encoding="utf-8"))
