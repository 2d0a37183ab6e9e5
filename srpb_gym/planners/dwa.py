"""The Dynamic Window Approach (Fox, Burgard and Thrun 1997) following a global path.

Each step samples target velocities (v, omega) and rolls every one out over the horizon
with the base's acceleration limits from the last command (the dynamic window: what the
base can reach), as the environment's velocity limiter will execute it. One compiled kernel
simulates all samples and measures their clearance from the static map and the lidar
points, and their gap to the tracked people predicted at constant velocity. Trajectories
that hit an obstacle within the horizon, or come closer than the safety distance to a
predicted person within ``people_horizon``, are inadmissible; the others are scored by
weighted critics (path distance, progress along the path, heading to a lookahead point,
clearance, people, speed, turning) and the cheapest one's velocity is commanded.

Near the goal the robot slows down and turns in place to the goal heading. When no
trajectory is admissible it takes the least bad one (often stop or turn); when it makes no
progress for a while it runs a recovery (back up slowly if clear behind, rotate in place,
replan).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.base import PERSON_RADIUS, Planner, command_to_action
from srpb_gym.planners.config import PlannerConfig
from srpb_gym.planners.global_planner import GlobalPlanner, GlobalPlannerConfig
from srpb_gym.planners.recovery import Recovery, RecoveryConfig, goal_turn
from srpb_gym.planners.rollout import people_array, rollout, scan_points

#: A recovery gives way to the trajectory choice when a person would walk into the robot
#: standing still within this time [s].
THREAT_HORIZON = 1.5


@dataclass(frozen=True)
class DWAConfig(PlannerConfig):
    """Settings of the :class:`DWA` (lengths in m, times in s, speeds in m/s, angles in
    rad). The robot's radius, bumper, velocity and acceleration limits come from its
    :class:`~srpb_gym.sim.robot.RobotConfig` (the planner's ``Knowledge``)."""

    # sampling
    n_v: int = 11  # linear velocity targets in [0, v_max] (and v_min, as a last resort)
    n_w: int = 21  # angular velocity targets in [-w_max, w_max]
    horizon: float = 2.0  # s, each sample is rolled out this long ...
    sim_dt: float = 0.1  # s, ... in steps of this
    candidates: int = 80  # social costs of this many admissible samples of lowest cost
    # safety
    safety_margin: float = 0.05  # m, beyond the robot's radius plus bumper: walls, points
    person_radius: float = PERSON_RADIUS  # m, assumed body radius of a tracked person
    person_margin: float = 0.1  # m, beyond the two radii: inadmissible near a person ...
    people_horizon: float = 1.2  # s, ... predicted at constant velocity this far ahead
    people_lookahead: float = 3.5  # s, the people cost looks this far (robot stopped after)
    standing_speed: float = 0.15  # m/s, slower people are predicted standing still
    people_range: float = 6.0  # m, farther people are ignored
    # critics: the cost of a sample is their weighted sum
    w_path: float = 3.0  # 1/m, end point's distance to the path
    w_progress: float = 2.0  # 1/m, arc length gained along the path (subtracted)
    w_heading: float = 0.6  # 1/rad, end heading's error to the path point ``lookahead`` on
    lookahead: float = 0.8  # m, how far along the path the heading critic looks
    w_goal: float = 2.0  # 1/m, end point's distance to the goal when within reach
    w_clear: float = 0.5  # obstacle cost exp(-(clearance - safe) / clear_scale)
    clear_scale: float = 0.15  # m, decay length of the obstacle cost
    w_people: float = 1.0  # people cost exp(-gap / people_scale), gap >= -0.5 m
    people_scale: float = 0.45  # m, decay length of the people cost
    w_speed: float = 0.2  # (1 - v / v_max)
    w_turn: float = 0.05  # |omega| / w_max
    w_smooth: float = 0.1  # |omega - previous omega| / w_max
    # goal
    arrive_radius: float = 0.1  # m, closer to the goal: turn in place to its heading
    approach_decel: float = 0.6  # m/s^2, the deceleration the approach speed cap allows
    # parts
    global_planner: GlobalPlannerConfig = field(
        default_factory=lambda: GlobalPlannerConfig(person_margin=0.1)
    )
    recovery: RecoveryConfig = field(default_factory=RecoveryConfig)

    def __post_init__(self) -> None:
        self._count("n_v", 2)
        self._count("n_w", 2)
        self._count("candidates", 1)
        self._positive("horizon", "sim_dt", "lookahead", "clear_scale", "people_scale",
                       "approach_decel")  # fmt: skip
        self._nonnegative("safety_margin", "person_radius", "person_margin", "people_horizon",
                          "people_lookahead", "standing_speed", "people_range", "w_path",
                          "w_progress", "w_heading", "w_goal", "w_clear", "w_people",
                          "w_speed", "w_turn", "w_smooth", "arrive_radius")  # fmt: skip
        self._nested("global_planner", GlobalPlannerConfig)
        self._nested("recovery", RecoveryConfig)


class DWA(Planner):
    """Dynamic Window Approach along the :class:`GlobalPlanner` path.

    Sampling: ``n_v`` linear targets in [0, v_max] and ``n_w`` angular targets in
    [-w_max, w_max], simulated for ``horizon`` [s] in steps of ``sim_dt`` [s].
    Safety: the collision shape is the robot radius plus bumper; trajectories closer than
    that plus ``safety_margin`` [m] to a wall or a lidar point are inadmissible, and so are
    those closer than the collision shape plus ``person_radius`` + ``person_margin`` [m]
    to a person predicted at constant velocity within ``people_horizon`` [s]. The people
    cost looks ``people_lookahead`` [s] ahead (the robot stopped at the trajectory's end
    after the horizon); people slower than ``standing_speed`` [m/s] are predicted standing
    still; people farther than ``people_range`` [m] are ignored. Reversing at v_min is
    sampled too, but only as a last resort. Extra (social) costs are computed for the
    ``candidates`` admissible samples of lowest cost only.
    Critic weights (the cost is their sum; lengths in m, angles in rad):
    ``w_path`` [1/m] end point's distance to the path; ``w_progress`` [1/m] arc length
    gained along the path (subtracted); ``w_heading`` [1/rad] end heading's error to the
    path point ``lookahead`` [m] further on; ``w_goal`` [1/m] end point's distance to the
    goal when it is within reach; ``w_clear`` obstacle cost exp(-(clearance - safe) /
    ``clear_scale``) with clearance and ``clear_scale`` in m; ``w_people`` people cost
    exp(-gap / ``people_scale``) (gap in m, negative inside the safety distance, >= -0.5);
    ``w_speed`` (1 - v / v_max); ``w_turn`` |omega| / w_max; ``w_smooth`` |omega -
    previous omega| / w_max.
    Goal: ``arrive_radius`` [m] distance under which the robot turns in place to the goal
    heading; ``approach_decel`` [m/s^2] the deceleration its speed cap allows before it.
    ``global_planner`` and ``recovery``: the settings of its :class:`GlobalPlanner` and
    :class:`~srpb_gym.planners.recovery.Recovery`.

    ``config``: the settings (:class:`DWAConfig`, a mapping of the fields to change, or
    ``None``: the defaults).
    """

    name = "dwa"
    config_class: ClassVar[type[DWAConfig]] = DWAConfig

    def __init__(self, config: DWAConfig | Mapping[str, Any] | None = None) -> None:
        self.config = cfg = self.config_class.from_spec(config)
        self.planner = GlobalPlanner(cfg.global_planner, cfg.person_radius)
        self.recovery = Recovery(cfg.recovery)
        self._steps = max(round(cfg.horizon / cfg.sim_dt), 1)
        self._hold = max(round((cfg.people_lookahead - cfg.horizon) / cfg.sim_dt), 0)

    # ------------------------------------------------------------------ episode
    def reset(self, knowledge: Knowledge) -> None:
        self.planner.reset(knowledge)
        self.recovery.reset()
        self._arrived = False
        self._w_prev = 0.0
        robot = knowledge.robot
        v = np.concatenate([[robot.v_min], np.linspace(0.0, robot.v_max, self.config.n_v)])
        w = np.linspace(-robot.w_max, robot.w_max, self.config.n_w)
        self._vt, self._wt = (a.ravel().copy() for a in np.meshgrid(v, w, indexing="ij"))
        n = self._vt.shape[0]
        self._traj = np.empty((n, self._steps, 4))
        self._out = np.empty((5, n))

    # ------------------------------------------------------------------ decision
    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        v, w = self.decide(knowledge)
        self._w_prev = w
        return command_to_action(v, 0.0, w, knowledge.robot)

    def decide(self, knowledge: Knowledge) -> tuple[float, float]:
        """The (v [m/s], omega [rad/s]) command of this step."""
        k = knowledge
        gp = self.planner
        dist = math.hypot(k.goal[0] - k.pose[0], k.goal[1] - k.pose[1])
        if self._arrived or dist <= self.config.arrive_radius:
            self._arrived = dist < 0.9 * k.goal_tolerance
            if self._arrived:
                return goal_turn(k)
        gp.update(k)
        rec = self.recovery
        look = gp.lookahead(1.0)
        ahead = look - k.pose[:2]
        ahead = ahead / max(float(np.hypot(*ahead)), 1e-9)
        x, y = float(k.pose[0]), float(k.pose[1])
        clear = float(gp.clearance(np.array([x]), np.array([y]))[0])
        rec.observe(k, gp.cost_to_go(x, y), ahead, clear)
        if rec.phase:
            cmd = rec.command(k, gp, look)
            if cmd is not None and not self._threatened(k):
                return cmd
            if rec.phase == "retreat":  # drive back along the trail
                target = rec.target
                n = max(int(np.hypot(*(target - k.pose[:2])) / gp.config.spacing), 1) + 1
                local = np.linspace(k.pose[:2], target, n)
                s_local = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(local, axis=0).T))])
                return self._best(k, local, s_local, target)
        local, s_local = gp.local(3.0 + k.robot.v_max * self.config.horizon)
        return self._best(k, local, s_local, k.goal[:2])

    def _threatened(self, k: Knowledge) -> bool:
        """Whether a tracked person walks into the robot standing still within
        :data:`THREAT_HORIZON` [s] (then a recovery yields to the people-aware trajectory
        choice)."""
        people = self._people(k)
        if people.shape[0] == 0:
            return False
        dt = self.config.sim_dt
        t = np.arange(1, round(THREAT_HORIZON / dt) + 1) * dt
        px = people[None, :, 0] + people[None, :, 2] * t[:, None] - k.pose[0]
        py = people[None, :, 1] + people[None, :, 3] * t[:, None] - k.pose[1]
        return bool((np.hypot(px, py) < people[None, :, 4]).any())

    def _best(
        self, k: Knowledge, local: NDArray[np.float64], s_local: NDArray[np.float64],
        goal: NDArray[np.float64],
    ) -> tuple[float, float]:  # fmt: skip
        """The best sample following ``local`` (path points, arc length ``s_local``) to
        ``goal`` (x, y)."""
        cfg, gp, robot = self.config, self.planner, k.robot
        x, y, yaw = (float(a) for a in k.pose)
        dist = math.hypot(goal[0] - x, goal[1] - y)
        cap = math.sqrt(2.0 * cfg.approach_decel * max(dist - 0.5 * cfg.arrive_radius, 0.0))
        vt = np.minimum(self._vt, max(cap, 0.05))
        pts = self._scan_points(k)
        people = self._people(k)
        r_hard = gp.robot_radius + 0.01
        d0 = float(gp.clearance(np.array([x]), np.array([y]))[0])
        if pts.shape[0]:
            d0 = min(d0, float(np.hypot(pts[:, 0] - x, pts[:, 1] - y).min()))
        r_static = max(r_hard, min(gp.robot_radius + cfg.safety_margin, d0 - 0.01))
        traj, (clear, t_static, gap, t_people, gap_near) = self._traj, self._out
        rollout(x, y, yaw, float(k.command[0]), float(k.command[2]), vt, self._wt,
                robot.acc_lin, robot.acc_ang, cfg.sim_dt, gp.dist, gp.x0, gp.y0, gp.res,
                pts, people, r_static, cfg.people_horizon, self._hold, traj, clear, t_static,
                gap, t_people, gap_near)  # fmt: skip
        cost = self._critics(k, vt, traj, clear, gap, local, s_local, goal)
        ok = (t_static == np.inf) & (t_people > cfg.people_horizon) & (vt >= 0.0)
        if ok.any():  # extra costs of the most promising admissible samples only
            rows = np.flatnonzero(ok)
            rows = rows[np.argsort(cost[rows], kind="stable")[: cfg.candidates]]
            extra = np.full(cost.shape[0], np.inf)
            extra[rows] = self._social_costs(k, traj[rows])
            cost = cost + extra
            best = int(np.argmin(np.where(ok, cost, np.inf)))
        else:  # least bad: no static hit, then the largest gap to people soon (keeping the
            # turn it had: flipping between turns leaves it in the way)
            score = np.where(t_static == np.inf, 10.0, t_static) * 100.0 + np.minimum(
                gap_near, 10.0) - 0.1 * np.abs(self._wt - self._w_prev) / robot.w_max  # fmt: skip
            best = int(np.argmax(score))
        return float(vt[best]), float(self._wt[best])

    def _critics(self, k: Knowledge, vt, traj, clear, gap, local, s_local, goal) -> NDArray:
        """Weighted sum of the critics of every sample (see the class docstring)."""
        cfg, gp, robot = self.config, self.planner, k.robot
        end = traj[:, -1, :]
        dist = math.hypot(goal[0] - k.pose[0], goal[1] - k.pose[1])
        d = np.hypot(end[:, None, 0] - local[None, :, 0], end[:, None, 1] - local[None, :, 1])
        j = np.argmin(d, axis=1)
        path_d = d[np.arange(j.shape[0]), j]
        progress = s_local[j]
        look_idx = np.minimum(np.searchsorted(s_local, progress + cfg.lookahead), len(local) - 1)
        look = local[look_idx]
        to_look = np.arctan2(look[:, 1] - end[:, 1], look[:, 0] - end[:, 0])
        head = np.abs(wrap_angle(to_look - end[:, 2]))
        near = np.hypot(look[:, 0] - end[:, 0], look[:, 1] - end[:, 1]) < 0.3
        head = np.where(near, 0.0, head)
        cost = cfg.w_path * path_d - cfg.w_progress * progress + cfg.w_heading * head
        if dist < robot.v_max * cfg.horizon + cfg.lookahead:
            cost += cfg.w_goal * np.hypot(end[:, 0] - goal[0], end[:, 1] - goal[1])
        safe = gp.robot_radius + cfg.safety_margin
        cost += cfg.w_clear * np.exp(-np.maximum(clear - safe, 0.0) / cfg.clear_scale)
        cost += cfg.w_people * np.exp(-np.maximum(gap, -0.5) / cfg.people_scale)
        cost += cfg.w_speed * (1.0 - vt / robot.v_max)
        cost += cfg.w_turn * np.abs(self._wt) / robot.w_max
        cost += cfg.w_smooth * np.abs(self._wt - self._w_prev) / robot.w_max
        return cost

    def _social_costs(self, k: Knowledge, traj: NDArray[np.float64]) -> NDArray[np.float64]:
        """Extra costs of the admissible trajectories ``traj`` (none here; see
        :class:`SocialDWA`)."""
        return np.zeros(traj.shape[0])

    # ------------------------------------------------------------------ perception
    def _scan_points(self, k: Knowledge) -> NDArray[np.float64]:
        reach = k.robot.v_max * self.config.horizon + 1.0
        return scan_points(k, self.planner, reach, self.config.person_radius)

    def _people(self, k: Knowledge) -> NDArray[np.float64]:
        cfg = self.config
        people = people_array(k, self.planner.robot_radius, cfg.person_radius,
                              cfg.person_margin, cfg.standing_speed)  # fmt: skip
        # people that cannot come within 1.5 m of any trajectory in the lookahead are left out
        dist = np.hypot(people[:, 0] - k.pose[0], people[:, 1] - k.pose[1])
        reach = k.robot.v_max * cfg.horizon + np.hypot(people[:, 2], people[:, 3]) * (
            cfg.people_lookahead) + people[:, 4] + 1.5  # fmt: skip
        return people[(dist < reach) & (dist < cfg.people_range)]
