"""Hostile inputs: each becomes a one-line error (exit status 2), a clear exception or a
documented rule, never a traceback, a silent wrong number or a lost file."""

from __future__ import annotations

import shutil
from pathlib import Path

import gymnasium as gym
import pytest

from srpb_gym.cli import main

ENV = "SRPB-Corridor-v0"


def _error(capsys) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines() if "error" in line]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0].removeprefix("srpb-gym: error: ")


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
