"""Where the packaged data lives (light: safe to import from ``srpb_gym/__init__``)."""

from __future__ import annotations

import importlib.resources
from pathlib import Path
from typing import Any

SCENARIOS_PACKAGE = "srpb_gym.envs_data"


def scenarios_dir() -> Any:
    """The folder of packaged scenario files (installed package data, else the source
    checkout's ``envs/``)."""
    try:
        return importlib.resources.files(SCENARIOS_PACKAGE)
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[1] / "envs"
