"""The ``srpb-gym`` command line, end to end."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from srpb_gym import __version__
from srpb_gym.cli import main
from srpb_gym.metrics import (
    METRIC_NAMES,
    METRIC_UNITS,
    PARAM_NAMES,
    EpisodeRecord,
    SRPBMetricWarning,
    evaluate,
)
from srpb_gym.metrics.io import load_episode
from srpb_gym.metrics.io_npz import save_record

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "tests" / "fixtures"
EPISODES = sorted(p.name for p in FIXTURES.iterdir() if (p / "srpb_log").is_dir())


def _robot_log(name: str = "e17_fformation_5") -> Path:
    return FIXTURES / name / "srpb_log" / "log_robot.txt"


def _number(value) -> float:
    return float({"NaN": "nan", "Infinity": "inf", "-Infinity": "-inf"}.get(value, value))


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------------------- output
def test_table_lists_every_metric_with_its_unit(capsys):
    code, out, err = _run(capsys, "metrics", _robot_log())
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].split() == ["metric", "value", "unit"]
    rows = [line.split() for line in lines[1:]]
    assert [r[0] for r in rows] == list(METRIC_NAMES)
    assert all(r[2] == METRIC_UNITS[r[0]] for r in rows)
    values = evaluate(load_episode(_robot_log()))
    assert all(math.isclose(float(r[1]), values[r[0]], rel_tol=1e-5, abs_tol=1e-12) for r in rows)
    # aligned columns: every value ends, and every unit starts, in the same column
    assert len({re.match(r"\S+\s+\S+", line).end() for line in lines}) == 1
    assert len({re.match(r"\S+\s+\S+\s+", line).end() for line in lines}) == 1


@pytest.mark.parametrize("semantics", ["paper", "reference"])
@pytest.mark.parametrize("preset", ["paper", "srpb-code"])
def test_json_equals_evaluate(capsys, semantics, preset):
    argv = ["metrics", _robot_log(), "--json", "--semantics", semantics, "--preset", preset]
    code, out, _ = _run(capsys, *argv, "--param", "safety_distance=0.7", "--param",
                        "robot_max_speed=0.6")  # fmt: skip
    assert code == 0
    got = json.loads(out)
    assert list(got) == list(METRIC_NAMES)
    expected = evaluate(load_episode(_robot_log()), semantics, preset, safety_distance=0.7,
                        robot_max_speed=0.6)  # fmt: skip
    assert all(_same(_number(got[k]), expected[k]) for k in METRIC_NAMES)


def test_param_changes_the_result(capsys):
    base = json.loads(_run(capsys, "metrics", _robot_log("e01_forward_no_humans"), "--json")[1])
    more = json.loads(_run(capsys, "metrics", _robot_log("e01_forward_no_humans"), "--json",
                           "--param", "safety_distance=5")[1])  # fmt: skip
    assert more["m_obs"] == 100.0 and base["m_obs"] < 100.0


def test_json_writes_non_finite_values_as_strings(capsys, tmp_path):
    rec = EpisodeRecord()
    rec.append(np.zeros(12))  # a single sample: several metrics are undefined
    save_record(rec, tmp_path / "one.npz")
    code, out, err = _run(capsys, "metrics", tmp_path / "one.npz", "--json")
    assert code == 0
    got = json.loads(out)
    with pytest.warns(SRPBMetricWarning):
        expected = evaluate(rec)
    for name in METRIC_NAMES:
        if math.isnan(expected[name]):
            assert got[name] == "NaN"
        else:
            assert got[name] == expected[name]
    assert "NaN" in got.values()
    assert err.startswith("srpb-gym: warning: ") and "Traceback" not in err


@pytest.mark.parametrize("name", EPISODES)
def test_native_logs_reproduce_the_reference_tool(capsys, name):
    code, out, _ = _run(capsys, "metrics", _robot_log(name), "--json", "--semantics",
                        "reference", "--preset", "srpb-code")  # fmt: skip
    assert code == 0
    got = json.loads(out)
    reference = json.loads((FIXTURES / name / "reference_code_defaults.json").read_text())
    for key in METRIC_NAMES:
        if name == "e09_fformation_2" and key.startswith("m_fsi"):
            continue  # ill-posed fit of a two-member group (see the fixtures' README)
        a, b = _number(got[key]), _number(reference["metrics"][key])
        assert _same(a, b) or math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), key


def test_explicit_logs_and_npz_input_agree(capsys, tmp_path):
    log = _robot_log().parent
    explicit = _run(capsys, "metrics", log / "log_robot.txt", log / "log_people.txt",
                    log / "log_groups.txt", "--json")[1]  # fmt: skip
    save_record(load_episode(log / "log_robot.txt"), tmp_path / "e.npz")
    from_npz = _run(capsys, "metrics", tmp_path / "e.npz", "--json")[1]
    assert json.loads(explicit) == json.loads(from_npz)


SOCIAL = [m for m in METRIC_NAMES if m.startswith(("m_psi", "m_fsi", "m_dir"))]
FSI = [m for m in METRIC_NAMES if m.startswith("m_fsi")]


def test_robot_log_without_people_log_leaves_social_metrics_not_computed(capsys, tmp_path):
    log = _robot_log().parent
    full = json.loads(_run(capsys, "metrics", log / "log_robot.txt", "--json")[1])
    alone = shutil.copy(log / "log_robot.txt", tmp_path / "copy_robot.txt")  # no siblings
    code, out, err = _run(capsys, "metrics", alone, "--json")
    assert code == 0
    got = json.loads(out)
    assert [m for m in METRIC_NAMES if got[m] is None] == SOCIAL  # null, never 0
    assert all(got[m] == full[m] for m in METRIC_NAMES if m not in SOCIAL)
    assert err == (f"srpb-gym: note: no people log given or found for {alone}: the social "
                   "metrics m_psi, m_fsi, m_dir are not computed (--no-people: the run had "
                   "nobody around)\n")  # fmt: skip
    code, out, _ = _run(capsys, "metrics", alone)
    rows = {line.split()[0]: line.split()[1] for line in out.splitlines()[1:]}
    assert code == 0 and all(rows[m] == "n/a" for m in SOCIAL)
    assert all(rows[m] != "n/a" for m in METRIC_NAMES if m not in SOCIAL)


def test_no_people_flag_scores_an_empty_scene(capsys, tmp_path):
    alone = shutil.copy(_robot_log(), tmp_path / "copy_robot.txt")
    code, out, err = _run(capsys, "metrics", alone, "--json", "--no-people")
    assert code == 0 and err == ""
    got = json.loads(out)
    assert all(got[m] == 0 for m in ("m_psi", "m_fsi", "m_dir"))
    code, _, err = _run(capsys, "metrics", _robot_log(), "--no-people")
    assert code == 2
    assert _single_error_line(err) == (
        f"srpb-gym: error: --no-people: the run has a log of them: "
        f"{_robot_log().parent / 'log_people.txt'}"
    )


def test_people_log_without_groups_log_leaves_fsi_not_computed(capsys, tmp_path):
    log = _robot_log().parent
    full = json.loads(_run(capsys, "metrics", log / "log_robot.txt", "--json")[1])
    code, out, err = _run(capsys, "metrics", log / "log_robot.txt", log / "log_people.txt",
                          "--json")  # fmt: skip
    got = json.loads(out)
    assert code == 0 and [m for m in METRIC_NAMES if got[m] is None] == FSI
    assert all(got[m] == full[m] for m in METRIC_NAMES if m not in FSI)
    assert "no groups log for" in err and "m_fsi is not computed" in err
    code, out, _ = _run(capsys, "metrics", log / "log_robot.txt", log / "log_people.txt",
                        "--json", "--no-groups")  # fmt: skip
    assert code == 0 and json.loads(out)["m_fsi"] == 0


def test_version(capsys):
    code, out, _ = _run(capsys, "--version")
    assert code == 0 and out.strip() == f"srpb-gym {__version__}"


def test_eval_help_lists_the_planner_settings(capsys):
    code, out, _ = _run(capsys, "eval", "--help")
    assert code == 0
    assert "--planner-config FILE" in out and "--planner-param NAME.FIELD=VALUE" in out


# ---------------------------------------------------------------------------- errors
def _single_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("srpb-gym: error: ")
    return lines[0]


def test_malformed_log(capsys, tmp_path):
    bad = tmp_path / "bad_robot.txt"
    bad.write_text("0.0 " + " ".join(["0"] * 23) + "\n\n0.1 1 2\n")
    code, out, err = _run(capsys, "metrics", bad)
    assert code == 2 and out == ""
    line = _single_error_line(err)
    assert line.startswith(f"srpb-gym: error: {bad}:3: expected 24 values")
    assert "got 3" in line


def test_missing_file(capsys, tmp_path):
    code, _, err = _run(capsys, "metrics", tmp_path / "nothing_robot.txt")
    assert code == 2
    assert _single_error_line(err) == f"srpb-gym: error: {tmp_path}/nothing_robot.txt: no such file"


@pytest.mark.parametrize("item", ["speed=1", "safety_distance=abc", "safety_distance",
                                  "safety_distance=nan"])  # fmt: skip
def test_bad_param(capsys, item):
    code, out, err = _run(capsys, "metrics", _robot_log(), "--param", item)
    assert code == 2 and out == ""
    line = _single_error_line(err)
    assert "--param" in line
    if item.startswith("speed"):
        assert all(name in line for name in PARAM_NAMES)


def test_unevaluable_episode(capsys, tmp_path):
    save_record(EpisodeRecord(), tmp_path / "empty.npz")
    code, _, err = _run(capsys, "metrics", tmp_path / "empty.npz")
    assert code == 2
    assert _single_error_line(err).startswith(f"srpb-gym: error: {tmp_path}/empty.npz: ")


def test_usage_errors_exit_2(capsys):
    assert main([]) == 2
    assert main(["metrics"]) == 2
    assert main(["metrics", str(_robot_log()), "--semantics", "other"]) == 2
    capsys.readouterr()


# ---------------------------------------------------------------------------- subprocess
def _subprocess(*argv: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "srpb_gym", *map(str, argv)], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=300)  # fmt: skip


def test_subprocess_end_to_end(tmp_path):
    done = _subprocess("metrics", _robot_log(), "--json")
    assert done.returncode == 0, done.stderr
    assert list(json.loads(done.stdout)) == list(METRIC_NAMES)
    table = _subprocess("metrics", _robot_log(), "--preset", "srpb-code")
    assert table.returncode == 0 and table.stdout.splitlines()[0].split()[0] == "metric"
    bad = tmp_path / "x_people.txt"
    bad.write_text("1.0 p1 oops\n")
    failed = _subprocess("metrics", _robot_log(), bad)
    assert failed.returncode == 2 and failed.stdout == ""
    assert _single_error_line(failed.stderr).startswith(f"srpb-gym: error: {bad}:1: expected 26")
