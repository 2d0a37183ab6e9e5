"""Learning curves of the shipped models: success rate, collision rate and median m_psi of
the periodic evaluations against training steps, both reward presets in one figure per
scenario.

    python -m training.plot_curves                 # every scenario with shipped models
    python -m training.plot_curves --out docs/figures

Reads ``srpb_gym/models/ppo-<scenario>-<preset>/evaluations.csv`` (a run folder's
``evaluations.csv`` is the same file) and writes ``learning_<scenario>.png``. A model that
started from another trained model (its card's ``training.init``) is drawn from the steps
that model had taken, so that a fine-tuning continues the curve it started from.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

from srpb_gym.evaluation.figures import pyplot

MODELS_DIR = Path(__file__).resolve().parents[1] / "srpb_gym" / "models"
PANELS = (("success", "success rate [%]", 100.0), ("collision", "collision rate [%]", 100.0),
          ("m_psi", "median m_psi [%]", 1.0))  # fmt: skip


def read_curve(path: Path) -> dict[str, list[float]]:
    """Steps and each panel's values, averaged over the evaluated environments per step."""
    by_step: dict[int, list[dict[str, str]]] = {}
    with open(path, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            by_step.setdefault(int(row["step"]), []).append(row)
    out: dict[str, list[float]] = {"step": sorted(by_step)}
    for key, _, scale in PANELS:
        out[key] = []
        for step in out["step"]:
            values = [float(r[key]) for r in by_step[step] if r[key] != ""]
            out[key].append(scale * sum(values) / len(values) if values else float("nan"))
    return out


def start(folder: Path) -> tuple[int, str | None]:
    """The steps of the model a shipped model started from (0: random weights) and that
    model's name: its folder's (``ppo-crowd-task``), or the run's for a run's ``best/``."""
    card = folder / "card.json"
    if not card.is_file():
        return 0, None
    init = json.loads(card.read_text(encoding="utf-8")).get("training", {}).get("init")
    if not init:
        return 0, None
    model = Path(init["model"]).parent
    name = f"{model.parent.name}/{model.name}" if model.name == "best" else model.name
    return int(init["steps"]), name


def plot(scenario: str, curves: dict[str, dict[str, Any]], out: Path) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, len(PANELS), figsize=(12, 3.2), constrained_layout=True)
    for ax, (key, label, _) in zip(axes, PANELS):
        for _, curve in sorted(curves.items()):
            ax.plot(curve["step"], curve[key], marker="o", markersize=3, label=curve["label"])
        ax.set_xlabel("training steps [millions]")
        ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1e6:g}")
        if key in ("success", "collision"):
            ax.set_ylim(-3, 103)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(title="reward preset")
    fig.suptitle(f"PPO on {scenario}: periodic evaluations on seeds never trained on")
    path = out / f"learning_{scenario}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", type=Path, default=MODELS_DIR)
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    curves: dict[str, dict[str, dict[str, Any]]] = {}
    for folder in sorted(args.models.glob("ppo-*-*")):
        _, scenario, preset = folder.name.split("-", 2)
        if (folder / "evaluations.csv").is_file():
            curve: dict[str, Any] = read_curve(folder / "evaluations.csv")
            offset, origin = start(folder)
            curve["step"] = [offset + step for step in curve["step"]]
            curve["label"] = preset if origin is None else f"{preset} (from {origin})"
            curves.setdefault(scenario, {})[preset] = curve
    args.out.mkdir(parents=True, exist_ok=True)
    for scenario, by_preset in curves.items():
        print(f"wrote {plot(scenario, by_preset, args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
