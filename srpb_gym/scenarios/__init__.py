"""Navigation scenarios: YAML recipes of a world and its episodes, and their sampler.

>>> import numpy as np
>>> from srpb_gym.scenarios import load_scenario, sample
>>> scenario = load_scenario("corridor")  # or a path to a YAML file
>>> layout = sample(scenario, np.random.default_rng(0))  # an EpisodeLayout

The file format is documented in ``envs/README.md``.
"""

from __future__ import annotations

from srpb_gym.scenarios.loader import list_scenarios, load_scenario, parse_scenario
from srpb_gym.scenarios.sampler import sample
from srpb_gym.scenarios.schema import (
    ROBOT_RADIUS,
    FormationSpec,
    Place,
    PoseSpec,
    RobotSpec,
    Scenario,
    SensorSpecs,
    WalkerEntry,
    WalkerParams,
    YawSpec,
)  # fmt: skip
from srpb_gym.scenarios.validate import FreeSpace, validate

__all__ = [
    "ROBOT_RADIUS", "FormationSpec", "FreeSpace", "Place", "PoseSpec", "RobotSpec", "Scenario",
    "SensorSpecs", "WalkerEntry", "WalkerParams", "YawSpec", "list_scenarios", "load_scenario",
    "parse_scenario", "sample", "validate",
]  # fmt: skip
