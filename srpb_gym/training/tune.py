"""Several seeds, or a small hyperparameter grid, of one ``srpb-gym train`` recipe as Ray
Tune trials (``srpb-gym train --seeds 0 1 2 --backend ray``).

Every trial is one ordinary run (:func:`srpb_gym.training.run.train`) into a run folder of
its own, ``<out>/<trial>`` (``seed0``, or ``learning_rate=0.001-seed0`` in a grid), with
exactly the files a single ``srpb-gym train`` writes. Its periodic evaluations (on the
checkpoint-selection seeds; they choose the run's ``best/``) are reported to Tune as they
happen (``eval/success``, ``eval/m_psi``, ``eval/gt_m_psi``, ... : the mean over the
evaluated environments; ``gt_``: from the true people).
When a trial has trained, its best checkpoint (``best/``, else the final model) is
evaluated on the **validation** seeds (:data:`~srpb_gym.seeds.VALIDATION`, from its
start; ``--validation-episodes`` per environment) into ``<out>/validation/<trial>``, and
that is the trial's last report (``validation/success``, ``validation/gt_m_psi``, ...).
The best trial is chosen on those figures alone (the highest success rate, then the
lowest median ``m_psi`` from the true people, as ``best/`` is chosen within a run); the
test seeds are never used.
``<out>/trials.csv`` lists every trial and its validation figures, ``<out>/best.json``
names the best; Tune's own records are in ``<out>/tune/``.

Ray is imported only when trials run. On a cluster (``--address``) ``--out`` must be a
folder that every node sees at the same path (a shared file system).
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math
import os
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.evaluation import harness, spec
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.evaluation.ray_pool import connect
from srpb_gym.models.shipped import MODEL_FILE
from srpb_gym.seeds import TRAINING, VALIDATION, check_not_test, check_within
from srpb_gym.training.callbacks import CHOOSE_BY, eval_score, summarize_results
from srpb_gym.training.config import DEFAULT_VALIDATION_EPISODES, resolve
from srpb_gym.training.run import train
from srpb_gym.training.targets import eval_setup

FIGURES = ("success", "collision", "timeout", "m_psi", CHOOSE_BY)


@dataclass(frozen=True)
class SweepSpec:
    """What every trial shares: the recipe (``env_id``, ``overrides``, the hyperparameter
    file ``config_file``, ``preset``, ``env_kwargs``), the sweep's folder ``out``, the
    working folder ``cwd``, the validation episodes and the wall-time limit of a trial."""

    env_id: str
    overrides: Mapping[str, Any]
    config_file: str | None
    preset: str
    env_kwargs: Mapping[str, Any]
    out: str
    cwd: str
    validation_episodes: int = DEFAULT_VALIDATION_EPISODES
    max_minutes: float | None = None
    argv: tuple[str, ...] = ()


@dataclass
class SweepOutcome:
    """The trials (name, seed, grid point, run folder, validation figures or ``error``)
    and the best one's name (``None`` when none finished)."""

    out: str
    trials: list[dict[str, Any]] = field(default_factory=list)
    best: str | None = None


def trial_name(point: Mapping[str, Any], seed: int) -> str:
    """``seed3``, or ``key=value-...-seed3`` for a grid point (safe as a folder name)."""
    parts = [f"{k}={v}" for k, v in point.items()] + [f"seed{seed}"]
    return re.sub(r"[^A-Za-z0-9=._,+-]", "_", "-".join(parts))


def grid_points(grid: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every combination of the grid's values (``{key: [values]}``); ``[{}]`` without one."""
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InputError(f"give a list of values, e.g. '{key}=[0.0003, 0.001]', got "
                             f"{values!r}", key=f"--grid: {key}")  # fmt: skip
    keys = list(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def plan(sweep: SweepSpec, seeds: Sequence[int], grid: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The trials of a sweep, every setting checked first (each grid point's
    configuration, each seed's training range, the validation seeds)."""
    if not seeds:
        raise InputError("give at least one seed", key="--seeds")
    if len(set(seeds)) != len(seeds):
        raise InputError(f"a seed is given twice: {list(seeds)}", key="--seeds")
    if sweep.validation_episodes < 1:
        raise InputError(f"must be at least 1, got {sweep.validation_episodes}",
                         key="--validation-episodes")  # fmt: skip
    check_not_test(VALIDATION.start, sweep.validation_episodes, "--validation-episodes")
    check_within(VALIDATION, VALIDATION.start, sweep.validation_episodes, "--validation-episodes")
    trials = []
    for point in grid_points(grid):
        config = resolve(sweep.env_id, {**sweep.overrides, **point}, sweep.config_file)
        for seed in seeds:
            check_within(TRAINING, seed, config.n_envs, "--seeds")
            cpus = config.n_envs if config.vec_env == "subproc" else 1
            trials.append({"name": trial_name(point, seed), "seed": int(seed),
                           "point": dict(point), "cpus": cpus})  # fmt: skip
    return trials


def run_sweep(sweep: SweepSpec, seeds: Sequence[int], grid: Mapping[str, Any],
              address: str | None = None,
              log: Callable[[str], None] = print) -> SweepOutcome:  # fmt: skip
    """Run the trials of ``seeds`` x ``grid`` as Ray Tune trials (see the module
    docstring); returns them, the best chosen on the validation seeds."""
    trials = plan(sweep, seeds, grid)
    out = os.path.abspath(check_out_dir(sweep.out))
    sweep = dataclasses.replace(sweep, out=out)
    ray, started = connect(address)
    try:
        from ray import tune

        trainable = tune.with_resources(lambda params: _trial(sweep, params["trial"]),
                                        {"cpu": max(t["cpus"] for t in trials)})  # fmt: skip
        tuner = tune.Tuner(
            trainable, param_space={"trial": tune.grid_search(trials)},
            tune_config=tune.TuneConfig(trial_dirname_creator=_trial_folder),
            run_config=tune.RunConfig(storage_path=os.path.join(out, "tune"), name="trials",
                                      verbose=0),
        )  # fmt: skip
        log(f"{len(trials)} trial(s) on Ray Tune; run folders in {out}")
        grid_result = tuner.fit()
    finally:
        if started:
            ray.shutdown()
    return _summarise(out, trials, grid_result, log)


def _trial_folder(trial: Any) -> str:
    return str(trial.config["trial"]["name"])


def _trial(sweep: SweepSpec, trial: Mapping[str, Any]) -> None:
    """One trial in a Ray worker: train, report each periodic evaluation, validate."""
    from ray import tune

    if os.path.isdir(sweep.cwd):  # Tune starts a trial in a folder of its own
        os.chdir(sweep.cwd)
    config = resolve(sweep.env_id, {**sweep.overrides, **trial["point"]}, sweep.config_file)
    run_dir = os.path.join(sweep.out, trial["name"])

    def report(step: int, figures: Mapping[str, Mapping[str, float]]) -> None:
        tune.report({"step": step, **flat("eval", figures)})

    result = train(sweep.env_id, config, preset=sweep.preset, seed=trial["seed"], out=run_dir,
                   env_kwargs=dict(sweep.env_kwargs), progress=False, argv=sweep.argv,
                   log=lambda line: None, max_minutes=sweep.max_minutes,
                   on_eval=report)  # fmt: skip
    figures = validate(run_dir, sweep.env_id, sweep.env_kwargs, sweep.validation_episodes,
                       os.path.join(sweep.out, "validation", trial["name"]))  # fmt: skip
    tune.report({"step": result.steps, **flat("validation", figures), "done": True})


def validate(run_dir: str, env_id: str, env_kwargs: Mapping[str, Any], episodes: int,
             out: str) -> dict[str, dict[str, float]]:  # fmt: skip
    """The figures of a run's best checkpoint (``best/``, else its final model) on the
    first ``episodes`` validation seeds of each environment it is evaluated on."""
    best = os.path.join(run_dir, "best")
    policy = best if os.path.isfile(os.path.join(best, MODEL_FILE)) else run_dir
    env_ids, kwargs = eval_setup(env_id, dict(env_kwargs))
    config = spec.resolve_config(env_ids, policies=[policy], episodes=episodes,
                                 seed=VALIDATION.start, out=out, warmup=0, log=None,
                                 env_kwargs=kwargs)  # fmt: skip
    outcome = harness.run_evaluation(config, log=lambda line: None, progress=False)
    return summarize_results(outcome.results)


def flat(prefix: str, figures: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
    """``prefix/<figure>``: each figure's mean over the environments (``gt_m_psi``: as
    :func:`~srpb_gym.training.callbacks.eval_score` takes it), and ``prefix/<env>/<figure>``
    for each environment when there are several."""
    out: dict[str, float] = {}
    success, neg_psi = eval_score(figures.values())
    for key in FIGURES:
        values = [f[key] for f in figures.values() if math.isfinite(f.get(key, math.nan))]
        out[f"{prefix}/{key}"] = sum(values) / len(values) if values else math.nan
    out[f"{prefix}/success"], out[f"{prefix}/{CHOOSE_BY}"] = success, -neg_psi
    if len(figures) > 1:
        for env, fig in figures.items():
            out |= {f"{prefix}/{env}/{k}": float(fig[k]) for k in FIGURES if k in fig}
    return out


def _summarise(out: str, trials: list[dict[str, Any]], grid_result: Any,
               log: Callable[[str], None]) -> SweepOutcome:  # fmt: skip
    outcome = SweepOutcome(out)
    by_name = {}
    for result in grid_result:
        name = (result.config or {}).get("trial", {}).get("name")
        by_name[name] = result
    for trial in trials:
        result = by_name.get(trial["name"])
        metrics = dict(result.metrics or {}) if result is not None else {}
        row = {"trial": trial["name"], "seed": trial["seed"], **trial["point"],
               "run": os.path.join(out, trial["name"]),
               "validation_success": metrics.get("validation/success", math.nan),
               "validation_m_psi": metrics.get("validation/m_psi", math.nan),
               "validation_gt_m_psi": metrics.get(f"validation/{CHOOSE_BY}", math.nan),
               "error": "" if result is None or result.error is None
               else str(result.error).strip().splitlines()[-1][:200]}  # fmt: skip
        outcome.trials.append(row)
    done = [r for r in outcome.trials if not r["error"] and math.isfinite(r["validation_success"])]
    if done:
        best = max(done, key=lambda r: (r["validation_success"],
                                        -r["validation_gt_m_psi"] if math.isfinite(
                                            r["validation_gt_m_psi"]) else -math.inf))  # fmt: skip
        outcome.best = best["trial"]
    keys = list(dict.fromkeys(k for r in outcome.trials for k in r))
    with open(os.path.join(out, "trials.csv"), "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(outcome.trials)
    with open(os.path.join(out, "best.json"), "w", encoding="utf-8") as f:
        best_row = next((r for r in outcome.trials if r["trial"] == outcome.best), None)
        json.dump({"chosen_on": f"{VALIDATION.text()}, from {VALIDATION.start}",
                   "rule": "highest validation success rate, then lowest median m_psi "
                           "from the true people",
                   "best": best_row, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")},
                  f, indent=1, default=str)  # fmt: skip
        f.write("\n")
    for r in outcome.trials:
        state = r["error"] or (f"validation success {100 * r['validation_success']:.0f} %, "
                               f"m_psi {r['validation_gt_m_psi']:.3g} % (ground truth), "
                               f"{r['validation_m_psi']:.3g} % (tracked)")  # fmt: skip
        log(f"{r['trial']}: {state}{' (best)' if r['trial'] == outcome.best else ''}")
    return outcome
