"""Controlled comparison of two training recipes that differ in one thing (the reward of
twin models, the people their reward sees): each run's checkpoint evaluated on the same
test episodes, the runs paired by training seed, the effect reported in ground truth.

    python scripts/controlled_comparison.py --env SRPB-Crowd-v0 \\
        --a runs/train/ppo-crowd-task-s0-* runs/train/ppo-crowd-task-s1-* ... \\
        --b runs/train/ppo-crowd-srpb-s0-* runs/train/ppo-crowd-srpb-s1-* ... \\
        --planner dwa social-dwa --episodes 200 --workers 2 --out runs/compare-crowd

``--a`` and ``--b`` name ``srpb-gym train`` run folders, the i-th of each trained with the
same seed, environment and hyperparameters (checked; what else differs is printed). A
shipped model (its name, or its folder in ``srpb_gym/models``) stands for the run it was
packaged from: its card holds the run's settings, and its ``model.zip`` is the checkpoint
its card names (printed where that is not ``--checkpoint``). Each
run's ``best/`` (``--checkpoint final``: its final model) and every ``--planner`` run the
same ``--episodes`` seeds from ``--seed`` (default the test range, 20,000,000:
:data:`srpb_gym.seeds.TEST`) with the ``srpb-gym eval`` harness into ``--out`` (an
interrupted evaluation continues there). Reported, for every run and planner: success
with its Wilson 95 % interval, collisions (those the robot caused), the episodes in which
the robot pushed a walker back more than 1 m (``people_pushed_back``), and the mean and median
of ``m_psi``, ``m_fsi`` and ``m_dir`` from ground truth (tracked beside). For every pair
(one training seed): the success difference (B - A, McNemar) and the relative change of
mean ground-truth ``m_psi`` (Wilcoxon on the episode differences). Pooled over the seeds:
each episode's values averaged over the training seeds of A and of B, then the success
difference in points and the relative change of each ground-truth metric's mean, with
percentile bootstrap 95 % intervals over the episodes (10,000 resamples, default_rng(0))
and the Wilcoxon signed-rank test of the episode differences. ``report.md`` and
``report.json`` in ``--out`` hold the same. ``--env-kwargs`` are environment arguments
for every run and planner (``'crowd={robot_backing_gap: 0.3}'``: people who back away
from a robot only at close range); the runs are evaluated in that environment whatever
they were trained in.

With ``--robots N`` the runs are ``python -m training.multi_robot`` runs (or a shipped
policy for several robots), each policy drives all N robots of an episode, and in place
of ``best/`` each run's checkpoint chosen by ``python -m training.select_checkpoint``
is compared (its ``selection.json``; the final model of a run without one, or with
``--checkpoint final``). The rates of the runs
are over every robot's episode (with ``hit a robot``: first collisions with another robot,
and the success of each robot); the pairs and the pooled effects are over episodes, each
episode's values the mean over its robots (the robots of one episode share it, so their
values are not independent), and a pair's success difference is tested with the Wilcoxon
signed-rank test of the episodes' differences in the share of robots that reached their
goals (McNemar with one robot). The pooled effects add the success of each robot (robot
k's success in an episode, averaged over the training seeds): a reward can serve one
robot's route worse while the success over every robot holds.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from srpb_gym.config import parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.harness import run_evaluation
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.evaluation.multi import robot_hits, success_by_robot
from srpb_gym.evaluation.paired import mcnemar, signed_rank
from srpb_gym.evaluation.spec import resolve_config
from srpb_gym.evaluation.stats import PUSHED_BACK, pushed_back_rate
from srpb_gym.models import model_path
from srpb_gym.registration import ENV_IDS
from srpb_gym.seeds import TEST
from srpb_gym.training.run_folder import chosen_model, read_selection

METRICS = ("m_psi", "m_fsi", "m_dir")
#: the settings of a shipped model's card that its run's config.yaml has, and its checkpoint
CARD_KEYS = ("algo", "env", "reward", "env_kwargs", "seed", "hyperparams", "checkpoint", "robots")
#: the settings of a multi-robot run's run.json that the comparison reads
MULTI_KEYS = ("reward", "env_kwargs", "seed", "hyperparams", "robots", "init")
RESAMPLES = 10_000


def shipped_folder(run: Path) -> Path | None:
    """The folder of the shipped model ``run`` names (its name or its folder), else None."""
    model = None if run.exists() else model_path(str(run))
    if model is not None:
        return model.parent
    if (run / "card.json").is_file() and (run / "model.zip").is_file():
        return run
    return None


def _card(shipped: Path) -> dict[str, Any]:
    """The ``card.json`` of the shipped model in folder ``shipped``."""
    return json.loads((shipped / "card.json").read_text(encoding="utf-8"))


def run_config(run: Path) -> dict[str, Any]:
    """The ``config.yaml`` of a ``srpb-gym train`` run, or the settings on a shipped
    model's card (an error naming the run if neither)."""
    shipped = shipped_folder(run)
    if shipped is not None:
        card = _card(shipped)
        return {key: card[key] for key in CARD_KEYS if key in card}
    multi = run / "run.json"
    if multi.is_file() and not (run / "config.yaml").is_file():
        info = json.loads(multi.read_text(encoding="utf-8"))
        config = {key: info[key] for key in MULTI_KEYS if key in info}
        return {"env": ENV_IDS.get(info.get("scenario"), info.get("scenario")), **config}
    path = run / "config.yaml"
    if not path.is_file():
        raise InputError("no config.yaml: not a srpb-gym train run folder (nor a shipped "
                         "model)", str(run), key="--a/--b")  # fmt: skip
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def checkpoint_of(run: Path, checkpoint: str) -> tuple[str, str | None]:
    """The model of ``run`` to evaluate (``best/`` or the final ``model.zip``; a shipped
    model's folder, which the tables name after it), and a line to print when a shipped
    model's checkpoint is not ``checkpoint``."""
    shipped = shipped_folder(run)
    if shipped is None and (run / "run.json").is_file() and not (run / "best").exists():
        selection = read_selection(run) if checkpoint == "best" else None
        if selection is not None:  # the multi-robot run's choice stands for best/
            return str(chosen_model(run, selection)), None
        note = None
        if checkpoint == "best":
            note = f"{run}: a multi-robot run with no selection.json, its final model"
        return str(run / "model.zip"), note
    if shipped is None:
        return str(run / "best") if checkpoint == "best" else str(run / "model.zip"), None
    chosen = str(_card(shipped).get("checkpoint", ""))
    note = None
    if not chosen.startswith(checkpoint):
        note = f"{run}: the shipped model is its run's {chosen or 'unnamed'} checkpoint"
    return str(shipped), note


def check_pairs(a: list[Path], b: list[Path]) -> list[str]:
    """Refuse pairs of runs that differ in seed, environment or hyperparameters; the other
    settings in which they differ, as lines to print."""
    if len(a) != len(b) or not a:
        raise InputError(f"--a and --b: as many runs each, at least one (got {len(a)} and "
                         f"{len(b)})")  # fmt: skip
    notes = []
    for ra, rb in zip(a, b):
        ca, cb = run_config(ra), run_config(rb)
        for key in ("seed", "env", "hyperparams", "robots"):
            if ca.get(key) != cb.get(key):
                raise InputError(f"{ra} and {rb} differ in {key}: {ca.get(key)!r} against "
                                 f"{cb.get(key)!r}")  # fmt: skip
        differ = sorted(k for k in set(ca) | set(cb) if ca.get(k) != cb.get(k))
        notes.append(f"seed {ca['seed']}: {ra.name} and {rb.name} differ in "
                     f"{', '.join(differ) or 'nothing'}")  # fmt: skip
        for key in differ:
            notes.append(f"  {key}: {ca.get(key)!r} | {cb.get(key)!r}")
    return notes


def values(rows: list[EpisodeResult], metric: str, gt: bool) -> np.ndarray:
    """The metric of every episode, by seed order (NaN where undefined)."""
    if metric == "success":
        return np.array([float(r.is_success) for r in rows])
    return np.array([r.value(metric, gt) for r in rows], dtype=np.float64)


def per_episode(v: np.ndarray, robots: int) -> np.ndarray:
    """Robot-episode values (by seed, then robot) as one value per episode: the mean over
    its robots where defined (NaN where none is)."""
    if robots == 1:
        return v
    v = v.reshape(-1, robots)
    defined = np.isfinite(v)
    count = defined.sum(axis=1)
    total = np.where(defined, v, 0.0).sum(axis=1)
    return np.divide(total, count, out=np.full(count.shape, np.nan), where=count > 0)


def bootstrap(a: np.ndarray, b: np.ndarray, statistic: Any) -> tuple[float, float]:
    """Percentile bootstrap 95 % interval of ``statistic(a, b)`` over resampled pairs."""
    rng = np.random.default_rng(0)
    n = a.size
    out = np.empty(RESAMPLES)
    for k in range(RESAMPLES):
        idx = rng.integers(0, n, n)
        out[k] = statistic(a[idx], b[idx])
    low, high = np.percentile(out, [2.5, 97.5])
    return float(low), float(high)


def success_difference(a: np.ndarray, b: np.ndarray) -> float:
    """mean B - mean A of success indicators, in percentage points."""
    return 100.0 * (b.mean() - a.mean())


def relative_change(a: np.ndarray, b: np.ndarray) -> float:
    """(mean B - mean A) / mean A, in %."""
    return 100.0 * (b.mean() - a.mean()) / a.mean() if a.mean() > 0 else float("nan")


def effect(a: np.ndarray, b: np.ndarray, metric: str) -> dict[str, Any]:
    """B against A over paired episode values (undefined pairs left out): the success
    difference in points or a metric's relative change of the mean, its interval and the
    Wilcoxon p of the differences."""
    both = np.isfinite(a) & np.isfinite(b)
    a, b = a[both], b[both]
    stat = success_difference if metric == "success" else relative_change
    low, high = bootstrap(a, b, stat)
    return {"metric": metric, "n": int(a.size), "a": float(a.mean()), "b": float(b.mean()),
            "effect": float(stat(a, b)), "ci": [low, high], "p": signed_rank(b - a)}  # fmt: skip


def run_row(label: str, rows: list[EpisodeResult], robots: int = 1) -> dict[str, Any]:
    """The figures of one run or planner (rates over every robot's episode)."""
    n = len(rows)
    wins = sum(r.is_success for r in rows)
    low, high = wilson(wins, n) or (float("nan"), float("nan"))
    collided = [r for r in rows if r.collision]
    by_robot = sum(1 for r in collided if r.first_collision and r.first_collision.by == "robot")
    pushed = pushed_back_rate([r.pushed_back for r in rows])  # None: unknown (older csv)
    row = {"label": label, "episodes": n, "success": 100.0 * wins / n, "ci": [low, high],
           "collision": 100.0 * len(collided) / n,
           "robot_caused": 100.0 * by_robot / n,
           "pushed_back": pushed[0] if pushed else None}  # fmt: skip
    if robots > 1:
        row["hit_robot"] = 100.0 * robot_hits(rows) / n
        row["success_by_robot"] = [100.0 * rate for rate in success_by_robot(rows)]
    for metric in METRICS:
        for gt, tag in ((True, "gt"), (False, "tracked")):
            v = values(rows, metric, gt)
            v = v[np.isfinite(v)]
            row[f"{metric}_{tag}_mean"] = float(v.mean()) if v.size else None
            row[f"{metric}_{tag}_median"] = float(np.median(v)) if v.size else None
    return row


def analyse(results: list[EpisodeResult], a: list[str], b: list[str], planners: list[str],
            names: tuple[str, str], robots: int = 1) -> dict[str, Any]:  # fmt: skip
    """Every figure of the report from the evaluated episodes (of ``robots`` robots each)."""
    by: dict[str, list[EpisodeResult]] = {}
    for r in results:
        by.setdefault(r.planner, []).append(r)
    for rows in by.values():
        rows.sort(key=lambda r: (r.seed, -1 if r.robot is None else r.robot))
    keys = [(r.seed, r.robot) for r in by[a[0]]]
    for label in [*a, *b, *planners]:
        if [(r.seed, r.robot) for r in by.get(label, [])] != keys:
            raise InputError(f"{label}: not every episode was evaluated; run again to finish")
    seeds = [seed for seed, _ in keys[::robots]]
    report: dict[str, Any] = {
        "names": list(names),
        "episodes": len(seeds),
        "robots": robots,
        "seeds": [seeds[0], seeds[-1]],
        "runs": [run_row(label, by[label], robots) for label in [*a, *b, *planners]],
    }

    def episode_values(label: str, metric: str) -> np.ndarray:
        return per_episode(values(by[label], metric, metric != "success"), robots)

    pairs = []
    for la, lb in zip(a, b):
        sa, sb = episode_values(la, "success"), episode_values(lb, "success")
        if robots == 1:
            a_only, b_only = int(np.sum((sa == 1) & (sb == 0))), int(np.sum((sa == 0) & (sb == 1)))
            p_success = mcnemar(a_only, b_only)
        else:
            p_success = signed_rank(sb - sa)
        psi = effect(episode_values(la, "m_psi"), episode_values(lb, "m_psi"), "m_psi")
        pairs.append({"a": la, "b": lb, "success": 100.0 * (sb.mean() - sa.mean()),
                      "p_success": p_success, "m_psi_gt": psi})  # fmt: skip
    report["pairs"] = pairs
    pooled = {}
    for metric in ("success", *METRICS):
        ma = np.mean([episode_values(label, metric) for label in a], axis=0)
        mb = np.mean([episode_values(label, metric) for label in b], axis=0)
        pooled[metric] = effect(ma, mb, metric)

    def robot_success(label: str, robot: int) -> np.ndarray:
        return values(by[label], "success", False).reshape(-1, robots)[:, robot]

    for robot in range(robots if robots > 1 else 0):
        ma = np.mean([robot_success(label, robot) for label in a], axis=0)
        mb = np.mean([robot_success(label, robot) for label in b], axis=0)
        pooled[f"success of robot {robot}"] = effect(ma, mb, "success")
    report["pooled"] = pooled
    return report


def run_label(run: Path, model: str) -> str | None:
    """The report's name for a checkpoint a multi-robot run kept: the run folder's name
    and the checkpoint's (``keep-3robots-s1 (step_000200004)``); ``None`` for any other
    model, which keeps the evaluation's label."""
    model_path = Path(model)
    if model_path.parent.name == "checkpoints" and model_path.parent.parent == run:
        return f"{run.name} ({model_path.name})"
    return None


def relabel(report: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    """``report`` with its runs named by ``names`` (evaluation label -> name) where given."""
    for row in report["runs"]:
        row["label"] = names.get(row["label"], row["label"])
    for pair in report["pairs"]:
        pair["a"], pair["b"] = names.get(pair["a"], pair["a"]), names.get(pair["b"], pair["b"])
    return report


def _num(value: float | None, fmt: str = ".3g") -> str:
    return "n/a" if value is None or not np.isfinite(value) else format(value, fmt)


def _signed(value: float, unit: str = "") -> str:
    return "n/a" if not np.isfinite(value) else f"{value:+.1f}{unit}"


def _interval(ci: list[float]) -> str:
    return "n/a" if not all(np.isfinite(ci)) else f"[{ci[0]:+.1f}, {ci[1]:+.1f}]"


def markdown(report: dict[str, Any]) -> str:
    na, nb = report["names"]
    robots = report.get("robots", 1)
    multi = robots > 1
    what = "episodes"
    if multi:
        what = f"episodes of {robots} robots (rates over every robot's episode)"
    extra = " hit a robot | success by robot |" if multi else ""
    lines = [f"{report['episodes']} {what}, seeds {report['seeds'][0]}-{report['seeds'][1]}; "
             "metrics from ground truth (tracked in brackets), mean / median", "",
             f"| run | success | collisions (robot) | pushed back > {PUSHED_BACK:g} m |{extra} "
             "m_psi | m_fsi | m_dir |",
             "| --- | --- | --- | --- |" + " --- |" * (3 + 2 * multi)]  # fmt: skip
    for row in report["runs"]:
        cells = [f"{_num(row[f'{m}_gt_mean'])} / {_num(row[f'{m}_gt_median'])} "
                 f"({_num(row[f'{m}_tracked_median'])})" for m in METRICS]  # fmt: skip
        if multi:
            by_robot = " / ".join(f"{v:.0f}" for v in row["success_by_robot"])
            cells = [f"{row['hit_robot']:.1f} %", by_robot, *cells]
        lines.append(f"| {row['label']} | {row['success']:.1f} % [{row['ci'][0]:.1f}-"
                     f"{row['ci'][1]:.1f}] | {row['collision']:.1f} % ({row['robot_caused']:.1f} "
                     f"%) | {_num(row.get('pushed_back'), '.1f')} % | "
                     f"{' | '.join(cells)} |")  # fmt: skip
    test = "Wilcoxon p" if multi else "McNemar p"
    unit = ", episode values the mean over the robots" if multi else ""
    lines += ["", f"Pairs ({nb} against {na}, one training seed each{unit}):", "",
              f"| pair | success B - A | {test} | mean GT m_psi change | Wilcoxon p |",
              "| --- | --- | --- | --- | --- |"]  # fmt: skip
    for p in report["pairs"]:
        e = p["m_psi_gt"]
        lines.append(f"| {p['b']} vs {p['a']} | {p['success']:+.1f} pt | {p['p_success']:.3g} "
                     f"| {_signed(e['effect'], ' %')} {_interval(e['ci'])} | "
                     f"{_num(e['p'])} |")  # fmt: skip
    lines += ["", f"Pooled over the training seeds ({nb} against {na}, episode values averaged "
              "over the seeds):", "", "| figure | A | B | B against A | 95 % interval | "
              "Wilcoxon p | n |", "| --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    for metric, e in report["pooled"].items():
        if metric.startswith("success"):
            label, scale, unit = metric, 100.0, " pt"
        else:
            label, scale, unit = f"mean GT {metric}", 1.0, " %"
        lines.append(f"| {label} | {_num(scale * e['a'])} | {_num(scale * e['b'])} | "
                     f"{_signed(e['effect'], unit)} | {_interval(e['ci'])} | "
                     f"{_num(e['p'])} | {e['n']} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", required=True, help="environment id")
    parser.add_argument("--a", type=Path, nargs="+", required=True, help="runs of recipe A")
    parser.add_argument("--b", type=Path, nargs="+", required=True, help="runs of recipe B")
    parser.add_argument("--names", nargs=2, default=("A", "B"), help="names of A and B")
    parser.add_argument("--planner", nargs="*", default=[], help="classical planners beside")
    parser.add_argument("--checkpoint", choices=("best", "final"), default="best")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=TEST.start)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--robots", type=int, default=1, help="robots per episode")
    parser.add_argument(
        "--env-kwargs",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="environment arguments of every run and planner, e.g. "
        "'crowd={robot_backing_gap: 0.3}' (as srpb-gym eval --env-kwargs)",
    )
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    try:
        env_kwargs = parse_overrides(args.env_kwargs, "--env-kwargs")
        for line in check_pairs(args.a, args.b):
            print(line)
        models = []
        for run in [*args.a, *args.b]:
            model, note = checkpoint_of(run, args.checkpoint)
            models.append(model)
            if note:
                print(note)
        resume = os.path.isfile(os.path.join(args.out, "episodes.csv"))
        config = resolve_config([args.env], planners=args.planner or None, policies=models,
                                episodes=args.episodes, seed=args.seed, out=args.out,
                                workers=args.workers, warmup=0, resume=resume,
                                robots=args.robots, env_kwargs=env_kwargs)  # fmt: skip
        outcome = run_evaluation(config)
        labels = [spec.name for spec in config.planners if spec.policy is not None]
        n = len(args.a)
        report = analyse(outcome.results, labels[:n], labels[n:], list(args.planner),
                         tuple(args.names), args.robots)  # fmt: skip
        runs = [*args.a, *args.b]
        names = {label: run_label(run, model) for label, run, model in zip(labels, runs, models)}
        relabel(report, {label: name for label, name in names.items() if name})
    except InputError as exc:
        print(f"controlled_comparison: {exc}", file=sys.stderr)
        return 2
    text = markdown(report)
    print(text)
    Path(args.out, "report.md").write_text(text, encoding="utf-8")
    Path(args.out, "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
