"""Social-force crowd: walking people follow routes, standing F-formations hold their places.

A control step is ``v = crowd.desired_velocity(t, dt, robots_xy, robots_vel, robots_radius)``
(velocities for the next ``dt`` seconds), the physics, then ``crowd.sync(positions,
velocities)``; each is one compiled kernel call on preallocated arrays. People are ordered
walkers first (layout order), then formation members formation by formation. A person is
:data:`WAITING` (before its start delay), :data:`WALKING`, :data:`STOPPED` (end of its route)
or :data:`STANDING` (F-formation member). Walkers follow the social force model; the others
hold an anchor with a critically damped spring (members: their place plus a small jitter).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import astuple, dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym import config as _config
from srpb_gym.sim import social_force as sf
from srpb_gym.sim.layout import FormationLayout, PersonLayout
from srpb_gym.sim.social_force import FORMATION, GROUP, STANDING, STOPPED, WAITING, WALKING

__all__ = ["PRESETS", "STANDING", "STOPPED", "WAITING", "WALKING", "Crowd", "SocialForceConfig"]


@dataclass(frozen=True)
class SocialForceConfig:
    """Parameters of the crowd model (SI units; accelerations in m/s^2).

    Walkers (Helbing & Molnar 1995, Helbing et al. 2000): relaxation to the preferred velocity
    towards the next waypoint within the relaxation time; repulsion ``A exp((r_ij - d_ij) /
    B)`` from people, weighted by the anisotropy ``lambda + (1 - lambda)(1 + cos phi) / 2``;
    walls and robots repel in the same form with their own A, B (robots scaled by the
    robot reaction, below); speed cap ``max_speed_factor`` x preferred speed. ``d_ij`` is
    the pair's smallest distance within ``anticipation_time`` at constant velocities
    (collision prediction, Zanlungo et al. 2011; 0: the circular specification). The
    ``evasion`` share of a braking repulsion is turned sideways (to the right when dead
    ahead; along a wall as the walker slides, else to its goal) so that head-on encounters
    resolve. A wall that the straight way to the next waypoint passes with the body clear of
    it pushes only sideways, without braking (a walker lined up with a door goes through
    it; the scenario's routes lead around walls through such openings). Walkers go around
    F-formations (Kendon 1990) as around a disc that covers the O-space and the members
    (``ospace_strength``).

    The part of a walker's desired velocity that people, walls and the group terms turn
    against its heading is dropped (in a dense crowd people stop; they do not walk
    backwards). Calibrated against pedestrian data (free walking speed, Weidmann's
    speed-density relation, group shapes, lanes, passing distance): ``docs/crowd.md`` and
    ``benchmarks/calibration.py``.

    Routes: a waypoint is reached within ``waypoint_tolerance``, or once past it within
    ``waypoint_pass_radius``. Where the leg after it clears the walls for the body, the
    walker goes on only when it can walk straight on from where it stands; a walker pushed
    off such a leg, to where a wall is in the way to its waypoint, heads back towards the
    leg's start until the way is clear again.

    Walking groups (Moussaid et al. 2010): gaze ``-beta1 alpha v`` (alpha: head rotation that
    keeps the group's centre of mass within ``group_view_angle``), attraction ``beta2`` to it
    beyond ``(N - 1) / 2`` m, repulsion ``beta3`` between members closer than their radii plus
    ``group_repulsion_margin``.

    Standing people hold an anchor (spring ``hold_stiffness``, ``hold_damping``); members'
    targets wander as an Ornstein-Uhlenbeck process (``jitter_time``). Members hold their
    place when a robot comes close unless ``formation_robot_reaction`` > 0.

    Robots (people see them coming): besides the social force above, a walker anticipates
    a collision with a robot through the time-to-collision power law of Karamouzas, Skinner
    and Guy 2014 (Phys. Rev. Lett. 113, 238701): the energy ``k tau^-2 exp(-tau / tau0)``,
    ``tau`` the time until the bodies (radii plus ``robot_ttc_margin``) touch if the
    walker walks as it means to (its preferred speed towards its waypoint; a standing
    person at rest) and the robot keeps its velocity, gives the force ``-grad`` of it
    (``robot_ttc_strength`` k, ``robot_ttc_horizon`` tau0, capped at ``robot_ttc_max``),
    which brakes and steers sideways long before contact and grows without bound as contact
    nears; its braking part is turned sideways by ``evasion`` like the social force's. A
    walker therefore slows, steps aside or waits for a robot that drives at it, parks on
    its line or stands by a door. Measured in the packaged scenarios: a robot parked where
    it starts is touched in none of 100 episodes in each (``benchmarks/people.py``);
    without this term 13 of 30 corridor episodes ended with a person walking into it.
    The robot's terms may make a walker back away (the people, walls and group terms
    never do), but only while the gap between its body and a robot's is below
    ``robot_backing_gap``; farther off, the part of its target velocity against its heading
    is dropped and the walker stops for the robot. The default (inf) lets a robot push a
    walker back from any distance: a robot that keeps a walker's distance while driving
    at it can herd the walker back along its route (in ``corridor``, along the wall for
    metres). Each walker's distance moved against its heading is kept
    (:attr:`Crowd.pushed_back`; ``info["people_pushed_back"]`` at an episode's end). With
    a finite gap, people who react to the robot also never walk into one: the part of a
    person's velocity that would close on a robot's body within the step by more than the
    gap leaves (less 2 cm and what the robot's own motion closes) is cut, and where a wall
    turns it back towards the robot the person slows down instead. Pressed between another
    person and a robot, a walker no longer bounces into the robot; a robot that drives
    into a person still reaches it.

    Doors (the layout's ``doors``: openings narrower than one body can share, found from
    the walls): walkers take turns. A walker whose next waypoint, or the one after, lies
    across a door within ``door_approach`` of it goes on while the door is free or taken
    by bodies going its way; while someone is in it going the other way or standing (a
    robot in the door included), or someone nearer the door comes at it from the other
    side, the walker steps to a spot beside the opening on its own side
    (``door_wait_distance`` from the wall and from the opening's edge), slows to a stop
    there and goes once the way is clear. People waiting do not hold the door.

    Robot reaction: the repulsion from robots is scaled, for each person, by its own
    reaction times ``robot_reaction``. A walker's own reaction is its per-person
    ``robot_reaction`` drawn from the scenario (also while it waits or stands at its route's
    end); an F-formation member's is ``formation_robot_reaction``. ``robot_reaction``
    (default 1) multiplies them all; 0 makes robots invisible to every person (the
    "invisible robot" of CrowdNav): people neither evade nor make room for a robot, though
    they still collide with it physically. Values above 1 make everyone more wary.
    """

    person_strength: float = 2.1  # A, Helbing & Molnar 1995 (V0 = 2.1 m^2/s^2)
    person_range: float = 0.3  # B [m], Helbing & Molnar 1995 (sigma = 0.3 m)
    anisotropy: float = 0.35  # lambda, weight of interactions behind the person
    anticipation_time: float = 1.0  # [s] horizon of the collision prediction (calibrated)
    evasion: float = 0.5  # share of a braking repulsion turned sideways
    interaction_range: float = 5.0  # [m] centre distance beyond which people ignore others
    wall_strength: float = 5.0  # A_w
    wall_range: float = 0.2  # B_w [m], Helbing & Molnar 1995 (R = 0.2 m)
    robot_strength: float = 3.0  # A_r: people keep more room from robots than from people
    robot_range: float = 0.5  # B_r [m]
    ospace_strength: float = 2.1  # repulsion of a walker from an F-formation's disc
    max_speed_factor: float = 1.3  # Helbing et al. 2000: v_max = 1.3 v0
    group_gaze: float = 4.0  # beta1 [1/(s rad)], Moussaid et al. 2010
    group_attraction: float = 3.0  # beta2, Moussaid et al. 2010
    group_repulsion: float = 1.0  # beta3, Moussaid et al. 2010
    group_view_angle: float = math.pi / 2  # [rad] half-angle of the vision field (90 deg)
    group_repulsion_margin: float = 0.2  # [m] added to the radii for the member repulsion
    waypoint_tolerance: float = 0.3  # [m] next waypoint when closer than this
    waypoint_pass_radius: float = 1.5  # [m] ... or past the waypoint and closer than this
    hold_stiffness: float = 25.0  # [1/s^2] spring to the anchor of a standing person
    hold_damping: float = 10.0  # [1/s] (2 sqrt(stiffness): critically damped)
    standing_max_speed: float = 0.6  # [m/s] speed cap of formation members
    jitter_time: float = 2.0  # [s] time constant of the formation members' jitter
    formation_robot_reaction: float = 0.0  # robot reaction of formation members
    robot_reaction: float = 1.0  # multiplies every person's robot reaction (0: robots unseen)
    yaw_time_constant: float = 0.3  # [s] walkers' heading follows their motion
    yaw_min_speed: float = 0.1  # [m/s] below this a walker keeps its heading
    robot_ttc_strength: float = 1.5  # k [m^2/s^2], Karamouzas et al. 2014 (0: no term)
    robot_ttc_horizon: float = 3.0  # tau0 [s], Karamouzas et al. 2014
    robot_ttc_max: float = 10.0  # [m/s^2] cap of the time-to-collision repulsion
    robot_ttc_margin: float = 0.1  # [m] added to the bodies' radii: the gap people keep
    door_approach: float = 2.0  # [m] walkers take turns at doors this close (0: never)
    door_wait_distance: float = 0.5  # [m] from the door's wall and opening to the wait spot
    robot_backing_gap: float = math.inf  # [m] walkers back away from closer robots only

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or math.isnan(value) or (
                    math.isinf(value) and f.name not in _UNBOUNDED):  # fmt: skip
                raise ValueError(f"{f.name} must be a finite number, got {value!r}")
            if f.name in _POSITIVE and value <= 0.0:
                raise ValueError(f"{f.name} must be > 0, got {value!r}")
            if value < 0.0:
                raise ValueError(f"{f.name} must be >= 0, got {value!r}")
        for name, low, high in _BOUNDS:
            if not low <= getattr(self, name) <= high:
                raise ValueError(f"{name} must be in [{low}, {high}], got {getattr(self, name)!r}")

    @classmethod
    def from_spec(
        cls, spec: str | Mapping[str, Any] | SocialForceConfig | None, path: str = "",
        file: str | None = None,
    ) -> SocialForceConfig:  # fmt: skip
        """A config from a preset name, a mapping (``preset: NAME`` as base) or ``None``."""
        return _config.from_spec(cls, spec, PRESETS, path, file)


_POSITIVE = frozenset({
    "person_range", "wall_range", "robot_range", "interaction_range", "max_speed_factor",
    "robot_ttc_horizon", "robot_ttc_max", "door_wait_distance",
    "group_view_angle", "waypoint_tolerance", "hold_stiffness", "standing_max_speed",
    "jitter_time", "yaw_time_constant"})  # fmt: skip
_UNBOUNDED = frozenset({"robot_backing_gap"})  # may be inf
_BOUNDS = (("anisotropy", 0.0, 1.0), ("max_speed_factor", 1.0, math.inf),
           ("group_view_angle", 0.0, math.pi))  # fmt: skip
PRESETS: dict[str, SocialForceConfig] = {"default": SocialForceConfig()}


def _readonly(a: NDArray[Any]) -> NDArray[Any]:
    return np.lib.stride_tricks.as_strided(a, writeable=False)  # a read-only view


class Crowd:
    """The people of one episode: their state arrays and the two per-step kernels.

    Read-only views, updated in place until the next :meth:`reset`: ``position`` (P, 2) [m],
    ``velocity`` (P, 2) [m/s], ``yaw`` (P,) [rad], ``radius`` (P,) [m], ``state`` (P,) int64,
    ``waiting`` (P,) int64 (1 while a walker waits for a door, else 0), ``pushed_back``
    (P,) [m] (how far each walker has moved against the way it walks since :meth:`reset`
    while a robot made it back away; people, walls and groups never make it back away),
    ``walking_group`` (P,) int64 (0..G-1 in order of first appearance; -1 alone, also for a
    group id used once), ``formation_of`` (P,) int64 (or -1), ``formation_centers`` (F, 2)
    [m]; ``formation_members``: list of F int64 arrays of person indices.
    """

    def __init__(self, config: SocialForceConfig | None = None) -> None:
        self.config = config if config is not None else PRESETS["default"]
        self._prm = np.array(astuple(self.config), dtype=np.float64)
        self.reset((), (), np.zeros((0, 4)))

    def reset(
        self, people: Sequence[PersonLayout], formations: Sequence[FormationLayout],
        walls: NDArray[np.float64], rng: np.random.Generator | None = None,
        doors: NDArray[np.float64] | None = None,
    ) -> None:  # fmt: skip
        """Build the crowd of an episode, at rest: walkers at their layout yaw (waiting for
        their start delay), members at their places facing the O-space centre. ``walls``
        (S, 4) and ``rng`` are the defaults of :meth:`desired_velocity`; ``doors`` (D, 6)
        the doors walkers take turns at (see :attr:`EpisodeLayout.doors
        <srpb_gym.sim.layout.EpisodeLayout.doors>`; default none)."""
        self._walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        self._doors = np.ascontiguousarray(np.zeros((0, 6)) if doors is None else doors,
                                           dtype=np.float64).reshape(-1, 6)  # fmt: skip
        self._rng, self._dt = rng, 0.0
        m = sum(len(f.members) for f in formations)
        n = len(people) + m
        self._pos, self._vel, self._anchor, self._out = (np.zeros((n, 2)) for _ in range(4))
        self._yaw, self._radius = np.zeros(n), np.zeros(n)
        self._props, self._links = np.zeros((n, 6)), np.full((n, 5), -1, dtype=np.int64)
        self._cursor, self._state = np.zeros(n, np.int64), np.full(n, WAITING, np.int64)
        self._waiting = np.zeros(n, np.int64)
        self._heading, self._back = np.zeros((n, 2)), np.zeros(n)
        self._jit, self._noise = np.zeros((m, 3)), np.zeros((m, 3))
        self._set_walkers(people)
        self._set_formations(formations, len(people))
        self._leg_from = self._pos.copy()
        self._bind()

    # the arrays derived from the state ones: kernel argument tuples and read-only views
    _DERIVED = ("_step_args", "_sync_args", "position", "velocity", "yaw", "radius", "state",
                "waiting", "pushed_back", "walking_group", "formation_of",
                "formation_centers")  # fmt: skip

    def _bind(self) -> None:
        """The kernels' argument tuples and the public read-only views of the state arrays
        (after :meth:`reset` and after a copy or unpickling)."""
        # the crowd's arrays as the kernels take them (after the time step, walls and robots)
        self._step_args = (self._pos, self._vel, self._yaw, self._radius, self._props,
                           self._links, self._cursor, self._state, self._route, self._anchor,
                           self._leg_from, self._jit, self._noise, self._fcenter,
                           self._fradius, self._gsum, self._doors, self._waiting,
                           self._heading, self._prm, self._out)  # fmt: skip
        self._sync_args = (self._pos, self._vel, self._yaw, self._state, self._links,
                           self._fcenter, self._jit, self._heading, self._back,
                           self._prm)  # fmt: skip
        self.position, self.velocity = _readonly(self._pos), _readonly(self._vel)
        self.yaw, self.radius = _readonly(self._yaw), _readonly(self._radius)
        self.state = _readonly(self._state)
        self.waiting = _readonly(self._waiting)
        self.pushed_back = _readonly(self._back)
        self.walking_group = _readonly(np.ascontiguousarray(self._links[:, GROUP]))
        self.formation_of = _readonly(np.ascontiguousarray(self._links[:, FORMATION]))
        self.formation_centers = _readonly(self._fcenter)

    def __getstate__(self) -> dict[str, Any]:
        # a copied view would no longer follow its array: the views are rebuilt
        return {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()

    def _set_walkers(self, people: Sequence[PersonLayout]) -> None:
        ids = [p.group for p in people]
        shared = [g for g in dict.fromkeys(ids) if g >= 0 and ids.count(g) > 1]
        compact = {g: k for k, g in enumerate(shared)}
        routes: list[tuple[float, float]] = []
        for i, p in enumerate(people):
            self._pos[i] = self._anchor[i] = p.position
            self._yaw[i], self._radius[i] = p.yaw, p.radius
            vmax = self.config.max_speed_factor * p.preferred_speed
            self._props[i] = (p.preferred_speed, p.relaxation_time, p.robot_reaction, vmax,
                              p.start_delay, 0.0)  # fmt: skip
            loop = p.loop and len(p.route) > 1
            self._links[i] = (compact.get(p.group, -1), -1, len(routes), len(p.route), loop)
            routes.extend(p.route)
        self._route = np.array(routes, dtype=np.float64).reshape(-1, 2)
        self._gsum = np.zeros((len(compact), 3))

    def _set_formations(self, formations: Sequence[FormationLayout], first: int) -> None:
        self._fcenter = np.array([f.center for f in formations], dtype=np.float64).reshape(-1, 2)
        self._fradius = np.zeros(len(formations))
        self.formation_members: list[NDArray[np.int64]] = []
        i = first
        for f, form in enumerate(formations):
            places = np.array(form.members, dtype=np.float64).reshape(-1, 2)
            if len(places):  # the O-space and the members' bodies
                self._fradius[f] = np.hypot(*(places - self._fcenter[f]).T).max() + form.radius
            self.formation_members.append(np.arange(i, i + len(places), dtype=np.int64))
            for x, y in places:
                self._pos[i] = self._anchor[i] = (x, y)
                self._yaw[i] = math.atan2(form.center[1] - y, form.center[0] - x)
                self._radius[i] = form.radius
                self._props[i] = (0, 1, 0, self.config.standing_max_speed, 0, form.jitter)
                self._links[i, FORMATION], self._state[i] = f, STANDING
                i += 1

    def desired_velocity(
        self, t: float, dt: float, robots_xy: NDArray[np.float64],
        robots_vel: NDArray[np.float64], robots_radius: NDArray[np.float64],
        walls: NDArray[np.float64] | None = None, rng: np.random.Generator | None = None,
    ) -> NDArray[np.float64]:  # fmt: skip
        """The (P, 2) velocities [m/s] to apply to the people for the next ``dt`` seconds.

        ``t``: time since :meth:`reset` [s] (start delays); robots: float64 (R, 2)
        positions and (R, 2) velocities (or wider tables whose first two columns are x and
        y, such as poses), (R,) radii (R may be 0). ``walls`` (S, 4) and
        ``rng`` (drives the formation jitter) default to those given to :meth:`reset`. The
        returned buffer is reused by the next call: copy it or use it at once.
        """
        if not dt > 0.0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        if self._noise.shape[0]:
            gen = rng if rng is not None else self._rng
            if gen is None:
                raise ValueError("formation members need an rng (here or in reset)")
            gen.standard_normal(out=self._noise)
        sf.step(float(t), float(dt), self._walls if walls is None else walls, robots_xy,
                robots_vel, robots_radius, *self._step_args)  # fmt: skip
        self._dt = dt
        return self._out

    def sync(self, positions: NDArray[np.float64], velocities: NDArray[np.float64]) -> None:
        """Take the people's (P, 2) positions [m] and velocities [m/s] after the physics
        (float64) and turn walkers towards their motion, members towards their centre."""
        sf.sync(positions, velocities, float(self._dt), *self._sync_args)
