"""The PettingZoo environment: several robots sharing a world of walls and people, each
scored by SRPB.

:class:`SRPBParallelEnv` is a thin adapter over one
:class:`~srpb_gym.simulation.Simulation` and one :class:`~srpb_gym.task.RobotTask` per
robot, the same task the Gymnasium environment uses; the adapter adds the PettingZoo API,
the agents that leave, the time and step limits, planning times and rendering.

Module-level functions follow PettingZoo's environment families::

    from srpb_gym import pettingzoo_env as srpb_pz
    par = srpb_pz.parallel_env(scenario="crowd", n_robots=3)  # ParallelEnv
    aec = srpb_pz.env(scenario="crowd", n_robots=3)           # AEC, order enforced
    raw = srpb_pz.raw_env(scenario="crowd", n_robots=3)       # AEC, unwrapped
"""

from __future__ import annotations

import math
import numbers
import os
import time
import uuid
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.utils import EzPickle, seeding
from numpy.typing import NDArray
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils import conversions, wrappers

from srpb_gym.episode_setup import check_render_mode, episode_layout, out_of_time, planning_seconds
from srpb_gym.errors import InputError
from srpb_gym.knowledge import Knowledge
from srpb_gym.observation import ObservationConfig
from srpb_gym.render import Renderer
from srpb_gym.settings import EnvSettings
from srpb_gym.task import RobotTask

__all__ = ["SRPBParallelEnv", "env", "parallel_env", "raw_env"]


class SRPBParallelEnv(ParallelEnv, EzPickle):
    """Several robots navigating among people, each to its own goal, scored by SRPB.

    ## Description
    ``n_robots`` robots (agents ``robot_0``, ``robot_1``, ...) share one world with the
    scenario's walls, walking people and F-formations. Each has its own start and goal
    (the scenario's ``robots`` regions; with one robot its ``robot`` entry, exactly as the
    Gymnasium environment), its own lidar, people detector and tracker, and its own SRPB
    record. Robots are real to each other: each appears in the others' lidar, counts as an
    obstacle for ``m_obs`` and as a collision on contact, and people react to every
    robot. A robot's tracker reports people only, like SRPB's: another robot is an
    obstacle in its lidar, never a tracked person.

    ## Spaces, rewards, info
    Each agent's observation and action spaces, reward terms and step info are those of
    :class:`srpb_gym.env.SRPBNavEnv` with the same arguments (see its docstring). A
    collision of two robots is in the info of both, with ``collision_kind`` ``"robot"``;
    ``collision_by`` is ``"robot"`` for a robot that closed the gap at least as fast as the
    other, else ``"other_robot"``.

    ## Agents leaving and episode end
    An agent that reaches its goal, or collides with ``collision="terminate"``, is
    terminated: its last step returns its final info with its ``srpb/<metric>`` and
    ``srpb_gt/<metric>`` episode metrics, and it leaves ``agents``. Its robot stays in the
    world as an obstacle: it receives zero commands from then on, so it slows to a stop
    within its acceleration limits (about 0.1 m at full speed) and stays there. At
    the scenario's time limit, or after ``max_steps`` steps, every remaining agent is
    truncated with its metrics. The episode ends when no agent is left. For training,
    :meth:`return_trip` sends a robot that has just reached its goal back to its start
    (then to its goal again) with a fresh task, while the others drive on.

    ## Arguments
    ``scenario``, ``render_mode`` and the settings ``observation``, ``reward``,
    ``reward_weights``, ``reward_people``, ``collision``, ``metrics``, ``record_dir``,
    ``sim``, ``robot``, ``sensors``, ``crowd`` (or ``settings``: one
    :class:`~srpb_gym.settings.EnvSettings`): as :class:`srpb_gym.env.SRPBNavEnv` (the
    episode files of robot r end in ``_robot<r>`` when there are several). ``n_robots``:
    how many robots; more than the scenario has places for is an error that names its
    limit. ``max_steps``: an optional step limit.
    ``reset(options=...)`` takes ``people`` (False: an empty variant) and, with one robot,
    ``start`` and ``goal``; other keys are ignored with a warning (PettingZoo's API test
    passes options of its own).

    The planner computation time of each agent's step (``m_cef``, ``m_cre``) is the wall
    time between the previous ``reset``/``step`` returning and this ``step``, unless a
    harness calls :meth:`set_planning_time` with each agent's own time.

    ## Version History
    * v0: initial release.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "srpb_v0",
        "render_modes": ["human", "rgb_array"],
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        scenario: str | os.PathLike[str] = "crowd",
        n_robots: int = 2,
        render_mode: str | None = None,
        max_steps: int | None = None,
        settings: EnvSettings | None = None,
        **kwargs: Any,
    ) -> None:
        EzPickle.__init__(self, scenario, n_robots, render_mode, max_steps, settings, **kwargs)
        check_render_mode(render_mode, self.metadata["render_modes"])
        if (isinstance(n_robots, (bool, np.bool_)) or not isinstance(n_robots, numbers.Integral)
                or n_robots < 1):  # fmt: skip
            raise InputError(f"expected a whole number >= 1, got {n_robots!r}", key="n_robots")
        if max_steps is not None and (
            isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1
        ):
            raise InputError(f"expected a whole number >= 1, got {max_steps!r}",
                             key="max_steps")  # fmt: skip
        self.render_mode = render_mode
        self.settings = EnvSettings.given(settings, kwargs, type(self).__name__)
        self.scenario = self.settings.load_scenario(scenario)
        self.n_robots, self.max_steps = int(n_robots), max_steps
        self.sim, self.tasks = self.settings.build(self.scenario, self.n_robots)
        self.possible_agents = [f"robot_{r}" for r in range(self.n_robots)]
        self.agents: list[str] = []
        self._task = dict(zip(self.possible_agents, self.tasks))
        self.observation_spaces = {a: t.observation_space for a, t in self._task.items()}
        self.action_spaces = {a: t.action_space for a, t in self._task.items()}
        self._cmd = np.zeros((self.n_robots, 3))
        self._planning = np.full(self.n_robots, math.nan)
        self._override: dict[str, float] = {}
        self._np_random: np.random.Generator | None = None
        self._steps, self._episode = 0, 0
        self._trips = np.zeros(self.n_robots, dtype=np.int64)  # return trips this episode
        self._token, self._seed = uuid.uuid4().hex[:8], None
        self._renderer = None

    # ------------------------------------------------------------------ spaces
    @property
    def observation_config(self) -> ObservationConfig:
        """What every robot observes: the resolved ``observation`` argument."""
        return self.tasks[0].obs_builder.config

    def observation_space(self, agent: str) -> gym.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gym.Space:
        return self.action_spaces[agent]

    # ------------------------------------------------------------------ API
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        rng = self._np_random
        if seed is not None or rng is None:
            rng, _ = seeding.np_random(seed)
            layout = episode_layout(self.scenario, rng, options, self.n_robots, strict=False)
        else:  # bad options leave the generator as it was
            state = rng.bit_generator.state
            try:
                layout = episode_layout(self.scenario, rng, options, self.n_robots, strict=False)
            except Exception:
                rng.bit_generator.state = state
                raise
        self._np_random, self._seed = rng, seed
        self._override.clear()
        self.sim.reset(layout, self._np_random)
        self._steps = 0
        self._episode += 1
        self._trips[:] = 0
        self.agents = self.possible_agents[:]
        observations, infos = {}, {}
        for agent, task in self._task.items():
            observations[agent], infos[agent] = task.reset()
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return observations, infos

    def step(self, actions: Mapping[str, Any]) -> tuple[
        dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict]
    ]:  # fmt: skip
        started = time.perf_counter()
        if not self.agents:
            raise gym.error.ResetNeeded(
                "call reset() before step(): no episode has started" if self._episode == 0
                else "every agent has left the episode; call reset() before step()"
            )  # fmt: skip
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for {', '.join(missing)}; every agent in `agents` "
                             f"acts each step")  # fmt: skip
        unknown = [a for a in actions if a not in self.agents]
        if unknown:
            raise ValueError(f"actions for agents not in the episode: {', '.join(unknown)}")
        self._cmd[:] = 0.0
        self._planning[:] = math.nan
        wall = started - self._last_return
        for agent in self.agents:  # every action checked before anything is consumed
            task = self._task[agent]
            task.decode(actions[agent], self._cmd[task.robot])
        for agent in self.agents:
            self._planning[self._task[agent].robot] = self._override.get(agent, wall)
        self._override.clear()
        self.sim.step(self._cmd, self._planning)
        self._steps += 1
        time_up = out_of_time(self.sim, self._steps, self.max_steps)
        obs, rewards, terms, truncs, infos = {}, {}, {}, {}, {}
        for agent in self.agents:
            task = self._task[agent]
            obs[agent], rewards[agent], terms[agent], infos[agent] = task.step()
            truncs[agent] = time_up and not terms[agent]
            if terms[agent] or truncs[agent]:
                task.finish(infos[agent], self.episode_name(task.robot))
        self.agents = [a for a in self.agents if not (terms[a] or truncs[a])]
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return obs, rewards, terms, truncs, infos

    def at_goal(self, agent: str) -> bool:
        """Whether ``agent``'s robot is at its goal now (the SRPB goal rule)."""
        return self._task_of(agent).goal_reached()

    def _task_of(self, agent: str) -> RobotTask:
        if agent not in self._task:
            raise ValueError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
        return self._task[agent]

    def return_trip(self, agent: str) -> tuple[Any, dict[str, Any]]:
        """For training: ``agent``, whose robot has just reached its goal (so it left
        ``agents``) while others drive on, turns back to where it started this episode
        (heading there), later to its goal again, and so on. It rejoins ``agents`` with a
        fresh task from where it stands (reward, SRPB records and metrics start at this
        step); returns its first observation and info, as ``reset`` does. Evaluation
        never calls it: there a robot leaves at its goal. ``ValueError`` for an agent
        still in the episode, one that left by other than its goal, or an episode that
        has ended."""
        task = self._task_of(agent)
        if agent in self.agents or not self.agents or not task.goal_reached():
            raise ValueError(f"{agent} can start a return trip only right after reaching its "
                             "goal, while other agents are still in the episode")  # fmt: skip
        robot = task.robot
        spec = self.sim.layout.robots[robot]
        self._trips[robot] += 1
        if self._trips[robot] % 2:  # back to the start, heading there
            x, y = spec.start[0], spec.start[1]
            goal = (x, y, math.atan2(y - spec.goal[1], x - spec.goal[0]))
        else:
            goal = tuple(spec.goal)
        self.sim.new_goal(robot, goal)
        self.agents = [a for a in self.possible_agents if a in self.agents or a == agent]
        return task.reset()

    def set_planning_time(self, seconds: Mapping[str, float] | float) -> None:
        """Use these planner computation times for the next step instead of the measured
        wall time: one number for every agent, or a mapping from agent to seconds."""
        if not self.agents:
            raise gym.error.ResetNeeded("no agent is in an episode; call reset() first")
        times = seconds if isinstance(seconds, Mapping) else dict.fromkeys(self.agents, seconds)
        absent = [a for a in times if a not in self.agents]
        if absent:
            raise ValueError(f"agents not in the episode: {', '.join(map(str, absent))}")
        self._override.update({a: planning_seconds(v) for a, v in times.items()})

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; set render_mode at creation")
            return None
        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        shown = self._task[self.agents[0]] if self.agents else self.tasks[0]
        return self._renderer.render(self.sim, shown.robot, shown.running_metrics())

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def knowledge(self, agent: str, ground_truth: bool = False) -> Knowledge:
        """What ``agent``'s robot knows now, for classical planners: the tracker's people,
        or with ``ground_truth`` the true people, for reference planners only
        (:meth:`srpb_gym.task.RobotTask.knowledge`)."""
        return self._task[agent].knowledge(ground_truth)

    def episode_name(self, robot: int) -> str:
        """File stem of robot ``robot``'s current episode (see :class:`SRPBNavEnv`), with
        ``_robot<r>`` when there are several robots."""
        base = (f"{self.scenario.name}_seed{self._seed}" if self._seed is not None
                else f"{self.scenario.name}_{self._token}_{self._episode:05d}")  # fmt: skip
        return base if self.n_robots == 1 else f"{base}_robot{robot}"


def parallel_env(**kwargs: Any) -> SRPBParallelEnv:
    """The parallel environment (see :class:`SRPBParallelEnv` for the arguments)."""
    return SRPBParallelEnv(**kwargs)


def raw_env(**kwargs: Any) -> AECEnv:
    """The AEC version through PettingZoo's own conversion, unwrapped."""
    return conversions.parallel_to_aec(parallel_env(**kwargs))


def env(**kwargs: Any) -> AECEnv:
    """The AEC version with PettingZoo's order-enforcing wrapper."""
    return wrappers.OrderEnforcingWrapper(raw_env(**kwargs))
