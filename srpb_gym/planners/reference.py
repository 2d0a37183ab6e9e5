"""Reference planners: good drivers handed the true people, to show what each scenario allows.

:class:`OracleDWA` is the :class:`~srpb_gym.planners.dwa.DWA` (its settings and defaults)
and :class:`OracleSocialDWA` the :class:`~srpb_gym.planners.social_dwa.SocialDWA` handed the
people as they are (:func:`srpb_gym.knowledge.true_people`: exact positions, velocities and
headings, their true ids, zero covariance) in ``knowledge.tracks`` instead of the
tracker's. Everything else is what every planner gets: the robot and its limits, the static
map and the lidar scan; it drives through the same environment step as any planner.

A reference planner is no baseline: it knows what no robot knows. It is registered in
:data:`srpb_gym.planners.REFERENCE_PLANNERS`, not in :data:`srpb_gym.planners.PLANNERS`, so
it runs only when named (``srpb-gym eval --planner oracle-social-dwa``) and never among the
default planners of an evaluation or the published tables.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.dwa import DWA
from srpb_gym.planners.global_planner import GlobalPlannerConfig
from srpb_gym.planners.social_dwa import SocialDWA, SocialDWAConfig

#: social-dwa's global planner with walkers heading at the robot costlier for longer
#: (walking_cost 15 -> 100, person_horizon 2 -> 4 s), people counted standing later
#: (settle_time 1 -> 3 s) and a new path taken only when clearly cheaper (hysteresis
#: 0.15 -> 0.3)
_GLOBAL_PLANNER = replace(SocialDWAConfig().global_planner, walking_cost=100.0,
                          person_horizon=4.0, settle_time=3.0, hysteresis=0.3)  # fmt: skip


@dataclass(frozen=True)
class OracleSocialDWAConfig(SocialDWAConfig):
    """Settings of the :class:`OracleSocialDWA`: the fields of :class:`SocialDWAConfig`,
    with defaults of its own, chosen on validation seeds (``srpb_gym.seeds.VALIDATION``)
    for a driver that reaches its goal without contact rather than for the social metrics:
    walking people are kept a wider gap (``person_margin``; ``standing_margin`` for people
    predicted standing still, slower than ``standing_speed``, as the social DWA keeps them)
    over a longer prediction (exact velocities make it reliable), walkers heading at the
    robot block their way for longer in the global plan, and the social costs weigh half
    as much (less hesitation in a crowd)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self._nonnegative("standing_margin")

    person_margin: float = 0.4  # social-dwa: 0.1; for the people predicted walking ...
    standing_margin: float = 0.1  # m, ... and this for those predicted standing still
    people_horizon: float = 2.0  # social-dwa: 1.2
    w_psi: float = 4.0  # social-dwa: 8.0
    w_dir: float = 1.0  # social-dwa: 2.0
    psi_layer: float = 1.5  # social-dwa: 3.0
    walking_layer: float = 5.0  # social-dwa: 10.0
    global_planner: GlobalPlannerConfig = field(default_factory=lambda: _GLOBAL_PLANNER)


class OracleSocialDWA(SocialDWA):
    """:class:`SocialDWA` handed the true people (``ground_truth``); see the module
    docstring. ``config``: the settings (:class:`OracleSocialDWAConfig`, a mapping of the
    fields to change, or ``None``: the defaults)."""

    name = "oracle-social-dwa"
    config_class: ClassVar[type[OracleSocialDWAConfig]] = OracleSocialDWAConfig
    config: OracleSocialDWAConfig
    ground_truth: ClassVar[bool] = True

    def _people(self, k: Knowledge) -> NDArray[np.float64]:
        """The people of the trajectory checks (:meth:`DWA._people`), those predicted
        standing still (zero velocity) with ``standing_margin`` instead of
        ``person_margin``."""
        people = super()._people(k)
        still = (people[:, 2] == 0.0) & (people[:, 3] == 0.0)
        if still.any():
            cfg = self.config
            radii = self.planner.robot_radius + cfg.person_radius
            now = np.hypot(people[still, 0] - k.pose[0], people[still, 1] - k.pose[1])
            gap = np.minimum(radii + cfg.standing_margin, now - 0.05)
            people[still, 4] = np.maximum(radii + 0.01, gap)
        return people


class OracleDWA(DWA):
    """:class:`~srpb_gym.planners.dwa.DWA`, with its own settings and defaults, handed the
    true people (``ground_truth``); see the module docstring."""

    name = "oracle-dwa"
    ground_truth: ClassVar[bool] = True
