"""The names of the reward terms and the packaged weight presets (``configs/reward/``).

The ground floor of the reward: plain names and checked numbers, read with the safe YAML
reader, so that scenario files can check their ``reward`` section against the same names
as :mod:`srpb_gym.reward` without importing the reward itself.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from importlib.resources import files
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.yaml_io import load_file

TASK_TERMS: tuple[str, ...] = ("progress", "success", "collision", "time", "approach")
SRPB_TERMS: tuple[str, ...] = (
    "obs", "vsm", "hsm", "osc", "bwd", "iprot", "chc", "psi", "fsi", "dir",
)  # fmt: skip
TERMS: tuple[str, ...] = TASK_TERMS + SRPB_TERMS
#: the index of each term in :data:`TERMS` (and in a weight vector)
TERM_INDEX: dict[str, int] = {name: i for i, name in enumerate(TERMS)}


def preset_names() -> list[str]:
    """Names of the packaged reward presets."""
    return sorted(p.name[:-5] for p in files("srpb_gym.reward_presets").iterdir()
                  if p.name.endswith(".yaml"))  # fmt: skip


def load_preset(name: str) -> dict[str, float]:
    """The weights of a packaged preset (``task`` or ``srpb``)."""
    if not isinstance(name, str) or name not in preset_names():
        raise InputError(f"unknown reward preset {name!r}; choose one of {preset_names()}",
                         key="reward")  # fmt: skip
    path = files("srpb_gym.reward_presets") / f"{name}.yaml"
    return check_weights(load_file(path, str(path)), file=str(path))


def check_weights(
    weights: Mapping[str, Any], where: str = "reward_weights", file: str | None = None
) -> dict[str, float]:
    """Weights by term name, each a finite number; unknown names are errors. ``where``
    names the mapping in errors (``file``: the file it was read from, if any)."""
    prefix = "" if file is not None else f"{where}."
    if not isinstance(weights, Mapping):
        raise InputError(f"expected a mapping of term names to weights, got {weights!r}",
                         file, key=None if file is not None else where)  # fmt: skip
    out = {}
    for name, value in weights.items():
        if name not in TERM_INDEX:
            raise InputError(f"unknown reward term; valid terms: {', '.join(TERMS)}",
                             file, key=f"{prefix}{name}")  # fmt: skip
        number = math.nan
        if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
            try:
                number = float(value)
            except OverflowError:  # an int too large for a float
                number = math.inf
        if not math.isfinite(number):
            raise InputError(f"expected a finite number, got {value!r}", file,
                             key=f"{prefix}{name}")  # fmt: skip
        out[name] = number
    return out
