"""Finding a model's files: the ``model.zip`` that a name, path or run folder names, and the
observation-normalisation statistics trained with it (``vecnormalize.npz``, or the
``vecnormalize.pkl`` pickle of stable-baselines3 and the RL Zoo, which loads only when
trusted: :mod:`srpb_gym.models.normalization`), looked for only where training puts them.

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

VECNORMALIZE = "vecnormalize.npz"
"""The statistics file srpb-gym writes beside a model (numbers only)."""
VECNORMALIZE_PICKLE = "vecnormalize.pkl"
"""The statistics file of stable-baselines3's ``VecNormalize.save`` and the RL Zoo (a
pickle)."""
_NAMES = (VECNORMALIZE, VECNORMALIZE_PICKLE)


def find_model(given: str) -> str | None:
    """The ``model.zip`` that ``given`` names: a model file, a run folder holding
    ``model.zip``, or a shipped model's name; ``None`` if it names none."""
    path = os.path.join(given, MODEL_FILE) if os.path.isdir(given) else given
    if os.path.isfile(path):
        return path
    shipped = model_path(given)
    return None if shipped is None else str(shipped)


def resolve_model(given: str, key: str) -> tuple[str, str | None]:
    """The ``model.zip`` (:func:`find_model`) and statistics file (or ``None``:
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
    """Where observation-normalisation statistics of the model ``path`` may lie, in order,
    each place as ``vecnormalize.npz`` then ``vecnormalize.pkl``: ``<stem>_vecnormalize.*``
    and ``vecnormalize.*`` beside it (``srpb-gym train``: ``<run>/vecnormalize.npz``
    beside ``<run>/model.zip``), then the RL Zoo's ``<run>/<env_id>/vecnormalize.pkl``
    beside ``<run>/<env_id>.zip`` or ``<run>/best_model.zip``: ``<stem>/`` and each of
    ``env_ids`` as a subfolder. Nowhere else: statistics in another subfolder may be
    another model's (:func:`stray_vecnormalize`)."""
    model = Path(path)
    folder = model.parent
    places = [(folder, f"{model.stem}_"), (folder, ""), (folder / model.stem, "")]
    places += [(folder / env_id, "") for env_id in env_ids]
    out = [where / f"{prefix}{name}" for where, prefix in places for name in _NAMES]
    return list(dict.fromkeys(out))


def find_vecnormalize(path: str | os.PathLike[str], env_ids: Sequence[str] = ()) -> str | None:
    """The first existing file of :func:`vecnormalize_candidates`, or ``None``."""
    for candidate in vecnormalize_candidates(path, env_ids):
        if candidate.is_file():
            return str(candidate)
    return None


def stray_vecnormalize(path: str | os.PathLike[str], env_ids: Sequence[str] = ()) -> list[Path]:
    """Statistics files in the subfolders of the model ``path``'s folder that are none of
    its :func:`vecnormalize_candidates`: they may belong to another model, so they are
    never taken for this one (an evaluation asks for ``--vecnormalize FILE`` instead)."""
    folder = Path(path).parent
    known = set(vecnormalize_candidates(path, env_ids))
    try:
        found = [p for name in _NAMES for p in folder.glob(f"*/{name}") if p.is_file()]
    except OSError:
        return []
    return sorted(p for p in found if p not in known)
