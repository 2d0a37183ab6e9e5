"""Train PPO on an srpb-gym environment: the same command as ``srpb-gym train``.

    python -m training.train --env SRPB-Crowd-v0 --reward srpb --seed 0 --out runs/ppo-crowd
    python -m training.train --env SRPB-Corridor-v0 --reward task --steps 200000 \\
        --hyperparams n_steps=1024 "net_arch=[128, 128]"

Hyperparameters come from configs/train/ppo.yaml (keyed by environment id, RL Zoo style);
see ``srpb-gym train --help`` and srpb_gym/training/run.py for the run folder.
"""

from __future__ import annotations

import sys

from srpb_gym.cli import main

if __name__ == "__main__":
    sys.exit(main(["train", *sys.argv[1:]]))
