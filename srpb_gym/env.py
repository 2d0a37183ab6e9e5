"""The Gymnasium environment: one robot navigating among people, scored by SRPB.

:class:`SRPBNavEnv` is a thin adapter over one :class:`~srpb_gym.simulation.Simulation` and
one :class:`~srpb_gym.task.RobotTask`: the task owns the robot's action decoding, goal
rule, reward, observation, info and episode end; the adapter adds the Gymnasium API, the
episode's time and step limits, the planner's computation time and rendering.
"""

from __future__ import annotations

import math
import os
import time
import uuid
from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from srpb_gym.episode_setup import (
    RESET_OPTIONS,
    check_render_mode,
    episode_layout,
    out_of_time,
    planning_seconds,
    route_choice,
)
from srpb_gym.errors import InputError
from srpb_gym.knowledge import Knowledge
from srpb_gym.metrics.params import MetricParams
from srpb_gym.observation import ObservationConfig
from srpb_gym.render import Renderer
from srpb_gym.settings import EnvSettings
from srpb_gym.sim.layout import EpisodeLayout
from srpb_gym.task import COLLISION_MODES

__all__ = ["COLLISION_MODES", "RESET_OPTIONS", "EnvSettings", "SRPBNavEnv", "StepLimitSync"]


class SRPBNavEnv(gym.Env):
    """Human-aware navigation in a 2-D world of walls and people, scored by the SRPB metrics.

    ## Description
    A robot (a differential drive by default: circumradius 0.275 m and the limits of the
    SRPB paper's Table 2; ``robot={...}`` changes them) drives from a start to a goal pose
    through a scenario of walls, walking people (social-force model) and standing
    F-formations. It senses with a lidar and a people detector whose detections feed a
    Kalman tracker; the observation, the SRPB reward terms and the episode metrics use the
    tracked people (with their covariances), like the paper's robot, and the metrics are
    also reported from ground truth. The robot's settings are the one source for
    everything that depends on them: the physics, the scenario's placement and
    reachability checks, the metric parameters (``robot_circumradius``,
    ``robot_max_speed``), the planners' knowledge and the renderer.

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
    | 1, 2 | cos, sin of the bearing of the goal | - | x min(1, d / ``goal_fade``) |
    | 3, 4 | cos, sin of (goal yaw - robot yaw) | - | - |
    | 5 | measured vx | m/s | / 0.5 (the largest speed) |
    | 6 | measured vy (0 for a differential drive) | m/s | / 0.3 (vy_max) |
    | 7 | measured omega | rad/s | / 1.05 |
    | 8 .. 8+L-1 | shortest lidar range of each of L sectors, right to left | m | / 25 (below) |
    | 8+L+7j+0, +1 | tracked person j (nearest first): relative x, y | m | / 8 (``people_range``) |
    | 8+L+7j+2, +3 | its velocity relative to the robot, x, y | m/s | / 2 (``speed_scale``) |
    | 8+L+7j+4, +5 | its position standard deviation along x, y | m | / 1 (``uncertainty_scale``) |
    | 8+L+7j+6 | presence: 1, or 0 for an empty slot (all its values 0) | - | - |

    ``observation={"type": "dict"}``: ``Dict`` with ``goal`` (5,), ``velocity`` (3,),
    ``lidar`` (L,), ``people`` (K, 6) and ``people_mask`` (K,), the same values. Other keys
    of the mapping (``lidar_bins``, ``people``, the scales) change L, K and the scales;
    ``lidar_encoding="log"`` encodes the lidar as log(r / 0.05 m) / log(25 m / 0.05 m)
    (the lidar's range_min and range_max) instead of r / 25 m: 2.5 cm at 0.3 m move it by
    0.013 instead of 0.001, so that a policy can tell the clearance of a door (a range_min
    below range_max / 1000 is taken as range_max / 1000). ``lidar_groups=0.01`` draws the
    O-spaces of the groups standing among the tracks into the lidar sectors, out to where
    their ``fsi`` value falls to 0.01 (groups: tracks slower than 0.3 m/s, tracked for 1 s
    or more, within ``group_distance``, 3 m, of another), so that the robot sees an
    F-formation as an obstacle; the physical lidar and the reward are unchanged (0: none,
    the default; see :mod:`srpb_gym.observation`). ``goal_fade=0.5`` fades the goal's
    bearing to (0, 0) within 0.5 m of the goal (scaled by the distance d over 0.5 m),
    where the bearing of a goal a centimetre away turns with every millimetre moved (0:
    never, the default). Models trained by ``srpb-gym train``
    record these settings and observe with them in any environment
    (:mod:`srpb_gym.planners.learned`).

    ## Rewards
    A weighted sum of named terms (:mod:`srpb_gym.reward`): task terms ``progress``,
    ``success``, ``collision``, ``time``, ``approach`` (potential-based shaping of the last
    1.5 m towards the goal's position and heading, in no preset) and SRPB per-step terms
    ``obs``, ``vsm``, ``hsm``, ``osc``, ``bwd``, ``iprot``, ``chc``, ``psi``, ``fsi``,
    ``dir``. ``reward="srpb"``
    (default) or ``"task"`` picks a preset (``configs/reward/``); every packaged scenario
    pays the preset as it is. A scenario file of your own may re-weight it in a ``reward``
    section (``envs/README.md``); ``reward_weights`` overrides weights by name. The
    weights in force are in the ``info`` of ``reset``: ``info["reward_weights"]``, every
    term by name.

    | term | ``srpb`` | ``task`` | paid |
    | --- | --- | --- | --- |
    | progress | 1.0 | 1.0 | per metre of progress towards the goal |
    | success | 10.0 | 10.0 | once, on reaching the goal |
    | collision | -25.0 | -25.0 | once, at a contact |
    | time | -0.1 | -0.1 | per second |
    | approach | 0 | 0 | potential-based, the last 1.5 m to the goal's pose |
    | obs | -0.2 | 0 | per second closer than ``safety_distance`` to an obstacle |
    | vsm | -0.002 | 0 | per m/s^2 of linear acceleration in the step |
    | hsm | -0.002 | 0 | per rad/s^2 of angular acceleration in the step |
    | osc | -0.05 | 0 | per second oscillating |
    | bwd | -0.1 | 0 | per second moving backward |
    | iprot | -0.05 | 0 | per second rotating in place |
    | chc | -0.05 | 0 | per radian of heading change |
    | psi | -1.0 | 0 | per second of full personal-space intrusion |
    | fsi | -0.6 | 0 | per second of full O-space intrusion |
    | dir | -0.2 | 0 | per second of heading straight into a person |

    The social terms (``psi``, ``fsi``, ``dir``) see the people the tracker reports, as
    the robot does (``reward_people="tracked"``, default); ``reward_people="ground_truth"``
    computes every term from the true people instead (a privileged reward, as the
    ``srpb_gt/`` metrics are; the observation stays the tracker's).
    ``info["reward_<term>"]`` holds each weighted term (they sum to the reward) and
    ``info["srpb_step/<term>"]`` the unweighted SRPB terms. The presets cannot be gamed by
    crashing: for a learner discounting by 0.99 per step, every shaping term at its worst
    on every remaining step costs less than the collision penalty
    (:func:`srpb_gym.reward.shaping_bound`); weights or settings that break this bound get
    a :class:`~srpb_gym.reward.RewardGameableWarning` at reset.

    ## Starting State
    Start and goal poses, people, their routes and parameters are sampled from the
    scenario's ranges with the environment's generator (``reset(seed=...)``).

    ## Episode End
    Terminated when the robot is within the scenario's goal tolerance of the goal position
    and within ``goal_tolerance_yaw`` (metric parameter, 0.2 rad) of its heading (the rule
    of ``m_goal``), or on a collision when ``collision="terminate"`` (default;
    ``"continue"`` penalises and goes on). Truncated at the scenario's time limit, or at
    the step limit of ``gym.make(..., max_episode_steps=N)`` (registered ids: the
    scenario's time limit at the default 0.1 s control step), whichever comes first: the
    environment ends the episode itself at that step, so ``TimeLimit`` and the environment
    agree. ``info["is_success"]``: goal reached with no collision in the episode.

    The last ``info`` of every episode, terminated or truncated, holds its SRPB metrics:
    ``info["srpb/<metric>"]`` from the tracked people, ``info["srpb_gt/<metric>"]`` from
    ground truth (equal to ``srpb-gym metrics`` of the recorded episode),
    ``info["srpb_semantics"]`` and ``info["srpb_params"]`` (every metric parameter used).
    Earlier steps do not have these keys, so a metric that was not computed can never be
    read as a number (vector environments mark them absent in ``info["_srpb/<metric>"]``;
    ``Monitor(info_keywords=...)`` reads them at the episode end). ``step`` after the end
    raises ``gymnasium.error.ResetNeeded``.

    ``info["collision"]`` is True on every step with a contact (a wall, a person or a
    robot). A step on which a contact with a body begins (one not touched on the step
    before; the walls count as one body) is a *collision*, and its info describes it
    (:mod:`srpb_gym.sim.contact`; two at once: the one closing faster):
    ``collision_kind`` (``"wall"``, ``"person"``, ``"robot"``), ``collision_by`` (who
    caused it: ``"robot"``, ``"person"`` or ``"other_robot"``, whoever closed the gap
    faster; a wall collision and a tie are the robot's), ``collision_robot_speed`` and
    ``collision_other_speed`` [m/s] (0 for a wall), ``collision_robot_closing`` and
    ``collision_other_closing`` [m/s] (each one's velocity towards the other along the
    line between them, the contact normal for a wall; negative: moving away). The
    velocities are those just before the contact's first impulse (the physics substep
    before it), so the collision does not hide who moved. Other steps lack these keys. The
    last ``info`` has ``collision_count`` (the episode's collisions: at most 1 with
    ``collision="terminate"``) and, after a collision, the first one as
    ``first_collision_kind``, ``first_collision_by``, ... (the same six fields), and
    ``people_pushed_back``: the most any walker moved against the way it walks in the
    episode [m] (:attr:`~srpb_gym.sim.crowd.Crowd.pushed_back`): a walker pushed back
    by a robot, which ``crowd={"robot_backing_gap": ...}`` limits to close range.

    ## Arguments
    ``scenario``: a packaged name (corridor, fformation, crossing, crowd, doorway) or a path
    to a YAML file. ``render_mode``: "human" or "rgb_array". ``observation``: type name or
    mapping of :class:`~srpb_gym.observation.ObservationConfig`. ``reward``: preset name.
    ``reward_weights``: weights by term. ``reward_people``: "tracked" or "ground_truth",
    the people the reward sees. ``collision``: "terminate" or "continue".
    ``metrics``: ``{"semantics": "paper"|"reference", "preset": "paper"|"srpb-code",
    "params": {...}}``; the robot's circumradius and largest speed and the scenario's goal
    tolerance replace the preset's values, and ``params`` replaces any value.
    ``record_dir``: write every episode there as SRPB native logs and an ``.npz`` record
    (created and checked when the environment is made). ``sim``, ``robot``, ``sensors``
    (``lidar``, ``detector``, ``tracker``), ``crowd``: overrides of the simulation
    settings. ``crowd`` takes the fields of :class:`~srpb_gym.sim.crowd.SocialForceConfig`;
    ``crowd={"robot_reaction": 0.0}`` makes the robot invisible to people (CrowdNav's
    "invisible robot"): it multiplies every person's own robot reaction (the scenario's
    per-walker ``robot_reaction``, F-formation members' ``formation_robot_reaction``);
    people still collide with the robot physically. Every argument is plain data;
    ``reset(options=...)`` takes ``people`` (False: an empty variant), ``start`` and
    ``goal`` (x, y, yaw). ``route``: which start and goal the robot draws from, ``None``
    (default) the scenario's ``robot`` entry, ``i`` its ``robots[i]`` entry (the route of
    robot i of the multi-robot environment), ``"random"`` one of its ``robots`` entries
    drawn for each episode with the environment's generator (to train a single robot for
    every robot's route), or a list of entries, one drawn for each episode (an entry
    listed twice is drawn twice as often); the entries must have the ``robot`` entry's
    goal tolerance.
    The arguments after ``render_mode`` and ``route`` are the environment's
    settings (:class:`~srpb_gym.settings.EnvSettings`, checked once when the environment
    is made; an unknown one is a ``TypeError``); ``settings=EnvSettings.from_kwargs({...})``
    passes them as one object instead (the same settings for several environments).

    The planner's computation time (m_cef, m_cre) is the wall time between the previous
    ``reset``/``step`` returning and this ``step`` starting, unless a harness calls
    :meth:`set_planning_time` before the step. Inside a vector environment that wall time
    includes the other environments' steps: set the time explicitly where it matters.

    ## Version History
    * v0: initial release. Later changes within v0 leave dynamics, reward, observations
      and metric values as they were: the episode metrics are only in the last ``info``
      (earlier steps used to carry placeholder 0.0 values) and at every truncation,
      ``TimeLimit``'s included; ``robot_circumradius`` and ``robot_max_speed`` come from
      the robot's settings (the same values for the default robot). Before the first
      release the reward presets were re-weighted so that no termination pays (collision
      -25, shaping bounded) and the fformation, crowd and doorway scenarios were reworked
      so that every SRPB metric is exercised, and corridor and fformation were given
      five times the ``srpb`` social and obstacle weights: returns and metrics of
      earlier v0 builds are not comparable with these. The ``approach`` term was added
      with weight 0 in both presets (their rewards unchanged). The observation setting
      ``lidar_encoding`` was added; its default ``"linear"`` is the observation as before.
      So were ``lidar_groups`` and ``group_distance``; by default (0) no O-space is drawn,
      the observation as before. ``corridor`` and ``fformation`` no longer re-weight the
      ``srpb`` preset (they paid its ``obs``, ``psi``, ``fsi`` and ``dir`` five times over,
      with ``collision`` -110): ``gym.make(id)`` pays the documented preset in every
      scenario, and returns of earlier builds in these two scenarios are not comparable
      (``reward_weights={obs: -1, psi: -5, fsi: -3, dir: -1, collision: -110}`` gives the
      former weights; metrics, dynamics and observations are unchanged). The info
      gained the attribution of collisions (``collision_kind``, ``collision_by``, ...,
      ``collision_count``); everything else is as it was. ``reward_people`` was added;
      its default ``"tracked"`` is the reward as before. ``route`` was added; by default
      the robot drives the scenario's ``robot`` entry, the episodes as before. The last
      info gained ``people_pushed_back``, and the crowd setting ``robot_backing_gap``
      was added; its default (inf) is the people's motion as before (with a finite gap
      people also never walk into a robot). ``route`` also takes a list of entries.
      The observation setting ``goal_fade`` was added; its default (0) is the
      observation as before.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str | os.PathLike[str] = "corridor",
        render_mode: str | None = None,
        settings: EnvSettings | None = None,
        *,
        route: int | str | Sequence[int] | None = None,
        **kwargs: Any,
    ) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.settings = EnvSettings.given(settings, kwargs, type(self).__name__)
        self.scenario = self.settings.load_scenario(scenario)
        self.route = route_choice(self.scenario, route)
        self.sim, (self.task,) = self.settings.build(self.scenario)
        self.observation_space = self.task.observation_space
        self.action_space = self.task.action_space
        self._cmd = np.zeros((1, 3))
        self._planning_override: float | None = None
        self._step_limit: int | None = None
        self._steps = 0
        self._renderer = None
        self._token, self._episode = uuid.uuid4().hex[:8], 0
        self._seed: int | None = None

    # ------------------------------------------------------------------ settings
    @property
    def params(self) -> MetricParams:
        """The SRPB metric parameters of the episodes (also the reward's)."""
        return self.task.params

    @property
    def observation_config(self) -> ObservationConfig:
        """What the robot observes: the resolved ``observation`` argument."""
        return self.task.obs_builder.config

    @property
    def semantics(self) -> str:
        """The SRPB semantics of the episode metrics: ``"paper"`` or ``"reference"``."""
        return self.task.metrics.semantics

    @property
    def record_dir(self) -> str | None:
        """Where finished episodes are written (``None``: not recorded)."""
        return self.task.record_dir

    def set_step_limit(self, steps: int | None) -> None:
        """End every episode after at most ``steps`` steps (truncated, with its metrics),
        besides the scenario's time limit. :class:`StepLimitSync` calls this with the limit
        of Gymnasium's ``TimeLimit`` wrapper, so both end the episode at the same step."""
        if steps is not None and not (isinstance(steps, int) and steps > 0):
            raise InputError(f"expected a whole number > 0, got {steps!r}",
                             key="max_episode_steps")  # fmt: skip
        self._step_limit = steps

    def _warn_short_limit(self) -> None:
        """Warn when the step limit ends episodes before the scenario's time limit."""
        steps, dt = self._step_limit, self.sim.config.control_dt
        limit = self.scenario.time_limit
        if steps is not None and steps * dt < limit - 1e-9:
            gym.logger.warn(
                f"{self.scenario.name}: episodes end after {steps} steps ({steps * dt:g} s), "
                f"before the scenario's time limit ({limit:g} s at control_dt {dt:g} s); "
                f"pass max_episode_steps={math.ceil(limit / dt - 1e-9)} to gym.make for the "
                f"whole scenario"
            )

    # ------------------------------------------------------------------ API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        rng = self._np_random
        saved = (rng, None if rng is None else rng.bit_generator.state, self._np_random_seed)
        try:
            super().reset(seed=seed)
            layout = self._layout(options)
        except Exception:  # bad options: the environment stays as it was
            self._np_random, state, self._np_random_seed = saved
            if self._np_random is not None:
                self._np_random.bit_generator.state = state
            raise
        self._seed = seed
        self._planning_override = None
        self.sim.reset(layout, self.np_random)
        self._steps = 0
        self._episode += 1
        obs, info = self.task.reset()
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        started = time.perf_counter()
        if self.task.done:
            raise gym.error.ResetNeeded(
                "call reset() before step(): no episode has started"
                if self._episode == 0 else
                "the episode has ended (terminated or truncated); call reset() before step()"
            )  # fmt: skip
        self.task.decode(action, self._cmd[0])  # a bad action raises before anything changes
        planning = self._planning_override
        if planning is None:
            planning = started - self._last_return
        self._planning_override = None
        self.sim.step(self._cmd, planning)
        self._steps += 1
        obs, reward, terminated, info = self.task.step()
        truncated = not terminated and self._out_of_time()
        if terminated or truncated:
            self.task.finish(info, self.episode_name())
        if self.render_mode == "human":
            self.render()
        self._last_return = time.perf_counter()
        return obs, reward, terminated, truncated, info

    def set_planning_time(self, seconds: float) -> None:
        """Use ``seconds`` as the planner computation time of the next step instead of the
        measured wall time (for harnesses that time the planner themselves)."""
        self._planning_override = planning_seconds(seconds)

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; set render_mode at make()")
            return None
        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        return self._renderer.render(self.sim, 0, self.running_metrics())

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def knowledge(self, ground_truth: bool = False) -> Knowledge:
        """What the robot knows now, for classical planners: the tracker's people, or with
        ``ground_truth`` the true people, for reference planners only
        (:meth:`srpb_gym.task.RobotTask.knowledge`)."""
        return self.task.knowledge(ground_truth)

    def running_metrics(self) -> dict[str, float]:
        """The episode's SRPB metrics so far (tracked people), for display."""
        return self.task.running_metrics()

    def episode_name(self) -> str:
        """File stem of the current episode: ``<scenario>_seed<seed>`` when reset with a
        seed, else ``<scenario>_<instance>_<episode number>``."""
        if self._seed is not None:
            return f"{self.scenario.name}_seed{self._seed}"
        return f"{self.scenario.name}_{self._token}_{self._episode:05d}"

    # ------------------------------------------------------------------ internals
    def _out_of_time(self) -> bool:
        return out_of_time(self.sim, self._steps, self._step_limit)

    def _layout(self, options: dict[str, Any] | None) -> EpisodeLayout:
        route = self.route
        if route == "random":
            route = int(self.np_random.integers(len(self.scenario.robots)))
        elif isinstance(route, tuple):
            route = route[int(self.np_random.integers(len(route)))]
        return episode_layout(self.scenario, self.np_random, options, route=route)


class StepLimitSync(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Tells the environment the step limit of the ``TimeLimit`` wrapper beneath it.

    Registered with every srpb-gym id (``additional_wrappers``), so ``gym.make(id,
    max_episode_steps=N)`` gives episodes that the environment itself ends at step N, with
    the episode metrics in the last ``info``; ``TimeLimit`` then agrees. It changes nothing
    else.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)
        spec = env.spec
        limit = spec.max_episode_steps if spec is not None else None
        base = env.unwrapped
        if isinstance(base, SRPBNavEnv):
            base.set_step_limit(limit)
            registered = gym.registry.get(spec.id) if spec is not None else None
            if registered is not None and registered.max_episode_steps == limit:
                base._warn_short_limit()  # the registered default, not the user's choice
