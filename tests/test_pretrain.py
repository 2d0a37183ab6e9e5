"""The behaviour-cloning warm start: returns computed as VecNormalize and PPO see them, and
a cloned policy that acts like its planner with the statistics it was fitted on."""

from __future__ import annotations

import numpy as np
import pytest

from srpb_gym.training.pretrain import collect, discounted_returns, running_returns


def test_discounted_returns_restart_at_each_episode_end():
    rewards = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    dones = np.array([False, False, True, False, True])
    out = discounted_returns(rewards, dones, 0.5)
    # episode 1: 1 + 0.5 * (2 + 0.5 * 3) = 2.75; 2 + 1.5 = 3.5; 3; episode 2: 4 + 2.5, 5
    np.testing.assert_allclose(out, [2.75, 3.5, 3.0, 6.5, 5.0])


def test_running_returns_accumulate_like_vecnormalize():
    rewards = np.array([1.0, 2.0, 3.0, 4.0])
    dones = np.array([False, True, False, False])
    np.testing.assert_allclose(running_returns(rewards, dones, 0.5), [1.0, 2.5, 3.0, 5.5])


def test_collect_records_the_planner_action_not_the_noisy_one():
    demos = collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 1, noise=0.3)
    again = collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 1, noise=0.3)
    assert demos.obs.shape[0] == demos.actions.shape[0] == demos.rewards.shape[0] > 10
    assert demos.dones[-1] and demos.dones.sum() == 1
    assert np.all(np.abs(demos.actions) <= 1.0)
    np.testing.assert_array_equal(demos.actions, again.actions)  # seeded noise
    clean = collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 1, noise=0.0)
    assert not np.array_equal(clean.obs[:10], demos.obs[:10])  # the noise was executed
    # and not recorded: go-to-goal's own command changes little from step to step, the
    # noisy one would by about 0.3
    assert np.abs(np.diff(demos.actions[:, 0])).mean() < 0.1


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_pretrain_clones_the_planner_and_sets_the_statistics():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from srpb_gym.training.config import Pretraining, TrainConfig
    from srpb_gym.training.pretrain import pretrain
    from srpb_gym.training.run import make_vec_env

    config = TrainConfig(n_envs=1, n_steps=64, batch_size=64, net_arch=(64, 64))
    venv = VecNormalize(make_vec_env("SRPB-Corridor-v0", config, {"reward": "task"}, 0))
    assert isinstance(venv.venv, DummyVecEnv)
    model = PPO("MlpPolicy", venv, seed=0, **{**config.ppo_kwargs(), "n_steps": 64})
    demos = collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 2, noise=0.0)
    before, _ = model.predict(demos.obs, deterministic=True)
    settings = Pretraining(planner="go-to-goal", episodes=2, epochs=40, noise=0.0, log_std=-1.5)
    report = pretrain(model, venv, "SRPB-Corridor-v0", {"reward": "task"}, settings,
                      gamma=0.99, log=lambda _: None)  # fmt: skip
    assert report["demo_episodes"] == 2 and report["demo_steps"] > 20
    assert venv.obs_rms.count > report["demo_steps"] and venv.ret_rms.count > 1
    np.testing.assert_allclose(model.policy.log_std.detach().numpy(), -1.5)
    after, _ = model.predict(venv.normalize_obs(demos.obs), deterministic=True)
    error_before = float(np.mean((before - demos.actions) ** 2))
    error_after = float(np.mean((after - demos.actions) ** 2))
    assert error_after < 0.1 * error_before, (error_before, error_after)
    # the report's error is the fit's on its own demonstrations (other episodes than the
    # two collected here): the same order, and as far below the error before
    assert report["action_mse"] < 0.1 * error_before
    assert report["action_mse"] == pytest.approx(error_after, rel=1.0)


MIX = {"reward": "task", "scenarios": ["corridor", "crossing"]}


def _episodes(demos):
    """The recorded actions of each episode, in order."""
    ends = np.flatnonzero(demos.dones) + 1
    return np.split(demos.actions, ends[:-1])


def test_each_scenario_of_a_mixture_is_driven_by_its_teacher():
    alone = collect("SRPB-Mix-v0", MIX, "go-to-goal", 6, noise=0.0)
    assert set(alone.scenarios) == {"corridor", "crossing"} and alone.episodes == 6
    named = collect("SRPB-Mix-v0", MIX, "", 6, noise=0.0,
                    teachers={"corridor": "go-to-goal", "crossing": "go-to-goal"})  # fmt: skip
    np.testing.assert_array_equal(named.actions, alone.actions)
    mixed = collect("SRPB-Mix-v0", MIX, "go-to-goal", 6, noise=0.0, teachers={"crossing": "dwa"})
    assert mixed.scenarios == alone.scenarios
    for scenario, ours, theirs in zip(mixed.scenarios, _episodes(mixed), _episodes(alone)):
        if scenario == "corridor":  # the fallback planner, as alone
            np.testing.assert_array_equal(ours, theirs)
        else:  # dwa, which slows down and turns where go-to-goal does not
            assert ours.shape != theirs.shape or not np.array_equal(ours, theirs)
    counts = mixed.by_scenario()
    assert sum(n for n, _ in counts.values()) == 6
    assert counts["crossing"][1] == sum(
        r for s, r in zip(mixed.scenarios, mixed.reached) if s == "crossing"
    )


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_teacher_whose_scenario_was_never_drawn_is_reported():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from srpb_gym.training.config import Pretraining, TrainConfig
    from srpb_gym.training.pretrain import pretrain
    from srpb_gym.training.run import make_vec_env

    kwargs = {**MIX, "weights": [1, 1e-9]}
    config = TrainConfig(n_envs=1, n_steps=64, batch_size=64, net_arch=(16,))
    venv = VecNormalize(make_vec_env("SRPB-Mix-v0", config, kwargs, 0))
    model = PPO("MlpPolicy", venv, seed=0, **config.ppo_kwargs())
    lines: list[str] = []
    settings = Pretraining(planner="go-to-goal", teachers={"crossing": "dwa"}, episodes=2,
                           epochs=1, noise=0.0, log_std=-1.0)  # fmt: skip
    report = pretrain(model, venv, "SRPB-Mix-v0", kwargs, settings, gamma=0.99,
                      log=lines.append)  # fmt: skip
    venv.close()
    assert report["teachers_without_episodes"] == ["crossing"]
    assert list(report["demo_by_scenario"]) == ["corridor"]
    assert lines[-1] == ("warning: no demonstration episode drew crossing: dwa taught nothing "
                         "(raise pretrain_episodes or the scenario's weight)")  # fmt: skip


def test_a_scenario_never_drawn_needs_no_teacher():
    kwargs = {**MIX, "weights": [1, 0]}
    demos = collect("SRPB-Mix-v0", kwargs, "", 2, noise=0.0, teachers={"corridor": "go-to-goal"})
    assert demos.scenarios == ("corridor", "corridor")


@pytest.mark.parametrize(
    ("env_id", "kwargs", "planner", "teachers", "expected"),
    [
        (
            "SRPB-Corridor-v0",
            {},
            "",
            {"corridor": "dwa"},
            "pretrain_teachers: SRPB-Corridor-v0 draws no scenarios",
        ),
        (
            "SRPB-Mix-v0",
            MIX,
            "dwa",
            {"crowd": "dwa"},
            "pretrain_teachers: crowd: no scenario of SRPB-Mix-v0 (its scenarios: corridor, "
            "crossing)",
        ),
        (
            "SRPB-Mix-v0",
            MIX,
            "",
            {"corridor": "dwa"},
            "pretrain_planner: no teacher for crossing: name it in pretrain_teachers",
        ),
    ],
)
def test_teacher_errors(env_id, kwargs, planner, teachers, expected):
    from srpb_gym.errors import InputError

    with pytest.raises(InputError) as err:
        collect(env_id, {"reward": "task", **kwargs}, planner, 1, noise=0.0, teachers=teachers)
    assert expected in str(err.value)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_trained_model_teaches_with_its_own_statistics(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3 import PPO

    from srpb_gym.errors import InputError
    from srpb_gym.planners.learned import LearnedPolicy

    demos = collect("SRPB-Corridor-v0", {"reward": "srpb"}, "ppo-corridor-srpb", 1, noise=0.2)
    assert demos.episodes == 1 and len(demos.obs) > 20
    policy = LearnedPolicy(_shipped("ppo-corridor-srpb"))
    assert policy._normalizer is not None
    normalized = policy._normalizer.normalize_obs(demos.obs)
    expected = policy.model.predict(normalized, deterministic=True)[0]
    np.testing.assert_allclose(demos.actions, expected, atol=1e-6)
    # a student that observes otherwise is taught the same: the teacher observes as trained
    kwargs = {"reward": "srpb", "observation": {"lidar_encoding": "log"}}
    student = collect("SRPB-Corridor-v0", kwargs, "ppo-corridor-srpb", 1, noise=0.2)
    np.testing.assert_array_equal(student.actions, demos.actions)
    assert not np.array_equal(student.obs[:, 8:38], demos.obs[:, 8:38])  # log lidar
    np.testing.assert_array_equal(np.delete(student.obs, np.s_[8:38], 1),
                                  np.delete(demos.obs, np.s_[8:38], 1))  # fmt: skip

    env = gym.make("SRPB-Corridor-v0", observation={"people": 3})
    PPO("MlpPolicy", env, n_steps=64, batch_size=64).save(tmp_path / "other.zip")
    env.close()
    with pytest.raises(InputError) as err:
        collect("SRPB-Mix-v0", MIX, "dwa", 1, noise=0.0,
                teachers={"crossing": str(tmp_path / "other.zip")})  # fmt: skip
    assert str(err.value).startswith("pretrain_teachers.crossing: ")
    assert "trained for the observation space" in str(err.value)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_trained_teacher_leaves_the_run_generators_alone():
    """Loading a model seeds the global generators with the seed it was trained with
    (0 for the shipped models): runs of different seeds that learn from it would draw the
    same numbers in PPO afterwards."""
    torch = pytest.importorskip("torch")
    import random

    torch.manual_seed(7)
    np.random.seed(7)
    random.seed(7)
    before = (torch.get_rng_state(), np.random.get_state()[1].copy(), random.getstate())
    collect("SRPB-Mix-v0", MIX, "go-to-goal", 1, noise=0.0,
            teachers={"corridor": "ppo-corridor-srpb"})  # fmt: skip
    assert torch.equal(torch.get_rng_state(), before[0])
    np.testing.assert_array_equal(np.random.get_state()[1], before[1])
    assert random.getstate() == before[2]


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_loading_a_model_leaves_the_global_generators_alone(tmp_path):
    """stable-baselines3's load seeds them with the model's own seed; a training run loads
    models for its warm start and for every periodic evaluation (in its own process)."""
    torch = pytest.importorskip("torch")
    import random

    from stable_baselines3 import PPO

    from srpb_gym.evaluation.harness import run_evaluation
    from srpb_gym.evaluation.spec import resolve_config
    from srpb_gym.models import global_rngs_kept
    from srpb_gym.planners.learned import LearnedPolicy

    def states():
        return torch.get_rng_state(), np.random.get_state()[1].copy(), random.getstate()

    def same(a, b):
        return torch.equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2] == b[2]

    torch.manual_seed(7)
    np.random.seed(7)
    random.seed(7)
    before = states()
    with global_rngs_kept():
        PPO.load(_shipped("ppo-corridor-srpb"), device="cpu")  # re-seeds: the guard undoes it
        assert not same(states(), before)
    assert same(states(), before)
    LearnedPolicy(_shipped("ppo-corridor-srpb"))
    assert same(states(), before)
    config = resolve_config(["SRPB-Corridor-v0"], policies=[_shipped("ppo-corridor-srpb")],
                            episodes=1, seed=1_000_000, out=str(tmp_path / "eval"),
                            warmup=0, log=None)  # fmt: skip
    run_evaluation(config, log=None, progress=False)  # as the periodic evaluation does
    assert same(states(), before)


def _shipped(name: str) -> str:
    from srpb_gym.models import model_path

    path = model_path(name)
    assert path is not None
    return str(path)


def test_a_driver_drives_and_the_teacher_labels_each_step():
    seen: list[np.ndarray] = []

    def stand(obs):
        seen.append(obs.copy())
        return np.zeros(2, np.float32)  # a stop command: never reaches the goal

    short = {"reward": "task", "max_episode_steps": 40}
    alone = collect("SRPB-Corridor-v0", short, "go-to-goal", 1, noise=0.0)
    driven = collect("SRPB-Corridor-v0", short, "go-to-goal", 1, noise=0.0, driver=stand)
    np.testing.assert_array_equal(driven.obs, np.asarray(seen))  # the driver saw every step
    assert driven.reached == (False,)  # the driver's outcome
    # the labels are go-to-goal's: it drives ahead, its first command is the same as alone
    np.testing.assert_array_equal(driven.actions[0], alone.actions[0])
    assert np.all(driven.actions[:, 0] > 0.1)
    # the driver's stop commands were executed, not the teacher's: the same start, then
    # another episode than go-to-goal's own
    assert driven.obs.shape == alone.obs.shape  # neither reaches the goal in 40 steps
    np.testing.assert_array_equal(driven.obs[0], alone.obs[0])
    assert not np.allclose(driven.obs[5:], alone.obs[5:], atol=0.05)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_dagger_rounds_let_the_clone_drive_on_later_seeds(monkeypatch):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from srpb_gym.training import pretrain as module
    from srpb_gym.training.config import Pretraining, TrainConfig
    from srpb_gym.training.run import make_vec_env

    calls = []
    real = module.collect

    def spy(*args, **kwargs):
        demos = real(*args, **kwargs)
        calls.append((args[3], kwargs.get("seed", module.DEMO_SEED), kwargs.get("driver"),
                      len(demos.obs)))  # fmt: skip
        return demos

    monkeypatch.setattr(module, "collect", spy)
    kwargs = {"reward": "task", "max_episode_steps": 60}
    config = TrainConfig(n_envs=1, n_steps=64, batch_size=64, net_arch=(16,))
    venv = VecNormalize(make_vec_env("SRPB-Corridor-v0", config, kwargs, 0))
    model = PPO("MlpPolicy", venv, seed=0, **config.ppo_kwargs())
    lines: list[str] = []
    settings = Pretraining(planner="go-to-goal", episodes=2, epochs=2, noise=0.0, log_std=-1.0,
                           dagger_rounds=2, dagger_episodes=3)  # fmt: skip
    report = module.pretrain(model, venv, "SRPB-Corridor-v0", kwargs, settings, gamma=0.99,
                             log=lines.append)  # fmt: skip
    # the teacher's 2 episodes, then two rounds of 3 driven by the clone, on the next seeds
    assert [(n, seed) for n, seed, _, _ in calls] == [
        (2, module.DEMO_SEED), (3, module.DEMO_SEED + 2), (3, module.DEMO_SEED + 5)
    ]  # fmt: skip
    assert calls[0][2] is None and all(driver is not None for _, _, driver, _ in calls[1:])
    assert [r["episodes"] for r in report["dagger"]] == [3, 3]
    assert [r["steps"] for r in report["dagger"]] == [c[3] for c in calls[1:]]
    assert report["demo_episodes"] == 2 and report["demo_steps"] == calls[0][3]
    assert venv.obs_rms.count > sum(c[3] for c in calls)  # every step went into the statistics
    assert lines[0].startswith("DAgger round 1: the clone reached the goal in ")
    assert f"{sum(c[3] for c in calls[1:])} DAgger steps" in lines[-1]
    # the driver is the clone itself: its action for an observation is the policy's
    obs = real("SRPB-Corridor-v0", kwargs, "go-to-goal", 1, noise=0.0).obs[:3]
    drive = calls[1][2]
    expected, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
    np.testing.assert_allclose([drive(o) for o in obs], expected, atol=1e-6)
    venv.close()


def test_a_reference_planner_teaches_with_the_true_people(monkeypatch):
    """A privileged teacher: handed the true people (zero covariance, every person) while
    it drives the demonstrations; the recorded observations stay the robot's own."""
    from srpb_gym.planners.reference import OracleDWA

    handed: list[tuple[int, float]] = []
    act = OracleDWA.act

    def spy(self, observation, knowledge):
        tracks = knowledge.tracks
        handed.append((len(tracks.ids), float(np.abs(tracks.covariance).sum())))
        return act(self, observation, knowledge)

    monkeypatch.setattr(OracleDWA, "act", spy)
    short = {"reward": "task", "max_episode_steps": 60}
    demos = collect("SRPB-Corridor-v0", short, "oracle-dwa", 1, noise=0.0)
    plain = collect("SRPB-Corridor-v0", short, "dwa", 1, noise=0.0)
    assert len(handed) == demos.actions.shape[0] == 60
    assert all(n == 2 and cov == 0.0 for n, cov in handed)  # both walkers, exactly
    np.testing.assert_array_equal(demos.obs[0], plain.obs[0])  # the same observation
