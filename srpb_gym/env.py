"""The Gymnasium environment: one robot navigating among people, scored by SRPB."""

from __future__ import annotations

import math
import os
import time
import uuid
import warnings
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from srpb_gym.metrics import METRIC_NAMES, SRPBMetricWarning, evaluate, resolve_params
from srpb_gym.metrics.params import check_semantics
from srpb_gym.observation import ObservationBuilder, ObservationConfig
from srpb_gym.perception.detector import DetectorConfig
from srpb_gym.perception.lidar import LidarConfig
from srpb_gym.perception.tracker import TrackerConfig
from srpb_gym.planners.base import Knowledge
from srpb_gym.reward import SRPB_TERMS, TERMS, RewardFunction, resolve_weights
from srpb_gym.scenarios import load_scenario, sample
from srpb_gym.sim.crowd import SocialForceConfig
from srpb_gym.sim.layout import RobotLayout
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.simulation import SimConfig, Simulation

COLLISION_MODES = ("terminate", "continue")
RESET_OPTIONS = ("people", "start", "goal")


class SRPBNavEnv(gym.Env):
    """Human-aware navigation in a 2-D world of walls and people, scored by the SRPB metrics.

    ## Description
    A differential-drive robot (circumradius 0.275 m, the limits of the SRPB paper's Table
    2) drives from a start to a goal pose through a scenario of walls, walking people
    (social-force model) and standing F-formations. It senses with a lidar and a people
    detector whose detections feed a Kalman tracker; the observation, the SRPB reward terms
    and the episode metrics use the tracked people (with their covariances), like the
    paper's robot, and the metrics are also reported from ground truth.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: (linear, angular) command. Linear a >= 0 maps to
    a * v_max (0.5 m/s), a < 0 to a * |v_min| (0.1 m/s backward); angular a maps to
    a * w_max (1.05 rad/s). Zero is a stop command. A holonomic robot
    (``robot={"kinematics": "holonomic"}``) has 3 dims (vx, vy, omega), vy scaled by vy_max.
    Commands then pass the robot's acceleration limits. Out-of-range actions are clipped;
    NaN or infinite actions raise ``ValueError``.

    ## Observation Space
    ``observation={"type": "flat"}`` (default): ``Box(-1, 1, (8 + L + 7 K,), float32)``,
    80 values with the defaults L = 30 lidar sectors and K = 6 people. Robot frame: x
    ahead, y to the left; every value is normalised and clipped to [-1, 1].

    | index | element | unit before scaling | scale |
    | --- | --- | --- | --- |
    | 0 | distance to the goal | m | / 20 (``goal_scale``) |
    | 1, 2 | cos, sin of the bearing of the goal | - | - |
    | 3, 4 | cos, sin of (goal yaw - robot yaw) | - | - |
    | 5 | measured vx | m/s | / 0.5 (the largest speed) |
    | 6 | measured vy (0 for a differential drive) | m/s | / 0.3 (vy_max) |
    | 7 | measured omega | rad/s | / 1.05 |
    | 8 .. 8+L-1 | shortest lidar range of each of L sectors, right to left | m | / 25 |
    | 8+L+7j+0, +1 | tracked person j (nearest first): relative x, y | m | / 8 (``people_range``) |
    | 8+L+7j+2, +3 | its velocity relative to the robot, x, y | m/s | / 2 (``speed_scale``) |
    | 8+L+7j+4, +5 | its position standard deviation along x, y | m | / 1 (``uncertainty_scale``) |
    | 8+L+7j+6 | presence: 1, or 0 for an empty slot (all its values 0) | - | - |

    ``observation={"type": "dict"}``: ``Dict`` with ``goal`` (5,), ``velocity`` (3,),
    ``lidar`` (L,), ``people`` (K, 6) and ``people_mask`` (K,), the same values. Other keys
    of the mapping (``lidar_bins``, ``people``, the scales) change L, K and the scales.

    ## Rewards
    A weighted sum of named terms (:mod:`srpb_gym.reward`): task terms ``progress``,
    ``success``, ``collision``, ``time`` and SRPB per-step terms ``obs``, ``vsm``, ``hsm``,
    ``osc``, ``bwd``, ``iprot``, ``chc``, ``psi``, ``fsi``, ``dir``. ``reward="srpb"``
    (default) or ``"task"`` picks a preset; ``reward_weights`` overrides weights by name.
    ``info["reward_<term>"]`` holds each weighted term (they sum to the reward) and
    ``info["srpb_step/<term>"]`` the unweighted SRPB terms.

    ## Starting State
    Start and goal poses, people, their routes and parameters are sampled from the
    scenario's ranges with the environment's generator (``reset(seed=...)``).

    ## Episode End
    Terminated when the robot is within the scenario's goal tolerance of the goal position
    and within ``goal_tolerance_yaw`` (metric parameter, 0.2 rad) of its heading, or on a
    collision when ``collision="terminate"`` (default; ``"continue"`` penalises and goes
    on). Truncated at the scenario's time limit. ``info["is_success"]``: goal reached with
    no collision in the episode. On the last step ``info["srpb/<metric>"]`` holds every
    episode metric from the tracked people and ``info["srpb_gt/<metric>"]`` from ground
    truth (0.0 on earlier steps; every key is present from ``reset`` on, so vector envs
    and ``Monitor(info_keywords=...)`` work).

    ## Arguments
    ``scenario``: a packaged name (corridor, fformation, crossing, crowd, doorway) or a path
    to a YAML file. ``render_mode``: "human" or "rgb_array". ``observation``: type name or
    mapping of :class:`~srpb_gym.observation.ObservationConfig`. ``reward``: preset name.
    ``reward_weights``: weights by term. ``collision``: "terminate" or "continue".
    ``metrics``: ``{"semantics": "paper"|"reference", "preset": "paper"|"srpb-code",
    "params": {...}}``. ``record_dir``: write every episode there as SRPB native logs and an
    ``.npz`` record. ``sim``, ``robot``, ``sensors`` (``lidar``, ``detector``,
    ``tracker``), ``crowd``: overrides of the simulation settings. Every argument is plain
    data; ``reset(options=...)`` takes ``people`` (False: an empty variant), ``start`` and
    ``goal`` (x, y, yaw).

    The planner's computation time (m_cef, m_cre) is the wall time between the previous
    ``reset``/``step`` returning and this ``step`` starting, unless a harness calls
    :meth:`set_planning_time` before the step.

    ## Version History
    * v0: initial release.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str = "corridor",
        render_mode: str | None = None,
        observation: str | Mapping[str, Any] | None = None,
        reward: str = "srpb",
        reward_weights: Mapping[str, float] | None = None,
        collision: str = "terminate",
        metrics: Mapping[str, Any] | None = None,
        record_dir: str | None = None,
        sim: Mapping[str, Any] | None = None,
        robot: str | Mapping[str, Any] | None = None,
        sensors: Mapping[str, Any] | None = None,
        crowd: Mapping[str, Any] | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}")
        if collision not in COLLISION_MODES:
            raise ValueError(f"collision must be one of {COLLISION_MODES}, got {collision!r}")
        self.render_mode, self.collision_mode, self.record_dir = render_mode, collision, record_dir
        self.scenario = load_scenario(scenario)
        self.sim = self._build_simulation(sim, robot, sensors, crowd)
        self._metric_settings(metrics)
        robot_cfg = self.sim.robot_config
        self.obs_builder = ObservationBuilder(
            ObservationConfig.from_spec(observation), self.sim.lidar_config.n_beams,
            self.sim.lidar_config.range_max, max(robot_cfg.v_max, -robot_cfg.v_min),
            robot_cfg.vy_max, robot_cfg.w_max,
        )  # fmt: skip
        self.observation_space = self.obs_builder.space
        dims = robot_cfg.action_dims
        self.action_space = gym.spaces.Box(-1.0, 1.0, (dims,), np.float32)
        self.reward_fn = RewardFunction(resolve_weights(reward, reward_weights), self.params,
                                        self.semantics)  # fmt: skip
        self._info_template = self._make_info_template()
        self._reward_keys = [f"reward_{t}" for t in TERMS]
        self._step_keys = [f"srpb_step/{t}" for t in SRPB_TERMS]
        self._cmd = np.zeros((1, 3))
        self._planning_override: float | None = None
        self._renderer = None
        self._token, self._episode = uuid.uuid4().hex[:8], 0
        self._seed: int | None = None

    # ------------------------------------------------------------------ construction
    def _build_simulation(self, sim, robot, sensors, crowd) -> Simulation:
        sensors = dict(sensors or {})
        unknown = set(sensors) - {"lidar", "detector", "tracker"}
        if unknown:
            raise ValueError(f"unknown sensors {sorted(unknown)}; valid: lidar, detector, tracker")
        spec = self.scenario.sensors
        return Simulation(
            SimConfig.from_spec(sim),
            RobotConfig.from_spec(robot),
            LidarConfig.from_spec(sensors.get("lidar", spec.lidar), "sensors.lidar"),
            DetectorConfig.from_spec(sensors.get("detector", spec.detector), "sensors.detector"),
            TrackerConfig.from_spec(sensors.get("tracker", spec.tracker), "sensors.tracker"),
            SocialForceConfig.from_spec(crowd, "crowd"),
        )

    def _metric_settings(self, metrics: Mapping[str, Any] | None) -> None:
        metrics = dict(metrics or {})
        unknown = set(metrics) - {"semantics", "preset", "params"}
        if unknown:
            raise ValueError(
                f"unknown metrics keys {sorted(unknown)}; valid: semantics, preset, params"
            )
        self.semantics = check_semantics(metrics.get("semantics", "paper"))
        params = {"goal_tolerance_xy": self.scenario.robot.goal_tolerance}
        params |= dict(metrics.get("params") or {})
        self.params = resolve_params(metrics.get("preset", "paper"), **params)

    def _make_info_template(self) -> dict[str, Any]:
        info: dict[str, Any] = {f"reward_{t}": 0.0 for t in TERMS}
        info |= {f"srpb_step/{t}": 0.0 for t in SRPB_TERMS}
        info |= {"is_success": False, "collision": False, "goal_distance": 0.0, "t": 0.0}
        # episode metrics: filled on the last step; 0.0 before (NaN would make identical
        # runs compare unequal, and planning time, being wall time, is not reported here)
        info |= {f"srpb/{m}": 0.0 for m in METRIC_NAMES}
        info |= {f"srpb_gt/{m}": 0.0 for m in METRIC_NAMES}
        return info

    # ------------------------------------------------------------------ API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        self._seed = seed
        layout = self._layout(options or {})
        self.sim.reset(layout, self.np_random)
        self._collided = False
        record = self.sim.robots[0].record
        distance = self.sim.goal_distance()
        self.reward_fn.reset(record, distance)
        self._episode += 1
        info = dict(self._info_template)
        info["goal_distance"] = distance
        obs = self._observation()
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        started = time.perf_counter()
        planning = self._planning_override
        if planning is None:
            planning = started - self._last_return
        self._planning_override = None
        self.sim.step(self._command(action), planning)
        collided = bool(self.sim.collisions[0].any())
        self._collided |= collided
        distance = self.sim.goal_distance()
        reached = self._goal_reached(distance)
        terminated = reached or (collided and self.collision_mode == "terminate")
        truncated = not terminated and self.sim.t >= self.sim.layout.time_limit - 1e-9
        success = reached and not self._collided
        record = self.sim.robots[0].record
        reward = self.reward_fn.step(record, distance, success, collided)
        info = self._step_info(collided, success, distance)
        if terminated or truncated:
            self._finish_episode(info)
        obs = self._observation()
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return obs, reward, terminated, truncated, info

    def set_planning_time(self, seconds: float) -> None:
        """Use ``seconds`` as the planner computation time of the next step instead of the
        measured wall time (for harnesses that time the planner themselves)."""
        if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"planning time must be a finite number >= 0, got {seconds!r}")
        self._planning_override = float(seconds)

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; set render_mode at make()")
            return None
        if self._renderer is None:
            from srpb_gym.render import Renderer

            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        return self._renderer.render(self.sim, 0, self.running_metrics())

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def knowledge(self) -> Knowledge:
        """What the robot knows now, for classical planners (never the ground truth)."""
        sim, state = self.sim, self.sim.robots[0]
        return Knowledge(
            walls=sim.walls, bounds=sim.layout.bounds, pose=sim.world.robot_pose[0].copy(),
            velocity=sim.velocity[0].copy(), command=sim.command[0].copy(),
            goal=state.goal.copy(), goal_tolerance=self.params.goal_tolerance_xy,
            goal_yaw_tolerance=self.params.goal_tolerance_yaw, tracks=state.tracker.tracks(),
            scan=state.scan.copy(), scan_angles=state.lidar.angles,
            range_max=sim.lidar_config.range_max, robot=sim.robot_config,
            control_dt=sim.config.control_dt, t=sim.t,
        )  # fmt: skip

    def running_metrics(self) -> dict[str, float]:
        """The episode's SRPB metrics so far (tracked people), for display."""
        record = self.sim.robots[0].record
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SRPBMetricWarning)
            values = evaluate(record, self.semantics, self.params)
        keys = ("m_psi", "m_fsi", "m_dir", "m_obs", "m_plin", "m_chc")
        return {"t": self.sim.t} | {k: values[k] for k in keys}

    # ------------------------------------------------------------------ internals
    def _layout(self, options: dict[str, Any]):
        unknown = set(options) - set(RESET_OPTIONS)
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; valid: {RESET_OPTIONS}")
        layout = sample(self.scenario, self.np_random)
        if not options.get("people", True):
            layout = replace(layout, people=(), formations=())
        if "start" in options or "goal" in options:
            robot = layout.robots[0]
            start = tuple(float(v) for v in options.get("start", robot.start))
            goal = tuple(float(v) for v in options.get("goal", robot.goal))
            if len(start) != 3 or len(goal) != 3:
                raise ValueError("start and goal options are (x, y, yaw)")
            layout = replace(layout, robots=(RobotLayout(start, goal),))
        return layout

    def _command(self, action: Any) -> NDArray[np.float64]:
        """(1, 3) body-frame command of an action (see the class docstring)."""
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        a = a.tolist()
        if not all(map(math.isfinite, a)):
            raise ValueError(f"action must be finite, got {a}")
        a = [min(max(v, -1.0), 1.0) for v in a]
        cfg, cmd = self.sim.robot_config, self._cmd
        cmd[0, 0] = a[0] * (cfg.v_max if a[0] >= 0 else -cfg.v_min)
        if cfg.kinematics == "holonomic":
            cmd[0, 1], cmd[0, 2] = a[1] * cfg.vy_max, a[2] * cfg.w_max
        else:
            cmd[0, 2] = a[1] * cfg.w_max
        return cmd

    def _goal_reached(self, distance: float) -> bool:
        yaw = self.sim.world.robot_pose[0, 2]
        goal_yaw = self.sim.robots[0].goal[2]
        yaw_error = abs(math.remainder(goal_yaw - yaw, 2 * math.pi))
        return (distance <= self.params.goal_tolerance_xy
                and yaw_error <= self.params.goal_tolerance_yaw)  # fmt: skip

    def _observation(self):
        state = self.sim.robots[0]
        pose = self.sim.world.robot_pose[0]
        return self.obs_builder.build(pose, state.goal, self.sim.velocity[0], state.scan,
                                      state.tracker.tracks())  # fmt: skip

    def _step_info(self, collided: bool, success: bool, distance: float) -> dict[str, Any]:
        info = dict(self._info_template)
        info.update(zip(self._reward_keys, self.reward_fn.weighted.tolist()))
        info.update(zip(self._step_keys, self.reward_fn.values[-len(SRPB_TERMS) :].tolist()))
        info["is_success"], info["collision"] = success, collided
        info["goal_distance"], info["t"] = distance, self.sim.t
        return info

    def _finish_episode(self, info: dict[str, Any]) -> None:
        state = self.sim.robots[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SRPBMetricWarning)
            tracked = evaluate(state.record, self.semantics, self.params)
            truth = evaluate(state.gt_record, self.semantics, self.params)
        for name in METRIC_NAMES:
            info[f"srpb/{name}"] = tracked[name]
            info[f"srpb_gt/{name}"] = truth[name]
        if self.record_dir is not None:
            self._write_episode()

    def _write_episode(self) -> None:
        from srpb_gym.metrics.io_native import write_native
        from srpb_gym.metrics.io_npz import save_record

        os.makedirs(self.record_dir, exist_ok=True)
        stem = self.episode_name()
        base = os.path.join(self.record_dir, stem)
        record = self.sim.robots[0].record
        write_native(record, f"{base}_robot.txt", f"{base}_people.txt", f"{base}_groups.txt")
        save_record(record, f"{base}.npz")
        save_record(self.sim.robots[0].gt_record, f"{base}_gt.npz")

    def episode_name(self) -> str:
        """File stem of the current episode: ``<scenario>_seed<seed>`` when reset with a
        seed, else ``<scenario>_<instance>_<episode number>``."""
        if self._seed is not None:
            return f"{self.scenario.name}_seed{self._seed}"
        return f"{self.scenario.name}_{self._token}_{self._episode:05d}"
