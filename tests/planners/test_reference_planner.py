"""The reference planner: handed the true people (only it), built by name, kept out of the
default planners, and run end to end by ``srpb-gym eval --planner oracle-social-dwa``."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.cli import main
from srpb_gym.errors import InputError
from srpb_gym.evaluation import resolve_config, run_episode
from srpb_gym.knowledge import true_people
from srpb_gym.pettingzoo_env import parallel_env
from srpb_gym.planners import (
    PLANNERS,
    REFERENCE_PLANNERS,
    GoToGoal,
    OracleSocialDWA,
    OracleSocialDWAConfig,
    SocialDWA,
    SocialDWAConfig,
    check_settings,
    knowledge_for,
    make_planner,
    planner_class,
)

ORACLE = "oracle-social-dwa"


def _truth(sim) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return sim.world.people_xy.copy(), sim.world.people_velocity.copy(), sim.crowd.yaw.copy()


@pytest.fixture(scope="module")
def crowd():
    """SRPB-Crowd-v0 some steps into an episode (people walking, tracks noisy)."""
    env = gym.make("SRPB-Crowd-v0")
    env.reset(seed=3_000_000)
    for _ in range(40):
        env.step(np.array([0.3, 0.1], np.float32))
    yield env.unwrapped
    env.close()


def test_ground_truth_knowledge_holds_the_true_people(crowd):
    sim = crowd.sim
    xy, velocity, yaw = _truth(sim)
    tracks = crowd.knowledge(ground_truth=True).tracks
    assert np.array_equal(tracks.ids, np.arange(sim.n_people))
    assert np.array_equal(tracks.xy, xy) and np.array_equal(tracks.velocity, velocity)
    assert np.array_equal(tracks.yaw, yaw)
    assert np.array_equal(tracks.covariance, np.zeros((sim.n_people, 2, 2)))
    assert np.all(tracks.age == sim.t) and np.all(tracks.time_since_update == 0.0)
    assert tracks.matched.all() and np.all(tracks.detection == -1)
    assert not tracks.xy.flags.writeable  # read-only, like the tracker's views
    # the rest of the snapshot is the robot's own
    normal, truth = crowd.knowledge(), crowd.knowledge(ground_truth=True)
    for name in ("walls", "pose", "velocity", "command", "goal", "scan", "scan_angles"):
        assert np.array_equal(getattr(normal, name), getattr(truth, name)), name


def test_normal_knowledge_holds_the_trackers_people(crowd):
    tracks = crowd.knowledge().tracks
    expected = crowd.sim.robots[0].tracker.tracks()
    for got, want in zip(tracks, expected):
        assert np.array_equal(got, want)
    xy, _, _ = _truth(crowd.sim)
    assert tracks.xy.shape != xy.shape or not np.array_equal(tracks.xy, xy)


def test_true_people_of_an_empty_scene():
    tracks = true_people(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), 1.0)
    assert tracks.xy.shape == (0, 2) and tracks.covariance.shape == (0, 2, 2)


def test_knowledge_for_hands_the_truth_to_reference_planners_only(crowd):
    xy, _, _ = _truth(crowd.sim)
    for name in REFERENCE_PLANNERS:
        tracks = knowledge_for(make_planner(name), crowd.knowledge).tracks
        assert np.array_equal(tracks.xy, xy), name
    for name in PLANNERS:
        tracks = knowledge_for(make_planner(name), crowd.knowledge).tracks
        assert np.array_equal(tracks.ids, crowd.sim.robots[0].tracker.tracks().ids), name
    assert all(cls.ground_truth for cls in REFERENCE_PLANNERS.values())
    assert not any(cls.ground_truth for cls in PLANNERS.values())


class _Spy(GoToGoal):
    """Checks, at every step, which people it is handed."""

    def __init__(self, env, truth: bool) -> None:
        super().__init__()
        self.env, self.truth, self.steps = env, truth, 0

    def act(self, observation, knowledge):
        sim = self.env.unwrapped.sim
        want = sim.world.people_xy if self.truth else sim.robots[0].tracker.tracks().xy
        assert np.array_equal(knowledge.tracks.xy, want)
        self.steps += 1
        return super().act(observation, knowledge)


@pytest.mark.parametrize("truth", [False, True])
def test_the_episode_loop_hands_each_planner_its_people(truth):
    env = gym.make("SRPB-Crossing-v0", max_episode_steps=30)
    spy = _Spy(env, truth)
    spy.ground_truth = truth  # an instance attribute shadows the class's
    run_episode(env, spy, seed=3_000_000)
    assert spy.steps == 30
    env.close()


def test_the_multi_robot_environment_hands_the_truth_on_request():
    par = parallel_env(scenario="crossing", n_robots=2)
    par.reset(seed=3_000_000)
    agent = par.agents[1]
    xy = par.sim.world.people_xy
    assert np.array_equal(par.knowledge(agent, ground_truth=True).tracks.xy, xy)
    assert par.knowledge(agent).tracks.xy.shape[0] <= xy.shape[0]
    par.close()


def test_registered_apart_and_built_by_name():
    assert ORACLE in REFERENCE_PLANNERS and ORACLE not in PLANNERS
    assert planner_class(ORACLE) is OracleSocialDWA
    planner = make_planner(ORACLE, {"w_psi": 3.0, "global_planner": {"spacing": 0.2}})
    assert isinstance(planner, SocialDWA) and isinstance(planner.config, OracleSocialDWAConfig)
    assert planner.config.w_psi == 3.0 and planner.planner.config.spacing == 0.2
    assert planner.planner.config.walking_cost == 100.0  # the reference planner's default
    assert check_settings({ORACLE: {"w_psi": 3.0}}) == {ORACLE: {"w_psi": 3.0}}
    with pytest.raises(KeyError, match=ORACLE):  # the message names the reference planners
        make_planner("no-such-planner")


def test_same_robot_limits_and_map_as_social_dwa():
    """Only people-related settings differ from the social DWA's: no robot limit, no wall
    margin, no sampling or horizon of the trajectories."""
    ours, theirs = OracleSocialDWAConfig(), SocialDWAConfig()
    changed = {f for f in vars(ours) if getattr(ours, f) != getattr(theirs, f, None)}
    assert changed <= {"person_margin", "standing_margin", "people_horizon", "w_psi", "w_dir",
                       "psi_layer", "walking_layer", "global_planner"}  # fmt: skip
    gp_ours, gp_theirs = ours.global_planner, theirs.global_planner
    gp_changed = {f for f in vars(gp_ours) if getattr(gp_ours, f) != getattr(gp_theirs, f)}
    assert gp_changed <= {"walking_cost", "person_horizon", "settle_time", "hysteresis"}


def test_not_among_the_default_planners(tmp_path):
    config = resolve_config(out=str(tmp_path / "d"), log=None)
    assert ORACLE not in [p.name for p in config.planners]
    notes: list[str] = []
    config = resolve_config(planners=[ORACLE], out=str(tmp_path / "o"), log=notes.append)
    assert [p.planner for p in config.planners] == [ORACLE]
    assert any("reference planner" in n and ORACLE in n for n in notes)
    with pytest.raises(InputError, match="unknown planner"):
        resolve_config(planners=["oracle"], out=str(tmp_path / "x"), log=None)


def test_eval_runs_it_when_named(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["eval", "--env", "SRPB-FFormation-v0", "--planner", ORACLE, "--episodes", "2",
                 "--seed", "3000000", "--warmup", "0", "--out", str(out)]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert "reference planner" in captured.err
    with open(out / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["planner"], r["seed"]) for r in rows] == [(ORACLE, "3000000"), (ORACLE, "3000001")]
    assert all(r["is_success"] == "1" for r in rows)
    described = json.loads((out / "config.json").read_text())["planners"][0]
    assert described["class"].endswith("OracleSocialDWA") and described["planner"] == ORACLE
    assert Path(out / "episodes" / "SRPB-FFormation-v0" / ORACLE).is_dir()


def test_docs_list_every_default_that_differs_from_social_dwa():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "planners.md").read_text()
    section = doc.split("### `OracleSocialDWAConfig`")[1].split("\n### ")[0]
    ours, theirs = OracleSocialDWAConfig(), SocialDWAConfig()
    for name in vars(ours):
        if name != "global_planner" and getattr(ours, name) != getattr(theirs, name, None):
            given = f"`{getattr(theirs, name)}`" if hasattr(theirs, name) else "-"
            assert f"| `{name}` | `{getattr(ours, name)}` | {given} |" in section, name
    gp_ours, gp_theirs = ours.global_planner, theirs.global_planner
    for name in vars(gp_ours):
        if getattr(gp_ours, name) != getattr(gp_theirs, name):
            row = f"| `global_planner.{name}` | `{getattr(gp_ours, name)}` | "
            assert row + f"`{getattr(gp_theirs, name)}` |" in section, name


def test_standing_people_keep_the_smaller_margin():
    """In the trajectory checks a person predicted standing gets ``standing_margin``, a
    walking one ``person_margin`` (beyond the two radii)."""
    env = gym.make("SRPB-FFormation-v0")
    env.reset(seed=3_000_000)
    planner = OracleSocialDWA({"people_range": 50.0})
    k = knowledge_for(planner, env.unwrapped.knowledge)
    planner.reset(k)
    tracks = k.tracks._replace(
        xy=k.pose[:2] + np.array([[3.0, 0.0], [0.0, 3.0]]),
        velocity=np.array([[0.0, 0.0], [0.5, 0.0]]), ids=np.arange(2), yaw=np.zeros(2),
        covariance=np.zeros((2, 2, 2)),
    )  # fmt: skip
    people = planner._people(dataclasses.replace(k, tracks=tracks))
    radii = planner.planner.robot_radius + planner.config.person_radius
    assert np.allclose(people[:, 4], radii + np.array([0.1, 0.4]))
    env.close()


def test_oracle_dwa_is_dwa_with_its_settings_and_the_true_people():
    from srpb_gym.planners import DWA, DWAConfig

    planner = make_planner("oracle-dwa", {"horizon": 2.0})
    assert isinstance(planner, DWA) and planner.ground_truth and "oracle-dwa" not in PLANNERS
    assert planner.config == DWAConfig(horizon=2.0)
