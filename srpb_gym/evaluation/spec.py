"""What an evaluation runs: environment ids, planners, seeds, output folder, checked once.

:func:`resolve_config` turns user choices into an :class:`EvalConfig`, raising
:class:`~srpb_gym.errors.InputError` (key = the command-line option) for anything wrong, so
a run never starts with an argument that would fail halfway. Planners are described by
:class:`PlannerSpec` (plain data), so worker processes can build their own.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.metrics.params import PRESETS, SEMANTICS
from srpb_gym.planners import PLANNERS, Planner, check_settings, make_planner, planner_config
from srpb_gym.registration import SCENARIO_IDS

DEFAULT_ENVS: tuple[str, ...] = ("SRPB-Corridor-v0",)
DEFAULT_EPISODES = 5


@dataclass(frozen=True)
class PlannerSpec:
    """A planner to evaluate: a registered one (``planner`` with the settings ``config``,
    plain data: the fields to change, see :func:`srpb_gym.planners.make_planner`) or a
    learned policy file (``policy``, ``algo``, ``vecnormalize``); ``name`` labels its
    results."""

    name: str
    planner: str | None = None
    config: Mapping[str, Any] = field(default_factory=dict)
    policy: str | None = None
    algo: str = "PPO"
    vecnormalize: str | None = None

    def build(self) -> Planner:
        """A fresh planner instance."""
        if self.policy is None:
            return make_planner(str(self.planner), dict(self.config) or None)
        from srpb_gym.planners.learned import LearnedPolicy

        return LearnedPolicy(self.policy, self.algo, self.vecnormalize)

    def describe(self, planner: Planner | None = None) -> dict[str, Any]:
        """Plain-data description for ``config.json``: the class, the settings given
        (``config``, registered planners) and every resolved parameter (``params``)."""
        planner = planner if planner is not None else self.build()
        cls = type(planner)
        out: dict[str, Any] = {"name": self.name, "class": f"{cls.__module__}.{cls.__qualname__}"}
        if self.policy is not None:
            out |= {"policy": self.policy, "algo": self.algo, "vecnormalize": self.vecnormalize}
        else:
            out |= {"planner": self.planner, "config": jsonable(self.config)}
        out["params"] = planner_params(planner)
        return out


@dataclass(frozen=True)
class EvalConfig:
    """A resolved evaluation: every (env, planner) pair runs ``episodes`` episodes with
    seeds ``seed``, ``seed + 1``, ...; ``video`` episodes of each pair are filmed."""

    envs: tuple[str, ...]
    planners: tuple[PlannerSpec, ...]
    episodes: int = DEFAULT_EPISODES
    seed: int = 0
    out: str = "runs/eval"
    workers: int = 1
    video: int = 0
    semantics: str = "paper"
    preset: str = "paper"
    argv: tuple[str, ...] = ()

    @property
    def seeds(self) -> list[int]:
        """The seed of each episode index."""
        return [self.seed + i for i in range(self.episodes)]

    def record_dir(self, env_id: str, planner: str) -> str:
        """Where the episodes of one (env, planner) pair are written."""
        return os.path.join(self.out, "episodes", env_id, planner)

    def env_kwargs(self, env_id: str, planner: str | None = None) -> dict[str, Any]:
        """Keyword arguments of ``gym.make(env_id, ...)`` (records only with ``planner``)."""
        kwargs: dict[str, Any] = {"metrics": {"semantics": self.semantics, "preset": self.preset}}
        if planner is not None:
            kwargs["record_dir"] = self.record_dir(env_id, planner)
        if self.video > 0:
            kwargs["render_mode"] = "rgb_array"
        return kwargs


def default_out(now: float | None = None) -> str:
    """``runs/eval-<YYYYmmdd-HHMMSS>``."""
    return os.path.join("runs", "eval-" + time.strftime("%Y%m%d-%H%M%S", time.localtime(now)))


def resolve_config(
    envs: Sequence[str] | None = None,
    planners: Sequence[str] | None = None,
    policies: Sequence[str] = (),
    *,
    policy_algo: str = "PPO",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    out: str | None = None,
    workers: int = 1,
    video: int = 0,
    semantics: str = "paper",
    preset: str = "paper",
    planner_settings: Mapping[str, Mapping[str, Any]] | None = None,
    argv: Sequence[str] = (),
) -> EvalConfig:
    """Check every choice and fill in the defaults: :data:`DEFAULT_ENVS`, every registered
    planner when neither ``planners`` nor ``policies`` is given, ``runs/eval-<time>``.

    ``planner_settings``: ``{planner name: settings}`` (plain data, e.g. from
    :func:`srpb_gym.planners.config.planner_settings`); every name must be a registered
    planner, and the settings of the planners evaluated are checked now (errors name
    ``planner.<name>.<field>``); those of planners not evaluated are left out.
    """
    _check_counts(episodes, workers, video)
    if seed < 0:
        raise InputError(f"must be at least 0, got {seed}", key="--seed")
    if semantics not in SEMANTICS:
        raise InputError(f"choose one of: {', '.join(SEMANTICS)}", key="--semantics")
    if preset not in PRESETS:
        raise InputError(f"choose one of: {', '.join(PRESETS)}", key="--preset")
    env_ids = _unique(envs or DEFAULT_ENVS)
    for env_id in env_ids:
        if env_id not in SCENARIO_IDS:
            raise InputError(f"unknown environment id {env_id!r}; choose one of: "
                             f"{', '.join(SCENARIO_IDS)}", key="--env")  # fmt: skip
    if planners is None and not policies:
        planners = list(PLANNERS)
    settings = check_settings(planner_settings or {})
    specs = [_planner_spec(name, settings.get(name)) for name in _unique(planners or ())]
    specs += _policy_specs(policies, policy_algo, env_ids)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(f"two planners are named {dup!r}; rename a policy file", key="--policy")
    out = check_out_dir(out or default_out())
    return EvalConfig(tuple(env_ids), tuple(specs), episodes, seed, out, workers, video,
                      semantics, preset, tuple(argv))  # fmt: skip


def _check_counts(episodes: int, workers: int, video: int) -> None:
    if episodes < 1:
        raise InputError(f"must be at least 1, got {episodes}", key="--episodes")
    if workers < 1:
        raise InputError(f"must be at least 1, got {workers}", key="--workers")
    if video < 0:
        raise InputError(f"must be at least 0, got {video}", key="--video")


def _unique(items: Sequence[str]) -> list[str]:
    return list(dict.fromkeys(items))


def _planner_spec(name: str, settings: Mapping[str, Any] | None = None) -> PlannerSpec:
    if name not in PLANNERS:
        raise InputError(f"unknown planner {name!r}; choose one of: {', '.join(PLANNERS)}",
                         key="--planner")  # fmt: skip
    planner_config(name, settings)  # fail now on a bad setting, not in a worker
    return PlannerSpec(name=name, planner=name, config=dict(settings or {}))


def _policy_specs(paths: Sequence[str], algo: str, env_ids: Sequence[str]) -> list[PlannerSpec]:
    """One spec per policy file, named after the file (``<folder>-<stem>`` when two
    files share a stem); each file is loaded once here and checked against the spaces of
    every environment, to fail early."""
    from srpb_gym.planners.learned import ALGORITHMS, find_vecnormalize

    if paths and algo.upper() not in ALGORITHMS:
        raise InputError(f"choose one of: {', '.join(ALGORITHMS)}", key="--policy-algo")
    stems = [Path(p).stem for p in paths]
    specs = []
    for path, stem in zip(paths, stems):
        name = stem if stems.count(stem) == 1 else f"{Path(path).resolve().parent.name}-{stem}"
        spec = PlannerSpec(name=name, policy=os.fspath(path), algo=algo.upper(),
                           vecnormalize=find_vecnormalize(path))  # fmt: skip
        specs.append(spec)
    if specs:
        _check_policy_spaces(specs, env_ids)
    return specs


def _check_policy_spaces(specs: Sequence[PlannerSpec], env_ids: Sequence[str]) -> None:
    import gymnasium as gym

    policies = [load_policy(spec) for spec in specs]
    for env_id in env_ids:
        env = gym.make(env_id)
        try:
            for policy in policies:
                try:
                    policy.check_spaces(env.observation_space, env.action_space)  # type: ignore[attr-defined]
                except ValueError as exc:
                    raise InputError(f"{exc} ({env_id})", key="--policy") from None
        finally:
            env.close()


def load_policy(spec: PlannerSpec) -> Planner:
    """Build a learned policy, turning every failure into an :class:`InputError`."""
    path = str(spec.policy)
    if not os.path.isfile(path):
        raise InputError("no such file", path, key="--policy")
    if not os.access(path, os.R_OK):
        raise InputError("cannot read the file", path, key="--policy")
    try:
        return spec.build()
    except ImportError as exc:
        raise InputError(str(exc), key="--policy") from None
    except Exception as exc:  # any loader failure means a bad file
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(
            f"not a stable-baselines3 {spec.algo} model ({why})", path, key="--policy"
        ) from None


def check_out_dir(out: str) -> str:
    """Create ``out`` if needed; refuse a file, an unwritable folder or a finished run."""
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError(f"{out} is an existing file, not a folder", key="--out")
    if os.path.exists(os.path.join(out, "episodes.csv")):
        raise InputError(f"{out} already holds a run (episodes.csv); choose another folder",
                         key="--out")  # fmt: skip
    try:
        os.makedirs(out, exist_ok=True)
        probe = os.path.join(out, f".write-test-{os.getpid()}")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError as exc:
        raise InputError(f"cannot write into {out}: {exc.strerror or exc}", key="--out") from None
    return out


def planner_params(planner: Planner) -> dict[str, Any]:
    """Every setting of ``planner`` as plain data: its resolved ``config`` dataclass, or for
    a planner without one (a learned policy) its constructor parameters with the values it
    holds."""
    config = getattr(planner, "config", None)
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        return jsonable(config)
    out: dict[str, Any] = {}
    for name, p in inspect.signature(type(planner).__init__).parameters.items():
        if name == "self" or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        value = getattr(planner, name, getattr(planner, f"_{name}", p.default))
        if value is not inspect.Parameter.empty:
            out[name] = jsonable(value)
    return out


def jsonable(value: Any) -> Any:
    """``value`` as JSON data: dataclasses and mappings as objects, arrays as lists,
    non-finite floats as ``None``, anything else unknown as its ``repr``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return repr(value)
