"""Training learned planners on srpb-gym environments with stable-baselines3 PPO.

``srpb-gym train --env SRPB-Crowd-v0 --reward srpb`` (or ``python -m training.train``)
resolves the hyperparameters of :mod:`srpb_gym.training.config` (``configs/train/ppo.yaml``,
keyed by environment id in the RL Zoo style), trains with the callbacks of
:mod:`srpb_gym.training.callbacks` (TensorBoard reward terms and SRPB metrics, a progress
bar, periodic evaluation through the ``srpb-gym eval`` harness) and writes a run folder
(:mod:`srpb_gym.training.run`). :mod:`srpb_gym.training.models` lists the shipped models.

Only :mod:`srpb_gym.training.config` and :mod:`srpb_gym.training.models` import without
stable-baselines3 and torch (the ``train`` extra).
"""
