"""Conformance and behaviour of the Gymnasium environments, over every registered id."""

from __future__ import annotations

import json
import math
import pickle
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import srpb_gym
from srpb_gym.cli import main as cli_main
from srpb_gym.metrics import METRIC_NAMES, evaluate
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.registration import CUSTOM_ID, SCENARIO_IDS
from tests.helpers import same

ENVS = Path(srpb_gym.__file__).resolve().parents[1] / "envs"
IDS = [*SCENARIO_IDS, CUSTOM_ID]


def make(env_id: str, **kwargs) -> gym.Env:
    if env_id == CUSTOM_ID:
        kwargs.setdefault("scenario", str(ENVS / "doorway.yaml"))
    return gym.make(env_id, **kwargs)


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0):
    """Observations, rewards and infos of a seeded run with timed-out planning time."""
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, info)]
    for _ in range(steps):
        env.unwrapped.set_planning_time(0.001)
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1, 1, env.action_space.shape)
        )
        out.append((obs, reward, info))
        if terminated or truncated:
            obs, info = env.reset()
            out.append((obs, 0.0, info))
    return out


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_checker(env_id):
    env = make(env_id)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("env_id", IDS)
def test_stable_baselines3_checker(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = make(env_id)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_rollout(env_id):
    a = rollout(make(env_id), seed=7, steps=120)
    b = rollout(make(env_id), seed=7, steps=120)
    assert len(a) == len(b)
    for (oa, ra, ia), (ob, rb, ib) in zip(a, b):
        assert same(oa, ob) and ra == rb and same(ia, ib)
    c = rollout(make(env_id), seed=8, steps=5)
    assert not same(a[1][0], c[1][0])


@pytest.mark.parametrize("observation", ["flat", "dict"])
def test_observations_never_share_memory(observation):
    env = make("SRPB-Crowd-v0", observation=observation)
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        nxt, *_ = env.step(env.action_space.sample())
        pairs = [(obs, nxt)] if observation == "flat" else [(obs[k], nxt[k]) for k in obs]
        assert not any(np.shares_memory(x, y) for x, y in pairs)
        assert env.observation_space.contains(nxt)
        obs = nxt


@pytest.mark.parametrize("env_id", IDS)
def test_spec_is_json_and_info_keys_stable(env_id):
    env = make(env_id)
    assert json.loads(env.spec.to_json())["id"] == env_id
    _, info = env.reset(seed=0)
    keys = {k: type(v) for k, v in info.items()}
    assert not any(k.startswith(("srpb/", "srpb_gt/")) for k in keys)  # not computed yet
    assert keys.pop("reward_weights") is dict  # the weights in force: at reset only
    for _ in range(5):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            break
        assert {k: type(v) for k, v in info.items()} == keys


def test_pickling_keeps_the_episode():
    env = make("SRPB-Corridor-v0")
    env.reset(seed=3)
    for _ in range(5):
        env.unwrapped.set_planning_time(0.001)
        env.step(np.array([0.5, 0.1], dtype=np.float32))
    clone = pickle.loads(pickle.dumps(env))
    for e in (env, clone):
        e.unwrapped.set_planning_time(0.001)
    a = env.step(np.array([0.3, -0.2], dtype=np.float32))
    b = clone.step(np.array([0.3, -0.2], dtype=np.float32))
    assert same(a[0], b[0]) and a[1] == b[1] and same(a[4], b[4])


@pytest.mark.parametrize("vector", ["sync", "async"])
def test_vector_envs(vector):
    cls = gym.vector.SyncVectorEnv if vector == "sync" else gym.vector.AsyncVectorEnv
    envs = cls([lambda: gym.make("SRPB-Corridor-v0") for _ in range(2)])
    obs, infos = envs.reset(seed=[0, 1])
    assert obs.shape == (2, *envs.single_observation_space.shape)
    for _ in range(10):
        obs, rewards, _term, _trunc, infos = envs.step(envs.action_space.sample())
    assert rewards.shape == (2,) and infos["goal_distance"].shape == (2,)
    assert "srpb/m_psi" not in infos  # no episode has ended
    envs.close()
    # an episode that ends shows its metrics, and the mask says which env ended
    envs = cls([lambda i=i: gym.make("SRPB-Corridor-v0", max_episode_steps=5 + i)
                for i in range(2)])  # fmt: skip
    envs.reset(seed=[0, 1])
    for _ in range(5):
        _, _, _, truncated, infos = envs.step(np.zeros((2, 2), dtype=np.float32))
    assert truncated.tolist() == [True, False]
    assert infos["_srpb/m_psi"].tolist() == [True, False]
    assert np.isfinite(infos["srpb/m_mef"][0]) and infos["srpb/m_mef"][0] == pytest.approx(0.5)
    envs.close()


@pytest.mark.filterwarnings("ignore::srpb_gym.reward.RewardGameableWarning")
@pytest.mark.parametrize("env_id", IDS)
def test_reward_is_the_sum_of_its_terms(env_id):
    env = make(env_id, reward_weights={"vsm": -0.5, "psi": -3.0})
    for _, reward, info in rollout(env, seed=1, steps=150)[1:]:
        terms = sum(v for k, v in info.items() if k.startswith("reward_"))
        assert reward == pytest.approx(terms, abs=1e-12)


def run_episode(env: gym.Env, seed: int, controller, options: dict | None = None) -> dict:
    """The last info of an episode driven by ``controller(env) -> action``."""
    _, info = env.reset(seed=seed, options=options)
    done = False
    while not done:
        env.unwrapped.set_planning_time(0.002)
        _, _, terminated, truncated, info = env.step(controller(env))
        done = terminated or truncated
    return info


def go_to_goal(env: gym.Env) -> np.ndarray:
    """A proportional controller on the true pose: turn towards the goal, drive, then turn
    to the goal heading."""
    sim = env.unwrapped.sim
    x, y, yaw = sim.world.robot_pose[0]
    gx, gy, gyaw = sim.robots[0].goal
    dist = math.hypot(gx - x, gy - y)
    target = math.atan2(gy - y, gx - x) if dist > 0.1 else gyaw
    err = math.remainder(target - yaw, 2 * math.pi)
    speed = 0.0 if dist <= 0.1 else min(1.0, dist) * max(0.0, math.cos(err)) ** 4
    return np.array([speed, np.clip(2.0 * err, -1, 1)], dtype=np.float32)


# scenarios whose goal is in straight sight of the start (fformation's route bends round
# cabinets, doorway's through a door)
@pytest.mark.parametrize("env_id", ["SRPB-Corridor-v0", "SRPB-Crossing-v0", "SRPB-Crowd-v0"])
def test_go_to_goal_reaches_the_goal_of_an_empty_scenario(env_id):
    env = make(env_id)
    for seed in range(3):
        info = run_episode(env, seed, go_to_goal, {"people": False})
        assert info["is_success"] and not info["collision"], (seed, info["goal_distance"])
        assert info["srpb/m_goal"] == 1.0 and info["srpb/m_psi"] == 0.0


def test_episode_metrics_equal_offline_evaluation(tmp_path):
    env = make("SRPB-FFormation-v0", record_dir=str(tmp_path))
    info = run_episode(env, 4, go_to_goal)
    stem = tmp_path / env.unwrapped.episode_name()
    record = load_record(f"{stem}.npz")
    offline = evaluate(record)
    truth = evaluate(load_record(f"{stem}_gt.npz"))
    for name in METRIC_NAMES:
        assert same(info[f"srpb/{name}"], offline[name]), name
        assert same(info[f"srpb_gt/{name}"], truth[name]), name
    assert info["srpb/m_cef"] == pytest.approx(2.0)
    # the command line on the full-precision file: exactly; on the native logs: to rounding
    assert cli_main(["metrics", f"{stem}.npz", "--json"]) == 0


def test_cli_reproduces_info(tmp_path, capsys):
    env = make("SRPB-Corridor-v0", record_dir=str(tmp_path))
    info = run_episode(env, 2, go_to_goal)
    stem = tmp_path / env.unwrapped.episode_name()
    capsys.readouterr()
    assert cli_main(["metrics", f"{stem}.npz", "--json"]) == 0
    exact = json.loads(capsys.readouterr().out)
    assert cli_main(["metrics", f"{stem}_robot.txt", "--json"]) == 0
    rounded = json.loads(capsys.readouterr().out)
    for name in METRIC_NAMES:
        value = info[f"srpb/{name}"]
        assert same(float(exact[name]) if exact[name] != "NaN" else math.nan, value), name
        assert float(rounded[name]) == pytest.approx(value, rel=0.02, abs=0.05), name


def test_step_terms_add_up_to_the_episode_metrics():
    env = make("SRPB-Crossing-v0")
    env.reset(seed=5)
    totals: dict[str, float] = {}
    info: dict = {}
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(go_to_goal(env))
        for k, v in info.items():
            if k.startswith("srpb_step/"):
                totals[k[10:]] = totals.get(k[10:], 0.0) + v
        done = terminated or truncated
    duration = info["srpb/m_mef"]
    assert totals["obs"] == pytest.approx(info["srpb/m_obs"] * duration / 100)
    assert totals["chc"] == pytest.approx(info["srpb/m_chc"])
    assert totals["bwd"] == pytest.approx(info["srpb/m_bwd"] * duration / 100)
    record = env.unwrapped.sim.robots[0].record
    with_people = np.zeros(record.n_samples, dtype=bool)
    with_people[record.people_sample] = True
    busy = float(np.diff(record.robot_col("t"))[with_people[:-1]].sum())
    assert totals["psi"] == pytest.approx(info["srpb/m_psi"] * busy / 100)
    assert totals["dir"] == pytest.approx(info["srpb/m_dir"] * busy / 100)


def test_actions_are_checked_and_clipped():
    env = make("SRPB-Corridor-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))
    a, b = make("SRPB-Corridor-v0"), make("SRPB-Corridor-v0")
    a.reset(seed=1), b.reset(seed=1)
    for _ in range(5):
        for e in (a, b):
            e.unwrapped.set_planning_time(0.0)
        oa, *_ = a.step(np.array([5.0, -9.0], dtype=np.float32))
        ob, *_ = b.step(np.array([1.0, -1.0], dtype=np.float32))
        assert np.array_equal(oa, ob)


def test_zero_action_is_stop_and_mapping():
    env = make("SRPB-Corridor-v0")
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.array([1.0, 0.0], dtype=np.float32))
    assert env.unwrapped.sim.velocity[0, 0] == pytest.approx(0.5, abs=0.01)
    for _ in range(10):
        env.step(np.zeros(2, dtype=np.float32))
    assert env.unwrapped.sim.velocity[0] == pytest.approx([0.0, 0.0, 0.0], abs=0.01)


def test_holonomic_robot_has_three_action_dims():
    env = make("SRPB-Corridor-v0", robot={"kinematics": "holonomic"})
    assert env.action_space.shape == (3,)
    env.reset(seed=0)
    env.step(np.array([0.0, 1.0, 0.0], dtype=np.float32))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scenario": "nowhere"}, "unknown scenario"),
        ({"reward": "fast"}, "unknown reward preset"),
        ({"reward_weights": {"speed": 1.0}}, "unknown reward term"),
        ({"collision": "ignore"}, "collision"),
        ({"observation": {"type": "image"}}, "observation type"),
        ({"metrics": {"semantics": "other"}}, "semantics"),
        ({"metrics": {"params": {"safety": 1.0}}}, "unknown metric parameter"),
        ({"sensors": {"sonar": "x"}}, "sensors.sonar: unknown sensor"),
        ({"sim": {"physics_dt": 0.03}}, "whole multiple"),
        ({"observation": {"lidar_bins": 1000}}, "lidar_bins: 1000 lidar sectors need"),
        ({"metrics": "paper"}, "metrics: expected a mapping"),
        ({"sensors": [1]}, "sensors: expected a mapping"),
    ],
)
def test_bad_arguments(kwargs, message):
    with pytest.raises((ValueError, KeyError), match=message):
        gym.make("SRPB-Corridor-v0", **kwargs)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"start": (math.nan, 1.0, 0.0)}, r"options\.start: expected \(x, y, yaw\), three finite"),
        ({"goal": (1.0, 1.0)}, r"options\.goal: expected \(x, y, yaw\)"),
        ({"start": "here"}, r"options\.start: expected"),
        ({"start": (50.0, 1.0, 0.0)}, r"options\.start: a robot of radius 0.275 m at \(50, 1\)"),
        ({"start": (2.0, 0.1, 0.0)}, r"options\.start: a robot .* overlaps a wall"),
        ({"goal": (5.0, 2.15, 0.0)}, r"options\.goal: a robot .* overlaps"),
    ],
)
def test_reset_poses_are_checked(options, message):
    env = make("SRPB-Corridor-v0")
    with pytest.raises(ValueError, match=message):
        env.reset(seed=0, options=options)


def test_reset_goal_must_be_reachable(tmp_path):
    room = tmp_path / "closet.yaml"
    room.write_text(
        "name: closet\nbounds: [0, 0, 10, 5]\n"
        "walls: [[6, 1, 8, 1], [8, 1, 8, 4], [8, 4, 6, 4], [6, 4, 6, 1]]  # a closed box\n"
        "robot: {start: {position: [1, 2.5], yaw_deg: 0}, goal: {position: [4, 2.5], "
        "yaw_deg: 0}}\n"
    )
    env = gym.make("SRPB-Custom-v0", scenario=str(room))
    env.reset(seed=0, options={"goal": (9.0, 2.5, 0.0)})  # around the box: reachable
    with pytest.raises(ValueError, match=r"options\.goal: the goal is not reachable"):
        env.reset(seed=0, options={"goal": (7.0, 2.5, 0.0)})  # inside the box


def test_bad_reset_options():
    env = make("SRPB-Corridor-v0")
    with pytest.raises(ValueError, match=r"options\.crowd: unknown reset option"):
        env.reset(seed=0, options={"crowd": 3})


def test_collision_modes():
    for mode, expect_end in (("terminate", True), ("continue", False)):
        env = make("SRPB-Corridor-v0", collision=mode, reward="task")
        env.reset(seed=0, options={"people": False, "start": (2.0, 1.1, math.pi / 2)})
        ended, hit = False, False
        for _ in range(60):
            _, _reward, terminated, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
            hit |= info["collision"]
            if info["collision"]:
                assert info["reward_collision"] == -25.0 and not info["is_success"]
            if terminated:
                ended = True
                break
        assert hit and ended == expect_end


def test_make_without_prior_import():
    env = gym.make("srpb_gym:SRPB-Corridor-v0")
    assert env.spec.max_episode_steps == 600


def test_render_draws_the_robot_where_it_is(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    env = make("SRPB-Corridor-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frames = []
    for _ in range(2):
        for _ in range(15):
            env.step(np.array([1.0, 0.0], dtype=np.float32))
        frame = env.render()
        assert frame.shape == (540, 720, 3) and frame.dtype == np.uint8
        x, y = env.unwrapped.sim.world.robot_pose[0, :2]
        px, py = env.unwrapped._renderer.world_to_pixel(x, y)
        from srpb_gym.render import ROBOT_COLOR

        assert tuple(frame[py, px]) == tuple(ROBOT_COLOR[:3])
        frames.append((px, py))
    assert frames[1][0] > frames[0][0]  # drove right, drawn further right
    env.close()
    plain = make("SRPB-Corridor-v0")
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert plain.render() is None


def test_monitor_logs_episode_metrics(tmp_path):
    monitor = pytest.importorskip("stable_baselines3.common.monitor")
    keys = ("srpb/m_psi", "srpb/m_goal", "is_success")
    env = monitor.Monitor(make("SRPB-Corridor-v0"), str(tmp_path / "run"), info_keywords=keys)
    info = run_episode(env, 0, lambda e: go_to_goal(e))
    logged = info["episode"]
    assert {"r", "l", "t"} <= logged.keys()
    lines = (tmp_path / "run.monitor.csv").read_text().splitlines()
    assert lines[1].split(",")[3:] == list(keys)
    assert lines[2].split(",")[3:] == [str(info[k]) for k in keys]


def test_knowledge_is_what_the_robot_knows():
    env = make("SRPB-Crowd-v0")
    env.reset(seed=2)
    for _ in range(10):
        env.step(np.array([0.5, 0.2], dtype=np.float32))
    k = env.unwrapped.knowledge()
    sim = env.unwrapped.sim
    tracks = sim.robots[0].tracker.tracks()
    assert np.array_equal(k.tracks.ids, tracks.ids) and np.array_equal(k.tracks.xy, tracks.xy)
    assert not np.array_equal(k.tracks.xy, sim.world.people_xy[: len(k.tracks.xy)])  # noisy
    assert np.array_equal(k.pose, sim.world.robot_pose[0]) and k.scan.shape == (181,)
    assert k.goal_tolerance == 0.2 and k.control_dt == 0.1 and k.t == pytest.approx(1.0)


def _entry_of(scenario, start, goal) -> int | None:
    """The index of the robots entry whose start and goal places hold ``start``, ``goal``."""

    def inside(place, pose) -> bool:
        return place.xmin <= pose[0] <= place.xmax and place.ymin <= pose[1] <= place.ymax

    for i, spec in enumerate(scenario.robots):
        if inside(spec.start.place, start) and inside(spec.goal.place, goal):
            return i
    return None


def test_route_drives_a_robots_entry():
    env = gym.make("SRPB-Crowd-v0", route=2).unwrapped
    scenario = env.scenario
    for seed in range(3):
        env.reset(seed=seed)
        robot = env.sim.layout.robots[0]
        assert _entry_of(scenario, robot.start, robot.goal) == 2
        assert robot.start[0] > robot.goal[0] + 8.0  # right to left
    # the default: the robot entry, the same episodes as before the argument existed
    plain = gym.make("SRPB-Crowd-v0").unwrapped
    plain.reset(seed=5)
    from srpb_gym.scenarios import sample

    expected = sample(plain.scenario, np.random.default_rng(np.random.SeedSequence(5)))
    assert plain.sim.layout.robots == expected.robots


def test_random_route_draws_every_entry_from_the_env_generator():
    env = gym.make("SRPB-Crowd-v0", route="random").unwrapped
    entries = []
    for seed in range(40):
        env.reset(seed=seed)
        robot = env.sim.layout.robots[0]
        entries.append(_entry_of(env.scenario, robot.start, robot.goal))
    assert None not in entries and set(entries) == set(range(len(env.scenario.robots)))
    again = gym.make("SRPB-Crowd-v0", route="random").unwrapped
    for seed in (3, 17):
        env.reset(seed=seed)
        again.reset(seed=seed)
        assert env.sim.layout.robots == again.sim.layout.robots


def test_a_list_of_routes_draws_its_entries_as_often_as_listed():
    env = gym.make("SRPB-Crowd-v0", route=[0, 2, 2]).unwrapped
    assert env.route == (0, 2, 2)
    entries = []
    for seed in range(90):
        env.reset(seed=seed)
        robot = env.sim.layout.robots[0]
        entries.append(_entry_of(env.scenario, robot.start, robot.goal))
    assert set(entries) == {0, 2}
    # entry 2 is drawn with probability 2/3: 60 of 90 expected, 3 standard deviations 13
    assert 47 <= entries.count(2) <= 73
    again = gym.make("SRPB-Crowd-v0", route=(0, 2, 2)).unwrapped
    for seed in (4, 11):
        env.reset(seed=seed)
        again.reset(seed=seed)
        assert env.sim.layout.robots == again.sim.layout.robots
    # a single entry listed is that entry's route
    one, fixed = (gym.make("SRPB-Crowd-v0", route=r).unwrapped for r in ([1], 1))
    one.reset(seed=7)
    fixed.reset(seed=7)
    for made in (one, fixed):
        robot = made.sim.layout.robots[0]
        assert _entry_of(made.scenario, robot.start, robot.goal) == 1


@pytest.mark.parametrize(
    ("route", "message"),
    [
        ("any", r"route: expected a robots entry's index, a list of them or 'random', got 'any'"),
        ([], r"route: expected at least one robots entry in the list"),
        ([0, 9], r"route: scenario 'crowd' has its robots entries 0-7, got 9"),
        ([0, "1"], r"route: scenario 'crowd' has its robots entries 0-7, got '1'"),
        (8, r"route: scenario 'crowd' has its robots entries 0-7, got 8"),
        (-1, r"route: scenario 'crowd' has its robots entries 0-7, got -1"),
        (True, r"route: scenario 'crowd' has its robots entries 0-7, got True"),
        (1.0, r"route: scenario 'crowd' has its robots entries 0-7, got 1.0"),
    ],
)
def test_bad_routes(route, message):
    with pytest.raises(ValueError, match=message):
        gym.make("SRPB-Crowd-v0", route=route)


def test_routes_need_robots_entries_with_the_robot_s_goal_tolerance(tmp_path):
    room = tmp_path / "room.yaml"
    base = (
        "name: room\nbounds: [0, 0, 10, 5]\n"
        "robot: {start: {position: [1, 2.5], yaw_deg: 0}, goal: {position: [9, 2.5], "
        "yaw_deg: 0}}\n"
    )
    room.write_text(base)
    with pytest.raises(ValueError, match=r"route: scenario 'room' has no robots entries to draw"):
        gym.make("SRPB-Custom-v0", scenario=str(room), route="random")
    room.write_text(
        base + "robots:\n"
        "  - {start: {position: [1, 1]}, goal: {position: [9, 1]}}\n"
        "  - {start: {position: [9, 4]}, goal: {position: [1, 4]}, goal_tolerance: 0.5}\n"
    )
    env = gym.make("SRPB-Custom-v0", scenario=str(room), route=0).unwrapped
    env.reset(seed=0)
    assert env.sim.layout.robots[0].start[:2] == (1.0, 1.0)
    with pytest.raises(ValueError, match=r"room.yaml:6: robots\[1\]\.goal_tolerance: a "
                       r"route's goal tolerance must be the robot entry's \(0.2 m\)"):  # fmt: skip
        gym.make("SRPB-Custom-v0", scenario=str(room), route="random")
