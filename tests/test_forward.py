"""The fixed-order forward pass: torch's actions to 1e-6 for every shipped model, the same
bits whatever MKL's code path, torch kept (and said) for the policies it does not cover."""

from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401
from srpb_gym.models import card, model_names, model_path
from srpb_gym.models.forward import FixedOrderPolicy, fixed_tanh
from srpb_gym.training.targets import eval_env_ids

ROOT = Path(__file__).resolve().parents[1]
TOLERANCE = 1e-6


def test_tanh_is_close_to_the_c_library_and_odd():
    xs = np.concatenate([np.linspace(-25.0, 25.0, 20001), [0.0, 1e-12, 1e-9, 3e-9, 19.99, 20.0]])
    for x in xs:
        t = fixed_tanh(float(x))
        assert abs(t - math.tanh(x)) <= 4e-16, x
        assert fixed_tanh(-float(x)) == -t
    assert fixed_tanh(1e300) == 1.0 and fixed_tanh(-np.inf) == -1.0
    assert math.isnan(fixed_tanh(math.nan))


def _reference(layers, x, squash):
    """The same network in plain Python floats, summing in the documented order."""
    a = [float(v) for v in np.float32(x)]
    for weight, bias, activation in layers:
        out = []
        for j in range(weight.shape[0]):
            s = 0.0
            for i in range(weight.shape[1]):
                s += float(weight[j, i]) * a[i]
            v = s + float(bias[j])
            if activation == "Tanh":
                v = fixed_tanh(v)
            elif activation == "ReLU" and v < 0.0:
                v = 0.0
            out.append(v)
        a = out
    return np.float32([fixed_tanh(v) if squash else v for v in a])


@pytest.mark.parametrize("squash", [False, True])
def test_sums_in_the_documented_order(squash):
    """Bit for bit the plain-Python loop: the order is fixed, no fused multiply-add."""
    rng = np.random.default_rng(3)
    sizes, acts = (7, 33, 17, 3), ("Tanh", "ReLU", None)
    layers = [(rng.normal(size=(n, m)).astype(np.float32), rng.normal(size=n).astype(np.float32),
               act) for m, n, act in zip(sizes[:-1], sizes[1:], acts)]  # fmt: skip
    low, high = np.float32([-1, -2, 0]), np.float32([1, 2, 0.5])
    policy = FixedOrderPolicy(layers, low, high, squash, (7,), (3,))
    assert policy.sizes == sizes
    obs = rng.normal(size=(20, 7)) * 3
    mean = policy.mean(obs)
    for row, x in zip(mean, obs):
        np.testing.assert_array_equal(row, _reference(layers, x, squash))
    actions = policy.predict(obs)
    assert actions.dtype == np.float32 and actions.shape == (20, 3)
    single = policy.predict(obs[4].astype(np.float32))
    assert single.shape == (3,)
    np.testing.assert_array_equal(single, actions[4])
    if squash:
        np.testing.assert_array_equal(actions, low + 0.5 * (mean + 1.0) * (high - low))
    else:
        np.testing.assert_array_equal(actions, np.clip(mean, low, high))
    with pytest.raises(ValueError, match="observation of shape"):
        policy.predict(np.zeros(6))


def _real_observations(policy, name: str, steps: int = 30) -> np.ndarray:
    """The normalised observations ``policy`` (a LearnedPolicy) acts on in the first
    ``steps`` steps of its model's first evaluation environment."""
    seen = []
    forward = policy.forward

    class Recorder:
        def predict(self, observation):
            seen.append(np.array(observation))
            return forward.predict(observation)

    policy.forward = Recorder()
    observation = card(name)["env_kwargs"].get("observation")
    env = gym.make(eval_env_ids(card(name)["env"])[0],
                   **({} if observation is None else {"observation": observation}))  # fmt: skip
    obs, _ = env.reset(seed=7)
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(policy.act(obs, env.unwrapped.knowledge()))
        if terminated or truncated:
            break
    env.close()
    policy.forward = forward
    return np.array(seen)


@pytest.mark.parametrize("name", model_names())
def test_shipped_models_act_as_torch_does(name):
    """Random and real observations, one at a time and batched: within 1e-6 of torch's
    ``predict(obs, deterministic=True)``."""
    pytest.importorskip("stable_baselines3")
    from srpb_gym.planners.learned import LearnedPolicy

    policy = LearnedPolicy(model_path(name))
    assert policy.forward is not None and policy.forward_note is None
    rng = np.random.default_rng(0)
    scale = rng.choice([0.3, 1.0, 3.0], size=(200, 1))  # VecNormalize's outputs: about N(0, 1)
    random = (rng.normal(size=(200, 80)) * scale).astype(np.float32)
    real = _real_observations(policy, name)
    assert len(real) >= 10
    for obs in (random, real):
        torch_actions, _ = policy.model.predict(obs, deterministic=True)
        assert np.abs(policy.forward.predict(obs) - torch_actions).max() <= TOLERANCE
    for obs in real[:10]:
        torch_action, _ = policy.model.predict(obs, deterministic=True)
        fixed = policy.forward.predict(obs)
        assert fixed.dtype == np.float32 and fixed.shape == torch_action.shape
        assert np.abs(fixed - torch_action).max() <= TOLERANCE


def test_normalisation_is_elementwise_numpy():
    """VecNormalize's statistics are applied by correctly rounded elementwise operations:
    the same bits as the formula written out."""
    pytest.importorskip("stable_baselines3")
    from srpb_gym.models import find_vecnormalize, load_vecnormalize

    name = model_names()[0]
    normalizer = load_vecnormalize(find_vecnormalize(model_path(name)))
    obs = np.random.default_rng(1).normal(size=(50, 80)).astype(np.float32) * 5
    rms = normalizer.obs_rms
    by_hand = np.clip((obs - rms.mean) / np.sqrt(rms.var + normalizer.epsilon),
                      -normalizer.clip_obs, normalizer.clip_obs).astype(np.float32)  # fmt: skip
    np.testing.assert_array_equal(normalizer.normalize_obs(obs), by_hand)


def _pendulum_model(algo: str, **kwargs):
    import stable_baselines3

    return getattr(stable_baselines3, algo)("MlpPolicy", "Pendulum-v1", device="cpu", seed=0,
                                            **kwargs)  # fmt: skip


@pytest.mark.parametrize(
    "algo, kwargs",
    [
        ("PPO", {"policy_kwargs": {"net_arch": [32, 16], "activation_fn": "ReLU"}}),
        ("A2C", {"policy_kwargs": {"net_arch": {"pi": [8], "vf": [64, 64]}}}),
        ("PPO", {"use_sde": True, "policy_kwargs": {"squash_output": True, "log_std_init": -1}}),
        ("PPO", {"use_sde": True}),
    ],
)
def test_other_mlp_policies_act_as_torch_does(algo, kwargs):
    pytest.importorskip("stable_baselines3")
    import torch

    from srpb_gym.models import fixed_order_policy

    policy_kwargs = dict(kwargs.pop("policy_kwargs", {}))
    if isinstance(policy_kwargs.get("activation_fn"), str):
        policy_kwargs["activation_fn"] = getattr(torch.nn, policy_kwargs["activation_fn"])
    model = _pendulum_model(algo, policy_kwargs=policy_kwargs, **kwargs)
    with torch.no_grad():  # weights of a trained size, not the small initial ones
        for p in model.policy.parameters():
            p.mul_(4.0)
    fixed = fixed_order_policy(model)
    assert fixed.squash == bool(policy_kwargs.get("squash_output"))
    obs = np.random.default_rng(2).uniform(-8, 8, size=(300, 3)).astype(np.float32)
    torch_actions, _ = model.predict(obs, deterministic=True)
    assert np.abs(fixed.predict(obs) - torch_actions).max() <= TOLERANCE


def test_other_policies_keep_torch_and_say_so(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from srpb_gym.models import UnsupportedPolicyError, fixed_order_policy
    from srpb_gym.planners.learned import LearnedPolicy

    sac = _pendulum_model("SAC", buffer_size=100)
    with pytest.raises(UnsupportedPolicyError, match="its policy is a SACPolicy"):
        fixed_order_policy(sac)
    ppo = _pendulum_model("PPO", n_steps=32, batch_size=32)
    with pytest.raises(UnsupportedPolicyError, match="sampled"):
        fixed_order_policy(ppo, deterministic=False)
    sac.save(tmp_path / "sac.zip")
    policy = LearnedPolicy(tmp_path / "sac.zip", vecnormalize=None)
    assert policy.forward is None and "SACPolicy" in policy.forward_note
    err = capsys.readouterr().err
    assert err.count("srpb-gym: note: ") == 1 and "actions from torch" in err, err
    obs = np.float32([1.0, 0.0, 0.5])
    np.testing.assert_array_equal(policy.act(obs, None), sac.predict(obs, deterministic=True)[0])
    LearnedPolicy(tmp_path / "sac.zip", vecnormalize=None)
    assert capsys.readouterr().err == ""  # said once per file and process


# the run compared under each MKL code path: unset (MKL picks by processor), AVX2 and the
# path common to all x86 processors; the timing metrics are the only columns left out
MKL_PATHS = (None, "AVX2", "COMPATIBLE")
TIMING = {"m_cef", "m_cre", "gt_m_cef", "gt_m_cre"}


def test_the_same_episodes_whatever_mkl_picks(tmp_path):
    """A shipped model evaluated in fresh processes under each MKL code path: the same
    episodes.csv, bit for bit but for the timing metrics. (torch's own actions differ
    between unset and COMPATIBLE on an AMD EPYC, between AVX2 and COMPATIBLE on Intel
    processors with AVX2 or AVX-512.)"""
    pytest.importorskip("stable_baselines3")
    runs = []
    for setting in MKL_PATHS:
        env = {k: v for k, v in os.environ.items() if k != "MKL_CBWR"}
        env.update({"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
        if setting is not None:
            env["MKL_CBWR"] = setting
        out = tmp_path / f"mkl-{setting or 'unset'}"
        command = [sys.executable, "-m", "srpb_gym", "eval", "--env", "SRPB-Corridor-v0",
                   "--policy", "ppo-corridor-srpb", "--episodes", "2", "--workers", "1",
                   "--warmup", "0", "--out", str(out)]  # fmt: skip
        pipe = subprocess.PIPE
        process = subprocess.Popen(command, env=env, cwd=tmp_path, text=True, stdout=pipe,
                                   stderr=pipe)  # fmt: skip
        runs.append((out, process))
    tables = []
    for out, process in runs:
        _, err = process.communicate(timeout=600)
        assert process.returncode == 0, err
        with open(out / "episodes.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == 2
        tables.append([{k: v for k, v in row.items() if k not in TIMING} for row in rows])
    for setting, table in zip(MKL_PATHS[1:], tables[1:]):
        assert table == tables[0], f"MKL_CBWR={setting} against unset"
