"""Global path planning on an inflated grid of the static map (like ROS navfn on a costmap).

:class:`GlobalPlanner` rasterises the static walls once per episode into a grid of exact
wall distances (``resolution``, 5 cm by default) and turns it into a traversal cost: cells
closer than ``wall_keepout`` to a wall are impassable, cells closer than the robot's radius
plus bumper plus ``margin`` are lethal (very expensive), and beyond that the cost decays
exponentially to 1 (the inflation gradient that keeps paths clear of walls). A Dijkstra
sweep from the goal gives the static cost-to-go, which is the exact heuristic of the A*
searches that replan with tracked people as temporary obstacles. Paths are smoothed and
resampled every ``spacing`` metres.

Every grid operation is one compiled kernel; nothing loops over cells in Python.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.base import PERSON_RADIUS
from srpb_gym.planners.config import PlannerConfig
from srpb_gym.planners.grid import (
    grid_search,
    people_layer,
    sample_grid,
    trace_path,
    wall_distance,
)

#: Walls farther than this from a cell [m] are not measured (its distance reads this).
WALL_REACH = 5.0
#: The robot's place on the path is searched this far ahead of the last one [m].
NEAREST_WINDOW = 2.0
#: Tracks slower than this [m/s] for ``settle_time`` are standing people.
STANDING_SPEED = 0.3


def _lookup(keys: NDArray, values: NDArray, query: NDArray, default: float) -> NDArray:
    """``values`` of ``keys`` (unique) equal to each ``query`` entry, else ``default``."""
    out = np.full(query.shape[0], default, dtype=np.float64)
    if keys.shape[0] == 0 or query.shape[0] == 0:
        return out
    order = np.argsort(keys)
    pos = np.minimum(np.searchsorted(keys[order], query), keys.shape[0] - 1)
    found = keys[order][pos] == query
    out[found] = values[order][pos[found]]
    return out


@dataclass(frozen=True)
class GlobalPlannerConfig(PlannerConfig):
    """Settings of the :class:`GlobalPlanner` (lengths in m, times in s, costs per metre of
    path; a cost of 1 is free space). The robot's radius and bumper come from its
    :class:`~srpb_gym.sim.robot.RobotConfig`, the assumed person radius from the owner."""

    resolution: float = 0.05  # m, grid cell size
    margin: float = 0.04  # m, beyond the robot's radius plus bumper: cells closer are lethal
    wall_keepout: float = 0.12  # m, cells closer than this to a wall are impassable
    lethal_cost: float = 200.0  # per m, a lethal cell (passable only as a last resort)
    inflation_weight: float = 4.0  # per m, extra cost at the lethal boundary, decaying ...
    inflation_scale: float = 0.25  # m, ... exponentially over this length (the gradient)
    person_margin: float = 0.05  # m, beyond the two radii: a person's core
    walking_cost: float = 15.0  # per m, the core of a walking person (standing: lethal_cost)
    person_weight: float = 3.0  # per m, soft cost at the edge of a person's core, ...
    person_scale: float = 0.3  # m, ... decaying exponentially over this length
    person_horizon: float = 2.0  # s, walking people block their way this far ahead
    oncoming_cos: float = 0.87  # walkers count within acos(this) of heading at the robot
    pass_bias: float = 0.4  # m, a walker's cost is shifted this far to the person's right
    memory: float = 5.0  # s, standing people stay obstacles this long after track loss
    settle_time: float = 1.0  # s, slower than STANDING_SPEED this long: standing
    people_range: float = 6.0  # m, only people this close to the robot are obstacles
    replan_period: float = 2.0  # s, replan at least this often
    max_deviation: float = 0.6  # m, replan when the robot is this far from the path
    block_check: float = 3.0  # m, replan when a person blocks the path this far ahead ...
    min_replan_interval: float = 0.5  # s, ... (and off the path) at most this often
    heuristic_weight: float = 1.001  # A* heuristic weight (> 1: faster, costlier paths)
    hysteresis: float = 0.15  # a new path must be this fraction cheaper ...
    hysteresis_length: float = 0.5  # m, ... and this much more to replace the current one
    spacing: float = 0.1  # m, distance between the returned path points

    def __post_init__(self) -> None:
        self._positive("resolution", "lethal_cost", "inflation_scale", "person_scale",
                       "replan_period", "max_deviation", "spacing")  # fmt: skip
        self._nonnegative("margin", "wall_keepout", "inflation_weight", "person_margin",
                          "walking_cost", "person_weight", "person_horizon", "memory",
                          "settle_time", "people_range", "block_check",
                          "min_replan_interval", "heuristic_weight", "hysteresis",
                          "hysteresis_length")  # fmt: skip
        self._within("oncoming_cos", -1.0, 1.0)
        self._number("pass_bias")


class GlobalPlanner:
    """Grid planner of the static map with people as temporary obstacles.

    The grid (cells of ``resolution``) holds each cell's distance to the nearest wall; cells
    closer than ``wall_keepout`` are impassable, cells closer than the robot's radius plus
    bumper plus ``margin`` cost ``lethal_cost`` per metre, and beyond that the cost decays
    from 1 + ``inflation_weight`` to 1 over ``inflation_scale``. Tracked people within
    ``people_range`` are temporary obstacles: standing people (slower than 0.3 m/s for
    ``settle_time``, remembered ``memory`` seconds after their track is lost) and people
    walking straight at the robot (within acos(``oncoming_cos``) of the line to it), swept
    ``person_horizon`` ahead and shifted ``pass_bias`` to their right (the robot keeps
    right). A person's core (robot radius plus bumper plus ``person_radius`` plus
    ``person_margin``) costs ``lethal_cost`` (standing) or ``walking_cost`` (walking: the
    local planner handles them) per metre, with a soft edge of ``person_weight``
    decaying over ``person_scale``. The path is replanned every ``replan_period``, when the
    robot is more than ``max_deviation`` off it, and when a person blocks it within
    ``block_check`` ahead (at most every ``min_replan_interval``); a new path replaces the
    current one only when cheaper than its cost / (1 + ``hysteresis``) minus
    ``hysteresis_length``.

    Args:
        config: the settings (:class:`GlobalPlannerConfig`, a mapping of the fields to
            change, or ``None``: the defaults).
        person_radius: assumed body radius of a tracked person [m].
    """

    def __init__(
        self, config: GlobalPlannerConfig | Mapping[str, Any] | None = None,
        person_radius: float = PERSON_RADIUS,
    ) -> None:  # fmt: skip
        self.config = GlobalPlannerConfig.from_spec(config)
        self.person_radius = float(person_radius)
        self.res = self.config.resolution
        # extra cost layers: called as layer(knowledge, cost grid) before each search
        self.layers: list[Callable[[Knowledge, NDArray[np.float64]], None]] = []
        self.path, self.arc = np.zeros((0, 2)), np.zeros(0)

    # ------------------------------------------------------------------ episode setup
    def reset(self, knowledge: Knowledge) -> None:
        """Rasterise the static map, build the cost grid and the cost-to-go of the goal."""
        xmin, ymin, xmax, ymax = knowledge.bounds
        res = self.res
        self.x0, self.y0 = float(xmin), float(ymin)
        self.nx = max(math.ceil((xmax - xmin) / res), 2)
        self.ny = max(math.ceil((ymax - ymin) / res), 2)
        walls = np.ascontiguousarray(knowledge.walls, dtype=np.float64).reshape(-1, 4)
        self.dist = np.empty((self.ny, self.nx))
        wall_distance(walls, self.x0, self.y0, res, WALL_REACH, self.dist)
        cfg, robot = self.config, knowledge.robot
        self.robot_radius = robot.radius + robot.bumper
        lethal = self.robot_radius + cfg.margin
        d = self.dist
        cost = 1.0 + cfg.inflation_weight * np.exp(-(np.maximum(d, lethal) - lethal)
                                                   / cfg.inflation_scale)  # fmt: skip
        cost[d < lethal] = cfg.lethal_cost
        cost[d < cfg.wall_keepout] = np.inf
        self.goal = np.array(knowledge.goal[:2], dtype=np.float64)
        goal_cell = self.cell(*self.goal)
        cost.ravel()[goal_cell] = min(cost.ravel()[goal_cell], cfg.lethal_cost)  # reachable
        self.static_cost = cost
        n = self.nx * self.ny
        self._g, self._h = np.empty(n), np.zeros(n)
        self._parent, self._done = np.empty(n, np.int64), np.empty(n, np.bool_)
        self._hk, self._hv = np.empty(8 * n + 8), np.empty(8 * n + 8, np.int64)
        self._cells = np.empty(n, np.int64)
        grid_search(cost.ravel(), self.nx, res, goal_cell, -1, self._h, 1.0, self._g, self._parent,
                    self._done, self._hk, self._hv)  # fmt: skip
        self._h = np.where(np.isfinite(self._g), self._g, 0.0)
        self._goal_cell = goal_cell
        self.path, self.arc = np.zeros((0, 2)), np.zeros(0)
        self.index = 0
        self.last_plan = -math.inf
        self._mem = np.zeros((0, 4))  # standing people: id, x, y, time last seen
        self._slow_ids, self._slow_t = np.zeros(0, np.int64), np.zeros(0)
        self._still = np.zeros(0, dtype=np.bool_)

    def cell(self, x: float, y: float) -> int:
        """Flat index of the cell that holds (x, y) (clamped to the grid)."""
        i = min(max(int((x - self.x0) / self.res), 0), self.nx - 1)
        j = min(max(int((y - self.y0) / self.res), 0), self.ny - 1)
        return j * self.nx + i

    def clearance(self, xs: NDArray[np.float64], ys: NDArray[np.float64]) -> NDArray:
        """Distance [m] from each point to the nearest static wall (0 off the map)."""
        xs, ys = np.ascontiguousarray(xs, np.float64), np.ascontiguousarray(ys, np.float64)
        out = np.empty(xs.shape[0])
        sample_grid(self.dist, self.x0, self.y0, self.res, xs, ys, 0.0, out)
        return out

    # ------------------------------------------------------------------ planning
    def update(self, knowledge: Knowledge) -> bool:
        """Replan when needed (no path, periodically, off the path, blocked by people).
        Returns whether it searched."""
        x, y = float(knowledge.pose[0]), float(knowledge.pose[1])
        t, cfg = knowledge.t, self.config
        self._remember(knowledge)
        if self.path.shape[0] == 0:
            self.plan(knowledge, keep=False)
            return True
        self.index = self.nearest(x, y)
        off = math.hypot(self.path[self.index, 0] - x, self.path[self.index, 1] - y)
        if off > cfg.max_deviation and t - self.last_plan >= cfg.min_replan_interval:
            self.plan(knowledge, keep=True)  # the old path (joined from here) may still win
            return True
        due = t - self.last_plan >= cfg.replan_period
        if not due and t - self.last_plan >= cfg.min_replan_interval:
            due = self._blocked(knowledge)
        if due:
            self.plan(knowledge, keep=True)
        return due

    def plan(self, knowledge: Knowledge, keep: bool = False) -> NDArray[np.float64]:
        """Search a path from the robot to the goal now; returns it (N, 2). With ``keep``
        the rest of the current path stays unless the new one is cheaper by more than the
        ``hysteresis`` (so the path does not flip between sides of moving people)."""
        x, y = float(knowledge.pose[0]), float(knowledge.pose[1])
        cfg = self.config
        cost = self.static_cost.copy()
        ax, ay, bx, by, core_cost = self._obstacle_segments(knowledge)
        if ax.shape[0]:
            core = self.robot_radius + self.person_radius + cfg.person_margin
            people_layer(cost, self.x0, self.y0, self.res, ax, ay, bx, by, core, core_cost,
                         cfg.person_weight, cfg.person_scale, 4.0 * cfg.person_scale)  # fmt: skip
        for layer in self.layers:
            layer(knowledge, cost)
        start = self.cell(x, y)
        flat = cost.ravel()
        flat[start] = min(flat[start], cfg.lethal_cost)  # leave a lethal start cell
        found = grid_search(flat, self.nx, self.res, start, self._goal_cell, self._h,
                            cfg.heuristic_weight, self._g, self._parent, self._done, self._hk,
                            self._hv)  # fmt: skip
        n = trace_path(self._parent, self._goal_cell, self._cells) if found else 0
        if n == 0:  # unreachable: head straight for the goal
            pts = np.array([[x, y], self.goal])
        else:
            cells = self._cells[:n]
            pts = np.column_stack([self.x0 + (cells % self.nx + 0.5) * self.res,
                                   self.y0 + (cells // self.nx + 0.5) * self.res])  # fmt: skip
            pts[0], pts[-1] = (x, y), self.goal
        path, arc = self._smooth(pts)
        self.last_plan = knowledge.t
        if keep and self.path.shape[0]:
            old = np.vstack([[x, y], self.path[self.index :]])
            old_cost, new_cost = self._path_cost(cost, old), self._path_cost(cost, path)
            if old_cost <= new_cost * (1.0 + cfg.hysteresis) + cfg.hysteresis_length:
                return self.path
        self.path, self.arc = path, arc
        self.index = 0
        return self.path

    def _path_cost(self, cost: NDArray[np.float64], pts: NDArray[np.float64]) -> float:
        """Cost of the polyline ``pts`` on the grid ``cost``: each segment's length times
        the cost of the cell of its end point."""
        i = np.clip(((pts[1:, 0] - self.x0) / self.res).astype(np.int64), 0, self.nx - 1)
        j = np.clip(((pts[1:, 1] - self.y0) / self.res).astype(np.int64), 0, self.ny - 1)
        seg = np.hypot(*np.diff(pts, axis=0).T)
        return float(np.minimum(cost[j, i], 1e6) @ seg)

    def _remember(self, knowledge: Knowledge) -> None:
        """Track since when each track has been slow and keep the tracks slow for
        ``settle_time`` as standing people (rows id, x, y, last seen) for ``memory`` s."""
        tr, t = knowledge.tracks, knowledge.t
        slow = np.hypot(*tr.velocity.T) < STANDING_SPEED
        since = np.where(slow, _lookup(self._slow_ids, self._slow_t, tr.ids, t), t)
        self._slow_ids, self._slow_t = tr.ids[slow], since[slow]
        self._still = slow & (t - since >= self.config.settle_time)
        mem = self._mem[~np.isin(self._mem[:, 0], tr.ids[self._still])]
        new = np.column_stack([tr.ids[self._still], tr.xy[self._still],
                               np.full(int(self._still.sum()), t)])  # fmt: skip
        mem = np.vstack([mem, new])
        self._mem = mem[np.isin(mem[:, 0], tr.ids) | (t - mem[:, 3] <= self.config.memory)]

    def _obstacle_people(self, knowledge: Knowledge) -> tuple[NDArray, NDArray, NDArray]:
        """Tracked people that are obstacles of the global plan: within ``people_range``,
        standing, or walking straight at the robot. Returns their (K, 2) positions and
        velocities (zero when standing) and whether each is standing."""
        tr, cfg = knowledge.tracks, self.config
        rel = knowledge.pose[:2] - tr.xy
        dist, speed = np.hypot(*rel.T), np.hypot(*tr.velocity.T)
        standing = self._still if self._still.shape == speed.shape else speed < 0.0
        towards = (tr.velocity * rel).sum(axis=1) > cfg.oncoming_cos * speed * dist
        use = (dist < cfg.people_range) & (standing | (towards & (cfg.walking_cost > 0)))
        vel = np.where(standing[:, None], 0.0, tr.velocity)
        return tr.xy[use], vel[use], standing[use]

    def _obstacle_segments(self, knowledge: Knowledge):
        """People as segments from their current position (walkers: shifted by
        ``pass_bias`` to their right) to where they will be ``person_horizon`` s ahead,
        plus remembered standing people whose tracks were lost; and their core costs."""
        cfg = self.config
        xy, vel, standing = self._obstacle_people(knowledge)
        speed = np.maximum(np.hypot(vel[:, 0], vel[:, 1]), 1e-9)
        right = np.column_stack([vel[:, 1], -vel[:, 0]]) / speed[:, None]
        a = xy + np.where(standing[:, None], 0.0, cfg.pass_bias * right)
        b = a + vel * cfg.person_horizon
        core_cost = np.where(standing, cfg.lethal_cost, cfg.walking_cost)
        lost = self._mem[~np.isin(self._mem[:, 0], knowledge.tracks.ids), 1:3]
        if lost.shape[0]:
            a, b = np.vstack([a, lost]), np.vstack([b, lost])
            core_cost = np.concatenate([core_cost, np.full(lost.shape[0], cfg.lethal_cost)])
        return (
            np.ascontiguousarray(a[:, 0]),
            np.ascontiguousarray(a[:, 1]),
            np.ascontiguousarray(b[:, 0]),
            np.ascontiguousarray(b[:, 1]),
            core_cost,
        )

    def _blocked(self, knowledge: Knowledge) -> bool:
        """Whether an obstacle person (now or ``person_horizon`` ahead) is within the core
        radius of the path in the next ``block_check`` metres."""
        xy, vel, _ = self._obstacle_people(knowledge)
        if xy.shape[0] == 0:
            return False
        ahead = self.arc[self.index] + self.config.block_check
        seg = self.path[self.index : int(np.searchsorted(self.arc, ahead)) + 1]
        core = self.robot_radius + self.person_radius + self.config.person_margin
        people = np.vstack([xy, xy + vel * self.config.person_horizon])
        d = np.hypot(seg[:, None, 0] - people[None, :, 0], seg[:, None, 1] - people[None, :, 1])
        return bool((d < core).any())

    def _smooth(self, pts: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Moving-average smoothing that never moves a point closer to a wall than the
        lethal clearance, resampled every ``spacing`` metres; returns (path, arc length)."""
        if pts.shape[0] > 4:
            lethal = self.robot_radius + self.config.margin
            raw_clear = self.clearance(pts[:, 0], pts[:, 1])
            sm = pts.copy()
            k = 7
            kernel = np.ones(k) / k
            for _ in range(3):
                pad = np.pad(sm, ((k // 2, k // 2), (0, 0)), mode="edge")
                new = np.column_stack([np.convolve(pad[:, i], kernel, "valid") for i in (0, 1)])
                new[0], new[-1] = pts[0], pts[-1]
                clear = self.clearance(new[:, 0], new[:, 1])
                bad = (clear < lethal) & (clear < raw_clear)
                new[bad] = pts[bad]
                sm = new
            pts = sm
        seg = np.hypot(*np.diff(pts, axis=0).T)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        if arc[-1] < 1e-9:
            return pts[-1:].copy(), np.zeros(1)
        n = max(math.ceil(arc[-1] / self.config.spacing), 1) + 1
        s = np.linspace(0.0, arc[-1], n)
        path = np.column_stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])])
        return path, s

    def cost_to_go(self, x: float, y: float) -> float:
        """Static cost of the way from (x, y) to the goal (metres weighted by the cost)."""
        return float(self._h[self.cell(x, y)])

    # ------------------------------------------------------------------ path following
    def nearest(self, x: float, y: float) -> int:
        """Index of the path point nearest to (x, y) among those from the last index to
        :data:`NEAREST_WINDOW` metres ahead of it (the robot does not jump along the path)."""
        lo = self.index
        hi = int(np.searchsorted(self.arc, self.arc[lo] + NEAREST_WINDOW)) + 1
        seg = self.path[lo:hi]
        return lo + int(np.argmin(np.hypot(seg[:, 0] - x, seg[:, 1] - y)))

    def lookahead(self, distance: float) -> NDArray[np.float64]:
        """The path point ``distance`` metres ahead of the current index (the goal at most)."""
        s = self.arc[self.index] + distance
        return self.path[min(int(np.searchsorted(self.arc, s)), self.path.shape[0] - 1)]

    def local(self, length: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The path from the current index to ``length`` metres ahead and its arc length
        measured from the current index."""
        lo = self.index
        hi = int(np.searchsorted(self.arc, self.arc[lo] + length)) + 1
        return self.path[lo:hi], self.arc[lo:hi] - self.arc[lo]
