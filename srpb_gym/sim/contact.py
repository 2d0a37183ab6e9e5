"""Collisions attributed: what a robot touched, how fast both moved and who closed the gap.

A *collision* is the first control step of a robot's contact with a body: a wall (every
wall segment counts as one body), a person or another robot, touched on this step and
not on the step before. With ``collision="terminate"`` an episode has at most one; with
``"continue"`` a contact that lasts several steps is one collision, and touching another
body during it is another.

The velocities are read when the physics first finds the contact (pymunk's
``pre_solve``, called before the contact's first impulse): each body's velocity at the
end of the previous physics substep, so the impulses of the contact itself never hide
who moved. Robot velocities are those of the robot's centre. The *line* of a contact is
its normal, from the robot towards the other body: the line between the two centres for
a person or a robot, the direction to the touched point for a wall. Along it:

* ``robot_closing`` = v_robot . n, the speed at which the robot drove at the other;
* ``other_closing`` = -v_other . n, the speed at which the other came at the robot
  (0 for a wall).

A negative value moves away. Who caused a collision (:func:`caused_by`): a wall
collision is always the robot's; otherwise the robot's when ``robot_closing >=
other_closing`` (a tie, both standing still included, is the robot's: keeping clear is
its task), else the person's (``"person"``) or the other robot's (``"other_robot"``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import astuple, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: what a robot touched, by the code the world stores (the columns of its flags)
KINDS: tuple[str, ...] = ("wall", "person", "robot")
#: who caused a collision, by code: this robot, the person, the other robot
CAUSES: tuple[str, ...] = ("robot", "person", "other_robot")
#: the fields of a collision, in the order of :class:`Collision` and the world's rows
FIELDS: tuple[str, ...] = ("kind", "by", "robot_speed", "other_speed", "robot_closing",
                           "other_closing")  # fmt: skip
#: the world's row of a robot's collision: kind code, cause code, then the four speeds
ROW_SIZE = len(FIELDS)
STEP_PREFIX = "collision_"
"""The prefix of a step info's keys of the collision that began on that step."""
FIRST_PREFIX = "first_collision_"
"""The prefix of an episode's last info's keys of its first collision."""


def caused_by(kind: int, robot_closing: float, other_closing: float) -> int:
    """The code in :data:`CAUSES` of who caused a collision of kind code ``kind``: the
    robot for a wall or when it closed the gap at least as fast as the other; else the
    person (kind 1) or the other robot (kind 2)."""
    if kind == 0 or robot_closing >= other_closing:
        return 0
    return kind


@dataclass(frozen=True)
class Collision:
    """One collision of a robot (see the module docstring): ``kind`` (:data:`KINDS`),
    ``by`` (:data:`CAUSES`), ``robot_speed`` and ``other_speed`` [m/s] (0 for a wall),
    ``robot_closing`` and ``other_closing`` [m/s] along the line of the contact."""

    kind: str
    by: str
    robot_speed: float
    other_speed: float
    robot_closing: float
    other_closing: float

    @classmethod
    def from_row(cls, row: NDArray[np.float64]) -> Collision:
        """A collision from a world's row (kind and cause codes, then the speeds)."""
        speeds = [float(v) for v in row[2:ROW_SIZE]]
        return cls(KINDS[int(row[0])], CAUSES[int(row[1])], *speeds)

    def info(self, prefix: str) -> dict[str, Any]:
        """The fields as info keys ``<prefix><field>``."""
        return {f"{prefix}{k}": v for k, v in zip(FIELDS, astuple(self))}

    @classmethod
    def from_info(cls, info: Mapping[str, Any], prefix: str) -> Collision | None:
        """The collision in ``info`` under ``<prefix><field>`` (:meth:`info`), ``None``
        when it holds none (an empty kind or no such keys)."""
        if not info.get(f"{prefix}kind"):
            return None
        values = [info[f"{prefix}{k}"] for k in FIELDS]
        return cls(str(values[0]), str(values[1]), *(float(v) for v in values[2:]))
