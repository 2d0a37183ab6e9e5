"""The evaluation run and the comparison of runs, with every file they write.

An evaluation writes into its output folder ``config.json`` (the resolved configuration),
``command.txt``, ``versions.json``, ``episodes.csv`` (a row per episode, written as each one
finishes), ``episodes/<env id>/<planner>/`` (SRPB native logs and ``.npz`` records),
``summary.json``, ``table_<env>.md|.csv|.tex``, with two planners or more ``paired.json``
and ``paired.md`` (:mod:`srpb_gym.evaluation.paired`), ``trajectories_<env>_<planner>.png``,
``bars_<env>.png`` and, when asked, ``videos/``. A multi-robot run (``config.robots`` > 1)
has a row per (episode, robot) and per-robot and pooled columns in its tables. With
``config.resume`` it continues the interrupted run in that folder
(:mod:`srpb_gym.evaluation.outdir`): the finished episodes are kept, the others run, and the
summary, tables and figures cover them all.
"""

from __future__ import annotations

import os
import platform
import shlex
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

from srpb_gym._version import __version__
from srpb_gym.evaluation import figures, outdir, paired, stats
from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, tasks_of
from srpb_gym.evaluation.outdir import write_json
from srpb_gym.evaluation.pool import remove_unfinished, run_tasks
from srpb_gym.metrics import MetricParams, SRPBMetricWarning
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.scenarios import load_scenario

VERSIONED: tuple[tuple[str, str], ...] = (
    ("srpb-gym", "srpb-gym"), ("numpy", "numpy"), ("scipy", "scipy"), ("numba", "numba"),
    ("gymnasium", "gymnasium"), ("pymunk", "pymunk"), ("matplotlib", "matplotlib"),
    ("stable-baselines3", "stable_baselines3"), ("torch", "torch"),
    ("imageio", "imageio"), ("pygame-ce", "pygame-ce"), ("tqdm", "tqdm"),
)  # fmt: skip
"""(name in versions.json, distribution name); absent distributions are left out."""
BARS = "median with its 95 % interval (hatched: ground truth)"


@dataclass
class RunOutcome:
    """What a run produced: its finished episodes (canonical order), whether it was
    interrupted, the tables as printed and every file written (joined with ``config.out``)."""

    config: EvalConfig
    results: list[EpisodeResult]
    interrupted: bool
    text: str = ""
    files: list[str] = field(default_factory=list)

    @property
    def planned(self) -> int:
        return len(self.config.envs) * len(self.config.planners) * self.config.episodes

    @property
    def finished(self) -> int:
        """Finished episodes (a multi-robot episode counts once, not once per robot)."""
        return len({(r.env, r.planner, r.seed) for r in self.results})


def run_evaluation(config: EvalConfig, log: Callable[[str], None] | None = None,
                   progress: bool = True) -> RunOutcome:  # fmt: skip
    """Run every episode of ``config`` and write every artifact into ``config.out``.

    Ctrl-C stops the run: the finished episodes stay on disk with their CSV rows, the
    summary and tables of what finished are written (figures are not) and the outcome says
    ``interrupted``. With ``config.resume`` the finished episodes of the run in
    ``config.out`` are kept and only the others run. ``log`` receives one-line warnings
    (a missing plotting library, a dropped unfinished CSV line). ``progress``: a progress
    bar of episodes on stderr.
    """
    log = log or (lambda line: print(f"srpb-gym: {line}", file=sys.stderr))
    out = config.out
    if config.resume:
        resolved = resolved_config(config)
        outdir.check_resumable(config, resolved, versions())
        done, tasks = outdir.finished_episodes(config, log)
        remove_unfinished(config, tasks)  # files a killed run may have left
        if not tasks:
            log(f"note: every episode of the run in {out} is finished: nothing to run; "
                "its tables are made again")  # fmt: skip
        files = [os.path.join(out, name) for name in outdir.RUN_FILES]
        with open(files[1], "a", encoding="utf-8") as f:
            f.write(shlex.join(["srpb-gym", *config.argv]) + "\n")
    else:
        files, resolved = write_run_info(config)
        done, tasks = [], tasks_of(config)
    results: list[EpisodeResult] = list(done)
    writer = stats.EpisodeWriter(os.path.join(out, "episodes.csv"), done, config.robots > 1)
    bar = _progress(len(tasks), config.robots) if progress else _NoBar()
    try:
        interrupted = run_tasks(config, tasks, lambda r: _record(r, results, writer, bar))
    finally:
        writer.close()
        bar.close()
    order = {(t.env, config.planners[t.planner].name, t.seed): i
             for i, t in enumerate(tasks_of(config))}  # fmt: skip
    results.sort(key=lambda r: (order[(r.env, r.planner, r.seed)], r.robot or 0))
    stats.write_episodes(writer.path, results, config.robots > 1)
    outcome = RunOutcome(config, results, interrupted, files=[*files, writer.path])
    outcome.files += _write_summary(outcome)
    if not interrupted and results:
        outcome.files += draw_figures(config, resolved, results, log)
    return outcome


def _record(result: EpisodeResult, results: list, writer: stats.EpisodeWriter, bar: Any) -> None:
    results.append(result)
    writer.write(result)
    bar.set_postfix_str(f"{result.env} {result.planner}", refresh=False)
    if result.robot is None or result.robot == 0:  # an episode, once for all its robots
        bar.update(1)


def _progress(total: int, robots: int = 1) -> Any:
    """A tqdm bar on stderr (a silent stand-in without tqdm)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return _NoBar()
    desc = "eval" if robots == 1 else f"eval ({robots} robots)"
    return tqdm(total=total, file=sys.stderr, unit="episode", desc=desc, dynamic_ncols=True)


class _NoBar:
    def set_postfix_str(self, *args: Any, **kwargs: Any) -> None: ...
    def update(self, n: int = 1) -> None: ...
    def close(self) -> None: ...


def _write_summary(outcome: RunOutcome) -> list[str]:
    """``summary.json`` and the tables of the finished episodes."""
    config, out = outcome.config, outcome.config.out
    summary = stats.summarize(outcome.results)
    doc = {"interrupted": outcome.interrupted, "episodes_planned": outcome.planned,
           "episodes_finished": outcome.finished, "semantics": config.semantics,
           "preset": config.preset, "statistics": stats.STATISTICS,
           "results": summary}  # fmt: skip
    if config.robots > 1:
        doc = {"robots": config.robots, **doc}
    path = os.path.join(out, "summary.json")
    write_json(path, doc)
    comparisons = paired.paired_comparisons(outcome.results)
    outcome.text = "\n\n".join(t for t in (stats.tables_text(summary),
                                            paired.paired_text(comparisons)) if t)  # fmt: skip
    return [path, *stats.write_tables(summary, out), *paired.write_paired(comparisons, out)]


def write_run_info(config: EvalConfig) -> tuple[list[str], dict[str, Any]]:
    """``config.json``, ``command.txt`` and ``versions.json``; returns their paths and the
    resolved configuration."""
    paths = [os.path.join(config.out, n) for n in ("config.json", "command.txt", "versions.json")]
    resolved = resolved_config(config)
    write_json(paths[0], resolved)
    with open(paths[1], "w", encoding="utf-8") as f:
        f.write(shlex.join(["srpb-gym", *config.argv]) + "\n")
    write_json(paths[2], versions())
    return paths, resolved


def resolved_config(config: EvalConfig) -> dict[str, Any]:
    """Everything that defines the run, as plain data."""
    import gymnasium as gym

    envs = []
    for env_id in config.envs:
        env = config.make_env(env_id)
        base, spec = env.unwrapped, gym.spec(config.gym_id(env_id))
        entry: dict[str, Any] = {"id": env_id, "scenario": base.scenario.name}
        params: dict[str, Any] = base.params.as_dict()
        if hasattr(base, "params_of"):  # SRPB-Mix-v0: every scenario it draws, and its weight
            entry = {"id": env_id, "scenarios": dict(zip(base.scenarios, base.weights))}
            params = {name: base.params_of(name).as_dict() for name in base.scenarios}
        if config.scenario_file(env_id) is not None:
            entry |= {"gym_id": spec.id, "scenario_file": config.scenario_file(env_id)}
        kwargs = {**spec.kwargs, **config.env_kwargs(env_id)}
        if config.robots > 1:
            entry["env"] = "srpb_gym.parallel_env"
            kwargs["n_robots"] = config.robots
        envs.append(entry | {"kwargs": kwargs,
                             "max_episode_steps": spec.max_episode_steps,
                             "metric_params": params})  # fmt: skip
        env.close()
    return {
        "envs": envs,
        "planners": [spec.describe() for spec in config.planners],
        "episodes": config.episodes,
        "seed": config.seed,
        "seeds": config.seeds,
        "semantics": config.semantics,
        "preset": config.preset,
        "workers": config.workers,
        "backend": config.backend,
        "address": config.address,
        "warmup": {"steps": config.warmup, "seed": config.warmup_seed},
        "video": config.video,
        "video_stride": config.video_stride,
        "robots": config.robots,
        "env_kwargs": dict(config.make_kwargs),
        "out": config.out,
        "record_dirs": "episodes/<env id>/<planner>/",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "notes": list(config.notes),
    }


def cpu() -> dict[str, str]:
    """The processor figures are computed on: ``cpu``, its model name (``/proc/cpuinfo``
    where there is one, else what :mod:`platform` says), ``torch_cpu_capability``, the
    vector instructions torch's kernels use (when torch is loaded), and ``MKL_CBWR`` when it
    is set. A learned policy's actions may differ in their last bits between these, and its
    episodes then drift apart (docs/evaluation.md, reproducibility across machines)."""
    name = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            name = next((line.split(":", 1)[1].strip() for line in f
                         if line.startswith("model name")), name)  # fmt: skip
    except OSError:
        pass
    out = {"cpu": name}
    torch = sys.modules.get("torch")
    if torch is not None:
        out["torch_cpu_capability"] = str(torch.backends.cpu.get_cpu_capability())
    if os.environ.get("MKL_CBWR"):
        out["MKL_CBWR"] = os.environ["MKL_CBWR"]
    return out


def versions() -> dict[str, str]:
    """Python, the platform, the installed version of each package of :data:`VERSIONED`
    and the processor (:func:`cpu`)."""
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for key, dist in VERSIONED:
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            if key == "srpb-gym":
                out[key] = __version__
    return out | cpu()


def draw_figures(
    config: EvalConfig, resolved: dict[str, Any], results: Sequence[EpisodeResult], log: Callable
) -> list[str]:
    """Trajectory plots per (env, planner) and a bar chart per env (``resolved``: the
    resolved configuration); skipped with a warning when matplotlib is missing."""
    try:
        figures.pyplot()
    except ImportError as exc:
        log(f"warning: {exc}; no figures written")
        return []
    envs = {e["id"]: e for e in resolved["envs"]}
    paths = []
    for env_id, planners in stats.group(results).items():
        mix = "scenarios" in envs[env_id]
        for planner, all_rows in planners.items():
            by_scenario = {"": all_rows}
            if mix:  # a plot per scenario drawn, over its walls
                by_scenario = {}
                for r in all_rows:
                    by_scenario.setdefault(r.scenario, []).append(r)
            for scenario, rows in by_scenario.items():
                label = f"{env_id}_{planner}_{scenario}" if mix else f"{env_id}_{planner}"
                path = os.path.join(config.out, f"trajectories_{label}.png")
                count = f"{len(rows)} episodes"
                if config.robots > 1:
                    count = f"{len({r.seed for r in rows})} episodes, {config.robots} robots"
                what = f"{env_id} ({scenario})" if mix else env_id
                _trajectories(config, envs[env_id], rows, f"{what}: {planner} ({count})", path,
                              scenario or None)  # fmt: skip
                paths.append(path)
        summary = stats.summarize([r for rows in planners.values() for r in rows])[env_id]
        path = os.path.join(config.out, f"bars_{env_id}.png")
        figures.bar_chart(summary, f"{env_id}: {BARS}", path, stats.PEOPLE_METRICS)
        paths.append(path)
    return paths


def _trajectories(
    config: EvalConfig, env: dict, rows: list, title: str, path: str, scenario: str | None = None
) -> None:
    records = [load_record(os.path.join(config.out, r.record)) for r in rows]
    walls = load_scenario(scenario or env.get("scenario_file") or env["scenario"]).walls
    params = env["metric_params"][scenario] if scenario else env["metric_params"]
    people = [not r.robot for r in rows]  # an episode's people once: as robot 0 saw them
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SRPBMetricWarning)
        figures.trajectory_plot(records, walls, title, path, MetricParams(**params),
                                config.semantics, people)  # fmt: skip
