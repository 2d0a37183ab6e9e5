"""Comparing earlier evaluation runs: their ``episodes.csv`` merged into one table per scenario.

Runs are compared only when their figures mean the same: each run's ``config.json`` (beside
its ``episodes.csv``) gives the metric semantics, the parameter preset, every scenario's
metric parameters and the robots per episode, and runs that differ in any of them (or whose
settings are unknown) are refused, naming the differing keys, unless ``separate`` keeps them
apart as columns of their own (``planner@run``) with a note of each run's settings.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.evaluation import figures, paired, stats
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.outdir import (
    check_out_dir,
    describe_differences,
    differences,
    read_json,
    write_json,
)


@dataclass
class Run:
    """One run given to :func:`compare_runs`: its label (folder name), ``episodes.csv``,
    rows, and settings (``None`` when it has no ``config.json``)."""

    label: str
    csv: str
    rows: list[EpisodeResult]
    config: str | None
    settings: dict[str, Any] | None


def run_settings(config: Any) -> dict[str, Any] | None:
    """``{"semantics", "preset", "robots", "env_kwargs", "metric_params": {env: params}}``
    of a run's ``config.json`` content (``robots`` absent: 1, ``env_kwargs`` absent: none),
    or ``None`` when it does not say them."""
    if not isinstance(config, dict) or not {"semantics", "preset"} <= set(config):
        return None
    envs = config.get("envs") if isinstance(config.get("envs"), list) else []
    params = {e["id"]: e.get("metric_params") for e in envs if isinstance(e, dict) and "id" in e}
    return {"semantics": config["semantics"], "preset": config["preset"],
            "robots": config.get("robots", 1), "env_kwargs": config.get("env_kwargs", {}),
            "metric_params": params}  # fmt: skip


def load_run(path: str) -> Run:
    """A run folder (or its ``episodes.csv``) with its rows and settings."""
    csv_path = os.path.join(path, "episodes.csv") if os.path.isdir(path) else path
    if not os.path.isfile(csv_path):
        raise InputError("no episodes.csv here (not an evaluation folder)", path)
    folder = os.path.dirname(csv_path) or "."
    config = os.path.join(folder, "config.json")
    settings = run_settings(read_json(config)) if os.path.isfile(config) else None
    label = os.path.basename(os.path.abspath(folder))
    rows = stats.read_episodes(csv_path)
    return Run(label, csv_path, rows, config if os.path.isfile(config) else None, settings)


def settings_differences(a: dict[str, Any], b: dict[str, Any]) -> list[tuple[str, Any, Any]]:
    """Differing keys of two runs' settings: semantics, preset, robots, the environments'
    keyword arguments (``env_kwargs.<key>``) and the metric parameters of the scenarios
    both ran (``metric_params.<env>.<name>``)."""
    keys = ("semantics", "preset", "robots")
    diffs = [(k, a.get(k, 1), b.get(k, 1)) for k in keys if a.get(k, 1) != b.get(k, 1)]
    diffs += differences(a.get("env_kwargs", {}), b.get("env_kwargs", {}), "env_kwargs")
    common = [env for env in a["metric_params"] if env in b["metric_params"]]
    for env in common:
        diffs += differences(a["metric_params"][env], b["metric_params"][env],
                             f"metric_params.{env}")  # fmt: skip
    return diffs


def _check_settings(runs: list[Run], separate: bool) -> list[str]:
    """Refuse runs whose settings differ or are unknown (unless ``separate``); returns the
    notes describing each run's settings when they are kept apart, else none."""
    if len(runs) < 2:
        return []
    first = runs[0]
    problems: list[str] = []
    for run in runs:
        if run.settings is None:
            problems.append(f"{run.csv}: no config.json beside it: its semantics, preset and "
                            f"metric parameters are unknown")  # fmt: skip
        elif first.settings is not None and run is not first:
            diffs = settings_differences(first.settings, run.settings)
            if diffs:
                text = describe_differences(diffs, f"in {first.label}", f"in {run.label}")
                problems.append(f"{run.config}: made with other settings than "
                                f"{first.config}: {text}")  # fmt: skip
    if not problems:
        return []
    if not separate:
        raise InputError(f"{problems[0]}; pass --separate to keep the runs apart as separate "
                         f"columns", key="compare")  # fmt: skip
    notes = ["the runs were made with different settings and are kept apart (planner@run):"]
    for run in runs:
        s = run.settings
        what = ("settings unknown (no config.json)" if s is None
                else f"semantics {s['semantics']}, preset {s['preset']}, robots "
                     f"{s.get('robots', 1)}"
                     + (f", env kwargs {json.dumps(s['env_kwargs'])}" if s.get("env_kwargs")
                        else ""))  # fmt: skip
        notes.append(f"  {run.label}: {what}")
    notes += [f"  {p}" for p in problems if "other settings" in p]
    return notes


def compare_runs(
    dirs: Sequence[str],
    out: str | None = None,
    separate: bool = False,
    reference: str | None = None,
) -> tuple[str, list[str]]:
    """Merge the ``episodes.csv`` of earlier runs into one table per scenario. A planner
    found in more than one run is labelled ``<planner>@<run folder>``; with ``separate``,
    runs made with different settings are kept apart (every planner labelled by its run)
    instead of refused. With ``out``, also writes the merged ``episodes.csv``,
    ``summary.json``, ``config.json`` (the common settings), the tables and bar charts
    there. The paired tests compare every planner with ``reference`` (default: the first
    of each scenario). Returns the printed text and the files written."""
    runs = [load_run(d) for d in dirs]
    labels = [run.label for run in runs]
    for i, run in enumerate(runs):
        if labels.count(run.label) > 1:
            run.label = f"{run.label}#{i + 1}"
    notes = _check_settings(runs, separate)
    merged = _label_planners(runs, every=bool(notes))
    if not merged:
        raise InputError("the runs hold no episode", key="compare")
    summary = stats.summarize(merged)
    text = stats.tables_text(summary)
    if notes:
        text += "\n\n" + "\n".join(notes)
    # runs of other settings score other things: their planners are not paired
    comparisons = [] if notes else paired.paired_comparisons(merged, reference)
    if notes:
        text += "\n\nno paired comparisons: the runs were made with different settings"
    elif comparisons:
        text += "\n\n" + paired.paired_text(comparisons)
    if out is None:
        return text, []
    check_out_dir(out)
    files = [os.path.join(out, n) for n in ("episodes.csv", "summary.json", "config.json")]
    stats.write_episodes(files[0], merged)
    write_json(files[1], {"runs": list(dirs), "notes": notes, "statistics": stats.STATISTICS,
                          "results": summary})  # fmt: skip
    write_json(files[2], _merged_config(runs, notes))
    files += paired.write_paired(comparisons, out)
    return text, files + stats.write_tables(summary, out) + _compare_bars(summary, out)


def _merged_config(runs: list[Run], notes: list[str]) -> dict[str, Any]:
    """``config.json`` of a comparison: the runs, and their common settings when they
    agree (then a later comparison can check them)."""
    doc: dict[str, Any] = {"compare": [run.csv for run in runs]}
    first = runs[0].settings
    if notes or first is None:
        return doc | {"settings": [run.settings for run in runs]}
    params: dict[str, Any] = {}
    for run in runs:
        params |= (run.settings or {}).get("metric_params", {})
    envs = [{"id": env, "metric_params": p} for env, p in params.items()]
    return doc | {"semantics": first["semantics"], "preset": first["preset"],
                  "robots": first.get("robots", 1), "env_kwargs": first.get("env_kwargs", {}),
                  "envs": envs}  # fmt: skip


def _label_planners(runs: list[Run], every: bool) -> list[EpisodeResult]:
    seen: dict[tuple[str, str], int] = {}
    for run in runs:
        for pair in {(r.env, r.planner) for r in run.rows}:
            seen[pair] = seen.get(pair, 0) + 1
    merged = []
    for run in runs:
        for r in run.rows:
            if every or seen[(r.env, r.planner)] > 1:
                r.planner = f"{r.planner}@{run.label}"
            merged.append(r)
    return merged


def _compare_bars(summary: stats.Summary, out: str) -> list[str]:
    try:
        figures.pyplot()
    except ImportError:
        return []
    paths = []
    for env_id, planners in summary.items():
        path = os.path.join(out, f"bars_{env_id}.png")
        figures.bar_chart(planners, f"{env_id}: median with its 95 % interval (hatched: "
                          f"ground truth)", path, stats.PEOPLE_METRICS)  # fmt: skip
        paths.append(path)
    return paths
