"""Observation-normalisation statistics kept as numbers: ``vecnormalize.npz``.

stable-baselines3 saves the statistics of its ``VecNormalize`` wrapper as a pickle
(``vecnormalize.pkl``), and loading a pickle runs whatever code it names: a pickle is
code. srpb-gym writes and ships the same statistics as a numpy ``.npz`` archive of
numbers (:func:`save_vecnormalize`, read with ``numpy.load(path, allow_pickle=False)``),
and :func:`load_vecnormalize` reads a pickle only when the caller trusts it
(``trust_pickle``: the ``--trust-pickle`` option of ``srpb-gym eval`` and ``srpb-gym
train``); otherwise it refuses it with a :class:`~srpb_gym.models.loading.VecNormalizeError`
saying why. :func:`convert_vecnormalize` turns a trusted pickle into the archive once.

The archive (:data:`FORMAT`) holds float64 arrays: ``obs_mean``, ``obs_var`` and
``obs_count`` (the running statistics of the observations), ``obs_low`` and ``obs_high``
(the bounds of the observation space, in its dtype), ``ret_mean``, ``ret_var`` and
``ret_count`` (those of the discounted return), the scalars ``clip_obs`` and
``clip_reward`` (infinite: no clip), ``gamma`` and ``epsilon``, the flags ``norm_obs``
and ``norm_reward``, and ``format``. A ``Dict`` observation space keeps one set of
``obs_*`` entries per key, ``obs_mean:<key>`` and so on, its keys in ``obs_keys`` (those
normalised) and ``space_keys`` (every key, each a ``Box``).

:class:`Normalization` normalises an observation as ``VecNormalize.normalize_obs`` does,
``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)`` in float32, with the
same numpy operations: the same bits. Nothing here needs stable-baselines3 or torch,
but for reading a trusted pickle and saving a live ``VecNormalize``.
"""

from __future__ import annotations

import os
import pickle
import zipfile
from collections.abc import Mapping
from copy import deepcopy
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.models.loading import VecNormalizeError, import_sb3

__all__ = ["FORMAT", "PICKLE_REFUSED", "Normalization", "RunningStats", "convert_vecnormalize",
           "is_pickle", "load_vecnormalize", "save_vecnormalize"]  # fmt: skip

FORMAT = "srpb-gym vecnormalize 1"
"""The ``format`` entry of a ``vecnormalize.npz``."""
PICKLE_REFUSED = (
    "a pickle, and loading a pickle runs the code it names; srpb-gym reads normalisation "
    "statistics from vecnormalize.npz (numbers only): pass --trust-pickle if you trust "
    "where this file came from"
)
"""Why a pickled statistics file is refused without ``trust_pickle``."""
_SCALARS = ("clip_obs", "clip_reward", "gamma", "epsilon")


@dataclass(frozen=True)
class RunningStats:
    """Running mean, variance and count of a stream (``RunningMeanStd``'s numbers)."""

    mean: NDArray[np.float64]
    var: NDArray[np.float64]
    count: float

    def rms(self) -> Any:
        """These numbers as a stable-baselines3 ``RunningMeanStd``."""
        import_sb3()
        from stable_baselines3.common.running_mean_std import RunningMeanStd

        out = RunningMeanStd(shape=self.mean.shape)
        out.mean, out.var, out.count = self.mean.copy(), self.var.copy(), float(self.count)
        return out


@dataclass(frozen=True)
class Normalization:
    """The statistics of a ``VecNormalize``, frozen: ``obs`` (one :class:`RunningStats`,
    or one per key of a ``Dict`` observation, the normalised keys only), ``ret`` (the
    discounted return's), the bounds of the observation space (``bounds``: ``(low,
    high)``, or a mapping of them per key of a ``Dict`` space) and the settings of the
    wrapper. ``path``: the file read, for messages."""

    obs: RunningStats | Mapping[str, RunningStats]
    ret: RunningStats
    bounds: tuple[NDArray[Any], NDArray[Any]] | Mapping[str, tuple[NDArray[Any], NDArray[Any]]]
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    gamma: float = 0.99
    epsilon: float = 1e-8
    norm_obs: bool = True
    norm_reward: bool = True
    path: str = ""

    @property
    def observation_space(self) -> Any:
        """The observation space the statistics were gathered on (a ``Box`` or a ``Dict``
        of them)."""
        from gymnasium import spaces

        if isinstance(self.bounds, Mapping):
            return spaces.Dict({k: spaces.Box(lo, hi, dtype=lo.dtype)
                                for k, (lo, hi) in self.bounds.items()})  # fmt: skip
        low, high = self.bounds
        return spaces.Box(low, high, dtype=low.dtype)

    @property
    def obs_rms(self) -> Any:
        """The observation statistics as ``VecNormalize.obs_rms`` holds them."""
        if isinstance(self.obs, Mapping):
            return {k: s.rms() for k, s in self.obs.items()}
        return self.obs.rms()

    def normalize_obs(self, obs: Any) -> Any:
        """``obs`` normalised as ``VecNormalize.normalize_obs`` does (float32)."""
        out = deepcopy(obs)
        if not self.norm_obs:
            return out
        if isinstance(self.obs, Mapping):
            for key, stats in self.obs.items():
                out[key] = self._normalize(obs[key], stats)
            return out
        return self._normalize(obs, self.obs)

    def _normalize(self, obs: Any, stats: RunningStats) -> NDArray[np.float32]:
        scaled = (obs - stats.mean) / np.sqrt(stats.var + self.epsilon)
        return np.clip(scaled, -self.clip_obs, self.clip_obs).astype(np.float32)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the statistics to ``path`` (a ``vecnormalize.npz``)."""
        arrays: dict[str, Any] = {"format": np.array(FORMAT)}
        arrays |= {name: np.array(float(getattr(self, name))) for name in _SCALARS}
        arrays |= {"norm_obs": np.array(self.norm_obs), "norm_reward": np.array(self.norm_reward)}
        arrays |= _stats_arrays("ret", self.ret)
        if isinstance(self.obs, Mapping):
            assert isinstance(self.bounds, Mapping)
            arrays["obs_keys"] = np.array(list(self.obs), dtype=np.str_)
            arrays["space_keys"] = np.array(list(self.bounds), dtype=np.str_)
            for key, stats in self.obs.items():
                arrays |= _stats_arrays("obs", stats, f":{key}")
            for key, (low, high) in self.bounds.items():
                arrays |= {f"obs_low:{key}": low, f"obs_high:{key}": high}
        else:
            assert not isinstance(self.bounds, Mapping)
            arrays |= _stats_arrays("obs", self.obs)
            arrays |= {"obs_low": self.bounds[0], "obs_high": self.bounds[1]}
        with open(path, "wb") as f:
            np.savez(f, **arrays)


def _stats_arrays(prefix: str, stats: RunningStats, suffix: str = "") -> dict[str, Any]:
    return {f"{prefix}_mean{suffix}": np.asarray(stats.mean, dtype=np.float64),
            f"{prefix}_var{suffix}": np.asarray(stats.var, dtype=np.float64),
            f"{prefix}_count{suffix}": np.array(float(stats.count))}  # fmt: skip


def is_pickle(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is not a numpy archive (a zip file), whatever its name: a pickle, or
    something else that only the pickle reader could tell."""
    return not zipfile.is_zipfile(path)


def load_vecnormalize(path: str | os.PathLike[str], trust_pickle: bool = False) -> Normalization:
    """The statistics saved at ``path``: a ``vecnormalize.npz`` (a numpy archive, whatever
    the file's name) or, with ``trust_pickle``, a pickled ``VecNormalize``
    (``vecnormalize.pkl``, which needs stable-baselines3; any file that is no archive and
    not named ``.npz`` is taken for one). Raises :class:`VecNormalizeError` naming the
    file when it cannot be read, is corrupt, holds something else or is a pickle not
    trusted (:data:`PICKLE_REFUSED`)."""
    where = os.fspath(path)
    try:
        pickled = is_pickle(path)
    except OSError as exc:
        raise VecNormalizeError(where, f"cannot read: {exc.strerror or exc}") from None
    if not pickled:
        return _read_archive(where)
    if where.endswith(".npz"):
        raise VecNormalizeError(where, "corrupt statistics file (not a numpy archive)")
    if not trust_pickle:
        raise VecNormalizeError(where, PICKLE_REFUSED)
    return _read_pickle(where)


def _read_archive(where: str) -> Normalization:
    try:
        with np.load(where, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except OSError as exc:
        raise VecNormalizeError(where, f"cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # a damaged archive, or one holding pickled objects
        why = "it holds pickled objects" if "pickle" in str(exc) else _first_line(exc)
        raise VecNormalizeError(where, f"corrupt statistics file ({why})") from None
    try:
        return _from_arrays(arrays, where)
    except (KeyError, TypeError, ValueError) as exc:
        why = f"no {exc.args[0]!r} entry" if isinstance(exc, KeyError) else _first_line(exc)
        raise VecNormalizeError(where, f"not a statistics file of srpb-gym ({why})") from None


def _from_arrays(arrays: Mapping[str, Any], where: str) -> Normalization:
    form = str(arrays["format"])
    if form != FORMAT:
        raise ValueError(f"format {form!r}, this version reads {FORMAT!r}")
    scalars = {name: _scalar(arrays, name) for name in _SCALARS}
    flags = {name: bool(np.asarray(arrays[name]).item()) for name in ("norm_obs", "norm_reward")}
    ret = _stats(arrays, "ret", "")
    if "obs_keys" in arrays:
        keys = [str(k) for k in np.asarray(arrays["obs_keys"]).ravel()]
        space_keys = [str(k) for k in np.asarray(arrays["space_keys"]).ravel()]
        if not set(keys) <= set(space_keys):
            raise ValueError("obs_keys names keys that space_keys has not")
        obs: Any = {k: _stats(arrays, "obs", f":{k}") for k in keys}
        bounds: Any = {k: _bounds(arrays, f":{k}") for k in space_keys}
        for k in keys:
            _same_shape(obs[k], bounds[k], k)
    else:
        obs, bounds = _stats(arrays, "obs", ""), _bounds(arrays, "")
        _same_shape(obs, bounds, "")
    if scalars["epsilon"] < 0 or scalars["clip_obs"] <= 0 or scalars["clip_reward"] <= 0:
        raise ValueError("epsilon below 0, or a clip not above 0")
    return Normalization(obs, ret, bounds, **scalars, **flags, path=where)


def _scalar(arrays: Mapping[str, Any], name: str) -> float:
    """A number of the archive: finite, but a clip, which may be infinite (no clip)."""
    value = np.asarray(arrays[name])
    if value.shape != () or value.dtype.kind not in "fiu" or np.isnan(value):
        raise ValueError(f"{name} is not a number")
    if not name.startswith("clip_") and not np.isfinite(value):
        raise ValueError(f"{name} is not a finite number")
    return float(value)


def _stats(arrays: Mapping[str, Any], prefix: str, suffix: str) -> RunningStats:
    mean = np.asarray(arrays[f"{prefix}_mean{suffix}"])
    var = np.asarray(arrays[f"{prefix}_var{suffix}"])
    count = _scalar(arrays, f"{prefix}_count{suffix}")
    name = f"{prefix}_*{suffix}"
    if mean.dtype != np.float64 or var.dtype != np.float64 or mean.shape != var.shape:
        raise ValueError(f"{name}: mean and var are not float64 arrays of one shape")
    if not (np.isfinite(mean).all() and np.isfinite(var).all() and (var >= 0).all()):
        raise ValueError(f"{name}: a mean or variance that is not finite, or a negative variance")
    if not count > 0:
        raise ValueError(f"{name}: count {count:g} is not above 0")
    return RunningStats(mean, var, count)


def _bounds(arrays: Mapping[str, Any], suffix: str) -> tuple[NDArray[Any], NDArray[Any]]:
    low, high = np.asarray(arrays[f"obs_low{suffix}"]), np.asarray(arrays[f"obs_high{suffix}"])
    if low.shape != high.shape or low.dtype != high.dtype or low.dtype.kind not in "fiu":
        raise ValueError(f"obs_low{suffix} and obs_high{suffix} differ in shape or dtype")
    return low, high


def _same_shape(stats: RunningStats, bounds: tuple[NDArray[Any], NDArray[Any]], key: str) -> None:
    if stats.mean.shape != bounds[0].shape:
        where = f" of {key!r}" if key else ""
        raise ValueError(f"statistics{where} of shape {stats.mean.shape}, observations of "
                         f"shape {bounds[0].shape}")  # fmt: skip


def _read_pickle(where: str) -> Normalization:
    """A trusted ``vecnormalize.pkl``: unpickled (it may run code), then its numbers."""
    import_sb3()
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(where, "rb") as f:
            obj = pickle.load(f)  # trusted by the caller: trust_pickle
    except OSError as exc:
        raise VecNormalizeError(where, f"cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # truncated, garbled or foreign pickle
        raise VecNormalizeError(where, f"corrupt VecNormalize file ({_why(exc)})") from None
    if not isinstance(obj, VecNormalize):
        raise VecNormalizeError(where, f"not a VecNormalize file (holds {type(obj).__name__})")
    try:
        return from_vecnormalize(obj, where)
    except (AttributeError, TypeError, ValueError) as exc:
        raise VecNormalizeError(where, f"corrupt VecNormalize file ({_why(exc)})") from None


def from_vecnormalize(venv: Any, where: str = "") -> Normalization:
    """The numbers of a stable-baselines3 ``VecNormalize`` (live or unpickled)."""
    from gymnasium import spaces

    space = venv.observation_space

    def box(s: Any) -> tuple[NDArray[Any], NDArray[Any]]:
        if not isinstance(s, spaces.Box):
            raise ValueError(f"an observation space of {type(s).__name__}, not of Box")
        return np.asarray(s.low).copy(), np.asarray(s.high).copy()

    def stats(rms: Any) -> RunningStats:
        return RunningStats(np.array(rms.mean, dtype=np.float64),
                            np.array(rms.var, dtype=np.float64), float(rms.count))  # fmt: skip

    rms = getattr(venv, "obs_rms", None)  # absent when observations are not normalised
    if isinstance(space, spaces.Dict):
        if not isinstance(rms, dict | None):
            raise ValueError("one set of statistics for a Dict observation space")
        obs: Any = {k: stats(v) for k, v in (rms or {}).items()}
        bounds: Any = {k: box(s) for k, s in space.spaces.items()}
    else:
        if isinstance(rms, dict):
            raise ValueError("statistics per key of an observation space that is no Dict")
        bounds = box(space)
        shape = bounds[0].shape
        obs = stats(rms) if rms is not None else RunningStats(np.zeros(shape), np.ones(shape), 1e-4)
    return Normalization(obs, stats(venv.ret_rms), bounds, float(venv.clip_obs),
                         float(venv.clip_reward), float(venv.gamma), float(venv.epsilon),
                         bool(venv.norm_obs), bool(venv.norm_reward), where)  # fmt: skip


def save_vecnormalize(venv: Any, path: str | os.PathLike[str]) -> None:
    """Write the statistics of a stable-baselines3 ``VecNormalize`` to ``path`` (a
    ``vecnormalize.npz``), where srpb-gym writes them instead of ``venv.save``'s pickle."""
    from_vecnormalize(venv, os.fspath(path)).save(path)


def convert_vecnormalize(src: str | os.PathLike[str], dst: str | os.PathLike[str] | None = None
                         ) -> str:  # fmt: skip
    """Convert the pickled ``VecNormalize`` ``src``, which the caller trusts (it is
    unpickled), to a ``vecnormalize.npz`` at ``dst`` (default: ``vecnormalize.npz`` beside
    ``src``); returns ``dst``."""
    target = os.fspath(dst) if dst is not None else os.path.join(
        os.path.dirname(os.fspath(src)), "vecnormalize.npz")  # fmt: skip
    load_vecnormalize(src, trust_pickle=True).save(target)
    return target


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def _why(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {_first_line(exc)}"
