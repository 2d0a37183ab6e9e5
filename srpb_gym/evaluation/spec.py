"""What an evaluation runs: environments, planners, seeds, output folder, checked once.

:func:`resolve_config` turns user choices into an :class:`EvalConfig`, raising
:class:`~srpb_gym.errors.InputError` (key = the command-line option) for anything wrong, so
a run never starts with an argument that would fail halfway. Planners are described by
:class:`PlannerSpec` (plain data), so worker processes can build their own.

An environment is a registered id (``SRPB-Corridor-v0``, or ``SRPB-Mix-v0``, whose every
episode draws one of the packaged scenarios) or a scenario file (``envs/my_lab.yaml``), run
as ``SRPB-Custom-v0`` with that scenario and labelled by the scenario's name in tables, file
names and ``episodes.csv``.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from srpb_gym.errors import InputError, env_kwargs_error
from srpb_gym.metrics.params import PRESETS, SEMANTICS
from srpb_gym.planners import PLANNERS, Planner, check_settings, make_planner, planner_config
from srpb_gym.registration import CUSTOM_ID, MIX_ID, SCENARIO_IDS

DEFAULT_ENVS: tuple[str, ...] = ("SRPB-Corridor-v0",)
ENV_IDS: tuple[str, ...] = (*SCENARIO_IDS, MIX_ID)
"""The registered ids an evaluation runs (a scenario file runs as ``SRPB-Custom-v0``)."""
DEFAULT_EPISODES = 5
DEFAULT_WARMUP = 100
"""Untimed control steps each planner takes before its first timed episode, per process:
10 s at the 0.1 s control step, long enough to meet the people of the packaged scenarios,
whose first sight compiles more of a planner than an empty scene does."""
SCENARIO_SUFFIXES = (".yaml", ".yml")


@dataclass(frozen=True)
class PlannerSpec:
    """A planner to evaluate: a registered one (``planner`` with the settings ``config``,
    plain data: the fields to change, see :func:`srpb_gym.planners.make_planner`) or a
    learned policy file (``policy``, its ``algo``, the ``vecnormalize`` statistics or
    ``None`` for raw observations, and the places searched for them); ``name`` labels its
    results."""

    name: str
    planner: str | None = None
    config: Mapping[str, Any] = field(default_factory=dict)
    policy: str | None = None
    algo: str | None = None
    vecnormalize: str | None = None
    vecnormalize_searched: tuple[str, ...] = ()

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
    the evaluation's own (:meth:`env_kwargs`)."""

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
        from srpb_gym.pettingzoo_env import parallel_env

        kwargs = {"scenario": self.scenario_name(env_id)}
        kwargs |= self.env_kwargs(env_id, planner, render=render)
        return parallel_env(n_robots=self.robots, **kwargs)


def default_out(now: float | None = None) -> str:
    """``runs/eval-<YYYYmmdd-HHMMSS>``."""
    return os.path.join("runs", "eval-" + time.strftime("%Y%m%d-%H%M%S", time.localtime(now)))


def stderr_log(line: str) -> None:
    """Print one ``srpb-gym: <line>`` to stderr."""
    print(f"srpb-gym: {line}", file=sys.stderr)


def resolve_config(
    envs: Sequence[str] | None = None,
    planners: Sequence[str] | None = None,
    policies: Sequence[str] = (),
    *,
    policy_algo: str | None = None,
    vecnormalize: str | None = "auto",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    out: str | None = None,
    workers: int = 1,
    video: int = 0,
    semantics: str = "paper",
    preset: str = "paper",
    planner_settings: Mapping[str, Mapping[str, Any]] | None = None,
    argv: Sequence[str] = (),
    warmup: int = DEFAULT_WARMUP,
    resume: bool = False,
    log: Callable[[str], None] | None = stderr_log,
    robots: int = 1,
    env_kwargs: Mapping[str, Any] | None = None,
    video_stride: int = 1,
) -> EvalConfig:
    """Check every choice and fill in the defaults: :data:`DEFAULT_ENVS`, every registered
    planner when neither ``planners`` nor ``policies`` is given, ``runs/eval-<time>``.

    ``envs``: registered ids or scenario files. ``planner_settings``: ``{planner name:
    settings}`` (plain data, e.g. from :func:`srpb_gym.planners.config.planner_settings`);
    every name must be a registered planner, and the settings of the planners evaluated are
    checked now (errors name ``planner.<name>.<field>``); those of planners not evaluated
    are left out. ``policy_algo``: force the algorithm of the policy files (default: read
    from each file); ``vecnormalize``: ``"auto"`` (look where training puts it), a file or
    ``None`` (raw observations). ``workers`` is capped at ``os.cpu_count()`` and at the
    number of episodes, with a warning. ``resume``: continue the run in ``out`` (see
    :mod:`srpb_gym.evaluation.outdir`). ``robots``: robots per episode, at most what every
    scenario places (else an error naming the limit, key ``--robots``). ``log`` receives
    each note and warning as it is made (they are also kept in ``notes``). ``env_kwargs``:
    keyword arguments of every environment (e.g. ``{"crowd": {"robot_reaction": 0.0}}``, or
    the ``observation`` a policy was trained with), checked by making each environment
    (errors: key ``--env-kwargs``); the keys the evaluation sets itself
    (:data:`RESERVED_ENV_KWARGS`) are refused. ``video_stride``: film every this many
    control steps (at least 1).
    """
    from srpb_gym.evaluation.outdir import check_out_dir
    from srpb_gym.evaluation.policies import policy_specs

    notes: list[str] = []

    def note(line: str) -> None:
        notes.append(line)
        if log is not None:
            log(line)

    _check_counts(episodes, workers, video, warmup, video_stride)
    if seed < 0:
        raise InputError(f"must be at least 0, got {seed}", key="--seed")
    if semantics not in SEMANTICS:
        raise InputError(f"choose one of: {', '.join(SEMANTICS)}", key="--semantics")
    if preset not in PRESETS:
        raise InputError(f"choose one of: {', '.join(PRESETS)}", key="--preset")
    env_ids, files = resolve_envs(envs or DEFAULT_ENVS)
    _check_robots(robots, env_ids, dict(files))
    probe = EvalConfig(tuple(env_ids), (), scenario_files=tuple(files), robots=robots,
                       make_kwargs=_check_env_kwargs(env_kwargs))  # fmt: skip
    if probe.make_kwargs:
        _probe_envs(probe)
    if planners is None and not policies:
        planners = list(PLANNERS)
    settings = check_settings(planner_settings or {})
    specs = [_planner_spec(name, settings.get(name)) for name in _unique(planners or ())]
    specs += policy_specs(policies, policy_algo, vecnormalize, probe, note)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(f"two planners are named {dup!r}; rename a policy file", key="--policy")
    workers = _cap_workers(workers, len(env_ids) * len(specs) * episodes, note)
    out = check_out_dir(out or default_out(), resume=resume)
    return EvalConfig(tuple(env_ids), tuple(specs), episodes, seed, out, workers, video,
                      semantics, preset, tuple(argv), tuple(files), warmup, resume,
                      tuple(notes), robots, probe.make_kwargs, video_stride)  # fmt: skip


#: ``gym.make`` keywords an evaluation sets itself, with the option that sets each
RESERVED_ENV_KWARGS: dict[str, str] = {
    "metrics": "--semantics and --preset",
    "scenario": "--env with a scenario file",
    "record_dir": "the evaluation (episodes/ in --out)",
    "render_mode": "--video",
    "n_robots": "--robots",
    "max_episode_steps": "the scenario's time_limit (a scenario file as --env)",
    "max_steps": "the scenario's time_limit (a scenario file as --env)",
}


def _check_env_kwargs(env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:
    if env_kwargs is None:
        return {}
    if not isinstance(env_kwargs, Mapping):
        raise InputError(f"expected KEY=VALUE pairs, got {env_kwargs!r}", key="--env-kwargs")
    for key in env_kwargs:
        if key in RESERVED_ENV_KWARGS:
            raise InputError(f"set by {RESERVED_ENV_KWARGS[key]}, not here",
                             key=f"--env-kwargs: {key}")  # fmt: skip
    return dict(env_kwargs)


def _probe_envs(probe: EvalConfig) -> None:
    """Make each environment of ``probe`` once, so that a keyword it does not take (or a
    bad value) fails now, naming the environment, rather than in a worker."""
    for env_id in probe.envs:
        try:
            env = probe.make_parallel(env_id) if probe.robots > 1 else probe.make_env(env_id)
        except (TypeError, ValueError) as exc:
            raise env_kwargs_error(env_id, exc) from None
        env.close()


def resolve_envs(items: Sequence[str]) -> tuple[list[str], list[tuple[str, str]]]:
    """Labels of the environments ``items`` (registered ids or scenario files) and the
    (label, file) pairs of the files; a file is labelled by its scenario's name."""
    from srpb_gym.scenarios import load_scenario

    labels: list[str] = []
    files: list[tuple[str, str]] = []
    for item in _unique(items):
        if item in ENV_IDS:
            labels.append(item)
            continue
        if not (item.endswith(SCENARIO_SUFFIXES) or "/" in item or os.sep in item
                or os.path.exists(item)):  # fmt: skip
            raise InputError(f"unknown environment id {item!r}; choose one of: "
                             f"{', '.join(ENV_IDS)}, or give a scenario file (.yaml)",
                             key="--env")  # fmt: skip
        if not os.path.isfile(item):
            why = "is a folder, not a scenario file" if os.path.isdir(item) else "no such file"
            raise InputError(why, item, key="--env")
        label = load_scenario(item).name
        path = os.path.abspath(item)
        if label in labels or label in SCENARIO_IDS:
            other = dict(files).get(label, label)
            raise InputError(f"its scenario is named {label!r}, as {other}; give the scenarios "
                             f"different names (key 'name')", item, key="--env")  # fmt: skip
        labels.append(label)
        files.append((label, path))
    return labels, files


def _check_robots(robots: int, env_ids: Sequence[str], files: Mapping[str, str]) -> None:
    """Refuse ``robots`` below 1 or above what a scenario places (naming its limit)."""
    from srpb_gym.scenarios import load_scenario

    if isinstance(robots, bool) or not isinstance(robots, int) or robots < 1:
        raise InputError(f"must be at least 1, got {robots}", key="--robots")
    for env in env_ids:
        if env == MIX_ID:
            if robots > 1:
                raise InputError(f"{MIX_ID} runs one robot per episode, got {robots}; "
                                 f"evaluate several robots on single-scenario ids",
                                 key="--robots")  # fmt: skip
            continue
        try:
            load_scenario(files.get(env, SCENARIO_IDS.get(env, env))).robot_specs(robots)
        except InputError as exc:
            if exc.key != "n_robots":
                raise
            raise InputError(exc.message, files.get(env), key="--robots") from None


def _check_counts(episodes: int, workers: int, video: int, warmup: int, video_stride: int) -> None:
    if episodes < 1:
        raise InputError(f"must be at least 1, got {episodes}", key="--episodes")
    if workers < 1:
        raise InputError(f"must be at least 1, got {workers}", key="--workers")
    if video < 0:
        raise InputError(f"must be at least 0, got {video}", key="--video")
    if warmup < 0:
        raise InputError(f"must be at least 0, got {warmup}", key="--warmup")
    if video_stride < 1:
        raise InputError(f"must be at least 1, got {video_stride}", key="--video-stride")


def _cap_workers(workers: int, planned: int, note: Callable[[str], None]) -> int:
    """``workers`` capped at the CPU count and at the number of episodes, with a warning."""
    cpus = os.cpu_count() or 1
    if workers > cpus:
        note(f"warning: --workers {workers} is more than the {cpus} CPU cores "
             f"(os.cpu_count() = {cpus}); using {cpus} (processes sharing a core "
             f"inflate the planning times m_cef and m_cre)")  # fmt: skip
        workers = cpus
    if workers > planned:
        note(f"note: --workers {workers} for {planned} episode(s); using {planned}")
        workers = planned
    return max(workers, 1)


def _unique(items: Sequence[str]) -> list[str]:
    return list(dict.fromkeys(items))


def _planner_spec(name: str, settings: Mapping[str, Any] | None = None) -> PlannerSpec:
    if name not in PLANNERS:
        raise InputError(f"unknown planner {name!r}; choose one of: {', '.join(PLANNERS)}",
                         key="--planner")  # fmt: skip
    planner_config(name, settings)  # fail now on a bad setting, not in a worker
    return PlannerSpec(name=name, planner=name, config=dict(settings or {}))


def check_out_dir(out: str, resume: bool = False) -> str:
    """See :func:`srpb_gym.evaluation.outdir.check_out_dir`."""
    from srpb_gym.evaluation.outdir import check_out_dir as check

    return check(out, resume=resume)


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
