"""Multi-robot episodes: every robot of the PettingZoo environment driven at once.

With ``--robots N`` (N > 1) an episode is one ``reset(seed=seed)`` of
:class:`~srpb_gym.pettingzoo_env.SRPBParallelEnv` with N robots. A classical planner drives
each robot with an instance of its own (its own ``reset(knowledge)`` and ``act``); a
learned policy is one model shared by every robot (its normalisation statistics applied
to each robot's observation, as for one robot). Each robot's ``act`` is timed and handed
over with ``set_planning_time({agent: seconds})``. A robot leaves when it terminates or is
truncated, with its SRPB episode metrics (tracked and ground truth) in its last info: one
:class:`~srpb_gym.evaluation.data.EpisodeResult` per robot.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, PlannerSpec, Task
from srpb_gym.evaluation.figures import VideoWriter
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.planners import Planner, knowledge_for
from srpb_gym.sim.contact import FIRST_PREFIX, Collision


def robot_hits(rows: Sequence[EpisodeResult]) -> int:
    """The robot episodes whose first collision was with another robot."""
    return sum(r.first_collision is not None and r.first_collision.kind == "robot" for r in rows)


def success_by_robot(rows: Sequence[EpisodeResult]) -> list[float]:
    """The success rate (0-1) of each robot index among ``rows``, by index."""
    return [float(np.mean([r.is_success for r in rows if r.robot == robot]))
            for robot in sorted({r.robot for r in rows})]  # fmt: skip


def build_planners(spec: PlannerSpec, agents: list[str]) -> dict[str, Planner]:
    """The planner of each agent: one instance each for a classical planner, one model
    shared by every agent for a learned policy."""
    if spec.policy is not None:
        shared = spec.build()
        return dict.fromkeys(agents, shared)
    return {agent: spec.build() for agent in agents}


def run_multi_episode(
    par: Any,
    planners: Mapping[str, Planner],
    seed: int,
    on_frame: Callable[[Callable[[], Any]], None] | None = None,
) -> dict[str, dict[str, Any]]:
    """Drive one episode of the parallel environment ``par`` (``par.reset(seed=seed)``),
    each agent with its planner of ``planners``.

    Each ``act`` is timed with :func:`time.perf_counter` and the times are passed to
    ``set_planning_time`` before each step. ``on_frame`` receives ``par.render`` after
    the reset and every step, to call for the frames it wants. Returns, per agent, its
    last ``info``, ``collision`` (any of its steps), ``timeout`` (truncated, not
    terminated) and ``steps``.
    """
    observations, _ = par.reset(seed=seed)
    for agent in par.agents:
        planners[agent].reset(knowledge_for(planners[agent], par.knowledge, agent))
    if on_frame is not None:
        on_frame(par.render)
    collided = dict.fromkeys(par.agents, False)
    steps = dict.fromkeys(par.agents, 0)
    finished: dict[str, dict[str, Any]] = {}
    while par.agents:
        actions, times = {}, {}
        for agent in par.agents:
            knowledge = knowledge_for(planners[agent], par.knowledge, agent)
            started = time.perf_counter()
            actions[agent] = planners[agent].act(observations[agent], knowledge)
            times[agent] = time.perf_counter() - started
        par.set_planning_time(times)
        observations, _, terms, truncs, infos = par.step(actions)
        for agent, info in infos.items():
            collided[agent] |= bool(info["collision"])
            steps[agent] += 1
            if terms[agent] or truncs[agent]:
                finished[agent] = {"info": info, "collision": collided[agent],
                                   "timeout": bool(truncs[agent] and not terms[agent]),
                                   "steps": steps[agent]}  # fmt: skip
        if on_frame is not None:
            on_frame(par.render)
    return finished


def warm_up_multi(par: Any, planners: Mapping[str, Planner], seed: int, steps: int) -> int:
    """Drive every robot's planner untimed for up to ``steps`` control steps of ``par``
    (reset with ``seed``; an environment that records nothing); returns the steps taken."""
    if steps <= 0:
        return 0
    observations, _ = par.reset(seed=seed)
    for agent in par.agents:
        planners[agent].reset(knowledge_for(planners[agent], par.knowledge, agent))
    for step in range(steps):
        actions = {}
        for a in par.agents:
            knowledge = knowledge_for(planners[a], par.knowledge, a)
            actions[a] = planners[a].act(observations[a], knowledge)
        par.set_planning_time(0.0)
        observations, *_ = par.step(actions)
        if not par.agents:
            return step + 1
    return steps


def make_pair(config: EvalConfig, env_id: str, planner: int) -> tuple[Any, dict[str, Planner]]:
    """The parallel environment (recording) and the agents' planners of one (env id,
    planner number) pair, warmed up on an environment of their own."""
    spec = config.planners[planner]
    par = config.make_parallel(env_id, spec.name)
    planners = build_planners(spec, par.possible_agents)
    if config.warmup > 0:
        scratch = config.make_parallel(env_id, render=False)
        try:
            warm_up_multi(scratch, planners, config.warmup_seed, config.warmup)
        finally:
            scratch.close()
    return par, planners


def run_multi_task(
    config: EvalConfig, pair: tuple[Any, dict[str, Planner]], task: Task
) -> list[EpisodeResult]:
    """Run one multi-robot episode of ``task``; one result per robot, in robot order."""
    par, planners = pair
    name = config.planners[task.planner].name
    video = None
    if task.index < config.video:
        stem = os.path.join(config.out, "videos", f"{task.env}_{name}_seed{task.seed}")
        video = VideoWriter(stem, par.metadata.get("render_fps", 10), config.video_stride)
    finished = run_multi_episode(par, planners, task.seed, None if video is None else video.film)
    clip = "" if video is None else os.path.relpath(video.close(), config.out)
    results = []
    for robot, agent in enumerate(par.possible_agents):
        out = finished[agent]
        info = out["info"]
        record = os.path.join(config.record_dir(task.env, name), f"{par.episode_name(robot)}.npz")
        results.append(EpisodeResult(
            task.env, name, task.seed, bool(info["is_success"]), out["collision"],
            out["timeout"], {m: float(info[f"srpb/{m}"]) for m in METRIC_NAMES}, out["steps"],
            os.path.relpath(record, config.out), clip, robot, config.scenario_name(task.env),
            {m: float(info[f"srpb_gt/{m}"]) for m in METRIC_NAMES},
            Collision.from_info(info, FIRST_PREFIX), float(info["people_pushed_back"]),
        ))  # fmt: skip
    return results
