"""Training on Ray: ``srpb-gym train --backend ray`` (seeds as Ray Tune trials, each an
ordinary run folder, the best chosen on the validation seeds) and the RLlib multi-robot
recipe (``training/rllib_multi_robot.py``), both kept short: a few dozen steps, two RLlib
iterations of a tiny batch."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from srpb_gym.cli import main
from srpb_gym.seeds import CHECKPOINT_SELECTION, VALIDATION
from tests.helpers import error_line

ROOT = Path(__file__).resolve().parents[1]
RUN_FILES = {"model.zip", "vecnormalize.npz", "best", "checkpoints", "config.yaml",
             "command.txt", "run.json", "progress.csv", "tb", "evaluations.csv",
             "eval"}  # fmt: skip


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray of two CPUs for this module, shut down at its end."""
    ray = pytest.importorskip("ray")
    pytest.importorskip("ray.tune")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()


@pytest.fixture
def short_corridor(tmp_path) -> Path:
    """The corridor with a 3 s time limit: an untrained policy's episodes stay short."""
    text = (ROOT / "envs" / "corridor.yaml").read_text()
    path = tmp_path / "short.yaml"
    path.write_text(text.replace("time_limit: 60.0", "time_limit: 3.0"))
    return path


def test_seeds_as_tune_trials_each_a_run_folder_best_on_validation_seeds(
    ray_local, short_corridor, tmp_path, capsys
):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "sweep"
    assert main(["train", "--env", "SRPB-Custom-v0", "--reward", "task", "--backend", "ray",
                 "--seeds", "0", "1", "--steps", "32", "--no-progress",
                 "--env-kwargs", f"scenario={short_corridor}",
                 "--hyperparams", "n_envs=1", "n_steps=32", "batch_size=32", "n_epochs=1",
                 "eval_freq=32", "eval_episodes=1",
                 "--validation-episodes", "1", "--out", str(out)]) == 0  # fmt: skip
    for name in ("seed0", "seed1"):
        run = out / name
        assert {p.name for p in run.iterdir()} >= RUN_FILES, name
        assert json.loads((run / "run.json").read_text())["seed"] == int(name[-1])
        (step,) = (run / "eval").iterdir()  # the periodic evaluation: checkpoint selection
        assert json.loads((step / "config.json").read_text())["seed"] == CHECKPOINT_SELECTION.start
        validation = json.loads((out / "validation" / name / "config.json").read_text())
        assert validation["seed"] == VALIDATION.start  # the choice among trials
        lines = (out / "tune" / "trials" / name / "result.json").read_text().splitlines()
        reported = [json.loads(line) for line in lines]  # what the trial reported to Tune
        assert "eval/success" in reported[0] and "validation/success" in reported[-1]
        assert "eval/gt_m_psi" in reported[0] and "validation/gt_m_psi" in reported[-1]
    with open(out / "trials.csv", newline="") as f:
        trials = list(csv.DictReader(f))
    assert [t["trial"] for t in trials] == ["seed0", "seed1"]
    assert all(t["error"] == "" for t in trials)
    assert all(float(t["validation_gt_m_psi"]) >= 0.0 for t in trials)  # the choice's figure
    best = json.loads((out / "best.json").read_text())
    assert best["best"]["trial"] in ("seed0", "seed1") and "validation" in best["chosen_on"]
    assert "best trial on the validation seeds" in capsys.readouterr().out


def test_tune_options_need_the_ray_backend(tmp_path, capsys):
    assert main(["train", "--env", "SRPB-Corridor-v0", "--seeds", "0", "1",
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert error_line(capsys) == "--seeds: runs trials on Ray Tune: add --backend ray"


def test_rllib_shared_policy_two_iterations_with_srpb_metrics(ray_local, short_corridor, tmp_path):
    pytest.importorskip("ray.rllib")
    from training.rllib_multi_robot import train

    record = train(str(short_corridor), 2, 1, 1, 2, str(tmp_path / "rllib"), batch=128,
                   minibatch=64, epochs=1, log=lambda line: None)  # fmt: skip
    assert record["env_steps"] >= 256 and record["env_steps_per_s"] > 0
    lines = (tmp_path / "rllib" / "progress.jsonl").read_text().splitlines()
    assert len(lines) == 2
    last = json.loads(lines[-1])
    assert "srpb/m_psi" in last and 0 <= last["srpb/collision"] <= 1
    assert (tmp_path / "rllib" / "checkpoint").is_dir()
