"""Collisions attributed in the evaluation: ``episodes.csv`` columns, older files, tables."""

from __future__ import annotations

import csv
import json

import pytest

from srpb_gym.cli import main
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.evaluation.stats import (
    COLLISION_COLUMNS,
    CSV_COLUMNS,
    format_text,
    rate,
    read_episodes,
    summarize,
    table,
    write_episodes,
)
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.sim.contact import Collision

ENV = "SRPB-Corridor-v0"
BY_ROBOT = Collision("person", "robot", 0.45, 0.0, 0.45, 0.0)
BY_PERSON = Collision("person", "person", 0.0, 1.1, 0.0, 0.95)
WALL = Collision("wall", "robot", 0.3, 0.0, 0.25, 0.0)


def _episode(seed: int, collision: Collision | None = None, hit: bool | None = None,
             planner: str = "a") -> EpisodeResult:  # fmt: skip
    metrics = dict.fromkeys(METRIC_NAMES, 1.0)
    hit = collision is not None if hit is None else hit
    return EpisodeResult(ENV, planner, seed, not hit, hit, False, metrics, scenario="corridor",
                         ground_truth=dict(metrics), first_collision=collision)  # fmt: skip


def _runs() -> list[EpisodeResult]:
    """50 episodes of a: 2 collisions caused by the robot, 1 by a person; 50 of b: none."""
    hits = {3: BY_ROBOT, 7: BY_PERSON, 11: WALL}
    return [_episode(s, hits.get(s)) for s in range(50)] + [
        _episode(s, planner="b") for s in range(50)
    ]


def test_the_columns_round_trip(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs())
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(CSV_COLUMNS)
    assert list(CSV_COLUMNS[-len(COLLISION_COLUMNS) - 2 :]) == [
        "scenario", "collision_kind", "collision_by", "collision_robot_speed",
        "collision_other_speed", "collision_robot_closing", "collision_other_closing",
        "people_pushed_back",
    ]  # fmt: skip
    assert [rows[7][c] for c in COLLISION_COLUMNS] == ["person", "person", "0.0", "1.1", "0.0",
                                                       "0.95"]  # fmt: skip
    assert [rows[0][c] for c in COLLISION_COLUMNS] == ["", "", "nan", "nan", "nan", "nan"]
    back = read_episodes(str(path))
    assert [r.first_collision for r in back] == [r.first_collision for r in _runs()]


def test_an_older_file_without_the_columns_still_reads(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs())
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if name not in COLLISION_COLUMNS]
    with path.open("w", newline="") as f:
        csv.writer(f).writerows([[r[i] for i in keep] for r in rows])
    back = read_episodes(str(path))
    assert all(r.first_collision is None for r in back)
    assert [r.seed for r in back if r.collision] == [3, 7, 11]
    entry = summarize(back)[ENV]["a"]
    assert entry["collision_rate"] == 6.0
    assert entry["collision_by_rate"] == {"robot": 0.0, "person": 0.0, "other_robot": 0.0,
                                          "unattributed": 6.0}  # fmt: skip
    _, body = table(summarize(back)[ENV])
    low, high = wilson(3, 50)
    assert body[2][:3] == ["collision", "%", f"6 [{rate(low)}-{rate(high)}]"]  # as before
    # compare reads it too, and writes the columns (empty)
    assert main(["compare", str(path), "--out", str(tmp_path / "merged")]) == 0
    with (tmp_path / "merged" / "episodes.csv").open(newline="") as f:
        merged = list(csv.DictReader(f))
    assert {r["collision_kind"] for r in merged} == {""}


def test_the_tables_split_the_collision_rate_by_cause(tmp_path):
    summary = summarize(_runs())[ENV]
    assert summary["a"]["collision_by_rate"] == {"robot": 4.0, "person": 2.0, "other_robot": 0.0,
                                                 "unattributed": 0.0}  # fmt: skip
    header, body = table(summary)
    low, high = wilson(3, 50)
    rates = {r[0]: r[2:] for r in body}
    assert rates["collision"] == [f"6 [{rate(low)}-{rate(high)}] (robot 4 %, person 2 %)",
                                  f"0 [0-{rate(wilson(0, 50)[1])}]"]  # fmt: skip
    assert rates["success"][0] == f"94 [{rate(100 - high)}-{rate(100 - low)}]"  # no split
    text = format_text("t", header, body).splitlines()
    assert text[4].split()[:2] == ["collision", "%"]
    assert text[4].endswith("  ".join(rates["collision"]))
    # another robot, and a row of an older file, show where there are any
    rows = [_episode(0, Collision("robot", "other_robot", 0.0, 0.4, 0.0, 0.4)),
            _episode(1, hit=True), _episode(2), _episode(3)]  # fmt: skip
    cell = table(summarize(rows)[ENV])[1][2][2]
    assert cell.endswith("(robot 0 %, person 0 %, other robot 25 %, not attributed 25 %)")
    # the printed tables of a run: summary.json says what the split is
    write_episodes(str(tmp_path / "episodes.csv"), _runs())
    assert main(["compare", str(tmp_path / "episodes.csv"), "--out", str(tmp_path / "m")]) == 0
    saved = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert saved["results"][ENV]["a"]["collision_by_rate"]["robot"] == 4.0
    assert "collision_by_rate" in saved["statistics"]
    md = (tmp_path / "m" / f"table_{ENV}.md").read_text()
    assert "| collision | % | 6 [" in md and "(robot 4 %, person 2 %) |" in md
    tex = (tmp_path / "m" / f"table_{ENV}.tex").read_text()
    assert "(robot 4 \\%, person 2 \\%)" in tex


@pytest.mark.parametrize(
    ("column", "value", "message"),
    [
        ("collision_kind", "tree", "column collision_kind is 'tree', expected one of wall"),
        ("collision_by", "nobody", "column collision_by is 'nobody', expected one of robot"),
        ("collision_robot_speed", "fast", "column collision_robot_speed is 'fast'"),
    ],
)
def test_a_bad_attribution_names_the_line(tmp_path, column, value, message):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), [_episode(0, BY_ROBOT), _episode(1, BY_PERSON)])
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    rows[1][column] = value
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with pytest.raises(InputError, match=message) as caught:
        read_episodes(str(path))
    assert caught.value.line == 3


def test_an_attribution_without_a_collision_is_refused(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), [_episode(0, BY_ROBOT, hit=False)])
    with pytest.raises(InputError, match="in an episode without a collision"):
        read_episodes(str(path))
