"""Trained models: the shipped ones, loadable by their short names, and every model file.

Each shipped model is a folder ``srpb_gym/models/<name>/`` holding ``model.zip`` (a
stable-baselines3 PPO model), ``vecnormalize.npz`` (its observation statistics, numbers),
``card.md`` (its model card: environment id and version, reward preset and the weights
of each scenario, steps, wall time, machine, seed, command, results) and ``card.json``
(the same facts as data). Names follow ``ppo-<scenario>-<preset>``, e.g.
``ppo-corridor-srpb`` (``ppo-mix-srpb`` for a model trained on ``SRPB-Mix-v0``).
:func:`model_names` lists those shipped.

``srpb-gym eval --policy ppo-corridor-srpb`` takes a short name wherever it takes a model
file, and so do ``srpb-gym train --init`` and the teachers of a warm start. Loading a
model needs the ``train`` extra (stable-baselines3 and torch); listing and finding do not.

The modules, each importable without stable-baselines3 and torch:

* :mod:`srpb_gym.models.shipped`: the shipped models (:func:`model_names`,
  :func:`model_path`, :func:`card`);
* :mod:`srpb_gym.models.files`: the files a name, path or run folder names
  (:func:`find_model`, :func:`resolve_model`) and their normalisation statistics
  (:func:`find_vecnormalize`);
* :mod:`srpb_gym.models.loading`: loading a model (:func:`load_model`) and the errors of
  loading; a model file's pickles are never unpickled unless trusted
  (:mod:`srpb_gym.models.safe_data`: its saved attributes decoded as data only; its
  tensors read with ``weights_only=True``);
* :mod:`srpb_gym.models.normalization`: the normalisation statistics as numbers
  (``vecnormalize.npz``: :func:`load_vecnormalize`, :func:`save_vecnormalize`), a pickled
  ``vecnormalize.pkl`` read only when trusted (``--trust-pickle``);
* :mod:`srpb_gym.models.record`: the observation settings a model was trained with
  (:data:`OBSERVATION_RECORD`);
* :mod:`srpb_gym.models.forward`: the fixed-order forward pass of a PPO or A2C
  ``MlpPolicy`` (:func:`fixed_order_policy`), whose actions are the same on every CPU.
"""

from __future__ import annotations

from srpb_gym.models.files import (
    VECNORMALIZE,
    VECNORMALIZE_PICKLE,
    find_model,
    find_vecnormalize,
    resolve_model,
    stray_vecnormalize,
    vecnormalize_candidates,
)
from srpb_gym.models.forward import FixedOrderPolicy, UnsupportedPolicyError, fixed_order_policy
from srpb_gym.models.loading import (
    ALGORITHMS,
    PolicyFileError,
    VecNormalizeError,
    detect_algorithm,
    global_rngs_kept,
    load_model,
    model_data,
    model_steps,
)
from srpb_gym.models.normalization import (
    Normalization,
    convert_vecnormalize,
    load_vecnormalize,
    save_vecnormalize,
)
from srpb_gym.models.record import (
    OBSERVATION_RECORD,
    describe_space,
    lidar_beams_of,
    observation_config_of,
    observation_mismatch,
    read_record,
    record_observation,
    recorded_observation,
    settings_mismatch,
    settings_text,
    spaces_differ,
    stamp_observation,
)
from srpb_gym.models.shipped import MODEL_FILE, card, model_names, model_path

__all__ = ["ALGORITHMS", "MODEL_FILE", "OBSERVATION_RECORD", "VECNORMALIZE",
           "VECNORMALIZE_PICKLE", "FixedOrderPolicy", "Normalization", "PolicyFileError",
           "UnsupportedPolicyError", "VecNormalizeError", "card", "convert_vecnormalize",
           "describe_space", "detect_algorithm", "find_model", "find_vecnormalize",
           "fixed_order_policy", "global_rngs_kept", "lidar_beams_of", "load_model",
           "load_vecnormalize", "model_data", "model_names", "model_path", "model_steps",
           "observation_config_of", "observation_mismatch", "read_record",
           "record_observation", "recorded_observation", "resolve_model",
           "save_vecnormalize", "settings_mismatch", "settings_text", "spaces_differ",
           "stamp_observation", "stray_vecnormalize", "vecnormalize_candidates"]  # fmt: skip
