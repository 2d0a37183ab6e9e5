"""The pymunk world: static walls, robots and people as rigid bodies, SI units.

A new :class:`World` (a fresh ``pymunk.Space``) is built for every episode: a reused space
keeps cached contact impulses and is not reproducible.

Robots are dynamic bodies driven through a kinematic *control body* per robot, coupled by
a pivot joint and a gear joint whose ``max_bias`` is 0 and whose force is bounded: the
joints pull the robot's velocity towards the command while contacts stay hard
constraints, so a robot stops at a wall instead of sinking into it, and is slowed or
deflected by people. A robot's collision shape is its footprint plus a thin bumper
(:attr:`RobotConfig.bumper`), which absorbs the overlap of the substep in which a contact
is first found, so the footprint itself stays out of walls. People are dynamic bodies (no
rotation) whose velocity is set once per control step from the crowd model; the robot can
push them but never through a wall.

All bodies are read and written in one batch call each (``pymunk.batch``). Collisions of
each robot with walls, people and other robots are reported per control step through
pymunk collision callbacks: every robot has its own collision type, so each pair of types
has its own handler that knows which robots and which kind of contact it reports. The
handlers also keep which bodies each robot touches, so that a contact that begins on a
step is told from one that lasts, and attribute each new one from the velocities and the
normal the physics finds it with (:mod:`srpb_gym.sim.contact`); only the steps with a
contact pay for this.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pymunk
import pymunk.batch as pb
from numba import njit
from numpy.typing import NDArray

from srpb_gym.sim.contact import ROW_SIZE, caused_by
from srpb_gym.sim.robot import RobotConfig

WALL, PERSON, ROBOT = 2, 3, 16  # collision types; robot i has ROBOT + i
PERSON_MASS = 70.0  # kg
COLLISION_SLOP = 0.001  # m, overlap pymunk tolerates before pushing bodies apart


class World:
    """One episode's physics.

    Arguments: ``walls`` (S, 4) segments [m]; ``robots``: a config and a start pose
    (x, y, yaw) per robot; ``people_xy`` (P, 2) and ``people_radius`` (P,) [m];
    ``physics_dt`` [s] and ``substeps`` per control step.
    """

    def __init__(
        self,
        walls: NDArray[np.float64],
        robots: Sequence[tuple[RobotConfig, tuple[float, float, float]]],
        people_xy: NDArray[np.float64],
        people_radius: NDArray[np.float64],
        physics_dt: float,
        substeps: int,
    ) -> None:
        self.physics_dt, self.substeps = float(physics_dt), int(substeps)
        self.space = space = pymunk.Space()
        space.collision_slop = COLLISION_SLOP
        space.iterations = 15
        for x0, y0, x1, y1 in np.asarray(walls, dtype=float).reshape(-1, 4):
            seg = pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0)
            seg.collision_type, seg.friction, seg.elasticity = WALL, 0.0, 0.0
            space.add(seg)
        self.n_robots, self.n_people = len(robots), int(people_xy.shape[0])
        self._robot_bodies, self._controls, self._joints = [], [], []
        for i, (cfg, pose) in enumerate(robots):
            self._add_robot(i, cfg, pose)
        self._people_bodies = [self._add_person(p, r) for p, r in zip(people_xy, people_radius)]
        # contacts per robot (wall, person, robot) since the caller last cleared them
        self.collisions = np.zeros((self.n_robots, 3), dtype=np.bool_)
        #: the bodies each robot touches since the last :meth:`clear_contacts` and touched
        #: before it (columns: robots, people, then every wall as one body)
        n_bodies = self.n_robots + self.n_people + 1
        self.touching = np.zeros((self.n_robots, n_bodies), dtype=np.bool_)
        self.touched = np.zeros_like(self.touching)
        #: (R,) collisions (contacts that began) of each robot since the last clear
        self.new_collisions = np.zeros(self.n_robots, dtype=np.int64)
        #: (R, 6) the collision of each robot with the largest closing speed (robot's plus
        #: other's) among those: :class:`~srpb_gym.sim.contact.Collision` ``from_row``;
        #: valid only where ``new_collisions`` > 0
        self.collision = np.zeros((self.n_robots, ROW_SIZE))
        for i in range(self.n_robots):  # the handler's data: the robots and the column
            space.on_collision(ROBOT + i, WALL, pre_solve=self._on_contact, data=(i, 0))
            space.on_collision(ROBOT + i, PERSON, pre_solve=self._on_contact, data=(i, 1))
            for j in range(i + 1, self.n_robots):
                space.on_collision(ROBOT + i, ROBOT + j, pre_solve=self._on_contact,
                                   data=((i, j), 2))  # fmt: skip
        self._init_batch()

    # ------------------------------------------------------------------ building
    def _add_robot(self, index: int, cfg: RobotConfig, pose: tuple[float, float, float]) -> None:
        body = pymunk.Body(cfg.mass, pymunk.moment_for_circle(cfg.mass, 0.0, cfg.radius))
        body.position, body.angle = (pose[0], pose[1]), pose[2]
        shape = pymunk.Circle(body, cfg.radius + cfg.bumper)
        shape.collision_type, shape.friction, shape.elasticity = ROBOT + index, 0.0, 0.0
        control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        control.position, control.angle = body.position, body.angle
        pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
        pivot.max_bias, pivot.max_force = 0.0, cfg.mass * cfg.drive_accel
        gear = pymunk.GearJoint(control, body, 0.0, 1.0)
        gear.max_bias, gear.max_force = 0.0, body.moment * cfg.drive_accel / cfg.radius
        self.space.add(body, shape, control, pivot, gear)
        self._robot_bodies.append(body)
        self._controls.append(control)
        self._joints.append((pivot, gear))

    def _add_person(self, xy: NDArray[np.float64], radius: float) -> pymunk.Body:
        body = pymunk.Body(PERSON_MASS, float("inf"))
        body.position = (float(xy[0]), float(xy[1]))
        shape = pymunk.Circle(body, float(radius))
        shape.collision_type, shape.friction, shape.elasticity = PERSON, 0.0, 0.0
        self.space.add(body, shape)
        return body

    def _init_batch(self) -> None:
        """Locate robots, control bodies and people in the batch body order; set up the
        buffers of the batch reads and writes and the views into the body state."""
        buf = pb.Buffer()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, buf)
        order = {int(i): k for k, i in enumerate(np.frombuffer(buf.int_buf(), dtype=np.uintp))}
        self._n_bodies = len(order)
        self._robot_rows = np.array([order[b.id] for b in self._robot_bodies], dtype=np.int64)
        self._control_rows = np.array([order[b.id] for b in self._controls], dtype=np.int64)
        self._people_rows = np.array([order[b.id] for b in self._people_bodies], dtype=np.int64)
        self._person_of = {s: k for k, b in enumerate(self._people_bodies) for s in b.shapes}
        # vx, vy, omega of every body, written in one batch call per step (people's omega
        # stays 0)
        self._velocities = np.zeros((self._n_bodies, 3))
        self._calls = _SpaceCalls(self.space, self._velocities)
        self.state = np.zeros((self._n_bodies, 6))  # x, y, angle, vx, vy, omega of every body
        robots, people = _rows(self._robot_rows), _rows(self._people_rows)
        #: whether the views below are refreshed in place (bodies in runs of the batch order)
        self._views = isinstance(robots, slice) and isinstance(people, slice)
        self._robot_index, self._people_index = robots, people
        self._set_views()
        self.read_state()

    def _set_views(self) -> None:
        state, robots, people = self.state, self._robot_index, self._people_index
        #: (R, 3) robot poses: x, y [m], yaw [rad] (not wrapped)
        self.robot_pose = state[robots, :3]
        #: (P, 2) people positions [m] and velocities [m/s]
        self.people_xy = state[people, :2]
        self.people_velocity = state[people, 3:5]

    # what _init_batch derives from the space: the batch buffers (C data bound to the
    # bodies, whose ids change in a copy), the body rows and the views of ``state`` (a
    # copied view would no longer follow the array)
    _DERIVED = ("_n_bodies", "_robot_rows", "_control_rows", "_people_rows", "_person_of",
                "_velocities", "_calls", "state", "_views", "_robot_index", "_people_index",
                "robot_pose", "people_xy", "people_velocity")  # fmt: skip

    def __getstate__(self) -> dict:
        # pymunk copies and pickles the space with its bodies, contacts and collision
        # handlers (their callbacks are this world's bound methods: the copy's own), but not
        # the solver state that the next step starts from: kept here
        state = {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}
        state["_solver"] = _solver_state(self._bodies(), self._joints)
        return state

    def __setstate__(self, state: dict) -> None:
        solver = state.pop("_solver", None)
        self.__dict__.update(state)
        self._init_batch()
        if solver is not None:
            _solver_state(self._bodies(), self._joints, solver)

    def _bodies(self) -> list[pymunk.Body]:
        return [*self._robot_bodies, *self._controls, *self._people_bodies]

    def _on_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: tuple) -> None:
        robots, col = data  # every pair of collision types has its own handler
        self.collisions[robots, col] = True
        if col == 0:
            self._touch(robots, self.n_robots + self.n_people, 0, arbiter, False)
        elif col == 1:
            person = self._person_of[arbiter.shapes[1]]
            self._touch(robots, self.n_robots + person, 1, arbiter, False)
        else:  # the handler's first shape is robot i's
            i, j = robots
            self._touch(i, j, 2, arbiter, False)
            self._touch(j, i, 2, arbiter, True)

    def _touch(self, robot: int, body: int, kind: int, arbiter: pymunk.Arbiter, swap: bool) -> None:
        """Robot ``robot`` touches ``body`` (a column of :attr:`touching`), a contact of
        kind code ``kind``; ``swap``: the robot is the arbiter's second shape. A contact
        new since the last step is a collision, attributed now: pre_solve runs before the
        contact's impulses, so the bodies still move as they did before it."""
        if self.touching[robot, body]:
            return
        self.touching[robot, body] = True
        if self.touched[robot, body]:
            return  # a contact that lasts
        ours, other = arbiter.shapes
        n = arbiter.normal  # from the first shape towards the second
        if swap:
            ours, other, n = other, ours, -n
        v = ours.body.velocity
        robot_closing = 0.0 + v.dot(n)  # never -0.0
        if kind:
            w = other.body.velocity
            other_speed, other_closing = abs(w), 0.0 - w.dot(n)
        else:
            other_speed = other_closing = 0.0
        count = self.new_collisions[robot]
        row = self.collision[robot]
        self.new_collisions[robot] = count + 1
        if count and robot_closing + other_closing <= row[4] + row[5]:
            return  # the robot's hardest collision of the step is kept
        row[:] = (kind, caused_by(kind, robot_closing, other_closing), abs(v), other_speed,
                  robot_closing, other_closing)  # fmt: skip

    def clear_contacts(self) -> None:
        """Start a control step: no contacts, no collisions yet, and what each robot touched
        becomes what it touched before (:class:`~srpb_gym.simulation.Simulation` does this
        in its compiled step)."""
        clear_contacts(self.collisions, self.touching, self.touched, self.new_collisions)

    # ------------------------------------------------------------------ stepping
    def step(
        self,
        robot_velocity: NDArray[np.float64],
        people_velocity: NDArray[np.float64],
        substeps: int | None = None,
    ) -> None:
        """Advance ``substeps`` physics steps (default: one control step's worth) with
        ``robot_velocity`` (R, 3) world-frame commands (vx, vy, omega) for the control
        bodies and ``people_velocity`` (P, 2)."""
        _fill_velocities(self.state, self._robot_rows, self._control_rows, self._people_rows,
                         robot_velocity, people_velocity, self._velocities)  # fmt: skip
        self._calls.write()
        self._calls.step(self.substeps if substeps is None else substeps, self.physics_dt)
        self.read_state()

    def read_state(self) -> None:
        """Refresh :attr:`state` and the views of it (``robot_pose``, ``people_xy``,
        ``people_velocity``, updated in place) from the space (one batch call)."""
        self._calls.read(self.state)
        if not self._views:
            self._set_views()


class _SpaceCalls:
    """The pymunk calls of every control step with their setup done once.

    The batch read (x, y, angle, vx, vy, omega) and write (vx, vy, omega, from
    ``velocities``) of every body of ``space``: :mod:`pymunk.batch`'s functions allocate
    and look up their call data on every call. The physics steps: ``Space.step`` also
    runs the bookkeeping of bodies added or removed during a step, which a world never
    has; it is called only while some is pending (the checks of newly added bodies before
    the first step). ``direct`` False (pymunk without the internals used) calls pymunk's
    own functions.
    """

    _GET = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | pb.BodyFields.VELOCITY
    _GET |= pb.BodyFields.ANGULAR_VELOCITY
    _SET = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY

    def __init__(self, space: pymunk.Space, velocities: NDArray[np.float64]) -> None:
        self.space = space
        self.get_buf, self.set_buf = pb.Buffer(), pb.Buffer()
        self.set_buf.set_float_buf(velocities.reshape(-1))  # the buffer reads the array
        try:
            self.ffi, lib = pb.ffi, pb.lib
            self.each_body, self.cp_space = lib.cpSpaceEachBody, space._space
            self.get_call = self._batch_call(self.get_buf, self._GET, "Get")
            self.set_call = self._batch_call(self.set_buf, self._SET, "Set")
            self._pending()
            self.cp_step = lib.cpSpaceStep
            self.direct = not space.threaded
        except AttributeError:  # pragma: no cover - another pymunk layout
            self.direct = False

    def _batch_call(self, buf: pb.Buffer, fields: pb.BodyFields, kind: str) -> tuple:
        data = self.ffi.new("pmBatchedData *")
        data.fields, data.floatArray, data.intArray = fields.value, buf._float_arr, buf._int_arr
        iterator = self.ffi.addressof(pb.lib, f"pmSpaceBody{kind}IteratorFuncBatched")
        return buf._float_arr, iterator, data

    def _pending(self) -> bool:
        """Whether ``Space.step`` has bookkeeping to do."""
        s = self.space
        return bool(s._bodies_to_check or s._add_later or s._remove_later
                    or s._post_step_callbacks)  # fmt: skip

    def step(self, substeps: int, dt: float) -> None:
        """``substeps`` physics steps of ``dt`` [s]."""
        if not self.direct or self._pending():
            for _ in range(substeps):
                self.space.step(dt)
            return
        step, cp_space = self.cp_step, self.cp_space
        for _ in range(substeps):
            step(cp_space, dt)

    def read(self, into: NDArray[np.float64]) -> None:
        """Copy the state of every body, in batch order, into ``into`` (B, 6)."""
        if not self.direct:
            self.get_buf.clear()
            pb.get_space_bodies(self.space, self._GET, self.get_buf)
            into.reshape(-1)[:] = np.frombuffer(self.get_buf.float_buf(), dtype=np.float64)
            return
        arr, iterator, data = self.get_call
        arr.num = 0
        self.each_body(self.cp_space, iterator, data)
        if arr.num != into.size:
            raise RuntimeError("the space's bodies changed")
        self.ffi.memmove(into, arr.arr, into.nbytes)

    def write(self) -> None:
        """Set the velocity of every body from the ``velocities`` array."""
        if not self.direct:
            pb.set_space_bodies(self.space, self._SET, self.set_buf)
            return
        arr, iterator, data = self.set_call
        count = arr.num
        arr.num = 0  # the set iterator reads from the start
        self.each_body(self.cp_space, iterator, data)
        arr.num = count


def _solver_state(
    bodies: Sequence[pymunk.Body],
    joints: Sequence[tuple[pymunk.PivotJoint, pymunk.GearJoint]],
    values: NDArray[np.float64] | None = None,
) -> NDArray[np.float64] | None:
    """The state of chipmunk's solver that pymunk neither copies nor pickles, read from
    ``bodies`` and ``joints`` or, given ``values``, written back: each body's bias
    velocity (vx, vy, omega: the overlap correction of the last step, applied by the next
    position update) and each pivot and gear joint's accumulated impulse (the warm start
    of the next step). ``None`` (nothing read or written) where chipmunk's structs are not
    laid out as :func:`_struct_offsets` expects."""
    offsets = _struct_offsets()
    if offsets is None:
        return None
    body_at, pivot_at, gear_at = offsets
    fields = [(b._body, body_at) for b in bodies]
    for pivot, gear in joints:
        fields += [(pivot._constraint, pivot_at), (gear._constraint, gear_at)]
    out = np.empty(sum(len(at) for _, at in fields)) if values is None else values
    k = 0
    for pointer, at in fields:
        doubles = pb.ffi.cast("double *", pointer)
        for i in at:
            if values is None:
                out[k] = doubles[i]
            else:
                doubles[i] = float(values[k])
            k += 1
    return out


_OFFSETS: list = []  # the result of _struct_offsets, once computed


def _struct_offsets() -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]] | None:
    """Where a body's bias velocity and a pivot and a gear joint's accumulated impulse lie
    in chipmunk's (opaque) structs, in doubles: checked on probes against the values pymunk
    exposes (position, velocity, force, angle, angular velocity, torque, transform, which
    precede the bias velocity; the anchor and phase that precede the impulses, and the
    impulses' magnitudes after a step), ``None`` if they do not match."""
    if not _OFFSETS:
        try:
            _OFFSETS.append(_probe_offsets())
        except Exception:  # pragma: no cover - another chipmunk layout
            _OFFSETS.append(None)
    return _OFFSETS[0]


def _probe_offsets() -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]] | None:
    space = pymunk.Space()
    body = pymunk.Body(2.0, 3.0)
    body.position, body.velocity, body.force = (1.25, -2.5), (0.375, 0.625), (4.5, 5.5)
    body.angle, body.angular_velocity, body.torque = 0.3, 0.7, 0.9
    c, s = math.cos(0.3), math.sin(0.3)
    expected = [1.25, -2.5, 0.375, 0.625, 4.5, 5.5, 0.3, 0.7, 0.9, c, s, -s, c, 1.25, -2.5]
    doubles = pb.ffi.cast("double *", body._body)
    found = [p for p in range(32) if [doubles[p + i] for i in range(15)] == expected]
    if len(found) != 1:
        return None
    body_at = (found[0] + 16, found[0] + 17, found[0] + 18)  # after the user data pointer
    # a resting circle that overlaps a wall, held by joints to a moving kinematic body
    wall = pymunk.Segment(space.static_body, (-5.0, 0.0), (5.0, 0.0), 0.0)
    body.position, body.velocity, body.force, body.angle = (0.0, 0.2), (0.0, 0.0), (0, 0), 0.0
    body.angular_velocity, body.torque = 0.0, 0.0
    control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    control.velocity, control.angular_velocity = (0.5, -0.5), 1.0
    pivot = pymunk.PivotJoint(control, body, (0.123456789, 0.987654321), (0.0, 0.0))
    gear = pymunk.GearJoint(control, body, 0.31415926, 1.0)
    pivot.max_force = gear.max_force = 1.0
    space.add(wall, body, pymunk.Circle(body, 0.5), control, pivot, gear)
    joint_at = []
    for joint, value, shift in ((pivot, 0.123456789, 12), (gear, 0.31415926, 5)):
        doubles = pb.ffi.cast("double *", joint._constraint)
        found = [p for p in range(32) if doubles[p] == value]
        if len(found) != 1:
            return None
        joint_at.append(found[0] + shift)
    dt = 0.01
    space.step(dt)
    bias = [pb.ffi.cast("double *", body._body)[i] for i in body_at]
    p, v = body.position, body.velocity
    pivot_d = pb.ffi.cast("double *", pivot._constraint)
    jx, jy = pivot_d[joint_at[0]], pivot_d[joint_at[0] + 1]
    gear_j = pb.ffi.cast("double *", gear._constraint)[joint_at[1]]
    if not (bias[1] != 0.0 and jx != 0.0 and gear_j != 0.0):
        return None
    if math.sqrt(jx * jx + jy * jy) != pivot.impulse or abs(gear_j) != gear.impulse:
        return None
    space.step(dt)  # the position update adds the bias velocity
    if tuple(body.position) != (p.x + (v.x + bias[0]) * dt, p.y + (v.y + bias[1]) * dt):
        return None
    return body_at, (joint_at[0], joint_at[0] + 1), (joint_at[1],)


def _rows(rows: NDArray[np.int64]) -> slice | NDArray[np.int64]:
    """``rows`` as a slice when they are consecutive (then indexing gives a view)."""
    if rows.size and np.array_equal(rows, np.arange(rows[0], rows[0] + rows.size)):
        return slice(int(rows[0]), int(rows[0]) + rows.size)
    return rows if rows.size else slice(0, 0)


@njit(cache=True, error_model="numpy")
def clear_contacts(collisions, touching, touched, new_collisions):
    """See :meth:`World.clear_contacts`."""
    for r in range(touching.shape[0]):
        collisions[r, :] = False
        new_collisions[r] = 0
        for c in range(touching.shape[1]):
            touched[r, c] = touching[r, c]
            touching[r, c] = False


@njit(cache=True, error_model="numpy")
def _fill_velocities(state, robot_rows, control_rows, people_rows, robot_vel, people_vel, out):
    """Velocities of every body for the batch write: robots keep theirs, control bodies get
    the commands, people the crowd's."""
    for k in range(robot_rows.shape[0]):
        out[robot_rows[k], 0] = state[robot_rows[k], 3]
        out[robot_rows[k], 1] = state[robot_rows[k], 4]
        out[robot_rows[k], 2] = state[robot_rows[k], 5]
    for k in range(control_rows.shape[0]):
        out[control_rows[k], 0] = robot_vel[k, 0]
        out[control_rows[k], 1] = robot_vel[k, 1]
        out[control_rows[k], 2] = robot_vel[k, 2]
    for k in range(people_rows.shape[0]):
        out[people_rows[k], 0] = people_vel[k, 0]
        out[people_rows[k], 1] = people_vel[k, 1]
