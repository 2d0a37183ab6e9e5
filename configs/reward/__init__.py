"""Reward-weight presets of srpb-gym, packaged as ``srpb_gym.reward_presets``."""
