"""Retrain and re-package every shipped model (or those named), one after the other.

    python -m training.retrain_models                 # the shipped ones, at most 1 h each
    python -m training.retrain_models ppo-crowd-srpb  # one (also one not shipped yet)
    python -m training.retrain_models --dry-run       # print the commands only

Each model: ``srpb-gym train`` with its env id, reward preset, seed 0 and the steps of
configs/train/ppo.yaml, stopped after at most ``--max-minutes`` (60) of wall time or the
model's own shorter time (:attr:`RunSettings.minutes`), into ``runs/train/<name>-<time>``;
then ``python -m training.ship`` tests its best checkpoint (or, with
:attr:`RunSettings.validate`, the better of best/ and the final model on validation seeds)
once on 100 test seeds (from 20,000,000: :data:`srpb_gym.seeds.TEST`) and writes
``srpb_gym/models/<name>/`` with its model card, which says that one candidate run was
trained for the slot (the recipe is fixed here; it was chosen on validation seeds, and
docs/training.md counts the runs that chose it). On a 2-core machine two runs side by
side (``--jobs 2``, one torch thread each) finish sooner than one after the other.

Some models start from something else than random weights, as their cards say: a warm
start from a classical planner's demonstrations (``pretrain_planner``: ``dwa`` or
``social-dwa``), or the best checkpoint of another model's recipe, run first, that this
model's run then fine-tunes (:attr:`RunSettings.start`, ``--init``; no shipped recipe
does now); the two stages together stay within ``--max-minutes``. The
generalist is warm-started from the specialists, a teacher per scenario
(:attr:`RunSettings.teachers`): they are retrained first when named too (or when all
models are retrained), otherwise the shipped ones teach.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

from srpb_gym.models import model_names

#: name -> (environment id, reward preset)
MODELS: dict[str, tuple[str, str]] = {
    "ppo-corridor-task": ("SRPB-Corridor-v0", "task"),
    "ppo-corridor-srpb": ("SRPB-Corridor-v0", "srpb"),
    "ppo-fformation-task": ("SRPB-FFormation-v0", "task"),
    "ppo-fformation-srpb": ("SRPB-FFormation-v0", "srpb"),
    "ppo-crowd-task": ("SRPB-Crowd-v0", "task"),
    "ppo-crowd-srpb": ("SRPB-Crowd-v0", "srpb"),
    "ppo-crossing-srpb": ("SRPB-Crossing-v0", "srpb"),
    "ppo-doorway-srpb": ("SRPB-Doorway-v0", "srpb"),
    "ppo-mix-srpb": ("SRPB-Mix-v0", "srpb"),
}


@dataclass(frozen=True)
class RunSettings:
    """How a shipped model was made, where it differs from seed 0, configs/train/ppo.yaml
    and random initial weights (the model card has the exact commands).

    ``overrides``: ``--hyperparams`` of the run; ``env_kwargs``: its ``--env-kwargs``
    (the generalist's scenario draw weights); ``start``: another model whose recipe runs
    first, and whose best checkpoint this model's run starts from (``--init``); the two
    runs share ``--max-minutes``; ``minutes``: the wall time of the model's own run where
    it is shorter than ``--max-minutes`` allows (longer training gives another model: the
    fformation ``task`` model drifts towards the standing pair); ``validate``: ship best/
    or the final model, whichever is better on that many validation seeds
    (``training.ship --validate``), instead of best/; ``teachers``: (scenario, model)
    pairs of the warm start (``pretrain_teachers``), each a model of this script;
    ``new_observation``: the run observes with other settings than its ``start`` (of the
    same shape) and fine-tunes it to them (``--init-new-observation``)."""

    seed: int = 0
    overrides: tuple[str, ...] = ()
    start: str | None = None
    minutes: float | None = None
    validate: int = 0
    env_kwargs: tuple[str, ...] = ()
    teachers: tuple[tuple[str, str], ...] = ()
    new_observation: bool = False


WARM_START = ("pretrain_planner=dwa", "pretrain_episodes=150")
SOCIAL_WARM_START = ("pretrain_planner=social-dwa", "pretrain_episodes=150")
LARGE_ROLLOUT = ("n_envs=8", "n_steps=1024", "batch_size=512")
#: the crowd models observe the lidar log-encoded: with the linear encoding the task
#: model reached 85 % on the validation seeds (0 % success until 450,000 steps), with the
#: log encoding 88-90 % (80 % after 300,000 steps), and its srpb fine-tune 95 % against 87 %
LOG_LIDAR = "observation={lidar_encoding: log}"
#: the crowd srpb model sees the standing groups' O-spaces in its lidar, out to where
#: their fsi value falls to 1e-4 (85 % on the validation seeds, m_psi 18.8 %, m_fsi
#: 1.9e-6 %; at 0.01: 86 %, 23.5 %, 1.1e-5 %; none drawn: 78-82 %, 18.5-19.2 %, about
#: 1e-6 %, so they are not shown to matter), and starts from a clone of social-dwa, which
#: goes around the standing pairs (fine-tunes of ppo-crowd-task, which crosses them, kept
#: crossing with the O-spaces drawn and five times the fsi weight)
CROWD_GROUPS = "observation={lidar_encoding: log, lidar_groups: 0.0001}"
SOCIAL_CROWD_START = ("pretrain_planner=social-dwa", "pretrain_episodes=100")
#: the crowd srpb model's PPO updates stay nearer the policy that collected the rollout
#: (5 epochs, clip range 0.1, against 10 and 0.2): 94 and 93 % (best, final) on the
#: validation seeds with seed 0, 95 and 92 % with seed 1, against 70-90 % for seeds 0-2
#: with the default updates, which drove into people more often (collisions 5-8 %
#: against 10-22 % for seeds 1 and 2); with them, twice the psi weight (collision -60
#: keeps the bound) took m_psi from 19.5 to 16.9 % on the validation seeds at 94 %
#: (three times, collision -70: 17.3 % at 92 %; seed 1 of this recipe: 17.4 % at 95 %;
#: fine-tunes of that model with three and five times: 17.4-18.3 % at 95-98 %)
SMALL_STEPS = ("n_epochs=5", "clip_range=0.1")
#: and it discounts by 0.995 per step instead of 0.99 (a horizon of about 20 s instead of
#: 10, so that it weighs intrusions further ahead; collision -120 keeps the bound, which
#: the discount doubles: 116): 94 % on the validation seeds (as the model before) with
#: m_psi 15.5 % against 16.9 %, 94 % and 16.9 % on the test seeds (18.6 % before)
LONG_HORIZON = ("gamma=0.995",)
#: the generalist's teachers: a specialist per scenario, for crowd the task model (it
#: reached the goal in more of the demonstration episodes than the srpb fine-tune of the
#: model before it); each observes with its own settings, the student log-encoded (the
#: log-encoded student of the linear crowd teacher: 91.4 % on the validation seeds, the
#: linear student of the log-encoded one 83.8-90.0 %, the log-encoded student of the
#: log-encoded one 94.0-94.4 %, shipped: its run stopped after 26 minutes of PPO)
GENERALIST_TEACHERS = (
    ("corridor", "ppo-corridor-srpb"),
    ("fformation", "ppo-fformation-srpb"),
    ("crossing", "ppo-crossing-srpb"),
    ("crowd", "ppo-crowd-task"),
    ("doorway", "ppo-doorway-srpb"),
)
#: the srpb preset's social (psi, fsi, dir) and obs weights five times over, with a
#: collision penalty that still bounds them (their worst discounted cost is 103.9 < 110):
#: what the corridor and fformation srpb models pay. With the preset's weights PPO keeps
#: the route of the task reward past the people there; five times over gives them room.
FIVE_TIMES_SOCIAL = "reward_weights={obs: -1.0, psi: -5.0, fsi: -3.0, dir: -1.0, collision: -110.0}"
#: corridor and fformation: both presets start from the same clone of a classical planner
#: and train with the crowd's larger rollout, so that the reward is all that differs (the
#: preset, five times its social weights for srpb: FIVE_TIMES_SOCIAL; fformation: a clone of
#: social-dwa, which walks around the pair; from a clone of dwa, which walks between its
#: members, neither preset left the O-space); crowd: the task
#: specialist learns with 1e-4 (3e-4 declined after its peak), the srpb specialist
#: from a clone of social-dwa with 1e-4 and smaller PPO updates (:data:`SMALL_STEPS`),
#: a discount of 0.995 (:data:`LONG_HORIZON`), twice the preset's psi and five times its
#: fsi weight (collision -120 keeps the bound)
#: and the O-spaces in its lidar (:data:`CROWD_GROUPS`; from random weights the srpb
#: preset learns to wait; the srpb fine-tune of the task model, shipped before, crossed
#: the standing pairs); the crossing specialist starts from the clone of dwa and learns
#: with 5e-5 (with 3e-4 it stalled beside the goal: 62 %
#: against 99 % on the validation seeds); the doorway specialist from the clone of dwa
#: with 1e-4 (68 % on the validation seeds after 30 minutes; with 5e-5 its evaluations
#: read 50-70 % after 650,000 steps, with 1e-4 70-85 %); the generalist starts from the
#: clone of its teachers, 1000 episodes (from a clone of dwa: a mean success of 83.4 %
#: on the validation seeds against 91.8 %; DAgger rounds after the clone did not add),
#: and learns with 5e-5 (from the clone of dwa, with 1e-4 its evaluations peaked after
#: about 15 minutes and declined after about 22; with 5e-5 they rose for 55 minutes), drawing
#: crossing and doorway three times and crowd twice as often as corridor and fformation
#: (drawn evenly, it reached 23 % in doorway; with crossing drawn twice, 44 % in crossing;
#: distilled, doorway drawn five times was no better there: 75-81 % against 81 %)
#: and paying the srpb preset's own weights in every scenario (with the five times larger
#: social weights of corridor and fformation: 75.6 % against 83.4 % on the validation
#: seeds, crowd and doorway falling)
RUN_SETTINGS: dict[str, RunSettings] = {
    "ppo-corridor-task": RunSettings(overrides=(*WARM_START, *LARGE_ROLLOUT)),
    "ppo-corridor-srpb": RunSettings(
        overrides=(*WARM_START, *LARGE_ROLLOUT), env_kwargs=(FIVE_TIMES_SOCIAL,)
    ),
    "ppo-fformation-task": RunSettings(
        overrides=(*SOCIAL_WARM_START, *LARGE_ROLLOUT), minutes=10.0, validate=100
    ),
    "ppo-fformation-srpb": RunSettings(
        overrides=(*SOCIAL_WARM_START, *LARGE_ROLLOUT),
        minutes=10.0,
        validate=100,
        env_kwargs=(FIVE_TIMES_SOCIAL,),
    ),
    "ppo-crowd-task": RunSettings(
        overrides=("learning_rate=1e-4",), minutes=28.0, env_kwargs=(LOG_LIDAR,)
    ),
    "ppo-crowd-srpb": RunSettings(
        overrides=(
            "learning_rate=1e-4",
            *SOCIAL_CROWD_START,
            *LARGE_ROLLOUT,
            *SMALL_STEPS,
            *LONG_HORIZON,
        ),
        minutes=32.0,
        validate=100,
        env_kwargs=(CROWD_GROUPS, "reward_weights={psi: -2.0, fsi: -3.0, collision: -120.0}"),
    ),
    "ppo-crossing-srpb": RunSettings(
        overrides=("learning_rate=5e-5", *WARM_START, *LARGE_ROLLOUT),
        minutes=22.0,
        validate=100,
    ),
    "ppo-doorway-srpb": RunSettings(
        overrides=("learning_rate=1e-4", *WARM_START, *LARGE_ROLLOUT),
        minutes=30.0,
        validate=100,
    ),
    "ppo-mix-srpb": RunSettings(
        overrides=("learning_rate=5e-5", "pretrain_episodes=1000"),
        teachers=GENERALIST_TEACHERS,
        minutes=26.0,
        validate=100,
        env_kwargs=(
            "weights=[1, 1, 3, 2, 3]",
            "reward_weights={obs: -0.2, psi: -1.0, fsi: -0.6, dir: -0.2, collision: -25.0}",
            LOG_LIDAR,
        ),
    ),
}


def commands(name: str, max_minutes: float, threads: int) -> list[list[str]]:
    """The commands that remake model ``name``: its run(s) and ``training.ship``."""
    settings = RUN_SETTINGS.get(name, RunSettings())
    stamp = time.strftime("%Y%m%d-%H%M%S")
    run = f"runs/train/{name}-{stamp}"
    out: list[list[str]] = []
    own = max_minutes
    if settings.start is not None:
        first = f"runs/train/{name}-start-{stamp}"
        start = RUN_SETTINGS.get(settings.start, RunSettings())
        first_minutes = min(max_minutes, start.minutes or max_minutes)
        if first_minutes >= max_minutes:
            raise ValueError(f"{name}: its first stage ({settings.start}) alone takes "
                             f"{first_minutes:g} of the {max_minutes:g} minutes")  # fmt: skip
        out.append(_train(settings.start, first_minutes, first, threads))
        own = max_minutes - first_minutes
    if settings.minutes is not None:
        own = min(own, settings.minutes)
    out.append(_train(name, own, run, threads))
    if settings.start is not None:
        out[-1] += ["--init", f"{first}/best"]
        out[-1] += ["--init-new-observation"] if settings.new_observation else []
    ship = [sys.executable, "-m", "training.ship", run, "--name", name, "--candidates", "1"]
    if settings.validate:
        ship += ["--validate", str(settings.validate)]
    return [*out, ship]


def _train(name: str, minutes: float, out: str, threads: int) -> list[str]:
    """``srpb-gym train`` with the environment, preset and settings of model ``name``."""
    env_id, preset = MODELS[name]
    settings = RUN_SETTINGS.get(name, RunSettings())
    hyperparams = [*settings.overrides]
    if settings.teachers:
        pairs = ", ".join(f"{scenario}: {teacher}" for scenario, teacher in settings.teachers)
        hyperparams.append(f"pretrain_teachers={{{pairs}}}")
    hyperparams += [f"torch_threads={threads}"] if threads else []
    cmd = ["srpb-gym", "train", "--env", env_id, "--reward", preset, "--seed",
           str(settings.seed), "--max-minutes", f"{minutes:g}", "--out", out,
           "--no-progress"]  # fmt: skip
    cmd += ["--env-kwargs", *settings.env_kwargs] if settings.env_kwargs else []
    return cmd + (["--hyperparams", *hyperparams] if hyperparams else [])


def waves(names: list[str], shipped: list[str]) -> list[list[str]]:
    """``names`` in the order they can be retrained: the models taught by others
    (:attr:`RunSettings.teachers`) after the rest, so that a teacher retrained too is
    shipped before its student's run starts; a teacher that is no model of this script,
    neither named nor shipped, or taught itself, is an error (:class:`ValueError`)."""
    taught = [n for n in names if RUN_SETTINGS.get(n, RunSettings()).teachers]
    for name in taught:
        for scenario, teacher in RUN_SETTINGS[name].teachers:
            if teacher not in MODELS:
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is no model of "
                                 f"this script ({', '.join(MODELS)})")  # fmt: skip
            if RUN_SETTINGS.get(teacher, RunSettings()).teachers:
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is taught too")
            if teacher not in names and teacher not in shipped:
                raise ValueError(f"{name}: its teacher {teacher} ({scenario}) is not shipped; "
                                 "name it too to retrain it first")  # fmt: skip
    first = [n for n in names if n not in taught]
    return [wave for wave in (first, taught) if wave]


def main() -> int:
    parser = argparse.ArgumentParser(description="retrain the shipped models")
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"of: {', '.join(MODELS)}")
    parser.add_argument("--max-minutes", type=float, default=60.0)
    parser.add_argument("--jobs", type=int, default=1, help="runs side by side")
    parser.add_argument("--dry-run", action="store_true")
    args = parser.parse_args()
    unknown = [n for n in args.names if n not in MODELS]
    if unknown:
        parser.error(f"unknown model {unknown[0]!r}; choose from {', '.join(MODELS)}")
    names = args.names or [n for n in MODELS if n in model_names()]
    threads = 1 if args.jobs > 1 else 0
    try:
        order = waves(names, model_names())
    except ValueError as exc:
        parser.error(str(exc))
    try:
        plans = {name: commands(name, args.max_minutes, threads) for name in names}
    except ValueError as exc:
        parser.error(f"{exc}; raise --max-minutes")

    failed: set[str] = set()

    def one(name: str) -> int:
        teachers = {t for _, t in RUN_SETTINGS.get(name, RunSettings()).teachers}
        if teachers & failed:
            print(f"{name}: not retrained, its teacher {sorted(teachers & failed)[0]} failed",
                  file=sys.stderr, flush=True)  # fmt: skip
            return 1
        for cmd in plans[name]:
            print("+ " + shlex.join(cmd), flush=True)
            if not args.dry_run and subprocess.run(cmd, check=False).returncode != 0:
                failed.add(name)
                return 1
        return 0

    rc = 0
    for wave in order:  # the teachers of the second wave are shipped by the first
        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            rc = max(rc, *pool.map(one, wave))
    return rc


if __name__ == "__main__":
    sys.exit(main())
