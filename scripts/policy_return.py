"""What a reward pays each policy: the undiscounted return of its episodes, and each term's
share, under reward settings of your choice.

    python scripts/policy_return.py --env SRPB-Corridor-v0 --episodes 100 --seed 3000000 \\
        --policy runs/train/corridor-srpb-s0 runs/train/corridor-task-s0 --env-kwargs \\
        'reward_weights={obs: -0.2, psi: -5.0, fsi: -3.0, dir: -1.0, collision: -110.0}' \\
        reward_people=ground_truth

A controlled comparison says which of two policies keeps more distance; this says which
of them earns more of a given reward. When a policy trained without the SRPB terms earns
more of the ``srpb`` reward than the policy trained with them, from the same start, the
shaping pays for a behaviour its learner did not find: the shortfall lies in the
optimisation, not in what the reward asks for.

Each ``--policy`` (a run folder's final ``model.zip``, a model file or a shipped model's
name, with its observation statistics, checked to act on the environment's spaces; or a
planner's name) drives ``--episodes`` episodes (seeds from
``--seed``) with deterministic actions in ``gym.make(--env, **--env-kwargs)``; the environment
pays the reward (``reward``, ``reward_weights`` and ``reward_people`` among the
``--env-kwargs``; the default is what ``gym.make`` pays). Per policy: the mean return
with its standard error, the success rate, and the mean of each non-zero term over the
episodes (``info["reward_<term>"]``, weighted, summed over each episode).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym.config import parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.planners.base import Planner, knowledge_for
from srpb_gym.reward import TERMS
from srpb_gym.training.pretrain import make_teacher


def returns(policy: Planner, env_id: str, env_kwargs: Mapping[str, Any], episodes: int,
            seed: int) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:  # fmt: skip
    """(return of each episode, whether it reached the goal, each term's sum per episode)
    of ``policy`` driving ``episodes`` episodes of ``env_id`` from seed ``seed``."""
    env = gym.make(env_id, **env_kwargs)
    base = env.unwrapped
    totals = np.zeros(episodes)
    reached = np.zeros(episodes, dtype=bool)
    terms = {name: np.zeros(episodes) for name in TERMS}
    keys = [(f"reward_{name}", sums) for name, sums in terms.items()]
    try:
        for k in range(episodes):
            obs, _ = env.reset(seed=seed + k)
            policy.reset(knowledge_for(policy, base.knowledge))
            while True:
                action = policy.act(obs, knowledge_for(policy, base.knowledge))
                obs, reward, terminated, truncated, info = env.step(action)
                totals[k] += reward
                for key, sums in keys:
                    sums[k] += info[key]
                if terminated or truncated:
                    reached[k] = bool(info.get("is_success", False))
                    break
    finally:
        env.close()
    return totals, reached, terms


def line(name: str, totals: np.ndarray, reached: np.ndarray,
         terms: Mapping[str, np.ndarray]) -> str:  # fmt: skip
    """One policy's summary: mean return +- standard error, success, the non-zero terms."""
    n = totals.size
    error = float(totals.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan
    shares = " ".join(f"{t} {v.mean():+.2f}" for t, v in terms.items() if np.any(v != 0.0))
    return (f"{name}: return {totals.mean():.2f} +- {error:.2f} (standard error), "
            f"success {100 * reached.mean():.0f} % of {n}; terms: {shares}")  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", required=True, help="environment id")
    parser.add_argument("--policy", nargs="+", required=True,
                        help="run folders, model files, shipped models' or planners' "
                        "names")  # fmt: skip
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=3_000_000)
    parser.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                        help="environment arguments (as srpb-gym eval --env-kwargs), the "
                             "reward's among them")  # fmt: skip
    args = parser.parse_args(argv)
    try:
        if args.episodes < 1:
            raise InputError(f"must be >= 1, got {args.episodes}", key="--episodes")
        env_kwargs = parse_overrides(args.env_kwargs, "--env-kwargs")
        probe = gym.make(args.env, **env_kwargs)
        try:  # each policy loaded and checked to act on the environment's spaces
            policies = [make_teacher(name, probe, key="--policy") for name in args.policy]
        finally:
            probe.close()
        for name, policy in zip(args.policy, policies):
            print(line(name, *returns(policy, args.env, env_kwargs, args.episodes,
                                      args.seed)), flush=True)  # fmt: skip
    except InputError as exc:
        print(f"policy_return: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
