"""Everything an environment is built from, validated once: :class:`EnvSettings`.

The Gymnasium environment, the scenario mixture and the PettingZoo environment take the
same eleven settings (``observation``, ``reward``, ``reward_weights``, ``reward_people``,
``collision``, ``metrics``, ``record_dir``, ``sim``, ``robot``, ``sensors``, ``crowd``; see
:class:`srpb_gym.env.SRPBNavEnv` for what each means). They pass them here as plain data
and keep only their own arguments; the settings load a scenario for the robot, build its
simulation and one :class:`~srpb_gym.task.RobotTask` per robot::

    settings = EnvSettings.from_kwargs({"robot": "holonomic", "reward": "task"})
    scenario = settings.load_scenario("crowd")
    sim, tasks = settings.build(scenario, n_robots=3)

Every value is checked when the settings are made, with the strict readers of
:mod:`srpb_gym.config` (an error names the dotted key), and an unknown setting is a
``TypeError`` naming it, as for any keyword argument. ``gym.make(id, settings=...)``
works, but Gymnasium cannot write such a spec as JSON (``env.spec.to_json()``): pass the
keyword arguments where the spec must be JSON. What depends on a scenario (its
sensors when ``sensors`` names none, its reward section, its goal tolerance) is applied
when a simulation or a task is built for it.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.metrics.params import MetricParams
from srpb_gym.observation import ObservationConfig
from srpb_gym.perception.detector import DetectorConfig
from srpb_gym.perception.lidar import LidarConfig
from srpb_gym.perception.tracker import TrackerConfig
from srpb_gym.reward import check_weights, load_preset
from srpb_gym.scenarios import Scenario, load_scenario
from srpb_gym.sim.crowd import SocialForceConfig
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.simulation import SimConfig, Simulation
from srpb_gym.task import COLLISION_MODES, REWARD_PEOPLE, MetricSettings, RobotTask, build_task

__all__ = ["SENSORS", "SETTING_NAMES", "EnvSettings", "Frozen"]

SENSORS = ("lidar", "detector", "tracker")


class Frozen(Mapping[str, Any]):
    """A read-only copy of a mapping (nested mappings copied read-only too) that pickles
    and deep-copies like the environments that hold it."""

    def __init__(self, data: Mapping[str, Any]) -> None:
        self._data = {k: Frozen(v) if isinstance(v, Mapping) else v for k, v in data.items()}

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Any:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return repr(self._data)

    def __hash__(self) -> int:
        return hash(tuple(sorted(self._data.items())))


@dataclass(frozen=True)
class EnvSettings:
    """The settings every srpb-gym environment is built from, checked (frozen).

    ``observation``, ``sim``, ``robot`` and ``crowd`` are the resolved configs; ``sensors``
    holds the configs that replace the scenario's (``None``: the scenario's own);
    ``reward`` is a preset name and ``reward_weights`` the weights that override it by
    term, its terms computed from the people ``reward_people`` names; ``metrics`` the
    ``metrics`` mapping as given (checked); ``record_dir`` where finished episodes are
    written (created when a task is built).
    """

    observation: ObservationConfig = dataclasses.field(default_factory=ObservationConfig)
    reward: str = "srpb"
    reward_weights: Mapping[str, float] = dataclasses.field(default_factory=lambda: Frozen({}))
    reward_people: str = "tracked"
    collision: str = "terminate"
    metrics: Mapping[str, Any] = dataclasses.field(default_factory=lambda: Frozen({}))
    record_dir: str | None = None
    sim: SimConfig = dataclasses.field(default_factory=SimConfig)
    robot: RobotConfig = dataclasses.field(default_factory=RobotConfig)
    lidar: LidarConfig | None = None
    detector: DetectorConfig | None = None
    tracker: TrackerConfig | None = None
    crowd: SocialForceConfig = dataclasses.field(default_factory=SocialForceConfig)

    @classmethod
    def from_kwargs(
        cls, kwargs: Mapping[str, Any] | None = None, owner: str = "the environment"
    ) -> EnvSettings:
        """The settings of an environment's keyword arguments (plain data, as documented
        in :class:`srpb_gym.env.SRPBNavEnv`). A missing key takes its default; an unknown
        one is a ``TypeError`` naming it and ``owner``; a bad value an
        :class:`~srpb_gym.errors.InputError` naming its key."""
        kwargs = dict(kwargs or {})
        unknown = [k for k in kwargs if k not in SETTING_NAMES]
        if unknown:
            raise TypeError(f"{owner} got an unexpected keyword argument {unknown[0]!r}")
        record_dir = kwargs.get("record_dir")
        if isinstance(record_dir, os.PathLike):
            record_dir = os.fspath(record_dir)
        return cls(
            observation=ObservationConfig.from_spec(kwargs.get("observation")),
            reward=kwargs.get("reward", "srpb"),
            reward_weights=kwargs.get("reward_weights") or {},
            reward_people=kwargs.get("reward_people", "tracked"),
            collision=kwargs.get("collision", "terminate"),
            metrics=kwargs.get("metrics") or {},
            record_dir=record_dir,
            sim=SimConfig.from_spec(kwargs.get("sim")),
            robot=RobotConfig.from_spec(kwargs.get("robot")),
            crowd=SocialForceConfig.from_spec(kwargs.get("crowd"), "crowd"),
            **_checked_sensors(kwargs.get("sensors")),
        )

    def __post_init__(self) -> None:
        """Check every value (also of settings made directly, not by :meth:`from_kwargs`)
        and keep read-only copies of the mappings."""
        kinds = {"observation": ObservationConfig, "sim": SimConfig, "robot": RobotConfig,
                 "crowd": SocialForceConfig, "lidar": LidarConfig | None,
                 "detector": DetectorConfig | None, "tracker": TrackerConfig | None}  # fmt: skip
        for name, kind in kinds.items():
            if not isinstance(getattr(self, name), kind):
                label = getattr(kind, "__name__", None) or kind.__args__[0].__name__
                raise InputError(f"expected a {label} (EnvSettings.from_kwargs reads plain "
                                 f"data), got {getattr(self, name)!r}", key=name)  # fmt: skip
        if self.collision not in COLLISION_MODES:
            raise InputError(f"expected one of {COLLISION_MODES}, got {self.collision!r}",
                             key="collision")  # fmt: skip
        if self.reward_people not in REWARD_PEOPLE:
            raise InputError(f"expected one of {REWARD_PEOPLE}, got {self.reward_people!r}",
                             key="reward_people")  # fmt: skip
        load_preset(self.reward)  # an unknown preset: an error naming the key
        object.__setattr__(self, "reward_weights", Frozen(check_weights(self.reward_weights)))
        # checked now with the default goal tolerance; each task resolves its own
        MetricSettings.build(self.metrics, self.robot, MetricParams().goal_tolerance_xy)
        object.__setattr__(self, "metrics", Frozen(self.metrics))
        if self.record_dir is not None and not isinstance(self.record_dir, str):
            raise InputError(f"expected a folder path, got {self.record_dir!r}",
                             key="record_dir")  # fmt: skip

    @classmethod
    def given(cls, settings: EnvSettings | None, kwargs: dict[str, Any], owner: str) -> EnvSettings:
        """The settings of an environment ``owner``: ``settings``, or those of its keyword
        arguments ``kwargs`` (not both)."""
        if settings is None:
            return cls.from_kwargs(kwargs, f"{owner}()")
        if not isinstance(settings, cls):
            raise InputError(f"expected an EnvSettings, got {settings!r}", key="settings")
        if kwargs:
            raise TypeError(
                f"{owner}() takes either settings or the keyword arguments that "
                f"make them, not both (got settings and {sorted(kwargs)[0]!r})"
            )
        return settings

    # ------------------------------------------------------------------ building
    def load_scenario(self, scenario: str | os.PathLike[str]) -> Scenario:
        """The scenario (a packaged name or a YAML file), checked for this robot's radius."""
        return load_scenario(scenario, robot_radius=self.robot.radius)

    def simulation(self, scenario: Scenario) -> Simulation:
        """A simulation of ``scenario`` with these settings; the sensors these settings do
        not replace are the scenario's."""
        spec, where = scenario.sensors, scenario.source
        return Simulation(
            self.sim,
            self.robot,
            self.lidar or LidarConfig.from_spec(spec.lidar, "sensors.lidar", where),
            self.detector or DetectorConfig.from_spec(spec.detector, "sensors.detector", where),
            self.tracker or TrackerConfig.from_spec(spec.tracker, "sensors.tracker", where),
            self.crowd,
        )

    def task(self, sim: Simulation, robot: int, scenario: Scenario, n_robots: int = 1) -> RobotTask:
        """The task of robot ``robot`` (of ``n_robots``) in ``sim``, a simulation of
        ``scenario``: its goal tolerance and its reward section apply."""
        tolerance = scenario.robot_specs(n_robots)[robot].goal_tolerance
        return build_task(
            sim, robot, tolerance, self.observation, self.reward, self.reward_weights,
            self.collision, self.metrics, self.record_dir, scenario.reward, self.reward_people,
        )  # fmt: skip

    def build(self, scenario: Scenario, n_robots: int = 1) -> tuple[Simulation, list[RobotTask]]:
        """A simulation of ``scenario`` and the tasks of its ``n_robots`` robots (more
        robots than the scenario has places for: an error naming its limit)."""
        scenario.robot_specs(n_robots)
        sim = self.simulation(scenario)
        return sim, [self.task(sim, r, scenario, n_robots) for r in range(n_robots)]


#: the keyword arguments that make :class:`EnvSettings`, as the environments take them
SETTING_NAMES: tuple[str, ...] = (
    "observation", "reward", "reward_weights", "reward_people", "collision", "metrics",
    "record_dir", "sim", "robot", "sensors", "crowd",
)  # fmt: skip


def _checked_sensors(sensors: Any) -> dict[str, Any]:
    """The sensor configs of the ``sensors`` argument that replace the scenario's."""
    if sensors is None:
        return {}
    if not isinstance(sensors, Mapping):
        raise InputError(f"expected a mapping of {', '.join(SENSORS)} to presets or settings, "
                         f"got {sensors!r}", key="sensors")  # fmt: skip
    unknown = sorted(set(sensors) - set(SENSORS))
    if unknown:
        raise InputError(f"unknown sensor; valid: {', '.join(SENSORS)}",
                         key=f"sensors.{unknown[0]}")  # fmt: skip
    kinds = {"lidar": LidarConfig, "detector": DetectorConfig, "tracker": TrackerConfig}
    return {name: kinds[name].from_spec(spec, f"sensors.{name}")
            for name, spec in sensors.items()}  # fmt: skip
