"""The installed package: light import, console script, bundled example."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import srpb_gym
from srpb_gym.cli import main


def test_import_is_light():
    code = (
        "import sys, srpb_gym, srpb_gym.metrics, srpb_gym.cli; "
        "heavy = [m for m in ('torch', 'stable_baselines3', 'pygame', 'matplotlib') "
        "if m in sys.modules]; print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_console_script_version():
    beside = Path(sys.executable).with_name("srpb-gym")
    exe = str(beside) if beside.exists() else shutil.which("srpb-gym")
    if exe is None:
        pytest.skip("console script not installed (package not pip-installed)")
    out = subprocess.run([exe, "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == f"srpb-gym {srpb_gym.__version__}"


def test_example_episode(capsys):
    assert main(["metrics", "--example", "--json"]) == 0
    values = json.loads(capsys.readouterr().out)
    # a robot crossing the O-space of a five-person F-formation at 0.5 m/s
    assert values["m_goal"] == 1.0
    assert values["m_mef"] == pytest.approx(14.0)
    assert values["m_fsi_max"] > 90.0
    assert 0.0 < values["m_psi"] < 100.0


def test_example_and_log_are_exclusive(capsys):
    assert main(["metrics", "--example", "some_robot.txt"]) == 2
    assert "give either ROBOT_LOG or --example" in capsys.readouterr().err


def test_every_subpackage_is_packaged():
    """pyproject lists the packages explicitly: a new subpackage must be added there."""
    import tomllib

    root = Path(__file__).resolve().parents[1]
    listed = set(
        tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    found = {
        ".".join(p.parent.relative_to(root).parts) for p in (root / "srpb_gym").rglob("__init__.py")
    }
    data_only = {"srpb_gym.envs_data", "srpb_gym.reward_presets", "srpb_gym.train_configs",
                 "srpb_gym.data.example"}  # fmt: skip
    assert found | data_only == listed


def test_scenarios_are_package_data():
    from importlib.resources import files

    names = {p.name for p in files("srpb_gym.envs_data").iterdir()}
    assert {
        "corridor.yaml",
        "fformation.yaml",
        "crossing.yaml",
        "crowd.yaml",
        "doorway.yaml",
    } <= names
