"""Walkers pushed back by the robot, in the evaluation: the column, older files, tables."""

from __future__ import annotations

import csv
import json
import math

import pytest

from srpb_gym.cli import main
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.evaluation.stats import (
    PUSHED_BACK_LABEL,
    rate,
    read_episodes,
    summarize,
    table,
    write_episodes,
)
from srpb_gym.metrics import METRIC_NAMES

ENV = "SRPB-Corridor-v0"


def _runs() -> list[EpisodeResult]:
    """20 episodes of a: 5 with a walker pushed back more than 1 m; 20 of b: none."""
    metrics = dict.fromkeys(METRIC_NAMES, 1.0)
    back = [6.0, 1.5, 1.01, 2.0, 3.0] + [0.0, 0.2, 1.0, 0.5] * 3 + [0.0, 0.0, 0.3]
    out = []
    for p in ("a", "b"):
        for s, b in enumerate(back):
            out.append(EpisodeResult(ENV, p, s, True, False, False, metrics,
                                     ground_truth=dict(metrics),
                                     pushed_back=b if p == "a" else 0.0))  # fmt: skip
    return out


def test_pushed_back_round_trips_and_is_summarised(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs())
    back = read_episodes(str(path))
    assert [r.pushed_back for r in back] == [r.pushed_back for r in _runs()]
    a = summarize(back)[ENV]["a"]
    assert a["pushed_back_rate"] == 25.0  # 1.0 itself is not "farther than 1 m"
    assert a["pushed_back_rate_ci"] == wilson(5, 20)
    assert a["people_pushed_back"]["max"] == 6.0 and a["people_pushed_back"]["n"] == 20
    rows = {r[0]: r[2:] for r in table(summarize(back)[ENV])[1]}
    low, high = wilson(5, 20)
    assert rows[PUSHED_BACK_LABEL] == [f"25 [{rate(low)}-{rate(high)}]",
                                       f"0 [0-{rate(wilson(0, 20)[1])}]"]  # fmt: skip
    assert main(["compare", str(path), "--out", str(tmp_path / "m")]) == 0
    saved = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert saved["results"][ENV]["a"]["pushed_back_rate"] == 25.0
    assert "pushed_back_rate" in saved["statistics"]
    with (tmp_path / "m" / f"table_{ENV}.csv").open(newline="") as f:
        numbers = {r[0]: r for r in csv.reader(f)}
    assert float(numbers[PUSHED_BACK_LABEL][2]) == 25.0


def test_an_older_file_without_the_column_reads_as_not_known(tmp_path):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs())
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if name != "people_pushed_back"]
    with path.open("w", newline="") as f:
        csv.writer(f).writerows([[r[i] for i in keep] for r in rows])
    back = read_episodes(str(path))
    assert all(math.isnan(r.pushed_back) for r in back)
    entry = summarize(back)[ENV]["a"]
    assert entry["pushed_back_rate"] is None and entry["people_pushed_back"]["n"] == 0
    assert {r[0]: r[2] for r in table(summarize(back)[ENV])[1]}[PUSHED_BACK_LABEL] == "n/a"


@pytest.mark.parametrize(("value", "message"), [("-0.5", "expected >= 0"), ("inf", "finite"),
                                                ("far", "expected a number")])  # fmt: skip
def test_a_bad_value_names_the_line(tmp_path, value, message):
    path = tmp_path / "episodes.csv"
    write_episodes(str(path), _runs()[:3])
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    rows[1]["people_pushed_back"] = value
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with pytest.raises(InputError, match=message) as caught:
        read_episodes(str(path))
    assert caught.value.line == 3
