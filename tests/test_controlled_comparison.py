"""scripts/controlled_comparison.py: pairs checked, effects and intervals by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from scripts import controlled_comparison as cc
from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult


def episode(planner: str, seed: int, success: bool, psi: float, robot: int | None = None,
            back: float = 0.0) -> EpisodeResult:  # fmt: skip
    metrics = {"m_psi": psi + 1.0, "m_fsi": 0.0, "m_dir": 0.0}  # tracked: another value
    truth = {"m_psi": psi, "m_fsi": 0.0, "m_dir": 0.0}
    return EpisodeResult(env="SRPB-Crowd-v0", planner=planner, seed=seed, is_success=success,
                         collision=not success, timeout=False, metrics=metrics,
                         ground_truth=truth, robot=robot, pushed_back=back)  # fmt: skip


def test_effects_by_hand():
    # two training seeds per recipe, four episodes; B halves A's ground-truth m_psi
    psi_a = {"a0": [10, 20, 30, 40], "a1": [30, 20, 10, 0]}
    psi_b = {"b0": [5, 10, 15, 20], "b1": [15, 10, 5, 0]}
    results = []
    for label, psi in {**psi_a, **psi_b}.items():
        for seed, value in enumerate(psi):
            results.append(episode(label, 100 + seed, success=not (label == "b1" and seed == 0),
                                   psi=float(value), back=0.5 * value))  # fmt: skip
    report = cc.analyse(results, ["a0", "a1"], ["b0", "b1"], [], ("task", "srpb"))
    pooled = report["pooled"]
    # episode means over the seeds: A 20, 20, 20, 20; B 10, 10, 10, 10
    assert pooled["m_psi"]["a"] == 20.0 and pooled["m_psi"]["b"] == 10.0
    assert pooled["m_psi"]["effect"] == pytest.approx(-50.0)
    # success: B failed one of 8 seed-episodes: mean over episodes 7/8 against 1
    assert pooled["success"]["effect"] == pytest.approx(-12.5)
    assert pooled["success"]["ci"][0] <= -12.5 <= pooled["success"]["ci"][1]
    first = report["pairs"][0]
    assert first["m_psi_gt"]["effect"] == pytest.approx(-50.0)
    assert first["success"] == 0.0 and first["p_success"] == 1.0
    assert report["pairs"][1]["success"] == pytest.approx(-25.0)
    row = report["runs"][0]
    assert row["m_psi_gt_mean"] == 25.0 and row["m_psi_tracked_median"] == 26.0
    assert row["pushed_back"] == 100.0  # a0 pushed walkers back 5, 10, 15 and 20 m
    assert report["runs"][1]["pushed_back"] == 75.0  # a1: 15, 10, 5 and 0 m
    text = cc.markdown(report)
    assert "| -50.0 %" in text and "| 75.0 % |" in text
    # no O-space in these episodes: no relative change of m_fsi to report
    assert np.isnan(pooled["m_fsi"]["effect"]) and "| mean GT m_fsi | 0 | 0 | n/a | n/a |" in text


def test_every_pair_must_be_evaluated_on_the_same_episodes():
    results = [episode("a", 1, True, 1.0), episode("b", 2, True, 1.0)]
    with pytest.raises(InputError, match="b: not every episode"):
        cc.analyse(results, ["a"], ["b"], [], ("A", "B"))


def write_run(folder, seed=0, lr=1e-4, reward="task"):
    folder.mkdir()
    config = {"env": "SRPB-Crowd-v0", "seed": seed, "reward": reward,
              "hyperparams": {"learning_rate": lr}}  # fmt: skip
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    return folder


def test_pairs_differ_only_where_allowed(tmp_path):
    a = write_run(tmp_path / "a")
    b = write_run(tmp_path / "b", reward="srpb")
    notes = cc.check_pairs([a], [b])
    assert "differ in reward" in notes[0] and "'task' | 'srpb'" in notes[1]
    with pytest.raises(InputError, match="differ in seed"):
        cc.check_pairs([a], [write_run(tmp_path / "c", seed=1)])
    with pytest.raises(InputError, match="differ in hyperparams"):
        cc.check_pairs([a], [write_run(tmp_path / "d", lr=3e-4)])
    with pytest.raises(InputError, match="as many runs"):
        cc.check_pairs([a], [b, b])
    with pytest.raises(InputError, match="not a srpb-gym train run"):
        cc.check_pairs([a], [tmp_path])
    assert np.isnan(cc.relative_change(np.zeros(3), np.ones(3)))


def test_a_shipped_model_stands_for_its_run(tmp_path):
    from srpb_gym.models import card

    name = "ppo-fformation-task"
    config = cc.run_config(Path(name))
    assert config == {key: card(name)[key] for key in cc.CARD_KEYS if key in card(name)}
    assert config["seed"] == 0 and config["env"] == "SRPB-FFormation-v0"
    model, note = cc.checkpoint_of(Path(name), "best")  # its card: the best checkpoint
    assert Path(model).name == name and (Path(model) / "model.zip").is_file() and note is None
    model, note = cc.checkpoint_of(Path(name), "final")
    assert note == f"{name}: the shipped model is its run's {config['checkpoint']} checkpoint"
    run = write_run(tmp_path / "a", reward="task")
    assert cc.checkpoint_of(run, "best") == (str(run / "best"), None)
    # a shipped model is paired as its run is: by seed, environment and hyperparameters
    with pytest.raises(InputError, match="differ in"):
        cc.check_pairs([Path(name)], [run])


def test_several_robots_are_compared_by_episode():
    # 2 robots, 3 episodes; robot-episode m_psi of A and B (B: 0 where robot 1 failed)
    psi = {"a": [[10, 30], [20, 20], [6, 2]], "b": [[5, 15], [10, float("nan")], [3, 1]]}
    failed = {("b", 1, 1)}  # B's robot 1 fails in the second episode
    results = []
    for label, rows in psi.items():  # shuffled order: sorted by (seed, robot)
        for seed, pair in reversed(list(enumerate(rows))):
            for robot, value in enumerate(pair):
                ok = (label, seed, robot) not in failed
                results.append(episode(label, 7 + seed, ok, value, robot=robot))
    report = cc.analyse(results, ["a"], ["b"], [], ("task", "srpb"), robots=2)
    assert report["episodes"] == 3 and report["robots"] == 2 and report["seeds"] == [7, 9]
    # episode means: A 20, 20, 4; B 10, 10 (robot 1's NaN left out), 2
    psi_effect = report["pairs"][0]["m_psi_gt"]
    assert psi_effect["a"] == pytest.approx(44 / 3) and psi_effect["b"] == pytest.approx(22 / 3)
    assert psi_effect["effect"] == pytest.approx(-50.0) and psi_effect["n"] == 3
    # success: 6/6 against 5/6 robot-episodes; by episode 1, 0.5, 1 against 1, 1, 1
    b_row = report["runs"][1]
    assert b_row["episodes"] == 6 and b_row["success"] == pytest.approx(500 / 6)
    assert b_row["success_by_robot"] == [100.0, pytest.approx(200 / 3)]
    assert report["pairs"][0]["success"] == pytest.approx(-100 / 6)
    assert report["pooled"]["success"]["effect"] == pytest.approx(-100 / 6)
    # each robot's success pooled apart: robot 0 the same, robot 1 a third lower
    robot0, robot1 = report["pooled"]["success of robot 0"], report["pooled"]["success of robot 1"]
    assert (robot0["a"], robot0["b"], robot0["effect"]) == (1.0, 1.0, 0.0)
    assert robot1["b"] == pytest.approx(2 / 3) and robot1["effect"] == pytest.approx(-100 / 3)
    assert robot1["n"] == 3 and robot1["ci"][0] <= robot1["effect"] <= robot1["ci"][1]
    text = cc.markdown(report)
    assert "3 episodes of 2 robots" in text and "| 100 / 67 |" in text and "Wilcoxon p |" in text
    assert "| success of robot 1 | 100 | 66.7 | -33.3 pt |" in text
    # one robot missing from an episode: refused
    with pytest.raises(InputError, match="b: not every episode"):
        cc.analyse(results[:-1], ["a"], ["b"], [], ("task", "srpb"), robots=2)


def test_a_multi_robot_run_and_a_shipped_policy_for_several_robots(tmp_path):
    import json

    from srpb_gym.models import card

    name = "ppo-crowd-srpb-3robots"
    shipped = card(name)
    run = tmp_path / "multi"
    run.mkdir()
    info = {"scenario": "crowd", "robots": 3, "seed": 0, "reward": "task", "envs": 2,
            "hyperparams": shipped["hyperparams"], "env_kwargs": {}}  # fmt: skip
    (run / "run.json").write_text(json.dumps(info))
    config = cc.run_config(run)
    assert config["env"] == "SRPB-Crowd-v0" and config["robots"] == 3
    assert "envs" not in config  # the comparison reads only what it pairs and prints
    # a multi-robot run without a selection: its final model
    assert cc.checkpoint_of(run, "final") == (str(run / "model.zip"), None)
    model, note = cc.checkpoint_of(run, "best")
    assert model == str(run / "model.zip") and "no selection.json, its final model" in note
    # with one, the checkpoint it chose stands for best/
    chosen = run / "checkpoints" / "step_000000400"
    chosen.mkdir(parents=True)
    (chosen / "model.zip").write_bytes(b"")
    (run / "selection.json").write_text(json.dumps({"chosen": chosen.name}))
    assert cc.checkpoint_of(run, "best") == (str(chosen), None)
    assert cc.checkpoint_of(run, "final") == (str(run / "model.zip"), None)
    # the report names a kept checkpoint by its run, other models by their labels
    assert cc.run_label(run, str(chosen)) == "multi (step_000000400)"
    assert cc.run_label(run, str(run / "model.zip")) is None
    report = {"runs": [{"label": "step_000000400"}, {"label": "dwa"}],
              "pairs": [{"a": "x", "b": "step_000000400"}]}  # fmt: skip
    cc.relabel(report, {"step_000000400": "multi (step_000000400)"})
    assert [r["label"] for r in report["runs"]] == ["multi (step_000000400)", "dwa"]
    assert report["pairs"] == [{"a": "x", "b": "multi (step_000000400)"}]
    (run / "selection.json").unlink()
    notes = cc.check_pairs([run], [Path(name)])
    assert "differ in" in notes[0] and "reward" in notes[0]
    info["robots"] = 2
    (run / "run.json").write_text(json.dumps(info))
    with pytest.raises(InputError, match="differ in robots"):
        cc.check_pairs([run], [Path(name)])
