"""Package a trained run as a shipped model: ``srpb_gym/models/<name>/``.

    python -m training.ship runs/train/ppo-crowd-srpb --name ppo-crowd-srpb

Takes the run's best checkpoint (``best/``, the best periodic evaluation; ``--final`` takes
the final model; ``--validate N`` tests both on N validation seeds from
``--validation-seed``, none of which chose best/, and takes the better by the periodic
evaluations' rule: success, then the median ``m_psi`` from the true people,
``callbacks.CHOOSE_BY``; a test seed there is refused), evaluates it once with the
``srpb-gym eval`` harness on ``--episodes`` test seeds from ``--seed`` (200 from
20,000,000 by default: :data:`srpb_gym.seeds.TEST`; each scenario of the mixture for a
model trained on SRPB-Mix-v0; the environments made with the run's env kwargs but those
of training only, see :func:`srpb_gym.training.targets.eval_setup`), and writes
``model.zip``, ``vecnormalize.npz``, ``evaluations.csv`` (the periodic evaluations of
training), ``card.json`` and ``card.md`` (environment id and version, reward preset and
the weights it paid in each scenario, steps, wall time, machine, seed, command,
hyperparameters, the test results, the seed range they were measured on, how many
candidate runs were trained for the slot, ``--candidates``, and the ``srpb-gym eval``
command that reproduces them). ``--workers N`` spreads the evaluations over N processes,
as ``srpb-gym eval --workers`` (the same figures but for the computation times).

``--name`` must be a shipped model's name, ``ppo-<scenario>-<preset>`` (:func:`check_name`):
the folder of that name in ``srpb_gym/models`` is replaced, and nothing outside it. The
statistics are shipped as numbers (``vecnormalize.npz``); a run whose statistics are a
pickle (``vecnormalize.pkl``, from before) is converted only with ``--trust-pickle``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import shutil
import sys
import zipfile
from pathlib import Path
from typing import Any

import yaml

from srpb_gym.errors import InputError
from srpb_gym.evaluation.harness import cpu, run_evaluation
from srpb_gym.evaluation.spec import resolve_config
from srpb_gym.models import (
    VECNORMALIZE,
    VECNORMALIZE_PICKLE,
    convert_vecnormalize,
    settings_text,
    stamp_observation,
)
from srpb_gym.observation import ObservationConfig
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.reward_terms import preset_names
from srpb_gym.seeds import CHECKPOINT_SELECTION, TEST, VALIDATION, check_not_test, range_of
from srpb_gym.training.callbacks import CHOOSE_BY, eval_score, summarize_results
from srpb_gym.training.checks import reward_weights
from srpb_gym.training.targets import eval_command, eval_setup

MODELS_DIR = Path(__file__).resolve().parents[1] / "srpb_gym" / "models"
#: the test seeds (:data:`srpb_gym.seeds.TEST`), used once per shipped model, at shipping
TEST_SEED, TEST_EPISODES = TEST.start, 200
#: the first validation seed (:data:`srpb_gym.seeds.VALIDATION`): apart from the periodic
#: evaluations' seeds, which chose best/, the demonstrations of a warm start and the test
#: seeds
VALIDATION_SEED = VALIDATION.start
#: the warm-up of the test evaluation (none), which the card's command repeats
TEST_WARMUP = 0
#: the scenarios a shipped model's name may name: the packaged ones and the mixture
NAME_SCENARIOS = (*SCENARIO_IDS.values(), "mix")


def check_name(name: str) -> Path:
    """The folder of the shipped model ``name`` in :data:`MODELS_DIR`; a ``ValueError``
    unless ``name`` has the shipped form ``ppo-<scenario>-<preset>`` (a packaged scenario
    or ``mix``, a reward preset), so that no other folder is ever replaced."""
    pattern = f"ppo-({'|'.join(NAME_SCENARIOS)})-({'|'.join(preset_names())})"
    if not isinstance(name, str) or not re.fullmatch(pattern, name):
        raise ValueError(f"--name: {name!r} is not a shipped model's name: ppo-<scenario>-"
                         f"<preset>, the scenario one of {', '.join(NAME_SCENARIOS)}, the "
                         f"preset one of {', '.join(preset_names())}")  # fmt: skip
    target = MODELS_DIR / name
    if target.resolve().parent != MODELS_DIR.resolve():
        raise ValueError(f"--name: {MODELS_DIR / name} lies outside {MODELS_DIR}")
    return target


def evaluate(model: Path, env_ids: list[str], episodes: int, seed: int, out: Path,
             env_kwargs: dict[str, Any] | None = None, workers: int = 1,
             trust_pickle: bool = False) -> dict:  # fmt: skip
    """Test figures by env id of ``model`` (its statistics beside it), the environments
    made with ``env_kwargs``, the episodes spread over ``workers`` processes (the same
    figures but for the computation times ``m_cef`` and ``m_cre``); ``trust_pickle``: a
    pickled statistics file is read."""
    config = resolve_config(env_ids, policies=[str(model)], episodes=episodes, seed=seed,
                            out=str(out), warmup=TEST_WARMUP, workers=workers, log=None,
                            env_kwargs=env_kwargs, trust_pickle=trust_pickle)  # fmt: skip
    outcome = run_evaluation(config, log=lambda line: None)
    return with_caused(summarize_results(outcome.results), outcome.results)


def with_caused(summary: dict[str, dict[str, float]], results: list[Any]) -> dict:
    """``summary`` (:func:`summarize_results`, by env id: the medians of the metrics from
    the tracked and from the true people) with, for each env, the rate of collisions the
    robot caused (``caused_collision``: its first collision attributed to it)."""
    for env_id, figures in summary.items():
        rows = [r for r in results if r.env == env_id]
        caused = [r.first_collision is not None and r.first_collision.by == "robot"
                  for r in rows]  # fmt: skip
        figures["caused_collision"] = sum(caused) / len(rows) if rows else math.nan
    return summary


def test_command(name: str, test: dict[str, Any]) -> str:
    """The ``srpb-gym eval`` command that reproduces a card's test figures (``test``: its
    ``test`` entry): the shipped model by name, on the same environments, with the same
    env kwargs, episodes, first seed and warm-up."""
    return eval_command(test["envs"], test.get("env_kwargs") or {}, name,
                        episodes=test["episodes"], seed=test["seed"],
                        warmup=test.get("warmup", TEST_WARMUP))  # fmt: skip


def _load_line(name: str, card: dict[str, Any]) -> str:
    """How to load the model by name: for a card of the seed protocol, the command that
    reproduces its test figures; a card shipped before names 5 episodes of one scenario."""
    test = card["test"]
    if "seed_range" not in test:
        return f"Load it by name: `srpb-gym eval --env {test['envs'][0]} --policy {name}`."
    return f"Load it by name; this reproduces the test figures below: `{test_command(name, test)}`."


def _test_heading(test: dict[str, Any]) -> list[str]:
    """The heading of a card's test figures, and for a card of the seed protocol the seeds
    and the candidate runs behind them."""
    if "seed_range" not in test:
        return [f"## Test: {test['episodes']} episodes per scenario, seeds from "
                f"{test['seed']} (never trained on)", ""]  # fmt: skip
    last = test["seed"] + test["episodes"] - 1
    n = test["candidates"]
    runs = "1 candidate run was" if n == 1 else f"{n} candidate runs were"
    return [f"## Test: {test['episodes']} episodes per scenario, seeds {test['seed']}-{last} "
            f"({test['seed_range']} seeds, never trained on or chosen with)", "",
            f"{runs} trained for this slot; the test seeds were used once, at shipping.",
            ""]  # fmt: skip


def card_markdown(name: str, card: dict[str, Any]) -> str:
    t = card["training"]
    lines = [
        f"# {name}", "",
        f"PPO (stable-baselines3) trained on `{card['env']}` with the `{card['reward']}` "
        f"reward preset. {_load_line(name, card)}", "",
        "| fact | value |", "| --- | --- |",
        f"| environment | `{card['env']}` |",
        f"| reward preset | `{card['reward']}` |",
        f"| reward weights | {_weights_text(card['reward_weights'])} |",
        f"| observation | {_observation_text(card['env_kwargs'].get('observation'))} |",
        f"| steps | {t['steps']:,} |",
        f"| wall time | {_wall_time(t)} |",
        f"| initial weights | {_start(t)} |",
        f"| machine | {t['machine']['cpu_count']} cores ({t['machine']['processor']}), "
        f"{t['machine']['system']}, torch threads {t['machine']['torch_threads']} |",
        f"| seed | {card['seed']} |",
        f"| checkpoint | {card['checkpoint']}{_validation(card.get('validation'))} |",
        f"| command | `{t['command']}` |",
        f"| versions | {', '.join(f'{k} {v}' for k, v in t['versions'].items())} |",
        *(["", card["note"]] if card.get("note") else []),
        "", "Hyperparameters: " + ", ".join(f"`{k}={_flow(v)}`"
                                            for k, v in card["hyperparams"].items()),
        "", *_test_heading(card["test"]),
    ]  # fmt: skip
    results = card["test"]["results"]
    if all("gt_m_psi" in f for f in results.values()):
        lines += _truth_table(results)
        whose = ("from the true people (GT) and, after the slash, from the tracked ones; "
                 "*robot's*: the collisions the robot caused")  # fmt: skip
    else:  # a card shipped before the ground truth was kept
        lines += ["| scenario | success | collision | timeout | m_psi | m_fsi | m_dir | m_mef |",
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]  # fmt: skip
        for env_id, f in results.items():
            lines.append(f"| {env_id} | {100 * f['success']:.0f}% | "
                         f"{100 * f['collision']:.0f}% | {100 * f['timeout']:.0f}% | "
                         f"{f['m_psi']:.3g} | {f['m_fsi']:.3g} | {f['m_dir']:.3g} | "
                         f"{f['m_mef']:.3g} |")  # fmt: skip
        whose = "from the tracked people"
    lines += ["", f"Medians of the SRPB metrics (%, s), `paper` semantics, {whose}. "
              "Training curves: `evaluations.csv` (periodic evaluations, "
              f"{card['hyperparams']['eval_episodes']} episodes each on seeds from "
              f"{CHECKPOINT_SELECTION.start})."]  # fmt: skip
    if card["test"].get("machine"):
        lines += ["", f"Measured on {_cpu_text(card['test']['machine'])}; on another "
                  "processor the figures may differ a little (docs/evaluation.md, "
                  "reproducibility across machines)."]  # fmt: skip
    return "\n".join(lines) + "\n"


def _truth_table(results: dict[str, dict[str, float]]) -> list[str]:
    """The rows of a card's test figures with the ground truth beside the tracked."""
    lines = ["| scenario | success | collision (robot's) | timeout | m_psi GT / tracked | "
             "m_fsi GT / tracked | m_dir GT / tracked | m_mef |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]  # fmt: skip
    for env_id, f in results.items():
        pairs = " | ".join(f"{f['gt_' + m]:.3g} / {f[m]:.3g}" for m in ("m_psi", "m_fsi", "m_dir"))
        lines.append(f"| {env_id} | {100 * f['success']:.1f}% | {100 * f['collision']:.1f}% "
                     f"({100 * f['caused_collision']:.1f}%) | {100 * f['timeout']:.1f}% | "
                     f"{pairs} | {f['m_mef']:.3g} |")  # fmt: skip
    return lines


def _cpu_text(machine: dict[str, str]) -> str:
    """The processor of a card's test figures, as :func:`~srpb_gym.evaluation.harness.cpu`
    recorded it."""
    words = [machine["cpu"]]
    if "torch_cpu_capability" in machine:
        words.append(f"torch kernels {machine['torch_cpu_capability']}")
    if "MKL_CBWR" in machine:
        words.append(f"MKL_CBWR={machine['MKL_CBWR']}")
    return ", ".join(words)


def _observation_text(spec: Any) -> str:
    """The observation settings of a card's env kwargs, those that differ from the
    defaults named, and how the model uses them."""
    config = ObservationConfig.from_spec(spec)
    changed = settings_text(config, ObservationConfig())
    which = "the defaults" if changed == "{}" else f"`{changed}`, the rest the defaults"
    return f"{which}; the model observes with them wherever it runs"


def _trained_weights(config: dict[str, Any]) -> dict[str, dict[str, float]]:
    """The reward weights of each scenario that the environment of a run's (or a card's)
    ``config`` pays now: its preset, re-weighted by the scenario and by its
    ``reward_weights`` env kwarg."""
    return reward_weights(config["env"], config["reward"], config.get("env_kwargs"))


def _run_weights(run: Path, info: dict[str, Any], config: dict[str, Any]) -> Any:
    """The reward weights the run trained with, as its ``run.json`` records them; a run
    made before they were recorded gets those its environment pays now, said on stderr."""
    if "reward_weights" in info:
        return info["reward_weights"]
    print(
        f"{run / 'run.json'} does not record the reward weights (a run made before they "
        "were): the card lists those its environment pays now",
        file=sys.stderr,
    )
    return _trained_weights(config)


def _weights_text(weights: dict[str, dict[str, float]]) -> str:
    """The weights by scenario, scenarios with the same weights together."""
    groups: dict[str, list[str]] = {}
    for scenario, terms in weights.items():
        text = ", ".join(f"`{term}` {value:g}" for term, value in terms.items())
        groups.setdefault(text, []).append(scenario)
    return "; ".join(f"{', '.join(names)}: {text}" for text, names in groups.items())


def _validation(validation: dict[str, Any] | None) -> str:
    """How the checkpoint was chosen, when it was chosen on validation seeds (by the
    tracked median m_psi on cards from before ``by`` was recorded)."""
    if not validation:
        return ""
    by = validation.get("by", "m_psi")

    def mean(label: str, key: str) -> float:
        values = [f[key] for f in validation["results"][label].values() if math.isfinite(f[key])]
        return sum(values) / len(values) if values else math.nan

    chosen = validation["chosen"]
    other = "final" if chosen == "best" else "best"
    names = {"best": "the best periodic evaluation's checkpoint", "final": "the final model"}
    return (
        f", chosen over {names[other]} on {validation['episodes']} validation seeds "
        f"from {validation['seed']} (mean success {100 * mean(chosen, 'success'):.0f} % "
        f"against {100 * mean(other, 'success'):.0f} %, median m_psi "
        f"{'from ground truth ' if by == 'gt_m_psi' else ''}"
        f"{mean(chosen, by):.3g} % against {mean(other, by):.3g} %)"
    )


def _flow(value: Any) -> str:
    """A hyperparameter as ``--hyperparams`` takes it (a mapping in YAML's flow style)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {v}" for k, v in value.items()) + "}"
    return '""' if value == "" else str(value)  # an empty value is no YAML document


def side_by_side_text(runs: int) -> str:
    """What a card's wall time adds when ``runs`` runs trained at once on the cores."""
    return (f"; {runs} runs side by side on the machine's cores, the time of one run alone "
            "not measured" if runs > 1 else "")  # fmt: skip


def _wall_time(training: dict[str, Any]) -> str:
    ppo = training["wall_time_s"] / 60
    warm = training.get("warm_start")
    stopped = ", stopped by hand (Ctrl-C or SIGTERM)" if training.get("interrupted") else ""
    shared = side_by_side_text(training.get("side_by_side", 1))
    if not warm:
        return f"{ppo:.1f} min{stopped}{shared}"
    pre = warm["wall_time_s"] / 60
    return f"{ppo + pre:.1f} min ({pre:.1f} min warm start, {ppo:.1f} min PPO{stopped}){shared}"


def _init(init: dict[str, Any] | None) -> dict[str, Any] | None:
    """The starting model of a run (as run.json has it), its paths relative."""
    if not init:
        return None
    stats = init["vecnormalize"]
    return {**init, "model": _relative(init["model"]),
            "vecnormalize": stats and _relative(stats)}  # fmt: skip


def _relative(path: str) -> str:
    """``path`` relative to the working directory (the repository) when it is inside it."""
    relative = os.path.relpath(path)
    return path if relative.startswith("..") else relative


def _start(training: dict[str, Any]) -> str:
    init, warm = training.get("init"), training.get("warm_start")
    if init:
        return (
            f"the trained model `{init['model']}` after {init['steps']:,} steps "
            "(see the command); steps and wall time here are this run's own"
        )
    if not warm:
        return "random"
    by_scenario = warm.get("demo_by_scenario")
    if by_scenario:  # a teacher per scenario
        teachers = "; ".join(f"{name}: `{entry['teacher']}`, {entry['episodes']} episodes "
                             f"({100 * entry['success']:.0f} % success)"
                             for name, entry in by_scenario.items())  # fmt: skip
        source = f"of a teacher per scenario ({teachers})"
    else:
        source = f"of `{warm['planner']}`"
    labels = "the teachers" if by_scenario else f"`{warm['planner']}`"
    dagger = "".join(
        f"; DAgger round {i}: the clone drove {r['episodes']} episodes, {r['steps']:,} steps "
        f"({100 * r['success']:.0f} % success), labelled by {labels}"
        for i, r in enumerate(warm.get("dagger", ()), 1)
    )
    return (f"behaviour cloning {source}: {warm['demo_episodes']} episodes, "
            f"{warm['demo_steps']:,} steps ({100 * warm['demo_success']:.0f} % success)"
            f"{dagger}, action MSE {warm['action_mse']:.3f}")  # fmt: skip


def best_step(run: Path) -> int | None:
    """The step of the best periodic evaluation, by the rule that chose ``best/`` (highest
    mean success over the evaluated environments, then lowest mean median m_psi: from the
    true people, or from the tracked ones in a run written before ``evaluations.csv``
    kept the ground truth)."""
    path = run / "evaluations.csv"
    if not path.is_file():
        return None
    rows: dict[int, list[dict[str, str]]] = {}
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        psi = CHOOSE_BY if CHOOSE_BY in (reader.fieldnames or ()) else "m_psi"
        for row in reader:
            rows.setdefault(int(row["step"]), []).append(row)

    def score(step: int) -> tuple[float, float]:
        return eval_score(({"success": float(r["success"]), psi: float(r[psi] or "nan")}
                           for r in rows[step]), psi)  # fmt: skip

    best: int | None = None
    for step in sorted(rows):  # the first of equal scores, as during training
        if best is None or score(step) > score(best):
            best = step
    return best


def same_model(a: Path, b: Path) -> bool:
    """Whether two checkpoint folders hold the same model (every member of the two
    ``model.zip`` archives equal, whatever their time stamps) and the same statistics (byte
    for byte); a folder without a model file holds no model."""
    if not ((a / "model.zip").is_file() and (b / "model.zip").is_file()):
        return False
    try:
        with zipfile.ZipFile(a / "model.zip") as za, zipfile.ZipFile(b / "model.zip") as zb:
            if sorted(za.namelist()) != sorted(zb.namelist()):
                return False
            if any(za.read(name) != zb.read(name) for name in za.namelist()):
                return False
    except zipfile.BadZipFile:  # not a model archive: the bytes decide
        if (a / "model.zip").read_bytes() != (b / "model.zip").read_bytes():
            return False
    for name in (VECNORMALIZE, VECNORMALIZE_PICKLE):
        stats_a, stats_b = a / name, b / name
        if stats_a.is_file() != stats_b.is_file():
            return False
        if stats_a.is_file() and stats_a.read_bytes() != stats_b.read_bytes():
            return False
    return True


def choose(run: Path, env_ids: list[str], episodes: int, env_kwargs: dict[str, Any] | None = None,
           workers: int = 1, seed: int = VALIDATION_SEED, trust_pickle: bool = False,
           ) -> tuple[Path, dict[str, Any]]:  # fmt: skip
    """``best/`` or the final model of ``run``, whichever scores higher
    (:func:`~srpb_gym.training.callbacks.eval_score`: mean success, then the mean of the
    median m_psi from the true people, as the periodic evaluations chose best/)
    on ``episodes`` seeds from ``seed`` (default :data:`VALIDATION_SEED`; a test seed is an
    :class:`~srpb_gym.errors.InputError` naming ``--validation-seed``); ``best/`` on a tie
    (and without a second evaluation when ``best/`` is the final model). Returns the chosen
    folder and the validation figures of both."""
    check_not_test(seed, episodes, "--validation-seed")
    figures: dict[str, Any] = {}
    for label, folder in (("best", run / "best"), ("final", run)):
        work = run / "validation" / label
        shutil.rmtree(work, ignore_errors=True)
        if label == "final" and same_model(run / "best", run):
            figures[label] = figures["best"]
            continue
        figures[label] = evaluate(folder / "model.zip", env_ids, episodes, seed, work,
                                  env_kwargs, workers, trust_pickle)  # fmt: skip
    better = (eval_score(figures["final"].values(), CHOOSE_BY)
              > eval_score(figures["best"].values(), CHOOSE_BY))  # fmt: skip
    return (run if better else run / "best"), {
        "episodes": episodes,
        "seed": seed,
        "chosen": "final" if better else "best",
        "by": CHOOSE_BY,
        "results": figures,
    }


def ship(run: Path, name: str, episodes: int, seed: int, final: bool,
         validate: int = 0, workers: int = 1, candidates: int = 1,
         validation_seed: int = VALIDATION_SEED, trust_pickle: bool = False,
         side_by_side: int = 1) -> dict[str, Any]:  # fmt: skip
    """Package ``run`` as model ``name`` (see the module docstring): its test figures on
    ``episodes`` seeds from ``seed``, computed once, here; ``candidates``: the runs
    trained for this slot, which the card states; ``trust_pickle``: a run whose statistics
    are a pickle is read and its statistics converted; ``side_by_side``: the runs that
    shared the machine while it trained (its wall time is then not that of a run alone),
    which the card states."""
    target = check_name(name)
    if final and validate:
        raise ValueError("final and validate exclude each other")
    if candidates < 1:
        raise ValueError(f"candidates: at least the run shipped, got {candidates}")
    config = yaml.safe_load((run / "config.yaml").read_text(encoding="utf-8"))
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    env_ids, env_kwargs = eval_setup(config["env"], config.get("env_kwargs"))
    has_best = (run / "best" / "model.zip").is_file()
    if not has_best and not final:
        print(f"{run}: no best/ (no periodic evaluation): shipping the final model"
              + (" without validation" if validate else ""), file=sys.stderr)  # fmt: skip
    validation = None
    if validate and has_best:
        checkpoint, validation = choose(run, env_ids, validate, env_kwargs, workers,
                                        validation_seed, trust_pickle)  # fmt: skip
    else:
        checkpoint = run if final or not has_best else run / "best"
    work = run / "test"
    shutil.rmtree(work, ignore_errors=True)
    results = evaluate(checkpoint / "model.zip", env_ids, episodes, seed, work, env_kwargs,
                       workers, trust_pickle)  # fmt: skip
    # a model trained before models carried their observation settings gets them here (a
    # record that disagrees with the run's settings stops the packaging before it starts)
    observation = ObservationConfig.from_spec((env_kwargs or {}).get("observation"))
    stamp_observation(checkpoint / "model.zip", observation)
    shutil.rmtree(target, ignore_errors=True)  # nothing of an earlier model stays
    target.mkdir(parents=True)
    shutil.copyfile(checkpoint / "model.zip", target / "model.zip")
    if (checkpoint / VECNORMALIZE).is_file():  # no statistics without normalize
        shutil.copyfile(checkpoint / VECNORMALIZE, target / VECNORMALIZE)
    elif (checkpoint / VECNORMALIZE_PICKLE).is_file():  # read above: trusted
        convert_vecnormalize(checkpoint / VECNORMALIZE_PICKLE, target / VECNORMALIZE)
    if (run / "evaluations.csv").is_file():
        shutil.copyfile(run / "evaluations.csv", target / "evaluations.csv")
    card = {
        "name": name, "algo": "PPO", "env": config["env"], "reward": config["reward"],
        "env_kwargs": config.get("env_kwargs", {}), "seed": config["seed"],
        "reward_weights": _run_weights(run, info, config),
        "checkpoint": (f"best periodic evaluation (step {best_step(run)})"
                       if checkpoint != run else "final"),
        "validation": validation,
        "hyperparams": config["hyperparams"],
        "training": {"steps": info["steps"], "wall_time_s": info["wall_time_s"],
                     "machine": info["machine"], "versions": info["versions"],
                     "command": (run / "command.txt").read_text(encoding="utf-8").strip(),
                     "time_limit_reached": info.get("time_limit_reached", False),
                     "interrupted": info.get("interrupted", False),
                     "warm_start": info.get("warm_start"), "init": _init(info.get("init")),
                     "side_by_side": side_by_side},
        "test": {"episodes": episodes, "seed": seed, "seed_range": _range_name(seed, episodes),
                 "candidates": candidates, "envs": env_ids, "env_kwargs": env_kwargs,
                 "warmup": TEST_WARMUP, "results": results, "machine": cpu()},
    }  # fmt: skip
    card["test"]["command"] = test_command(name, card["test"])
    (target / "card.json").write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
    (target / "card.md").write_text(card_markdown(name, card), encoding="utf-8")
    return card


def _range_name(seed: int, episodes: int) -> str:
    """The name of the seed range that seeds ``seed`` to ``seed + episodes - 1`` lie in
    (:mod:`srpb_gym.seeds`), or ``"unreserved"``."""
    first, last = range_of(seed), range_of(seed + episodes - 1)
    return first.name if first is not None and first == last else "unreserved"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="package a training run as a shipped model")
    parser.add_argument("run", type=Path, help="the run folder of srpb-gym train")
    parser.add_argument("--name", required=True, help="short name, e.g. ppo-crowd-srpb")
    parser.add_argument("--episodes", type=int, default=TEST_EPISODES)
    parser.add_argument("--seed", type=int, default=TEST_SEED,
                        help=f"first test seed (default {TEST_SEED}: the {TEST.text()})",
                        )  # fmt: skip
    parser.add_argument("--candidates", type=int, metavar="N",
                        help="required: the candidate runs trained for this model's slot "
                        "(every seed, recipe and fine-tune tried), stated on the card")  # fmt: skip
    parser.add_argument("--final", action="store_true", help="ship the final model, not best/")
    parser.add_argument("--validate", type=int, default=0, metavar="N",
                        help="test best/ and the final model on N validation seeds (from "
                        "--validation-seed) and ship the better")  # fmt: skip
    parser.add_argument("--validation-seed", type=int, default=VALIDATION_SEED, metavar="S",
                        help=f"first validation seed (default {VALIDATION_SEED}: the "
                        f"{VALIDATION.text()}; never a test seed)")  # fmt: skip
    parser.add_argument("--workers", type=int, default=1, metavar="N",
                        help="evaluation processes (default: 1; the same figures but for "
                        "the computation times m_cef and m_cre)")  # fmt: skip
    parser.add_argument("--side-by-side", type=int, default=1, metavar="N",
                        help="the run trained beside N-1 others on the same machine: the "
                        "card says so (its wall time is not that of a run alone)")  # fmt: skip
    parser.add_argument("--trust-pickle", action="store_true",
                        help="read a run's pickled statistics (vecnormalize.pkl, from "
                        "before srpb-gym kept them as numbers) and ship them "
                        "converted")  # fmt: skip
    args = parser.parse_args(argv)
    if args.final and args.validate:
        parser.error("--final and --validate exclude each other")
    if args.workers < 1:
        parser.error(f"--workers must be at least 1, got {args.workers}")
    if args.candidates is None:
        parser.error("--candidates N is required: the candidate runs trained for this slot")
    if args.side_by_side < 1:
        parser.error(f"--side-by-side must be at least 1 (the run), got {args.side_by_side}")
    if args.candidates < 1:
        parser.error(f"--candidates must be at least 1 (the run shipped), got {args.candidates}")
    if args.validate:
        try:
            check_not_test(args.validation_seed, args.validate, "--validation-seed")
        except InputError as exc:
            parser.error(str(exc))
    try:
        check_name(args.name)
    except ValueError as exc:
        parser.error(str(exc))
    if _range_name(args.seed, args.episodes) != TEST.name:
        print(f"note: seeds {args.seed}-{args.seed + args.episodes - 1} are not the "
              f"{TEST.text()}: the card names the range they are in",
              file=sys.stderr)  # fmt: skip
    try:
        card = ship(args.run, args.name, args.episodes, args.seed, args.final, args.validate,
                    args.workers, args.candidates, args.validation_seed,
                    args.trust_pickle, args.side_by_side)  # fmt: skip
    except InputError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    for env_id, f in card["test"]["results"].items():
        print(f"{args.name} on {env_id}: success {100 * f['success']:.0f}%, "
              f"collision {100 * f['collision']:.0f}%, m_psi {f['m_psi']:.3g}, "
              f"m_fsi {f['m_fsi']:.3g}")  # fmt: skip
    print(f"wrote {MODELS_DIR / args.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
