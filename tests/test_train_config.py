"""Training hyperparameters: the packaged file, resolution by id, overrides, errors."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from srpb_gym.errors import InputError
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.training.config import (
    TrainConfig,
    load_entries,
    parse_overrides,
    resolve,
    rl_zoo_document,
    rl_zoo_entry,
)

ROOT = Path(__file__).resolve().parents[1]


def test_packaged_file_has_an_entry_per_id_and_a_default():
    entries, _, _ = load_entries()
    assert "default" in entries
    assert set(SCENARIO_IDS) | {"SRPB-Mix-v0"} <= set(entries)


def test_resolution_order_default_then_id_then_overrides(tmp_path):
    path = tmp_path / "ppo.yaml"
    path.write_text("default:\n  n_steps: 256\n  batch_size: 64\nSRPB-Crowd-v0:\n"
                    "  n_steps: 1024\n")  # fmt: skip
    assert resolve("SRPB-Corridor-v0", source=path).n_steps == 256
    assert resolve("SRPB-Crowd-v0", source=path).n_steps == 1024
    over = resolve("SRPB-Crowd-v0", {"n_steps": 128, "net_arch": [64, 32]}, source=path)
    assert over.n_steps == 128 and over.net_arch == (64, 32) and over.batch_size == 64
    assert resolve("SRPB-Crowd-v0", source=path).gamma == TrainConfig().gamma


def test_ppo_kwargs_build_the_networks():
    pytest.importorskip("torch")
    from torch import nn

    kwargs = resolve("SRPB-Corridor-v0", {"activation_fn": "relu", "net_arch": [32]}).ppo_kwargs()
    assert kwargs["policy_kwargs"] == {"net_arch": {"pi": [32], "vf": [32]},
                                       "activation_fn": nn.ReLU}  # fmt: skip
    assert kwargs["n_steps"] == 512 and "n_timesteps" not in kwargs


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("default:\n  n_steps: 64\n  n_stesp: 3\n", "ppo.yaml:3: default.n_stesp: unknown key"),
        ("SRPB-Crowd-v0:\n  gamma: 1.5\n", "ppo.yaml:2: SRPB-Crowd-v0.gamma: must be in (0, 1]"),
        ("SRPB-Crowd-v0:\n  n_envs: two\n", "ppo.yaml:2: SRPB-Crowd-v0.n_envs: expected an"),
        ("SRPB-Crowd-v0: 3\n", "ppo.yaml:1: SRPB-Crowd-v0: expected a mapping"),
        ("- 1\n", "ppo.yaml: expected a mapping of environment ids"),
        ("SRPB-Crowd-v0:\n  n_steps: 64\ndefault: 3\n", "ppo.yaml:3: default: expected a mapping"),
        ("default:\n  vec_env: threads\n", "vec_env: choose one of subproc, dummy"),
        ("default:\n  n_steps: [1\n", "ppo.yaml:3: invalid YAML"),
    ],
)
def test_file_errors_name_file_line_and_key(tmp_path, text, expected):
    path = tmp_path / "ppo.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        resolve("SRPB-Crowd-v0", source=path)
    assert expected in str(err.value).replace(str(tmp_path) + "/", "")


@pytest.mark.parametrize(
    ("items", "expected"),
    [
        (["learnin_rate=1e-4"], "--hyperparams: learnin_rate: unknown key"),
        (["n_steps=1"], "--hyperparams: n_steps: must be >= 2, got 1"),
        (["batch_size=16384"], "batch_size: 16384 is more than the 8192 steps of one rollout"),
        (["net_arch=hello"], "--hyperparams: net_arch: expected a list"),
        (["n_steps"], "--hyperparams: expected KEY=VALUE, got 'n_steps'"),
        (["n_steps=[1"], "--hyperparams: n_steps:"),
        (["learning_rate=.nan"], "--hyperparams: learning_rate: must be finite"),
        (["policy=CnnPolicy"], "policy: only MlpPolicy fits the flat observation"),
        (
            ["pretrain_planner=astar"],
            "pretrain_planner: 'astar' is no planner (dwa, go-to-goal, "
            "social-dwa, social-force, oracle-dwa, oracle-social-dwa), shipped model (",
        ),
        (["pretrain_teachers={crowd: astar}"], "pretrain_teachers.crowd: 'astar' is no planner"),
        (["pretrain_teachers=[dwa]"], "--hyperparams: pretrain_teachers: expected a mapping"),
        (["pretrain_teachers={crowd: 3}"], "pretrain_teachers.crowd: expected a string"),
        (["pretrain_noise=2"], "pretrain_noise: must be in [0, 1], got 2"),
        (["pretrain_episodes=0"], "pretrain_episodes: must be >= 1, got 0"),
        (["pretrain_dagger_rounds=-1"], "pretrain_dagger_rounds: must be >= 0, got -1"),
        (["pretrain_dagger_episodes=0"], "pretrain_dagger_episodes: must be >= 1, got 0"),
        (
            [
                "pretrain_episodes=1001",
                "pretrain_dagger_rounds=3",
                "pretrain_dagger_episodes=333000",
            ],
            "pretrain_episodes: 1000001 demonstration episodes in all (with the DAgger rounds'); "
            "at most 1,000,000 keep their seeds apart from the validation seeds",
        ),
    ],
)
def test_override_errors(items, expected):
    with pytest.raises(InputError) as err:
        resolve("SRPB-Crowd-v0", parse_overrides(items))
    assert expected in str(err.value)


def test_demonstration_seeds_stay_below_the_validation_seeds():
    from srpb_gym.training.config import DEMO_EPISODES_MAX
    from srpb_gym.training.pretrain import DEMO_SEED
    from training.ship import VALIDATION_SEED

    assert DEMO_SEED + DEMO_EPISODES_MAX <= VALIDATION_SEED
    most = ["pretrain_episodes=1000", "pretrain_dagger_rounds=3", "pretrain_dagger_episodes=333000"]
    config = resolve("SRPB-Crowd-v0", parse_overrides(most))
    assert config.pretrain_episodes + 3 * config.pretrain_dagger_episodes == DEMO_EPISODES_MAX


def test_a_bad_teacher_in_a_file_is_located_at_its_line(tmp_path):
    path = tmp_path / "ppo.yaml"
    path.write_text("default:\n  n_envs: 2\nSRPB-Mix-v0:\n  n_steps: 512\n"
                    "  pretrain_teachers:\n    crowd: astar\n")  # fmt: skip
    with pytest.raises(InputError) as err:
        resolve("SRPB-Mix-v0", source=str(path))
    assert str(err.value).startswith(
        f"{path}:6: SRPB-Mix-v0.pretrain_teachers.crowd: 'astar' is no planner"
    )


def test_teachers_are_planners_models_or_model_files(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "model.zip").write_bytes(b"")
    config = resolve("SRPB-Mix-v0", parse_overrides([
        "pretrain_planner=ppo-mix-srpb",
        f"pretrain_teachers={{crowd: dwa, corridor: ppo-corridor-srpb, doorway: {tmp_path}/run}}",
    ]))  # fmt: skip
    assert config.pretrain_planner == "ppo-mix-srpb"
    assert config.pretrain_teachers == {"crowd": "dwa", "corridor": "ppo-corridor-srpb",
                                        "doorway": f"{tmp_path}/run"}  # fmt: skip
    assert config.as_dict()["pretrain_teachers"] == config.pretrain_teachers
    assert resolve("SRPB-Mix-v0").pretrain_teachers == {}


def test_overrides_are_read_as_plain_data_only():
    assert parse_overrides(["net_arch=[64, 64]", "gamma=0.98"]) == {"net_arch": [64, 64],
                                                                    "gamma": 0.98}  # fmt: skip
    # numbers with an exponent are numbers, as in Python (YAML 1.1 reads 1e-4 as a string)
    assert parse_overrides(["learning_rate=1e-4", "n_timesteps=2e6", "clip_range=1.5E-1"]) == {
        "learning_rate": 1e-4, "n_timesteps": 2e6, "clip_range": 0.15}  # fmt: skip
    words = parse_overrides(["policy=2e", "activation_fn=e5"])
    assert words == {"policy": "2e", "activation_fn": "e5"}
    with pytest.raises(InputError, match=r"tag"):
        parse_overrides(["n_steps=!!python/object/apply:os.system ['true']"])


def test_rl_zoo_file_is_up_to_date():
    shipped = (ROOT / "configs" / "train" / "rl_zoo" / "ppo.yml").read_text(encoding="utf-8")
    assert shipped == rl_zoo_document()
    entry = __import__("yaml").safe_load(shipped)["SRPB-Crowd-v0"]
    config = resolve("SRPB-Crowd-v0")
    assert entry["n_steps"] == config.n_steps and entry["n_timesteps"] == config.n_timesteps
    assert "net_arch=dict(pi=[256, 256]" in entry["policy_kwargs"]
    # the Zoo evaluates a text `normalize` as VecNormalize's keyword arguments (and adds the
    # entry's gamma): the same normaliser as srpb-gym train's, the reward never clipped
    normalize = eval(entry["normalize"], {})
    assert normalize == {k: v for k, v in config.vecnormalize_kwargs().items() if k != "gamma"}
    assert normalize["clip_reward"] == math.inf and normalize["norm_reward"] is True
    assert rl_zoo_entry(resolve("SRPB-Crowd-v0", {"normalize": False}))["normalize"] is False


def test_reward_clip_keys_are_refused_naming_the_key(tmp_path):
    """srpb-gym train never clips the normalised reward (a clip of k sigma can cut the
    collision penalty below the shaping bound): a clip asked for is refused, naming the key
    in an override or the file's line."""
    for key in ("clip_reward", "norm_reward"):
        with pytest.raises(InputError) as err:
            resolve("SRPB-Crowd-v0", parse_overrides([f"{key}=10"]))
        assert str(err.value).startswith(f"--hyperparams: {key}: ")
        assert "\n" not in str(err.value)
    path = tmp_path / "ppo.yaml"
    path.write_text("default:\n  n_envs: 2\n  clip_reward: 10.0\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"ppo.yaml:3: default.clip_reward: srpb-gym train "
                       r"never clips the normalised reward"):  # fmt: skip
        resolve("SRPB-Crowd-v0", source=path)


def test_export_script_check_mode():
    run = subprocess.run([sys.executable, "-m", "training.export_rl_zoo", "--check"], cwd=ROOT,
                         capture_output=True, text=True, check=False)  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    assert "up to date" in run.stdout
