"""srpb-gym: human-aware robot navigation environments scored by the SRPB metrics.

Importing the package registers the Gymnasium ids ``SRPB-Corridor-v0``,
``SRPB-FFormation-v0``, ``SRPB-Crossing-v0``, ``SRPB-Crowd-v0``, ``SRPB-Doorway-v0``,
``SRPB-Mix-v0`` (one scenario drawn per reset: ``gym.make("SRPB-Mix-v0",
scenarios=["corridor", "crowd"], weights=[1, 3])``) and ``SRPB-Custom-v0``
(``gym.make("SRPB-Custom-v0", scenario="my_lab.yaml")``).
``srpb_gym.parallel_env(scenario="crowd", n_robots=3)`` makes the PettingZoo multi-robot
environment (:mod:`srpb_gym.pettingzoo_env`; ``srpb_gym.aec_env(...)`` its AEC version).
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

from srpb_gym._version import __version__
from srpb_gym.registration import register_envs

__all__ = ["__version__", "aec_env", "parallel_env"]

register_envs()


def parallel_env(**kwargs: Any) -> Any:
    """The PettingZoo ``ParallelEnv`` of several robots (arguments: the environment's
    arguments of ``gym.make``, plus ``n_robots`` and an optional step limit ``max_steps``;
    see :class:`srpb_gym.pettingzoo_env.SRPBParallelEnv`)."""
    return _pettingzoo().parallel_env(**kwargs)


def aec_env(**kwargs: Any) -> Any:
    """The PettingZoo AEC version of :func:`parallel_env` (order enforced)."""
    return _pettingzoo().env(**kwargs)


def _pettingzoo() -> ModuleType:
    # deferred: `import srpb_gym` registers the ids without loading the simulation (about
    # 4 s of compiled kernels) or PettingZoo
    from srpb_gym import pettingzoo_env

    return pettingzoo_env
