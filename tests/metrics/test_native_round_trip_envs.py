"""The native logs srpb-gym writes reproduce its own numbers: for an episode of every packaged
scenario, the metrics of the ``*_robot.txt``/``_people.txt``/``_groups.txt`` logs equal
those of the ``.npz`` record (and of the episode's ``info``) to 1e-9, planner times
included."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym.metrics import METRIC_NAMES, SRPBMetricWarning, evaluate
from srpb_gym.metrics.io_native import read_native, write_native
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.registration import SCENARIO_IDS

STEPS = 40


def _metrics(record, semantics: str) -> dict[str, float]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SRPBMetricWarning)
        return evaluate(record, semantics)


def _close(a: float, b: float, rtol: float = 1e-9) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=rtol, abs_tol=1e-12)


@pytest.mark.parametrize("env_id", sorted(SCENARIO_IDS))
def test_native_logs_score_like_the_record(tmp_path, env_id):
    env = gym.make(env_id, record_dir=str(tmp_path), max_episode_steps=STEPS)
    rng = np.random.default_rng(sum(map(ord, env_id)))
    env.reset(seed=3)
    info: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # short step limit, metric warnings
        for _ in range(STEPS):
            env.unwrapped.set_planning_time(float(rng.choice([rng.uniform(0, 0.3), 1 / 3, 0.0])))
            action = rng.uniform(-1, 1, env.action_space.shape)
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
    assert terminated or truncated
    stem = tmp_path / env.unwrapped.episode_name()
    env.close()
    logs = [f"{stem}_{kind}.txt" for kind in ("robot", "people", "groups")]
    record, native = load_record(f"{stem}.npz"), read_native(*logs)
    assert native.robot.tobytes() == record.robot.tobytes()  # planner times included
    assert native.people.tobytes() == record.people.tobytes()
    for semantics in ("paper", "reference"):
        exact, from_logs = _metrics(record, semantics), _metrics(native, semantics)
        wrong = {k: (exact[k], from_logs[k]) for k in METRIC_NAMES
                 if not _close(exact[k], from_logs[k])}  # fmt: skip
        assert not wrong, semantics
    exact = _metrics(record, "paper")
    assert all(_close(info[f"srpb/{k}"], exact[k]) for k in METRIC_NAMES)
    # the reference logger's 4 decimals would not reproduce them (m_cef at least)
    coarse = [f"{stem}_4_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(record, *coarse, precision=4)
    rounded = _metrics(read_native(*coarse), "paper")
    assert not _close(rounded["m_cef"], exact["m_cef"])
