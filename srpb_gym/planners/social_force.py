"""A social-force controller (Helbing and Molnar 1995) driving the robot along a global path.

The robot is a particle in the social force model: attraction to a lookahead point on the
:class:`~srpb_gym.planners.global_planner.GlobalPlanner` path at the preferred speed,
repulsion from each tracked person (exponential in the distance at the closest approach
within ``anticipation`` seconds at constant velocities, weighted by the anisotropy of the
robot's field of view, Zanlungo et al. 2011) and from obstacles: the static map (its
distance field's gradient) and the lidar points that are neither walls nor tracked people.
The resulting desired velocity becomes a differential-drive command: turn towards it,
drive at its speed times the cosine of the heading error. Every command is checked by the
DWA's rollout kernel: the fastest of a few speeds (same turn rate) that collides with
nothing within the check horizon is sent, else the robot turns in place. At the goal it
turns in place to the goal heading; when stuck it runs the DWA's recoveries.
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


@dataclass(frozen=True)
class SocialForcePlannerConfig(PlannerConfig):
    """Settings of the :class:`SocialForcePlanner` (lengths in m, times in s, speeds in
    m/s, accelerations in m/s^2). The robot's radius, bumper, velocity and acceleration
    limits come from its :class:`~srpb_gym.sim.robot.RobotConfig`."""

    # attraction
    v_pref: float | None = None  # m/s, preferred speed (None: the robot's v_max)
    lookahead: float = 1.0  # m, towards the path point this far ahead
    approach_decel: float = 0.6  # m/s^2, slow down within this braking distance of the goal
    arrive_radius: float = 0.1  # m, closer to the goal: turn in place to its heading
    # repulsion
    tau: float = 0.5  # s, the repulsions times this are added to the desired velocity
    a_person: float = 2.0  # m/s^2, a person's repulsion a exp(-gap / b) ...
    b_person: float = 0.35  # m, ... at the closest approach within ``anticipation``
    person_radius: float = PERSON_RADIUS  # m, assumed body radius of a tracked person
    anticipation: float = 1.5  # s, horizon of a person's closest approach
    anisotropy: float = 0.3  # weight of a person behind the robot (ahead: 1)
    a_obstacle: float = 2.0  # m/s^2, a wall's or lidar point's repulsion a exp(-d / b) ...
    b_obstacle: float = 0.15  # m, ... d the robot's clearance
    standing_speed: float = 0.25  # m/s, slower people are treated as standing still
    # command
    k_turn: float = 2.0  # 1/s, omega = k_turn x heading error
    # safety check of each command
    check_horizon: float = 1.5  # s, rolled out this long against walls and lidar points ...
    sim_dt: float = 0.1  # s, ... in steps of this
    safety_margin: float = 0.05  # m, beyond the robot's radius plus bumper
    people_horizon: float = 1.0  # s, and this long against people ...
    person_margin: float = 0.1  # m, ... kept this far beyond the two radii
    # parts
    global_planner: GlobalPlannerConfig = field(default_factory=GlobalPlannerConfig)
    recovery: RecoveryConfig = field(default_factory=RecoveryConfig)

    def __post_init__(self) -> None:
        if self.v_pref is not None:
            self._positive("v_pref")
        self._positive("lookahead", "approach_decel", "b_person", "b_obstacle", "k_turn",
                       "check_horizon", "sim_dt")  # fmt: skip
        self._nonnegative("arrive_radius", "tau", "a_person", "person_radius", "anticipation",
                          "a_obstacle", "standing_speed", "safety_margin", "people_horizon",
                          "person_margin")  # fmt: skip
        self._within("anisotropy", 0.0, 1.0)
        self._nested("global_planner", GlobalPlannerConfig)
        self._nested("recovery", RecoveryConfig)


class SocialForcePlanner(Planner):
    """Social-force navigation along the global path.

    Attraction: towards the path point ``lookahead`` [m] ahead at ``v_pref`` [m/s]
    (v_max when None), slowing down within the braking distance of ``approach_decel``
    [m/s^2] of the goal. Repulsion, added to the desired velocity times ``tau`` [s]:
    people ``a_person`` [m/s^2] exp(-d / ``b_person``), d [m] the gap between the robot and
    a person of radius ``person_radius`` [m] at their closest approach within
    ``anticipation`` [s], weighted by ``anisotropy`` + (1 - ``anisotropy``) (1 + cos phi) / 2
    (phi: bearing of the person from the robot's heading); obstacles ``a_obstacle``
    [m/s^2] exp(-d / ``b_obstacle``) from the nearest wall and the nearest unknown lidar
    point, d [m] the robot's clearance. Turning: omega = ``k_turn`` [1/s] x heading error.
    Safety check: ``check_horizon`` [s] in steps of ``sim_dt`` [s] against walls and lidar
    points (clearance over the collision shape: ``safety_margin`` [m]) and
    ``people_horizon`` [s] against people (``person_margin`` [m] more than the two radii).
    ``global_planner`` and ``recovery``: the settings of its :class:`GlobalPlanner` and
    :class:`~srpb_gym.planners.recovery.Recovery`.

    ``config``: the settings (:class:`SocialForcePlannerConfig`, a mapping of the fields to
    change, or ``None``: the defaults).
    """

    name = "social-force"
    config_class: ClassVar[type[SocialForcePlannerConfig]] = SocialForcePlannerConfig

    def __init__(self, config: SocialForcePlannerConfig | Mapping[str, Any] | None = None) -> None:
        self.config = cfg = self.config_class.from_spec(config)
        self.planner = GlobalPlanner(cfg.global_planner, cfg.person_radius)
        self.recovery = Recovery(cfg.recovery)
        self._steps = max(round(cfg.check_horizon / cfg.sim_dt), 1)
        self._traj = np.empty((4, self._steps, 4))
        self._out = np.empty((5, 4))

    def reset(self, knowledge: Knowledge) -> None:
        self.planner.reset(knowledge)
        self.recovery.reset()
        self._arrived = False

    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        v, w = self.decide(knowledge)
        return command_to_action(v, 0.0, w, knowledge.robot)

    def decide(self, knowledge: Knowledge) -> tuple[float, float]:
        """The (v [m/s], omega [rad/s]) command of this step."""
        k, gp = knowledge, self.planner
        x, y = float(k.pose[0]), float(k.pose[1])
        dist = math.hypot(k.goal[0] - x, k.goal[1] - y)
        if self._arrived or dist <= self.config.arrive_radius:
            self._arrived = dist < 0.9 * k.goal_tolerance
            if self._arrived:
                return goal_turn(k)
        gp.update(k)
        rec = self.recovery
        target = gp.lookahead(self.config.lookahead)
        ahead = target - k.pose[:2]
        clear = float(gp.clearance(np.array([x]), np.array([y]))[0])
        rec.observe(k, gp.cost_to_go(x, y), ahead / max(float(np.hypot(*ahead)), 1e-9), clear)
        if rec.phase:
            cmd = rec.command(k, gp, target)
            if cmd is not None:
                return cmd
            if rec.phase == "retreat":
                target, dist = rec.target, math.hypot(rec.target[0] - x, rec.target[1] - y)
        v_des = self.desired_velocity(k, target, dist)
        return self._command(k, v_des)

    def desired_velocity(
        self, k: Knowledge, target: NDArray[np.float64], dist: float
    ) -> NDArray[np.float64]:
        """World-frame desired velocity [m/s]: attraction plus tau times the repulsions."""
        cfg, robot, gp = self.config, k.robot, self.planner
        pos, yaw = k.pose[:2], float(k.pose[2])
        heading = np.array([math.cos(yaw), math.sin(yaw)])
        speed = min(cfg.v_pref or robot.v_max, robot.v_max)
        speed = min(speed, math.sqrt(2.0 * cfg.approach_decel * max(dist - 0.05, 0.0)))
        to_target = target - pos
        v_goal = speed * to_target / max(float(np.hypot(*to_target)), 1e-9)
        force = np.zeros(2)
        tr = k.tracks
        if tr.xy.shape[0]:
            v_robot = float(k.command[0]) * heading
            vel = np.where(np.hypot(*tr.velocity.T)[:, None] < cfg.standing_speed, 0.0,
                           tr.velocity)  # fmt: skip
            rel = pos - tr.xy  # person -> robot
            dv = v_robot - vel
            t_min = np.clip(-(rel * dv).sum(axis=1) / np.maximum((dv * dv).sum(axis=1), 1e-9),
                            0.0, cfg.anticipation)  # fmt: skip
            rel_c = rel + dv * t_min[:, None]
            dist_c = np.maximum(np.hypot(*rel_c.T), 1e-6)
            gap = dist_c - gp.robot_radius - cfg.person_radius
            cos_phi = -(rel @ heading) / np.maximum(np.hypot(*rel.T), 1e-6)
            weight = cfg.anisotropy + (1.0 - cfg.anisotropy) * 0.5 * (1.0 + cos_phi)
            mag = cfg.a_person * np.exp(-gap / cfg.b_person) * weight
            force += (mag[:, None] * rel_c / dist_c[:, None]).sum(axis=0)
        force += self._obstacle_force(k)
        return v_goal + cfg.tau * force

    def _obstacle_force(self, k: Knowledge) -> NDArray[np.float64]:
        """Repulsion from the nearest wall (distance-field gradient) and the nearest lidar
        point that is neither a wall nor a tracked person [m/s^2]."""
        cfg, gp = self.config, self.planner
        x, y = float(k.pose[0]), float(k.pose[1])
        h = 0.5 * gp.res
        d = gp.clearance(np.array([x, x + h, x - h, x, x]), np.array([y, y, y, y + h, y - h]))
        grad = np.array([d[1] - d[2], d[3] - d[4]])
        force = np.zeros(2)
        norm = float(np.hypot(*grad))
        if norm > 1e-9:
            mag = cfg.a_obstacle * math.exp(-(d[0] - gp.robot_radius) / cfg.b_obstacle)
            force += mag * grad / norm
        pts = scan_points(k, gp, 1.5, cfg.person_radius)
        if pts.shape[0]:
            rel = k.pose[:2] - pts
            dist = np.hypot(*rel.T)
            i = int(np.argmin(dist))
            mag = cfg.a_obstacle * math.exp(-(dist[i] - gp.robot_radius) / cfg.b_obstacle)
            force += mag * rel[i] / max(dist[i], 1e-6)
        return force

    def _command(self, k: Knowledge, v_des: NDArray[np.float64]) -> tuple[float, float]:
        """Differential-drive command towards ``v_des``: the fastest safe of a few speeds."""
        cfg, robot, gp = self.config, k.robot, self.planner
        yaw = float(k.pose[2])
        err = float(wrap_angle(math.atan2(v_des[1], v_des[0]) - yaw))
        w = float(np.clip(cfg.k_turn * err, -robot.w_max, robot.w_max))
        v = float(min(np.hypot(*v_des), robot.v_max)) * max(math.cos(err), 0.0)
        if abs(err) > 0.5 * math.pi:
            v = 0.0
        vt = np.array([v, 0.66 * v, 0.33 * v, 0.0])
        wt = np.full(4, w)
        pts = scan_points(k, gp, robot.v_max * cfg.check_horizon + 1.0, cfg.person_radius)
        people = people_array(k, gp.robot_radius, cfg.person_radius, cfg.person_margin,
                              cfg.standing_speed)  # fmt: skip
        x, y = float(k.pose[0]), float(k.pose[1])
        d0 = float(gp.clearance(np.array([x]), np.array([y]))[0])
        if pts.shape[0]:
            d0 = min(d0, float(np.hypot(pts[:, 0] - x, pts[:, 1] - y).min()))
        r_static = max(gp.robot_radius + 0.01, min(gp.robot_radius + cfg.safety_margin, d0 - 0.01))
        clear, t_static, gap, t_people, gap_near = self._out
        rollout(x, y, yaw, float(k.command[0]), float(k.command[2]), vt, wt, robot.acc_lin,
                robot.acc_ang, cfg.sim_dt, gp.dist, gp.x0, gp.y0, gp.res, pts, people, r_static,
                cfg.people_horizon, 0, self._traj, clear, t_static, gap, t_people,
                gap_near)  # fmt: skip
        ok = np.flatnonzero((t_static == np.inf) & (t_people > cfg.people_horizon))
        if ok.size:
            return float(vt[ok[0]]), w
        return 0.0, w
