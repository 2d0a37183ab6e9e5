"""Running episodes in one process: one environment and one planner per (env id, planner)
pair, built on first use and reused (:class:`Workspace`).

Episode ``i`` of a pair is ``env.reset(seed=config.seed + i)``. The planner's computation
time is measured around ``planner.act`` with :func:`time.perf_counter` and handed to the
environment with ``set_planning_time`` before each step, for classical planners and learned
policies alike. A reference planner (``ground_truth``) is handed the true people
(:func:`~srpb_gym.planners.knowledge_for`), every other planner the tracker's. Before its
first timed episode in a process, each planner is warmed up (:func:`warm_up`: compilation,
first inference) on an unrecorded environment of its own, so that ``m_cef`` and ``m_cre``
measure the planner, not the compiler. Episodes of several robots are driven by
:mod:`srpb_gym.evaluation.multi`; :mod:`srpb_gym.evaluation.pool` spreads the episodes of a
run over worker processes, with identical results.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from typing import Any

from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, Task
from srpb_gym.evaluation.figures import VideoWriter
from srpb_gym.evaluation.multi import make_pair, run_multi_task
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.planners import Planner, knowledge_for
from srpb_gym.sim.contact import FIRST_PREFIX, Collision


def run_episode(
    env: Any,
    planner: Planner,
    seed: int,
    on_frame: Callable[[Callable[[], Any]], None] | None = None,
    *,
    options: Mapping[str, Any] | None = None,
    on_act: Callable[[float], None] | None = None,
    on_step: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Drive one episode of ``env`` (``env.reset(seed=seed, options=options)``, e.g.
    ``options={"people": False}`` for the empty variant) with ``planner``.

    The planner's ``act`` is timed with :func:`time.perf_counter` and its duration [s]
    passed to ``set_planning_time`` before each step and to ``on_act`` (when given).
    ``on_frame`` receives ``env.render`` after the reset and every step, to call for the
    frames it wants (:meth:`~.figures.VideoWriter.film` draws only those it keeps),
    ``on_step`` the info of every step. Returns the last
    ``info``, ``collision`` (any step), ``timeout`` (truncated, not terminated), ``steps``
    and ``reset_time``, the duration of ``planner.reset`` [s].
    """
    base = env.unwrapped
    obs, info = env.reset(seed=seed, options=None if options is None else dict(options))
    started = time.perf_counter()
    planner.reset(knowledge_for(planner, base.knowledge))
    reset_time = time.perf_counter() - started
    if on_frame is not None:
        on_frame(env.render)
    collided, steps = False, 0
    while True:
        knowledge = knowledge_for(planner, base.knowledge)
        started = time.perf_counter()
        action = planner.act(obs, knowledge)
        duration = time.perf_counter() - started
        base.set_planning_time(duration)
        if on_act is not None:
            on_act(duration)
        obs, _, terminated, truncated, info = env.step(action)
        collided |= bool(info["collision"])
        steps += 1
        if on_step is not None:
            on_step(info)
        if on_frame is not None:
            on_frame(env.render)
        if terminated or truncated:
            break
    return {"info": info, "collision": collided, "timeout": bool(truncated and not terminated),
            "steps": steps, "reset_time": reset_time}  # fmt: skip


def warm_up(env: Any, planner: Planner, seed: int, steps: int) -> int:
    """Drive ``planner`` untimed for up to ``steps`` control steps of ``env`` (reset with
    ``seed``; an environment that records nothing), so that its compilation and first
    inference happen before the timed episodes; returns the steps taken."""
    if steps <= 0:
        return 0
    base = env.unwrapped
    obs, _ = env.reset(seed=seed)
    planner.reset(knowledge_for(planner, base.knowledge))
    for step in range(steps):
        action = planner.act(obs, knowledge_for(planner, base.knowledge))
        base.set_planning_time(0.0)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            return step + 1
    return steps


class Workspace:
    """The environments and planners of one process, built on first use (each planner
    warmed up then: :func:`warm_up`) and reused. With ``config.robots`` > 1 a pair is a
    PettingZoo environment and the planners of its agents (:mod:`.multi`)."""

    def __init__(self, config: EvalConfig) -> None:
        self.config = config
        self._pairs: dict[tuple[str, int], tuple[Any, Any]] = {}

    def pair(self, env_id: str, planner: int) -> tuple[Any, Any]:
        """The environment and planner of one (env id, planner number) pair."""
        key = (env_id, planner)
        if key not in self._pairs and self.config.robots > 1:
            self._pairs[key] = make_pair(self.config, env_id, planner)
        if key not in self._pairs:
            spec = self.config.planners[planner]
            env = self.config.make_env(env_id, spec.name)
            built = spec.build()
            if self.config.warmup > 0:
                scratch = self.config.make_env(env_id, render=False)
                try:
                    warm_up(scratch, built, self.config.warmup_seed, self.config.warmup)
                finally:
                    scratch.close()
            self._pairs[key] = (env, built)
        return self._pairs[key]

    def run(self, task: Task) -> list[EpisodeResult]:
        """Run one episode and return its results, one per robot (writing its video if it
        is filmed)."""
        if self.config.robots > 1:
            return run_multi_task(self.config, self.pair(task.env, task.planner), task)
        return [self._run_single(task)]

    def _run_single(self, task: Task) -> EpisodeResult:
        env, planner = self.pair(task.env, task.planner)
        name = self.config.planners[task.planner].name
        video = None
        if task.index < self.config.video:
            stem = os.path.join(self.config.out, "videos", f"{task.env}_{name}_seed{task.seed}")
            fps = env.unwrapped.metadata.get("render_fps", 10)
            video = VideoWriter(stem, fps, self.config.video_stride)
        out = run_episode(env, planner, task.seed, None if video is None else video.film)
        info, base = out["info"], env.unwrapped
        record = os.path.join(base.record_dir, f"{base.episode_name()}.npz")
        result = EpisodeResult(
            task.env, name, task.seed, bool(info["is_success"]), out["collision"], out["timeout"],
            {m: float(info[f"srpb/{m}"]) for m in METRIC_NAMES}, out["steps"],
            os.path.relpath(record, self.config.out), scenario=base.scenario.name,
            ground_truth={m: float(info[f"srpb_gt/{m}"]) for m in METRIC_NAMES},
            first_collision=Collision.from_info(info, FIRST_PREFIX),
            pushed_back=float(info["people_pushed_back"]),
        )  # fmt: skip
        if video is not None:
            result.video = os.path.relpath(video.close(), self.config.out)
        return result

    def close(self) -> None:
        """Close every environment."""
        for env, _ in self._pairs.values():
            env.close()
        self._pairs.clear()
