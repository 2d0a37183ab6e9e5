"""scripts/policy_return.py: a policy's return under a reward of one's choice, term by term."""

from __future__ import annotations

import numpy as np

from scripts import policy_return as pr
from srpb_gym.planners import make_planner

SHORT = {"max_episode_steps": 40}


def test_the_return_is_the_sum_of_the_terms_and_follows_the_weights():
    planner = make_planner("go-to-goal")
    totals, reached, terms = pr.returns(planner, "SRPB-Corridor-v0", {"reward": "task", **SHORT},
                                        2, 3_000_000)  # fmt: skip
    np.testing.assert_allclose(totals, sum(terms.values()))
    assert not reached.any()  # 4 s is too short for the corridor
    assert np.all(terms["psi"] == 0.0) and np.all(terms["time"] < 0.0)  # task pays no psi
    # the same episodes, time paid ten times over: the time term alone changes, tenfold
    heavy = {"reward": "task", "reward_weights": {"time": -1.0}, **SHORT}
    totals10, _, terms10 = pr.returns(planner, "SRPB-Corridor-v0", heavy, 2, 3_000_000)
    np.testing.assert_allclose(terms10["time"], 10 * terms["time"])
    np.testing.assert_allclose(terms10["progress"], terms["progress"])
    np.testing.assert_allclose(totals10 - totals, 9 * terms["time"])


def test_a_shipped_model_end_to_end(capsys):
    rc = pr.main(
        [
            "--env",
            "SRPB-Corridor-v0",
            "--policy",
            "ppo-corridor-srpb",
            "--episodes",
            "2",
            "--env-kwargs",
            "max_episode_steps=30",
            "reward_people=ground_truth",
        ]
    )
    out = capsys.readouterr().out
    assert rc == 0
    assert out.startswith("ppo-corridor-srpb: return ") and "success 0 % of 2" in out
    assert " progress +" in out and " time -" in out  # it drives towards the goal


def test_errors_name_what_is_wrong(capsys):
    assert pr.main(["--env", "SRPB-Corridor-v0", "--policy", "no-such-model"]) == 2
    assert "no-such-model" in capsys.readouterr().err
    assert pr.main(["--env", "SRPB-Corridor-v0", "--policy", "ppo-corridor-srpb",
                    "--episodes", "0"]) == 2  # fmt: skip
    assert "--episodes: must be >= 1, got 0" in capsys.readouterr().err
