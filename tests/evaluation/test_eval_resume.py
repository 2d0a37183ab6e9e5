"""``--out`` never overwrites anything; ``--resume`` continues an interrupted run."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from srpb_gym.cli import main
from srpb_gym.planners import PLANNERS, GoToGoal

ENV = "SRPB-Corridor-v0"
TIMING = ("m_cef", "m_cre", "gt_m_cef", "gt_m_cre")  # measured times


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("srpb-gym: error: ")
    return lines[0][len("srpb-gym: error: ") :]


class _Stopping(GoToGoal):
    """While ``armed``, Ctrl-C arrives during its third timed episode (the first reset is
    the warm-up's)."""

    name = "stopping"
    armed = True
    resets = 0

    def reset(self, knowledge):
        type(self).resets += 1

    def act(self, observation, knowledge):
        if type(self).armed and type(self).resets > 3 and knowledge.t > 1.0:
            raise KeyboardInterrupt
        return super().act(observation, knowledge)


@pytest.fixture
def stopping(monkeypatch):
    monkeypatch.setitem(PLANNERS, "stopping", _Stopping)
    monkeypatch.setattr(_Stopping, "armed", True)
    monkeypatch.setattr(_Stopping, "resets", 0)
    return _Stopping


def _eval(out: Path, *extra: str) -> int:
    return main(["eval", "--env", ENV, "--planner", "stopping", "--episodes", "4",
                 "--out", str(out), *extra])  # fmt: skip


def test_resume_finishes_an_interrupted_run(tmp_path, stopping, capsys):
    out = tmp_path / "run"
    assert _eval(out) == 130
    assert [r["seed"] for r in _rows(out)] == ["0", "1"]
    capsys.readouterr()
    stopping.armed = False
    assert _eval(out, "--resume") == 0
    printed = capsys.readouterr().out
    assert _eval(tmp_path / "whole") == 0
    resumed, whole = _rows(out), _rows(tmp_path / "whole")
    assert [r["seed"] for r in resumed] == ["0", "1", "2", "3"]  # each episode once
    assert _without_timing(resumed) == _without_timing(whole)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["episodes_finished"] == 4 and not summary["interrupted"]
    assert summary["results"][ENV]["stopping"]["episodes"] == 4
    assert f"{ENV}: median [95 % CI] (rates: Wilson 95 % CI) over 4 episodes" in printed
    records = sorted(p.name for p in (out / "episodes" / ENV / "stopping").glob("*[0-9].npz"))
    assert records == [f"corridor_seed{i}.npz" for i in range(4)]
    assert (out / f"trajectories_{ENV}_stopping.png").is_file()
    assert (out / "command.txt").read_text().count("srpb-gym eval") == 2
    # one planner in a comparison, not two halves
    assert main(["compare", str(out)]) == 0
    assert "stopping@" not in capsys.readouterr().out
    # resuming a finished run runs nothing and changes nothing
    assert _eval(out, "--resume") == 0
    assert _rows(out) == resumed


def test_resume_of_a_run_written_before_the_ground_truth_columns(tmp_path, stopping, capsys):
    out = tmp_path / "run"
    assert _eval(out) == 130
    path = out / "episodes.csv"
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    # nor the collision attribution's, which came later
    keep = [i for i, name in enumerate(rows[0]) if not name.startswith(("gt_", "collision_"))]
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows([[r[i] for i in keep] for r in rows])
    stopping.armed = False
    assert _eval(out, "--resume") == 0
    rows = _rows(out)
    assert [r["seed"] for r in rows] == ["0", "1", "2", "3"] and "gt_m_psi" in rows[0]
    assert [r["collision_kind"] for r in rows] == [""] * 4  # no collision
    # the older rows: ground truth not computed; the new ones: computed
    assert [r["gt_m_psi"] == "nan" for r in rows] == [True, True, False, False]
    summary = json.loads((out / "summary.json").read_text())["results"][ENV]["stopping"]
    assert summary["metrics_gt"]["m_psi"]["n"] == 2 and summary["metrics"]["m_psi"]["n"] == 4
    printed = capsys.readouterr().out.splitlines()
    assert [line for line in printed if line.startswith("m_psi (ground truth)")][-1].endswith(
        "(n=2/4)"
    )


def test_resume_refuses_another_configuration(tmp_path, stopping, capsys):
    out = tmp_path / "run"
    assert _eval(out) == 130
    capsys.readouterr()
    stopping.armed = False
    assert _eval(out, "--resume", "--preset", "srpb-code") == 2
    line = _error(capsys)
    assert line.startswith(
        f"{out}/config.json: --resume: the run was made with another "
        "configuration: preset ('paper' in the run, 'srpb-code' now)"
    )
    assert _eval(out, "--resume", "--seed", "5") == 2
    assert "seed (0 in the run, 5 now)" in _error(capsys)
    assert [r["seed"] for r in _rows(out)] == ["0", "1"]  # untouched


def test_resume_reruns_an_episode_cut_off_mid_line(tmp_path, stopping, capsys):
    out = tmp_path / "run"
    assert _eval(out) == 130
    text = (out / "episodes.csv").read_text()
    (out / "episodes.csv").write_text(text[: text.rindex("\n", 0, len(text) - 1) + 40])
    stopping.armed = False
    assert _eval(out, "--resume") == 0
    assert "dropped its unfinished last line 3" in capsys.readouterr().err
    assert [r["seed"] for r in _rows(out)] == ["0", "1", "2", "3"]


def test_out_never_overwrites_a_folder(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "config.json").write_text('{"my": "own settings"}')
    (mine / "notes.txt").write_text("x")
    args = ["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "1"]
    assert main([*args, "--out", str(mine)]) == 2
    assert _error(capsys) == (f"--out: {mine} is not empty (holds config.json, notes.txt); it "
                              "holds an evaluation run: add --resume to continue it, or "
                              "choose another one")  # fmt: skip
    assert (mine / "config.json").read_text() == '{"my": "own settings"}'
    assert main([*args, "--out", str(mine), "--resume"]) == 2
    assert "--resume: the run was made with another configuration: my (" in _error(capsys)
    (mine / "config.json").unlink()
    assert main([*args, "--out", str(mine)]) == 2
    assert _error(capsys).endswith("(holds notes.txt); choose a new or empty folder")
    assert main([*args, "--out", str(tmp_path / "nothing"), "--resume"]) == 2
    assert _error(capsys) == (f"--resume: nothing to resume in {tmp_path / 'nothing'}: no "
                              "config.json (not an evaluation run)")  # fmt: skip
    assert main([*args, "--resume"]) == 2
    assert _error(capsys).startswith("--resume: give the folder")
