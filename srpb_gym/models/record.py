"""The observation record of a trained model: the observation settings it observed with.

A model trained by ``srpb-gym train`` holds the :class:`ObservationConfig` it was trained
with as the attribute :data:`OBSERVATION_RECORD` (a mapping, saved in its ``model.zip``):
:func:`record_observation` gives a model its record before it is saved,
:func:`stamp_observation` gives one to a model file saved without it, :func:`read_record`
reads a file's record without loading the model and :func:`recorded_observation` turns a
record back into settings. A model saved without the record acts on the environment's
observation. :func:`observation_mismatch` and :func:`settings_text` say how two settings
differ; :func:`spaces_differ` and :func:`describe_space` compare the spaces a model was
trained on with an environment's.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np

from srpb_gym.models.loading import PolicyFileError, load_model, model_data
from srpb_gym.observation import ObservationConfig

OBSERVATION_RECORD = "srpb_observation"
"""The model attribute (saved in ``model.zip``) holding the :class:`ObservationConfig` a
model was trained with, as a mapping; a model saved without it acts on the environment's
observation."""


def read_record(path: str | os.PathLike[str]) -> Any:
    """The observation record saved in the model file ``path`` (a mapping), or ``None`` for
    a model saved without one; read from the file's saved attributes, without loading the
    model. :class:`PolicyFileError` when the file is no stable-baselines3 model."""
    return model_data(path).get(OBSERVATION_RECORD)


def record_observation(model: Any, config: ObservationConfig) -> None:
    """Make ``model`` carry ``config`` into every file it is saved to."""
    setattr(model, OBSERVATION_RECORD, dataclasses.asdict(config))


def stamp_observation(path: str | os.PathLike[str], config: ObservationConfig) -> bool:
    """Give the model file ``path`` the record of ``config`` if it has none (a model saved
    before records were kept); returns whether the file was rewritten. A record that
    disagrees with ``config`` is a :class:`PolicyFileError`."""
    model, _ = load_model(path)
    trained = getattr(model, OBSERVATION_RECORD, None)
    if trained is not None:
        why = observation_mismatch(trained, config)
        if why is not None:
            raise PolicyFileError(path, why)
        return False
    record_observation(model, config)
    model.save(os.fspath(path))
    return True


def recorded_observation(trained: Any) -> ObservationConfig:
    """The :class:`ObservationConfig` of a model's record (a mapping). Settings missing
    from it take their defaults (every setting added later defaults to what models observed
    before it); a record that is not a valid one is a ``ValueError`` saying why."""
    if not isinstance(trained, dict):
        raise ValueError(f"its observation record is not a mapping ({type(trained).__name__})")
    known = {f.name for f in dataclasses.fields(ObservationConfig)}
    unknown = sorted(set(trained) - known)
    if unknown:
        raise ValueError("it was trained with observation settings this version does not "
                         "know: " + ", ".join(unknown))  # fmt: skip
    try:
        return ObservationConfig(**trained)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"its observation record is invalid ({exc})") from None


def observation_mismatch(trained: Any, given: ObservationConfig,
                         other: str = "this run observes with") -> str | None:  # fmt: skip
    """``None`` when a model trained with the recorded settings ``trained`` (a mapping, or
    ``None``: no record) observes as ``given`` does; otherwise a sentence naming the
    settings that differ, ``other`` introducing ``given``'s (or what is wrong with the
    record)."""
    if trained is None:
        return None
    try:
        model_config = recorded_observation(trained)
    except ValueError as exc:
        return str(exc)
    return settings_mismatch(model_config, given, other)


def settings_mismatch(trained: ObservationConfig, given: ObservationConfig,
                      other: str = "this run observes with") -> str | None:  # fmt: skip
    """:func:`observation_mismatch` of a record already read into ``trained``."""
    if trained == given:
        return None
    return (f"it was trained with observation={settings_text(trained, given)}, "
            f"{other} observation={settings_text(given, trained)}")  # fmt: skip


def settings_text(config: ObservationConfig, other: ObservationConfig) -> str:
    """The settings of ``config`` that differ from ``other``'s, in YAML flow style."""
    names = [f.name for f in dataclasses.fields(ObservationConfig)
             if getattr(config, f.name) != getattr(other, f.name)]  # fmt: skip
    return "{" + ", ".join(f"{n}: {getattr(config, n)}" for n in names) + "}"


def lidar_beams_of(env: Any) -> int | None:
    """The number of lidar beams of an srpb-gym environment's robots; ``None`` for another
    environment."""
    sim = getattr(getattr(env, "unwrapped", env), "sim", None)
    lidar = getattr(sim, "lidar_config", None)
    return None if lidar is None else int(lidar.n_beams)


def observation_config_of(env: Any) -> ObservationConfig | None:
    """The observation settings of an srpb-gym environment (Gymnasium or PettingZoo,
    wrapped or not); ``None`` for another environment."""
    config = getattr(getattr(env, "unwrapped", env), "observation_config", None)
    return config if isinstance(config, ObservationConfig) else None


def describe_space(space: Any) -> str:
    """A one-line description of a gymnasium space: kind, shape, dtype and bounds."""
    spaces = getattr(space, "spaces", None)
    if isinstance(spaces, dict):
        return "Dict(" + ", ".join(f"{k}: {describe_space(v)}" for k, v in spaces.items()) + ")"
    low, high = getattr(space, "low", None), getattr(space, "high", None)
    if low is not None and high is not None:
        low, high = np.asarray(low), np.asarray(high)
        bounds = f"[{low.min():g}, {high.max():g}]" if low.size else "[]"
        return f"{type(space).__name__}{tuple(space.shape)} {space.dtype} in {bounds}"
    return " ".join(str(space).split())


def spaces_differ(trained: Any, given: Any) -> bool:
    """Whether a model trained on space ``trained`` cannot act in ``given``: another kind,
    shape, size or bounds."""
    if type(trained) is not type(given):
        return True
    a, b = getattr(trained, "spaces", None), getattr(given, "spaces", None)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() != b.keys() or any(spaces_differ(a[k], b[k]) for k in a)
    if getattr(trained, "shape", None) != getattr(given, "shape", None):
        return True
    if getattr(trained, "n", None) != getattr(given, "n", None):
        return True
    for bound in ("low", "high"):
        x, y = getattr(trained, bound, None), getattr(given, bound, None)
        if (x is None) != (y is None) or (x is not None and not np.array_equal(x, y)):
            return True
    return False
