"""The models shipped in ``srpb_gym/models/<name>/``, by short name."""

from __future__ import annotations

import json
from importlib.resources import files
from pathlib import Path
from typing import Any

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


def card(name: str) -> dict[str, Any]:
    """The facts of a shipped model's card (``card.json``); ``KeyError`` for an unknown name."""
    if name not in model_names():
        raise KeyError(f"no shipped model {name!r}; shipped: {', '.join(model_names()) or 'none'}")
    return json.loads((_root() / name / "card.json").read_text(encoding="utf-8"))
