"""A learned policy (a stable-baselines3 model file) behind the :class:`Planner` interface.

``LearnedPolicy("runs/ppo/best_model.zip")`` loads the model on the CPU (its algorithm read
from the file: :func:`detect_algorithm`) and normalises observations with saved
``VecNormalize`` statistics when :func:`find_vecnormalize` finds them where training puts
them (RL Zoo and ``srpb-gym train`` layouts), as during training. stable-baselines3 and
torch come from the ``train`` extra and are imported only when a policy is built.

Failures are one line naming the file: :class:`PolicyFileError` for a model that cannot be
loaded, :class:`VecNormalizeError` for a normalisation file that cannot be used.

A model trained by ``srpb-gym train`` holds the observation settings it was trained with
(:data:`OBSERVATION_RECORD`, saved in its ``model.zip``), and :class:`LearnedPolicy`
observes with them, whatever the environment's: it builds its observation from the
:class:`Knowledge` snapshot (the robot's own pose, scan and tracks) as the environment
builds its own. Settings that keep the space's shape (``lidar_encoding``, the scales) can
then never be mixed up, and models trained with different settings are evaluated side by
side. A model saved without the record acts on the environment's observation.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pickle
import zipfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.observation import ObservationBuilder, ObservationConfig
from srpb_gym.observation import observation_space as observation_space_of
from srpb_gym.planners.base import Knowledge, Planner

INSTALL_HINT = 'pip install "srpb-gym[train]"'
ALGORITHMS: tuple[str, ...] = ("PPO", "A2C", "SAC", "TD3", "DDPG", "DQN")
"""stable-baselines3 algorithms a model file may hold (:func:`detect_algorithm`)."""
VECNORMALIZE = "vecnormalize.pkl"
OBSERVATION_RECORD = "srpb_observation"
"""The model attribute (saved in ``model.zip``) holding the :class:`ObservationConfig` a
model was trained with, as a mapping; a model saved without it acts on the environment's
observation."""

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


def load_model(path: str | os.PathLike[str], algo: str | None = None) -> tuple[Any, str]:
    """Load a model on the CPU; returns it and its algorithm. The global random generators
    are left as they were (:func:`global_rngs_kept`).

    ``algo``: force one of :data:`ALGORITHMS`; ``None`` detects it from the file
    (:func:`detect_algorithm`), else tries each algorithm in turn. Raises
    :class:`PolicyFileError` naming the file, the algorithm(s) tried and why they failed.
    """
    path = os.fspath(path)
    detected = detect_algorithm(path)
    if algo is not None:
        name = algo.upper()
        try:
            with global_rngs_kept():
                return algorithm_class(name).load(path, device="cpu"), name
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
            with global_rngs_kept():
                return algorithm_class(name).load(path, device="cpu"), name
        except ImportError:
            raise
        except Exception as exc:
            failures.append(f"{name}: {_why(exc)}")
    raise PolicyFileError(path, f"not a loadable stable-baselines3 model (tried "
                                f"{'; '.join(failures)})")  # fmt: skip


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


# ---------------------------------------------------------------------------- VecNormalize
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


def load_vecnormalize(path: str | os.PathLike[str]) -> Any:
    """The ``VecNormalize`` object saved at ``path`` (without its environment), set to
    evaluation mode (its statistics frozen).

    Raises :class:`VecNormalizeError` naming the file when it cannot be read, is corrupt or
    holds something else.
    """
    import_sb3()
    from stable_baselines3.common.vec_env import VecNormalize

    where = os.fspath(path)
    try:
        with open(path, "rb") as f:
            obj = pickle.load(f)  # the user's own training artefact
    except OSError as exc:
        raise VecNormalizeError(where, f"cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # truncated, garbled or foreign pickle
        raise VecNormalizeError(where, f"corrupt VecNormalize file ({_why(exc)})") from None
    if not isinstance(obj, VecNormalize):
        raise VecNormalizeError(where, f"not a VecNormalize file (holds {type(obj).__name__})")
    obj.training = False
    obj.norm_reward = False
    return obj


# ---------------------------------------------------------------------------- spaces
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


class LearnedPolicy(Planner):
    """A stable-baselines3 model acting on its observation.

    ``path``: the model ``.zip``; ``algo``: its algorithm (see :data:`ALGORITHMS`), ``None``
    to read it from the file; ``vecnormalize``: a ``VecNormalize`` file, ``"auto"``
    (default) to look where training puts it (:func:`find_vecnormalize`) or ``None`` for
    raw observations; ``deterministic``: take the mode of the action distribution.

    A model that records its observation settings (``observation_config``) observes with
    them: each step it builds its observation from the :class:`Knowledge` snapshot, exactly
    as an environment with those settings would, and ignores the environment's (``act``
    then needs the snapshot). A model without the record acts on the environment's
    observation and may be given ``None``.
    """

    name = "learned"

    def __init__(
        self,
        path: str | os.PathLike[str],
        algo: str | None = None,
        vecnormalize: str | os.PathLike[str] | None = "auto",
        deterministic: bool = True,
    ) -> None:
        self.path = os.fspath(path)
        self.deterministic = deterministic
        self.model, self.algo = load_model(self.path, algo)
        record = getattr(self.model, OBSERVATION_RECORD, None)
        try:
            self.observation_config = None if record is None else recorded_observation(record)
        except ValueError as exc:
            raise PolicyFileError(self.path, str(exc)) from None
        self._builder: ObservationBuilder | None = None
        self._sensors: tuple[Any, ...] = ()
        if vecnormalize == "auto":
            vecnormalize = find_vecnormalize(self.path)
        self.vecnormalize = None if vecnormalize is None else os.fspath(vecnormalize)
        self._normalizer = None
        if self.vecnormalize is not None:
            self._normalizer = load_vecnormalize(self.vecnormalize)
            stats = getattr(self._normalizer, "observation_space", None)
            if stats is not None and spaces_differ(stats, self.model.observation_space):
                raise VecNormalizeError(
                    self.vecnormalize,
                    f"statistics of the observation space "
                    f"{describe_space(stats)}, the model {self.path} takes "
                    f"{describe_space(self.model.observation_space)}",
                )

    @property
    def trained_observation(self) -> dict[str, Any] | None:
        """The observation settings the model records (:data:`OBSERVATION_RECORD`), or
        ``None`` for a model saved without them."""
        return getattr(self.model, OBSERVATION_RECORD, None)

    def check_spaces(self, observation_space: Any, action_space: Any,
                     lidar_beams: int | None = None) -> None:  # fmt: skip
        """Raise ``ValueError`` (one line naming both spaces) unless the model acts in
        ``action_space`` and takes the observations it will get: those of
        ``observation_space`` or, for a model that observes with its recorded settings,
        those of its settings (the same kind, shape and bounds); such a model also needs
        at least as many ``lidar_beams`` (the environment's, when given) as its settings
        have lidar sectors."""
        where = "the environment has"
        own = self.observation_config
        if own is not None:
            observation_space = observation_space_of(own)
            where = "its observation record does not match it:"
            if lidar_beams is not None and own.lidar_bins > lidar_beams:
                raise ValueError(f"{self.path}: it observes {own.lidar_bins} lidar sectors "
                                 f"(its recorded observation settings), the environment's "
                                 f"lidar has {lidar_beams} beams")  # fmt: skip
        pairs = (("observation", self.model.observation_space, observation_space),
                 ("action", self.model.action_space, action_space))  # fmt: skip
        for what, trained, given in pairs:
            if spaces_differ(trained, given):
                same = describe_space(trained) == describe_space(given)
                place = where if what == "observation" else "the environment has"
                raise ValueError(
                    f"{self.path}: trained for the {what} space {describe_space(trained)}, "
                    f"{place} {describe_space(given)}" + (" (the bounds differ)" if same else "")
                )

    def reset(self, knowledge: Knowledge) -> None:
        if self.observation_config is not None:
            self._observer(knowledge)

    def _observer(self, knowledge: Knowledge | None) -> ObservationBuilder:
        """The builder of the model's own observation, for the robot and lidar of
        ``knowledge`` (made again when they change)."""
        if knowledge is None:
            raise TypeError(f"{self.path} observes with its recorded observation settings "
                            "and needs the Knowledge snapshot: act(observation, "
                            "env.unwrapped.knowledge())")  # fmt: skip
        sensors = (knowledge.robot, knowledge.scan.shape[0], knowledge.range_min,
                   knowledge.range_max, knowledge.scan_angles.tobytes())  # fmt: skip
        if self._builder is None or sensors != self._sensors:
            assert self.observation_config is not None
            try:
                self._builder = ObservationBuilder.for_robot(
                    self.observation_config, *sensors[:4], knowledge.scan_angles
                )
            except InputError as exc:
                raise ValueError(f"{self.path}: {exc.message} (its recorded observation "
                                 "settings)") from None  # fmt: skip
            self._sensors = sensors
        return self._builder

    def act(self, observation: Any, knowledge: Knowledge | None) -> NDArray[np.float32]:
        if self.observation_config is not None:
            builder, k = self._observer(knowledge), knowledge
            observation = builder.build(k.pose, k.goal, k.velocity, k.scan, k.tracks)
        if self._normalizer is not None:
            observation = self._normalizer.normalize_obs(observation)
        action, _ = self.model.predict(observation, deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float32)
