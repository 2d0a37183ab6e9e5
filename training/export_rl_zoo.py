"""Write configs/train/rl_zoo/ppo.yml: the hyperparameters of configs/train/ppo.yaml in the
format of the RL Baselines3 Zoo, so that

    python -m rl_zoo3.train --algo ppo --env SRPB-Corridor-v0 --gym-packages srpb_gym \\
        --conf-file configs/train/rl_zoo/ppo.yml --vec-env subproc

trains with the same settings (the Zoo has no periodic SRPB evaluation; its own
``--eval-freq`` evaluates the mean reward). A test checks that the shipped file equals what
this script writes.

    python -m training.export_rl_zoo            # rewrite the file
    python -m training.export_rl_zoo --check    # exit 1 if it differs
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from srpb_gym.training.config import rl_zoo_document

TARGET = Path(__file__).resolve().parents[1] / "configs" / "train" / "rl_zoo" / "ppo.yml"


def main() -> int:
    parser = argparse.ArgumentParser(description="export the RL Zoo hyperparameter file")
    parser.add_argument("--check", action="store_true", help="only check the shipped file")
    args = parser.parse_args()
    text = rl_zoo_document()
    if args.check:
        same = TARGET.is_file() and TARGET.read_text(encoding="utf-8") == text
        print(
            f"{TARGET}: {'up to date' if same else 'differs; run python -m training.export_rl_zoo'}"
        )
        return 0 if same else 1
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
