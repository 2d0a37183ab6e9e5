"""Compiled kernels of the crowd (:class:`srpb_gym.sim.crowd.Crowd`): the social force
model of walkers, the hold of standing people, and the yaw update after the physics.

:func:`step` computes every person's velocity for the next ``dt`` from preallocated
per-person tables; :func:`sync` takes the simulated positions and velocities back. The
model and its parameters are described in :class:`srpb_gym.sim.crowd.SocialForceConfig`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.sim.geometry import segment_distance, wall_within

WAITING, WALKING, STOPPED, STANDING = 0, 1, 2, 3  # values of Crowd.state
CUTOFF = 10.0  # repulsions are dropped beyond this many ranges B (factor exp(-10))
SLIDE_SPEED = 0.05  # [m/s] a walker slower than this along a wall picks a side afresh
KEEP_OFF = 0.02  # [m] of the gap to a robot that a person who stops for robots never walks into
# Columns of the per-person parameter table (float) and link table (int).
V0, TAU, REACTION, VMAX, DELAY, JITTER = range(6)
GROUP, FORMATION, RSTART, RLEN, LOOP = range(5)

# Indices of the parameters in the vector handed to the kernels: the order of the fields of
# SocialForceConfig (a test checks).
(A_P, B_P, LAM, T_ANT, EVADE, RANGE, A_W, B_W, A_R, B_R, A_O, _VMAX, BETA1, BETA2, BETA3, VIEW,
 MARGIN, TOL, PASS, K_HOLD, C_HOLD, _VSTAND, T_JIT, F_REACT, R_REACT, T_YAW,
 V_YAW, K_TTC, T_TTC, F_TTC, M_TTC, D_APPROACH, D_WAIT, G_BACK) = range(34)  # fmt: skip
DOOR_FLOW = 0.1  # [m/s] slower than this across a door, a body in it holds it both ways


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
def _side(dx: float, dy: float, ex: float, ey: float) -> tuple[float, float]:
    """The unit direction, across heading e, away from an obstacle that lies at -(dx, dy)
    from the body: the side the body is on (its right when dead ahead)."""
    side = 1.0 if dx * ey - dy * ex >= 0.0 else -1.0
    return side * ey, -side * ex


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
    sx, sy = _side(nx, ny, ex, ey)  # pass it on the side we are on
    return _evade(mag * nx, mag * ny, sx, sy, ex, ey, evasion)


@njit(cache=True, inline="always", error_model="numpy")
def _ttc(dx: float, dy: float, dvx: float, dvy: float, rsum: float, k: float, tau0: float,
         fmax: float) -> tuple[float, float]:  # fmt: skip
    """Anticipatory repulsion of the time-to-collision power law (Karamouzas, Skinner and
    Guy 2014) on a body at offset (dx, dy) and relative velocity (dvx, dvy) from another,
    combined radius ``rsum``: ``-grad_x k tau^-2 exp(-tau / tau0)``, tau the time until the
    discs touch at constant velocities, capped at ``fmax``. Zero when they never touch on
    their course; ``fmax`` straight apart while they overlap."""
    c = dx * dx + dy * dy - rsum * rsum
    if c < 0.0:  # already overlapping: straight apart
        d = math.sqrt(dx * dx + dy * dy)
        return (fmax * dx / d, fmax * dy / d) if d > 1e-9 else (fmax, 0.0)
    b = dx * dvx + dy * dvy
    a = dvx * dvx + dvy * dvy
    if b >= 0.0 or a < 1e-12:  # not closing in
        return 0.0, 0.0
    disc = b * b - a * c
    if disc <= 0.0:  # passes clear
        return 0.0, 0.0
    root = math.sqrt(disc)
    tau = (-b - root) / a
    if tau > CUTOFF * tau0:
        return 0.0, 0.0
    tau = max(tau, 1e-3)
    mag = k * math.exp(-tau / tau0) / (a * tau * tau) * (2.0 / tau + 1.0 / tau0)
    fx = -mag * (dvx - (a * dx - b * dvx) / root)
    fy = -mag * (dvy - (a * dy - b * dvy) / root)
    f = math.sqrt(fx * fx + fy * fy)
    if f > fmax:
        fx, fy = fx * fmax / f, fy * fmax / f
    return fx, fy


@njit(cache=True, inline="always", error_model="numpy")
def _advance_routes(t, pos, vel, radius, props, links, cursor, state, route, anchor, leg_from,
                    walls, prm):  # fmt: skip
    """Start delayed walkers, move cursors past reached waypoints, stop finished walkers. A
    waypoint from which the body can walk the next leg straight, clear of the walls, is
    passed only once it can go straight on from where it is too."""
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
        last = cursor[i] + 1 >= links[i, RLEN]
        if not (last and not links[i, LOOP]):  # the next leg, if walkable, from here too
            n = links[i, RSTART] + (0 if last else cursor[i] + 1)
            nx, ny, r = route[n, 0], route[n, 1], radius[i]
            if (wall_within(pos[i, 0], pos[i, 1], nx, ny, r, walls)
                    and not wall_within(wx, wy, nx, ny, r, walls)):  # fmt: skip
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
def _robot_force(i, pos, vel, radius, ex, ey, evasion, rxy, rvel, rrad, prm, ux, uy):
    """Unscaled repulsion of person i from all robots: the social force, and the
    time-to-collision term (for the robot's body plus ``robot_ttc_margin``; its braking part
    partly turned sideways like the social force's) of the velocity (ux, uy) the person
    means to walk at: the collision it would walk into, which its current velocity, already
    bent by this force, would hide (it would chatter between braking and walking on).
    Returns the force and the smallest gap between the person's body and a robot's [m]."""
    fx = fy = 0.0
    gap = math.inf
    for r in range(rxy.shape[0]):
        dx, dy = pos[i, 0] - rxy[r, 0], pos[i, 1] - rxy[r, 1]
        dvx, dvy = vel[i, 0] - rvel[r, 0], vel[i, 1] - rvel[r, 1]
        rsum = radius[i] + rrad[r]
        gap = min(gap, math.sqrt(dx * dx + dy * dy) - rsum)
        gx, gy = _social(dx, dy, dvx, dvy, rsum, prm[A_R], prm[B_R], prm[T_ANT], ex, ey,
                         prm[LAM], evasion, 1.0)  # fmt: skip
        fx, fy = fx + gx, fy + gy
        if prm[K_TTC] > 0.0:
            gx, gy = _ttc(dx, dy, ux - rvel[r, 0], uy - rvel[r, 1], rsum + prm[M_TTC],
                          prm[K_TTC], prm[T_TTC], prm[F_TTC])  # fmt: skip
            sx, sy = _side(dx, dy, ex, ey)
            gx, gy = _evade(gx, gy, sx, sy, ex, ey, evasion)
            fx, fy = fx + gx, fy + gy
    return fx, fy, gap


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
def _wall_force(px, py, vx, vy, r, ex, ey, dw, walls, prm):
    """Repulsion of a walker at (px, py) moving at (vx, vy) from all walls, heading e to its
    waypoint ``dw`` metres ahead. A wall that the straight way to the waypoint passes with
    the body clear of it only pushes sideways (its braking part is dropped: people walk
    through a door they are lined up with); a wall in the way brakes and turns the walker
    along it the way it already slides, else towards its goal, else to the right."""
    fx = fy = 0.0
    reach = r + CUTOFF * prm[B_W]
    tx, ty = px + dw * ex, py + dw * ey
    for s in range(walls.shape[0]):
        d, nx, ny = _wall_offset(px, py, walls, s, reach)
        if d == math.inf:
            continue
        mag = prm[A_W] * math.exp((r - d) / prm[B_W])
        brake = -mag * (nx * ex + ny * ey)
        if brake > 0.0 and segment_distance(px, py, tx, ty, walls[s, 0], walls[s, 1],
                                            walls[s, 2], walls[s, 3]) >= r:  # fmt: skip
            fx, fy = fx + mag * nx + brake * ex, fy + mag * ny + brake * ey
            continue
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
def _door_crossed(c, n, hw, wx, wy, s_i):
    """Whether waypoint (wx, wy) of a walker on side ``s_i`` of the door at c with normal n
    and half width hw, lies across it, beside its opening."""
    s_w = (wx - c[0]) * n[0] + (wy - c[1]) * n[1]
    t_w = -(wx - c[0]) * n[1] + (wy - c[1]) * n[0]
    return s_w * s_i < 0.0 and abs(t_w) < hw + 1.0


@njit(cache=True, inline="always", error_model="numpy")
def _holds_door(x, y, vx, vy, r, cx, cy, nx, ny, hw, hd, s_i, sigma):
    """Whether a body at (x, y) moving at (vx, vy) holds the door against a walker on side
    ``s_i`` crossing in direction ``sigma``: it is in the opening not going the walker's way
    (or barely moving), or it comes at the opening from the other side and is nearer to it."""
    s = (x - cx) * nx + (y - cy) * ny
    t = -(x - cx) * ny + (y - cy) * nx
    u = (vx * nx + vy * ny) * sigma  # its speed in the walker's crossing direction
    if abs(s) < hd + r and abs(t) < hw + r:
        return u < DOOR_FLOW
    return s * s_i < 0.0 and abs(s) < abs(s_i) and abs(t) < hw + r and u < -DOOR_FLOW


@njit(cache=True, inline="always", error_model="numpy")
def _door_wait(i, pos, vel, radius, links, cursor, state, route, doors, waiting, rxy, rvel,
               rrad, prm):  # fmt: skip
    """Turn-taking at doors: the spot where walker i waits beside a door held by someone
    coming the other way (:func:`_holds_door`; people waiting do not hold it), as (x, y, 1),
    or (0, 0, 0) when it walks on. A walker waits when its next waypoint, or the one after,
    lies across a door less than ``door_approach`` ahead of it; its spot is
    ``door_wait_distance`` before the door's wall, beside the opening on the side it is on
    (its right when in the middle)."""
    px, py, r = pos[i, 0], pos[i, 1], radius[i]
    k = links[i, RSTART] + cursor[i]
    last = cursor[i] + 1 >= links[i, RLEN]
    k2 = (links[i, RSTART] if links[i, LOOP] else -1) if last else k + 1
    for d in range(doors.shape[0]):
        c, n = doors[d, 0:2], doors[d, 2:4]
        hw, hd = doors[d, 4], doors[d, 5]
        s_i = (px - c[0]) * n[0] + (py - c[1]) * n[1]
        t_i = -(px - c[0]) * n[1] + (py - c[1]) * n[0]
        if not (hd + r <= abs(s_i) < hd + prm[D_APPROACH] and abs(t_i) < hw + prm[D_APPROACH]):
            continue
        if not (_door_crossed(c, n, hw, route[k, 0], route[k, 1], s_i) or (
                k2 >= 0 and _door_crossed(c, n, hw, route[k2, 0], route[k2, 1], s_i))):  # fmt: skip
            continue
        sigma = -1.0 if s_i > 0.0 else 1.0
        held = False
        for j in range(pos.shape[0]):
            if j != i and state[j] == WALKING and waiting[j] == 0 and _holds_door(
                    pos[j, 0], pos[j, 1], vel[j, 0], vel[j, 1], radius[j], c[0], c[1], n[0],
                    n[1], hw, hd, s_i, sigma):  # fmt: skip
                held = True
                break
        for j in range(rxy.shape[0]):
            if held:
                break
            held = _holds_door(rxy[j, 0], rxy[j, 1], rvel[j, 0], rvel[j, 1], rrad[j], c[0],
                               c[1], n[0], n[1], hw, hd, s_i, sigma)  # fmt: skip
        if held:
            side = (1.0 if t_i > 0.0 else -1.0) if abs(t_i) > 0.1 else -sigma
            back = -sigma * (hd + prm[D_WAIT])
            aside = side * (hw + r + prm[D_WAIT])
            return c[0] + back * n[0] - aside * n[1], c[1] + back * n[1] + aside * n[0], 1
    return 0.0, 0.0, 0


@njit(cache=True, inline="always", error_model="numpy")
def _reaction(i, state, props, prm):
    """How strongly person i reacts to robots: a formation member standing in it the
    formations' reaction, anyone else its own, times the crowd's ``robot_reaction``."""
    return (prm[F_REACT] if state[i] == STANDING else props[i, REACTION]) * prm[R_REACT]


@njit(cache=True, inline="always", error_model="numpy")
def _walker_velocity(i, dt, pos, vel, yaw, radius, props, links, cursor, state, route, leg_from,
                     gsum, fcenter, fradius, walls, rxy, rvel, rrad, doors, waiting, heading,
                     prm):  # fmt: skip
    """Social-force velocity of walker i after dt (exact relaxation, forces held). A walker
    pushed off a leg of its route that the body can walk straight, to where a wall is in
    the way to its waypoint, heads back towards the leg's start if it can go straight there.
    A walker waiting for a door (:func:`_door_wait`) heads for its spot beside it and slows
    to a stop there. The people, walls and group terms never make it walk backwards (the
    part of its target velocity against its heading is dropped: in a dense crowd people
    stop rather than back away); the robot's may, while the gap between the bodies is below
    ``robot_backing_gap``. ``heading[i]``: its heading (the unit direction it walks
    towards) while a robot makes it back away, else 0."""
    k = links[i, RSTART] + cursor[i]
    wx, wy = route[k, 0], route[k, 1]
    px, py, r = pos[i, 0], pos[i, 1], radius[i]
    lx, ly = leg_from[i, 0], leg_from[i, 1]
    speed = props[i, V0]
    waiting[i] = 0
    if doors.shape[0] and prm[D_APPROACH] > 0.0:
        sx, sy, waiting[i] = _door_wait(i, pos, vel, radius, links, cursor, state, route,
                                        doors, waiting, rxy, rvel, rrad, prm)  # fmt: skip
        if waiting[i]:
            wx, wy = sx, sy
            speed *= min(math.hypot(sx - px, sy - py) / prm[D_WAIT], 1.0)
    if not waiting[i] and (wall_within(px, py, wx, wy, r, walls)
                           and not wall_within(lx, ly, wx, wy, r, walls)
                           and not wall_within(px, py, lx, ly, r, walls)):  # fmt: skip
        wx, wy = lx, ly
    wx, wy = wx - pos[i, 0], wy - pos[i, 1]
    dw = math.hypot(wx, wy)
    ex, ey = (wx / dw, wy / dw) if dw > 1e-9 else (math.cos(yaw[i]), math.sin(yaw[i]))
    heading[i, 0] = heading[i, 1] = 0.0
    fx, fy = _people_force(i, ex, ey, pos, vel, radius, links, state, fcenter, fradius, prm)
    gx, gy = _wall_force(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], radius[i], ex, ey, dw,
                         walls, prm)  # fmt: skip
    fx, fy = fx + gx, fy + gy
    gx, gy = _group_force(i, ex, ey, pos, vel, links, gsum, prm)
    tau = props[i, TAU]
    tx, ty = speed * ex + tau * (fx + gx), speed * ey + tau * (fy + gy)
    ahead = tx * ex + ty * ey
    if ahead < 0.0:  # pressed by people and walls, a walker stops; it does not back away
        tx, ty = tx - ahead * ex, ty - ahead * ey
    reaction = _reaction(i, state, props, prm)
    if reaction > 0.0:  # a robot may make it back away, while it is close
        gx, gy, gap = _robot_force(i, pos, vel, radius, ex, ey, prm[EVADE], rxy, rvel, rrad,
                                   prm, speed * ex, speed * ey)  # fmt: skip
        tx, ty = tx + tau * reaction * gx, ty + tau * reaction * gy
        ahead = tx * ex + ty * ey
        if ahead < 0.0 and gap < math.inf:  # (no robot: nothing to back away from)
            if gap >= prm[G_BACK]:  # farther off, it stops for the robot
                tx, ty = tx - ahead * ex, ty - ahead * ey
            else:
                heading[i, 0], heading[i, 1] = ex, ey
    a = math.exp(-dt / tau)
    return tx + (vel[i, 0] - tx) * a, ty + (vel[i, 1] - ty) * a


@njit(cache=True, inline="always", error_model="numpy")
def _hold_velocity(i, dt, pos, vel, yaw, radius, props, state, anchor, jit, rxy, rvel, rrad,
                   prm):  # fmt: skip
    """Velocity of standing person i after dt: implicit spring-damper to its target."""
    ex, ey = anchor[i, 0] - pos[i, 0], anchor[i, 1] - pos[i, 1]
    if state[i] == STANDING:
        m = i - (pos.shape[0] - jit.shape[0])
        ex, ey = ex + jit[m, 0], ey + jit[m, 1]
    reaction = _reaction(i, state, props, prm)
    ax = ay = 0.0
    if reaction > 0.0:
        ax, ay, _ = _robot_force(i, pos, vel, radius, math.cos(yaw[i]), math.sin(yaw[i]),
                                 0.0, rxy, rvel, rrad, prm, 0.0, 0.0)  # fmt: skip
    k, c = prm[K_HOLD], prm[C_HOLD]
    den = 1.0 + dt * c + dt * dt * k
    return ((vel[i, 0] + dt * (k * ex + reaction * ax)) / den,
            (vel[i, 1] + dt * (k * ey + reaction * ay)) / den)  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def _keep_off(vx, vy, px, py, r, dt, rxy, rvel, rrad, stop):
    """Keep a person's own motion from closing on any robot's body within dt by more than
    the gap leaves, less ``KEEP_OFF`` and what the robot's own motion closes in that time
    (a robot that drives into a person still reaches it): the part of the velocity towards
    the robot is cut to that (``stop``: the whole velocity is scaled down instead, which
    keeps it clear of the walls where the cut velocity was)."""
    for k in range(rxy.shape[0]):
        nx, ny = px - rxy[k, 0], py - rxy[k, 1]
        d = math.sqrt(nx * nx + ny * ny)
        if d < 1e-9:
            continue
        nx, ny = nx / d, ny / d
        approach = -(vx * nx + vy * ny)
        closing = max(rvel[k, 0] * nx + rvel[k, 1] * ny, 0.0) * dt
        allowed = max(d - r - rrad[k] - KEEP_OFF - closing, 0.0) / dt
        if approach > allowed:
            if stop:
                vx, vy = vx * allowed / approach, vy * allowed / approach
            else:
                vx, vy = vx + (approach - allowed) * nx, vy + (approach - allowed) * ny
    return vx, vy


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
def step(t, dt, walls, rxy, rvel, rrad, pos, vel, yaw, radius, props, links, cursor, state,
         route, anchor, leg_from, jit, noise, fcenter, fradius, gsum, doors, waiting, heading,
         prm, out):  # fmt: skip
    """One update: states, group centres, members' (x, y, yaw) jitter, then all velocities."""
    _advance_routes(t, pos, vel, radius, props, links, cursor, state, route, anchor, leg_from,
                    walls, prm)  # fmt: skip
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
    stops = prm[G_BACK] < math.inf  # people who stop for a robot never step into one
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
                leg_from,
                gsum,
                fcenter,
                fradius,
                walls,
                rxy,
                rvel,
                rrad,
                doors,
                waiting,
                heading,
                prm,
            )
        else:
            waiting[i] = 0
            vx, vy = _hold_velocity(i, dt, pos, vel, yaw, radius, props, state, anchor, jit,
                                    rxy, rvel, rrad, prm)  # fmt: skip
        keep_off = stops and _reaction(i, state, props, prm) > 0.0
        if keep_off:
            vx, vy = _keep_off(vx, vy, pos[i, 0], pos[i, 1], radius[i], dt, rxy, rvel, rrad,
                               False)  # fmt: skip
        vx, vy = _limit(vx, vy, props[i, VMAX], pos[i, 0], pos[i, 1], radius[i], dt, walls)
        if keep_off:  # (the walls may have turned it back towards a robot)
            vx, vy = _keep_off(vx, vy, pos[i, 0], pos[i, 1], radius[i], dt, rxy, rvel, rrad,
                               True)  # fmt: skip
        out[i, 0], out[i, 1] = vx, vy


@njit(cache=True, error_model="numpy")
def sync(positions, velocities, dt, pos, vel, yaw, state, links, fcenter, jit, way, back,
         prm):  # fmt: skip
    """Store the simulated state; turn walkers to their motion, members to their centre;
    add to ``back`` the distance each walker moved against its heading ``way`` in the step
    (0 unless a robot made it back away: :func:`_walker_velocity`)."""
    turn = 1.0 - math.exp(-dt / prm[T_YAW])
    first = pos.shape[0] - jit.shape[0]
    for i in range(pos.shape[0]):
        if state[i] == WALKING:
            along = ((positions[i, 0] - pos[i, 0]) * way[i, 0]
                     + (positions[i, 1] - pos[i, 1]) * way[i, 1])  # fmt: skip
            if along < 0.0:
                back[i] -= along
        pos[i, 0], pos[i, 1] = positions[i, 0], positions[i, 1]
        vel[i, 0], vel[i, 1] = velocities[i, 0], velocities[i, 1]
        if state[i] == STANDING:
            f = links[i, FORMATION]
            heading = math.atan2(fcenter[f, 1] - pos[i, 1], fcenter[f, 0] - pos[i, 0])
            yaw[i] = wrap_angle(heading + jit[i - first, 2])
        elif state[i] == WALKING and math.hypot(vel[i, 0], vel[i, 1]) > prm[V_YAW]:
            heading = math.atan2(vel[i, 1], vel[i, 0])
            yaw[i] = wrap_angle(yaw[i] + turn * wrap_angle(heading - yaw[i]))
