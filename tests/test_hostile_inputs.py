"""Hostile inputs: each becomes a one-line error (exit status 2), a clear exception or a
documented rule, never a traceback, a silent wrong number or a lost file."""

from __future__ import annotations

import csv
import math
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym
from srpb_gym.cli import main
from srpb_gym.errors import InputError
from srpb_gym.evaluation import resolve_config
from srpb_gym.evaluation.figures import MAX_FRAME_SECONDS, VideoWriter
from srpb_gym.evaluation.stats import check_metric_value
from srpb_gym.metrics import METRIC_NAMES, METRIC_RANGES
from tests.helpers import error_line

ROOT = Path(__file__).resolve().parents[1]
ENV = "SRPB-Corridor-v0"


def _error(capsys) -> str:
    return error_line(capsys)


# ------------------------------------------------------------------ environments
def test_reset_options_must_be_a_mapping():
    env = gym.make(ENV)
    with pytest.raises(InputError, match=r"^options: expected a mapping of reset options"):
        env.reset(options=[1, 2])
    env.reset(seed=0)  # the environment stays usable
    par = srpb_gym.parallel_env(scenario="corridor", n_robots=2)
    with pytest.raises(InputError, match=r"^options: expected a mapping"):
        par.reset(options=[1, 2])


def test_numpy_integers_count_robots(tmp_path):
    par = srpb_gym.parallel_env(scenario="corridor", n_robots=np.int64(2))
    assert par.n_robots == 2 and type(par.n_robots) is int
    config = resolve_config([ENV], ["go-to-goal"], robots=np.int64(2), out=str(tmp_path / "o"),
                            log=None)  # fmt: skip
    assert config.robots == 2 and type(config.robots) is int
    with pytest.raises(InputError, match=r"^--robots: expected a whole number, got 2.0"):
        resolve_config([ENV], ["go-to-goal"], robots=2.0, out=str(tmp_path / "p"), log=None)


def test_mixture_weights_near_the_largest_float_are_normalised():
    env = gym.make("SRPB-Mix-v0", weights=[1e308, 1e308, 1, 1, 1])
    weights = env.unwrapped.weights
    assert weights[:2] == (0.5, 0.5) and all(0 <= w < 1e-300 for w in weights[2:])
    env.reset(seed=0)
    # ordinary weights keep their exact probabilities
    assert gym.make("SRPB-Mix-v0", weights=[1, 1, 1, 2, 3]).unwrapped.weights == (
        0.125, 0.125, 0.125, 0.25, 0.375)  # fmt: skip


# ------------------------------------------------------------------ metrics
def test_an_overflowing_metric_is_not_computable(tmp_path, capsys):
    src = ROOT / "tests" / "fixtures" / "e01_forward_no_humans" / "srpb_log" / "log_robot.txt"
    lines = src.read_text().splitlines()
    fields = lines[5].split()
    fields[1] = "1e308"  # x: finite, but the path length overflows
    lines[5] = "    ".join(fields)
    log = tmp_path / "log_robot.txt"
    log.write_text("\n".join(lines) + "\n")
    code = main(["metrics", str(log), "--no-people", "--no-groups", "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert '"m_plin": "NaN"' in out and "Infinity" not in out
    assert ("m_plin undefined (a value of the log is too large: the computation overflows): "
            "reported as NaN") in err  # fmt: skip


def test_metric_ranges():
    assert set(METRIC_RANGES) == set(METRIC_NAMES)
    assert METRIC_RANGES["m_goal"] == (0.0, 1.0) and METRIC_RANGES["m_psi_viol"] == (0.0, 100.0)
    assert METRIC_RANGES["m_plin"] == (0.0, math.inf)
    check_metric_value("m_psi", 100.00000000000001, "m_psi", "f", 2)  # rounding
    check_metric_value("m_psi", math.nan, "m_psi", "f", 2)  # not computed
    with pytest.raises(InputError, match=r"^f:3: column gt_m_mef is -1.0, out of the range"):
        check_metric_value("m_mef", -1.0, "gt_m_mef", "f", 3)


# ------------------------------------------------------------------ evaluation runs
@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A finished evaluation run: go-to-goal, 2 episodes of the corridor."""
    out = tmp_path_factory.mktemp("finished") / "run"
    assert main(["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "2",
                 "--warmup", "0", "--out", str(out)]) == 0  # fmt: skip
    return out


def test_resuming_a_finished_run_runs_nothing(finished, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    capsys.readouterr()
    code = main(["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "2",
                 "--warmup", "0", "--out", str(run), "--resume", "--workers", "2"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0 and "Traceback" not in err, err
    assert f"note: every episode of the run in {run} is finished: nothing to run" in err


def _edited(finished: Path, tmp_path: Path, column: str, value: str) -> Path:
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    with open(run / "episodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    rows[1][rows[0].index(column)] = value
    with open(run / "episodes.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return run


@pytest.mark.parametrize(("column", "value", "why"), [
    ("m_psi", "-5", "column m_psi is -5.0, out of the range of m_psi (from 0 to 100, %)"),
    ("m_psi", "250", "column m_psi is 250.0, out of the range of m_psi (from 0 to 100, %)"),
    ("gt_m_plin", "-1", "column gt_m_plin is -1.0, out of the range of m_plin (at least 0, m)"),
    ("m_psi", "inf", "column m_psi is inf: a metric is finite or not computed (nan)"),
])  # fmt: skip
def test_edited_results_are_refused(finished, tmp_path, capsys, column, value, why):
    run = _edited(finished, tmp_path, column, value)
    capsys.readouterr()
    assert main(["compare", str(run), "--out", str(tmp_path / "cmp")]) == 2
    assert _error(capsys) == f"{run / 'episodes.csv'}:2: {why}"
    assert main(["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "2", "--warmup",
                 "0", "--out", str(run), "--resume"]) == 2  # fmt: skip
    assert _error(capsys) == f"{run / 'episodes.csv'}:2: {why}"


def test_a_long_video_stride_keeps_the_episode(tmp_path, capsys):
    pytest.importorskip("PIL")
    out = tmp_path / "run"
    assert main(["eval", "--env", ENV, "--planner", "go-to-goal", "--episodes", "1", "--warmup",
                 "0", "--video", "1", "--video-stride", "7000", "--out",
                 str(out)]) == 0  # fmt: skip
    with open(out / "episodes.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    assert row["planner"] == "go-to-goal"
    assert list((out / "videos").iterdir())
    video = VideoWriter(str(tmp_path / "v"), fps=10, stride=7000)
    assert video.fps == 1 / MAX_FRAME_SECONDS  # a frame lasts 100 s at most


# ------------------------------------------------------------------ training starts
@pytest.fixture(scope="module")
def small_model(tmp_path_factory) -> Path:
    """A run folder with a tiny PPO model of the corridor (net_arch [8]) and its
    statistics."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from srpb_gym.models import save_vecnormalize

    folder = tmp_path_factory.mktemp("small")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]))
    PPO("MlpPolicy", venv, n_steps=16, batch_size=16, device="cpu", seed=0,
        policy_kwargs={"net_arch": [8]}).save(folder / "model.zip")  # fmt: skip
    save_vecnormalize(venv, folder / "vecnormalize.npz")
    return folder


def test_init_with_corrupt_statistics_writes_nothing(small_model, tmp_path, capsys):
    init = tmp_path / "init"
    init.mkdir()
    shutil.copy(small_model / "model.zip", init / "model.zip")
    (init / "vecnormalize.npz").write_bytes(b"\x80\x04garbage")
    out = tmp_path / "out"
    args = ["train", "--env", ENV, "--steps", "64", "--init", str(init), "--out", str(out),
            "--no-progress"]  # fmt: skip
    assert main(args) == 2
    assert _error(capsys) == (f"{init / 'vecnormalize.npz'}: --init: corrupt statistics file "
                              "(not a numpy archive)")  # fmt: skip
    assert not out.exists()
    out.mkdir()  # an empty folder given as --out stays, empty
    assert main(args) == 2
    capsys.readouterr()
    assert out.is_dir() and not any(out.iterdir())


def test_init_that_does_not_fit_says_which_layers(small_model, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert main(["train", "--env", ENV, "--steps", "64", "--init", str(small_model), "--out",
                 str(out), "--hyperparams", "n_envs=1", "eval_freq=0",
                 "--no-progress"]) == 2  # fmt: skip
    line = _error(capsys)
    assert line.startswith(f"--init: {small_model / 'model.zip'}: its networks do not fit this "
                           "run's spaces and net_arch (")  # fmt: skip
    assert (
        "size mismatch for mlp_extractor.policy_net.0.weight: copying a param with shape "
        "torch.Size([8, 80]) from checkpoint"
        in line
        and line.endswith("more)")
    )
    assert out.is_dir() and not any(out.iterdir())  # the folder stays, with nothing in it
