"""Planners behind one interface: classical baselines that drive the robot from what it
knows (never the ground truth). ``make_planner("dwa")`` builds one by name."""

from __future__ import annotations

from typing import Any

from srpb_gym.planners.base import Knowledge, Planner, command_to_action, heading_error
from srpb_gym.planners.dwa import DWA
from srpb_gym.planners.global_planner import GlobalPlanner
from srpb_gym.planners.go_to_goal import GoToGoal
from srpb_gym.planners.social_dwa import SocialDWA
from srpb_gym.planners.social_force import SocialForcePlanner

PLANNERS: dict[str, type[Planner]] = {
    GoToGoal.name: GoToGoal,
    DWA.name: DWA,
    SocialDWA.name: SocialDWA,
    SocialForcePlanner.name: SocialForcePlanner,
}


def make_planner(name: str, **kwargs: Any) -> Planner:
    """A planner by its name (see :data:`PLANNERS`)."""
    if name not in PLANNERS:
        raise KeyError(f"unknown planner {name!r}; choose one of: {', '.join(sorted(PLANNERS))}")
    return PLANNERS[name](**kwargs)


__all__ = ["DWA", "PLANNERS", "GlobalPlanner", "GoToGoal", "Knowledge", "Planner", "SocialDWA",
           "SocialForcePlanner", "command_to_action", "heading_error",
           "make_planner"]  # fmt: skip
