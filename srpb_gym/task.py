"""One robot's navigation task in a :class:`~srpb_gym.simulation.Simulation`.

A :class:`RobotTask` owns everything that concerns one robot and no Gym API: decoding its
action into a body-frame command, the goal rule, the collision latch, the reward, the
observation, the step info, finishing the episode (the SRPB metrics, the recorded logs)
and the :class:`~srpb_gym.knowledge.Knowledge` handed to classical planners. The
Gymnasium environment is a thin adapter over one simulation and one task; the PettingZoo
environment over one simulation and a task per robot.

A step, seen from an adapter::

    for task in tasks:                        # every robot still in the episode
        task.decode(action, commands[task.robot])
    sim.step(commands, planning_times)        # the shared world advances once
    for task in tasks:
        obs, reward, terminated, info = task.step()
        if terminated or out_of_time:
            task.finish(info, stem=...)
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.knowledge import Knowledge, true_people
from srpb_gym.metrics import METRIC_NAMES, SRPBMetricWarning, evaluate, resolve_params
from srpb_gym.metrics.episode import at_goal
from srpb_gym.metrics.io_native import write_native
from srpb_gym.metrics.io_npz import save_record
from srpb_gym.metrics.params import MetricParams, check_semantics
from srpb_gym.metrics.record import EpisodeRecord
from srpb_gym.observation import ObservationBuilder, ObservationConfig
from srpb_gym.perception.lidar import beam_angles
from srpb_gym.reward import SRPB_TERMS, TERMS, RewardFunction, resolve_weights
from srpb_gym.sim.contact import FIRST_PREFIX, STEP_PREFIX, Collision
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.simulation import Simulation

COLLISION_MODES = ("terminate", "continue")
#: whose people the reward's social terms (psi, fsi, dir) see: the tracker's, as the
#: robot does, or the simulation's true people (a privileged reward; the observation stays
#: the tracker's)
REWARD_PEOPLE = ("tracked", "ground_truth")
METRIC_KEYS = ("semantics", "preset", "params")


@dataclass(frozen=True)
class MetricSettings:
    """How the episodes are scored: the SRPB semantics and the resolved parameters."""

    semantics: str
    params: MetricParams

    @classmethod
    def build(
        cls, spec: Mapping[str, Any] | None, robot: RobotConfig, goal_tolerance: float
    ) -> MetricSettings:
        """Settings from the ``metrics`` argument of an environment.

        The preset's values come first; the robot's circumradius and largest speed and the
        scenario's goal tolerance replace them (one source for every robot setting); a
        value in ``spec["params"]`` replaces any of them.
        """
        if spec is None:
            spec = {}
        if not isinstance(spec, Mapping):
            raise InputError(f"expected a mapping with keys {', '.join(METRIC_KEYS)}, got "
                             f"{spec!r}", key="metrics")  # fmt: skip
        unknown = sorted(set(spec) - set(METRIC_KEYS))
        if unknown:
            raise InputError(f"unknown key; valid keys: {', '.join(METRIC_KEYS)}",
                             key=f"metrics.{unknown[0]}")  # fmt: skip
        try:
            semantics = check_semantics(spec.get("semantics", "paper"))
        except ValueError as exc:
            raise InputError(str(exc), key="metrics.semantics") from None
        explicit = spec.get("params") or {}
        if not isinstance(explicit, Mapping):
            raise InputError(f"expected a mapping of parameter names to numbers, got "
                             f"{explicit!r}", key="metrics.params")  # fmt: skip
        derived = {
            "robot_circumradius": robot.radius,
            "robot_max_speed": robot.max_speed,
            "goal_tolerance_xy": goal_tolerance,
        }
        try:
            params = resolve_params(spec.get("preset", "paper"), **(derived | dict(explicit)))
        except KeyError as exc:
            raise InputError(str(exc.args[0]), key="metrics") from None
        except ValueError as exc:
            raise InputError(str(exc), key="metrics.params") from None
        return cls(semantics, params)


class RobotTask:
    """Robot ``robot`` of ``sim`` driving to its goal, scored by SRPB.

    ``observation``: the observation type; ``weights``: reward weights over
    :data:`srpb_gym.reward.TERMS`; ``metrics``: how episodes are scored (the reward's SRPB
    terms use the same parameters); ``collision``: ``"terminate"`` ends the episode at a
    contact, ``"continue"`` penalises it and goes on; ``record_dir``: write every finished
    episode there as SRPB native logs and ``.npz`` records; ``reward_people``: the people
    the reward's terms are computed from (:data:`REWARD_PEOPLE`): ``"tracked"`` (the
    episode's record, as the metrics in ``srpb/``) or ``"ground_truth"`` (its ground-truth
    record, as ``srpb_gt/``).
    """

    def __init__(
        self,
        sim: Simulation,
        robot: int,
        observation: ObservationConfig,
        weights: NDArray[np.float64],
        metrics: MetricSettings,
        collision: str = "terminate",
        record_dir: str | None = None,
        reward_people: str = "tracked",
    ) -> None:
        if collision not in COLLISION_MODES:
            raise InputError(f"expected one of {COLLISION_MODES}, got {collision!r}",
                             key="collision")  # fmt: skip
        if reward_people not in REWARD_PEOPLE:
            raise InputError(f"expected one of {REWARD_PEOPLE}, got {reward_people!r}",
                             key="reward_people")  # fmt: skip
        self.reward_people = reward_people
        self.sim, self.robot = sim, robot
        self.collision_mode = collision
        self.metrics = metrics
        self.params = metrics.params
        self.record_dir = _checked_record_dir(record_dir)
        cfg = sim.robot_config
        lidar = sim.lidar_config
        self.obs_builder = ObservationBuilder.for_robot(observation, cfg, lidar.n_beams,
                                                        lidar.range_min, lidar.range_max,
                                                        beam_angles(lidar))  # fmt: skip
        self.observation_space = self.obs_builder.space
        self.action_space = gym.spaces.Box(-1.0, 1.0, (cfg.action_dims,), np.float32)
        self.reward_fn = RewardFunction(weights, self.params, metrics.semantics)
        self._scale_fwd, self._scale_back = cfg.v_max, -cfg.v_min
        self._scale_y, self._scale_w = cfg.vy_max, cfg.w_max
        self._holonomic = cfg.kinematics == "holonomic"
        self._reward_keys = [f"reward_{t}" for t in TERMS]
        self._step_keys = [f"srpb_step/{t}" for t in SRPB_TERMS]
        self._n_srpb = len(SRPB_TERMS)
        self.done = True  # no episode until reset

    # ------------------------------------------------------------------ episode
    def reset(self) -> tuple[Any, dict[str, Any]]:
        """Start the episode of a freshly reset simulation: the first observation and info
        (with ``reward_weights``: the weight of every term in force, by name)."""
        self.collided = False
        self.collision_count = 0
        self.first_collision: Collision | None = None
        self.done = False
        distance = self.sim.goal_distance(self.robot)
        if self.collision_mode == "terminate":
            self.reward_fn.check_bound(self.sim.layout.time_limit, self.sim.config.control_dt,
                                       self.sim.robot_config)  # fmt: skip
        self.reward_fn.reset(self.reward_record, distance)
        info = self._info(False, False, distance)
        info["reward_weights"] = dict(zip(TERMS, self.reward_fn.weights.tolist()))
        return self.observation(), info

    def decode(self, action: Any, out: NDArray[np.float64]) -> None:
        """Write the body-frame command (vx, vy, omega) of ``action`` into ``out`` (3,).

        Each element a in [-1, 1]: linear a >= 0 -> a * v_max, a < 0 -> a * |v_min|,
        lateral a * vy_max (holonomic), angular a * w_max. Out-of-range values are clipped;
        a wrong shape or a NaN or infinite value is a ``ValueError``.
        """
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        a = a.tolist()
        if not all(map(math.isfinite, a)):
            raise ValueError(f"action must be finite, got {a}")
        a = [min(max(v, -1.0), 1.0) for v in a]
        out[0] = a[0] * (self._scale_fwd if a[0] >= 0 else self._scale_back)
        if self._holonomic:
            out[1], out[2] = a[1] * self._scale_y, a[2] * self._scale_w
        else:
            out[1], out[2] = 0.0, a[1] * self._scale_w

    def step(self) -> tuple[Any, float, bool, dict[str, Any]]:
        """The outcome of the simulation step just taken: observation, reward, whether the
        task ended (goal or a terminating collision) and the step info."""
        if self.done:
            raise RuntimeError(f"robot {self.robot}'s episode has ended; reset first")
        collided = bool(self.sim.collisions[self.robot].any())
        self.collided |= collided
        count, collision = self.sim.new_collision(self.robot)
        if count:
            self.collision_count += count
            if self.first_collision is None:
                self.first_collision = collision
        distance = self.sim.goal_distance(self.robot)
        reached = self.goal_reached()
        terminated = reached or (collided and self.collision_mode == "terminate")
        success = reached and not self.collided
        reward = self.reward_fn.step(self.reward_record, distance, success, collided)
        info = self._info(success, collided, distance)
        if collision is not None:
            info.update(collision.info(STEP_PREFIX))
        return self.observation(), reward, terminated, info

    def finish(self, info: dict[str, Any], stem: str | None = None) -> None:
        """End the episode: put its SRPB metrics into ``info`` (``srpb/<metric>`` from the
        tracked people, ``srpb_gt/<metric>`` from ground truth, the parameters used), its
        collisions (``collision_count`` and the first one, ``first_collision_<field>``, when
        there was one), ``people_pushed_back`` (the most any walker moved against the way it
        walks, m: :attr:`~srpb_gym.sim.crowd.Crowd.pushed_back`) and write its logs as
        ``<record_dir>/<stem>*`` when recording."""
        info["collision_count"] = self.collision_count
        info["people_pushed_back"] = float(self.sim.crowd.pushed_back.max(initial=0.0))
        if self.first_collision is not None:
            info.update(self.first_collision.info(FIRST_PREFIX))
        tracked, truth = self.episode_metrics()
        for name in METRIC_NAMES:
            info[f"srpb/{name}"] = tracked[name]
        for name in METRIC_NAMES:
            info[f"srpb_gt/{name}"] = truth[name]
        info["srpb_semantics"] = self.metrics.semantics
        info["srpb_params"] = self.params.as_dict()
        self.done = True
        if self.record_dir is not None and stem is not None:
            self.write(os.path.join(self.record_dir, stem))

    # ------------------------------------------------------------------ queries
    @property
    def record(self) -> EpisodeRecord:
        """The episode's SRPB record from the tracked people."""
        return self.sim.robots[self.robot].record

    @property
    def reward_record(self) -> EpisodeRecord:
        """The record the reward is computed from: the tracked one, or the ground-truth one
        with ``reward_people="ground_truth"`` (the robot's samples are the same in both)."""
        state = self.sim.robots[self.robot]
        return state.gt_record if self.reward_people == "ground_truth" else state.record

    def goal_reached(self) -> bool:
        """Whether the robot is at its goal: the SRPB goal rule (``m_goal``)."""
        x, y, yaw = self.sim.world.robot_pose[self.robot]
        gx, gy, gyaw = self.sim.robots[self.robot].goal
        p = self.params
        return at_goal(x, y, yaw, gx, gy, gyaw, p.goal_tolerance_xy, p.goal_tolerance_yaw)

    def observation(self) -> Any:
        """A fresh observation of the robot's current state."""
        state = self.sim.robots[self.robot]
        return self.obs_builder.build(self.sim.world.robot_pose[self.robot], state.goal,
                                      self.sim.velocity[self.robot], state.scan,
                                      state.tracker.tracks())  # fmt: skip

    def episode_metrics(self) -> tuple[dict[str, float], dict[str, float]]:
        """The episode's SRPB metrics so far: from the tracked people and from ground truth."""
        state = self.sim.robots[self.robot]
        semantics = self.metrics.semantics
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SRPBMetricWarning)
            tracked = evaluate(state.record, semantics, self.params)
            truth = evaluate(state.gt_record, semantics, self.params)
        return tracked, truth

    def running_metrics(self) -> dict[str, float]:
        """A few of the episode's SRPB metrics so far (tracked people), for display."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SRPBMetricWarning)
            values = evaluate(self.record, self.metrics.semantics, self.params)
        keys = ("m_psi", "m_fsi", "m_dir", "m_obs", "m_plin", "m_chc")
        return {"t": self.sim.t} | {k: values[k] for k in keys}

    def knowledge(self, ground_truth: bool = False) -> Knowledge:
        """What the robot knows now, for classical planners: the tracker's people, or with
        ``ground_truth`` the true people (:func:`~srpb_gym.knowledge.true_people`), which
        only reference planners are handed (``Planner.ground_truth``)."""
        sim, r = self.sim, self.robot
        state = sim.robots[r]
        if ground_truth:
            world = sim.world
            tracks = true_people(world.people_xy, world.people_velocity, sim.crowd.yaw, sim.t)
        else:
            tracks = state.tracker.tracks()
        return Knowledge(
            walls=sim.walls, bounds=sim.layout.bounds, pose=sim.world.robot_pose[r].copy(),
            velocity=sim.velocity[r].copy(), command=sim.command[r].copy(),
            goal=state.goal.copy(), goal_tolerance=self.params.goal_tolerance_xy,
            goal_yaw_tolerance=self.params.goal_tolerance_yaw, tracks=tracks,
            scan=state.scan.copy(), scan_angles=state.lidar.angles,
            range_max=sim.lidar_config.range_max, robot=sim.robot_config,
            control_dt=sim.config.control_dt, t=sim.t, range_min=sim.lidar_config.range_min,
        )  # fmt: skip

    def write(self, base: str) -> None:
        """Write the episode as ``<base>_robot.txt``, ``_people.txt``, ``_groups.txt`` (SRPB
        native logs), ``<base>.npz`` and ``<base>_gt.npz`` (ground truth)."""
        state = self.sim.robots[self.robot]
        write_native(state.record, f"{base}_robot.txt", f"{base}_people.txt",
                     f"{base}_groups.txt")  # fmt: skip
        save_record(state.record, f"{base}.npz")
        save_record(state.gt_record, f"{base}_gt.npz")

    # ------------------------------------------------------------------ internals
    def _info(self, success: bool, collided: bool, distance: float) -> dict[str, Any]:
        info: dict[str, Any] = dict(zip(self._reward_keys, self.reward_fn.weighted.tolist()))
        info.update(zip(self._step_keys, self.reward_fn.values[-self._n_srpb :].tolist()))
        info["is_success"], info["collision"] = success, collided
        info["goal_distance"], info["t"] = distance, self.sim.t
        return info


def build_task(
    sim: Simulation,
    robot: int,
    goal_tolerance: float,
    observation: str | Mapping[str, Any] | None = None,
    reward: str = "srpb",
    reward_weights: Mapping[str, float] | None = None,
    collision: str = "terminate",
    metrics: Mapping[str, Any] | None = None,
    record_dir: str | None = None,
    scenario_reward: Mapping[str, Mapping[str, float]] | None = None,
    reward_people: str = "tracked",
) -> RobotTask:
    """A task from the plain-data arguments of an environment (see :class:`RobotTask`);
    ``scenario_reward``: the scenario's weights by preset (its ``reward`` section)."""
    settings = MetricSettings.build(metrics, sim.robot_config, goal_tolerance)
    weights = resolve_weights(reward, reward_weights, scenario_reward)
    return RobotTask(sim, robot, ObservationConfig.from_spec(observation), weights, settings,
                     collision, record_dir, reward_people)  # fmt: skip


def _checked_record_dir(path: str | os.PathLike[str] | None) -> str | None:
    """``path`` as a string, created and checked writable now (not when an episode ends)."""
    if path is None:
        return None
    path = os.fspath(path)
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder: {exc.strerror}", key="record_dir") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise InputError(f"the folder {path!r} is not writable", key="record_dir")
    return path
