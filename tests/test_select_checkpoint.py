"""Choosing a multi-robot run's checkpoint on checkpoint-selection seeds, and shipping it."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from srpb_gym.errors import InputError  # noqa: E402
from srpb_gym.evaluation.stats import read_episodes  # noqa: E402
from srpb_gym.training.run_folder import FINAL, read_selection  # noqa: E402
from training import multi_robot, select_checkpoint, ship_multi  # noqa: E402
from training.select_checkpoint import score  # noqa: E402


def figures(by_robot: list[float], psi: float = 5.0) -> dict:
    return {"success_by_robot": by_robot, "success": sum(by_robot) / len(by_robot),
            "gt_m_psi": psi}  # fmt: skip


def test_the_weakest_robot_decides_first_then_every_robot_then_the_distance_kept():
    # 96 / 100 / 88 beats 100 / 100 / 86: robot 2 is served better, though on average worse
    assert score(figures([0.96, 1.0, 0.88])) > score(figures([1.0, 1.0, 0.86]))
    # the same weakest robot: the higher success over every robot
    assert score(figures([0.9, 1.0, 0.9])) > score(figures([0.9, 0.9, 0.9], psi=1.0))
    # the same successes: the lower median m_psi from the true people
    assert score(figures([0.9, 0.9], psi=4.0)) > score(figures([0.9, 0.9], psi=6.0))
    # no median (no person ever near): the worst at equal success
    assert score(figures([0.9, 0.9], psi=math.nan)) < score(figures([0.9, 0.9], psi=60.0))


@pytest.fixture(scope="module")
def kept_run(tmp_path_factory) -> Path:
    """A 2-robot corridor run that kept 2 checkpoints (the last one at the final step)."""
    out = tmp_path_factory.mktemp("select") / "run"
    assert multi_robot.main(["--scenario", "corridor", "--robots", "2", "--envs", "1",
                             "--steps", "64", "--reward", "task", "--hyperparams",
                             "n_steps=256", "batch_size=64", "--save-every", "256",
                             "--keep-checkpoints", "--out", str(out)]) == 0  # fmt: skip
    return out


def test_every_checkpoint_is_evaluated_and_the_best_by_the_rule_is_chosen(kept_run, capsys):
    assert select_checkpoint.main([str(kept_run), "--episodes", "2", "--seed", "1000000"]) == 0
    printed = capsys.readouterr().out
    selection = json.loads((kept_run / "selection.json").read_text())
    table = selection["candidates"]
    assert list(table) == ["step_000000256", "step_000000512", FINAL]
    assert [f["steps"] for f in table.values()] == [256, 512, 512]
    assert selection["chosen"] == max(table, key=lambda name: score(table[name]))
    assert f"chosen: {selection['chosen']} (the highest success of the least" in printed
    # the figures are those of the episodes evaluated, on the selection seeds
    rows = read_episodes(str(kept_run / "selection" / "episodes.csv"))
    assert not (kept_run / "selection" / "episodes").exists()  # the records are let go
    assert {r.seed for r in rows} == {1_000_000, 1_000_001}
    for name, f in table.items():
        label = kept_run.name if name == FINAL else name
        mine = [r for r in rows if r.planner == label]
        assert len(mine) == 2 * 2 and f["episodes"] == 4  # 2 episodes of 2 robots
        assert f == {"steps": f["steps"], **select_checkpoint.figures(mine)}


def test_ship_takes_the_chosen_checkpoint_and_says_how_it_was_chosen(kept_run, tmp_path,
                                                                     monkeypatch):  # fmt: skip
    if not (kept_run / "selection.json").is_file():
        select_checkpoint.select(kept_run, episodes=2)
    selection = json.loads((kept_run / "selection.json").read_text())
    selection["chosen"] = "step_000000256"  # an earlier one than the final model
    (kept_run / "selection.json").write_text(json.dumps(selection))
    monkeypatch.setattr(ship_multi, "MODELS_DIR", tmp_path / "models")
    name = "ppo-corridor-task-2robots"
    card = ship_multi.ship(kept_run, name, episodes=1, seed=7, baselines=[])
    target = tmp_path / "models" / name
    first = kept_run / "checkpoints" / "step_000000256"
    for file in ("model.zip", "vecnormalize.npz"):
        assert (target / file).read_bytes() == (first / file).read_bytes()
    assert card["checkpoint"] == "step_000000256" and card["selection"] == selection
    assert (card["training"]["steps"], card["training"]["run_steps"]) == (256, 512)
    text = (target / "card.md").read_text()
    assert "| checkpoint | step_000000256, one of 3 candidates, chosen on 2 episodes" in text
    assert "| 256 robot-steps (1 environment of 2 robots), of the run's 512 |" in text
    assert "## Checkpoint selection" in text and "| **step_000000256** | 256 |" in text
    several = {**card, "test": {**card["test"], "candidates": 3}}
    assert "was chosen on validation and checkpoint-selection seeds." in (
        ship_multi.card_markdown(name, several))  # fmt: skip
    several["selection"] = None
    assert "was chosen on validation seeds." in ship_multi.card_markdown(name, several)
    # --final ships the last model whatever was chosen
    card = ship_multi.ship(kept_run, name, episodes=1, seed=7, baselines=[], final=True)
    assert card["checkpoint"] == FINAL and card["selection"] is None
    assert (target / "model.zip").read_bytes() == (kept_run / "model.zip").read_bytes()
    assert "## Checkpoint selection" not in (target / "card.md").read_text()


def test_what_cannot_be_chosen_from_is_refused(kept_run, tmp_path, capsys):
    bare = tmp_path / "bare"
    multi_robot.main(["--scenario", "corridor", "--robots", "2", "--envs", "1", "--steps",
                      "64", "--hyperparams", "n_steps=64", "batch_size=64", "--out",
                      str(bare)])  # fmt: skip
    assert select_checkpoint.main([str(bare), "--episodes", "1"]) == 2
    assert "no kept checkpoints (checkpoints/step_<N>/): train with --save-every N " \
        "--keep-checkpoints" in capsys.readouterr().err  # fmt: skip
    # seeds that are not checkpoint-selection seeds (validation, test) choose nothing
    for seed in ("3000000", "20000000", "999999"):
        assert select_checkpoint.main([str(kept_run), "--episodes", "2", "--seed", seed]) == 2
        assert "--seed: seeds " in capsys.readouterr().err
    # a selection naming a checkpoint that is gone
    (bare / "selection.json").write_text(json.dumps({"chosen": "step_000000999"}))
    with pytest.raises(InputError, match="the chosen candidate 'step_000000999' has no"):
        read_selection(bare)
    (bare / "selection.json").write_text("[1, 2]")
    with pytest.raises(InputError, match=r"not a selection of training\.select_checkpoint"):
        read_selection(bare)
