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
from numba import njit
from numpy.typing import NDArray

from srpb_gym import config as _config
from srpb_gym.angles import wrap_angle
from srpb_gym.sim.layout import FormationLayout, PersonLayout

WAITING, WALKING, STOPPED, STANDING = 0, 1, 2, 3  # values of Crowd.state
CUTOFF = 10.0  # repulsions are dropped beyond this many ranges B (factor exp(-10))
SLIDE_SPEED = 0.05  # [m/s] a walker slower than this along a wall picks a side afresh
# Columns of the per-person parameter table (float) and link table (int).
V0, TAU, REACTION, VMAX, DELAY, JITTER = range(6)
GROUP, FORMATION, RSTART, RLEN, LOOP = range(5)


@dataclass(frozen=True)
class SocialForceConfig:
    """Parameters of the crowd model (SI units; accelerations in m/s^2).

    Walkers (Helbing & Molnar 1995, Helbing et al. 2000): relaxation to the preferred velocity
    within the relaxation time; repulsion ``A exp((r_ij - d_ij) / B)`` from people, weighted
    by the anisotropy ``lambda + (1 - lambda)(1 + cos phi) / 2``; walls and robots repel in the
    same form with their own A, B (robots scaled by the person's robot reaction); speed cap
    ``max_speed_factor`` x preferred speed. ``d_ij`` is the pair's smallest distance within
    ``anticipation_time`` at constant velocities (collision prediction, Zanlungo et al. 2011;
    0: the circular specification). The ``evasion`` share of a braking repulsion is turned
    sideways (to the right when dead ahead; along a wall as the walker slides, else to its
    goal) so that head-on encounters resolve. Walkers go around F-formations (Kendon 1990)
    as around a disc that covers the O-space and the members (``ospace_strength``).

    Walking groups (Moussaid et al. 2010): gaze ``-beta1 alpha v`` (alpha: head rotation that
    keeps the group's centre of mass within ``group_view_angle``), attraction ``beta2`` to it
    beyond ``(N - 1) / 2`` m, repulsion ``beta3`` between members closer than their radii plus
    ``group_repulsion_margin``.

    Standing people hold an anchor (spring ``hold_stiffness``, ``hold_damping``); members'
    targets wander as an Ornstein-Uhlenbeck process (``jitter_time``). Members hold their
    place when a robot comes close unless ``formation_robot_reaction`` > 0.
    """

    person_strength: float = 2.1  # A, Helbing & Molnar 1995 (V0 = 2.1 m^2/s^2)
    person_range: float = 0.3  # B [m], Helbing & Molnar 1995 (sigma = 0.3 m)
    anisotropy: float = 0.35  # lambda, weight of interactions behind the person
    anticipation_time: float = 0.5  # [s] horizon of the collision prediction
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
    yaw_time_constant: float = 0.3  # [s] walkers' heading follows their motion
    yaw_min_speed: float = 0.1  # [m/s] below this a walker keeps its heading

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
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
    "group_view_angle", "waypoint_tolerance", "hold_stiffness", "standing_max_speed",
    "jitter_time", "yaw_time_constant"})  # fmt: skip
_BOUNDS = (("anisotropy", 0.0, 1.0), ("max_speed_factor", 1.0, math.inf),
           ("group_view_angle", 0.0, math.pi))  # fmt: skip
PRESETS: dict[str, SocialForceConfig] = {"default": SocialForceConfig()}
# Indices of the parameters in the vector handed to the kernels (the order of the fields).
(A_P, B_P, LAM, T_ANT, EVADE, RANGE, A_W, B_W, A_R, B_R, A_O, _VMAX, BETA1, BETA2, BETA3, VIEW,
 MARGIN, TOL, PASS, K_HOLD, C_HOLD, _VSTAND, T_JIT, F_REACT, T_YAW, V_YAW) = range(26)  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def _wall_offset(px: float, py: float, w: NDArray[np.float64], s: int,
                 reach: float) -> tuple[float, float, float]:  # fmt: skip
    """Distance from (px, py) to wall ``s`` of ``w`` and the unit normal pointing to the point;
    ``inf`` when the point is farther than ``reach`` from the wall's bounding box."""
    x0, y0, x1, y1 = w[s, 0], w[s, 1], w[s, 2], w[s, 3]
    if (px < min(x0, x1) - reach or px > max(x0, x1) + reach
            or py < min(y0, y1) - reach or py > max(y0, y1) + reach):  # fmt: skip
        return math.inf, 0.0, 0.0
    sx, sy = x1 - x0, y1 - y0
    l2 = sx * sx + sy * sy
    u = 0.0 if l2 == 0.0 else min(max(((px - x0) * sx + (py - y0) * sy) / l2, 0.0), 1.0)
    dx, dy = px - (x0 + u * sx), py - (y0 + u * sy)
    d = math.sqrt(dx * dx + dy * dy)
    if d > 1e-9:
        return d, dx / d, dy / d
    if l2 > 0.0:  # on the segment: its left normal
        s = math.sqrt(l2)
        return 0.0, -sy / s, sx / s
    return 0.0, 1.0, 0.0


@njit(cache=True, inline="always", error_model="numpy")
def _evade(fx: float, fy: float, sx: float, sy: float, ex: float, ey: float,
           evasion: float) -> tuple[float, float]:  # fmt: skip
    """Add to a repulsion (fx, fy) that brakes heading e the share ``evasion`` of its braking
    part along the unit direction (sx, sy)."""
    brake = -(fx * ex + fy * ey)
    if brake <= 0.0:
        return fx, fy
    return fx + evasion * brake * sx, fy + evasion * brake * sy


@njit(cache=True, inline="always", error_model="numpy")
def _social(dx: float, dy: float, dvx: float, dvy: float, rsum: float, A: float, B: float,
            T: float, ex: float, ey: float, lam: float, evasion: float,
            tie: float) -> tuple[float, float]:  # fmt: skip
    """Repulsion on a person at offset (dx, dy) and relative velocity (dvx, dvy) from an
    obstacle of combined radius ``rsum``; e is the person's heading; ``tie`` (+-1) picks the
    direction when both are at the same point."""
    px, py = dx, dy
    dv2 = dvx * dvx + dvy * dvy
    if T > 0.0 and dv2 > 1e-12:  # closest approach within the horizon
        tc = min(max(-(dx * dvx + dy * dvy) / dv2, 0.0), T)
        px, py = dx + dvx * tc, dy + dvy * tc
    dp = math.sqrt(px * px + py * py)
    if dp - rsum > CUTOFF * B:
        return 0.0, 0.0
    d = math.sqrt(dx * dx + dy * dy)
    if dp > 1e-9:
        nx, ny = px / dp, py / dp
    elif d > 1e-9:
        nx, ny = dx / d, dy / d
    else:
        nx, ny = tie, 0.0
    cos_phi = -(ex * dx + ey * dy) / d if d > 1e-9 else 1.0
    mag = A * math.exp((rsum - dp) / B) * (lam + (1.0 - lam) * 0.5 * (1.0 + cos_phi))
    side = 1.0 if nx * ey - ny * ex >= 0.0 else -1.0  # pass it on the side we are on
    return _evade(mag * nx, mag * ny, side * ey, -side * ex, ex, ey, evasion)


@njit(cache=True, inline="always", error_model="numpy")
def _advance_routes(t, pos, vel, props, links, cursor, state, route, anchor, leg_from, prm):
    """Start delayed walkers, move cursors past reached waypoints, stop finished walkers."""
    omega = math.sqrt(prm[K_HOLD])
    for i in range(pos.shape[0]):
        if state[i] == WAITING and t >= props[i, DELAY]:
            state[i] = WALKING if links[i, RLEN] > 0 else STOPPED
        if state[i] != WALKING:
            continue
        k = links[i, RSTART] + cursor[i]
        wx, wy = route[k, 0], route[k, 1]
        dx, dy = pos[i, 0] - wx, pos[i, 1] - wy
        d = math.hypot(dx, dy)
        past = dx * (wx - leg_from[i, 0]) + dy * (wy - leg_from[i, 1]) > 0.0
        if d >= prm[TOL] and not (past and d < prm[PASS]):
            continue
        leg_from[i, 0], leg_from[i, 1] = wx, wy
        cursor[i] += 1
        if cursor[i] < links[i, RLEN]:
            continue
        if links[i, LOOP]:
            cursor[i] = 0
        else:  # stop where a critically damped hold from this velocity comes to rest
            cursor[i], state[i] = links[i, RLEN] - 1, STOPPED
            for c in range(2):
                anchor[i, c] = pos[i, c] + vel[i, c] / omega


@njit(cache=True, inline="always", error_model="numpy")
def _robot_force(i, pos, vel, radius, ex, ey, evasion, rxy, rvel, rrad, prm):
    """Unscaled repulsion of person i from all robots."""
    fx = fy = 0.0
    for r in range(rxy.shape[0]):
        gx, gy = _social(
            pos[i, 0] - rxy[r, 0],
            pos[i, 1] - rxy[r, 1],
            vel[i, 0] - rvel[r, 0],
            vel[i, 1] - rvel[r, 1],
            radius[i] + rrad[r],
            prm[A_R],
            prm[B_R],
            prm[T_ANT],
            ex,
            ey,
            prm[LAM],
            evasion,
            1.0,
        )
        fx, fy = fx + gx, fy + gy
    return fx, fy


@njit(cache=True, inline="always", error_model="numpy")
def _people_force(i, ex, ey, pos, vel, radius, links, state, fcenter, fradius, prm):
    """Repulsion of walker i from the other people (plus the Moussaid group repulsion) and
    from the O-spaces of the formations."""
    fx = fy = 0.0
    g = links[i, GROUP]
    r2 = prm[RANGE] * prm[RANGE]
    for j in range(pos.shape[0]):
        dx, dy = pos[i, 0] - pos[j, 0], pos[i, 1] - pos[j, 1]
        if j == i or dx * dx + dy * dy > r2:
            continue
        tie = 1.0 if i > j else -1.0
        rsum = radius[i] + radius[j]
        gx, gy = _social(
            dx,
            dy,
            vel[i, 0] - vel[j, 0],
            vel[i, 1] - vel[j, 1],
            rsum,
            prm[A_P],
            prm[B_P],
            prm[T_ANT],
            ex,
            ey,
            prm[LAM],
            prm[EVADE],
            tie,
        )
        fx, fy = fx + gx, fy + gy
        d = math.sqrt(dx * dx + dy * dy)
        if g >= 0 and links[j, GROUP] == g and state[j] == WALKING and d < rsum + prm[MARGIN]:
            ux, uy = (dx / d, dy / d) if d > 1e-9 else (tie, 0.0)
            fx, fy = fx + prm[BETA3] * ux, fy + prm[BETA3] * uy
    for f in range(fcenter.shape[0]):
        dx, dy = pos[i, 0] - fcenter[f, 0], pos[i, 1] - fcenter[f, 1]
        gx, gy = _social(dx, dy, vel[i, 0], vel[i, 1], radius[i] + fradius[f], prm[A_O],
                         prm[B_P], prm[T_ANT], ex, ey, prm[LAM], prm[EVADE], 1.0)  # fmt: skip
        fx, fy = fx + gx, fy + gy
    return fx, fy


@njit(cache=True, inline="always", error_model="numpy")
def _wall_force(px, py, vx, vy, r, ex, ey, walls, prm):
    """Repulsion of a walker at (px, py) moving at (vx, vy) from all walls; a braking wall
    turns it along the wall the way it already slides, else towards its goal, else right."""
    fx = fy = 0.0
    reach = r + CUTOFF * prm[B_W]
    for s in range(walls.shape[0]):
        d, nx, ny = _wall_offset(px, py, walls, s, reach)
        if d == math.inf:
            continue
        mag = prm[A_W] * math.exp((r - d) / prm[B_W])
        along = -ny * vx + nx * vy  # tangent (-ny, nx): to the right when facing the wall
        if abs(along) < SLIDE_SPEED:
            along = -ny * ex + nx * ey
        side = 1.0 if along >= 0.0 else -1.0
        gx, gy = _evade(mag * nx, mag * ny, -side * ny, side * nx, ex, ey, prm[EVADE])
        fx, fy = fx + gx, fy + gy
    return fx, fy


@njit(cache=True, inline="always", error_model="numpy")
def _group_force(i, ex, ey, pos, vel, links, gsum, prm):
    """Moussaid et al. 2010 gaze and attraction terms of walking-group member i."""
    g = links[i, GROUP]
    if g < 0 or gsum[g, 2] < 2.0:
        return 0.0, 0.0
    cx, cy = gsum[g, 0] / gsum[g, 2] - pos[i, 0], gsum[g, 1] / gsum[g, 2] - pos[i, 1]
    dc = math.hypot(cx, cy)
    if dc < 1e-9:
        return 0.0, 0.0
    angle = math.acos(min(max((cx * ex + cy * ey) / dc, -1.0), 1.0))
    alpha = max(angle - prm[VIEW], 0.0)
    fx, fy = -prm[BETA1] * alpha * vel[i, 0], -prm[BETA1] * alpha * vel[i, 1]
    if dc > 0.5 * (gsum[g, 2] - 1.0):
        fx, fy = fx + prm[BETA2] * cx / dc, fy + prm[BETA2] * cy / dc
    return fx, fy


@njit(cache=True, inline="always", error_model="numpy")
def _walker_velocity(i, dt, pos, vel, yaw, radius, props, links, cursor, state, route, gsum,
                     fcenter, fradius, walls, rxy, rvel, rrad, prm):  # fmt: skip
    """Social-force velocity of walker i after dt (exact relaxation, forces held)."""
    k = links[i, RSTART] + cursor[i]
    wx, wy = route[k, 0] - pos[i, 0], route[k, 1] - pos[i, 1]
    dw = math.hypot(wx, wy)
    ex, ey = (wx / dw, wy / dw) if dw > 1e-9 else (math.cos(yaw[i]), math.sin(yaw[i]))
    fx, fy = _people_force(i, ex, ey, pos, vel, radius, links, state, fcenter, fradius, prm)
    gx, gy = _wall_force(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], radius[i], ex, ey, walls, prm)
    fx, fy = fx + gx, fy + gy
    if props[i, REACTION] > 0.0:
        gx, gy = _robot_force(i, pos, vel, radius, ex, ey, prm[EVADE], rxy, rvel, rrad, prm)
        fx, fy = fx + props[i, REACTION] * gx, fy + props[i, REACTION] * gy
    gx, gy = _group_force(i, ex, ey, pos, vel, links, gsum, prm)
    tau = props[i, TAU]
    tx, ty = props[i, V0] * ex + tau * (fx + gx), props[i, V0] * ey + tau * (fy + gy)
    a = math.exp(-dt / tau)
    return tx + (vel[i, 0] - tx) * a, ty + (vel[i, 1] - ty) * a


@njit(cache=True, inline="always", error_model="numpy")
def _hold_velocity(i, dt, pos, vel, yaw, radius, props, state, anchor, jit, rxy, rvel, rrad,
                   prm):  # fmt: skip
    """Velocity of standing person i after dt: implicit spring-damper to its target."""
    ex, ey = anchor[i, 0] - pos[i, 0], anchor[i, 1] - pos[i, 1]
    reaction = props[i, REACTION]
    if state[i] == STANDING:
        m = i - (pos.shape[0] - jit.shape[0])
        ex, ey = ex + jit[m, 0], ey + jit[m, 1]
        reaction = prm[F_REACT]
    ax = ay = 0.0
    if reaction > 0.0:
        ax, ay = _robot_force(i, pos, vel, radius, math.cos(yaw[i]), math.sin(yaw[i]), 0.0,
                              rxy, rvel, rrad, prm)  # fmt: skip
    k, c = prm[K_HOLD], prm[C_HOLD]
    den = 1.0 + dt * c + dt * dt * k
    return ((vel[i, 0] + dt * (k * ex + reaction * ax)) / den,
            (vel[i, 1] + dt * (k * ey + reaction * ay)) / den)  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def _limit(vx, vy, vmax, px, py, r, dt, walls):
    """Cap the speed, then keep the body from reaching any wall within dt."""
    s = math.sqrt(vx * vx + vy * vy)
    if s > vmax:
        vx, vy, s = vx * vmax / s, vy * vmax / s, vmax
    for w in range(walls.shape[0]):
        d, nx, ny = _wall_offset(px, py, walls, w, r + s * dt)
        approach = -(vx * nx + vy * ny)
        allowed = max(d - r, 0.0) / dt
        if approach > allowed:
            vx, vy = vx + (approach - allowed) * nx, vy + (approach - allowed) * ny
    return vx, vy


@njit(cache=True, error_model="numpy")
def _step(t, dt, pos, vel, yaw, radius, props, links, cursor, state, route, anchor, leg_from,
          jit, noise, fcenter, fradius, gsum, walls, rxy, rvel, rrad, prm, out):  # fmt: skip
    """One update: states, group centres, members' (x, y, yaw) jitter, then all velocities."""
    _advance_routes(t, pos, vel, props, links, cursor, state, route, anchor, leg_from, prm)
    gsum[:] = 0.0  # sum of x, y and count of the walking members of each group
    for i in range(pos.shape[0]):
        g = links[i, GROUP]
        if g >= 0 and state[i] == WALKING:
            gsum[g, 0] += pos[i, 0]
            gsum[g, 1] += pos[i, 1]
            gsum[g, 2] += 1.0
    a = math.exp(-dt / prm[T_JIT])  # exact Ornstein-Uhlenbeck step of the members' jitter
    for m in range(jit.shape[0]):
        sigma = props[pos.shape[0] - jit.shape[0] + m, JITTER] * math.sqrt(1.0 - a * a)
        for c in range(3):
            jit[m, c] = a * jit[m, c] + sigma * noise[m, c]
    for i in range(pos.shape[0]):
        if state[i] == WALKING:
            vx, vy = _walker_velocity(
                i,
                dt,
                pos,
                vel,
                yaw,
                radius,
                props,
                links,
                cursor,
                state,
                route,
                gsum,
                fcenter,
                fradius,
                walls,
                rxy,
                rvel,
                rrad,
                prm,
            )
        else:
            vx, vy = _hold_velocity(i, dt, pos, vel, yaw, radius, props, state, anchor, jit,
                                    rxy, rvel, rrad, prm)  # fmt: skip
        out[i, 0], out[i, 1] = _limit(vx, vy, props[i, VMAX], pos[i, 0], pos[i, 1], radius[i],
                                      dt, walls)  # fmt: skip


@njit(cache=True, error_model="numpy")
def _sync(positions, velocities, dt, pos, vel, yaw, state, links, fcenter, jit, prm):
    """Store the simulated state; turn walkers to their motion, members to their centre."""
    turn = 1.0 - math.exp(-dt / prm[T_YAW])
    first = pos.shape[0] - jit.shape[0]
    for i in range(pos.shape[0]):
        pos[i, 0], pos[i, 1] = positions[i, 0], positions[i, 1]
        vel[i, 0], vel[i, 1] = velocities[i, 0], velocities[i, 1]
        if state[i] == STANDING:
            f = links[i, FORMATION]
            heading = math.atan2(fcenter[f, 1] - pos[i, 1], fcenter[f, 0] - pos[i, 0])
            yaw[i] = wrap_angle(heading + jit[i - first, 2])
        elif state[i] == WALKING and math.hypot(vel[i, 0], vel[i, 1]) > prm[V_YAW]:
            heading = math.atan2(vel[i, 1], vel[i, 0])
            yaw[i] = wrap_angle(yaw[i] + turn * wrap_angle(heading - yaw[i]))


def _readonly(a: NDArray[Any]) -> NDArray[Any]:
    return np.lib.stride_tricks.as_strided(a, writeable=False)  # a read-only view


class Crowd:
    """The people of one episode: their state arrays and the two per-step kernels.

    Read-only views, updated in place until the next :meth:`reset`: ``position`` (P, 2) [m],
    ``velocity`` (P, 2) [m/s], ``yaw`` (P,) [rad], ``radius`` (P,) [m], ``state`` (P,) int64,
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
    ) -> None:  # fmt: skip
        """Build the crowd of an episode, at rest: walkers at their layout yaw (waiting for
        their start delay), members at their places facing the O-space centre. ``walls``
        (S, 4) and ``rng`` are the defaults of :meth:`desired_velocity`."""
        self._walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        self._rng, self._dt = rng, 0.0
        m = sum(len(f.members) for f in formations)
        n = len(people) + m
        self._pos, self._vel, self._anchor, self._out = (np.zeros((n, 2)) for _ in range(4))
        self._yaw, self._radius = np.zeros(n), np.zeros(n)
        self._props, self._links = np.zeros((n, 6)), np.full((n, 5), -1, dtype=np.int64)
        self._cursor, self._state = np.zeros(n, np.int64), np.full(n, WAITING, np.int64)
        self._jit, self._noise = np.zeros((m, 3)), np.zeros((m, 3))
        self._set_walkers(people)
        self._set_formations(formations, len(people))
        self._leg_from = self._pos.copy()
        self.position, self.velocity = _readonly(self._pos), _readonly(self._vel)
        self.yaw, self.radius = _readonly(self._yaw), _readonly(self._radius)
        self.state = _readonly(self._state)
        self.walking_group = _readonly(np.ascontiguousarray(self._links[:, GROUP]))
        self.formation_of = _readonly(np.ascontiguousarray(self._links[:, FORMATION]))
        self.formation_centers = _readonly(self._fcenter)

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
        _step(float(t), float(dt), self._pos, self._vel, self._yaw, self._radius, self._props,
              self._links, self._cursor, self._state, self._route, self._anchor,
              self._leg_from, self._jit, self._noise, self._fcenter, self._fradius, self._gsum,
              self._walls if walls is None else walls, robots_xy, robots_vel, robots_radius,
              self._prm, self._out)  # fmt: skip
        self._dt = dt
        return self._out

    def sync(self, positions: NDArray[np.float64], velocities: NDArray[np.float64]) -> None:
        """Take the people's (P, 2) positions [m] and velocities [m/s] after the physics
        (float64) and turn walkers towards their motion, members towards their centre."""
        _sync(positions, velocities, float(self._dt), self._pos, self._vel, self._yaw,
              self._state, self._links, self._fcenter, self._jit, self._prm)  # fmt: skip
