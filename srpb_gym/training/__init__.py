"""Training learned planners on srpb-gym environments with stable-baselines3 PPO.

``srpb-gym train --env SRPB-Crowd-v0 --reward srpb`` (or ``python -m training.train``)
resolves the hyperparameters of :mod:`srpb_gym.training.config` (``configs/train/ppo.yaml``,
keyed by environment id in the RL Zoo style), checks them (:mod:`srpb_gym.training.checks`),
trains in the phases of :mod:`srpb_gym.training.run` (set up, learn, save) with the
callbacks of :mod:`srpb_gym.training.callbacks` (TensorBoard reward terms and SRPB metrics,
a progress bar, periodic evaluation through the ``srpb-gym eval`` harness on what
:mod:`srpb_gym.training.targets` names), optionally after a warm start from
demonstrations (:mod:`srpb_gym.training.pretrain`), and writes a run folder
(:mod:`srpb_gym.training.run_folder`). :mod:`srpb_gym.training.shared_policy` trains one
policy for every robot of the multi-robot environment. The shipped models, and finding and
loading any model file, are :mod:`srpb_gym.models`'.

:mod:`srpb_gym.training.config`, :mod:`srpb_gym.training.targets`,
:mod:`srpb_gym.training.checks` and :mod:`srpb_gym.training.run_folder` import without
stable-baselines3 and torch (the ``train`` extra).
"""
