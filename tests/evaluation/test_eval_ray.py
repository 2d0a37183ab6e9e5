"""``srpb-gym eval --backend ray``: the process pool's episodes, files and tables on a
local Ray; a dead worker's episode run again and counted once; Ctrl-C and ``--resume``;
and no Ray at all without it (``import srpb_gym``, a plain evaluation)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from srpb_gym.cli import main
from srpb_gym.evaluation import harness, resolve_config, run_evaluation
from srpb_gym.evaluation.ray_pool import CRASH_ONCE
from tests.helpers import error_line

ENV = "SRPB-Corridor-v0"
ARGS = ["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "3", "--warmup", "0"]
TIMING = {"m_cef", "m_cre", "gt_m_cef", "gt_m_cre"}
ROOT = Path(__file__).resolve().parents[2]


def rows(folder: Path) -> list[dict[str, str]]:
    """The rows of a run's ``episodes.csv`` without the timing columns."""
    with open(folder / "episodes.csv", newline="", encoding="utf-8") as f:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(f)]


def files(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in (folder / "episodes").rglob("*"))


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray of two CPUs for this module's runs, shut down at its end."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory) -> Path:
    """The reference: the same episodes on 2 worker processes."""
    out = tmp_path_factory.mktemp("pool") / "run"
    assert main([*ARGS, "--workers", "2", "--out", str(out)]) == 0
    return out


def test_ray_runs_the_pools_episodes_and_reruns_a_dead_workers_one(
    ray_local, pool_run, tmp_path, monkeypatch, capsys
):
    marker = tmp_path / "crashed"
    monkeypatch.setenv(CRASH_ONCE, str(marker))  # the first episode's worker dies, once
    out = tmp_path / "ray"
    assert main([*ARGS, "--workers", "2", "--backend", "ray", "--out", str(out)]) == 0
    assert marker.exists()
    got = rows(out)
    assert len({(r["env"], r["planner"], r["seed"]) for r in got}) == len(got) == 3
    assert got == rows(pool_run)
    assert files(out) == files(pool_run)
    names = {p.name for p in out.iterdir()}
    assert names == {p.name for p in pool_run.iterdir()}
    table = "table_SRPB-Corridor-v0.md"  # the timing rows aside
    mine = [x for x in (out / table).read_text().splitlines() if "m_cef" not in x]
    theirs = [x for x in (pool_run / table).read_text().splitlines() if "m_cef" not in x]
    assert [x for x in mine if "m_cre" not in x] == [x for x in theirs if "m_cre" not in x]
    capsys.readouterr()


def test_ray_interrupted_keeps_what_finished_and_resumes(
    ray_local, pool_run, tmp_path, monkeypatch
):
    out = tmp_path / "ray"
    record = harness._record

    def record_then_interrupt(result, *args):  # Ctrl-C as the first episode finishes
        record(result, *args)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    monkeypatch.setattr(harness, "_record", record_then_interrupt)
    # Ctrl-C as a terminal delivers it (a SIGINT left ignored, as under nohup, is kept so)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    config = resolve_config([ENV], ["go-to-goal"], episodes=3, warmup=0, out=str(out),
                            workers=1, backend="ray", log=None)  # fmt: skip
    try:
        outcome = run_evaluation(config, progress=False)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert outcome.interrupted and 1 <= outcome.finished < 3, outcome.finished
    monkeypatch.setattr(harness, "_record", record)
    assert main([*ARGS, "--workers", "2", "--backend", "ray", "--out", str(out), "--resume"]) == 0
    assert rows(out) == rows(pool_run)
    assert files(out) == files(pool_run)


def test_address_needs_the_ray_backend_and_ray_says_how_to_install(tmp_path, monkeypatch, capsys):
    out = str(tmp_path / "x")
    assert main([*ARGS, "--address", "head:6379", "--out", out]) == 2
    assert error_line(capsys).startswith("--address: a Ray cluster's address needs --backend ray")
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert main([*ARGS, "--backend", "ray", "--out", out]) == 2
    assert error_line(capsys) == '--backend: the Ray backend needs Ray: pip install "srpb-gym[ray]"'


def test_import_and_a_plain_eval_never_load_ray(tmp_path):
    code = (
        "import sys, srpb_gym\n"
        "assert 'ray' not in sys.modules\n"
        "from srpb_gym.cli import main\n"
        f"assert main(['eval', '--env', '{ENV}', '--planner', 'go-to-goal', '--episodes', "
        f"'1', '--warmup', '0', '--out', {str(tmp_path / 'run')!r}]) == 0\n"
        "assert 'ray' not in sys.modules, 'ray was imported'\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
