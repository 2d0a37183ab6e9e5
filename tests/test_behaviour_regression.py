"""Episode metrics of fixed seeds stay the same across refactorings.

``tests/fixtures/behaviour_regression.json`` holds, for 3 seeds x every registered scenario
x {seeded random actions, ``dwa``}, the return, the episode length, the outcome and every
``srpb/*`` and ``srpb_gt/*`` metric of the last step. The planner's computation time is set
to a fixed 1 ms per step, so ``m_cef``/``m_cre`` are deterministic too.

A change that is meant to alter behaviour (a scenario, the crowd model, a reward preset)
regenerates the file and says so in its commit:

    python tests/test_behaviour_regression.py --write
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.registration import SCENARIO_IDS

FIXTURE = Path(__file__).parent / "fixtures" / "behaviour_regression.json"
SEEDS = (0, 1, 2)
POLICIES = ("random", "dwa")
PLANNING_TIME = 1e-3  # s, every step
CASES = [(env_id, policy, seed) for env_id in SCENARIO_IDS for policy in POLICIES
         for seed in SEEDS]  # fmt: skip


def run_case(env_id: str, policy: str, seed: int) -> dict[str, object]:
    """The outcome and final metrics of one seeded episode."""
    from srpb_gym.planners import make_planner

    env = gym.make(env_id)
    base = env.unwrapped
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(1000 + seed)
    planner = make_planner("dwa") if policy == "dwa" else None
    if planner is not None:
        planner.reset(base.knowledge())
    total, steps = 0.0, 0
    while True:
        if planner is None:
            action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        else:
            action = planner.act(obs, base.knowledge())
        base.set_planning_time(PLANNING_TIME)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        steps += 1
        if terminated or truncated:
            break
    env.close()
    out: dict[str, object] = {
        "return": total, "steps": steps, "terminated": bool(terminated),
        "truncated": bool(truncated), "is_success": bool(info["is_success"]),
    }  # fmt: skip
    out |= {k: float(v) for k, v in info.items() if k.startswith(("srpb/", "srpb_gt/"))}
    return out


def _key(env_id: str, policy: str, seed: int) -> str:
    return f"{env_id}|{policy}|{seed}"


def _close(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)
    return a == b


@pytest.mark.parametrize(("env_id", "policy", "seed"), CASES)
def test_same_seed_same_episode(env_id: str, policy: str, seed: int) -> None:
    expected = json.loads(FIXTURE.read_text())[_key(env_id, policy, seed)]
    got = run_case(env_id, policy, seed)
    for name, value in expected.items():
        if name.startswith(("srpb/", "srpb_gt/")):
            value = float(value)
        assert name in got, name
        assert _close(got[name], value), f"{name}: {got[name]!r} != {value!r}"


def _write() -> None:
    data = {_key(*case): run_case(*case) for case in CASES}
    FIXTURE.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    print(f"wrote {len(data)} episodes to {FIXTURE}")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(__doc__)
    _write()
