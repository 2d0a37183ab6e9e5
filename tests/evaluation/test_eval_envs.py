"""``eval --env`` takes scenario files; ``--workers`` never exceeds the cores or episodes;
video support names what writing a video needs."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

from srpb_gym.cli import main
from srpb_gym.evaluation import figures, resolve_config

ROOT = Path(__file__).resolve().parents[2]
ENV = "SRPB-Corridor-v0"
TIMING = ("m_cef", "m_cre", "gt_m_cef", "gt_m_cre")  # measured times


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_scenario_file_runs_as_the_custom_env(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    out = tmp_path / "file"
    assert main(["eval", "--env", "envs/corridor.yaml", "--planner", "go-to-goal",
                 "--episodes", "1", "--out", str(out)]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "corridor: median [95 % CI] (rates: Wilson 95 % CI) over 1 episodes" in printed
    rows = _rows(out)
    assert [(r["env"], r["seed"]) for r in rows] == [("corridor", "0")]
    env = json.loads((out / "config.json").read_text())["envs"][0]
    assert env["id"] == "corridor" and env["gym_id"] == "SRPB-Custom-v0"
    assert env["scenario_file"] == str(ROOT / "envs" / "corridor.yaml")
    assert (out / "episodes" / "corridor" / "go-to-goal" / "corridor_seed0.npz").is_file()
    assert (out / "table_corridor.md").is_file()
    assert (out / "trajectories_corridor_go-to-goal.png").is_file()
    # the same scenario as the registered id: the same episode
    assert main(["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "1",
                 "--out", str(tmp_path / "id")]) == 0  # fmt: skip
    same = {k: v for k, v in _rows(tmp_path / "id")[0].items() if k not in (*TIMING, "env")}
    assert {k: v for k, v in rows[0].items() if k not in (*TIMING, "env")} == same


def test_a_missing_scenario_file_is_one_line(tmp_path, capsys):
    missing = tmp_path / "nothere.yaml"
    assert main(["eval", "--env", str(missing), "--out", str(tmp_path / "o")]) == 2
    assert _error(capsys) == f"srpb-gym: error: {missing}: --env: no such file"
    assert main(["eval", "--env", "corridor", "--out", str(tmp_path / "o")]) == 2
    assert "or give a scenario file (.yaml)" in _error(capsys)


def test_workers_are_capped(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    lines: list[str] = []
    config = resolve_config([ENV], ["go-to-goal"], episodes=5, workers=16,
                            out=str(tmp_path / "a"), log=lines.append)  # fmt: skip
    assert config.workers == 2
    assert lines == ["warning: --workers 16 is more than the 2 CPU cores (os.cpu_count() = 2); "
                     "using 2 (processes sharing a core inflate the planning times m_cef and "
                     "m_cre)"]  # fmt: skip
    lines.clear()
    config = resolve_config([ENV], ["go-to-goal"], episodes=1, workers=2,
                            out=str(tmp_path / "b"), log=lines.append)  # fmt: skip
    assert config.workers == 1 and lines == ["note: --workers 2 for 1 episode(s); using 1"]


def test_video_hint_names_what_videos_need(monkeypatch):
    assert "srpb-gym[render]" not in figures.VIDEO_HINT
    assert "pillow" in figures.VIDEO_HINT and "imageio-ffmpeg" in figures.VIDEO_HINT
    monkeypatch.setattr(figures, "video_format", lambda: None)
    message = figures.video_support()
    assert message is not None and "Pillow (GIF) or imageio and imageio-ffmpeg (MP4)" in message
    assert not hasattr(figures, "write_video")


def test_the_mixture_reports_each_episodes_scenario(tmp_path, capsys):
    import gymnasium as gym

    out = tmp_path / "mix"
    assert main(["eval", "--env", "SRPB-Mix-v0", "--planner", "go-to-goal", "--episodes", "3",
                 "--warmup", "0", "--out", str(out)]) == 0  # fmt: skip
    drawn = [gym.make("SRPB-Mix-v0").reset(seed=s)[1]["scenario"] for s in range(3)]
    assert [r["scenario"] for r in _rows(out)] == drawn
    env = json.loads((out / "config.json").read_text())["envs"][0]
    assert (
        list(env["scenarios"])
        == list(env["metric_params"])
        == ["corridor", "fformation", "crossing", "crowd", "doorway"]
    )
    for seed, scenario in enumerate(drawn):
        assert (
            out / "episodes" / "SRPB-Mix-v0" / "go-to-goal" / f"{scenario}_seed{seed}.npz"
        ).is_file()
        assert (out / f"trajectories_SRPB-Mix-v0_go-to-goal_{scenario}.png").is_file()
    capsys.readouterr()
    assert main(["eval", "--env", "SRPB-Mix-v0", "--robots", "2",
                 "--out", str(tmp_path / "o")]) == 2  # fmt: skip
    assert "--robots: SRPB-Mix-v0 runs one robot per episode" in _error(capsys)
