"""What an evaluation runs: environments, planners, seeds, output folder, checked once.

:func:`resolve_config` turns user choices into an :class:`~srpb_gym.evaluation.data.EvalConfig`,
raising :class:`~srpb_gym.errors.InputError` (key = the command-line option) for anything
wrong, so a run never starts with an argument that would fail halfway. Planners are
described by :class:`~srpb_gym.evaluation.data.PlannerSpec` (plain data), so worker
processes can build their own.

An environment is a registered id (``SRPB-Corridor-v0``, or ``SRPB-Mix-v0``, whose every
episode draws one of the packaged scenarios) or a scenario file (``envs/my_lab.yaml``), run
as ``SRPB-Custom-v0`` with that scenario and labelled by the scenario's name in tables, file
names and ``episodes.csv``.
"""

from __future__ import annotations

import numbers
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from srpb_gym.errors import InputError, env_kwargs_error
from srpb_gym.evaluation import ray_pool
from srpb_gym.evaluation.data import DEFAULT_EPISODES, DEFAULT_WARMUP, EvalConfig, PlannerSpec
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.evaluation.policies import policy_specs
from srpb_gym.metrics.params import PRESETS, SEMANTICS
from srpb_gym.planners import (
    PLANNERS,
    REFERENCE_PLANNERS,
    check_settings,
    is_planner,
    planner_config,
    unknown_planner,
)
from srpb_gym.registration import MIX_ID, SCENARIO_IDS
from srpb_gym.scenarios import load_scenario

DEFAULT_ENVS: tuple[str, ...] = ("SRPB-Corridor-v0",)
ENV_IDS: tuple[str, ...] = (*SCENARIO_IDS, MIX_ID)
"""The registered ids an evaluation runs (a scenario file runs as ``SRPB-Custom-v0``)."""
SCENARIO_SUFFIXES = (".yaml", ".yml")
BACKENDS: tuple[str, ...] = ("process", "ray")
"""Where the episodes run: worker processes of this machine, or Ray tasks."""


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
    trust_pickle: bool = False,
    backend: str = "process",
    address: str | None = None,
) -> EvalConfig:
    """Check every choice and fill in the defaults: :data:`DEFAULT_ENVS`, every registered
    planner (:data:`~srpb_gym.planners.PLANNERS`; a reference planner of
    :data:`~srpb_gym.planners.REFERENCE_PLANNERS` runs only when named) when neither
    ``planners`` nor ``policies`` is given, ``runs/eval-<time>``.

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
    control steps (at least 1). ``trust_pickle``: the user trusts the pickles of the policy
    files (see :func:`~srpb_gym.evaluation.policies.policy_specs`). ``backend``:
    ``"process"`` or ``"ray"`` (Ray tasks on a local Ray, or on the cluster at ``address``;
    ``workers`` then caps the episodes running at once, 0: every CPU of the cluster, and
    is capped at the number of episodes only); ``address`` without ``"ray"``, or
    ``"ray"`` without Ray installed, is an :class:`InputError`.
    """
    notes: list[str] = []

    def note(line: str) -> None:
        notes.append(line)
        if log is not None:
            log(line)

    _check_backend(backend, address)
    _check_counts(episodes, workers, video, warmup, video_stride, 0 if backend == "ray" else 1)
    if seed < 0:
        raise InputError(f"must be at least 0, got {seed}", key="--seed")
    if semantics not in SEMANTICS:
        raise InputError(f"choose one of: {', '.join(SEMANTICS)}", key="--semantics")
    if preset not in PRESETS:
        raise InputError(f"choose one of: {', '.join(PRESETS)}", key="--preset")
    env_ids, files = resolve_envs(envs or DEFAULT_ENVS)
    _check_robots(robots, env_ids, dict(files))
    robots = int(robots)  # a numpy integer too
    probe = EvalConfig(tuple(env_ids), (), scenario_files=tuple(files), robots=robots,
                       make_kwargs=_check_env_kwargs(env_kwargs))  # fmt: skip
    if probe.make_kwargs:
        _probe_envs(probe)
    if planners is None and not policies:
        planners = list(PLANNERS)
    settings = check_settings(planner_settings or {})
    specs = [_planner_spec(name, settings.get(name)) for name in _unique(planners or ())]
    for spec in specs:
        if spec.planner in REFERENCE_PLANNERS:
            note(f"note: {spec.name} is a reference planner, handed the true people instead "
                 "of the tracker's: no baseline")  # fmt: skip
    specs += policy_specs(policies, policy_algo, vecnormalize, probe, note, trust_pickle)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(f"two planners are named {dup!r}; rename a policy file", key="--policy")
    planned = len(env_ids) * len(specs) * episodes
    # Ray: the cluster's CPUs are counted when it is reached
    ray = backend == "ray"
    workers = min(workers, planned) if ray else _cap_workers(workers, planned, note)
    out = check_out_dir(out or default_out(), resume=resume)
    return EvalConfig(tuple(env_ids), tuple(specs), episodes, seed, out, workers, video,
                      semantics, preset, tuple(argv), tuple(files), warmup, resume,
                      tuple(notes), robots, probe.make_kwargs, video_stride, backend,
                      address)  # fmt: skip


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
    if isinstance(robots, (bool, np.bool_)) or not isinstance(robots, numbers.Integral):
        raise InputError(f"expected a whole number, got {robots!r}", key="--robots")
    if robots < 1:
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


def _check_backend(backend: str, address: str | None) -> None:
    if backend not in BACKENDS:
        raise InputError(f"choose one of: {', '.join(BACKENDS)}, got {backend!r}", key="--backend")
    if address is not None and backend != "ray":
        raise InputError("a Ray cluster's address needs --backend ray", key="--address")
    if backend == "ray":
        ray_pool.check_installed()


def _check_counts(
    episodes: int, workers: int, video: int, warmup: int, video_stride: int, least: int = 1
) -> None:
    if episodes < 1:
        raise InputError(f"must be at least 1, got {episodes}", key="--episodes")
    if workers < least:
        raise InputError(f"must be at least {least}, got {workers}", key="--workers")
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
    if not is_planner(name):
        raise InputError(unknown_planner(name), key="--planner")
    planner_config(name, settings)  # fail now on a bad setting, not in a worker
    return PlannerSpec(name=name, planner=name, config=dict(settings or {}))
