"""``eval --robots N``: several robots per episode (the PettingZoo environment), a row per
(episode, robot), per-robot and pooled columns, the scenario's limit, workers, resume,
compare and a shared learned policy."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.cli import main
from srpb_gym.evaluation.stats import ROBOT_COLUMNS
from srpb_gym.metrics import METRIC_NAMES, MetricParams, evaluate
from srpb_gym.metrics.io_npz import load_record

ENV = "SRPB-Corridor-v0"
TIMING = ("m_cef", "m_cre", "gt_m_cef", "gt_m_cre")  # measured times
COLUMNS = ["dwa/robot_0", "dwa/robot_1", "dwa/pooled"]


def _eval(out: Path, *extra: str, planner: str = "dwa") -> int:
    return main(["eval", "--env", ENV, "--planner", planner, "--episodes", "2", "--warmup",
                 "10", "--out", str(out), *extra])  # fmt: skip


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("srpb-gym: error: ")
    return lines[0][len("srpb-gym: error: ") :]


@pytest.fixture(scope="module")
def printed(tmp_path_factory) -> dict[str, object]:
    """A 2-robot dwa run of the corridor, 2 episodes, and what it printed."""
    out = tmp_path_factory.mktemp("robots") / "run"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        assert _eval(out, "--robots", "2") == 0
    return {"out": out, "text": stdout.getvalue()}


@pytest.fixture(scope="module")
def run(printed) -> Path:
    return printed["out"]


def test_a_row_per_episode_and_robot(run):
    with open(run / "episodes.csv", newline="") as f:
        assert next(csv.reader(f)) == list(ROBOT_COLUMNS)
    rows = _rows(run)
    assert [(r["seed"], r["robot"]) for r in rows] == [("0", "0"), ("0", "1"), ("1", "0"),
                                                        ("1", "1")]  # fmt: skip
    config = json.loads((run / "config.json").read_text())
    assert config["robots"] == 2 and config["envs"][0]["kwargs"]["n_robots"] == 2
    folder = run / "episodes" / ENV / "dwa"
    assert sorted(p.name for p in folder.glob("*[0-9].npz")) == [
        f"corridor_seed{s}_robot{r}.npz" for s in (0, 1) for r in (0, 1)
    ]


def test_every_row_equals_its_recorded_episode(run):
    params = json.loads((run / "config.json").read_text())["envs"][0]["metric_params"]
    for row in _rows(run):
        stem = f"corridor_seed{row['seed']}_robot{row['robot']}.npz"
        values = evaluate(load_record(run / "episodes" / ENV / "dwa" / stem), "paper",
                          MetricParams(**params))  # fmt: skip
        for name in METRIC_NAMES:  # m_cef, m_cre included: each robot's own planning time
            assert _same(float(row[name]), values[name]), (stem, name)
        gt_record = load_record(run / "episodes" / ENV / "dwa" / stem.replace(".npz", "_gt.npz"))
        truth = evaluate(gt_record, "paper", MetricParams(**params))
        for name in METRIC_NAMES:  # and its ground truth
            assert _same(float(row[f"gt_{name}"]), truth[name]), (stem, name)


def test_per_robot_and_pooled_statistics(run):
    summary = json.loads((run / "summary.json").read_text())
    assert summary["robots"] == 2 and summary["episodes_finished"] == 2
    entries = summary["results"][ENV]
    assert list(entries) == COLUMNS
    rows = _rows(run)
    for column, mine in (("dwa/robot_0", [r for r in rows if r["robot"] == "0"]),
                         ("dwa/robot_1", [r for r in rows if r["robot"] == "1"]),
                         ("dwa/pooled", rows)):  # fmt: skip
        entry = entries[column]
        assert entry["episodes"] == len(mine) and entry["planner"] == "dwa"
        for label, key in (("success", "is_success"), ("collision", "collision"),
                           ("timeout", "timeout")):  # fmt: skip
            assert entry[f"{label}_rate"] == 100 * sum(int(r[key]) for r in mine) / len(mine)
        for name in METRIC_NAMES:
            values = np.array([float(r[name]) for r in mine])
            values = values[np.isfinite(values)]
            median = entry["metrics"][name]["median"]
            # np.percentile (the summary's) and np.median may differ in the last bit where
            # the median falls between two values: m_cef and m_cre are measured times
            same = (median is None) if values.size == 0 else np.isclose(
                median, np.median(values), rtol=1e-12, atol=0.0)  # fmt: skip
            assert same, (name, median, np.median(values))
    assert entries["dwa/pooled"]["robot"] == "pooled" and entries["dwa/robot_1"]["robot"] == 1


def test_tables_show_per_robot_and_pooled_columns(printed):
    run, text = printed["out"], printed["text"]
    lines = text.splitlines()
    assert lines[0].startswith(f"{ENV}, 2 robots: median [95 % CI] (rates: Wilson 95 % CI) "
                               "over 2 episodes per robot; pooled: ")  # fmt: skip
    assert lines[1].split() == ["metric", "unit", *COLUMNS]
    assert lines[2].split() == ["episodes", "-", "2", "2", "4"]
    md = (run / f"table_{ENV}.md").read_text().splitlines()
    assert md[0] == f"## {lines[0]}" and md[2] == "| metric | unit | " + " | ".join(COLUMNS) + " |"
    tex = (run / f"table_{ENV}.tex").read_text()
    assert "\\begin{tabular}{llrrr}" in tex and "dwa/robot\\_0 & dwa/robot\\_1 & dwa/pooled" in tex
    with open(run / f"table_{ENV}.csv", newline="") as f:
        header = next(csv.reader(f))
    assert header[2:] == [
        *(f"{c} {k}" for c in COLUMNS for k in ("median", "q1", "q3", "n")),
        *(f"{c} {k}" for c in COLUMNS for k in ("ci_low", "ci_high")),
    ]
    assert (run / f"trajectories_{ENV}_dwa.png").is_file() and (run / f"bars_{ENV}.png").is_file()


def test_more_robots_than_the_scenario_places(tmp_path, capsys):
    out = tmp_path / "many"
    assert _eval(out, "--robots", "50") == 2
    assert _error(capsys) == "--robots: scenario 'corridor' has places for at most 3 robots, got 50"
    assert not out.exists()  # refused before anything ran or was written
    assert _eval(out, "--robots", "0") == 2
    assert _error(capsys) == "--robots: must be at least 1, got 0"


def test_one_robot_is_the_single_robot_run(tmp_path):
    default, one = tmp_path / "default", tmp_path / "one"
    assert _eval(default, planner="go-to-goal") == 0
    assert _eval(one, "--robots", "1", planner="go-to-goal") == 0
    assert "robot" not in _rows(one)[0]
    assert _without_timing(_rows(one)) == _without_timing(_rows(default))
    names = sorted(p.name for p in (one / "episodes" / ENV / "go-to-goal").iterdir())
    assert names == sorted(p.name for p in (default / "episodes" / ENV / "go-to-goal").iterdir())
    summary = json.loads((one / "summary.json").read_text())
    assert "robots" not in summary and list(summary["results"][ENV]) == ["go-to-goal"]


def test_workers_give_the_same_rows(run, tmp_path):
    out = tmp_path / "workers"
    assert _eval(out, "--robots", "2", "--workers", "2") == 0
    assert _without_timing(_rows(out)) == _without_timing(_rows(run))


def test_resume_reruns_an_episode_missing_a_robot(run, tmp_path, capsys):
    out = tmp_path / "resumed"
    shutil.copytree(run, out)
    text = (out / "episodes.csv").read_text()
    (out / "episodes.csv").write_text(text[: text.rindex("\n", 0, len(text) - 1) + 1])
    assert _eval(out, "--robots", "2", "--resume") == 0
    assert "1 episode(s) lack the rows of some robots; they run again" in capsys.readouterr().err
    assert _without_timing(_rows(out)) == _without_timing(_rows(run))
    assert _eval(out, "--robots", "3", "--resume") == 2
    assert "robots (2 in the run, 3 now)" in _error(capsys)


def test_compare_refuses_other_robot_counts(run, tmp_path, capsys):
    single = tmp_path / "single"
    assert _eval(single) == 0
    capsys.readouterr()
    assert main(["compare", str(run), str(single)]) == 2
    assert "robots (2 in run, 1 in single)" in _error(capsys)
    assert main(["compare", str(run), str(single), "--separate"]) == 0
    header = capsys.readouterr().out.splitlines()[1].split()
    assert header == ["metric", "unit", "dwa@run/robot_0", "dwa@run/robot_1", "dwa@run/pooled",
                      "dwa@single"]  # fmt: skip
    assert main(["compare", str(run), "--out", str(tmp_path / "cmp")]) == 0
    assert _without_timing(_rows(tmp_path / "cmp")) == _without_timing(_rows(run))


def test_shared_policy_with_two_robots(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from srpb_gym.models import save_vecnormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]))
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, device="cpu", seed=0)
    model.learn(64)
    model.save(tmp_path / "tiny_ppo.zip")
    save_vecnormalize(venv, tmp_path / "tiny_ppo_vecnormalize.npz")
    out = tmp_path / "policy"
    assert main(["eval", "--env", ENV, "--policy", str(tmp_path / "tiny_ppo.zip"), "--robots",
                 "2", "--episodes", "1", "--warmup", "5", "--out", str(out)]) == 0  # fmt: skip
    rows = _rows(out)
    assert [(r["planner"], r["robot"]) for r in rows] == [("tiny_ppo", "0"), ("tiny_ppo", "1")]
    planner = json.loads((out / "config.json").read_text())["planners"][0]
    assert planner["vecnormalize"].endswith("tiny_ppo_vecnormalize.npz")
    for row in rows:
        record = load_record(out / "episodes" / ENV / "tiny_ppo" / f"corridor_seed0_robot"
                             f"{row['robot']}.npz")  # fmt: skip
        assert _same(float(row["m_psi"]), evaluate(record)["m_psi"])


def test_a_filmed_episode_shows_every_robot_in_one_video(tmp_path):
    pytest.importorskip("pygame")
    out = tmp_path / "video"
    assert _eval(out, "--robots", "2", "--video", "--video-stride", "3",
                 planner="go-to-goal") == 0  # fmt: skip
    (video,) = (out / "videos").iterdir()
    assert video.name.startswith(f"{ENV}_go-to-goal_seed0.")
    assert len(_rows(out)) == 4  # 2 episodes x 2 robots, the first of them filmed
    if video.suffix == ".gif":
        from PIL import Image

        with Image.open(video) as image:
            assert image.info["duration"] == 300  # 10 fps rendered, every third step shown
