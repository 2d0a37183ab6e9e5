"""Choose the model a multi-robot run ships among the checkpoints it kept, on
checkpoint-selection seeds.

    python -m training.multi_robot ... --save-every 200000 --keep-checkpoints --out RUN
    python -m training.select_checkpoint RUN --workers 2
    python -m training.ship_multi RUN --name ppo-crowd-srpb-3robots

A single-robot run chooses ``best/`` by its periodic evaluations; a run of
``training.multi_robot`` has none, and its last model is a draw: robot 2 of the 3-robot
crowd recipe reaches its goal in 27-44 of 50 episodes from one checkpoint to the next,
200,000 robot-steps apart. This script evaluates every ``checkpoints/step_<N>/`` of
``RUN`` and its final model, every robot driven by the one shared policy, on
``--episodes`` episodes (100: a robot's success read on 50 carries a 95 % interval about
20 points wide, wider than most of the gaps between candidates) from ``--seed``
(1,000,000: the checkpoint-selection seeds,
:data:`srpb_gym.seeds.CHECKPOINT_SELECTION`; seeds outside that range are refused), in
the environment the run trained in (:func:`srpb_gym.training.targets.eval_setup`), into
``RUN/selection/`` (an ``srpb-gym eval`` output folder, its episode records removed once
the candidates are scored: about 0.5 GB a candidate), and writes ``RUN/selection.json``:
per candidate, the success of each robot, the success over every robot's episode, the
collisions and the median ``m_psi`` from the true people; and the one chosen by
:func:`score`: the highest success of the least successful robot, then the success over
every robot's episode, then the lower median ``m_psi`` from the true people
(:data:`srpb_gym.training.callbacks.CHOOSE_BY`). The weakest robot comes first because a
shared policy is judged per robot: a policy that serves two robots well and the third
badly is not a good shared policy.

``training.ship_multi`` ships the chosen candidate of ``RUN/selection.json`` and puts the
table on the card. ``--resume`` continues an interrupted evaluation in ``RUN/selection``.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.evaluation.harness import run_evaluation
from srpb_gym.evaluation.spec import resolve_config
from srpb_gym.seeds import CHECKPOINT_SELECTION, check_within
from srpb_gym.training.callbacks import CHOOSE_BY
from srpb_gym.training.run_folder import FINAL, SELECTION_FILE
from training.ship_multi import run_environment, summarize, table_lines

#: the episodes and first seed of the selection (checkpoint-selection seeds)
SELECTION_EPISODES, SELECTION_SEED = 100, CHECKPOINT_SELECTION.start
#: the rule, as the selection file and the card state it
RULE = ("the highest success of the least successful robot, then the success over every "
        f"robot's episode, then the lower median {CHOOSE_BY}")  # fmt: skip


def candidates(run: Path) -> dict[str, Path]:
    """The models of ``run`` to choose from, by name: each kept checkpoint
    (``step_<N>``, in order) and the final model (:data:`FINAL`); an :class:`InputError`
    when the run kept none."""
    kept = sorted(p for p in (run / "checkpoints").glob("step_*") if (p / "model.zip").is_file())
    if not kept:
        raise InputError("no kept checkpoints (checkpoints/step_<N>/): train with "
                         "--save-every N --keep-checkpoints", str(run))  # fmt: skip
    return {**{p.name: p for p in kept}, FINAL: run}


def steps_of(name: str, run_steps: int) -> int:
    """The robot-steps a candidate had trained for (``step_<N>``: N; the final model: the
    run's)."""
    return run_steps if name == FINAL else int(name.removeprefix("step_"))


#: the figures of each candidate in the selection file (:func:`training.ship_multi.summarize`'s)
FIGURES = ("episodes", "success_by_robot", "success", "collision", CHOOSE_BY)


def figures(rows: Sequence[Any]) -> dict[str, Any]:
    """One candidate's figures over its robot episodes (:class:`EpisodeResult` rows):
    those of :data:`FIGURES`, as a shipped multi-robot model's card computes them."""
    summary = summarize(rows)
    return {key: summary[key] for key in FIGURES}


def score(f: dict[str, Any]) -> tuple[float, float, float]:
    """The key the choice maximises (see the module docstring); a missing median counts
    as the worst."""
    psi = f[CHOOSE_BY]
    return (min(f["success_by_robot"]), f["success"], -psi if math.isfinite(psi) else -math.inf)


def select(run: Path, episodes: int = SELECTION_EPISODES, seed: int = SELECTION_SEED,
           workers: int = 1, resume: bool = False) -> dict[str, Any]:  # fmt: skip
    """Evaluate the candidates of ``run`` and write ``run/selection.json``; returns its
    content (see the module docstring)."""
    check_within(CHECKPOINT_SELECTION, seed, episodes, "--seed")
    info_file = run / "run.json"
    if not info_file.is_file():
        raise InputError("no run.json (not a run of training.multi_robot)", str(run))
    info = json.loads(info_file.read_text(encoding="utf-8"))
    models = candidates(run)
    _, _, env_ids, kwargs = run_environment(info)
    work = run / "selection"
    resume = resume and (work / "config.json").is_file()
    if not resume:
        shutil.rmtree(work, ignore_errors=True)
    config = resolve_config(env_ids, planners=[], policies=[str(p) for p in models.values()],
                            episodes=episodes, seed=seed, out=str(work), workers=workers,
                            warmup=0, robots=int(info["robots"]), env_kwargs=kwargs,
                            resume=resume, log=None)  # fmt: skip
    label = dict(zip((spec.name for spec in config.planners), models))
    rows: dict[str, list[Any]] = {name: [] for name in models}
    for r in run_evaluation(config, log=lambda line: None).results:
        rows[label[r.planner]].append(r)
    # the episode records (about 10 MB an episode of 3 robots) choose nothing: episodes.csv
    # keeps every episode's metrics
    shutil.rmtree(work / "episodes", ignore_errors=True)
    table = {name: {"steps": steps_of(name, int(info["steps"])), **figures(rows[name])}
             for name in models}  # fmt: skip
    chosen = max(table, key=lambda name: score(table[name]))
    out = {"run": str(run), "episodes": episodes, "seed": seed, "env": env_ids[0],
           "env_kwargs": kwargs, "robots": int(info["robots"]), "rule": RULE,
           "candidates": table, "chosen": chosen}  # fmt: skip
    (run / SELECTION_FILE).write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a run of training.multi_robot --keep-checkpoints")
    parser.add_argument("--episodes", type=int, default=SELECTION_EPISODES)
    parser.add_argument("--seed", type=int, default=SELECTION_SEED,
                        help=f"the first seed (default {SELECTION_SEED}); "
                        f"{CHECKPOINT_SELECTION.text()} only")  # fmt: skip
    parser.add_argument("--workers", type=int, default=1, metavar="N")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted evaluation (RUN/selection)")  # fmt: skip
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    try:
        selection = select(args.run, args.episodes, args.seed, args.workers, args.resume)
    except InputError as exc:
        print(f"training.select_checkpoint: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(table_lines(selection)))
    print(f"chosen: {selection['chosen']} ({RULE})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
