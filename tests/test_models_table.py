"""scripts/models_table.py: the shipped models' figures from their cards."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import models_table  # noqa: E402

FIGURES = {"episodes": 200.0, "success": 0.95, "collision": 0.03, "timeout": 0.02,
           "m_psi": 12.0, "m_fsi": 0.0, "m_dir": 0.5}  # fmt: skip
TRUTH = {"gt_m_psi": 10.0, "gt_m_fsi": 0.25, "gt_m_dir": 1.5, "caused_collision": 0.01}
CARDS = {
    "ppo-crowd-srpb": {"env": "SRPB-Crowd-v0", "test": {
        "seed": 20000000, "episodes": 200,
        "results": {"SRPB-Crowd-v0": {**FIGURES, **TRUTH}}}},
    "ppo-doorway-srpb": {"env": "SRPB-Doorway-v0", "test": {
        "seed": 10000, "episodes": 200, "results": {"SRPB-Doorway-v0": FIGURES}}},
    "ppo-crowd-srpb-3robots": {"env": "SRPB-Crowd-v0", "robots": 3, "test": {
        "seed": 20000000, "episodes": 2, "results": {
            "dwa": {**FIGURES, **TRUTH, "episodes": 6},
            "ppo-crowd-srpb-3robots": {**FIGURES, **TRUTH, "episodes": 6,
                                       "success": 5 / 6, "collision": 1 / 6}}}},
}  # fmt: skip


def test_one_row_per_scenario_and_planner(monkeypatch):
    monkeypatch.setattr(models_table, "card", CARDS.__getitem__)
    lines = models_table.table(list(CARDS)).splitlines()
    assert len(lines) == 2 + 1 + 1 + 2
    # 190 of 200: Wilson 95 % [91.0-97.3]; the robot caused 1 % of the episodes' collisions
    assert lines[2] == (
        "| `ppo-crowd-srpb` | SRPB-Crowd-v0 | 20000000-20000199 | 95.0 [91.0-97.3] | "
        "3.0 [1.4-6.4] (1.0) | 10 / 12 | 0.25 / 0 | 1.5 / 0.5 |"
    )
    assert lines[3].endswith("| 3.0 [1.4-6.4] | n/a / 12 | n/a / 0 | n/a / 0.5 |")  # no truth kept
    assert lines[4].startswith("| 3 x `dwa` | SRPB-Crowd-v0, 3 robots | 20000000-20000001 | ")
    assert lines[5].startswith("| `ppo-crowd-srpb-3robots` | SRPB-Crowd-v0, 3 robots | ")
    assert "| 83.3 [43.6-97.0] | 16.7 [3.0-56.4] (1.0) |" in lines[5]  # 5 and 1 of 6


def test_every_shipped_model_has_its_rows(capsys):
    from srpb_gym.models import card, model_names

    assert models_table.main([]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 + sum(len(card(n)["test"]["results"]) for n in model_names())
