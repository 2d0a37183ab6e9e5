"""Warm-up: every planner runs untimed before its first timed episode, in every process, so
that m_cef and m_cre measure the planner, and nothing else changes."""

from __future__ import annotations

import csv
import json
import re
import statistics
import time
from pathlib import Path

from srpb_gym.cli import main
from srpb_gym.planners import PLANNERS, GoToGoal

ENV = "SRPB-Corridor-v0"
TIMING = ("m_cef", "m_cre", "gt_m_cef", "gt_m_cre")  # measured times


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def _first_over_median(rows: list[dict[str, str]]) -> float:
    cef = [float(r["m_cef"]) for r in rows]
    return cef[0] / statistics.median(cef)


class _SlowStart(GoToGoal):
    """Its first ``act`` takes 2 s, as a compilation or a first inference would; every
    ``act`` takes about 1 ms."""

    name = "slow-start"

    def __init__(self, config=None) -> None:
        super().__init__(config)
        self._first = True

    def act(self, observation, knowledge):
        if self._first:
            self._first = False
            time.sleep(2.0)
        time.sleep(0.001)
        return super().act(observation, knowledge)


def test_warmup_keeps_the_first_call_out_of_the_timing(tmp_path, monkeypatch):
    monkeypatch.setitem(PLANNERS, "slow-start", _SlowStart)
    args = ["eval", "--env", ENV, "--planner", "slow-start", "--episodes", "3"]
    assert main([*args, "--out", str(tmp_path / "cold"), "--warmup", "0"]) == 0
    assert main([*args, "--out", str(tmp_path / "warm")]) == 0
    cold, warm = _rows(tmp_path / "cold"), _rows(tmp_path / "warm")
    assert _first_over_median(cold) > 3.0  # without a warm-up the test would see it
    assert _first_over_median(warm) < 3.0
    # the warm-up episode is nowhere in the results: rows, records, summary
    assert [r["seed"] for r in warm] == ["0", "1", "2"]
    folder = tmp_path / "warm" / "episodes" / ENV / "slow-start"
    seeds = {re.match(r"corridor_seed(\d+)", p.name).group(1) for p in folder.iterdir()}
    assert seeds == {"0", "1", "2"}
    summary = json.loads((tmp_path / "warm" / "summary.json").read_text())
    assert summary["episodes_finished"] == 3
    # and it changes no other figure: episode i is still reset(seed=S+i)
    assert _without_timing(cold) == _without_timing(warm)


def test_dwa_first_episode_is_timed_like_the_others(tmp_path):
    out = tmp_path / "dwa"
    args = ["eval", "--env", ENV, "--planner", "dwa", "--episodes", "3", "--out", str(out)]
    assert main(args) == 0
    rows = _rows(out)
    assert _first_over_median(rows) < 3.0
    assert main([*args[:-1], str(tmp_path / "dwa-cold"), "--warmup", "0"]) == 0
    assert _without_timing(_rows(tmp_path / "dwa-cold")) == _without_timing(rows)


def test_every_worker_warms_up(tmp_path):
    out = tmp_path / "workers"
    assert main(["eval", "--env", ENV, "--planner", "dwa", "--episodes", "4", "--workers", "2",
                 "--out", str(out)]) == 0  # fmt: skip
    cef = [float(r["m_cef"]) for r in _rows(out)]
    assert max(cef) < 3.0 * statistics.median(cef)
