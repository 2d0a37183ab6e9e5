"""A warm start for PPO: behaviour cloning of a classical planner or of trained models.

PPO from random weights with the ``srpb`` preset does not find its way around the
standing pair of ``fformation`` (0 % success in five runs): exploration never reaches
the goal often enough to learn from it. A policy that starts where a classical planner
is, and is then improved by PPO on the reward, does; it also lets both reward presets
start from the same policy, so that what differs between their models is the reward's
doing (the shipped corridor models and the generalist clone ``dwa``; the fformation ones
clone ``social-dwa``, whose route around the pair the ``srpb`` preset keeps and the
``task`` preset wears down towards the pair). :func:`pretrain` drives ``episodes``
episodes with a teacher, on the demonstration seeds (from :data:`DEMO_SEED`:
:data:`srpb_gym.seeds.DEMONSTRATIONS`, apart from training, checkpoint-selection,
validation and test seeds): a planner of :mod:`srpb_gym.planners` (a baseline or a
reference planner, which is handed the true people while it teaches: a privileged
teacher, the student still observes only what the robot senses) or a trained model
(:func:`make_teacher`), and for a mixture of scenarios a teacher per scenario, so
that specialists are distilled into one policy. Then it:

1. sets the ``VecNormalize`` statistics (observations, discounted returns) from the
   demonstrations, so that the first PPO update sees the inputs the policy was fitted on;
2. fits the policy's action mean to the teachers' actions (mean squared error) and its
   value network to the demonstrations' discounted normalised returns;
3. optionally, for ``dagger_rounds`` rounds (DAgger, Ross et al. 2011), lets the clone
   drive more episodes (the next demonstration seeds), has the teachers label every step
   with their own action, and fits the policy and value network again on all the steps
   so far, with the statistics updated: the clone learns what to do in the states its
   own errors lead to;
4. sets the policy's log standard deviation to ``log_std`` (PPO's own start, 0, is a
   standard deviation of 1 on actions in [-1, 1]: it would undo the cloning at once).

While collecting, the executed action is the teacher's (in a DAgger round the clone's)
plus Gaussian noise of standard deviation ``noise``; the recorded target stays the
teacher's own action, so that the demonstrations also show how to get back from the small
errors the clone will make. A classical teacher labelling a DAgger round keeps its own
memory of what it commanded (``dwa``'s previous turn rate, its recovery and impatience
timers), not of what the clone did; a learned teacher acts on the observation alone,
built with its own observation settings where its model records them (a teacher trained
with ``lidar_encoding: log`` teaches a student that observes linearly, and the reverse).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.evaluation.policies import load_policy
from srpb_gym.evaluation.spec import PlannerSpec
from srpb_gym.models.files import resolve_model
from srpb_gym.models.record import lidar_beams_of
from srpb_gym.planners import is_planner, make_planner
from srpb_gym.planners.base import Planner, knowledge_for
from srpb_gym.seeds import DEMONSTRATIONS, check_not_test, check_within
from srpb_gym.training.config import Pretraining

#: first seed of the demonstration episodes (:data:`srpb_gym.seeds.DEMONSTRATIONS`)
DEMO_SEED = DEMONSTRATIONS.start

#: a policy that drives instead of the teachers (raw observation -> action)
Driver = Callable[[np.ndarray], np.ndarray]


@dataclass
class Demonstrations:
    """Raw observations, the teachers' actions, rewards and episode ends (step-aligned);
    the scenario of each episode (``""`` for an environment without scenarios to draw)
    and whether it reached the goal."""

    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    scenarios: tuple[str, ...] = ()
    reached: tuple[bool, ...] = ()

    @property
    def episodes(self) -> int:
        return len(self.reached)

    @property
    def successes(self) -> int:
        return sum(self.reached)

    def by_scenario(self) -> dict[str, tuple[int, int]]:
        """Episodes and successes of each scenario, by scenario name."""
        out: dict[str, tuple[int, int]] = {}
        for name, success in zip(self.scenarios, self.reached):
            n, k = out.get(name, (0, 0))
            out[name] = (n + 1, k + success)
        return dict(sorted(out.items()))


def make_teacher(teacher: str, env: gym.Env, key: str = "pretrain_planner",
                 trust_pickle: bool = False) -> Planner:  # fmt: skip
    """The planner behind ``teacher``: a classical or reference planner by its name
    (:data:`~srpb_gym.planners.PLANNERS`, :data:`~srpb_gym.planners.REFERENCE_PLANNERS`),
    or a learned one (a shipped model's name, a model file or a run folder holding
    ``model.zip``, with its observation statistics; their pickles unpickled only with
    ``trust_pickle``), checked to act on ``env``'s spaces. Failures are an
    :class:`InputError` naming ``key``."""
    if is_planner(teacher):
        return make_planner(teacher)
    try:
        path, vecnormalize = resolve_model(teacher, key)
        policy = load_policy(PlannerSpec(name=teacher, policy=path, vecnormalize=vecnormalize,
                                         trust_pickle=trust_pickle))  # fmt: skip
        policy.check_spaces(env.observation_space, env.action_space, lidar_beams_of(env))
    except InputError as exc:
        raise InputError(exc.message, exc.path, key=key) from None
    except ValueError as exc:  # the spaces check; its message names the model file
        raise InputError(str(exc), key=key) from None
    return policy


def collect(env_id: str, env_kwargs: Mapping[str, Any], planner: str, episodes: int,
            noise: float, seed: int = DEMO_SEED,
            teachers: Mapping[str, str] | None = None,
            driver: Driver | None = None,
            trust_pickle: bool = False) -> Demonstrations:  # fmt: skip
    """Drive ``episodes`` episodes of ``env_id`` (seeds from ``seed``) with ``planner``
    (executed actions with Gaussian noise ``noise``, drawn from a generator seeded with
    ``seed``). ``teachers``: the teacher of each scenario of a mixture
    (``info["scenario"]``) instead of ``planner``; an empty ``planner`` then requires a
    teacher for every scenario. ``driver``: a policy (raw observation -> action) that
    drives instead of the teachers, which then only label each step with their action
    (DAgger); ``reached`` is then the driver's success. Seeds that meet the test seeds, or
    leave the demonstration seeds, are an :class:`InputError` (``pretrain seed``).
    ``trust_pickle``: let the pickles of learned teachers be unpickled."""
    check_not_test(seed, episodes, "pretrain seed")
    check_within(DEMONSTRATIONS, seed, episodes, "pretrain seed")
    env = gym.make(env_id, **env_kwargs)
    base = env.unwrapped
    teachers = dict(teachers or {})
    scenarios = tuple(getattr(base, "scenarios", ()))
    try:
        if teachers and not scenarios:
            raise InputError(f"{env_id} draws no scenarios: give one teacher in "
                             "pretrain_planner", key="pretrain_teachers")  # fmt: skip
        unknown = sorted(set(teachers) - set(scenarios))
        if unknown:
            raise InputError(f"{', '.join(unknown)}: no scenario of {env_id} (its scenarios: "
                             f"{', '.join(scenarios)})", key="pretrain_teachers")  # fmt: skip
        drawn = [n for n, w in zip(scenarios, getattr(base, "weights", ())) if w > 0]
        untaught = [name for name in drawn if name not in teachers]
        if not planner and (untaught or not scenarios):
            raise InputError(f"no teacher for {', '.join(untaught) or env_id}: name it in "
                             "pretrain_teachers or give pretrain_planner",
                             key="pretrain_planner")  # fmt: skip
        agents = {name: make_teacher(teacher, env, f"pretrain_teachers.{name}", trust_pickle)
                  for name, teacher in teachers.items()}  # fmt: skip
        fallback = None
        if planner and (untaught or not scenarios):
            fallback = make_teacher(planner, env, trust_pickle=trust_pickle)
        rng = np.random.default_rng(seed)
        obs_l, act_l, rew_l, done_l = [], [], [], []
        scenario_l: list[str] = []
        reached_l: list[bool] = []
        for episode in range(episodes):
            obs, info = env.reset(seed=seed + episode)
            scenario = str(info.get("scenario", ""))
            agent = agents.get(scenario, fallback)
            assert agent is not None  # every scenario has a teacher (checked above)
            agent.reset(knowledge_for(agent, base.knowledge))
            scenario_l.append(scenario)
            while True:
                action = np.asarray(agent.act(obs, knowledge_for(agent, base.knowledge)),
                                    dtype=np.float32)  # fmt: skip
                base.set_planning_time(0.0)
                executed = action if driver is None else np.asarray(driver(obs), np.float32)
                if noise > 0:
                    executed = np.clip(executed + rng.normal(0.0, noise, action.shape), -1, 1)
                obs_l.append(obs)
                act_l.append(action)
                obs, reward, terminated, truncated, info = env.step(executed.astype(np.float32))
                rew_l.append(reward)
                done_l.append(terminated or truncated)
                if terminated or truncated:
                    reached_l.append(bool(info.get("is_success", False)))
                    break
    finally:
        env.close()
    return Demonstrations(np.asarray(obs_l, np.float32), np.asarray(act_l, np.float32),
                          np.asarray(rew_l, np.float64), np.asarray(done_l, bool),
                          tuple(scenario_l), tuple(reached_l))  # fmt: skip


def discounted_returns(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """Return from each step to the end of its episode, discounted by ``gamma``."""
    out = np.empty_like(rewards)
    running = 0.0
    for i in range(len(rewards) - 1, -1, -1):
        if dones[i]:
            running = 0.0
        running = rewards[i] + gamma * running
        out[i] = running
    return out


def running_returns(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """The discounted return accumulated so far at each step, as ``VecNormalize`` keeps
    it to scale rewards (reset after each episode's last step)."""
    out = np.empty_like(rewards)
    running = 0.0
    for i in range(len(rewards)):
        running = running * gamma + rewards[i]
        out[i] = running
        if dones[i]:
            running = 0.0
    return out


def pretrain(model: Any, venv: Any, env_id: str, env_kwargs: Mapping[str, Any],
             settings: Pretraining, *, gamma: float, log: Callable[[str], None] = print,
             trust_pickle: bool = False) -> dict[str, Any]:  # fmt: skip
    """Warm-start ``model`` (an SB3 ``PPO`` discounting by ``gamma``) and ``venv`` (its
    ``VecNormalize``, or any other VecEnv when observations are not normalised) from the
    demonstrations of ``settings.planner`` (and of ``settings.teachers``, by scenario:
    :func:`collect`); then, for each of ``settings.dagger_rounds`` rounds, the clone drives
    ``settings.dagger_episodes`` more episodes, the teachers label every step, and the
    policy is fitted again on all the steps so far (DAgger: the clone learns what to do in
    the states its own errors lead to, which the teachers' demonstrations seldom show).
    Returns what happened (demonstration success rate, by scenario too, the clone's success
    in each round, steps, final losses, wall time). ``trust_pickle``: let the pickles of
    learned teachers be unpickled (``--trust-pickle``)."""
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    planner, teachers, episodes = settings.planner, settings.teachers, settings.episodes
    epochs, noise, log_std = settings.epochs, settings.noise, settings.log_std
    dagger_rounds, dagger_episodes = settings.dagger_rounds, settings.dagger_episodes

    if dagger_rounds and dagger_episodes < 1:
        raise ValueError(f"dagger_episodes: must be >= 1 with DAgger rounds, got {dagger_episodes}")
    started = time.perf_counter()
    normalize = isinstance(venv, VecNormalize)
    rounds = [collect(env_id, env_kwargs, planner, episodes, noise, teachers=teachers,
                      trust_pickle=trust_pickle)]  # fmt: skip
    policy = model.policy
    generator = torch.Generator().manual_seed(DEMO_SEED)
    params = [p for name, p in policy.named_parameters() if name != "log_std"]
    optimizer = torch.optim.Adam(params, lr=1e-3)
    report: dict[str, Any] = {}
    seed = DEMO_SEED + episodes
    for round_ in range(dagger_rounds + 1):
        if round_:

            def drive(obs: np.ndarray) -> np.ndarray:
                x = venv.normalize_obs(obs) if normalize else obs
                action, _ = policy.predict(x, deterministic=True)
                return action

            demos = collect(env_id, env_kwargs, planner, dagger_episodes, noise, seed=seed,
                            teachers=teachers, driver=drive,
                            trust_pickle=trust_pickle)  # fmt: skip
            seed += dagger_episodes
            rounds.append(demos)
            report.setdefault("dagger", []).append(_clone_report(demos))
            log(f"DAgger round {round_}: the clone reached the goal in "
                f"{100 * demos.successes / demos.episodes:.0f} % of {demos.episodes} episodes "
                f"({_by_scenario_text(demos)})")  # fmt: skip
        obs = np.concatenate([d.obs for d in rounds])
        rewards = np.concatenate([d.rewards for d in rounds])
        dones = np.concatenate([d.dones for d in rounds])
        actions = np.concatenate([d.actions for d in rounds])
        if normalize:  # statistics of every step so far (PPO goes on updating them)
            fresh = rounds[-1]
            venv.obs_rms.update(fresh.obs)
            venv.ret_rms.update(running_returns(fresh.rewards, fresh.dones, gamma))
            obs = venv.normalize_obs(obs)
            rewards = venv.normalize_reward(rewards)
        targets = discounted_returns(np.asarray(rewards, np.float64), dones, gamma)
        action_loss, value_loss = _fit(policy, optimizer, generator, obs, actions, targets,
                                       epochs)  # fmt: skip
    with torch.no_grad():
        policy.log_std.fill_(log_std)
    policy.set_training_mode(False)
    demos = rounds[0]
    report = {"demo_episodes": demos.episodes, "demo_success": demos.successes / demos.episodes,
              "demo_steps": len(demos.obs), **report, "action_mse": action_loss,
              "value_mse": value_loss,
              "wall_time_s": round(time.perf_counter() - started, 1)}  # fmt: skip
    if teachers:
        report["demo_by_scenario"] = {
            name: {"teacher": teachers.get(name, planner), "episodes": n, "success": k / n}
            for name, (n, k) in demos.by_scenario().items()
        }
    source = (
        planner
        if not teachers
        else ", ".join(f"{name}: {teachers.get(name, planner)}" for name in demos.by_scenario())
    )
    more = f", {sum(len(d.obs) for d in rounds[1:])} DAgger steps" if dagger_rounds else ""
    log(
        f"warm start from {source}: {demos.episodes} episodes ({len(demos.obs)} steps, "
        f"{100 * report['demo_success']:.0f} % success{more}), action MSE {action_loss:.4f}, "
        f"value MSE {value_loss:.4f}, {report['wall_time_s']} s"
    )
    drawn = {name for d in rounds for name in d.scenarios}
    idle = sorted(set(teachers or {}) - drawn)
    if idle:
        report["teachers_without_episodes"] = idle
        log(f"warning: no demonstration episode drew {', '.join(idle)}: "
            f"{', '.join(str((teachers or {})[n]) for n in idle)} taught nothing "
            "(raise pretrain_episodes or the scenario's weight)")  # fmt: skip
    return report


def _fit(policy: Any, optimizer: Any, generator: Any, obs: np.ndarray, actions: np.ndarray,
         targets: np.ndarray, epochs: int) -> tuple[float, float]:  # fmt: skip
    """``epochs`` passes of behaviour cloning (action mean) and value regression on
    normalised ``obs``; the mean losses of the last pass."""
    import torch

    policy.set_training_mode(True)
    x = torch.as_tensor(obs, dtype=torch.float32, device=policy.device)
    a = torch.as_tensor(actions, dtype=torch.float32, device=policy.device)
    v = torch.as_tensor(targets, dtype=torch.float32, device=policy.device).unsqueeze(1)
    batch = 256
    action_loss = value_loss = float("nan")
    for _ in range(epochs):
        order = torch.randperm(len(x), generator=generator)
        totals = [0.0, 0.0]
        for start in range(0, len(x), batch):
            idx = order[start : start + batch]
            mean = policy.get_distribution(x[idx]).distribution.mean
            values = policy.predict_values(x[idx])
            la = torch.nn.functional.mse_loss(mean, a[idx])
            lv = torch.nn.functional.mse_loss(values, v[idx])
            optimizer.zero_grad()
            (la + 0.5 * lv).backward()
            optimizer.step()
            totals[0] += la.item() * len(idx)
            totals[1] += lv.item() * len(idx)
        action_loss, value_loss = totals[0] / len(x), totals[1] / len(x)
    policy.set_training_mode(False)
    return action_loss, value_loss


def _clone_report(demos: Demonstrations) -> dict[str, Any]:
    """A DAgger round's figures: the clone's episodes, steps and success, by scenario."""
    out: dict[str, Any] = {"episodes": demos.episodes, "steps": len(demos.obs),
                           "success": demos.successes / demos.episodes}  # fmt: skip
    if any(demos.scenarios):
        out["by_scenario"] = {name: {"episodes": n, "success": k / n}
                              for name, (n, k) in demos.by_scenario().items()}  # fmt: skip
    return out


def _by_scenario_text(demos: Demonstrations) -> str:
    parts = [f"{name} {100 * k / n:.0f} %" for name, (n, k) in demos.by_scenario().items()
             if name]  # fmt: skip
    return ", ".join(parts) or f"{len(demos.obs)} steps"
