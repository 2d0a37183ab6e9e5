"""Planners behind one interface: classical baselines that drive the robot from what it
knows (never the ground truth). ``make_planner("dwa", {"horizon": 2.5})`` builds one by
name from plain-data settings (see :mod:`srpb_gym.planners.config`).

:data:`PLANNERS` are the baselines, every evaluation's default. :data:`REFERENCE_PLANNERS`
are handed the true people (:mod:`srpb_gym.planners.reference`): built by name as the
others, run only when named."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.base import (
    PERSON_RADIUS,
    Planner,
    command_to_action,
    heading_error,
    knowledge_for,
)
from srpb_gym.planners.dwa import DWA, DWAConfig
from srpb_gym.planners.global_planner import GlobalPlanner, GlobalPlannerConfig
from srpb_gym.planners.go_to_goal import GoToGoal, GoToGoalConfig
from srpb_gym.planners.recovery import RecoveryConfig
from srpb_gym.planners.reference import OracleDWA, OracleSocialDWA, OracleSocialDWAConfig
from srpb_gym.planners.social_dwa import SocialDWA, SocialDWAConfig
from srpb_gym.planners.social_force import SocialForcePlanner, SocialForcePlannerConfig

PLANNERS: dict[str, type[Planner]] = {
    GoToGoal.name: GoToGoal,
    DWA.name: DWA,
    SocialDWA.name: SocialDWA,
    SocialForcePlanner.name: SocialForcePlanner,
}
"""The baselines: they see what the robot knows; an evaluation runs them all by default."""
REFERENCE_PLANNERS: dict[str, type[Planner]] = {
    OracleDWA.name: OracleDWA,
    OracleSocialDWA.name: OracleSocialDWA,
}
"""Reference planners, handed the true people (``ground_truth``): no baselines, run only
when named."""


def is_planner(name: str) -> bool:
    """Whether ``name`` is a registered planner: a baseline or a reference planner."""
    return name in PLANNERS or name in REFERENCE_PLANNERS


def planner_class(name: str) -> type[Planner]:
    """The class of the planner ``name``, a baseline or a reference planner; ``KeyError``
    naming the choices for an unknown name."""
    cls = PLANNERS.get(name) or REFERENCE_PLANNERS.get(name)
    if cls is None:
        raise KeyError(unknown_planner(name))
    return cls


def unknown_planner(name: str) -> str:
    """The message for an unknown planner ``name``, naming the choices."""
    return (f"unknown planner {name!r}; choose one of: {', '.join(PLANNERS)} (reference, "
            f"handed the true people: {', '.join(REFERENCE_PLANNERS)})")  # fmt: skip


def planner_config(name: str, config: Any = None, path: str | None = None) -> Any:
    """The resolved settings of the planner ``name``: ``config`` (an instance of its config
    class, a mapping of the fields to change, or ``None``: the defaults) checked and built.

    Raises ``KeyError`` for an unknown planner and :class:`InputError` naming the dotted key
    under ``path`` (default ``planner.<name>``) for bad settings; ``None`` for a planner
    without settings.
    """
    path = f"planner.{name}" if path is None else path
    cls = planner_class(name).config_class
    if cls is None:
        if config is not None and not (isinstance(config, Mapping) and not config):
            raise InputError(f"planner {name!r} has no settings", key=path)
        return None
    return cls.from_spec(config, path)


def check_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``settings`` (``{planner name: settings}``) as a dict, after checking that it is a
    mapping of registered planner names; :class:`InputError` (key ``planner.<name>``)
    otherwise. The settings themselves are checked when the planner is built."""
    if not isinstance(settings, Mapping):
        raise InputError(f"expected a mapping of planner names to settings, got {settings!r}",
                         key="planner")  # fmt: skip
    for name in settings:
        if not is_planner(name):
            raise InputError(unknown_planner(name), key=f"planner.{name}")
    return dict(settings)


def make_planner(name: str, config: Any = None, path: str | None = None) -> Planner:
    """A planner by its name (see :data:`PLANNERS`, :data:`REFERENCE_PLANNERS`) with the
    settings ``config`` (an instance of its config class, a mapping of the fields to change,
    e.g. ``{"horizon": 2.5, "global_planner": {"spacing": 0.2}}``, or ``None``: the
    defaults).

    Raises ``KeyError`` for an unknown name and :class:`InputError` naming the dotted key
    (``planner.<name>.<field>`` unless ``path`` is given) for bad settings.
    """
    resolved = planner_config(name, config, path)
    cls = planner_class(name)
    return cls() if cls.config_class is None else cls(resolved)  # type: ignore[call-arg]


__all__ = ["DWA", "PERSON_RADIUS", "PLANNERS", "REFERENCE_PLANNERS", "DWAConfig",
           "GlobalPlanner", "GlobalPlannerConfig", "GoToGoal", "GoToGoalConfig", "Knowledge",
           "OracleDWA", "OracleSocialDWA", "OracleSocialDWAConfig", "Planner", "RecoveryConfig",
           "SocialDWA", "SocialDWAConfig", "SocialForcePlanner", "SocialForcePlannerConfig",
           "check_settings", "command_to_action", "heading_error", "is_planner",
           "knowledge_for", "make_planner", "planner_class", "planner_config",
           "unknown_planner"]  # fmt: skip


def __getattr__(name: str) -> Any:
    # SocialForceConfig was this planner's settings class before the name was left to the
    # crowd model (srpb_gym.sim.crowd.SocialForceConfig): the old name still works, warned
    if name == "SocialForceConfig":
        warnings.warn("srpb_gym.planners.SocialForceConfig is now SocialForcePlannerConfig "
                      "(SocialForceConfig is the crowd model's settings, srpb_gym.sim.crowd)",
                      DeprecationWarning, stacklevel=2)  # fmt: skip
        return SocialForcePlannerConfig
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
