"""Retrain the shipped models, each beside its controlled twin.

    python -m training.retrain_models                             # every model, seed 0, shipped
    python -m training.retrain_models ppo-crowd-srpb ppo-crowd-task --seeds 0 1 2 --no-ship
    python -m training.retrain_models --dry-run                   # print the commands only

Every scenario has one recipe (:data:`RECIPES`): the environment, a step budget, the warm
start, the observation, the PPO hyperparameters and the weights of the task terms. Its two
models differ in the reward alone: ``ppo-<scenario>-srpb`` pays the ``srpb`` preset (with
the recipe's shaping weights), ``ppo-<scenario>-task`` the ``task`` preset with the same
task-term weights, the collision penalty included, so that the SRPB shaping terms are all
that differs between the twins (same start, budget, observation, hyperparameters and
seeds). A run trains for its step budget, never against a clock; every recipe fits within
an hour on a 2-core machine, warm start included (the model card records the wall time).

Each (model, seed) is one ``srpb-gym train`` run into ``runs/train/<name>-s<seed>-<time>``;
unless ``--no-ship``, the run of the first seed given is then packaged by ``python -m
training.ship``: the better of best/ and the final model on 100 validation seeds, tested
once on 200 test seeds (from 20,000,000: :data:`srpb_gym.seeds.TEST`) into
``srpb_gym/models/<name>/`` with its model card. The other seeds' runs are the controlled
comparison (``scripts/controlled_comparison.py``); no seed is chosen over another. On a 2-core
machine two runs side by side (``--jobs 2``, one torch thread each) finish sooner than one
after the other. ``--jobs`` runs that many (model, seed) runs at once, a run's stages one
after the other; each model is shipped once its runs are done.

The generalist (``mix``) is warm-started from a specialist per scenario
(:attr:`Recipe.teachers`), and the policy shared by 3 robots in crowd
(:data:`MULTI_RECIPES`, ``ppo-crowd-srpb-3robots``) starts from the crowd specialist: those
are retrained first when named too (or when all models are), otherwise the shipped ones
teach. Why each recipe is as it is: docs/notes/.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

from srpb_gym.models import model_names

PRESETS = ("srpb", "task")


@dataclass(frozen=True)
class Recipe:
    """How both models of a scenario are trained.

    ``steps``: the step budget (``--steps``); ``hyperparams``: ``--hyperparams`` beyond
    configs/train/ppo.yaml (the warm start's among them); ``observation``: the
    ``observation`` env kwarg (None: the defaults); ``shaping``: the ``srpb`` model's
    weights beyond its preset (a YAML flow mapping's items, e.g. ``"psi: -2.0"``);
    ``collision``: the collision weight both models pay (the ``srpb`` shaping bound needs
    more than the preset's 25 where the shaping is heavier); ``env_kwargs``: further
    ``gym.make`` arguments; ``teachers``: (scenario, model) pairs of a warm start by
    distillation (``pretrain_teachers``); ``validate``: validation episodes that choose
    between best/ and the final model at shipping; ``reward_people``: whose people the
    reward's social terms see (the env argument of that name): the true people, a
    privileged reward (the observation stays the tracker's), chosen on the validation
    seeds: in ``corridor`` (three training seeds, 200 validation episodes) the ``srpb``
    models rewarded on the true people kept more distance in ground truth than those
    rewarded on the tracked people (mean ``m_psi`` -5.0 % [-6.8, -3.3], Wilcoxon p = 6e-7)
    at 1.3 points less success (timeouts); docs/results.md has the figures."""

    env_id: str
    steps: int
    hyperparams: tuple[str, ...] = ()
    observation: str | None = None
    shaping: str = ""
    collision: float = -25.0
    env_kwargs: tuple[str, ...] = ()
    teachers: tuple[tuple[str, str], ...] = ()
    validate: int = 100
    reward_people: str = "ground_truth"


#: behaviour cloning of a classical planner's demonstrations before PPO
WARM_START = ("pretrain_planner=dwa", "pretrain_episodes=150")
#: social-dwa walks around standing pairs (a clone of dwa walks between their members)
SOCIAL_WARM_START = ("pretrain_planner=social-dwa", "pretrain_episodes=150")
#: one PPO update on 8192 steps (about 15 crowd episodes) instead of 1024
LARGE_ROLLOUT = ("n_envs=8", "n_steps=1024", "batch_size=512")
#: smaller PPO updates (5 epochs, clip range 0.1): fewer drives into people in crowd
SMALL_STEPS = ("n_epochs=5", "clip_range=0.1")
#: a horizon of about 20 s instead of 10, to weigh intrusions further ahead
LONG_HORIZON = ("gamma=0.995",)
#: five times the srpb preset's obs and social weights: with the preset's own weights PPO
#: keeps the task reward's route past the people of corridor and fformation; the shaping
#: bound then needs a collision penalty of 110 (their worst discounted cost is 103.9)
FIVE_TIMES_SOCIAL = "obs: -1.0, psi: -5.0, fsi: -3.0, dir: -1.0"
#: the generalist's teachers: a specialist per scenario
GENERALIST_TEACHERS = (
    ("corridor", "ppo-corridor-srpb"),
    ("fformation", "ppo-fformation-srpb"),
    ("crossing", "ppo-crossing-srpb"),
    ("crowd", "ppo-crowd-task"),
    ("doorway", "ppo-doorway-srpb"),
)

RECIPES: dict[str, Recipe] = {
    "corridor": Recipe(
        "SRPB-Corridor-v0", 600_000, (*WARM_START, *LARGE_ROLLOUT),
        shaping=FIVE_TIMES_SOCIAL, collision=-110.0,
    ),
    "fformation": Recipe(
        "SRPB-FFormation-v0", 1_000_000, (*SOCIAL_WARM_START, *LARGE_ROLLOUT),
        shaping=FIVE_TIMES_SOCIAL, collision=-110.0,
    ),
    "crossing": Recipe(
        "SRPB-Crossing-v0", 1_000_000, ("learning_rate=5e-5", *WARM_START, *LARGE_ROLLOUT),
    ),
    # the O-spaces of standing groups drawn into the lidar (lidar_groups), the lidar
    # log-encoded; twice the preset's psi and five times its fsi weight
    "crowd": Recipe(
        "SRPB-Crowd-v0", 3_000_000,
        ("learning_rate=1e-4", "pretrain_planner=social-dwa", "pretrain_episodes=100",
         *LARGE_ROLLOUT, *SMALL_STEPS, *LONG_HORIZON),
        observation="{lidar_encoding: log, lidar_groups: 0.0001}",
        shaping="psi: -2.0, fsi: -3.0", collision=-120.0,
    ),
    "doorway": Recipe(
        "SRPB-Doorway-v0", 2_000_000, ("learning_rate=1e-4", *WARM_START, *LARGE_ROLLOUT),
    ),
    # crossing and doorway drawn three times and crowd twice as often as the rest
    "mix": Recipe(
        "SRPB-Mix-v0", 2_000_000, ("learning_rate=5e-5", "pretrain_episodes=1000"),
        observation="{lidar_encoding: log}", env_kwargs=("weights=[1, 1, 3, 2, 3]",),
        teachers=GENERALIST_TEACHERS,
    ),
}  # fmt: skip

#: name -> (scenario, reward preset)
MODELS: dict[str, tuple[str, str]] = {
    f"ppo-{scenario}-{preset}": (scenario, preset) for scenario in RECIPES for preset in PRESETS
}


@dataclass(frozen=True)
class MultiRecipe:
    """How a policy shared by several robots is trained (``python -m training.multi_robot``)
    and shipped (``python -m training.ship_multi``): ``robots`` robots in each of ``envs``
    multi-robot environments of ``scenario``, ``steps`` robot-steps, started from the
    shipped single-robot model ``init`` (which it observes and is paid as: the env kwargs
    of its recipe), ``hyperparams`` for ``--hyperparams``. With ``routes_steps``, ``init``
    is first fine-tuned alone for that many steps (``srpb-gym train --init``, the same
    hyperparameters) on routes drawn from the scenario's ``robots`` entries (``route``:
    the env argument, ``random`` or a list of entries): a specialist trained on the
    single robot's route drives the others' routes less well; the multi-robot run then
    starts from that run's ``best/`` checkpoint. The run keeps a checkpoint every
    ``save_every`` robot-steps, and ``python -m training.select_checkpoint`` chooses the
    one it ships on checkpoint-selection seeds (the weakest robot's success first): from
    one checkpoint to the next the third robot's success moves by a tenth, so the last one
    is a draw."""

    scenario: str
    robots: int
    envs: int
    steps: int
    init: str
    hyperparams: tuple[str, ...] = ()
    routes_steps: int = 0
    route: str = "random"
    save_every: int = 200_000


#: the crowd specialist with its own PPO settings fine-tuned alone on the 3 robots' routes
#: (the scenario's robots entries 0-2), robot 2's (right to left, the hardest) drawn twice
#: as often, then among 2 other robots for 2M robot-steps, a checkpoint kept every 200k
#: and the one shipped chosen on checkpoint-selection seeds, weakest robot first
CROWD_3ROBOTS = MultiRecipe(
    "crowd", 3, 2, 2_000_000, "ppo-crowd-srpb",
    ("learning_rate=1e-4", "n_steps=1024", "batch_size=512", *SMALL_STEPS, *LONG_HORIZON),
    routes_steps=1_000_000, route="[0, 1, 2, 2]",
)  # fmt: skip

#: the shared policies for several robots, by name (``ppo-<scenario>-<preset>-<N>robots``)
MULTI_RECIPES: dict[str, MultiRecipe] = {
    "ppo-crowd-srpb-3robots": CROWD_3ROBOTS,
    # its controlled twin: the same recipe from the crowd specialist of the task preset,
    # paid the task preset (with the same collision penalty); not shipped
    "ppo-crowd-task-3robots": replace(CROWD_3ROBOTS, init="ppo-crowd-task"),
}


def teachers_of(name: str) -> tuple[tuple[str, str], ...]:
    """The (scenario, model) pairs model ``name`` starts from: the teachers of its warm
    start, or a multi-robot policy's initial model."""
    if name in MULTI_RECIPES:
        return ((MULTI_RECIPES[name].scenario, MULTI_RECIPES[name].init),)
    return recipe_of(name).teachers


def side_option(side_by_side: int) -> list[str]:
    """The shipping scripts' ``--side-by-side`` option, for runs trained ``side_by_side``
    at a time (none for a run alone)."""
    return ["--side-by-side", str(side_by_side)] if side_by_side > 1 else []


def multi_commands(name: str, seeds: list[int], threads: int, ship: bool = True,
                   root: str = "runs/train", side_by_side: int = 1) -> list[list[str]]:  # fmt: skip
    """The commands that retrain the multi-robot policy ``name``: per seed a run (its
    first stage alone on the routes, then the multi-robot run) and the choice of the
    run's checkpoint and, with ``ship``, ``training.ship_multi`` of the first seed's
    run."""
    multi = MULTI_RECIPES[name]
    scenario, preset = MODELS[multi.init]
    kwargs = env_kwargs_of(RECIPES[scenario], preset)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    runs = [f"{root}/{name}-s{seed}-{stamp}" for seed in seeds]
    hyper = [*multi.hyperparams, *([f"torch_threads={threads}"] if threads else [])]
    out, inits = [], [multi.init] * len(seeds)
    if multi.routes_steps:
        env_id = RECIPES[scenario].env_id
        inits = [f"{root}/{name}-routes-s{seed}-{stamp}" for seed in seeds]
        out += [[sys.executable, "-m", "srpb_gym", "train", "--env", env_id, "--reward", preset,
                 "--seed", str(seed), "--steps", str(multi.routes_steps), "--out", first,
                 "--no-progress", "--init", multi.init, "--env-kwargs", *kwargs,
                 f"route={multi.route}", *(["--hyperparams", *hyper] if hyper else [])]
                for seed, first in zip(seeds, inits)]  # fmt: skip
        inits = [f"{first}/best" for first in inits]
    out += [[sys.executable, "-m", "training.multi_robot", "--scenario", multi.scenario,
             "--robots", str(multi.robots), "--envs", str(multi.envs), "--steps",
             str(multi.steps), "--reward", preset, "--seed", str(seed), "--init", init,
             "--save-every", str(multi.save_every), "--keep-checkpoints", "--out", run,
             *(["--env-kwargs", *kwargs] if kwargs else []),
             *(["--hyperparams", *hyper] if hyper else [])]
            for seed, run, init in zip(seeds, runs, inits)]  # fmt: skip
    workers = str(threads or os.cpu_count() or 1)
    out += [[sys.executable, "-m", SELECT, run, "--workers", workers] for run in runs]
    if ship:
        out.append([sys.executable, "-m", "training.ship_multi", runs[0], "--name", name,
                    *side_option(side_by_side)])  # fmt: skip
    return out


#: the module that chooses a multi-robot run's checkpoint (it takes the run's folder)
SELECT = "training.select_checkpoint"


def recipe_of(name: str) -> Recipe:
    """The recipe of model ``name``."""
    return RECIPES[MODELS[name][0]]


def reward_kwarg(recipe: Recipe, preset: str) -> str | None:
    """The ``reward_weights`` env kwarg of the recipe's ``preset`` model (None: the preset)."""
    items = [recipe.shaping] if preset == "srpb" and recipe.shaping else []
    if recipe.collision != -25.0:
        items.append(f"collision: {recipe.collision!r}")
    return f"reward_weights={{{', '.join(items)}}}" if items else None


def env_kwargs_of(recipe: Recipe, preset: str) -> list[str]:
    """The ``--env-kwargs`` of the recipe's ``preset`` model: its observation, its other env
    kwargs, its reward weights and whose people its reward sees."""
    kwargs = [f"observation={recipe.observation}"] if recipe.observation else []
    kwargs += [*recipe.env_kwargs]
    weights = reward_kwarg(recipe, preset)
    kwargs += [weights] if weights else []
    if recipe.reward_people != "tracked":  # the environment's default
        kwargs.append(f"reward_people={recipe.reward_people}")
    return kwargs


def train_command(name: str, seed: int, out: str, threads: int) -> list[str]:
    """``srpb-gym train`` of model ``name`` with ``seed`` into ``out``."""
    _, preset = MODELS[name]
    recipe = recipe_of(name)
    kwargs = env_kwargs_of(recipe, preset)
    hyperparams = [*recipe.hyperparams]
    if recipe.teachers:
        pairs = ", ".join(f"{scenario}: {teacher}" for scenario, teacher in recipe.teachers)
        hyperparams.append(f"pretrain_teachers={{{pairs}}}")
    hyperparams += [f"torch_threads={threads}"] if threads else []
    cmd = [sys.executable, "-m", "srpb_gym", "train", "--env", recipe.env_id, "--reward",
           preset, "--seed", str(seed), "--steps", str(recipe.steps), "--out", out,
           "--no-progress"]  # fmt: skip
    cmd += ["--env-kwargs", *kwargs] if kwargs else []
    return cmd + (["--hyperparams", *hyperparams] if hyperparams else [])


def commands(name: str, seeds: list[int], threads: int, ship: bool = True,
             root: str = "runs/train", side_by_side: int = 1) -> list[list[str]]:  # fmt: skip
    """The commands that retrain model ``name``: a run per seed and, with ``ship``,
    ``training.ship`` of the first seed's run (a multi-robot policy's:
    :func:`multi_commands`); ``side_by_side``: the runs that train at once on the machine's
    cores (``--jobs``), which the model card records beside the run's wall time."""
    if name in MULTI_RECIPES:
        return multi_commands(name, seeds, threads, ship, root, side_by_side)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    runs = [f"{root}/{name}-s{seed}-{stamp}" for seed in seeds]
    out = [train_command(name, seed, run, threads) for seed, run in zip(seeds, runs)]
    if ship:
        out.append([sys.executable, "-m", "training.ship", runs[0], "--name", name,
                    "--candidates", "1", "--validate", str(recipe_of(name).validate),
                    *side_option(side_by_side)])  # fmt: skip
    return out


def waves(names: list[str], shipped: list[str]) -> list[list[str]]:
    """``names`` in the order they can be retrained: the models taught by others
    (:attr:`Recipe.teachers`) after the rest, so that a teacher retrained too is shipped
    before its student's run starts; a teacher that is no model of this script, neither
    named nor shipped, or taught itself, is an error (:class:`ValueError`)."""
    taught = [n for n in names if teachers_of(n)]
    for name in taught:
        for scenario, teacher in teachers_of(name):
            if teacher not in MODELS:
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is no model of "
                                 f"this script ({', '.join(MODELS)})")  # fmt: skip
            if teachers_of(teacher):
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is taught too")
            if teacher not in names and teacher not in shipped:
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is not shipped; "
                                 "name it too to retrain it first")  # fmt: skip
    first = [n for n in names if n not in taught]
    return [wave for wave in (first, taught) if wave]


def main() -> int:
    parser = argparse.ArgumentParser(description="retrain the shipped models and their twins")
    every = [*MODELS, *MULTI_RECIPES]
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"of: {', '.join(every)}")
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=[0],
        metavar="S",
        help="training seeds (default 0); the first one's run is shipped",
    )
    parser.add_argument("--no-ship", action="store_true", help="train only")
    parser.add_argument("--jobs", type=int, default=1, help="runs side by side")
    parser.add_argument("--dry-run", action="store_true")
    args = parser.parse_args()
    unknown = [n for n in args.names if n not in every]
    if unknown:
        parser.error(f"unknown model {unknown[0]!r}; choose from {', '.join(every)}")
    if len(set(args.seeds)) != len(args.seeds) or min(args.seeds) < 0:
        parser.error(f"--seeds: distinct seeds >= 0, got {args.seeds}")
    names = args.names or every
    threads = 1 if args.jobs > 1 else 0
    try:
        order = waves(names, model_names())
    except ValueError as exc:
        parser.error(str(exc))
    failed: set[str] = set()
    rc = 0
    for wave in order:  # the teachers of the second wave are shipped by the first
        ready = [n for n in wave if not _teacher_failed(n, failed)]
        rc = max(rc, 1) if len(ready) < len(wave) else rc
        at_once = min(max(1, args.jobs), len(ready) * len(args.seeds))
        plans = {name: commands(name, args.seeds, threads, not args.no_ship,
                                side_by_side=at_once) for name in ready}  # fmt: skip
        runs = [(name, chain) for name in ready for chain in seed_chains(plans[name], args.seeds)]
        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            codes = list(pool.map(lambda item: _run_chain(item[1], args.dry_run), runs))
        for (name, _), code in zip(runs, codes):
            if code:
                failed.add(name)
        ships = [(name, plans[name][-1]) for name in ready
                 if not args.no_ship and name not in failed]  # fmt: skip
        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            codes += list(pool.map(lambda item: _run_chain([item[1]], args.dry_run), ships))
        rc = max(rc, *codes, 0)
    return rc


def seed_chains(plan: list[list[str]], seeds: list[int]) -> list[list[list[str]]]:
    """A model's training commands (``plan`` from :func:`commands`, the shipping command
    left out) as one chain per seed, in the order they run: a run's stages one after the
    other (the choice of a multi-robot run's checkpoint last), the seeds side by side."""
    chains = []
    for seed in seeds:
        chain = [cmd for cmd in plan
                 if "--seed" in cmd and cmd[cmd.index("--seed") + 1] == str(seed)]  # fmt: skip
        outs = {cmd[cmd.index("--out") + 1] for cmd in chain if "--out" in cmd}
        chains.append(chain + [cmd for cmd in plan if cmd[2] == SELECT and cmd[3] in outs])
    return chains


def _teacher_failed(name: str, failed: set[str]) -> bool:
    teachers = {t for _, t in teachers_of(name)}
    if teachers & failed:
        print(f"{name}: not retrained, its teacher {sorted(teachers & failed)[0]} failed",
              file=sys.stderr, flush=True)  # fmt: skip
        return True
    return False


def _run_chain(chain: list[list[str]], dry_run: bool) -> int:
    """Run the commands of ``chain`` in turn, up to the first that fails: 1 if one did
    (any non-zero exit status), else 0."""
    for cmd in chain:
        print("+ " + shlex.join(cmd), flush=True)
        if not dry_run and subprocess.run(cmd, check=False).returncode != 0:
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
