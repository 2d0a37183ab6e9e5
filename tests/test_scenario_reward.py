"""A scenario's `reward` section: its weights over the packaged presets, read with the
file's lines in errors, applied by every environment on that scenario (single robot,
mixture, multi-robot) under `reward_weights`, and checked against the collision bound."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.env import SRPBNavEnv
from srpb_gym.errors import InputError
from srpb_gym.pettingzoo_env import SRPBParallelEnv
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.reward import TERMS, RewardGameableWarning, load_preset, resolve_weights
from srpb_gym.scenarios import load_scenario
from srpb_gym.training.checks import check_env_args

SCENARIO = """\
name: weighted
time_limit: 30.0
bounds: [0.0, 0.0, 10.0, 6.0]
robot: {start: {position: [1.0, 3.0]}, goal: {position: [9.0, 3.0]}}
people: [{route: [[8.0, 2.5], [2.0, 2.5]], count: 1}]
reward:
  srpb: {psi: -2.0, collision: -40.0}
"""


def _weights(env) -> dict[str, float]:
    return dict(zip(TERMS, env.unwrapped.task.reward_fn.weights.tolist()))


def _file(tmp_path, text: str = SCENARIO):
    path = tmp_path / "weighted.yaml"
    path.write_text(text)
    return path


def test_the_section_is_read_by_preset(tmp_path) -> None:
    scenario = load_scenario(_file(tmp_path))
    assert scenario.reward == {"srpb": {"psi": -2.0, "collision": -40.0}}
    assert load_scenario(_file(tmp_path, SCENARIO.split("reward:")[0])).reward == {}


@pytest.mark.parametrize(
    ("section", "line", "key", "message"),
    [
        (
            "reward:\n  fast: {psi: -2.0}\n",
            7,
            "reward.fast",
            "unknown key; valid keys: srpb, task",
        ),
        ("reward:\n  srpb: {colour: -2.0}\n", 7, "reward.srpb.colour", "unknown key; valid"),
        ("reward:\n  srpb: {psi: high}\n", 7, "reward.srpb.psi", "expected a number"),
        ("reward:\n  srpb: {psi: .nan}\n", 7, "reward.srpb.psi", "expected a finite number"),
        ("reward:\n  srpb: [-2.0]\n", 7, "reward.srpb", "expected a mapping"),
        ("reward: -2.0\n", 6, "reward", "expected a mapping"),
    ],
)
def test_bad_sections_name_file_line_and_key(tmp_path, section, line, key, message) -> None:
    path = _file(tmp_path, SCENARIO.split("reward:")[0] + section)
    with pytest.raises(InputError) as info:
        load_scenario(path)
    assert str(info.value).startswith(f"{path}:{line}: {key}: {message}")


def test_resolution_order_preset_scenario_overrides() -> None:
    scenario = {"srpb": {"psi": -2.0, "collision": -40.0}, "task": {"time": -0.5}}
    weights = dict(zip(TERMS, resolve_weights("srpb", {"psi": -3.0}, scenario).tolist()))
    expected = load_preset("srpb") | {"psi": -3.0, "collision": -40.0}
    assert weights == {t: expected.get(t, 0.0) for t in TERMS}
    task = dict(zip(TERMS, resolve_weights("task", None, scenario).tolist()))
    assert task["time"] == -0.5 and task["psi"] == 0.0


def test_an_environment_pays_the_scenarios_weights(tmp_path) -> None:
    path = str(_file(tmp_path))
    env = gym.make("SRPB-Custom-v0", scenario=path)
    assert _weights(env)["psi"] == -2.0 and _weights(env)["collision"] == -40.0
    assert _weights(env)["fsi"] == load_preset("srpb")["fsi"]
    env.reset(seed=0)
    paid = 0.0
    for _ in range(120):  # towards the walker: personal-space intrusion is paid at -2 per s
        _, reward, terminated, truncated, info = env.step(np.array([0.6, 0.0], np.float32))
        assert info["reward_psi"] == pytest.approx(-2.0 * info["srpb_step/psi"])
        assert reward == pytest.approx(sum(info[f"reward_{t}"] for t in TERMS))
        paid += info["srpb_step/psi"]
        if terminated or truncated:
            break
    env.close()
    assert paid > 0.0
    override = gym.make("SRPB-Custom-v0", scenario=path, reward_weights={"psi": -1.5})
    assert _weights(override)["psi"] == -1.5 and _weights(override)["collision"] == -40.0
    task = gym.make("SRPB-Custom-v0", scenario=path, reward="task")
    assert _weights(task) == {t: load_preset("task").get(t, 0.0) for t in TERMS}
    override.close()
    task.close()


def test_packaged_scenarios_pay_the_documented_preset() -> None:
    """gym.make(id) pays the preset as configs/reward/ and the env docstring give it, in
    every packaged scenario; reset's info says the weights in force."""
    for preset in ("srpb", "task"):
        expected = {t: load_preset(preset).get(t, 0.0) for t in TERMS}
        for env_id in SCENARIO_IDS:
            env = gym.make(env_id, reward=preset)
            assert _weights(env) == expected, (env_id, preset)
            _, info = env.reset(seed=0)
            assert info["reward_weights"] == expected
            env.close()


def test_the_docstring_table_is_the_presets() -> None:
    rows = {}
    for line in (SRPBNavEnv.__doc__ or "").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0] in TERMS:
            rows[cells[0]] = cells[1:3]
    assert set(rows) == set(TERMS)
    for term, (srpb, task) in rows.items():
        assert float(srpb) == load_preset("srpb").get(term, 0.0), term
        assert float(task) == load_preset("task").get(term, 0.0), term


def test_each_scenario_of_a_mixture_and_each_robot_keep_their_weights(tmp_path) -> None:
    path = tmp_path / "weighted.yaml"
    path.write_text(SCENARIO, encoding="utf-8")
    env = gym.make("SRPB-Mix-v0", scenarios=["crowd", str(path)]).unwrapped
    assert env.task_of("weighted").reward_fn.weights[TERMS.index("psi")] == -2.0
    assert env.task_of("crowd").reward_fn.weights[TERMS.index("psi")] == -1.0
    _, info = env.reset(seed=0, options={"scenario": "weighted"})
    assert info["reward_weights"]["psi"] == -2.0
    _, info = env.reset(seed=0, options={"scenario": "crowd"})
    assert info["reward_weights"]["psi"] == -1.0
    env.close()
    multi = SRPBParallelEnv(scenario=str(path), n_robots=1)
    assert [t.reward_fn.weights[TERMS.index("collision")] for t in multi.tasks] == [-40.0]
    multi.close()


def test_gameable_scenario_weights_warn_and_are_refused_for_training(tmp_path) -> None:
    gameable = SCENARIO.replace("{psi: -2.0, collision: -40.0}", "{psi: -2.0}")
    path = str(_file(tmp_path, gameable))
    env = gym.make("SRPB-Custom-v0", scenario=path)
    with pytest.warns(RewardGameableWarning, match="collision penalty"):
        env.reset(seed=0)
    env.close()
    with pytest.raises(InputError, match="in scenario 'weighted' can cost up to"):
        check_env_args("SRPB-Custom-v0", "srpb", {"scenario": path}, 0.99)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RewardGameableWarning)
        check_env_args("SRPB-Custom-v0", "srpb", {"scenario": str(_file(tmp_path))}, 0.99)
