"""Navigation scenarios: YAML recipes of a world and its episodes, and their sampler.

>>> import numpy as np
>>> from srpb_gym.scenarios import load_scenario, sample
>>> scenario = load_scenario("corridor")  # or a path to a YAML file
>>> layout = sample(scenario, np.random.default_rng(0))  # an EpisodeLayout
>>> pair = sample(scenario, np.random.default_rng(0), n_robots=2)  # from scenario.robots

Scenarios are checked and sampled for robots of a given radius (default
``DEFAULT_ROBOT_RADIUS``, 0.275 m): ``load_scenario("doorway", robot_radius=0.45)``.
One robot starts from the scenario's ``robot`` entry, several (up to
``scenario.max_robots``) from its ``robots`` entries.
The file format is documented in ``envs/README.md``.

Modules, each importing only those before it (files are read by :mod:`srpb_gym.yaml_io`,
the safe YAML reader): ``space`` (geometry, free-space grid), ``routes`` (the walking
route graph), ``schema`` (dataclasses), ``reader`` (typed values), ``sampler``,
``validate``, ``loader``.
"""

from __future__ import annotations

from srpb_gym.scenarios.loader import list_scenarios, load_scenario, parse_scenario
from srpb_gym.scenarios.sampler import sample
from srpb_gym.scenarios.schema import (
    DEFAULT_ROBOT_RADIUS,
    ROBOT_RADIUS,
    FormationSpec,
    PoseSpec,
    RobotSpec,
    Scenario,
    SensorSpecs,
    WalkerEntry,
    WalkerParams,
    YawSpec,
)  # fmt: skip
from srpb_gym.scenarios.space import FreeSpace, Place
from srpb_gym.scenarios.validate import validate

__all__ = [
    "DEFAULT_ROBOT_RADIUS", "ROBOT_RADIUS", "FormationSpec", "FreeSpace", "Place", "PoseSpec",
    "RobotSpec", "Scenario", "SensorSpecs", "WalkerEntry", "WalkerParams", "YawSpec",
    "list_scenarios", "load_scenario", "parse_scenario", "sample", "validate",
]  # fmt: skip
