"""SRPB-Mix-v0: one scenario drawn per reset from a weighted list, one pair of spaces."""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle
import warnings
from collections import Counter

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym.env import SRPBNavEnv
from srpb_gym.errors import InputError
from srpb_gym.metrics import METRIC_NAMES
from srpb_gym.mix import SRPBMixEnv
from srpb_gym.observation import ObservationConfig
from srpb_gym.registration import MIX_ID, MIX_SCENARIOS, SCENARIO_IDS
from srpb_gym.resources import scenarios_dir
from srpb_gym.settings import EnvSettings
from tests.helpers import same

STOP = np.zeros(2, dtype=np.float32)


def rollout(env: gym.Env, steps: int, action_seed: int = 0) -> list:
    """Every step's outcome under random actions (planning time fixed); after an episode
    ends, the next one starts with an unseeded reset."""
    rng = np.random.default_rng(action_seed)
    out = []
    for _ in range(steps):
        env.unwrapped.set_planning_time(0.001)
        result = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        out.append(result)
        if result[2] or result[3]:
            out.append(env.reset())
    return out


def scenario_file(tmp_path, base: str, name: str, **changes) -> str:
    """A copy of the packaged scenario ``base`` named ``name``, with top-level changes."""
    data = yaml.safe_load((scenarios_dir() / f"{base}.yaml").read_text(encoding="utf-8"))
    data |= {"name": name, **changes}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


def test_registered_id():
    env = gym.make(MIX_ID)
    base = env.unwrapped
    assert isinstance(base, SRPBMixEnv) and isinstance(base, SRPBNavEnv)
    assert base.scenarios == MIX_SCENARIOS == ("corridor", "fformation", "crossing", "crowd",
                                               "doorway")  # fmt: skip
    assert base.weights == pytest.approx([0.2] * 5)
    # the step limit covers the longest scenario (at the 0.1 s control step)
    limits = [base.scenario_of(s).time_limit for s in MIX_SCENARIOS]
    assert env.spec.max_episode_steps == max(math.ceil(t / 0.1 - 1e-9) for t in limits)
    assert min(limits) < max(limits)  # the scenarios end at different times
    for name in MIX_SCENARIOS:
        assert base.scenario_of(name).name == name
        single = gym.make(next(k for k, v in SCENARIO_IDS.items() if v == name)).unwrapped
        assert base.params_of(name) == single.params
    with pytest.raises(InputError, match="'office' is not a scenario") as caught:
        base.params_of("office")
    assert caught.value.key == "name"
    assert env.observation_space == gym.make("SRPB-Corridor-v0").observation_space
    assert env.action_space == gym.make("SRPB-Crowd-v0").action_space


def test_gymnasium_checker():
    env = gym.make(MIX_ID)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught] == []


def test_stable_baselines3_checker():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(MIX_ID)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("seed", [0, 3, 11])
def test_same_seed_same_scenario_and_episode(seed):
    a, b = gym.make(MIX_ID), gym.make(MIX_ID)
    first = [env.reset(seed=seed) for env in (a, b)]
    assert same(first[0][0], first[1][0]) and same(first[0][1], first[1][1])
    assert first[0][1]["scenario"] == a.unwrapped.scenario.name == b.unwrapped.scenario.name
    for x, y in zip(rollout(a, 50), rollout(b, 50), strict=True):
        assert all(same(u, v) for u, v in zip(x, y, strict=True))
    # the stream goes on: the next unseeded episodes agree too
    for _ in range(3):
        (oa, ia), (ob, ib) = a.reset(), b.reset()
        assert same(oa, ob) and same(ia, ib)


def test_different_seeds_give_different_episodes():
    env = gym.make(MIX_ID)
    starts = {}
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        starts[seed] = (info["scenario"], obs.tobytes())
    assert len({s for s, _ in starts.values()}) == 5  # every scenario drawn
    assert len({o for _, o in starts.values()}) == 20


def test_draw_frequencies_follow_the_weights():
    env = gym.make(MIX_ID, scenarios=["corridor", "crowd"], weights=[1, 3])
    assert env.unwrapped.weights == pytest.approx([0.25, 0.75])
    counts = Counter(env.reset(seed=seed)[1]["scenario"] for seed in range(200))
    # binomial(200, 0.75): mean 150, sd 6.1; 4.5 sd either side
    assert set(counts) == {"corridor", "crowd"} and 122 <= counts["crowd"] <= 178


def test_equal_weights_by_default():
    env = gym.make(MIX_ID)
    env.reset(seed=123)
    counts = Counter(env.reset()[1]["scenario"] for _ in range(200))  # unseeded: the stream
    expected = 200 / 5
    chi2 = sum((counts[s] - expected) ** 2 / expected for s in MIX_SCENARIOS)
    assert chi2 < 18.47  # chi-square, 4 degrees of freedom, p = 0.001


def test_a_scenario_of_weight_zero_is_never_drawn_but_can_be_forced():
    env = gym.make(MIX_ID, scenarios=["corridor", "doorway", "crowd"], weights=[1, 0, 1.5])
    drawn = {env.reset(seed=seed)[1]["scenario"] for seed in range(60)}
    assert drawn == {"corridor", "crowd"}
    _, info = env.reset(seed=0, options={"scenario": "doorway"})
    assert info["scenario"] == "doorway" == env.unwrapped.scenario.name


def test_forcing_a_scenario_keeps_the_rest_of_the_stream():
    env, twin = gym.make(MIX_ID), gym.make(MIX_ID)
    for seed in range(5):
        obs, info = env.reset(seed=seed)
        forced = twin.reset(seed=seed, options={"scenario": info["scenario"]})
        assert same(obs, forced[0]) and same(info, forced[1])
    for name in MIX_SCENARIOS:  # each scenario, whatever the draw
        _, info = env.reset(seed=7, options={"scenario": name})
        assert info["scenario"] == name and env.unwrapped.episode_name() == f"{name}_seed7"
        assert env.unwrapped.sim.layout.time_limit == env.unwrapped.scenario.time_limit


def test_forcing_by_file_and_options_of_the_scenario(tmp_path):
    lab = scenario_file(tmp_path, "doorway", "lab")
    env = gym.make(MIX_ID, scenarios=["corridor", lab])
    for given in ("lab", lab):
        _, info = env.reset(seed=1, options={"scenario": given, "people": False})
        assert info["scenario"] == "lab" and env.unwrapped.sim.layout.people == ()
    _, info = env.reset(seed=1, options={"scenario": "corridor", "start": (2.0, 1.1, 0.0)})
    assert np.allclose(env.unwrapped.sim.world.robot_pose[0], (2.0, 1.1, 0.0))


@pytest.mark.parametrize(
    ("options", "key", "message"),
    [
        ({"scenario": "office"}, "options.scenario", "'office' is not a scenario of the mixture"),
        ({"scenario": 3}, "options.scenario", "choose one of: corridor, crowd"),
        ({"crowd": 3}, "options.crowd", "unknown reset option; valid: scenario, people"),
        ({"scenario": "crowd", "start": (50.0, 1.0, 0.0)}, "options.start", "a robot of"),
    ],
)
def test_bad_reset_options_change_nothing(options, key, message):
    env = gym.make(MIX_ID, scenarios=["corridor", "crowd"])
    twin = gym.make(MIX_ID, scenarios=["corridor", "crowd"])
    env.reset(seed=4)
    twin.reset(seed=4)
    before = env.unwrapped.scenario.name
    with pytest.raises(InputError, match=message) as caught:
        env.reset(options=options)
    assert caught.value.key == key
    assert env.unwrapped.scenario.name == before
    (oa, ia), (ob, ib) = env.reset(), twin.reset()
    assert same(oa, ob) and same(ia, ib)


@pytest.mark.parametrize(
    ("kwargs", "key", "message"),
    [
        ({"scenarios": ["corridor", "office"]}, "scenarios[1]", "unknown scenario 'office'"),
        ({"scenarios": "crowd"}, "scenarios", r"write \['crowd'\] for one scenario"),
        ({"scenarios": []}, "scenarios", "at least one scenario"),
        ({"scenarios": {"crowd": 1}}, "scenarios", "expected a list"),
        ({"scenarios": ["crowd", 3]}, "scenarios[1]", "expected a scenario name or file"),
        ({"scenarios": ["crowd", "corridor", "crowd"]}, "scenarios[2]",
         r"'crowd' is already in the mixture \(scenarios\[0\]\)"),
        ({"weights": [1, 1]}, "weights", r"one weight per scenario \(5\), got 2"),
        ({"scenarios": ["crowd"], "weights": [1, 2]}, "weights", r"\(1\), got 2"),
        ({"weights": [1, -1, 1, 1, 1]}, "weights[1]", "finite number >= 0, got -1"),
        ({"weights": [1, 1, math.nan, 1, 1]}, "weights[2]", "finite number >= 0"),
        ({"weights": [1, 1, 1, 1, True]}, "weights[4]", "finite number >= 0, got True"),
        ({"weights": [0, 0, 0, 0, 0]}, "weights", "the weights are all 0"),
        ({"weights": "equal"}, "weights", "expected a list of numbers"),
        ({"scenarios": ["crowd"], "observation": {"lidar_bins": 1000}},
         "observation.lidar_bins", r"need .* \(in scenario 'crowd'\)"),
    ],
)  # fmt: skip
def test_bad_arguments(kwargs, key, message):
    with pytest.raises(InputError, match=message) as caught:
        gym.make(MIX_ID, **kwargs)
    assert caught.value.key == key


def test_a_scenario_file_error_names_the_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nbounds: [0, 0, 10, 5]\n", encoding="utf-8")
    with pytest.raises(InputError, match="robot") as caught:
        gym.make(MIX_ID, scenarios=["corridor", str(bad)])
    assert caught.value.path == str(bad)


def test_different_spaces_are_refused(monkeypatch):
    """A scenario whose observation would differ is refused, naming it and the space."""

    built = EnvSettings.task

    def task(self, sim, robot, scenario, n_robots=1):
        if scenario.name == "crowd":
            self = dataclasses.replace(self, observation=ObservationConfig(people=4))
        return built(self, sim, robot, scenario, n_robots)

    monkeypatch.setattr(EnvSettings, "task", task)
    with pytest.raises(InputError, match=r"'crowd' gives the observation_space Box") as caught:
        gym.make(MIX_ID, scenarios=["corridor", "doorway", "crowd"])
    assert caught.value.key == "scenarios[2]"
    assert "scenario 'corridor'" in caught.value.message
    gym.make(MIX_ID, scenarios=["corridor", "doorway"])  # the same spaces: fine


def test_a_different_lidar_is_reported(tmp_path):
    wide = scenario_file(tmp_path, "crowd", "wide", sensors={"lidar": {"fov": 6.283}})
    with pytest.warns(UserWarning, match="scenario 'wide': its lidar"):
        env = gym.make(MIX_ID, scenarios=["corridor", wide])
    assert env.observation_space == gym.make("SRPB-Corridor-v0").observation_space


def test_episodes_end_at_their_own_time_limit():
    env = gym.make(MIX_ID)
    limits = {name: env.unwrapped.scenario_of(name).time_limit for name in MIX_SCENARIOS}
    shortest, longest = min(limits, key=limits.get), max(limits, key=limits.get)
    for name, limit in ((shortest, limits[shortest]), (longest, limits[longest])):
        _, info = env.reset(seed=0, options={"scenario": name, "people": False})
        assert info["scenario"] == name and "srpb/m_goal" not in info
        steps = 0
        while True:
            _, _, terminated, truncated, info = env.step(STOP)
            steps += 1
            if terminated or truncated:
                break
            assert info["scenario"] == name and "srpb/m_goal" not in info
        assert truncated and not terminated and info["t"] == pytest.approx(limit)
        assert steps == round(limit / 0.1) <= env.spec.max_episode_steps
        assert info["scenario"] == name
        assert {f"srpb/{m}" for m in METRIC_NAMES} <= info.keys()
        assert {f"srpb_gt/{m}" for m in METRIC_NAMES} <= info.keys()
        assert info["srpb/m_goal"] == 0.0


def test_a_step_limit_applies_to_every_scenario():
    env = gym.make(MIX_ID, max_episode_steps=7)
    for name in ("fformation", "crossing"):
        env.reset(seed=2, options={"scenario": name})
        for step in range(7):
            _, _, terminated, truncated, info = env.step(STOP)
            assert truncated == (step == 6) and not terminated
        assert info["scenario"] == name and "srpb/m_psi" in info


def test_a_longer_scenario_than_the_registered_limit_is_reported(tmp_path):
    slow = scenario_file(tmp_path, "corridor", "slow", time_limit=120.0)
    with pytest.warns(UserWarning, match=r"slow \(120 s\).*max_episode_steps=1200"):
        gym.make(MIX_ID, scenarios=["crowd", slow])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym.make(MIX_ID, scenarios=["crowd", slow], max_episode_steps=1200)
        gym.make(MIX_ID)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_goes_on_like_the_original(how):
    env = gym.make(MIX_ID)
    env.reset(seed=5)
    rollout(env, 5)
    clone = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert clone.unwrapped.scenario.name == env.unwrapped.scenario.name
    for x, y in zip(rollout(env, 50, 1), rollout(clone, 50, 1), strict=True):
        assert all(same(u, v) for u, v in zip(x, y, strict=True))
    for _ in range(3):  # the scenario draws go on alike
        (oa, ia), (ob, ib) = env.reset(), clone.reset()
        assert same(oa, ob) and same(ia, ib)


def test_records_knowledge_and_render(tmp_path):
    env = gym.make(MIX_ID, record_dir=str(tmp_path), render_mode="rgb_array",
                   max_episode_steps=3)  # fmt: skip
    base = env.unwrapped
    for name in ("corridor", "crowd"):  # rooms of different sizes, one renderer
        env.reset(seed=9, options={"scenario": name})
        k = base.knowledge()
        assert np.allclose(k.bounds, tuple(base.scenario.bounds))  # this episode's room
        assert np.array_equal(k.walls, base.scenario.walls)
        assert np.array_equal(k.pose, base.sim.world.robot_pose[0])
        frame = env.render()
        assert frame.ndim == 3 and frame.shape[2] == 3
        for _ in range(3):
            env.step(STOP)
        assert (tmp_path / f"{name}_seed9.npz").is_file()
        assert (tmp_path / f"{name}_seed9_robot.txt").is_file()
    env.close()


def test_vector_env_and_monitor(tmp_path):
    envs = gym.vector.SyncVectorEnv([lambda: gym.make(MIX_ID) for _ in range(2)])
    _, infos = envs.reset(seed=[0, 1])
    expected = [gym.make(MIX_ID).reset(seed=s)[1]["scenario"] for s in (0, 1)]
    assert list(infos["scenario"]) == expected
    envs.close()
    monitor = pytest.importorskip("stable_baselines3.common.monitor")
    keys = ("scenario", "srpb/m_goal")
    env = monitor.Monitor(gym.make(MIX_ID, max_episode_steps=4), str(tmp_path / "run"),
                          info_keywords=keys)  # fmt: skip
    _, info = env.reset(seed=3)
    for _ in range(4):
        *_, info = env.step(STOP)
    lines = (tmp_path / "run.monitor.csv").read_text().splitlines()
    assert lines[1].split(",")[3:] == list(keys)
    assert lines[2].split(",")[3] == info["scenario"]
