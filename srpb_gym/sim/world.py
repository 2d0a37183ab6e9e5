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
pymunk collision callbacks.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymunk
import pymunk.batch as pb
from numpy.typing import NDArray

from srpb_gym.sim.robot import RobotConfig

ROBOT, WALL, PERSON = 1, 2, 3
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
        self._robot_bodies, self._controls, self._robot_of = [], [], {}
        for i, (cfg, pose) in enumerate(robots):
            self._add_robot(i, cfg, pose)
        self._people_bodies = [self._add_person(p, r) for p, r in zip(people_xy, people_radius)]
        # contacts per robot (wall, person, robot) since the caller last cleared them
        self.collisions = np.zeros((self.n_robots, 3), dtype=np.bool_)
        for other, col in ((WALL, 0), (PERSON, 1), (ROBOT, 2)):
            space.on_collision(ROBOT, other, pre_solve=self._on_contact, data=col)
        self._init_batch()

    # ------------------------------------------------------------------ building
    def _add_robot(self, index: int, cfg: RobotConfig, pose: tuple[float, float, float]) -> None:
        body = pymunk.Body(cfg.mass, pymunk.moment_for_circle(cfg.mass, 0.0, cfg.radius))
        body.position, body.angle = (pose[0], pose[1]), pose[2]
        shape = pymunk.Circle(body, cfg.radius + cfg.bumper)
        shape.collision_type, shape.friction, shape.elasticity = ROBOT, 0.0, 0.0
        control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        control.position, control.angle = body.position, body.angle
        pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
        pivot.max_bias, pivot.max_force = 0.0, cfg.mass * cfg.drive_accel
        gear = pymunk.GearJoint(control, body, 0.0, 1.0)
        gear.max_bias, gear.max_force = 0.0, body.moment * cfg.drive_accel / cfg.radius
        self.space.add(body, shape, control, pivot, gear)
        self._robot_bodies.append(body)
        self._controls.append(control)
        self._robot_of[shape] = index

    def _add_person(self, xy: NDArray[np.float64], radius: float) -> pymunk.Body:
        body = pymunk.Body(PERSON_MASS, float("inf"))
        body.position = (float(xy[0]), float(xy[1]))
        shape = pymunk.Circle(body, float(radius))
        shape.collision_type, shape.friction, shape.elasticity = PERSON, 0.0, 0.0
        self.space.add(body, shape)
        return body

    def _init_batch(self) -> None:
        """Locate robots, control bodies and people in the batch body order."""
        buf = pb.Buffer()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, buf)
        order = {int(i): k for k, i in enumerate(np.frombuffer(buf.int_buf(), dtype=np.uintp))}
        self._n_bodies = len(order)
        self._robot_rows = np.array([order[b.id] for b in self._robot_bodies], dtype=np.int64)
        self._control_rows = np.array([order[b.id] for b in self._controls], dtype=np.int64)
        self._people_rows = np.array([order[b.id] for b in self._people_bodies], dtype=np.int64)
        self._state_buf = pb.Buffer()
        self._set_buf = pb.Buffer()
        # vx, vy, omega of every body, written in one batch call per control step
        self._velocities = np.zeros((self._n_bodies, 3))
        f = pb.BodyFields
        self._fields_get = f.POSITION | f.ANGLE | f.VELOCITY | f.ANGULAR_VELOCITY
        self._fields_set = f.VELOCITY | f.ANGULAR_VELOCITY
        self.state = np.zeros((self._n_bodies, 6))  # x, y, angle, vx, vy, omega of every body
        self.read_state()

    def __getstate__(self) -> dict:
        # the batch buffers are C data: rebuilt after unpickling (body ids change too)
        state = self.__dict__.copy()
        for key in ("_state_buf", "_set_buf", "_fields_get", "_fields_set"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict) -> None:
        collisions = state["collisions"].copy()
        self.__dict__.update(state)
        self._init_batch()
        self.collisions[:] = collisions

    def _on_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, col: int) -> None:
        for shape in arbiter.shapes:
            index = self._robot_of.get(shape)
            if index is not None:
                self.collisions[index, col] = True

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
        v = self._velocities
        v[self._robot_rows] = self.state[self._robot_rows, 3:6]  # unchanged
        v[self._control_rows] = robot_velocity
        v[self._people_rows, :2] = people_velocity
        v[self._people_rows, 2] = 0.0
        self._set_buf.set_float_buf(v.reshape(-1))
        pb.set_space_bodies(self.space, self._fields_set, self._set_buf)
        for _ in range(self.substeps if substeps is None else substeps):
            self.space.step(self.physics_dt)
        self.read_state()

    def read_state(self) -> None:
        """Refresh :attr:`state` and the views below from the space (one batch call)."""
        self._state_buf.clear()
        pb.get_space_bodies(self.space, self._fields_get, self._state_buf)
        state = np.frombuffer(self._state_buf.float_buf(), dtype=np.float64).reshape(-1, 6)
        self.state[:] = state
        #: (R, 3) robot poses: x, y [m], yaw [rad] (not wrapped)
        self.robot_pose = self.state[self._robot_rows, :3]
        #: (P, 2) people positions [m] and velocities [m/s]
        self.people_xy = self.state[self._people_rows, :2]
        self.people_velocity = self.state[self._people_rows, 3:5]
