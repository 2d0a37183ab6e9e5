"""Packaged scenario files (YAML), installed as ``srpb_gym.envs_data``; see README.md."""
