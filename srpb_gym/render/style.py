"""Colours, the robots' palette and the screen layout (in pixels) of the renderer."""

from __future__ import annotations

from typing import NamedTuple

Color = tuple[int, int, int]  # RGB, 0-255

BACKGROUND: Color = (250, 250, 247)
GRID: Color = (229, 229, 224)
WALL: Color = (70, 70, 72)
PERSON: Color = (72, 125, 200)
PERSON_EDGE: Color = (30, 60, 112)
PERSONAL_SPACE: Color = (146, 184, 234)
OSPACE_FILL: Color = (238, 228, 247)
OSPACE_EDGE: Color = (146, 92, 186)
TRACK: Color = (0, 150, 112)
HALO: Color = (255, 255, 255)
LIDAR: Color = (226, 52, 60)
TRAIL: Color = (246, 188, 128)
PANEL: Color = (236, 238, 243)
TEXT: Color = (36, 38, 46)
MUTED: Color = (108, 110, 122)

#: body fill and outline of robot 0, 1, ... (repeated beyond the last); hues kept apart
#: from the people (blue), tracks (green), lidar hits (red) and O-spaces (violet)
ROBOT_PALETTE: tuple[tuple[Color, Color], ...] = (
    ((245, 134, 20), (110, 55, 0)),  # orange
    ((214, 62, 160), (100, 20, 72)),  # magenta
    ((222, 184, 0), (104, 84, 0)),  # gold
    ((20, 170, 210), (0, 76, 100)),  # cyan
    ((150, 96, 52), (70, 40, 14)),  # brown
    ((132, 170, 24), (58, 80, 0)),  # olive
    ((104, 104, 118), (36, 36, 44)),  # slate
)
ROBOT_COLOR: Color = ROBOT_PALETTE[0][0]
ROBOT_EDGE: Color = ROBOT_PALETTE[0][1]

MARGIN = 12  # px around the world
SIDE_STRIP = 190  # px, panel width when it sits on the right
BOTTOM_STRIP = 118  # px, panel height when it sits at the bottom
ROW = 21  # px, panel line height
COLUMN = 168  # px, panel column width


class RobotColors(NamedTuple):
    """The colours of one robot: its body, its outline, its goal marker and the fill of its
    goal's tolerance disc (drawn for the highlighted robot only)."""

    fill: Color
    edge: Color
    goal: Color
    goal_fill: Color


def blend(a: Color, b: Color, weight: float) -> Color:
    """``weight`` of colour ``a`` and the rest of ``b``, per channel, rounded."""
    return tuple(round(weight * x + (1.0 - weight) * y) for x, y in zip(a, b))  # type: ignore[return-value]


def robot_colors(index: int) -> RobotColors:
    """The palette entry of robot ``index`` (0-based; the palette repeats)."""
    fill, edge = ROBOT_PALETTE[index % len(ROBOT_PALETTE)]
    return RobotColors(fill, edge, blend(fill, edge, 0.7), blend(fill, BACKGROUND, 0.2))


#: panel legend: label, symbol, colour, fill
LEGEND: tuple[tuple[str, str, Color, Color | None], ...] = (
    ("robot", "disc", ROBOT_EDGE, ROBOT_COLOR),
    ("goal", "cross", robot_colors(0).goal, None),
    ("person", "disc", PERSON_EDGE, PERSON),
    ("personal space", "ring", PERSONAL_SPACE, None),
    ("O-space", "ring", OSPACE_EDGE, OSPACE_FILL),
    ("track (2 sigma)", "cross", TRACK, None),
    ("lidar hit", "dot", LIDAR, None),
    ("grid 1 m", "line", MUTED, None),
)
