"""Learned policies of an evaluation: each ``--policy`` file checked before the first episode.

For every model file (or ``srpb-gym train`` run folder, or short name of a shipped model,
:mod:`srpb_gym.models`) :func:`policy_specs` names its column, reads its algorithm (or
takes the forced one), finds its observation-normalisation statistics (or says that none
were found), loads both once and checks the model's observation and action spaces
against every environment's, so that a run never evaluates a model on observations it
was not trained for (a model that records its observation settings observes with them:
:class:`~srpb_gym.planners.learned.LearnedPolicy`; the note says so where they differ
from the environments').
Every call into :mod:`srpb_gym.models` and the model-file helpers of
:mod:`srpb_gym.planners.learned` of the evaluation is made here. stable-baselines3 and
torch are imported (by those modules) only when a policy is given.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EvalConfig, PlannerSpec
from srpb_gym.models import (
    ALGORITHMS,
    MODEL_FILE,
    PolicyFileError,
    VecNormalizeError,
    find_model,
    find_vecnormalize,
    lidar_beams_of,
    model_names,
    observation_config_of,
    settings_text,
    stray_vecnormalize,
    vecnormalize_candidates,
)
from srpb_gym.planners import Planner
from srpb_gym.planners.learned import LearnedPolicy


def policy_specs(
    paths: Sequence[str],
    algo: str | None,
    vecnormalize: str | None,
    probe: EvalConfig,
    note: Callable[[str], None],
    trust_pickle: bool = False,
) -> list[PlannerSpec]:
    """One spec per policy: a model file, a ``srpb-gym train`` run folder or a shipped
    model's short name, named after the file's stem, the folder or the short name (with
    as many folders above as tell two policies apart: ``<folder>-<stem>`` when two files
    share a stem). ``algo``: forced algorithm or ``None`` (read from each file);
    ``vecnormalize``: ``"auto"``, a file, or ``None``/``"none"`` (raw observations).
    ``probe`` gives the environments; ``note`` receives one line per policy saying which
    algorithm and which normalisation statistics it uses. ``trust_pickle``: the user
    trusts the files' pickles (``--trust-pickle``; otherwise a pickled statistics file is
    refused and a model's pickled attributes are decoded as data only)."""
    if not paths:
        return []
    if algo is not None and algo.upper() not in ALGORITHMS:
        raise InputError(f"choose one of: {', '.join(ALGORITHMS)}", key="--policy-algo")
    if vecnormalize is not None and vecnormalize.lower() == "none":
        vecnormalize = None
    if vecnormalize not in (None, "auto") and not os.path.isfile(vecnormalize):
        raise InputError("no such file", vecnormalize, key="--vecnormalize")
    resolved = [_model_file(os.fspath(p)) for p in paths]
    files = [os.path.realpath(path) for path, _ in resolved]
    for i, file in enumerate(files):
        if file in files[:i]:
            raise InputError("the same model is given twice", paths[i], key="--policy")
    specs = []
    for (path, _), name in zip(resolved, _unique_names([parts for _, parts in resolved])):
        spec = _policy_spec(name, path, algo, vecnormalize, probe.envs, trust_pickle)
        policy = load_policy(spec)
        spec = dataclasses.replace(spec, algo=policy.algo)
        how = "forced by --policy-algo" if algo is not None else "read from the file"
        note(
            f"note: policy {name}: {policy.algo} model ({how}); "
            + _normalisation(spec)
            + _observes(policy, probe)
        )
        _check_spaces(policy, probe)
        specs.append(spec)
    return specs


def _model_file(given: str) -> tuple[str, tuple[str, ...]]:
    """The model file that ``--policy`` names and the parts of the path that name it,
    last first: a file (its stem, then its folders), a ``srpb-gym train`` run folder (its
    ``model.zip``; the folder's name, then those above it) or a shipped model's short
    name (that name alone). A name that is none of them is returned as it is, for
    :func:`load_policy` to report. The file is found as ``--init`` and
    ``pretrain_teachers`` find theirs (:func:`srpb_gym.models.find_model`)."""
    folder = os.path.isdir(given)
    if folder and not os.path.isfile(os.path.join(given, MODEL_FILE)):
        raise InputError(f"a folder without {MODEL_FILE}: give the model file (.zip) of "
                         "the run", given, key="--policy")  # fmt: skip
    path = find_model(given)
    if path is not None and folder:
        return path, tuple(reversed(Path(given).resolve().parts[1:])) or (Path(path).stem,)
    if path is not None and not os.path.isfile(given):
        return path, (given,)  # a shipped model's short name
    file = Path(given)
    return given, (file.stem, *reversed(file.resolve().parent.parts[1:]))


def _unique_names(parts: Sequence[Sequence[str]]) -> list[str]:
    """A name for each path, from its parts (last first): its first part (a file's stem,
    a folder's or a shipped model's name), then as many of the folders above it, joined
    by '-', as it takes to tell it from the others' names. Paths that no part tells apart
    (``a/b.zip`` and the folder ``a/b``) keep their longest names."""
    depth = [1] * len(parts)
    while True:
        names = ["-".join(reversed(p[:d])) for p, d in zip(parts, depth)]
        grow = [i for i, n in enumerate(names) if names.count(n) > 1 and depth[i] < len(parts[i])]
        if not grow:
            return names
        for i in grow:
            depth[i] += 1


def _policy_spec(name: str, path: str, algo: str | None, vecnormalize: str | None,
                 env_ids: Sequence[str], trust_pickle: bool = False) -> PlannerSpec:  # fmt: skip
    searched: tuple[str, ...] = ()
    if vecnormalize == "auto":
        searched = tuple(str(p) for p in vecnormalize_candidates(path, env_ids))
        vecnormalize = find_vecnormalize(path, env_ids)
        if vecnormalize is None:
            _refuse_stray(path, env_ids)
    return PlannerSpec(name=name, policy=path, algo=None if algo is None else algo.upper(),
                       vecnormalize=vecnormalize, vecnormalize_searched=searched,
                       trust_pickle=trust_pickle)  # fmt: skip


def _refuse_stray(path: str, env_ids: Sequence[str]) -> None:
    """Refuse a model without statistics where training puts them whose folder holds
    statistics elsewhere: they may be another model's, and raw observations may be wrong."""
    stray = stray_vecnormalize(path, env_ids)
    if stray:
        raise InputError(f"no statistics where training puts them, but {stray[0]} lies in "
                         "another folder and may be another model's: give the model's "
                         "statistics with --vecnormalize FILE, or --vecnormalize none for "
                         "raw observations", path, key="--policy")  # fmt: skip


def _normalisation(spec: PlannerSpec) -> str:
    if spec.vecnormalize is not None:
        return f"observations normalised with {spec.vecnormalize}"
    if spec.vecnormalize_searched:
        return ("no statistics found (looked for "
                f"{', '.join(spec.vecnormalize_searched)}): raw observations")  # fmt: skip
    return "raw observations (--vecnormalize none)"


def _observes(policy: LearnedPolicy, probe: EvalConfig) -> str:
    """How the policy observes, when its recorded settings differ from the environments'."""
    own = policy.observation_config
    env = probe.make_env(probe.envs[0], render=False)
    try:
        given = observation_config_of(env)
    finally:
        env.close()
    if own is None or given is None or own == given:
        return ""
    return (
        f"; it observes with its own settings observation={settings_text(own, given)} "
        f"(the environments': {settings_text(given, own)})"
    )


def _check_spaces(policy: LearnedPolicy, probe: EvalConfig) -> None:
    for env_id in probe.envs:
        env = probe.make_env(env_id, render=False)
        try:
            policy.check_spaces(env.observation_space, env.action_space, lidar_beams_of(env))
        except ValueError as exc:
            raise InputError(f"{exc} ({env_id})", key="--policy") from None
        finally:
            env.close()


def load_policy(spec: PlannerSpec) -> LearnedPolicy:
    """Build a learned policy, turning every failure into an :class:`InputError` naming
    the file at fault (the model or its normalisation statistics)."""
    path = str(spec.policy)
    if not os.path.isfile(path):
        names = model_names()
        shipped = f"shipped models: {', '.join(names)}" if names else "no models are shipped"
        raise InputError(f"no such file or shipped model ({shipped})", path, key="--policy")
    if not os.access(path, os.R_OK):
        raise InputError("cannot read the file", path, key="--policy")
    try:
        planner: Planner = spec.build()
    except ImportError as exc:
        raise InputError(str(exc), key="--policy") from None
    except VecNormalizeError as exc:
        raise InputError(exc.reason, exc.path, key="vecnormalize") from None
    except PolicyFileError as exc:
        raise InputError(exc.reason, exc.path, key="--policy") from None
    return planner  # type: ignore[return-value]
