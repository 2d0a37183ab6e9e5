"""Running the episodes of an evaluation, in this process or spread over worker processes,
with identical results either way.

Each process (this one, or each worker) runs its episodes in a
:class:`~srpb_gym.evaluation.runner.Workspace` of its own. Every finished episode is
reported at once (its CSV row is written by the caller), so an interrupted run keeps what
finished; Ctrl-C stops the workers and removes the files of the unfinished episodes.
"""

from __future__ import annotations

import glob
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import AbstractContextManager, contextmanager
from typing import Any

from srpb_gym.evaluation import ray_pool
from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, Task
from srpb_gym.evaluation.runner import Workspace
from srpb_gym.registration import MIX_ID

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
    """Run ``tasks`` (``config.workers`` processes, or Ray tasks with ``config.backend``
    ``"ray"``: :mod:`~srpb_gym.evaluation.ray_pool`), calling ``on_result`` with each result
    (each robot's, in robot order) as its episode finishes. Returns ``True`` if interrupted
    (Ctrl-C); files of unfinished episodes are then removed, so what is on disk is exactly
    the finished episodes."""
    if not tasks:  # a resumed run that had finished
        return False
    done: set[Task] = set()

    def finish(task: Task, results: list[EpisodeResult]) -> None:
        done.add(task)
        for result in results:
            on_result(result)

    try:
        if config.backend == "ray":
            ray_pool.run_ray(config, tasks, finish, _sigint_as_flag)
        elif config.workers == 1 or len(tasks) == 1:
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
