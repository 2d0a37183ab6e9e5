"""Package a multi-robot run (``training.multi_robot``) as a shipped model.

    python -m training.ship_multi runs/ppo-multi --name ppo-crowd-srpb-3robots

Copies the run's model (``model.zip`` and ``vecnormalize.npz``) into
``srpb_gym/models/<name>/``: the checkpoint that ``training.select_checkpoint`` chose on
checkpoint-selection seeds when the run has its ``selection.json``, else (or with
``--final``) the run's final model. It evaluates the model once with the ``srpb-gym eval
--robots N`` harness on ``--episodes`` test seeds from ``--seed`` (200 from 20,000,000 by
default: :data:`srpb_gym.seeds.TEST`), every robot driven by the one shared policy,
beside the classical planners of ``--baselines`` (``dwa`` and ``social-dwa`` by default:
N robots each, on the same episodes), and writes ``card.json`` and ``card.md``: what the
model was trained on and how, which checkpoint and why (the selection's table), and per
planner the success, collision and timeout rates over every robot with 95 % Wilson
intervals, the robots that hit another robot, each robot's success, and the median SRPB
metrics from the true people and from the tracked ones. The card names the
``srpb-gym eval`` command that reproduces its figures.

``--workers N`` spreads the episodes over N processes; ``--resume`` continues a test
evaluation that was interrupted (Ctrl-C keeps its finished episodes in ``RUN/test``).
``--candidates N`` (default 1) states on the card how many runs were trained for this
slot and tested on the test seeds, and ``--side-by-side N`` that the run trained beside
N-1 others on the same cores (its wall time then not that of a run alone).

``--name`` must have the form ``ppo-<scenario>-<preset>-<N>robots`` (:func:`check_name`),
N the run's robots: the folder of that name in ``srpb_gym/models`` is replaced, and
nothing outside it.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from srpb_gym.evaluation.harness import cpu, run_evaluation
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.evaluation.multi import robot_hits, success_by_robot
from srpb_gym.evaluation.spec import resolve_config
from srpb_gym.registration import ENV_IDS, SCENARIO_IDS
from srpb_gym.reward_terms import preset_names
from srpb_gym.training.callbacks import CHOOSE_BY
from srpb_gym.training.checks import reward_weights
from srpb_gym.training.run_folder import FINAL, chosen_model, read_selection
from srpb_gym.training.targets import eval_command, eval_setup
from training.ship import (
    MODELS_DIR,
    TEST_EPISODES,
    TEST_SEED,
    TEST_WARMUP,
    _cpu_text,
    _flow,
    _observation_text,
    _range_name,
    _relative,
    _weights_text,
    side_by_side_text,
)

#: the classical planners a multi-robot model is tested beside, N robots each
BASELINES = ("dwa", "social-dwa")
#: the metrics of the card's table (medians over the robots' episodes)
METRICS = ("m_psi", "m_fsi", "m_dir", "m_mef")


def check_name(name: str, robots: int) -> Path:
    """The folder of the shipped model ``name`` in :data:`~training.ship.MODELS_DIR`; a
    ``ValueError`` unless ``name`` is ``ppo-<scenario>-<preset>-<robots>robots``."""
    pattern = (f"ppo-({'|'.join(SCENARIO_IDS.values())})-({'|'.join(preset_names())})-"
               f"{robots}robots")  # fmt: skip
    if not isinstance(name, str) or not re.fullmatch(pattern, name):
        raise ValueError(f"--name: {name!r} is not a multi-robot model's name: ppo-<scenario>-"
                         f"<preset>-{robots}robots (the run's {robots} robots)")  # fmt: skip
    return MODELS_DIR / name


def summarize(rows: Sequence[Any]) -> dict[str, Any]:
    """The figures of one planner's robot episodes (:class:`EpisodeResult` rows)."""
    n = len(rows)
    hit_robot = robot_hits(rows)
    caused = sum(r.first_collision is not None and r.first_collision.by == "robot" for r in rows)
    out: dict[str, Any] = {"episodes": n, "robots": len({r.robot for r in rows})}
    for key, count in (("success", sum(r.is_success for r in rows)),
                       ("collision", sum(r.collision for r in rows)),
                       ("timeout", sum(r.timeout for r in rows)),
                       ("robot_collision", hit_robot), ("caused_collision", caused)):  # fmt: skip
        interval = wilson(count, n)
        out[key] = count / n
        out[f"{key}_ci"] = [interval[0] / 100, interval[1] / 100] if interval else None
    out["success_by_robot"] = success_by_robot(rows)
    for gt, prefix in ((True, "gt_"), (False, "")):
        for m in METRICS:
            values = [r.value(m, gt) for r in rows]
            values = [v for v in values if math.isfinite(v)]
            out[prefix + m] = float(np.median(values)) if values else math.nan
    return out


def evaluate(run: Path, name: str, robots: int, env_id: str, env_kwargs: dict[str, Any],
             episodes: int, seed: int, baselines: Sequence[str], workers: int,
             resume: bool = False,
             model: Path | None = None) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The figures, by planner (the model as ``name``), of the model in ``model`` (by
    default ``run``) and ``baselines`` on the same ``episodes`` seeds from ``seed``, N
    robots each, evaluated into ``run/test`` (with ``resume``, an interrupted evaluation
    there continues)."""
    work = run / "test"
    resume = resume and (work / "config.json").is_file()
    if not resume:
        shutil.rmtree(work, ignore_errors=True)
    config = resolve_config([env_id], planners=list(baselines), policies=[str(model or run)],
                            episodes=episodes, seed=seed, out=str(work), workers=workers,
                            warmup=TEST_WARMUP, robots=robots, env_kwargs=env_kwargs,
                            resume=resume, log=None)  # fmt: skip
    results = run_evaluation(config, log=lambda line: None).results
    by_planner: dict[str, list[Any]] = {}
    for r in results:
        by_planner.setdefault(name if r.planner not in baselines else r.planner, []).append(r)
    return {planner: summarize(rows) for planner, rows in by_planner.items()}


def run_environment(info: dict[str, Any]) -> tuple[str, dict[str, Any], list[str], dict[str, Any]]:
    """The environment of a multi-robot run (its ``run.json`` facts ``info``): its id, the
    env kwargs it trained with (its reward preset among them), and the environment ids and
    env kwargs it is evaluated with (those of training only left out,
    :func:`srpb_gym.training.targets.eval_setup`)."""
    env_id = ENV_IDS[info["scenario"]]
    env_kwargs = {"reward": info["reward"], **info.get("env_kwargs", {})}
    env_ids, eval_kwargs = eval_setup(env_id, env_kwargs)
    return env_id, env_kwargs, env_ids, eval_kwargs


def test_command(name: str, test: dict[str, Any]) -> str:
    """The ``srpb-gym eval`` command that reproduces the card's test figures."""
    command = eval_command(test["envs"], test["env_kwargs"], name,
                           episodes=test["episodes"], seed=test["seed"],
                           warmup=test["warmup"], robots=test["robots"])  # fmt: skip
    return command + (" --planner " + " ".join(test["baselines"]) if test["baselines"] else "")


def ship(run: Path, name: str, episodes: int = TEST_EPISODES, seed: int = TEST_SEED,
         baselines: Sequence[str] = BASELINES, workers: int = 1,
         resume: bool = False, candidates: int = 1,
         side_by_side: int = 1, final: bool = False) -> dict[str, Any]:  # fmt: skip
    """Package ``run`` as model ``name`` (see the module docstring); returns the card.
    ``resume``: continue the interrupted test evaluation in ``run/test``; ``candidates``:
    the runs trained for this slot and tested on the test seeds; ``side_by_side``: the
    runs that trained at once on the machine's cores; ``final``: ship the final model
    even when the run has a selection."""
    for key, value in (("candidates", candidates), ("side_by_side", side_by_side)):
        if value < 1:
            raise ValueError(f"{key}: at least 1 (the run shipped), got {value}")
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    robots = int(info["robots"])
    target = check_name(name, robots)
    env_id, env_kwargs, env_ids, eval_kwargs = run_environment(info)
    selection = None if final else read_selection(run)
    model = chosen_model(run, selection)
    results = evaluate(run, name, robots, env_ids[0], eval_kwargs, episodes, seed, baselines,
                       workers, resume, model)  # fmt: skip
    shutil.rmtree(target, ignore_errors=True)  # nothing of an earlier model stays
    target.mkdir(parents=True)
    for file in ("model.zip", "vecnormalize.npz"):
        shutil.copyfile(model / file, target / file)
    init = info.get("init")
    if init:
        init = {**init, "model": _relative(init["model"]),
                "vecnormalize": init["vecnormalize"] and _relative(init["vecnormalize"]),
                "run": first_stage(Path(init["model"]))}  # fmt: skip
    card = {
        "name": name, "algo": "PPO", "env": env_id, "reward": info["reward"], "robots": robots,
        "env_kwargs": env_kwargs, "seed": info["seed"],
        "reward_weights": reward_weights(env_id, info["reward"], env_kwargs),
        "checkpoint": selection["chosen"] if selection else FINAL, "selection": selection,
        "validation": None, "hyperparams": info["hyperparams"],
        "training": {"steps": _steps(selection, info), "run_steps": info["steps"],
                     "wall_time_s": info["wall_time_s"],
                     "envs": info["envs"], "machine": cpu(), "command": info["command"],
                     "side_by_side": side_by_side, "init": init},
        "test": {"episodes": episodes, "seed": seed, "seed_range": _range_name(seed, episodes),
                 "robots": robots, "envs": env_ids, "env_kwargs": eval_kwargs,
                 "warmup": TEST_WARMUP, "baselines": list(baselines), "results": results,
                 "candidates": candidates,
                 "machine": cpu()},
    }  # fmt: skip
    card["test"]["command"] = test_command(name, card["test"])
    (target / "card.json").write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
    (target / "card.md").write_text(card_markdown(name, card), encoding="utf-8")
    return card


def first_stage(model: Path) -> dict[str, Any] | None:
    """The ``srpb-gym train`` run that the initial model ``model`` comes from (its
    ``best/`` checkpoint or its final model): its command, steps, wall time and the model
    it started from; ``None`` when ``model`` lies in no such run (a shipped model)."""
    for folder in (model.parent, model.parent.parent):
        if (folder / "run.json").is_file() and (folder / "command.txt").is_file():
            info = json.loads((folder / "run.json").read_text(encoding="utf-8"))
            init = info.get("init") or {}
            return {"command": (folder / "command.txt").read_text(encoding="utf-8").strip(),
                    "steps": info.get("steps"), "wall_time_s": info.get("wall_time_s"),
                    "init": init.get("model") and _relative(init["model"])}  # fmt: skip
    return None


def _start_text(init: dict[str, Any] | None) -> str:
    """The card's line on the initial weights: a model, and the run it comes from."""
    if not init:
        return "random"
    text = f"the trained model `{init['model']}` after {init['steps']:,} steps"
    run = init.get("run")
    if run:
        text += (
            f", of the run `{run['command']}` ({run['steps']:,} steps in "
            f"{run['wall_time_s'] / 60:.1f} min, from `{run['init'] or 'random weights'}`)"
        )
    return text


def _steps(selection: dict[str, Any] | None, info: dict[str, Any]) -> int:
    """The robot-steps the shipped model trained for: its checkpoint's, or the run's."""
    if selection is None:
        return int(info["steps"])
    return int(selection["candidates"][selection["chosen"]]["steps"])


def _checkpoint_text(card: dict[str, Any]) -> str:
    """The card's line on the checkpoint shipped, and how it was chosen."""
    selection = card.get("selection")
    if not selection:
        return str(card["checkpoint"])
    last = selection["seed"] + selection["episodes"] - 1
    return (
        f"{card['checkpoint']}, one of {len(selection['candidates'])} candidates, chosen on "
        f"{selection['episodes']} episodes of checkpoint-selection seeds "
        f"{selection['seed']}-{last} by {selection['rule']} (table below)"
    )


def _selection_section(card: dict[str, Any]) -> list[str]:
    """The card's section with the checkpoint selection's table (none without one)."""
    selection = card.get("selection")
    if not selection:
        return []
    return ["", "## Checkpoint selection", "",
            f"`python -m training.select_checkpoint RUN` evaluated the run's checkpoints on "
            f"{selection['episodes']} episodes of {card['robots']} robots from seed "
            f"{selection['seed']}; success in %, GT median over every robot's episode.", "",
            *table_lines(selection)]  # fmt: skip


def _run_steps(training: dict[str, Any]) -> str:
    """`` of the run's N`` when the model shipped is an earlier checkpoint."""
    total = training.get("run_steps")
    return f", of the run's {total:,}" if total and total != training["steps"] else ""


def _percent(f: dict[str, Any], key: str) -> str:
    ci = f.get(f"{key}_ci")
    interval = f" [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}]" if ci else ""
    return f"{100 * f[key]:.1f} %{interval}"


def _candidates(n: int | None, selected: bool = False) -> list[str]:
    """The card's line on the runs tested on the test seeds for this slot (``selected``:
    the model shipped is a checkpoint chosen on checkpoint-selection seeds)."""
    if n is None:  # a card from before the count was kept
        return []
    if n == 1:
        return ["1 candidate run was trained for this slot; the test seeds were used once, "
                "at shipping.", ""]  # fmt: skip
    seeds = "validation and checkpoint-selection seeds" if selected else "validation seeds"
    return [f"{n} candidate runs were trained for this slot and tested on these seeds; the "
            f"one shipped was chosen on {seeds}.", ""]  # fmt: skip


def card_markdown(name: str, card: dict[str, Any]) -> str:
    """The card's text, from its data."""
    t, test = card["training"], card["test"]
    n = card["robots"]
    start = _start_text(t["init"])
    last = test["seed"] + test["episodes"] - 1
    lines = [
        f"# {name}", "",
        f"PPO (stable-baselines3), one policy shared by {n} robots, trained on "
        f"`{card['env']}` with the `{card['reward']}` reward preset. Load it by name; this "
        f"reproduces the test figures below: `{test['command']}`.", "",
        "| fact | value |", "| --- | --- |",
        f"| environment | `{card['env']}`, {n} robots (`srpb_gym.parallel_env`) |",
        f"| reward preset | `{card['reward']}` |",
        f"| reward weights | {_weights_text(card['reward_weights'])} |",
        f"| reward people | `{card['env_kwargs'].get('reward_people', 'tracked')}` |",
        f"| observation | {_observation_text(card['env_kwargs'].get('observation'))} |",
        f"| steps | {t['steps']:,} robot-steps ({t['envs']} environment"
        f"{'s' if t['envs'] > 1 else ''} of {n} robots)"
        f"{_run_steps(t)} |",
        f"| wall time | {t['wall_time_s'] / 60:.1f} min"
        f"{' (the whole run)' if _run_steps(t) else ''}"
        f"{side_by_side_text(t.get('side_by_side', 1))} |",
        f"| initial weights | {start} |",
        f"| seed | {card['seed']} |",
        f"| checkpoint | {_checkpoint_text(card)} |",
        f"| command | `{t['command']}` |",
        "", "Hyperparameters: " + ", ".join(f"`{k}={_flow(v)}`"
                                            for k, v in card["hyperparams"].items()),
        "", f"## Test: {test['episodes']} episodes of {n} robots, seeds {test['seed']}-{last} "
        f"({test['seed_range']} seeds, never trained on or chosen with)", "",
        *_candidates(test.get("candidates"), bool(card.get("selection"))),
        "Rates over every robot's episode, with 95 % Wilson intervals; *hit a robot*: the "
        "robot's first collision was with another robot. Medians of the SRPB metrics (%, "
        "s), `paper` semantics, from the true people (GT) and, after the slash, from the "
        "tracked ones.", "",
        "| planner | success | collision | hit a robot | timeout | success by robot | "
        "m_psi | m_fsi | m_dir |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]  # fmt: skip
    for planner, f in test["results"].items():
        by_robot = " / ".join(f"{100 * s:.0f}" for s in f["success_by_robot"])
        metrics = " | ".join(f"{f['gt_' + m]:.3g} / {f[m]:.3g}" for m in METRICS[:3])
        lines.append(f"| {planner} | {_percent(f, 'success')} | {_percent(f, 'collision')} | "
                     f"{_percent(f, 'robot_collision')} | {_percent(f, 'timeout')} | "
                     f"{by_robot} | {metrics} |")  # fmt: skip
    lines += ["", f"Measured on {_cpu_text(test['machine'])}.", *_selection_section(card)]
    return "\n".join(lines) + "\n"


def table_lines(selection: dict[str, Any]) -> list[str]:
    """The selection as a Markdown table, one row per candidate, the chosen one bold."""
    lines = ["| candidate | robot-steps | success by robot | success | collision | "
             f"GT {CHOOSE_BY.removeprefix('gt_')} |",
             "| --- | ---: | ---: | ---: | ---: | ---: |"]  # fmt: skip
    for name, f in selection["candidates"].items():
        mark = "**" if name == selection["chosen"] else ""
        by_robot = " / ".join(f"{100 * s:.0f}" for s in f["success_by_robot"])
        lines.append(f"| {mark}{name}{mark} | {f['steps']:,} | {by_robot} | "
                     f"{100 * f['success']:.1f} % | {100 * f['collision']:.1f} % | "
                     f"{f[CHOOSE_BY]:.3g} |")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="package a multi-robot run as a shipped model")
    parser.add_argument("run", type=Path, help="the run folder of training.multi_robot")
    parser.add_argument("--name", required=True, help="e.g. ppo-crowd-srpb-3robots")
    parser.add_argument("--episodes", type=int, default=TEST_EPISODES)
    parser.add_argument("--seed", type=int, default=TEST_SEED)
    parser.add_argument("--baselines", nargs="*", default=list(BASELINES), metavar="PLANNER")
    parser.add_argument("--workers", type=int, default=1, metavar="N")
    parser.add_argument(
        "--resume", action="store_true", help="continue an interrupted test evaluation (RUN/test)"
    )
    parser.add_argument("--candidates", type=int, default=1, metavar="N",
                        help="the runs trained for this slot and tested on the test seeds "
                        "(default: 1), stated on the card")  # fmt: skip
    parser.add_argument(
        "--final",
        action="store_true",
        help="ship the final model even when the run has a selection.json",
    )
    parser.add_argument("--side-by-side", type=int, default=1, metavar="N",
                        help="the run trained beside N-1 others on the same machine: the "
                        "card says so")  # fmt: skip
    args = parser.parse_args(argv)
    try:
        if not (args.run / "run.json").is_file():
            raise ValueError(f"{args.run}: no run.json (not a run of training.multi_robot)")
        robots = json.loads((args.run / "run.json").read_text(encoding="utf-8"))["robots"]
        check_name(args.name, robots)
        card = ship(args.run, args.name, args.episodes, args.seed, args.baselines, args.workers,
                    args.resume, args.candidates, args.side_by_side, args.final)  # fmt: skip
    except (ValueError, KeyError) as exc:
        print(f"training.ship_multi: error: {exc}", file=sys.stderr)
        return 2
    print(f"shipped {args.name}: " + ", ".join(
        f"{p} {100 * f['success']:.1f} % success, {100 * f['robot_collision']:.1f} % hit a robot"
        for p, f in card["test"]["results"].items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
