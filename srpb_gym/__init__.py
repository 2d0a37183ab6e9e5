"""srpb-gym: human-aware robot navigation environments scored by the SRPB metrics.

Importing the package registers the Gymnasium ids ``SRPB-Corridor-v0``,
``SRPB-FFormation-v0``, ``SRPB-Crossing-v0``, ``SRPB-Crowd-v0``, ``SRPB-Doorway-v0`` and
``SRPB-Custom-v0`` (``gym.make("SRPB-Custom-v0", scenario="my_lab.yaml")``).
"""

__version__ = "0.1.0"

from srpb_gym.registration import register_envs

register_envs()
