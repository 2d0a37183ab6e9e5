"""The output folder of an evaluation: never overwriting what is there, and resuming.

``--out`` must be a new or empty folder; a folder holding anything else is refused, naming
what it holds, so that nothing of the user's is overwritten. ``--resume`` continues an
interrupted run in its own folder: the stored ``config.json`` (and the package versions of
``versions.json``) must equal the configuration resolved now, except the keys of
:data:`RESUME_FREE` (a difference is refused, naming the keys); the finished rows of
``episodes.csv`` are kept and only the other episodes run, with the same seeds.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterator
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.evaluation import stats
from srpb_gym.evaluation.data import EpisodeResult, EvalConfig, Task, jsonable, tasks_of

RUN_FILES: tuple[str, ...] = ("config.json", "command.txt", "versions.json")
RESUME_FREE: frozenset[str] = frozenset(
    {"created", "out", "workers", "video", "video_stride", "notes", "backend", "address"}
)
"""Top-level keys of ``config.json`` that may differ when resuming: none changes a figure."""
RESUME_VERSIONS: tuple[str, ...] = (
    "python", "srpb-gym", "numpy", "scipy", "numba", "gymnasium", "pymunk",
    "stable-baselines3", "torch",
)  # fmt: skip
"""Keys of ``versions.json`` that must be equal when resuming."""
_PATH = re.compile(r"[.\[]")


def check_out_dir(out: str, resume: bool = False) -> str:
    """Create ``out`` if needed and check that it is writable.

    Without ``resume`` a folder that is not empty is refused (naming what it holds, and
    suggesting ``--resume`` when it holds an evaluation run); with ``resume`` it must hold
    an evaluation run (``config.json``).
    """
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError(f"{out} is an existing file, not a folder", key="--out")
    entries = sorted(os.listdir(out)) if os.path.isdir(out) else []
    if resume and "config.json" not in entries:
        raise InputError(f"nothing to resume in {out}: no config.json (not an evaluation run)",
                         key="--resume")  # fmt: skip
    if not resume and entries:
        shown = ", ".join(entries[:4]) + (f" and {len(entries) - 4} more" if len(entries) > 4
                                           else "")  # fmt: skip
        hint = "choose a new or empty folder"
        if "config.json" in entries:
            hint = "it holds an evaluation run: add --resume to continue it, or choose another one"
        raise InputError(f"{out} is not empty (holds {shown}); {hint}", key="--out")
    try:
        os.makedirs(out, exist_ok=True)
        probe = os.path.join(out, f".write-test-{os.getpid()}")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError as exc:
        raise InputError(f"cannot write into {out}: {exc.strerror or exc}", key="--out") from None
    return out


def read_json(path: str) -> Any:
    """A JSON file; :class:`InputError` naming it when it cannot be read or parsed."""
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file: a binary file?", path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", path, exc.lineno) from None


def write_json(path: str, doc: Any) -> None:
    """``doc`` as indented JSON (non-finite floats become ``null``)."""
    with open(path, "w", encoding="utf-8") as f:
        json.dump(jsonable(doc), f, indent=2, allow_nan=False)
        f.write("\n")


def differences(stored: Any, now: Any, key: str = "") -> Iterator[tuple[str, Any, Any]]:
    """(dotted key, stored value, current value) of every leaf that differs."""
    if isinstance(stored, dict) and isinstance(now, dict):
        for k in dict.fromkeys([*stored, *now]):
            sub = f"{key}.{k}" if key else str(k)
            if k not in stored or k not in now:
                yield sub, stored.get(k, "<absent>"), now.get(k, "<absent>")
            else:
                yield from differences(stored[k], now[k], sub)
    elif isinstance(stored, list) and isinstance(now, list) and len(stored) == len(now):
        for i, (a, b) in enumerate(zip(stored, now)):
            yield from differences(a, b, f"{key}[{i}]")
    elif stored != now:
        yield key, stored, now


def _short(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def describe_differences(
    diffs: list[tuple[str, Any, Any]],
    first: str = "in the run",
    second: str = "now",
    limit: int = 4,
) -> str:
    """``key (A <first>, B <second>); ...``: at most ``limit`` keys, then how many more."""
    shown = [f"{k} ({_short(a)} {first}, {_short(b)} {second})" for k, a, b in diffs[:limit]]
    more = f" and {len(diffs) - limit} more" if len(diffs) > limit else ""
    return "; ".join(shown) + more


def check_resumable(config: EvalConfig, resolved: dict[str, Any], versions: dict) -> None:
    """Refuse to resume unless the stored ``config.json`` and ``versions.json`` equal the
    configuration resolved now (``resolved``) and the installed ``versions``."""
    path = os.path.join(config.out, "config.json")
    stored = read_json(path)
    now = json.loads(json.dumps(jsonable(resolved)))
    if not isinstance(stored, dict):
        raise InputError("not an evaluation configuration (not a JSON object)", path)
    # runs made before --robots had one robot, and before --env-kwargs none
    stored = {"robots": 1, "env_kwargs": {}, **stored}
    stored_cmp = {k: v for k, v in stored.items() if k not in RESUME_FREE}
    now_cmp = {k: v for k, v in now.items() if k not in RESUME_FREE}
    diffs = sorted(differences(stored_cmp, now_cmp), key=lambda d: len(_PATH.split(d[0])))
    if diffs:
        raise InputError(f"the run was made with another configuration: "
                         f"{describe_differences(diffs)}; resume with the same options, or "
                         f"start a new run in another folder", path, key="--resume")  # fmt: skip
    vpath = os.path.join(config.out, "versions.json")
    if os.path.isfile(vpath):
        stored_versions = read_json(vpath)
        stored_versions = stored_versions if isinstance(stored_versions, dict) else {}
        diffs = [(k, stored_versions.get(k), versions.get(k)) for k in RESUME_VERSIONS
                 if stored_versions.get(k) != versions.get(k)]  # fmt: skip
        if diffs:
            raise InputError(f"the run was made with other package versions: "
                             f"{describe_differences(diffs)}", vpath, key="--resume")  # fmt: skip


def finished_episodes(
    config: EvalConfig, note: Callable[[str], None]
) -> tuple[list[EpisodeResult], list[Task]]:
    """The finished episodes of the run in ``config.out`` (rows of its ``episodes.csv``,
    checked: planned, each once, with its record on disk) and the tasks still to run.

    An unfinished last line (a run killed while writing it) is dropped, with a note. In a
    multi-robot run an episode is finished when the rows of all its robots are there (keyed
    by episode and robot); an episode with some of them only runs again."""
    path = os.path.join(config.out, "episodes.csv")
    tasks = tasks_of(config)
    if not os.path.isfile(path):
        return [], tasks
    text = stats.read_text(path)
    if text and not text.endswith("\n"):
        kept, _, last = text.rpartition("\n")
        note(f"warning: {path}: dropped its unfinished last line {kept.count(chr(10)) + 2} "
             f"({last[:30]!r}...); that episode runs again")  # fmt: skip
        text = kept + "\n" if kept else ""
    rows = stats.parse_episodes(text, path) if text else []
    planned = {(t.env, config.planners[t.planner].name, t.seed): t for t in tasks}
    robots = list(range(config.robots)) if config.robots > 1 else [None]
    finished: dict[tuple[str, str, int], dict[int | None, EpisodeResult]] = {}
    for line, row in enumerate(rows, start=2):
        key = (row.env, row.planner, row.seed)
        if key not in planned or row.robot not in robots:
            robot = "" if row.robot is None else f" / robot {row.robot}"
            raise InputError(f"episode {row.env} / {row.planner} / seed {row.seed}{robot} is "
                             f"not part of this run's configuration", path, line)  # fmt: skip
        record = config.record_path(*key, row.robot, row.scenario or None)
        if not os.path.isfile(record):
            raise InputError(f"the record of this finished episode is missing: {record}",
                             path, line)  # fmt: skip
        row.record = os.path.relpath(record, config.out)
        finished.setdefault(key, {})[row.robot] = row
    complete = {k: v for k, v in finished.items() if len(v) == len(robots)}
    partial = len(finished) - len(complete)
    if partial:
        note(f"warning: {path}: {partial} episode(s) lack the rows of some robots; they run "
             f"again")  # fmt: skip
    remaining = [t for key, t in planned.items() if key not in complete]
    done = [by_robot[r] for by_robot in complete.values() for r in robots]
    return done, remaining
