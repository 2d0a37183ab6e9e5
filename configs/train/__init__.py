"""PPO hyperparameters of srpb-gym by environment id, packaged as ``srpb_gym.train_configs``."""
