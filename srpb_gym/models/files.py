"""Finding a model's files: the ``model.zip`` that a name, path or run folder names, and the
observation-normalisation statistics (``vecnormalize.pkl``) trained with it.

:func:`find_model` is how every part of srpb-gym finds a model (``srpb-gym eval
--policy``, ``srpb-gym train --init``, the teachers of a warm start);
:func:`resolve_model` adds its statistics and turns a name that names nothing into an
:class:`~srpb_gym.errors.InputError`. Nothing here loads a file (see
:mod:`srpb_gym.models.loading`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from srpb_gym.errors import InputError
from srpb_gym.models.shipped import MODEL_FILE, model_path

VECNORMALIZE = "vecnormalize.pkl"


def find_model(given: str) -> str | None:
    """The ``model.zip`` that ``given`` names: a model file, a run folder holding
    ``model.zip``, or a shipped model's name; ``None`` if it names none."""
    path = os.path.join(given, MODEL_FILE) if os.path.isdir(given) else given
    if os.path.isfile(path):
        return path
    shipped = model_path(given)
    return None if shipped is None else str(shipped)


def resolve_model(given: str, key: str) -> tuple[str, str | None]:
    """The ``model.zip`` (:func:`find_model`) and ``vecnormalize.pkl`` (or ``None``:
    :func:`find_vecnormalize`) that ``given`` names; an :class:`InputError` naming the
    setting ``key`` when it names no model."""
    path = find_model(given)
    if path is None:
        raise InputError(f"no model file, run folder with model.zip or shipped model "
                         f"named {given!r}", key=key)  # fmt: skip
    return path, find_vecnormalize(path)


def vecnormalize_candidates(
    path: str | os.PathLike[str], env_ids: Sequence[str] = ()
) -> list[Path]:
    """Where observation-normalisation statistics of the model ``path`` may lie, in order:
    ``<stem>_vecnormalize.pkl`` and ``vecnormalize.pkl`` beside it (``srpb-gym train``:
    ``<run>/vecnormalize.pkl`` beside ``<run>/model.zip``), then the RL Zoo's
    ``<run>/<env_id>/vecnormalize.pkl`` beside ``<run>/<env_id>.zip`` or
    ``<run>/best_model.zip``: ``<stem>/``, each of ``env_ids`` as a subfolder, and the
    model folder's only subfolder holding one."""
    model = Path(path)
    folder = model.parent
    out = [model.with_name(f"{model.stem}_{VECNORMALIZE}"), folder / VECNORMALIZE,
           folder / model.stem / VECNORMALIZE]  # fmt: skip
    out += [folder / env_id / VECNORMALIZE for env_id in env_ids]
    try:
        found = sorted(p for p in folder.glob(f"*/{VECNORMALIZE}") if p.is_file())
    except OSError:
        found = []
    if len(found) == 1:
        out.append(found[0])
    return list(dict.fromkeys(out))


def find_vecnormalize(path: str | os.PathLike[str], env_ids: Sequence[str] = ()) -> str | None:
    """The first existing file of :func:`vecnormalize_candidates`, or ``None``."""
    for candidate in vecnormalize_candidates(path, env_ids):
        if candidate.is_file():
            return str(candidate)
    return None
