"""A mixture of scenarios: one environment that draws its scenario at every reset.

:class:`SRPBMixEnv` (``gym.make("SRPB-Mix-v0")``) builds one simulation and one task per
scenario with the same settings and, at every ``reset``, draws which one the episode runs
from the environment's own generator, so a generalist policy trains on all of them through
one observation space and one action space.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from srpb_gym.env import RESET_OPTIONS, SRPBNavEnv
from srpb_gym.episode_setup import episode_layout
from srpb_gym.errors import InputError
from srpb_gym.metrics.params import MetricParams
from srpb_gym.registration import MIX_SCENARIOS
from srpb_gym.scenarios import Scenario
from srpb_gym.settings import EnvSettings
from srpb_gym.sim.layout import EpisodeLayout
from srpb_gym.simulation import Simulation
from srpb_gym.task import RobotTask

__all__ = ["MIX_RESET_OPTIONS", "MIX_SCENARIOS", "SRPBMixEnv"]

MIX_RESET_OPTIONS = ("scenario", *RESET_OPTIONS)


class _Part(NamedTuple):
    """What differs between the scenarios of a mixture: each has its own of these."""

    scenario: Scenario
    sim: Simulation
    task: RobotTask


class SRPBMixEnv(SRPBNavEnv):
    """Human-aware navigation over a mixture of scenarios, one drawn per episode.

    ## Description
    The environment of :class:`~srpb_gym.env.SRPBNavEnv` (the same robot, dynamics, reward
    and SRPB metrics) over several scenarios: every ``reset`` draws one scenario
    with the given weights and runs the episode in it. By default the five packaged
    scenarios corridor, fformation, crossing, crowd and doorway, with equal weights.
    Each scenario keeps its own simulation, sensors (the scenario's ``sensors`` section:
    the packaged scenarios differ in their people detector, a camera detector or a lidar
    leg detector), goal tolerance, time limit and metric parameters; every other setting
    (the arguments below) is shared. ``scenario``, ``sim``, ``task`` and ``params`` are
    those of the current episode (of the first scenario before the first reset);
    ``scenarios`` names the scenarios of the mixture, ``weights`` gives their
    probabilities, and :meth:`scenario_of` and :meth:`params_of` the scenario and the
    metric parameters of each.

    ## Action Space
    As :class:`~srpb_gym.env.SRPBNavEnv`: ``Box(-1, 1, (2,), float32)`` (linear, angular)
    for the default differential drive, 3 dims for a holonomic robot. The same in every
    scenario.

    ## Observation Space
    As :class:`~srpb_gym.env.SRPBNavEnv` (``observation=...``: ``flat``, 80 values with the
    defaults, or ``dict``): one fixed space for every scenario. The layout depends on the
    ``observation`` and ``robot`` arguments only, which all scenarios share; the space of
    every scenario is compared with the first one's when the environment is made, and a
    difference is an error naming the scenario and the space. A scenario whose lidar
    differs from the first one's (field of view, beams or range, which change what a lidar
    sector of the observation means) is reported with a warning.

    ## Rewards
    As :class:`~srpb_gym.env.SRPBNavEnv` (``reward``, ``reward_weights``), in every scenario,
    each scenario re-weighting the preset by its own ``reward`` section (:meth:`task_of`).

    ## Starting State
    Each ``reset`` first draws the scenario from the environment's generator (one uniform
    number), then the scenario's start and goal poses, people, routes and parameters from
    the same generator. ``reset(seed=s)`` therefore reproduces both the scenario and the
    episode bit for bit, and unseeded resets continue the stream. An episode of the
    mixture is not the episode of the single-scenario environment with the same seed (the
    draw comes first). ``reset(options={"scenario": name})`` runs that scenario of the
    mixture (by its name, or as given in ``scenarios``), also one of weight 0, which is
    never drawn otherwise: the draw is still made and replaced, so the rest of the
    episode is the one a drawn ``name`` would have had. The other options are those of
    :class:`~srpb_gym.env.SRPBNavEnv` (``people``, ``start``, ``goal``; poses are checked
    against the episode's scenario, so give ``scenario`` with them).

    ## Episode End
    As :class:`~srpb_gym.env.SRPBNavEnv`, each episode with its own scenario's goal
    tolerance and time limit: the environment truncates an episode at its scenario's time
    limit itself (60 s for most packaged scenarios, 90 s for crowd), with the metrics in
    the last ``info``. ``SRPB-Mix-v0`` is registered with the ``max_episode_steps`` of the
    longest default scenario (900 steps with crowd's 90 s at the 0.1 s control step), so
    ``TimeLimit`` never ends an episode before the environment does. A step limit of
    ``gym.make(..., max_episode_steps=N)`` applies to every scenario; when the registered
    limit is shorter than a scenario's time limit (a longer scenario file), a warning names
    the scenario and the ``max_episode_steps`` that covers it.

    ## Info
    The ``info`` of :class:`~srpb_gym.env.SRPBNavEnv` (the SRPB metrics, ``srpb/<metric>``
    and ``srpb_gt/<metric>``, in the last ``info`` of each episode), plus
    ``info["scenario"]``: the name of the episode's scenario, in the ``info`` of ``reset``
    and of every step (for ``Monitor(info_keywords=("scenario", ...))`` and per-scenario
    logging).

    ## Arguments
    ``scenarios``: a list of packaged scenario names or scenario files (default: corridor,
    fformation, crossing, crowd, doorway); each scenario at most once (by name).
    ``weights``: one number >= 0 per scenario, not all 0, relative (default: equal).
    The other arguments are those of :class:`~srpb_gym.env.SRPBNavEnv` (``render_mode``,
    and the settings ``observation``, ``reward``, ``reward_weights``, ``reward_people``,
    ``collision``, ``metrics``, ``record_dir``, ``sim``, ``robot``, ``sensors``, ``crowd``, or
    ``settings``: one :class:`~srpb_gym.settings.EnvSettings`), applied to every scenario;
    ``sensors`` replaces the sensors of every scenario. Recorded episodes are named after
    the episode's scenario (``crowd_seed3`` for ``reset(seed=3)`` drawing crowd), so the
    scenarios' records share ``record_dir``. Planners read ``knowledge()`` of the current
    episode as with a single scenario.

    ## Version History
    * v0: initial release.
    """

    def __init__(
        self,
        scenarios: Sequence[str | os.PathLike[str]] | None = None,
        weights: Sequence[float] | None = None,
        render_mode: str | None = None,
        settings: EnvSettings | None = None,
        **kwargs: Any,
    ) -> None:
        items = _checked_scenarios(scenarios)
        probabilities = _checked_weights(weights, len(items))
        settings = EnvSettings.given(settings, kwargs, type(self).__name__)
        with _naming(items, 0):
            super().__init__(items[0], render_mode, settings)
        parts = [_Part(self.scenario, self.sim, self.task)]
        for i, item in enumerate(items[1:], 1):
            with _naming(items, i):
                scenario = settings.load_scenario(item)
                sim, (task,) = settings.build(scenario)
            parts.append(_Part(scenario, sim, task))
        _check_parts(items, parts)
        self._parts = parts
        self._given = tuple(os.fspath(item) for item in items)
        #: the names of the scenarios of the mixture, in the order given
        self.scenarios: tuple[str, ...] = tuple(p.scenario.name for p in parts)
        #: the probability of drawing each scenario (the weights, normalised)
        self.weights: tuple[float, ...] = tuple(probabilities.tolist())
        self._probabilities = probabilities

    # ------------------------------------------------------------------ API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        info["scenario"] = self.scenario.name
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        info["scenario"] = self.scenario.name
        return obs, reward, terminated, truncated, info

    def scenario_of(self, name: str) -> Scenario:
        """The scenario ``name`` of the mixture (its name, or as given in ``scenarios``)."""
        return self._parts[self._index_of(name, "name")].scenario

    def task_of(self, name: str) -> RobotTask:
        """The robot task (observation, reward weights, metrics) of scenario ``name``."""
        return self._parts[self._index_of(name, "name")].task

    def params_of(self, name: str) -> MetricParams:
        """The SRPB metric parameters of the episodes of scenario ``name``."""
        return self._parts[self._index_of(name, "name")].task.params

    # ------------------------------------------------------------------ internals
    def _layout(self, options: dict[str, Any] | None) -> EpisodeLayout:
        """Draw the scenario, then its layout; switch to it only when both succeeded (a bad
        option leaves the environment as it was, the generator included)."""
        if options is not None and not isinstance(options, Mapping):
            raise InputError(f"expected a mapping of reset options, got {options!r}",
                             key="options")  # fmt: skip
        options = dict(options or {})
        unknown = sorted(set(options) - set(MIX_RESET_OPTIONS))
        if unknown:
            raise InputError(f"unknown reset option; valid: {', '.join(MIX_RESET_OPTIONS)}",
                             key=f"options.{unknown[0]}")  # fmt: skip
        index = int(self.np_random.choice(len(self._parts), p=self._probabilities))
        if "scenario" in options:
            index = self._index_of(options.pop("scenario"), "options.scenario")
        part = self._parts[index]
        layout = episode_layout(part.scenario, self.np_random, options)
        self.scenario, self.sim, self.task = part
        return layout

    def _index_of(self, name: Any, key: str) -> int:
        """The index of the scenario ``name`` (its name, or as given in ``scenarios``); an
        error names ``key``."""
        if isinstance(name, os.PathLike):
            name = os.fspath(name)
        if isinstance(name, str):
            for names in (self.scenarios, self._given):
                if name in names:
                    return names.index(name)
        raise InputError(f"{name!r} is not a scenario of the mixture; choose one of: "
                         f"{', '.join(self.scenarios)}", key=key)  # fmt: skip

    def _warn_short_limit(self) -> None:
        """Warn when the step limit ends a scenario's episodes before its time limit."""
        steps, dt = self._step_limit, self.sim.config.control_dt
        if steps is None:
            return
        longer = [p.scenario for p in self._parts if steps * dt < p.scenario.time_limit - 1e-9]
        if longer:
            needed = math.ceil(max(s.time_limit for s in longer) / dt - 1e-9)
            names = ", ".join(f"{s.name} ({s.time_limit:g} s)" for s in longer)
            gym.logger.warn(
                f"episodes end after {steps} steps ({steps * dt:g} s), before the time limit "
                f"of {names} at control_dt {dt:g} s; pass max_episode_steps={needed} to "
                f"gym.make for whole episodes of every scenario"
            )


def _checked_scenarios(
    scenarios: Sequence[str | os.PathLike[str]] | None,
) -> tuple[str | os.PathLike[str], ...]:
    """The scenarios of a mixture: a non-empty list of names or files."""
    if scenarios is None:
        return MIX_SCENARIOS
    if isinstance(scenarios, (str, os.PathLike)):
        raise InputError(f"expected a list of scenario names or files, got {scenarios!r}; "
                         f"write [{scenarios!r}] for one scenario", key="scenarios")  # fmt: skip
    if isinstance(scenarios, Mapping) or not isinstance(scenarios, (Sequence, np.ndarray)):
        raise InputError(f"expected a list of scenario names or files, got {scenarios!r}",
                         key="scenarios")  # fmt: skip
    items = tuple(scenarios)
    if not items:
        raise InputError("expected at least one scenario, got an empty list", key="scenarios")
    for i, item in enumerate(items):
        if not isinstance(item, (str, os.PathLike)):
            raise InputError(f"expected a scenario name or file, got {item!r}",
                             key=f"scenarios[{i}]")  # fmt: skip
    return items


def _checked_weights(weights: Sequence[float] | None, count: int) -> np.ndarray:
    """The probabilities of the weights of ``count`` scenarios (equal when ``None``)."""
    if weights is None:
        return np.full(count, 1.0 / count)
    if isinstance(weights, (str, bytes, Mapping)) or not isinstance(
        weights, (Sequence, np.ndarray)
    ):
        raise InputError(f"expected a list of numbers, one per scenario, got {weights!r}",
                         key="weights")  # fmt: skip
    values = list(weights)
    if len(values) != count:
        raise InputError(f"expected one weight per scenario ({count}), got {len(values)}",
                         key="weights")  # fmt: skip
    for i, w in enumerate(values):
        if (isinstance(w, (bool, np.bool_)) or not isinstance(w, numbers.Real)
                or not math.isfinite(w) or w < 0):  # fmt: skip
            raise InputError(f"expected a finite number >= 0, got {w!r}", key=f"weights[{i}]")
    floats = [float(w) for w in values]
    try:
        total = math.fsum(floats)
    except OverflowError:  # weights near the largest float: their sum is not one
        total = math.inf
    if total <= 0:
        raise InputError("the weights are all 0; give at least one scenario a weight > 0",
                         key="weights")  # fmt: skip
    if not math.isfinite(total):  # relative weights: scale them by the largest first
        largest = max(floats)
        floats = [w / largest for w in floats]
        total = math.fsum(floats)
    return np.array([w / total for w in floats])


@contextmanager
def _naming(items: Sequence[str | os.PathLike[str]], i: int) -> Iterator[None]:
    """Locate an input error raised while building scenario ``i``: an error without a
    location (an unknown scenario) at ``scenarios[i]``; one of an argument with the
    scenario it arose in. An error in a scenario file already names the file."""
    try:
        yield
    except InputError as exc:
        if exc.path is not None:
            raise
        if exc.key is None:
            raise InputError(exc.message, key=f"scenarios[{i}]") from None
        raise InputError(f"{exc.message} (in scenario {os.fspath(items[i])!r})",
                         key=exc.key) from None  # fmt: skip


def _check_parts(items: Sequence[str | os.PathLike[str]], parts: Sequence[_Part]) -> None:
    """Every scenario once, one observation and one action space; a warning for a lidar
    that differs from the first scenario's."""
    first = parts[0]
    seen: dict[str, int] = {}
    for i, part in enumerate(parts):
        name = part.scenario.name
        if name in seen:
            raise InputError(f"scenario {name!r} is already in the mixture (scenarios"
                             f"[{seen[name]}]); list each scenario once and set its share "
                             f"with weights", key=f"scenarios[{i}]")  # fmt: skip
        seen[name] = i
        for space in ("observation_space", "action_space"):
            mine, theirs = getattr(part.task, space), getattr(first.task, space)
            if mine != theirs:
                raise InputError(f"scenario {name!r} gives the {space} {mine}, scenario "
                                 f"{first.scenario.name!r} {theirs}; a mixture needs one "
                                 f"{space}", key=f"scenarios[{i}]")  # fmt: skip
        if part.sim.lidar_config != first.sim.lidar_config:
            gym.logger.warn(
                f"scenario {name!r}: its lidar ({part.sim.lidar_config}) differs from the "
                f"one of {first.scenario.name!r} ({first.sim.lidar_config}); the lidar "
                f"sectors of the observation mean different directions or ranges in them"
            )
