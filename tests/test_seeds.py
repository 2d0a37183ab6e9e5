"""The seed protocol (srpb_gym/seeds.py): ranges apart from each other, everything that
chooses refuses the test seeds, and a shipped model's card says how to reproduce its test
figures on them."""

from __future__ import annotations

import itertools
import json
import shlex
import sys

import pytest

from srpb_gym import seeds
from srpb_gym.errors import InputError
from srpb_gym.seeds import (
    CHECKPOINT_SELECTION,
    DEMONSTRATIONS,
    RETIRED_TEST,
    TEST,
    TRAINING,
    VALIDATION,
    check_not_test,
)

USES = (TRAINING, CHECKPOINT_SELECTION, DEMONSTRATIONS, VALIDATION, TEST)


def test_the_ranges_do_not_overlap_and_the_test_range_is_far_from_all():
    for a, b in itertools.combinations(USES, 2):
        assert not a.overlaps(b.start, b.size), (a, b)
    assert TEST.start - max(r.stop for r in USES if r is not TEST) >= 10_000_000
    # the retired test seeds: in no held-out range (they lie among the training seeds)
    assert all(not r.overlaps(RETIRED_TEST.start, RETIRED_TEST.size) for r in USES[1:])
    assert (RETIRED_TEST.start, RETIRED_TEST.stop) == (10_000, 11_000)
    assert seeds.range_of(10_050) is RETIRED_TEST and seeds.range_of(20_000_099) is TEST
    assert seeds.range_of(5_000_000) is None


def test_the_old_names_are_the_protocol_s_constants():
    pytest.importorskip("stable_baselines3")
    from srpb_gym.training.callbacks import EVAL_SEED
    from srpb_gym.training.config import DEMO_EPISODES_MAX
    from srpb_gym.training.pretrain import DEMO_SEED
    from training import ship

    assert (CHECKPOINT_SELECTION.start, DEMONSTRATIONS.start) == (EVAL_SEED, DEMO_SEED)
    assert (VALIDATION.start, TEST.start) == (ship.VALIDATION_SEED, ship.TEST_SEED)
    assert (DEMONSTRATIONS.stop,) == (DEMO_SEED + DEMO_EPISODES_MAX,)


def test_check_not_test_names_the_option_in_one_line():
    check_not_test(VALIDATION.start, 100, "--x")
    check_not_test(TEST.start - 100, 100, "--x")  # up to the last seed before
    with pytest.raises(InputError) as err:
        check_not_test(TEST.start - 99, 100, "--validation-seed")
    text = str(err.value)
    assert text.startswith("--validation-seed: seeds 19999901-20000000 meet the test seeds")
    assert "\n" not in text


def test_periodic_evaluation_refuses_test_seeds(tmp_path):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.training.callbacks import PeriodicEvalCallback

    with pytest.raises(InputError, match=r"^periodic evaluation seed: seeds 20000000-20000019 "
                       r"meet the test seeds"):  # fmt: skip
        PeriodicEvalCallback(str(tmp_path), ["SRPB-Corridor-v0"], 100, 20, seed=TEST.start)
    with pytest.raises(InputError, match=r"leave the checkpoint-selection seeds"):
        PeriodicEvalCallback(str(tmp_path), ["SRPB-Corridor-v0"], 100, 20, seed=VALIDATION.start)
    assert PeriodicEvalCallback(str(tmp_path), ["SRPB-Corridor-v0"], 100, 20).seed == 1_000_000


def test_demonstrations_refuse_test_seeds():
    pytest.importorskip("stable_baselines3")
    from srpb_gym.training.pretrain import collect

    with pytest.raises(InputError, match=r"^pretrain seed: seeds 20000000-20000001 meet the test"):
        collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 2, 0.0, seed=TEST.start)
    with pytest.raises(InputError, match=r"leave the demonstration seeds"):
        collect("SRPB-Corridor-v0", {"reward": "task"}, "go-to-goal", 2, 0.0, seed=0)


def test_training_seeds_stay_in_the_training_range(tmp_path):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.training.config import resolve
    from srpb_gym.training.run import set_up

    config = resolve("SRPB-Corridor-v0", {"n_envs": 2, "eval_freq": 0})
    with pytest.raises(InputError, match=r"^--seed: seeds 999999-1000000 leave the training"):
        set_up("SRPB-Corridor-v0", config, seed=999_999, out=str(tmp_path / "run"))
    assert not (tmp_path / "run").exists()


def test_ship_validation_refuses_test_seeds(tmp_path, monkeypatch, capsys):
    from training import ship

    run = tmp_path / "run"
    (run / "best").mkdir(parents=True)
    monkeypatch.setattr(ship, "evaluate", lambda *a, **k: pytest.fail("evaluated"))
    with pytest.raises(InputError, match=r"^--validation-seed: seeds 20000000-20000099 meet"):
        ship.choose(run, ["SRPB-Crowd-v0"], 100, seed=TEST.start)
    argv = ["ship", str(run), "--name", "x", "--candidates", "3", "--validate", "100",
            "--validation-seed", str(TEST.start + 50)]  # fmt: skip
    monkeypatch.setattr(sys, "argv", argv)
    with pytest.raises(SystemExit) as exc:
        ship.main()
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--validation-seed: seeds 20000050-20000149 meet the test" in err
    monkeypatch.setattr(sys, "argv", ["ship", str(run), "--name", "x"])
    with pytest.raises(SystemExit):
        ship.main()
    assert "--candidates N is required" in capsys.readouterr().err


def test_tuning_refuses_test_seeds(capsys):
    sys.path.insert(0, "scripts")
    try:
        import tune_planners
    finally:
        sys.path.remove("scripts")
    with pytest.raises(SystemExit):
        tune_planners.main(["--first-seed", str(TEST.start), "--seeds", "5"])
    assert "--first-seed: seeds 20000000-20000004 meet the test seeds" in capsys.readouterr().err


def _fake_run(run):
    """A run folder as srpb-gym train leaves it, with placeholder model files."""
    (run / "best").mkdir(parents=True)
    for folder in (run, run / "best"):
        (folder / "model.zip").write_text(f"model in {folder.name}")
        (folder / "vecnormalize.npz").write_text("statistics")
    (run / "config.yaml").write_text(
        "env: SRPB-Mix-v0\nreward: srpb\nseed: 0\nhyperparams: {eval_episodes: 20}\n"
        "env_kwargs: {weights: [1, 1, 3, 2, 3], reward_weights: {psi: -1.0}, "
        "observation: {lidar_encoding: log}}\n"
    )
    machine = {"cpu_count": 2, "processor": "x", "system": "y", "torch_threads": 1}
    info = {"steps": 1000, "wall_time_s": 60.0, "machine": machine,
            "versions": {"srpb-gym": "0"},
            "reward_weights": {"corridor": {"psi": -1.0}}}  # fmt: skip
    (run / "run.json").write_text(json.dumps(info))
    (run / "command.txt").write_text("srpb-gym train --env SRPB-Mix-v0\n")


def test_the_card_records_the_test_seeds_and_the_command_that_reproduces_them(
    tmp_path, monkeypatch
):
    from srpb_gym.cli import build_parser
    from srpb_gym.config import parse_overrides
    from training import ship

    seen = []

    def evaluate(
        model, env_ids, episodes, seed, out, env_kwargs=None, workers=1, trust_pickle=False
    ):
        seen.append((env_ids, episodes, seed, env_kwargs))
        return {env: {"success": 1.0, "collision": 0.0, "timeout": 0.0, "m_psi": 10.0,
                      "m_fsi": 0.0, "m_dir": 0.0, "m_mef": 20.0, "gt_m_psi": 9.0,
                      "gt_m_fsi": 0.0, "gt_m_dir": 0.0, "caused_collision": 0.0}
                for env in env_ids}  # fmt: skip

    monkeypatch.setattr(ship, "evaluate", evaluate)
    monkeypatch.setattr(ship, "MODELS_DIR", tmp_path / "models")
    monkeypatch.setattr(ship, "stamp_observation", lambda *args: None)
    _fake_run(tmp_path / "run")
    card = ship.ship(tmp_path / "run", "ppo-mix-srpb", 40, TEST.start, False, validate=30,
                     candidates=7)  # fmt: skip
    *validation, test = seen  # best/ and the final model, then the test
    assert [v[1:3] for v in validation] == [(30, VALIDATION.start)] * 2
    assert test[1:3] == (40, TEST.start)
    assert card["test"]["seed_range"] == "test" and card["test"]["candidates"] == 7

    # the card's command, read by srpb-gym eval's own parser, runs the test evaluation
    command = card["test"]["command"]
    words = shlex.split(command)
    assert words[:2] == ["srpb-gym", "eval"]
    args = build_parser().parse_args(words[1:])
    assert args.policy == ["ppo-mix-srpb"] and args.env == test[0] == card["test"]["envs"]
    assert (args.episodes, args.seed, args.warmup) == (40, TEST.start, ship.TEST_WARMUP)
    assert parse_overrides(args.env_kwargs, "--env-kwargs") == test[3]
    assert test[3] == {"observation": {"lidar_encoding": "log"}}  # training's own left out

    text = (tmp_path / "models" / "ppo-mix-srpb" / "card.md").read_text(encoding="utf-8")
    assert f"`{command}`" in text
    assert "--episodes 40 --seed 20000000 --warmup 0" in command
    assert ("7 candidate runs were trained for this slot; the test seeds were used once, at "
            "shipping.") in text  # fmt: skip
    assert "seeds 20000000-20000039 (test seeds, never trained on or chosen with)" in text
    assert "--episodes 5" not in text and "--seed 0" not in text
    card = json.loads((tmp_path / "models" / "ppo-mix-srpb" / "card.json").read_text())
    assert ship.card_markdown("ppo-mix-srpb", card) == text
