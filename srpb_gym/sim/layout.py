"""A concrete episode: what a scenario's sampler draws and the simulation builds.

A scenario file describes ranges (start regions, crowd recipes); the sampler turns it into
one :class:`EpisodeLayout` with the generator it is given, and the simulation builds its
world from that layout alone. SI units, global frame, angles in rad.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class RobotLayout:
    """One robot's start pose and goal pose (x [m], y [m], yaw [rad])."""

    start: tuple[float, float, float]
    goal: tuple[float, float, float]


@dataclass(frozen=True)
class PersonLayout:
    """One walking person.

    ``route``: waypoints (x, y) walked in order from ``position``; with ``loop`` the route
    repeats (back to its first waypoint), otherwise the person stops at the last one.
    ``robot_reaction``: scale of the social-force repulsion from robots (0 ignores robots
    like a scripted actor, 1 the nominal reaction). ``group``: walking-group index or -1.
    """

    position: tuple[float, float]
    yaw: float
    route: tuple[tuple[float, float], ...]
    loop: bool = False
    preferred_speed: float = 1.2  # m/s
    radius: float = 0.25  # m, body circle
    relaxation_time: float = 0.5  # s
    robot_reaction: float = 1.0
    group: int = -1
    start_delay: float = 0.0  # s, stands still until then


@dataclass(frozen=True)
class FormationLayout:
    """A standing F-formation: members on a circle around the O-space centre, facing it.

    ``members`` are the members' positions (x, y); ``jitter`` the standard deviation of
    their small natural motion around them [m] (yaw jitter is ``jitter`` rad).
    """

    center: tuple[float, float]
    members: tuple[tuple[float, float], ...]
    radius: float = 0.25  # m, body circle of each member
    jitter: float = 0.02


@dataclass(frozen=True)
class EpisodeLayout:
    """Everything the simulation needs to build one episode."""

    walls: NDArray[np.float64]  # (S, 4) segments x0, y0, x1, y1 [m]
    robots: tuple[RobotLayout, ...]
    people: tuple[PersonLayout, ...] = ()
    formations: tuple[FormationLayout, ...] = ()
    time_limit: float = 60.0  # s
    goal_tolerance: float = 0.2  # m
    bounds: tuple[float, float, float, float] = (0.0, 0.0, 10.0, 10.0)  # xmin, ymin, xmax, ymax
    metadata: dict = field(default_factory=dict)
    #: (D, 6) doors that walkers take turns at: centre x, y [m], unit normal x, y, half
    #: width and half depth [m] (see :attr:`srpb_gym.scenarios.routes.RouteGraph.doors`)
    doors: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 6)))
