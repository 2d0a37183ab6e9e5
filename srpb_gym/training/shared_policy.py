"""One policy shared by every robot of the PettingZoo environment, as an SB3 ``VecEnv``.

:class:`SharedPolicyVecEnv` turns K multi-robot environments of N robots each into an SB3
``VecEnv`` of K x N slots, one per robot. It is our own small adapter rather than
SuperSuit's ``pettingzoo_env_to_vec_env_v1`` + ``concat_vec_envs_v1``: SuperSuit refuses
environments whose agents leave early unless ``black_death=True``, and with black death a
robot that has left keeps producing zero observations with reward 0 and ``done=False``
until every robot has left (its terminal observation is only kept when all are done), so
those made-up transitions would enter PPO's rollout buffer.

Here a robot that reaches its goal ends its task (its slot is done, terminated, with its
``terminal_observation``) and at once starts a return trip from where it stands
(:meth:`SRPBParallelEnv.return_trip <srpb_gym.pettingzoo_env.SRPBParallelEnv.return_trip>`:
back to its start, then to its goal again), so that its slot goes on with a new task while
the other robots drive on: a robot on a long or slow route is not cut short because
another arrived first. The episode of an environment ends for all its robots at a
collision that ends a robot's task (``collision="terminate"``) or at the time limit: the
robots still driving are done as *truncated* (``info["TimeLimit.truncated"] = True`` with
their ``terminal_observation``), so PPO bootstraps their value instead of treating the cut
as an end. Every transition in the buffer is then a real one. Evaluation (``srpb-gym eval
--robots N --policy model.zip``) has no return trips: there a robot leaves at its goal.

The recipe ``python -m training.multi_robot`` trains PPO with it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from srpb_gym.pettingzoo_env import SRPBParallelEnv

__all__ = ["SharedPolicyVecEnv"]


class SharedPolicyVecEnv(VecEnv):
    """K multi-robot environments as one SB3 ``VecEnv`` of K x N robot slots (see the
    module docstring for how robots that leave are handled). Slot ``k * N + i`` is robot
    ``i`` of environment ``k``."""

    def __init__(self, env_fns: Sequence[Callable[[], SRPBParallelEnv]]) -> None:
        self.envs = [fn() for fn in env_fns]
        first = self.envs[0]
        self.agents = list(first.possible_agents)
        if any(list(e.possible_agents) != self.agents for e in self.envs):
            raise ValueError("every environment must have the same robots")
        agent = self.agents[0]
        super().__init__(len(self.envs) * len(self.agents), first.observation_space(agent),
                         first.action_space(agent))  # fmt: skip
        self._actions: np.ndarray | None = None

    # ------------------------------------------------------------------ VecEnv
    def reset(self) -> np.ndarray:
        n = len(self.agents)
        rows = []
        for k, env in enumerate(self.envs):
            seed = self._seeds[k * n]
            obs, infos = env.reset(seed=seed)
            rows += [obs[a] for a in self.agents]
            self.reset_infos[k * n : (k + 1) * n] = [infos[a] for a in self.agents]
        self._reset_seeds()
        self._reset_options()
        return np.stack(rows)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        assert self._actions is not None, "step_async first"
        n = len(self.agents)
        obs_out, rewards = [], np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = []
        for k, env in enumerate(self.envs):
            actions = {a: self._actions[k * n + i] for i, a in enumerate(self.agents)}
            obs, rew, term, trunc, info = env.step(actions)
            # arrived: the task ended at the goal, not by a collision at the same step
            arrived = {a: term[a] and env.at_goal(a) and not info[a]["collision"]
                       for a in self.agents}  # fmt: skip
            ended = any(trunc.values()) or any(term[a] and not arrived[a] for a in term)
            for i, a in enumerate(self.agents):
                rewards[k * n + i] = rew[a]
                slot_info = dict(info[a])
                if ended or term[a]:
                    dones[k * n + i] = True
                    slot_info["terminal_observation"] = obs[a]
                    # cut short (by the time limit, or because another robot ended it)
                    slot_info["TimeLimit.truncated"] = not term[a]
                infos.append(slot_info)
            if ended or not env.agents:
                obs, _ = env.reset()
            else:
                for a in self.agents:
                    if term[a]:
                        obs[a], _ = env.return_trip(a)
            obs_out += [obs[a] for a in self.agents]
        self._actions = None
        return np.stack(obs_out), rewards, dones, infos

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.envs[i // len(self.agents)], attr_name)
                for i in self._get_indices(indices)]  # fmt: skip

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._get_indices(indices):
            setattr(self.envs[i // len(self.agents)], attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:  # fmt: skip
        return [getattr(self.envs[i // len(self.agents)], method_name)(*method_args,
                                                                       **method_kwargs)
                for i in self._get_indices(indices)]  # fmt: skip

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper],
                       indices: VecEnvIndices = None) -> list[bool]:  # fmt: skip
        return [False for _ in self._get_indices(indices)]
