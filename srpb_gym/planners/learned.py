"""A learned policy (a stable-baselines3 model file) behind the :class:`Planner` interface.

``LearnedPolicy("runs/ppo/best_model.zip")`` loads the model on the CPU (its algorithm read
from the file: :func:`~srpb_gym.models.loading.load_model`) and normalises observations
with saved ``VecNormalize`` statistics when
:func:`~srpb_gym.models.files.find_vecnormalize` finds them where training puts them (RL
Zoo and ``srpb-gym train`` layouts), as during training. stable-baselines3 and torch come
from the ``train`` extra and are imported only when a policy is built. Finding and loading
the files, and the observation record, are :mod:`srpb_gym.models`'; this module adapts a
loaded model to the planner interface.

Failures are one line naming the file: :class:`~srpb_gym.models.loading.PolicyFileError`
for a model that cannot be loaded, :class:`~srpb_gym.models.loading.VecNormalizeError` for
a normalisation file that cannot be used. Nothing a model file or a statistics file
pickles is unpickled unless ``trust_pickle`` says that the user trusts them (a pickle is
code: :mod:`srpb_gym.models.loading`, :mod:`srpb_gym.models.normalization`).

A model trained by ``srpb-gym train`` holds the observation settings it was trained with
(:data:`~srpb_gym.models.record.OBSERVATION_RECORD`, saved in its ``model.zip``), and
:class:`LearnedPolicy` observes with them, whatever the environment's: it builds its
observation from the :class:`Knowledge` snapshot (the robot's own pose, scan and tracks)
as the environment builds its own. Settings that keep the space's shape
(``lidar_encoding``, the scales) can then never be mixed up, and models trained with
different settings are evaluated side by side. A model saved without the record acts on
the environment's observation.

The deterministic actions of a PPO or A2C ``MlpPolicy`` (every shipped model) are
computed by :class:`~srpb_gym.models.forward.FixedOrderPolicy`, a fixed-order forward pass
of the model's weights, not by torch: they are bit-identical on every CPU, whatever MKL
would pick. Other policies act through torch's ``predict`` (a note on stderr at load says
so) and may differ in their last bits from one CPU to another.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.knowledge import Knowledge
from srpb_gym.models.files import find_vecnormalize
from srpb_gym.models.forward import FixedOrderPolicy, UnsupportedPolicyError, fixed_order_policy
from srpb_gym.models.loading import PolicyFileError, VecNormalizeError, load_model
from srpb_gym.models.normalization import load_vecnormalize
from srpb_gym.models.record import (
    OBSERVATION_RECORD,
    describe_space,
    recorded_observation,
    spaces_differ,
)
from srpb_gym.observation import ObservationBuilder
from srpb_gym.observation import observation_space as observation_space_of
from srpb_gym.planners.base import Planner

__all__ = ["LearnedPolicy"]

_NOTED: set[str] = set()
"""The notes on torch's actions already printed by this process (one per model file)."""


class LearnedPolicy(Planner):
    """A stable-baselines3 model acting on its observation.

    ``path``: the model ``.zip``; ``algo``: its algorithm (see :data:`ALGORITHMS`), ``None``
    to read it from the file; ``vecnormalize``: a ``VecNormalize`` file, ``"auto"``
    (default) to look where training puts it (:func:`find_vecnormalize`) or ``None`` for
    raw observations; ``deterministic``: take the mode of the action distribution;
    ``trust_pickle``: let the model file's pickled attributes and a pickled statistics
    file (``vecnormalize.pkl``) be unpickled, which may run code (otherwise the first
    are decoded as data only and the second refused).

    A model that records its observation settings (``observation_config``) observes with
    them: each step it builds its observation from the :class:`Knowledge` snapshot, exactly
    as an environment with those settings would, and ignores the environment's (``act``
    then needs the snapshot). A model without the record acts on the environment's
    observation and may be given ``None``.

    The same actions on every CPU: the observation is normalised elementwise in numpy
    (``VecNormalize``'s ``(obs - mean) / sqrt(var + eps)``, clipped: correctly rounded
    operations only), and the deterministic action of a PPO or A2C ``MlpPolicy`` comes
    from a fixed-order forward pass of its weights (``forward``, a
    :class:`~srpb_gym.models.forward.FixedOrderPolicy`; within 1e-6 of torch's), so it is
    bit-identical whatever the processor or MKL's code path. Other policies (SAC, TD3,
    DDPG, DQN, CNN or custom extractors) and sampled actions (``deterministic=False``)
    keep torch's ``predict``: ``forward`` is ``None``, ``forward_note`` says why, and a
    note on stderr at load says so (once per model file and process).
    """

    name = "learned"

    def __init__(
        self,
        path: str | os.PathLike[str],
        algo: str | None = None,
        vecnormalize: str | os.PathLike[str] | None = "auto",
        deterministic: bool = True,
        trust_pickle: bool = False,
    ) -> None:
        self.path = os.fspath(path)
        self.deterministic = deterministic
        self.trust_pickle = trust_pickle
        self.model, self.algo = load_model(self.path, algo, trust_pickle)
        record = getattr(self.model, OBSERVATION_RECORD, None)
        try:
            self.observation_config = None if record is None else recorded_observation(record)
        except ValueError as exc:
            raise PolicyFileError(self.path, str(exc)) from None
        self.forward: FixedOrderPolicy | None = None
        self.forward_note: str | None = None
        try:
            self.forward = fixed_order_policy(self.model, deterministic)
        except UnsupportedPolicyError as exc:
            self.forward_note = (f"{self.path}: actions from torch, which may differ in "
                                 f"their last bits on another CPU ({exc})")  # fmt: skip
            if self.forward_note not in _NOTED:
                _NOTED.add(self.forward_note)
                print(f"srpb-gym: note: {self.forward_note}", file=sys.stderr)
        self._builder: ObservationBuilder | None = None
        self._sensors: tuple[Any, ...] = ()
        if vecnormalize == "auto":
            vecnormalize = find_vecnormalize(self.path)
        self.vecnormalize = None if vecnormalize is None else os.fspath(vecnormalize)
        self._normalizer = None
        if self.vecnormalize is not None:
            self._normalizer = load_vecnormalize(self.vecnormalize, trust_pickle)
            stats = self._normalizer.observation_space
            if spaces_differ(stats, self.model.observation_space):
                raise VecNormalizeError(
                    self.vecnormalize,
                    f"statistics of the observation space "
                    f"{describe_space(stats)}, the model {self.path} takes "
                    f"{describe_space(self.model.observation_space)}",
                )

    @property
    def trained_observation(self) -> dict[str, Any] | None:
        """The observation settings the model records (:data:`OBSERVATION_RECORD`), or
        ``None`` for a model saved without them."""
        return getattr(self.model, OBSERVATION_RECORD, None)

    def check_spaces(self, observation_space: Any, action_space: Any,
                     lidar_beams: int | None = None) -> None:  # fmt: skip
        """Raise ``ValueError`` (one line naming both spaces) unless the model acts in
        ``action_space`` and takes the observations it will get: those of
        ``observation_space`` or, for a model that observes with its recorded settings,
        those of its settings (the same kind, shape and bounds); such a model also needs
        at least as many ``lidar_beams`` (the environment's, when given) as its settings
        have lidar sectors."""
        where = "the environment has"
        own = self.observation_config
        if own is not None:
            observation_space = observation_space_of(own)
            where = "its observation record does not match it:"
            if lidar_beams is not None and own.lidar_bins > lidar_beams:
                raise ValueError(f"{self.path}: it observes {own.lidar_bins} lidar sectors "
                                 f"(its recorded observation settings), the environment's "
                                 f"lidar has {lidar_beams} beams")  # fmt: skip
        pairs = (("observation", self.model.observation_space, observation_space),
                 ("action", self.model.action_space, action_space))  # fmt: skip
        for what, trained, given in pairs:
            if spaces_differ(trained, given):
                same = describe_space(trained) == describe_space(given)
                place = where if what == "observation" else "the environment has"
                raise ValueError(
                    f"{self.path}: trained for the {what} space {describe_space(trained)}, "
                    f"{place} {describe_space(given)}" + (" (the bounds differ)" if same else "")
                )

    def reset(self, knowledge: Knowledge) -> None:
        if self.observation_config is not None:
            self._observer(knowledge)

    def _observer(self, knowledge: Knowledge | None) -> ObservationBuilder:
        """The builder of the model's own observation, for the robot and lidar of
        ``knowledge`` (made again when they change)."""
        if knowledge is None:
            raise TypeError(f"{self.path} observes with its recorded observation settings "
                            "and needs the Knowledge snapshot: act(observation, "
                            "env.unwrapped.knowledge())")  # fmt: skip
        sensors = (knowledge.robot, knowledge.scan.shape[0], knowledge.range_min,
                   knowledge.range_max, knowledge.scan_angles.tobytes())  # fmt: skip
        if self._builder is None or sensors != self._sensors:
            assert self.observation_config is not None
            try:
                self._builder = ObservationBuilder.for_robot(
                    self.observation_config, *sensors[:4], knowledge.scan_angles
                )
            except InputError as exc:
                raise ValueError(f"{self.path}: {exc.message} (its recorded observation "
                                 "settings)") from None  # fmt: skip
            self._sensors = sensors
        return self._builder

    def act(self, observation: Any, knowledge: Knowledge | None) -> NDArray[np.float32]:
        if self.observation_config is not None:
            builder, k = self._observer(knowledge), knowledge
            observation = builder.build(k.pose, k.goal, k.velocity, k.scan, k.tracks)
        if self._normalizer is not None:
            observation = self._normalizer.normalize_obs(observation)
        if self.forward is not None:
            return self.forward.predict(observation)
        action, _ = self.model.predict(observation, deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float32)
