"""The evaluation harness: planners and learned policies on the srpb-gym scenarios, scored
by the SRPB metrics, compared in tables like the SRPB paper's Table 4.

Quick use::

    from srpb_gym.evaluation import resolve_config, run_evaluation
    config = resolve_config(["SRPB-Corridor-v0"], ["go-to-goal", "dwa"], episodes=5,
                            out="runs/x", planner_settings={"dwa": {"horizon": 2.5}})
    outcome = run_evaluation(config)
    print(outcome.text)

Planner settings are plain data, ``{planner name: {field: value}}`` (see
``docs/planners.md``), checked before the first episode and stored in ``config.json``.

Episode ``i`` uses ``env.reset(seed=seed + i)``, so any episode can be replayed alone; the
planner's ``act`` is timed and its time handed to ``env.unwrapped.set_planning_time``
(:func:`run_episode`, the one episode loop, also used by the benchmark and the tuning
script), after an untimed warm-up of every planner in every process; runs spread over worker
processes give the same episodes. With ``robots=N`` (N > 1) every episode runs in the
PettingZoo environment with N robots (:mod:`srpb_gym.evaluation.multi`): a row per (episode,
robot) and per-robot and pooled table columns. An interrupted run resumes in its own folder
(``resume=True``); runs made with different metric settings are not merged silently. Every
episode keeps its metrics from the tracked people and from ground truth; the tables give
95 % intervals (:mod:`~srpb_gym.evaluation.intervals`) and, with two planners or more,
paired comparisons (:mod:`~srpb_gym.evaluation.paired`). See
``docs/evaluation.md``. ``srpb-gym eval`` and ``srpb-gym compare`` are the command-line
front ends. matplotlib, torch, stable-baselines3 and pygame are imported only by the
functions that need them.
"""

from srpb_gym.evaluation.compare import compare_runs
from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, PlannerSpec, Task
from srpb_gym.evaluation.harness import RunOutcome, run_evaluation
from srpb_gym.evaluation.runner import run_episode, warm_up
from srpb_gym.evaluation.spec import resolve_config
from srpb_gym.evaluation.stats import read_episodes, summarize

__all__ = [
    "EpisodeResult",
    "EvalConfig",
    "PlannerSpec",
    "RunOutcome",
    "Task",
    "compare_runs",
    "read_episodes",
    "resolve_config",
    "run_episode",
    "run_evaluation",
    "summarize",
    "warm_up",
]
