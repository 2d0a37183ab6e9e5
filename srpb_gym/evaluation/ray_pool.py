"""Running the episodes of an evaluation as Ray tasks: on a local Ray (``ray.init()`` on
this machine) or on a Ray cluster (``address``), with the results, files and tables of the
process pool (:mod:`srpb_gym.evaluation.pool`) for the same seeds; the timings aside.

Each episode is one task. A Ray worker process keeps a
:class:`~srpb_gym.evaluation.runner.Workspace` per run (its environments and planners,
built and warmed up on first use, as a pool worker does) that writes into a scratch folder
of its own; the task returns the episode's results with the bytes of every file it wrote,
and this process writes them into the output folder. Nothing is written into the run
folder by a worker, so a worker on another machine needs no shared disk, and a task cut
short leaves nothing behind.

A task whose worker died (killed, out of memory, a node lost) is run again by Ray
(``max_retries``): its result arrives once, and a result is taken at most once per
episode, so no episode is counted twice. An episode that raises is not retried (a bug,
not a lost worker): the run stops with its error, keeping what finished. Ctrl-C cancels
the tasks still running and keeps the finished episodes, as the process pool does.

Ray is imported only here, and only when a run uses it: ``import srpb_gym`` and a run on
the process pool never load it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import os
import shutil
import tempfile
import uuid
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Any

from srpb_gym._version import __version__
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, Task
from srpb_gym.evaluation.runner import Workspace

INSTALL_HINT = 'the Ray backend needs Ray: pip install "srpb-gym[ray]"'
MAX_RETRIES = 3
"""How many times Ray runs an episode again whose worker died."""
CRASH_ONCE = "SRPB_GYM_RAY_CRASH_ONCE"
"""Fault injection for tests: when this environment variable names a file that does not
exist, the first episode to start creates it and ends its worker process abruptly (as a
killed worker would), once."""
_POLL_S = 0.1
_WORKSPACES: dict[str, tuple[Workspace, str]] = {}


def check_installed() -> None:
    """Refuse the Ray backend when Ray is not installed: one line saying how to install it
    (key ``--backend``). Imports nothing."""
    try:
        found = importlib.util.find_spec("ray") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise InputError(INSTALL_HINT, key="--backend")


def connect(address: str | None = None) -> tuple[Any, bool]:
    """The ``ray`` module, connected: to the cluster at ``address``, or (``None``) to the
    Ray this process already uses or a new local one. Returns ``(ray, started)``, whether
    this call started the connection (and so should end it)."""
    check_installed()
    import ray

    if ray.is_initialized():
        return ray, False
    try:
        ray.init(address=address, include_dashboard=False, log_to_driver=False,
                 configure_logging=False)  # fmt: skip
    except (ConnectionError, ValueError, RuntimeError) as exc:
        where = address or "a local Ray"
        line = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot start or reach {where}: {line}", key="--address") from None
    return ray, True


def run_ray(
    config: EvalConfig,
    tasks: Sequence[Task],
    finish: Callable[[Task, list[EpisodeResult]], None],
    watch: Callable[[], AbstractContextManager[Any]],
) -> None:
    """Run ``tasks`` as Ray tasks, calling ``finish`` with each task and its results as it
    finishes (and writing its files into ``config.out`` first). ``watch``: a context
    manager giving an event that Ctrl-C sets (the loop then stops with
    ``KeyboardInterrupt``, after taking the results that had arrived)."""
    ray, started = connect(config.address)
    try:
        _run(ray, config, tasks, finish, watch)
    finally:
        if started:
            ray.shutdown()


def _run(ray: Any, config: EvalConfig, tasks: Sequence[Task], finish: Callable,
         watch: Callable) -> None:  # fmt: skip
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=False)(_episode)
    cpus = max(int(ray.cluster_resources().get("CPU", 1)), 1)
    workers = config.workers or cpus
    in_flight = workers if workers < cpus else 2 * cpus  # a queue keeps every CPU busy
    shipped = ray.put(_portable(config))
    token, crash = uuid.uuid4().hex, os.environ.get(CRASH_ONCE)
    todo = iter(tasks)
    pending: dict[Any, Task] = {}
    taken: set[Task] = set()

    def take(ref: Any) -> None:
        task = pending.pop(ref)
        results, files = ray.get(ref)
        if task in taken:  # never counted twice
            return
        _write_files(config.out, files)
        taken.add(task)
        finish(task, results)

    def refill() -> None:
        while len(pending) < in_flight:
            task = next(todo, None)
            if task is None:
                return
            pending[remote.remote(shipped, task, token, __version__, crash)] = task

    try:
        with watch() as interrupted:
            refill()
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=_POLL_S)
                if ready:  # and whatever else is done by now
                    ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0)
                for ref in ready:
                    take(ref)
                if interrupted.is_set():
                    raise KeyboardInterrupt
                refill()
    except BaseException:
        if pending:
            ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0)
            for ref in ready:
                with contextlib.suppress(Exception):  # one that failed meanwhile: unfinished
                    take(ref)
            for ref in pending:
                ray.cancel(ref, force=True)
        raise


def _portable(config: EvalConfig) -> EvalConfig:
    """``config`` with absolute paths for its policy, statistics and scenario files, so
    that a worker finds them whatever its working folder (on a cluster: at the same path
    on every node)."""
    specs = tuple(
        spec if spec.policy is None else dataclasses.replace(
            spec, policy=os.path.abspath(spec.policy),
            vecnormalize=None if spec.vecnormalize is None else os.path.abspath(spec.vecnormalize),
        )
        for spec in config.planners
    )  # fmt: skip
    files = tuple((label, os.path.abspath(path)) for label, path in config.scenario_files)
    return dataclasses.replace(config, planners=specs, scenario_files=files)


def _write_files(out: str, files: dict[str, bytes]) -> None:
    for relative, data in files.items():
        path = os.path.normpath(os.path.join(out, relative))
        if os.path.isabs(relative) or not path.startswith(os.path.normpath(out) + os.sep):
            raise ValueError(f"a Ray worker returned a file outside the run: {relative!r}")
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(data)


def _episode(config: EvalConfig, task: Task, token: str, version: str,
             crash: str | None) -> tuple[list[EpisodeResult], dict[str, bytes]]:  # fmt: skip
    """One episode in a Ray worker: its results and the files it wrote (relative to the
    run folder), read back and removed from the worker's scratch folder."""
    if version != __version__:
        raise RuntimeError(f"this Ray worker has srpb-gym {__version__}, the run {version}: "
                           "install the same version on every node")  # fmt: skip
    if crash and not os.path.exists(crash):
        with open(crash, "w", encoding="utf-8") as f:
            f.write(f"{os.getpid()}\n")
        os._exit(1)
    entry = _WORKSPACES.get(token)
    if entry is None:
        for old, scratch in _WORKSPACES.values():  # another run's: this worker moved on
            old.close()
            shutil.rmtree(scratch, ignore_errors=True)
        _WORKSPACES.clear()
        scratch = tempfile.mkdtemp(prefix="srpb-gym-ray-")
        entry = _WORKSPACES[token] = (Workspace(dataclasses.replace(config, out=scratch)),
                                      scratch)  # fmt: skip
    workspace, scratch = entry
    results = workspace.run(task)
    files: dict[str, bytes] = {}
    for folder, _, names in os.walk(scratch):
        for name in names:
            path = os.path.join(folder, name)
            with open(path, "rb") as f:
                files[os.path.relpath(path, scratch)] = f.read()
            os.remove(path)
    return results, files
