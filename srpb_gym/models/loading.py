"""Loading a stable-baselines3 model file, without running the code a file may carry.

:func:`load_model` loads a model on the CPU, its algorithm read from the file
(:func:`detect_algorithm`), leaving the global random generators as they were. A model
file holds pickles (the saved attributes that JSON cannot hold), and a pickle is code:
the model's ``data`` entries are decoded by :mod:`srpb_gym.models.safe_data`, which
builds data only, and its tensors are read with ``torch.load(..., weights_only=True)``
(:func:`tensors_only`), whatever the version of stable-baselines3; only ``trust_pickle``
(``--trust-pickle``) lets stable-baselines3 unpickle what it finds. stable-baselines3 and
torch come from the ``train`` extra and are imported only when a file is loaded, so this
module imports without them; reading a file's saved attributes (:func:`model_data`) needs
neither. The normalisation statistics of a model are :mod:`srpb_gym.models.normalization`'s.

Failures are one line naming the file: :class:`PolicyFileError` for a model that cannot be
loaded, :class:`VecNormalizeError` for a normalisation file that cannot be used.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from srpb_gym.models.safe_data import UnsafeEntryError, safe_objects

INSTALL_HINT = 'pip install "srpb-gym[train]"'
ALGORITHMS: tuple[str, ...] = ("PPO", "A2C", "SAC", "TD3", "DDPG", "DQN")
"""stable-baselines3 algorithms a model file may hold (:func:`detect_algorithm`)."""

_POLICY_MODULES = {
    "stable_baselines3.sac.policies": "SAC",
    "stable_baselines3.td3.policies": "TD3",
    "stable_baselines3.dqn.policies": "DQN",
}


class PolicyFileError(ValueError):
    """A model file that cannot be loaded: ``path`` and ``reason`` (one line); ``str()``
    gives ``path: reason``."""

    def __init__(self, path: str | os.PathLike[str], reason: str) -> None:
        self.path, self.reason = os.fspath(path), reason
        super().__init__(f"{self.path}: {reason}")


class VecNormalizeError(PolicyFileError):
    """A ``VecNormalize`` file that cannot be used (``path``: that file)."""


def import_sb3() -> Any:
    """The ``stable_baselines3`` module; ``ImportError`` naming the ``train`` extra if absent."""
    try:
        import stable_baselines3
    except ImportError as err:
        raise ImportError(
            f"learned policies need stable-baselines3 and torch: {INSTALL_HINT}"
        ) from err
    return stable_baselines3


def algorithm_class(algo: str) -> Any:
    """The stable-baselines3 algorithm class named ``algo`` (case-insensitive)."""
    name = algo.upper()
    if name not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of: {', '.join(ALGORITHMS)}")
    return getattr(import_sb3(), name)


def model_data(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``data`` JSON of a stable-baselines3 model ``.zip`` (the saved attributes).

    Raises :class:`PolicyFileError` when the file is not such a zip archive.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            raw = archive.read("data")
    except KeyError:
        why = "not a stable-baselines3 model (the zip has no 'data' entry)"
        raise PolicyFileError(path, why) from None
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        why = "not a zip archive" if isinstance(exc, zipfile.BadZipFile) else str(exc)
        raise PolicyFileError(path, f"not a stable-baselines3 model ({why})") from None
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        why = "not a stable-baselines3 model (its 'data' entry is not JSON)"
        raise PolicyFileError(path, why) from None
    if not isinstance(data, dict):
        raise PolicyFileError(path, "not a stable-baselines3 model (bad 'data')")
    return data


def detect_algorithm(path: str | os.PathLike[str]) -> str | None:
    """The algorithm of a model file, read from its ``data`` JSON: the policy class's module
    tells SAC, TD3 (DDPG when ``policy_delay`` is 1 and ``target_noise_clip`` 0) and DQN
    apart from the actor-critic policies, of which PPO has a ``clip_range`` and A2C none.

    ``None`` when the file gives no hint; :class:`PolicyFileError` when it is no model or
    names a policy class outside stable-baselines3 (sb3-contrib, a custom class).
    """
    data = model_data(path)
    policy = data.get("policy_class")
    module = policy.get("__module__") if isinstance(policy, dict) else None
    if not isinstance(module, str):
        return None
    if module in _POLICY_MODULES:
        algo = _POLICY_MODULES[module]
        if algo == "TD3" and data.get("policy_delay") == 1 and data.get("target_noise_clip") == 0:
            return "DDPG"
        return algo
    if module == "stable_baselines3.common.policies":
        return "PPO" if "clip_range" in data else "A2C"
    raise PolicyFileError(path, f"its policy class comes from {module}, not from a "
                          f"stable-baselines3 algorithm ({', '.join(ALGORITHMS)})")  # fmt: skip


@contextmanager
def global_rngs_kept() -> Iterator[None]:
    """Restore the global generators of ``random``, numpy and torch (CUDA included) on
    leaving. stable-baselines3's ``load`` seeds them with the seed the model was trained
    with: a training run that loads a model (a teacher of its warm start, or the
    checkpoint of each periodic evaluation, evaluated in the training process) would
    otherwise draw the same numbers whatever its own seed, and again after every
    evaluation."""
    import random

    states = (random.getstate(), np.random.get_state())
    try:
        import torch
    except ImportError:
        torch = None
    torch_state = None if torch is None else torch.get_rng_state()
    cuda = torch is not None and torch.cuda.is_available()
    cuda_states = torch.cuda.get_rng_state_all() if cuda else None
    try:
        yield
    finally:
        random.setstate(states[0])
        np.random.set_state(states[1])
        if torch is not None:
            torch.set_rng_state(torch_state)
        if cuda:
            torch.cuda.set_rng_state_all(cuda_states)


@contextmanager
def tensors_only() -> Iterator[None]:
    """Make every ``torch.load`` inside read tensors only (``weights_only=True``, which
    refuses any other pickled object), whatever its caller asks: stable-baselines3 2.4 to
    2.7 read a model's ``policy.pth`` with ``weights_only=False``."""
    import torch

    original = torch.load

    def load(*args: Any, **kwargs: Any) -> Any:
        kwargs["weights_only"] = True
        return original(*args, **kwargs)

    torch.load = load
    try:
        yield
    finally:
        torch.load = original


def _load_as(name: str, path: str, custom: dict[str, Any] | None) -> tuple[Any, str]:
    """The model in ``path`` loaded as algorithm ``name`` on the CPU, and ``name``, its
    pickled entries replaced by ``custom`` (``None``: unpickled, a trusted file); the
    global random generators as they were."""
    cls = algorithm_class(name)
    with global_rngs_kept():
        if custom is None:
            return cls.load(path, device="cpu"), name
        with tensors_only():
            return cls.load(path, device="cpu", custom_objects=custom), name


def load_model(path: str | os.PathLike[str], algo: str | None = None,
               trust_pickle: bool = False) -> tuple[Any, str]:  # fmt: skip
    """Load a model on the CPU; returns it and its algorithm. The global random generators
    are left as they were (:func:`global_rngs_kept`).

    ``algo``: force one of :data:`ALGORITHMS`; ``None`` detects it from the file
    (:func:`detect_algorithm`), else tries each algorithm in turn. ``trust_pickle``: let
    stable-baselines3 unpickle the file's saved attributes and tensors (it may run code);
    otherwise none is unpickled (module doc). Raises :class:`PolicyFileError` naming the
    file, the algorithm(s) tried and why they failed.
    """
    path = os.fspath(path)
    detected = detect_algorithm(path)
    import_sb3()  # the install hint first: without it nothing decodes
    custom = None
    if not trust_pickle:
        try:
            custom = safe_objects(model_data(path))
        except UnsafeEntryError as exc:
            raise PolicyFileError(path, str(exc)) from None
    if algo is not None:
        name = algo.upper()
        try:
            return _load_as(name, path, custom)
        except ImportError:
            raise
        except Exception as exc:
            hint = f"; the file holds a {detected} model" if detected and detected != name else ""
            raise PolicyFileError(path, f"cannot be loaded as a stable-baselines3 {name} model "
                                  f"({_why(exc)}){hint}") from None  # fmt: skip
    order = [detected] if detected else [a for a in ALGORITHMS if a != "DDPG"]
    failures = []
    for name in order:
        try:
            return _load_as(name, path, custom)
        except ImportError:
            raise
        except Exception as exc:
            failures.append(f"{name}: {_why(exc)}")
    raise PolicyFileError(path, f"not a loadable stable-baselines3 model (tried "
                                f"{'; '.join(failures)})")  # fmt: skip


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def model_steps(path: str | os.PathLike[str]) -> int:
    """The training steps a saved SB3 model had taken (its ``num_timesteps``), read from
    its ``data`` JSON (nothing unpickled); 0 when it records none."""
    steps = model_data(path).get("num_timesteps", 0)
    return int(steps) if isinstance(steps, int) and not isinstance(steps, bool) else 0
