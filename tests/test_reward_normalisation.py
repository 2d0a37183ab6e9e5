"""The learner sees a collision's full penalty: ``srpb-gym train`` normalises the reward
without a clip, so that the guarantee "no policy gains by crashing", which the raw reward
holds (tests/test_reward_bound.py), holds for the normalised reward PPO learns from."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from srpb_gym.training.callbacks import SeenRewardCallback, reward_sigma, seen_margin
from srpb_gym.training.checks import check_reward
from srpb_gym.training.config import REWARD_CLIP, resolve
from srpb_gym.training.run import make_vec_env, normalize

ENV = "SRPB-Corridor-v0"
#: the smallest return spread of the shipped models' statistics
SIGMA = 1.26


def _warm(venv, sigma: float) -> None:
    """Return statistics as after a long run: spread ``sigma``, too many samples for one
    episode to move it."""
    venv.ret_rms.var = np.array(sigma**2 - venv.epsilon)
    venv.ret_rms.count = 1e9


def _crash(venv) -> tuple[float, float, float]:
    """Turn into the corridor's wall at full speed until the episode ends; the raw reward,
    the reward the learner got and the sigma it was divided by, at the last step."""
    venv.reset()
    for _ in range(200):
        _, seen, dones, infos = venv.step(np.array([[1.0, 1.0]], dtype=np.float32))
        if dones[0]:
            assert infos[0]["collision"], "the episode ended without a collision"
            return float(venv.get_original_reward()[0]), float(seen[0]), reward_sigma(venv)
    raise AssertionError("no collision in 200 steps")


@pytest.mark.parametrize("preset", ["task", "srpb"])
def test_the_learner_sees_the_full_collision_penalty(preset):
    from stable_baselines3.common.vec_env import VecNormalize

    config = resolve(ENV, {"n_envs": 1})
    kwargs = {"reward": preset, "collision": "terminate"}
    venv = normalize(make_vec_env(ENV, config, kwargs, 0), config)  # as srpb-gym train does
    try:
        assert isinstance(venv, VecNormalize) and venv.clip_reward == REWARD_CLIP == math.inf
        assert venv.gamma == config.gamma and venv.norm_reward and venv.norm_obs
        _warm(venv, SIGMA)
        raw, seen, sigma = _crash(venv)
        checked = check_reward(ENV, preset, {"collision": "terminate"}, config.gamma)
        ((penalty, bound),) = checked.bounds.values()
        assert raw <= -penalty + 1.0  # the penalty, and little else, on the last step
        assert sigma == pytest.approx(SIGMA, rel=1e-3)
        assert seen == pytest.approx(raw / sigma)  # divided by sigma, nothing cut
        assert seen < -10.0  # beyond SB3's default clip
        # the bound, on what the learner sees: a collision costs more than any shaping
        assert seen_margin(venv, penalty, bound) == pytest.approx((penalty - bound) / sigma)
        assert seen_margin(venv, penalty, bound) > 0.0

        # stable-baselines3's default normaliser, with the same statistics, would have cut it
        default = VecNormalize(make_vec_env(ENV, config, kwargs, 0), gamma=config.gamma)
        assert default.clip_reward == 10.0
        default.ret_rms = venv.ret_rms
        assert float(default.normalize_reward(np.array([raw]))[0]) == -10.0 != seen
        if preset == "srpb":  # its shaping (23.9) outweighs the cut penalty: crashing pays
            assert bound / sigma > 10.0 and seen_margin(default, penalty, bound) < 0.0
        default.close()
    finally:
        venv.close()


def test_the_callback_logs_clipped_rewards_and_the_margin():
    """``train/reward_clip_fraction`` counts the steps whose reward the normaliser clipped
    and ``train/collision_margin`` is the smallest margin, at the end of each rollout; a
    margin that is not positive is said once."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecNormalize

    config = resolve(ENV, {"n_envs": 1, "n_steps": 64, "batch_size": 64, "net_arch": [8]})
    kwargs = {"reward": "srpb", "collision": "terminate"}
    bounds = check_reward(ENV, "srpb", {"collision": "terminate"}, config.gamma).bounds
    records: dict[str, float] = {}

    class Record(Logger):
        def record(self, key, value, exclude=None):
            records[key] = value

    for clip, clipped in ((REWARD_CLIP, False), (1e-6, True)):
        venv = VecNormalize(make_vec_env(ENV, config, kwargs, 0), gamma=config.gamma,
                            clip_reward=clip)  # fmt: skip
        model = PPO("MlpPolicy", venv, seed=0, **config.ppo_kwargs())
        records.clear()
        model.set_logger(Record(None, []))
        lines: list[str] = []
        callback = SeenRewardCallback(bounds, lines.append)
        model.learn(128, callback=callback)
        assert (records["train/reward_clip_fraction"] > 0.5) is clipped
        assert (records["train/collision_margin"] > 0.0) is not clipped
        assert len(lines) == int(clipped)  # said once, over two rollouts
        if clipped:
            assert "a policy could learn to crash" in lines[0]
        venv.close()
