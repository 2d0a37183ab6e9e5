"""SRPB metrics: episode records, the metric engine and log readers/writers.

Quick use::

    from srpb_gym.metrics import evaluate, load_episode
    record = load_episode("log_robot.txt")          # finds _people/_groups siblings
    evaluate(record)                                 # paper semantics, paper preset
    evaluate(record, semantics="reference", preset="srpb-code", safety_distance=0.6)

Nothing here imports the simulation, torch or pygame.
"""

from srpb_gym.metrics.episode import (
    METRIC_DESCRIPTIONS,
    METRIC_NAMES,
    METRIC_RANGES,
    METRIC_UNITS,
    EpisodeEvaluation,
    SRPBMetricWarning,
    evaluate,
    evaluate_detailed,
)
from srpb_gym.metrics.params import PARAM_NAMES, PRESETS, SEMANTICS, MetricParams, resolve_params
from srpb_gym.metrics.record import PERSON_FIELDS, ROBOT_FIELDS, EpisodeRecord

__all__ = [
    "METRIC_DESCRIPTIONS",
    "METRIC_NAMES",
    "METRIC_RANGES",
    "METRIC_UNITS",
    "PARAM_NAMES",
    "PERSON_FIELDS",
    "PRESETS",
    "ROBOT_FIELDS",
    "SEMANTICS",
    "EpisodeEvaluation",
    "EpisodeRecord",
    "MetricParams",
    "SRPBMetricWarning",
    "evaluate",
    "evaluate_detailed",
    "resolve_params",
]
