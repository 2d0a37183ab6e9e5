"""A warm start for PPO: behaviour cloning of a classical planner.

PPO from random weights with the ``srpb`` preset does not find its way around the
standing pair of ``fformation`` (0 % success in five runs): exploration never reaches
the goal often enough to learn from it. A policy that starts where a classical planner
is, and is then improved by PPO on the reward, does; it also lets both reward presets
start from the same policy, so that what differs between their models is the reward's
doing (the shipped corridor models and the generalist clone ``dwa``; the fformation ones
clone ``social-dwa``, whose route around the pair the ``srpb`` preset keeps and the
``task`` preset wears down towards the pair). :func:`pretrain` drives ``episodes``
episodes with a planner of :mod:`srpb_gym.planners`, on seeds from :data:`DEMO_SEED`
(apart from training, periodic-evaluation and test seeds), and:

1. sets the ``VecNormalize`` statistics (observations, discounted returns) from the
   demonstrations, so that the first PPO update sees the inputs the policy was fitted on;
2. fits the policy's action mean to the planner's actions (mean squared error) and its
   value network to the demonstrations' discounted normalised returns;
3. sets the policy's log standard deviation to ``log_std`` (PPO's own start, 0, is a
   standard deviation of 1 on actions in [-1, 1]: it would undo the cloning at once).

While collecting, the executed action is the planner's plus Gaussian noise of standard
deviation ``noise`` (the recorded target stays the planner's own action), so that the
demonstrations also show how to get back from the small errors the clone will make.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

#: first seed of the demonstration episodes (training: the run's seed; periodic
#: evaluation: 1,000,000; tests of shipped models: 10,000)
DEMO_SEED = 2_000_000


@dataclass
class Demonstrations:
    """Raw observations, the planner's actions, rewards and episode ends (step-aligned)."""

    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    successes: int
    episodes: int


def collect(env_id: str, env_kwargs: Mapping[str, Any], planner: str, episodes: int,
            noise: float, seed: int = DEMO_SEED) -> Demonstrations:  # fmt: skip
    """Drive ``episodes`` episodes of ``env_id`` with ``planner`` (executed actions with
    Gaussian noise ``noise``, drawn from a generator seeded with ``seed``)."""
    from srpb_gym.planners import make_planner

    env = gym.make(env_id, **env_kwargs)
    base = env.unwrapped
    agent = make_planner(planner)
    rng = np.random.default_rng(seed)
    obs_l, act_l, rew_l, done_l = [], [], [], []
    successes = 0
    try:
        for episode in range(episodes):
            obs, _ = env.reset(seed=seed + episode)
            agent.reset(base.knowledge())
            while True:
                action = np.asarray(agent.act(obs, base.knowledge()), dtype=np.float32)
                base.set_planning_time(0.0)
                executed = action
                if noise > 0:
                    executed = np.clip(action + rng.normal(0.0, noise, action.shape), -1, 1)
                obs_l.append(obs)
                act_l.append(action)
                obs, reward, terminated, truncated, info = env.step(executed.astype(np.float32))
                rew_l.append(reward)
                done_l.append(terminated or truncated)
                if terminated or truncated:
                    successes += bool(info.get("is_success", False))
                    break
    finally:
        env.close()
    return Demonstrations(np.asarray(obs_l, np.float32), np.asarray(act_l, np.float32),
                          np.asarray(rew_l, np.float64), np.asarray(done_l, bool),
                          successes, episodes)  # fmt: skip


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


def pretrain(model: Any, venv: Any, env_id: str, env_kwargs: Mapping[str, Any], *,
             planner: str, episodes: int, epochs: int, noise: float, log_std: float,
             gamma: float, log: Callable[[str], None] = print) -> dict[str, float]:  # fmt: skip
    """Warm-start ``model`` (an SB3 ``PPO``) and ``venv`` (its ``VecNormalize``, or any
    other VecEnv when observations are not normalised) from ``planner``'s demonstrations;
    returns what happened (demonstration success rate, steps, final losses, wall time)."""
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    started = time.perf_counter()
    demos = collect(env_id, env_kwargs, planner, episodes, noise)
    obs, rewards = demos.obs, demos.rewards
    if isinstance(venv, VecNormalize):
        venv.obs_rms.update(obs)
        venv.ret_rms.update(running_returns(rewards, demos.dones, gamma))
        obs = venv.normalize_obs(obs)
        rewards = venv.normalize_reward(rewards)
    targets = discounted_returns(np.asarray(rewards, np.float64), demos.dones, gamma)

    policy = model.policy
    policy.set_training_mode(True)
    x = torch.as_tensor(obs, dtype=torch.float32, device=policy.device)
    a = torch.as_tensor(demos.actions, dtype=torch.float32, device=policy.device)
    v = torch.as_tensor(targets, dtype=torch.float32, device=policy.device).unsqueeze(1)
    params = [p for name, p in policy.named_parameters() if name != "log_std"]
    optimizer = torch.optim.Adam(params, lr=1e-3)
    generator = torch.Generator().manual_seed(DEMO_SEED)
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
    with torch.no_grad():
        policy.log_std.fill_(log_std)
    policy.set_training_mode(False)
    report = {"demo_episodes": demos.episodes, "demo_success": demos.successes / demos.episodes,
              "demo_steps": len(x), "action_mse": action_loss, "value_mse": value_loss,
              "wall_time_s": round(time.perf_counter() - started, 1)}  # fmt: skip
    log(
        f"warm start from {planner}: {demos.episodes} episodes ({len(x)} steps, "
        f"{100 * report['demo_success']:.0f} % success), action MSE {action_loss:.4f}, "
        f"value MSE {value_loss:.4f}, {report['wall_time_s']} s"
    )
    return report
