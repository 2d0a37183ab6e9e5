"""A top-down renderer of a :class:`~srpb_gym.simulation.Simulation`.

Drawn for one chosen robot: walls, people with their heading and personal-space contour
(the ``personal_space_threshold`` level set of Kirby's asymmetric Gaussian used by
``m_psi``), the O-spaces of the F-formations (the ellipses ``m_fsi`` uses), the chosen
robot's tracks with their 2-sigma position covariance and ids, its lidar hit points and
trajectory, every robot (its size from the simulation's robot config) and goal (tolerance
circle and heading) in the robot's own colour, the chosen one highlighted, and a side or
bottom panel with the time and any values the caller passes (running SRPB metrics).

Modules: :mod:`~srpb_gym.render.geometry` (outlines in metres, the world-to-pixel
:class:`View`), :mod:`~srpb_gym.render.scene` (a frame's content as pixel-space numpy
arrays, :func:`scene_primitives`), :mod:`~srpb_gym.render.style` (colours, palette,
layout) are plain numpy; :mod:`~srpb_gym.render.renderer` (:class:`Renderer`) draws with
pygame (pygame-ce), which is imported only when a :class:`Renderer` is built, never with
the package.
"""

from srpb_gym.render.geometry import (
    View,
    covariance_ellipses,
    ellipse_points,
    fit_view,
    formation_ellipses,
    grid_lines,
    personal_space_contours,
)
from srpb_gym.render.renderer import (
    INSTALL_HINT,
    RENDER_MODES,
    RenderDependencyError,
    Renderer,
)
from srpb_gym.render.scene import (
    Discs,
    Goals,
    PanelRow,
    Robots,
    Scene,
    Tracks,
    panel_layout,
    panel_values,
    scene_primitives,
)
from srpb_gym.render.style import ROBOT_COLOR, ROBOT_EDGE, ROBOT_PALETTE, RobotColors, robot_colors

__all__ = [
    "INSTALL_HINT",
    "RENDER_MODES",
    "ROBOT_COLOR",
    "ROBOT_EDGE",
    "ROBOT_PALETTE",
    "Discs",
    "Goals",
    "PanelRow",
    "RenderDependencyError",
    "Renderer",
    "RobotColors",
    "Robots",
    "Scene",
    "Tracks",
    "View",
    "covariance_ellipses",
    "ellipse_points",
    "fit_view",
    "formation_ellipses",
    "grid_lines",
    "panel_layout",
    "panel_values",
    "personal_space_contours",
    "robot_colors",
    "scene_primitives",
]
