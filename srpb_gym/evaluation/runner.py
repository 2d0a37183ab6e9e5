"""Running episodes: one environment and one planner per (env id, planner) pair, in this
process or spread over worker processes, with identical results either way.

Episode ``i`` of a pair is ``env.reset(seed=config.seed + i)``. The planner's computation
time is measured around ``planner.act`` with :func:`time.perf_counter` and handed to the
environment with ``set_planning_time`` before each step, for classical planners and learned
policies alike. Before its first timed episode in a process, each planner is warmed up
(:func:`warm_up`: compilation, first inference) on an unrecorded environment of its own, so
that ``m_cef`` and ``m_cre`` measure the planner, not the compiler. Every finished episode
is reported at once (its CSV row is written by the caller), so an interrupted run keeps
what finished.
"""

from __future__ import annotations

import glob
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from typing import Any

from srpb_gym.evaluation.spec import EvalConfig
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.planners import Planner
from srpb_gym.registration import MIX_ID


@dataclass(frozen=True)
class Task:
    """Episode ``index`` (seed ``seed``) of environment ``env`` with planner number
    ``planner`` of the configuration."""

    env: str
    planner: int
    index: int
    seed: int


@dataclass
class EpisodeResult:
    """One finished episode: its outcome and every SRPB metric (``info["srpb/<m>"]`` of
    the last step). ``record``: the ``.npz`` record, relative to the output folder.
    ``robot``: the robot's index in a multi-robot episode, ``None`` in a single-robot run.
    ``scenario``: the episode's scenario (for ``SRPB-Mix-v0`` the one drawn)."""

    env: str
    planner: str
    seed: int
    is_success: bool
    collision: bool
    timeout: bool
    metrics: dict[str, float]
    steps: int = 0
    record: str = ""
    video: str = ""
    robot: int | None = None
    scenario: str = ""


def tasks_of(config: EvalConfig) -> list[Task]:
    """Every episode of the run in the canonical order: env, planner, seed."""
    return [Task(env, p, i, seed) for env in config.envs for p in range(len(config.planners))
            for i, seed in enumerate(config.seeds)]  # fmt: skip


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
    planner.reset(base.knowledge())
    reset_time = time.perf_counter() - started
    if on_frame is not None:
        on_frame(env.render)
    collided, steps = False, 0
    while True:
        knowledge = base.knowledge()
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
    planner.reset(base.knowledge())
    for step in range(steps):
        action = planner.act(obs, base.knowledge())
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
            from srpb_gym.evaluation.multi import make_pair

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
            from srpb_gym.evaluation.multi import run_multi_task

            return run_multi_task(self.config, self.pair(task.env, task.planner), task)
        return [self._run_single(task)]

    def _run_single(self, task: Task) -> EpisodeResult:
        env, planner = self.pair(task.env, task.planner)
        name = self.config.planners[task.planner].name
        video = None
        if task.index < self.config.video:
            from srpb_gym.evaluation.figures import VideoWriter

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
        )  # fmt: skip
        if video is not None:
            result.video = os.path.relpath(video.close(), self.config.out)
        return result

    def close(self) -> None:
        """Close every environment."""
        for env, _ in self._pairs.values():
            env.close()
        self._pairs.clear()


# ------------------------------------------------------------------ worker processes
_WORKSPACE: Workspace | None = None


def _init_worker(config: EvalConfig) -> None:
    """Worker start: Ctrl-C is the parent's to handle; one thread per numeric library."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    global _WORKSPACE
    _WORKSPACE = Workspace(config)


def _run_in_worker(task: Task) -> list[EpisodeResult]:
    assert _WORKSPACE is not None, "worker not initialised"
    return _WORKSPACE.run(task)


def _context() -> Any:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def run_tasks(
    config: EvalConfig, tasks: Sequence[Task], on_result: Callable[[EpisodeResult], None]
) -> bool:
    """Run ``tasks`` (``config.workers`` processes), calling ``on_result`` with each result
    (each robot's, in robot order) as its episode finishes. Returns ``True`` if interrupted
    (Ctrl-C); files of unfinished episodes are then removed, so what is on disk is exactly
    the finished episodes."""
    done: set[Task] = set()

    def finish(task: Task, results: list[EpisodeResult]) -> None:
        done.add(task)
        for result in results:
            on_result(result)

    try:
        if config.workers == 1 or len(tasks) == 1:
            _run_here(config, tasks, finish)
        else:
            _run_pool(config, tasks, finish)
    except KeyboardInterrupt:
        remove_unfinished(config, [t for t in tasks if t not in done])
        return True
    return False


def _run_here(config: EvalConfig, tasks: Sequence[Task], finish: Callable) -> None:
    workspace = Workspace(config)
    try:
        for task in tasks:
            finish(task, workspace.run(task))
    finally:
        workspace.close()


def _run_pool(config: EvalConfig, tasks: Sequence[Task], finish: Callable) -> None:
    """Run ``tasks`` in worker processes, at most two per worker queued at a time. Ctrl-C
    sets a flag that the loop checks between waits: raised as an exception inside
    ``concurrent.futures.wait``, it could leave the locks of the futures held, and the
    pool's own thread waiting on them forever."""
    workers = min(config.workers, len(tasks))
    with _sigint_ignored():
        pool = ProcessPoolExecutor(workers, _context(), _init_worker, (config,))
    todo = iter(tasks)
    pending: dict[Future, Task] = {}

    def refill() -> None:
        while len(pending) < _QUEUED_PER_WORKER * workers:
            task = next(todo, None)
            if task is None:
                return
            pending[pool.submit(_run_in_worker, task)] = task

    try:
        with _sigint_as_flag() as interrupted:
            refill()
            while pending:
                finished, _ = wait(list(pending), timeout=_POLL_S, return_when=FIRST_COMPLETED)
                for future in finished:
                    finish(pending.pop(future), future.result())
                if interrupted.is_set():
                    raise KeyboardInterrupt
                refill()
    except BaseException:
        _stop_pool(pool)
        for future, task in pending.items():  # episodes whose result arrived meanwhile
            if future.done() and not future.cancelled() and future.exception() is None:
                finish(task, future.result())
        raise
    pool.shutdown(wait=True)


#: tasks queued per worker process (one running, one waiting), and how often the loop
#: of :func:`_run_pool` looks for Ctrl-C while it waits for results [s]
_QUEUED_PER_WORKER = 2
_POLL_S = 0.1


@contextmanager
def _sigint(handler: Any) -> Iterator[None]:
    """SIGINT handled by ``handler`` for a moment, then as before; outside the main thread,
    which alone receives signals, nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)


@contextmanager
def _sigint_as_flag() -> Iterator[threading.Event]:
    """Ctrl-C sets the event instead of raising ``KeyboardInterrupt`` wherever the main
    thread is. Where SIGINT is ignored (``nohup``) it stays ignored."""
    flag = threading.Event()
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        yield flag
        return
    with _sigint(lambda signum, frame: flag.set()):
        yield flag


def _sigint_ignored() -> AbstractContextManager[None]:
    """Ignore Ctrl-C for a moment: worker processes started meanwhile inherit it and leave
    the interruption to this process."""
    return _sigint(signal.SIG_IGN)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """End the workers now (an episode cut short leaves no result) and drop queued ones."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=10)
    pool.shutdown(wait=True, cancel_futures=True)


def remove_unfinished(config: EvalConfig, tasks: Sequence[Task]) -> None:
    """Delete any file an unfinished episode may have left (a record cut short)."""
    for task in tasks:
        name = config.planners[task.planner].name
        folder = glob.escape(config.record_dir(task.env, name))
        videos = glob.escape(os.path.join(config.out, "videos"))
        scenario = "*" if task.env == MIX_ID else glob.escape(config.scenario_name(task.env))
        stem = f"{scenario}_seed{task.seed}"  # SRPB-Mix-v0: whichever scenario it drew
        patterns = (os.path.join(folder, f"{stem}[._]*"),
                    os.path.join(videos, f"{task.env}_{name}_seed{task.seed}.*"))  # fmt: skip
        for path in (p for pattern in patterns for p in glob.glob(pattern)):
            os.remove(path)
