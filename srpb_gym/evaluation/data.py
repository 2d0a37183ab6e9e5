"""The plain data of an evaluation: what it runs and what each episode gave.

:class:`EvalConfig` (a resolved run: environments, planners, seeds, output folder; made by
:func:`~srpb_gym.evaluation.spec.resolve_config`), :class:`PlannerSpec` (a planner as plain
data, so that worker processes can build their own), :class:`Task` (one episode to run),
:class:`EpisodeResult` (one finished episode) and :func:`jsonable` (any of them as JSON
data). This module imports no other module of the evaluation.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from srpb_gym.planners import Planner, make_planner
from srpb_gym.planners.learned import LearnedPolicy
from srpb_gym.registration import CUSTOM_ID, MIX_ID, SCENARIO_IDS
from srpb_gym.sim.contact import Collision

DEFAULT_EPISODES = 5
DEFAULT_WARMUP = 100
"""Untimed control steps each planner takes before its first timed episode, per process:
10 s at the 0.1 s control step, long enough to meet the people of the packaged scenarios,
whose first sight compiles more of a planner than an empty scene does."""


@dataclass(frozen=True)
class PlannerSpec:
    """A planner to evaluate: a registered one (``planner`` with the settings ``config``,
    plain data: the fields to change, see :func:`srpb_gym.planners.make_planner`) or a
    learned policy file (``policy``, its ``algo``, the ``vecnormalize`` statistics or
    ``None`` for raw observations, and the places searched for them; ``trust_pickle``:
    the user trusts the file's pickles, see :class:`LearnedPolicy`); ``name`` labels its
    results."""

    name: str
    planner: str | None = None
    config: Mapping[str, Any] = field(default_factory=dict)
    policy: str | None = None
    algo: str | None = None
    vecnormalize: str | None = None
    vecnormalize_searched: tuple[str, ...] = ()
    trust_pickle: bool = False

    def build(self) -> Planner:
        """A fresh planner instance."""
        if self.policy is None:
            return make_planner(str(self.planner), dict(self.config) or None)
        return LearnedPolicy(self.policy, self.algo, self.vecnormalize,
                             trust_pickle=self.trust_pickle)  # fmt: skip

    def describe(self, planner: Planner | None = None) -> dict[str, Any]:
        """Plain-data description for ``config.json``: the class, the settings given
        (``config``, registered planners) and every resolved parameter (``params``)."""
        planner = planner if planner is not None else self.build()
        cls = type(planner)
        out: dict[str, Any] = {"name": self.name, "class": f"{cls.__module__}.{cls.__qualname__}"}
        if self.policy is not None:
            out |= {"policy": self.policy, "algo": self.algo, "vecnormalize": self.vecnormalize}
            if self.vecnormalize is None and self.vecnormalize_searched:
                out["vecnormalize_searched"] = list(self.vecnormalize_searched)
        else:
            out |= {"planner": self.planner, "config": jsonable(self.config)}
        out["params"] = planner_params(planner)
        return out


@dataclass(frozen=True)
class EvalConfig:
    """A resolved evaluation: every (env, planner) pair runs ``episodes`` episodes with
    seeds ``seed``, ``seed + 1``, ...; ``video`` episodes of each pair are filmed, every
    ``video_stride``-th control step of each (:class:`~.figures.VideoWriter`).

    ``envs`` are labels: registered ids, or scenario names for the scenario files of
    ``scenario_files`` ((label, file path) pairs). ``warmup``: untimed control steps of
    each planner before its first timed episode in each process (0: none). ``resume``:
    continue the run in ``out``. ``notes``: warnings and notes of the resolution
    (one line each, e.g. ``"warning: ..."``). ``robots``: robots per episode; more than
    one runs the PettingZoo environment (:meth:`make_parallel`), one the Gymnasium one.
    ``make_kwargs``: keyword arguments given to every environment (``--env-kwargs``), under
    the evaluation's own (:meth:`env_kwargs`). ``backend``: where the episodes run,
    ``"process"`` (this process, or ``workers`` worker processes) or ``"ray"`` (Ray tasks,
    :mod:`~srpb_gym.evaluation.ray_pool`: a local Ray, or the cluster at ``address``;
    ``workers`` then caps the episodes running at once, 0: every CPU of the cluster)."""

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
    scenario_files: tuple[tuple[str, str], ...] = ()
    warmup: int = DEFAULT_WARMUP
    resume: bool = False
    notes: tuple[str, ...] = ()
    robots: int = 1
    make_kwargs: Mapping[str, Any] = field(default_factory=dict, hash=False)
    video_stride: int = 1
    backend: str = "process"
    address: str | None = None

    @property
    def seeds(self) -> list[int]:
        """The seed of each episode index."""
        return [self.seed + i for i in range(self.episodes)]

    @property
    def warmup_seed(self) -> int:
        """The seed of the warm-up episode: the first after the evaluated ones."""
        return self.seed + self.episodes

    def record_dir(self, env_id: str, planner: str) -> str:
        """Where the episodes of one (env, planner) pair are written."""
        return os.path.join(self.out, "episodes", env_id, planner)

    def scenario_file(self, env: str) -> str | None:
        """The scenario file of the environment labelled ``env``, or ``None`` (an id)."""
        return dict(self.scenario_files).get(env)

    def gym_id(self, env: str) -> str:
        """The Gymnasium id to make the environment labelled ``env`` with."""
        return env if self.scenario_file(env) is None else CUSTOM_ID

    def scenario_name(self, env: str) -> str:
        """The scenario's name, which the episode files are named after (``SRPB-Mix-v0``:
        none, each episode is named after the scenario it draws)."""
        if env == MIX_ID:
            raise ValueError(f"{MIX_ID} names each episode after the scenario it draws")
        return SCENARIO_IDS[env] if self.scenario_file(env) is None else env

    def record_path(
        self, env: str, planner: str, seed: int, robot: int | None = None,
        scenario: str | None = None,
    ) -> str:  # fmt: skip
        """The ``.npz`` record of one episode (of robot ``robot`` in a multi-robot run) of
        the scenario ``scenario`` (default: the environment's; needed for ``SRPB-Mix-v0``)."""
        stem = f"{scenario or self.scenario_name(env)}_seed{seed}"
        stem += "" if robot is None else f"_robot{robot}"
        return os.path.join(self.record_dir(env, planner), f"{stem}.npz")

    def env_kwargs(
        self, env_id: str, planner: str | None = None, *, render: bool = True
    ) -> dict[str, Any]:
        """Keyword arguments of ``gym.make(self.gym_id(env_id), ...)``: :attr:`make_kwargs`,
        then the metric settings, the scenario file, the records (only with ``planner``) and
        rendering (with ``render`` when videos are filmed)."""
        kwargs: dict[str, Any] = dict(self.make_kwargs)
        kwargs["metrics"] = {"semantics": self.semantics, "preset": self.preset}
        if self.scenario_file(env_id) is not None:
            kwargs["scenario"] = self.scenario_file(env_id)
        if planner is not None:
            kwargs["record_dir"] = self.record_dir(env_id, planner)
        if self.video > 0 and render:
            kwargs["render_mode"] = "rgb_array"
        return kwargs

    def make_env(self, env_id: str, planner: str | None = None, *, render: bool = True) -> Any:
        """A new environment for the label ``env_id`` (see :meth:`env_kwargs`)."""
        import gymnasium as gym

        return gym.make(self.gym_id(env_id), **self.env_kwargs(env_id, planner, render=render))

    def make_parallel(self, env_id: str, planner: str | None = None, *, render: bool = True) -> Any:
        """A new PettingZoo environment with :attr:`robots` robots for the label ``env_id``,
        made with the same arguments as :meth:`make_env`."""
        # deferred: pettingzoo_env loads pettingzoo and pymunk; keeps the CLI's start light
        from srpb_gym.pettingzoo_env import parallel_env

        kwargs = {"scenario": self.scenario_name(env_id)}
        kwargs |= self.env_kwargs(env_id, planner, render=render)
        return parallel_env(n_robots=self.robots, **kwargs)


@dataclass(frozen=True)
class Task:
    """Episode ``index`` (seed ``seed``) of environment ``env`` with planner number
    ``planner`` of the configuration."""

    env: str
    planner: int
    index: int
    seed: int


@dataclass
class EpisodeResult:
    """One finished episode: its outcome and every SRPB metric, ``metrics`` from the people
    the robot tracked (``info["srpb/<m>"]`` of the last step) and ``ground_truth`` from the
    people as they were (``info["srpb_gt/<m>"]``; a metric absent, e.g. read from an
    ``episodes.csv`` written before it was kept, is not computed: :meth:`truth` gives NaN).
    ``record``: the ``.npz`` record, relative to the output folder. ``robot``: the robot's
    index in a multi-robot episode, ``None`` in a single-robot run. ``scenario``: the
    episode's scenario (for ``SRPB-Mix-v0`` the one drawn). ``first_collision``: the
    episode's first collision, attributed (``info["first_collision_<field>"]``;
    :mod:`srpb_gym.sim.contact`), ``None`` without a collision or when not known (an
    ``episodes.csv`` written before it was kept). ``pushed_back``: the most any walker of
    the episode moved against the way it walks [m] (``info["people_pushed_back"]``: pushed
    back by a robot; NaN when not known)."""

    env: str
    planner: str
    seed: int
    is_success: bool
    collision: bool
    timeout: bool
    metrics: dict[str, float]
    steps: int = 0
    record: str = ""
    video: str = ""
    robot: int | None = None
    scenario: str = ""
    ground_truth: dict[str, float] = field(default_factory=dict)
    first_collision: Collision | None = None
    pushed_back: float = math.nan

    def truth(self, metric: str) -> float:
        """The ground-truth value of ``metric`` (NaN when not computed)."""
        return float(self.ground_truth.get(metric, math.nan))

    def value(self, metric: str, gt: bool = False) -> float:
        """The tracked (or with ``gt`` the ground-truth) value of ``metric``."""
        return self.truth(metric) if gt else float(self.metrics[metric])


def tasks_of(config: EvalConfig) -> list[Task]:
    """Every episode of the run in the canonical order: env, planner, seed."""
    return [Task(env, p, i, seed) for env in config.envs for p in range(len(config.planners))
            for i, seed in enumerate(config.seeds)]  # fmt: skip


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
    if value is None or isinstance(value, (str, Path)):
        return None if value is None else str(value)
    return repr(value)
