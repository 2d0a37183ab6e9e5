"""What a training run is checked against before anything is trained: the environment id,
the reward preset and the env kwargs (:func:`check_env_args`, :func:`check_reward` with the
bounds the learner is checked against while it trains, :func:`reward_weights` the weights
each scenario pays) and the environments of the periodic evaluations
(:func:`check_eval_targets`)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

from srpb_gym.errors import InputError, env_kwargs_error
from srpb_gym.evaluation.spec import ENV_IDS
from srpb_gym.reward import PRESET_GAMMA, TERMS, preset_names, shaping_bound


@dataclass(frozen=True)
class RewardCheck:
    """What :func:`check_reward` found: the reward weights of each scenario (as
    :func:`reward_weights`) and, when a collision ends the episode, each scenario's
    collision penalty and the discounted worst case of its shaping
    (:func:`~srpb_gym.reward.shaping_bound`), raw, by scenario name (empty when collisions
    go on: no bound is claimed then)."""

    weights: dict[str, dict[str, float]]
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)


def check_env_args(env_id: str, preset: str, env_kwargs: Mapping[str, Any],
                   gamma: float = PRESET_GAMMA) -> dict[str, dict[str, float]]:  # fmt: skip
    """Refuse an unknown id or preset, env kwargs the environment refuses and a reward that
    the discount ``gamma`` makes gameable (a collision worth more than going on), now.
    Returns the reward weights of each scenario, as :func:`reward_weights`."""
    return check_reward(env_id, preset, env_kwargs, gamma).weights


def check_reward(env_id: str, preset: str, env_kwargs: Mapping[str, Any],
                 gamma: float = PRESET_GAMMA) -> RewardCheck:  # fmt: skip
    """:func:`check_env_args`, returning the weights and the bounds of each scenario."""
    if env_id not in gym.registry or not env_id.startswith("SRPB-"):
        ids = sorted(k for k in gym.registry if k.startswith("SRPB-"))
        raise InputError(f"unknown environment {env_id!r}; choose one of: {', '.join(ids)}",
                         key="--env")  # fmt: skip
    if preset not in preset_names():
        raise InputError(f"choose one of: {', '.join(preset_names())}", key="--reward")
    try:
        env = gym.make(env_id, reward=preset, **env_kwargs)
    except (TypeError, ValueError) as exc:
        raise env_kwargs_error(env_id, exc) from None
    try:
        base = env.unwrapped
        weights_of = _weights_of(base)
        if base.task.collision_mode != "terminate":
            return RewardCheck(weights_of)
        bounds: dict[str, tuple[float, float]] = {}
        for scenario, task in _scenario_tasks(base):  # a mixture's, each with its weights
            weights = task.reward_fn.weights
            penalty = -float(weights[TERMS.index("collision")])
            bound = shaping_bound(weights, scenario.time_limit, base.sim.config.control_dt,
                                  base.sim.robot_config, gamma)  # fmt: skip
            if bound > 0.0 and bound >= penalty:
                raise InputError(
                    f"with gamma {gamma:g} the shaping of the {preset!r} reward in scenario "
                    f"{scenario.name!r} can cost up to {bound:.3g} (discounted) from any "
                    f"state, not less than the collision penalty {penalty:g}: a policy could "
                    "learn to crash. Lower gamma or the shaping weights, or raise "
                    "'collision'", key="--hyperparams: gamma")  # fmt: skip
            bounds[scenario.name] = (penalty, bound)
        return RewardCheck(weights_of, bounds)
    finally:
        env.close()


def _scenario_tasks(base: Any) -> list[tuple[Any, Any]]:
    """(scenario, robot task) of each scenario of an environment (one unless a mixture)."""
    names = getattr(base, "scenarios", None)
    if names is None:
        return [(base.scenario, base.task)]
    return [(base.scenario_of(n), base.task_of(n)) for n in names]


def reward_weights(
    env_id: str, preset: str, env_kwargs: Mapping[str, Any] | None = None
) -> dict[str, dict[str, float]]:
    """The reward weights (non-zero ones, by term) that ``env_id`` with ``preset`` and
    ``env_kwargs`` pays in each of its scenarios, by scenario name: the preset's, re-weighted
    by the scenario's ``reward`` section and by ``reward_weights``. ``env_kwargs`` may be
    a run's (its ``config.yaml``): its ``reward`` is ``preset``, and records and rendering,
    which do not change the reward, are left out."""
    skip = ("reward", "record_dir", "render_mode")
    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k not in skip}
    env = gym.make(env_id, reward=preset, **kwargs)
    try:
        return _weights_of(env.unwrapped)
    finally:
        env.close()


def _weights_of(base: Any) -> dict[str, dict[str, float]]:
    return {scenario.name: {t: float(w) for t, w in zip(TERMS, task.reward_fn.weights) if w}
            for scenario, task in _scenario_tasks(base)}  # fmt: skip


def check_eval_targets(env_id: str, eval_ids: Sequence[str]) -> None:
    """Refuse, before any training, periodic evaluations that the evaluation harness
    cannot run: it runs the packaged ids and scenario files, not an id registered
    elsewhere."""
    for target in eval_ids:
        if target not in ENV_IDS and not os.path.isfile(target):
            raise InputError(
                f"{env_id} is not a packaged environment, and the periodic evaluation runs "
                f"those ({', '.join(ENV_IDS)}) and scenario files only: train "
                "SRPB-Custom-v0 with --env-kwargs scenario=FILE, or set "
                "--hyperparams eval_freq=0", key="--env")  # fmt: skip
