"""A learned policy (a stable-baselines3 model file) behind the :class:`Planner` interface.

``LearnedPolicy("runs/ppo/best_model.zip")`` loads the model on the CPU and, when a
``<stem>_vecnormalize.pkl`` or ``vecnormalize.pkl`` (the RL-Zoo convention) lies beside it,
normalises observations with the saved statistics, as during training. stable-baselines3
and torch come from the ``train`` extra and are imported only when a policy is built.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.planners.base import Knowledge, Planner

INSTALL_HINT = 'pip install "srpb-gym[train]"'
ALGORITHMS: tuple[str, ...] = ("PPO", "A2C", "SAC", "TD3", "DDPG")


def import_sb3() -> Any:
    """The ``stable_baselines3`` module; ``ImportError`` naming the ``train`` extra if absent."""
    try:
        import stable_baselines3
    except ImportError as err:
        raise ImportError(
            f"learned policies need stable-baselines3 and torch: {INSTALL_HINT}"
        ) from err
    return stable_baselines3


def algorithm_class(algo: str) -> Any:
    """The stable-baselines3 algorithm class named ``algo`` (case-insensitive)."""
    name = algo.upper()
    if name not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of: {', '.join(ALGORITHMS)}")
    return getattr(import_sb3(), name)


def find_vecnormalize(path: str | os.PathLike[str]) -> str | None:
    """The observation-normalisation file beside a model: ``<stem>_vecnormalize.pkl``, else
    ``vecnormalize.pkl`` in the same folder, else ``None``."""
    model = Path(path)
    for candidate in (model.with_name(f"{model.stem}_vecnormalize.pkl"),
                      model.with_name("vecnormalize.pkl")):  # fmt: skip
        if candidate.is_file():
            return str(candidate)
    return None


def load_vecnormalize(path: str | os.PathLike[str]) -> Any:
    """The ``VecNormalize`` object saved at ``path`` (without its environment).

    Raises ``ValueError`` when the file holds something else.
    """
    import_sb3()
    from stable_baselines3.common.vec_env import VecNormalize

    with open(path, "rb") as f:
        obj = pickle.load(f)  # the user's own training artefact
    if not isinstance(obj, VecNormalize):
        raise ValueError(f"{os.fspath(path)}: not a VecNormalize file ({type(obj).__name__})")
    obj.training = False
    return obj


class LearnedPolicy(Planner):
    """A stable-baselines3 model acting on the environment's observation.

    ``path``: the model ``.zip``; ``algo``: its algorithm (see :data:`ALGORITHMS`);
    ``vecnormalize``: a ``VecNormalize`` file, ``"auto"`` (default) to look beside the model
    (:func:`find_vecnormalize`) or ``None`` for raw observations; ``deterministic``: take
    the mode of the action distribution. The :class:`Knowledge` snapshot is not used.
    """

    name = "learned"

    def __init__(
        self,
        path: str | os.PathLike[str],
        algo: str = "PPO",
        vecnormalize: str | os.PathLike[str] | None = "auto",
        deterministic: bool = True,
    ) -> None:
        self.path = os.fspath(path)
        self.algo = algo.upper()
        self.deterministic = deterministic
        self.model = algorithm_class(self.algo).load(self.path, device="cpu")
        if vecnormalize == "auto":
            vecnormalize = find_vecnormalize(self.path)
        self.vecnormalize = None if vecnormalize is None else os.fspath(vecnormalize)
        self._normalizer = None if vecnormalize is None else load_vecnormalize(vecnormalize)

    def check_spaces(self, observation_space: Any, action_space: Any) -> None:
        """Raise ``ValueError`` unless the model was trained on these spaces' shapes."""
        pairs = (("observation", self.model.observation_space, observation_space),
                 ("action", self.model.action_space, action_space))  # fmt: skip
        for what, trained, given in pairs:
            if type(trained) is not type(given) or _shape(trained) != _shape(given):
                raise ValueError(
                    f"{self.path}: trained for the {what} space {trained}, "
                    f"the environment has {given}"
                )

    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        if self._normalizer is not None:
            observation = self._normalizer.normalize_obs(observation)
        action, _ = self.model.predict(observation, deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float32)


def _shape(space: Any) -> Any:
    """A comparable shape of a gymnasium space (keys and shapes for a ``Dict``)."""
    spaces = getattr(space, "spaces", None)
    if isinstance(spaces, dict):
        return tuple((key, _shape(sub)) for key, sub in sorted(spaces.items()))
    return getattr(space, "shape", None)
