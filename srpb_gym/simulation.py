"""The simulation step pipeline for any number of robots; no Gym API.

One :meth:`Simulation.step` advances the world by one control step:

commands -> velocity and acceleration limits -> crowd desired velocities -> physics
substeps -> measured robot velocities -> obstacle distance, lidar scan, people detection ->
tracker -> groups seen -> one sample appended to each robot's SRPB records (tracked and
ground truth).

Every robot has its own lidar, detector, tracker, goal and records; robots see each other
in their lidar and avoid each other physically; people react to all robots. A record
sample n holds the state at time t_n and the planner computation time of the decision
taken at t_n, written when that decision arrives with the next :meth:`Simulation.step`;
the final sample, at which no decision is taken, keeps NaN there (the metrics skip it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from srpb_gym.config import from_spec
from srpb_gym.metrics.record import SAMPLES, EpisodeRecord, R
from srpb_gym.perception.detector import DetectorConfig, PeopleDetector
from srpb_gym.perception.groups import seen_groups
from srpb_gym.perception.lidar import Lidar, LidarConfig
from srpb_gym.perception.sensing import sense
from srpb_gym.perception.tracker import KalmanTracker, TrackerConfig
from srpb_gym.recording import GROW_TRACK_PERSON, GROW_TRACKED, MIN_GROUP, OK, record_sample
from srpb_gym.sim.contact import Collision
from srpb_gym.sim.crowd import Crowd, SocialForceConfig
from srpb_gym.sim.layout import EpisodeLayout
from srpb_gym.sim.robot import RobotConfig, body_to_world, limit_commands, measure_velocity
from srpb_gym.sim.world import World, clear_contacts

OBSTACLE_DISTANCE = ("exact", "lidar")
GOAL_FIELDS = [R["goal_x"], R["goal_y"], R["goal_yaw"]]


@dataclass(frozen=True)
class SimConfig:
    """Rates and options of the simulation (SI units)."""

    control_dt: float = 0.1  # s, one step of the agent
    physics_dt: float = 0.025  # s, one physics substep; control_dt / physics_dt substeps
    crowd_every_substep: bool = False  # recompute the social force at every substep
    # "exact": distance from the robot centre to the nearest wall or body;
    # "lidar": the shortest lidar range (what a real robot's costmap would see)
    obstacle_distance: str = "exact"

    def __post_init__(self) -> None:
        if not (self.control_dt > 0 and self.physics_dt > 0):
            raise ValueError("control_dt and physics_dt must be > 0")
        ratio = self.control_dt / self.physics_dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(
                f"control_dt ({self.control_dt} s) must be a whole multiple of "
                f"physics_dt ({self.physics_dt} s)"
            )
        if self.obstacle_distance not in OBSTACLE_DISTANCE:
            raise ValueError(f"obstacle_distance must be one of {OBSTACLE_DISTANCE}")

    @property
    def substeps(self) -> int:
        return round(self.control_dt / self.physics_dt)

    @classmethod
    def from_spec(cls, spec: Any, path: str = "sim", file: str | None = None) -> SimConfig:
        return from_spec(cls, spec, {"default": cls()}, path, file)


@dataclass
class RobotState:
    """Per-robot sensing of the latest step (arrays are overwritten every step)."""

    lidar: Lidar
    detector: PeopleDetector
    tracker: KalmanTracker
    record: EpisodeRecord
    gt_record: EpisodeRecord
    goal: NDArray[np.float64]
    scan: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    track_person: NDArray[np.int64] = field(default_factory=lambda: np.full(64, -1))


class Simulation:
    """A world of robots and people; see the module docstring for the step pipeline."""

    def __init__(
        self,
        sim: SimConfig | None = None,
        robot: RobotConfig | None = None,
        lidar: LidarConfig | None = None,
        detector: DetectorConfig | None = None,
        tracker: TrackerConfig | None = None,
        crowd: SocialForceConfig | None = None,
    ) -> None:
        self.config = sim or SimConfig()
        self.robot_config = robot or RobotConfig()
        self.lidar_config = lidar or LidarConfig()
        self.detector_config = detector or DetectorConfig()
        self.tracker_config = tracker or TrackerConfig()
        self.crowd = Crowd(crowd or SocialForceConfig())
        low, high = self.robot_config.velocity_bounds
        self._low, self._high = low, high
        c = self.robot_config
        self._acc = np.array([c.acc_lin, c.acc_lin, c.acc_ang])
        self._exact_distance = self.config.obstacle_distance == "exact"
        self._lateral = self.robot_config.kinematics == "holonomic"
        cfg = self.config  # crowd updates per step, physics substeps per update, their dt
        rounds, sub = (cfg.substeps, 1) if cfg.crowd_every_substep else (1, cfg.substeps)
        self._rounds = rounds, sub, cfg.physics_dt * sub

    @classmethod
    def from_scenario(
        cls,
        scenario: Any,
        sim: SimConfig | None = None,
        robot: RobotConfig | None = None,
        crowd: SocialForceConfig | None = None,
    ) -> Simulation:
        """A simulation with the sensors and tracker a scenario names."""
        where = scenario.source
        sensors = scenario.sensors
        return cls(
            sim,
            robot,
            LidarConfig.from_spec(sensors.lidar, "sensors.lidar", where),
            DetectorConfig.from_spec(sensors.detector, "sensors.detector", where),
            TrackerConfig.from_spec(sensors.tracker, "sensors.tracker", where),
            crowd,
        )

    # ------------------------------------------------------------------ reset
    def reset(self, layout: EpisodeLayout, rng: np.random.Generator) -> None:
        """Build a fresh world for ``layout``; all randomness of the episode comes from ``rng``."""
        self.layout, self.rng = layout, rng
        self.walls = np.ascontiguousarray(np.asarray(layout.walls, dtype=np.float64).reshape(-1, 4))
        self.t, self.steps = 0.0, 0
        self.crowd.reset(layout.people, layout.formations, self.walls, rng, layout.doors)
        n_robots = len(layout.robots)
        robots = [(self.robot_config, r.start) for r in layout.robots]
        self.world = World(
            self.walls,
            robots,
            self.crowd.position.copy(),
            self.crowd.radius,
            self.config.physics_dt,
            self.config.substeps,
        )
        self.n_robots, self.n_people = n_robots, self.crowd.position.shape[0]
        # bodies as circles: people first, then robots (their footprints)
        self.circles = np.zeros((self.n_people + n_robots, 3))
        self.circles[: self.n_people, 2] = self.crowd.radius
        self.circles[self.n_people :, 2] = self.robot_config.radius
        self._people_circle = np.arange(self.n_people, dtype=np.int64)
        self.command = np.zeros((n_robots, 3))  # last body-frame command, limited
        self.velocity = np.zeros((n_robots, 3))  # measured body-frame velocity
        self.obstacle_dist = np.zeros(n_robots)
        self._world_cmd = np.zeros((n_robots, 3))
        self._before = np.zeros((n_robots, 3))  # poses before the physics of a step
        self._robot_radius = np.full(n_robots, self.robot_config.radius)
        self.robots = [self._robot_state(r.goal) for r in layout.robots]
        self._init_group_buffers()
        self._reserve_records()
        self._planning_time = None
        self.circles[: self.n_people, :2] = self.world.people_xy
        self.circles[self.n_people :, :2] = self.world.robot_pose[:, :2]
        self._sense_and_record()

    def _init_group_buffers(self) -> None:
        """The true groups (membership is fixed for the episode) and scratch space for the
        groups each robot sees."""
        p, crowd = self.n_people, self.crowd
        self._form_counts = np.zeros(crowd.formation_centers.shape[0], dtype=np.int64)
        self._gt_groups = self._collect_groups(np.arange(p, dtype=np.int64), MIN_GROUP)
        self._group_scratch = np.zeros((5, self.tracker_config.max_tracks), dtype=np.int64)

    def _reserve_records(self) -> None:
        """Size the records for the layout's time limit (they grow beyond it if need be), so
        that they are not copied as they grow: people rows for everyone (the tracked ones
        are fewer; untouched memory costs nothing)."""
        n = int(self.layout.time_limit / self.config.control_dt) + 2
        p, (gids, _, members) = self.n_people, self._gt_groups
        for state in self.robots:
            state.record.reserve(n, n * p, n * gids.shape[0], n * members.shape[0])
            state.gt_record.reserve(n, n * p, n * gids.shape[0], n * members.shape[0])

    def _robot_state(self, goal: Sequence[float]) -> RobotState:
        lidar = Lidar(self.lidar_config)
        return RobotState(
            lidar,
            PeopleDetector(self.detector_config),
            KalmanTracker(self.tracker_config),
            EpisodeRecord(),
            EpisodeRecord(),
            np.asarray(goal, dtype=np.float64),
            lidar.arrays[-1],  # the scan buffer, rewritten every step
        )

    # ------------------------------------------------------------------ step
    def step(self, commands: ArrayLike, planning_time: ArrayLike | None = None) -> None:
        """Advance one control step.

        ``commands``: (R, 3) body-frame (vx [m/s], vy [m/s], omega [rad/s]) per robot (vy
        is ignored by a differential drive); clipped to the limits. ``planning_time``: (R,)
        computation time [s] of each command, stored with the sample it was decided at.
        """
        cmd = np.asarray(commands, dtype=np.float64)
        if cmd.shape != self.command.shape:
            cmd = cmd.reshape(self.n_robots, 3)
        self._planning_time = planning_time
        dt, world, before = self.config.control_dt, self.world, self._before
        _before_physics(cmd, self.command, self._low, self._high, self._acc, dt, self._lateral,
                        world.robot_pose, before, world.collisions, world.touching,
                        world.touched, world.new_collisions, self._rounds[2],
                        self._world_cmd)  # fmt: skip
        self._advance_physics()
        _after_physics(before, world.robot_pose, world.people_xy, dt, self.velocity, self.circles)
        self.steps += 1
        self.t = self.steps * dt
        self._sense_and_record()

    def _advance_physics(self) -> None:
        """The crowd's velocities and the physics substeps (the first world commands are
        set by :func:`_before_physics`)."""
        world, crowd, cmd = self.world, self.crowd, self._world_cmd
        rounds, sub, dt = self._rounds
        for k in range(rounds):
            if k:
                body_to_world(self.command, world.robot_pose, dt, cmd)
            v = crowd.desired_velocity(self.t + k * dt, dt, world.robot_pose, cmd,
                                       self._robot_radius, self.walls, self.rng)  # fmt: skip
            world.step(cmd, v, sub)
            crowd.sync(world.people_xy, world.people_velocity)

    # ------------------------------------------------------------------ sensing
    def _sense_and_record(self) -> None:
        for r, state in enumerate(self.robots):
            detected = self._sense(r, state)
            self._track(state, detected)
            self._record(r, state)

    def _sense(self, r: int, state: RobotState) -> int:
        """Lidar scan, obstacle distance and people detection of robot ``r`` (one compiled
        call); returns the number of detections."""
        state.lidar.draw(self.rng)
        state.detector.draw(self.rng, self.n_people)
        world = self.world
        return sense(world.robot_pose, r, self.walls, self.circles, self.n_people + r,
                     self._exact_distance, self.obstacle_dist, *state.lidar.arrays,
                     world.people_xy, self.crowd.yaw, self._people_circle,
                     *state.detector.arrays)  # fmt: skip

    def _track(self, state: RobotState, detected: int) -> None:
        """Fuse the robot's detections of this step into its tracker."""
        dt = self.config.control_dt if state.record.counts[SAMPLES] else 0.0
        xy, yaw, std = state.detector.arrays[-3:]
        state.tracker.fuse(dt, xy, yaw, std, detected)

    def _record(self, r: int, state: RobotState) -> None:
        """Append this step's sample to both records of robot ``r`` (one compiled call)."""
        pt = self._planning_time
        if pt is None:
            pt = math.nan
        elif not isinstance(pt, float):
            pt = np.ravel(pt)
            pt = float(pt[r] if pt.size > 1 else pt[0])
        rec, gt, world, crowd = state.record, state.gt_record, self.world, self.crowd
        detected_person = state.detector.arrays[5]  # true index of each detection
        while True:
            code = record_sample(
                self.t, world.robot_pose, self.velocity, r, state.goal, self.obstacle_dist, pt,
                *state.tracker.arrays, detected_person, state.track_person, crowd.formation_of,
                self._form_counts, self._group_scratch, world.people_xy, crowd.yaw,
                world.people_velocity, *self._gt_groups, rec.tables, rec.counts, gt.tables,
                gt.counts,
            )  # fmt: skip
            if code == OK:
                return
            if code == GROW_TRACK_PERSON:
                grown = np.full(2 * state.tracker.next_id + 1, -1, dtype=np.int64)
                grown[: state.track_person.shape[0]] = state.track_person
                state.track_person = grown
            elif code == GROW_TRACKED:
                cap = self.tracker_config.max_tracks
                rec.reserve(1, cap, cap, cap)
            else:
                gt.reserve(1, self.n_people, self.n_people, self.n_people)

    def _collect_groups(self, people: NDArray[np.int64], min_members: int):
        """F-formations with at least ``min_members`` of ``people`` (the true person of each
        row, -1 unknown): group ids (formation indices), sizes, member rows."""
        k = people.shape[0]
        gids, sizes, members = (np.empty(k, dtype=np.int64) for _ in range(3))
        g, m = seen_groups(people, self.crowd.formation_of, min_members, self._form_counts,
                           gids, sizes, members)  # fmt: skip
        return gids[:g], sizes[:g], members[:m]

    def new_goal(self, robot: int, goal: Sequence[float]) -> None:
        """Give robot ``robot`` the goal (x, y, yaw) [m, m, rad] of a new task that starts
        where it stands: its records keep only their last sample, as the new task's first
        (with the new goal), so that the task's metrics and reward start there."""
        state = self.robots[robot]
        state.goal[:] = np.asarray(goal, dtype=np.float64)
        for record in (state.record, state.gt_record):
            record.keep_last()
            record.tables[0][0, GOAL_FIELDS] = state.goal

    # ------------------------------------------------------------------ queries
    def goal_distance(self, robot: int = 0) -> float:
        """Distance from a robot to its goal position [m]."""
        pose, goal = self.world.robot_pose[robot], self.robots[robot].goal
        return math.hypot(goal[0] - pose[0], goal[1] - pose[1])

    @property
    def collisions(self) -> NDArray[np.bool_]:
        """(R, 3) contacts of each robot during the last step: wall, person, robot."""
        return self.world.collisions

    def new_collision(self, robot: int = 0) -> tuple[int, Collision | None]:
        """How many collisions (contacts that began) robot ``robot`` had in the last step,
        and the one with the largest closing speed (``None`` when none began): see
        :mod:`srpb_gym.sim.contact`."""
        world = self.world
        count = int(world.new_collisions[robot])
        return count, Collision.from_row(world.collision[robot]) if count else None


@njit(cache=True, error_model="numpy")
def _before_physics(target, command, low, high, acc, dt, lateral, pose, before, collisions,
                    touching, touched, new_collisions, round_dt, world_cmd):  # fmt: skip
    """The limited commands (:func:`~srpb_gym.sim.robot.limit_commands`, into ``command``),
    the poses before the physics, no contacts yet (:meth:`World.clear_contacts
    <srpb_gym.sim.world.World.clear_contacts>`), and the world-frame commands of the first
    physics round of ``round_dt`` (:func:`~srpb_gym.sim.robot.body_to_world`)."""
    limit_commands(target, command, low, high, acc, dt, lateral, command)
    for r in range(pose.shape[0]):
        before[r, 0], before[r, 1], before[r, 2] = pose[r, 0], pose[r, 1], pose[r, 2]
    clear_contacts(collisions, touching, touched, new_collisions)
    body_to_world(command, pose, round_dt, world_cmd)


@njit(cache=True, error_model="numpy")
def _after_physics(before, pose, people_xy, dt, velocity, circles):
    """The robots' measured velocity (:func:`~srpb_gym.sim.robot.measure_velocity`) and the
    body circles at their new positions (people first, then robots)."""
    measure_velocity(before, pose, dt, velocity)
    p = people_xy.shape[0]
    for i in range(p):
        circles[i, 0], circles[i, 1] = people_xy[i, 0], people_xy[i, 1]
    for r in range(pose.shape[0]):
        circles[p + r, 0], circles[p + r, 1] = pose[r, 0], pose[r, 1]
