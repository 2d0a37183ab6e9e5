"""``srpb-gym compare``: only runs whose figures mean the same are merged; medians over fewer
episodes than the ``episodes`` row say so; a bad ``episodes.csv`` is a one-line error."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from srpb_gym.cli import main

ENV = "SRPB-Corridor-v0"


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("srpb-gym: error: ")
    return lines[0][len("srpb-gym: error: ") :]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cmp") / "base"
    args = ["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "2", "--out", str(out)]
    assert main(args) == 0
    return out


def _copy(run: Path, dest: Path, **changes) -> Path:
    shutil.copytree(run, dest)
    config = json.loads((dest / "config.json").read_text())
    for key, value in changes.items():
        if key == "safety_distance":
            config["envs"][0]["metric_params"][key] = value
        else:
            config[key] = value
    (dest / "config.json").write_text(json.dumps(config))
    return dest


def test_runs_with_other_semantics_are_refused_or_kept_apart(run, tmp_path, capsys):
    other = _copy(run, tmp_path / "other", semantics="reference")
    capsys.readouterr()
    assert main(["compare", str(run), str(other)]) == 2
    assert _error(capsys) == (f"compare: {other}/config.json: made with other settings than "
                              f"{run}/config.json: semantics ('paper' in base, 'reference' in "
                              "other); pass --separate to keep the runs apart as separate "
                              "columns")  # fmt: skip
    assert main(["compare", str(run), str(other), "--separate"]) == 0
    out = capsys.readouterr().out
    header = out.splitlines()[1].split()
    assert header == ["metric", "unit", "go-to-goal@base", "go-to-goal@other"]
    assert "  base: semantics paper, preset paper" in out
    assert "  other: semantics reference, preset paper" in out


def test_runs_with_other_metric_parameters_are_refused(run, tmp_path, capsys):
    other = _copy(run, tmp_path / "other", safety_distance=0.9)
    capsys.readouterr()
    assert main(["compare", str(run), str(other)]) == 2
    assert f"metric_params.{ENV}.safety_distance (" in _error(capsys)
    preset = _copy(run, tmp_path / "preset", preset="srpb-code")
    assert main(["compare", str(run), str(preset)]) == 2
    assert "preset ('paper' in base, 'srpb-code' in preset)" in _error(capsys)


def test_a_run_of_unknown_settings_is_refused(run, tmp_path, capsys):
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(run / "episodes.csv", bare / "episodes.csv")
    capsys.readouterr()
    assert main(["compare", str(run), str(bare)]) == 2
    assert _error(capsys).startswith(f"compare: {bare}/episodes.csv: no config.json beside it")
    assert main(["compare", str(run), str(bare), "--separate"]) == 0
    assert "  bare: settings unknown (no config.json)" in capsys.readouterr().out


def test_same_settings_merge_and_the_merge_compares_again(run, tmp_path, capsys):
    twin = _copy(run, tmp_path / "twin")
    merged = tmp_path / "merged"
    assert main(["compare", str(run), str(twin), "--out", str(merged)]) == 0
    out = capsys.readouterr().out
    assert "go-to-goal@base" in out and "go-to-goal@twin" in out and "kept apart" not in out
    assert json.loads((merged / "config.json").read_text())["semantics"] == "paper"
    assert main(["compare", str(merged), str(run)]) == 0
    assert main(["compare", str(run), str(twin), "--out", str(merged)]) == 2
    assert "is not empty" in _error(capsys)


def test_planners_are_paired_by_seed(run, tmp_path, capsys):
    twin = _copy(run, tmp_path / "twin")
    with open(twin / "episodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    psi, gt_psi = rows[0].index("m_psi"), rows[0].index("gt_m_psi")
    for row in rows[1:]:
        row[psi] = repr(float(row[psi]) + 1.0)
    rows[1][gt_psi] = "nan"
    with open(twin / "episodes.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows[:2])  # seed 0 only: seed 1 of base has no partner
    merged = tmp_path / "merged"
    capsys.readouterr()
    assert main(["compare", str(run), str(twin), "--out", str(merged)]) == 0
    out = capsys.readouterr().out
    tables, _, paired_text = out.partition("\nPaired comparisons.")
    assert paired_text and "m_psi (tracked)" in tables
    assert f"{ENV}: go-to-goal@twin minus go-to-goal@base" in paired_text
    assert ("1 pair by (scenario, seed); episodes without a partner, left out: 1 of "
            "go-to-goal@base, 0 of go-to-goal@twin;") in paired_text  # fmt: skip
    doc = json.loads((merged / "paired.json").read_text())
    assert set(doc) == {"method", "comparisons"}
    [c] = doc["comparisons"]
    assert (c["a"], c["b"], c["pairs"], c["unpaired"]) == ("go-to-goal@base", "go-to-goal@twin",
                                                          1, {"a": 1, "b": 0})  # fmt: skip
    tests = {t["label"]: t for t in c["tests"]}
    assert tests["m_psi (tracked)"]["difference"] == pytest.approx(1.0)
    assert tests["m_psi (ground truth)"]["n"] == 0 and tests["m_psi (ground truth)"]["p"] is None
    assert tests["success"]["test"] == "McNemar" and tests["success"]["p"] == 1.0
    for t in c["tests"]:
        assert {"n", "a", "b", "difference", "ci_low", "ci_high", "p", "p_holm",
                "significant"} <= set(t)  # fmt: skip
    md = (merged / "paired.md").read_text()
    assert md.startswith("# Paired comparisons") and "| m_psi (ground truth) | % | 0 |" in md
    # runs of other settings are not paired
    other = _copy(run, tmp_path / "other", semantics="srpb-code")
    assert main(["compare", str(run), str(other), "--separate"]) == 0
    out = capsys.readouterr().out
    assert "no paired comparisons: the runs were made with different settings" in out
    assert "Paired comparisons." not in out


def test_a_median_over_fewer_episodes_says_so(run, tmp_path, capsys):
    gaps = _copy(run, tmp_path / "gaps")
    with open(gaps / "episodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    rows[1][rows[0].index("m_psi")] = "nan"
    rows[1][rows[0].index("m_dir")] = "nan"  # an infinite value is refused (test_hostile_inputs)
    with open(gaps / "episodes.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    capsys.readouterr()
    assert main(["compare", str(gaps)]) == 0
    lines = {line.split("  ")[0]: line for line in capsys.readouterr().out.splitlines()[2:]}
    assert lines["episodes"].split()[-1] == "2"
    assert lines["m_psi (tracked)"].endswith("(n=1/2)")
    assert lines["m_dir (tracked)"].endswith("(n=1/2)")
    assert "(n=" not in lines["m_obs"] and "(n=" not in lines["m_psi (ground truth)"]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["results"][ENV]["go-to-goal"]["metrics"]["m_psi"]["n"] == 2


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (b"\x89PNG\r\n\x1a\n\x00\x00binary", ":1: not a UTF-8 text file (byte 0x89): a binary"),
        (b"env,planner\x00,seed\n", ":1: not a text file (NUL byte): a binary file?"),
        (b"a,b,c\n1,2,3\n", ":1: missing column(s) env, planner, seed, is_success, collision"),
        (b"env,planner,seed,is_success,collision,timeout\nE,p,0,2,0,0\n",
         ":2: column is_success is '2', expected 0 or 1"),
        (b"env,planner,seed,is_success,collision,timeout,m_psi\nE,p,0,1,0,0,abc\n",
         ":2: column m_psi is 'abc', expected a number"),
        (b"env,planner,seed,is_success,collision,timeout\nE,p,x,1,0,0\n",
         ":2: column seed is 'x', expected an integer"),
        (b"env,planner,seed,is_success,collision,timeout\nE,p,0,1,0,0\nE,p,0,1,0,0\n",
         ":3: episode E / p / seed 0 is listed twice (also on line 2)"),
        (b'env,planner,seed,is_success,collision,timeout\n"E,p,0,1,0,0\n', ":2: expected 6 values"),
    ],
)  # fmt: skip
def test_a_bad_episodes_csv_is_one_line(tmp_path, capsys, content, expected):
    path = tmp_path / "episodes.csv"
    path.write_bytes(content)
    assert main(["compare", str(path)]) == 2
    assert _error(capsys).startswith(f"{path}{expected}")
