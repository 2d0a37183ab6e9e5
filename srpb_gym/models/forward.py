"""A fixed-order forward pass of a stable-baselines3 MLP policy: the same actions on every CPU.

torch's matrix products (Intel MKL, oneDNN) choose their code path by the processor's
vector instructions, and so does the order in which they sum: a policy's actions then
differ in their last bits from one CPU to another, and where the robot's path interacts
with walkers the episodes drift apart. :class:`FixedOrderPolicy` computes the
deterministic action of a PPO or A2C ``MlpPolicy`` (stable-baselines3's
``ActorCriticPolicy`` with its flattening feature extractor and ``MlpExtractor``) with
numba-compiled loops from the weights of the model, converted to numpy once at load:

* every sum runs in one fixed order (over the inputs of a unit, first to last) in float64
  (the float32 weights and inputs convert exactly, each product is exact), compiled
  without ``fastmath``, so no reassociation and no fused multiply-add; no BLAS call;
* ``tanh`` (the ``Tanh`` activation, a squashed output) is computed here from additions,
  multiplications and divisions alone, not by the C library, whose ``exp`` and ``tanh``
  may also pick a code path by processor;
* the action is the Gaussian mean (``tanh`` of it for a squashed policy), rounded to
  float32, then clipped to the action space's bounds (rescaled to them, when squashed) in
  float32, as ``policy.predict(obs, deterministic=True)`` does.

IEEE-754 additions, multiplications and divisions are correctly rounded on every
processor, so the actions are bit-identical wherever the package runs; they agree with
torch's to a few float32 ulps (the tests hold every shipped model to 1e-6).

:func:`fixed_order_policy` builds it from a loaded model and raises
:class:`UnsupportedPolicyError` (its reason, one line) for a policy it does not cover:
SAC, TD3, DDPG and DQN policies, CNN or custom feature extractors, activations other than
``Tanh`` and ``ReLU``, other than Box observation and action spaces, sampled
(non-deterministic) actions. Those keep torch's ``predict``. torch is imported only when
a policy is read; this module imports without it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["FixedOrderPolicy", "UnsupportedPolicyError", "fixed_order_policy", "fixed_tanh"]

_IDENTITY, _TANH, _RELU = 0, 1, 2
_ACTIVATIONS = {"Tanh": _TANH, "ReLU": _RELU}
"""The activation modules the fixed-order pass computes (torch class name: code)."""

# exp(r) for |r| <= ln(2)/2: the Taylor series to r**13/13! (truncation below 1e-17),
# summed by Horner's rule; ln 2 split so that k * _LN2_HI is exact (|k| <= 58 here)
_EXP_COEFFICIENTS = tuple(1.0 / math.factorial(n) for n in range(13, -1, -1))
_C13, _C12, _C11, _C10, _C9, _C8, _C7, _C6, _C5, _C4, _C3, _C2, _C1, _C0 = _EXP_COEFFICIENTS
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_TANH_ONE = 20.0
"""|x| from which tanh(x) rounds to +-1 in float64 (1 - tanh(20) is 8.5e-18)."""

_AGREEMENT = 1e-4
"""Largest relative gap to torch's means that :func:`fixed_order_policy` accepts (float32
rounding gives about 1e-7; a gap above this means a network read wrongly)."""


class UnsupportedPolicyError(ValueError):
    """A policy the fixed-order forward pass does not cover; ``str()`` gives why."""


@njit(cache=True, error_model="numpy")
def _exp_minus(y: float) -> float:
    """exp(-y) for 0 <= y < 40, from +, -, *, / alone (no C library call)."""
    k = math.floor(y * _INV_LN2 + 0.5)  # an int64 in numba
    r = (k * _LN2_HI - y) + k * _LN2_LO  # -y - (-k) ln 2, in [-ln2/2, ln2/2]
    p = _C13
    for c in (_C12, _C11, _C10, _C9, _C8, _C7, _C6, _C5, _C4, _C3, _C2, _C1, _C0):
        p = p * r + c
    return p / float(1 << k)  # exp(-y) = exp(r) * 2**-k, the division by 2**k is exact


@njit(cache=True, error_model="numpy")
def fixed_tanh(x: float) -> float:
    """tanh of a float64 from +, -, *, / alone: the same bits on every processor (within a
    few 1e-16 of the exact value)."""
    a = abs(x)
    if a != a:
        return x  # NaN
    if a >= _TANH_ONE:
        t = 1.0
    elif a < 1e-9:
        t = a  # tanh(a) = a - a**3/3: a**3/3 is below half an ulp of a
    else:
        e = _exp_minus(2.0 * a)
        t = (1.0 - e) / (1.0 + e)
    return -t if x < 0.0 else t


@njit(cache=True, error_model="numpy")
def _forward(
    x: NDArray[np.float64],
    weights: NDArray[np.float64],
    biases: NDArray[np.float64],
    sizes: NDArray[np.int64],
    activations: NDArray[np.int64],
    squash: bool,
    out: NDArray[np.float64],
) -> None:
    """The MLP on each row of ``x`` into ``out``. Layer ``l`` maps ``sizes[l]`` inputs to
    ``sizes[l + 1]`` units; its weights are stored input-major (``[i, j]``: input ``i`` to
    unit ``j``) in ``weights``, one layer after the other. Unit ``j`` sums its products
    ``w[i, j] * x[i]`` for ``i`` = 0, 1, ... in turn, then adds its bias."""
    width = 0
    for size in sizes:
        width = max(width, size)
    a = np.empty(width)
    b = np.empty(width)
    n_layers = activations.shape[0]
    for row in range(x.shape[0]):
        for i in range(sizes[0]):
            a[i] = x[row, i]
        w0 = 0
        b0 = 0
        for layer in range(n_layers):
            n_in = sizes[layer]
            n_out = sizes[layer + 1]
            for j in range(n_out):
                b[j] = 0.0
            for i in range(n_in):
                xi = a[i]
                base = w0 + i * n_out
                for j in range(n_out):
                    b[j] += weights[base + j] * xi
            kind = activations[layer]
            for j in range(n_out):
                v = b[j] + biases[b0 + j]
                if kind == _TANH:
                    v = fixed_tanh(v)
                elif kind == _RELU and v < 0.0:
                    v = 0.0
                b[j] = v
            w0 += n_in * n_out
            b0 += n_out
            a, b = b, a
        for j in range(sizes[n_layers]):
            out[row, j] = fixed_tanh(a[j]) if squash else a[j]


class FixedOrderPolicy:
    """The deterministic action of an MLP actor, computed in a fixed order (module doc).

    ``layers``: ``(weight, bias, activation)`` from the input on, ``weight`` shaped
    ``(units, inputs)`` as torch stores it, ``activation`` ``"Tanh"``, ``"ReLU"`` or
    ``None``; the last layer gives the action mean. ``low``, ``high``: the Box action
    space's bounds; ``squash``: a ``tanh``-squashed policy, whose output is rescaled to the
    bounds instead of clipped. ``observation_shape``, ``action_shape``: the spaces'
    shapes. Built from a model by :func:`fixed_order_policy`.
    """

    def __init__(
        self,
        layers: list[tuple[NDArray[Any], NDArray[Any], str | None]],
        low: NDArray[Any],
        high: NDArray[Any],
        squash: bool,
        observation_shape: tuple[int, ...],
        action_shape: tuple[int, ...],
    ) -> None:
        if not layers:
            raise ValueError("a policy needs at least one layer")
        sizes = [int(np.asarray(layers[0][0]).shape[1])]
        weights, biases, activations = [], [], []
        for weight, bias, activation in layers:
            w = np.asarray(weight, dtype=np.float64)
            if w.ndim != 2 or w.shape[1] != sizes[-1] or np.shape(bias) != (w.shape[0],):
                raise ValueError(f"layer {len(sizes)}: weight {w.shape} and bias "
                                 f"{np.shape(bias)} do not follow {sizes[-1]} inputs")  # fmt: skip
            if activation is not None and activation not in _ACTIVATIONS:
                raise ValueError(f"activation {activation!r}: not one of {list(_ACTIVATIONS)}")
            weights.append(w.T.ravel())  # input-major
            biases.append(np.asarray(bias, dtype=np.float64))
            activations.append(_IDENTITY if activation is None else _ACTIVATIONS[activation])
            sizes.append(w.shape[0])
        self.observation_shape = tuple(int(n) for n in observation_shape)
        self.action_shape = tuple(int(n) for n in action_shape)
        if math.prod(self.observation_shape) != sizes[0]:
            raise ValueError(f"observation shape {self.observation_shape}, {sizes[0]} inputs")
        if math.prod(self.action_shape) != sizes[-1]:
            raise ValueError(f"action shape {self.action_shape}, {sizes[-1]} outputs")
        self._weights = np.ascontiguousarray(np.concatenate(weights))
        self._biases = np.ascontiguousarray(np.concatenate(biases))
        self._sizes = np.asarray(sizes, dtype=np.int64)
        self._activations = np.asarray(activations, dtype=np.int64)
        self.low = np.asarray(low, dtype=np.float32).reshape(self.action_shape)
        self.high = np.asarray(high, dtype=np.float32).reshape(self.action_shape)
        self.squash = bool(squash)

    @property
    def sizes(self) -> tuple[int, ...]:
        """Inputs, then the units of each layer (the last: the action's size)."""
        return tuple(int(n) for n in self._sizes)

    def mean(self, observation: Any) -> NDArray[np.float32]:
        """The network's output for a batch of observations (rows ``(n, inputs)``, taken as
        float32 as torch takes them): the Gaussian mean, ``tanh`` of it when squashed;
        float32, before clipping or rescaling."""
        x = np.asarray(observation, dtype=np.float32).reshape(-1, int(self._sizes[0]))
        out = np.empty((x.shape[0], int(self._sizes[-1])))
        _forward(x.astype(np.float64), self._weights, self._biases, self._sizes,
                 self._activations, self.squash, out)  # fmt: skip
        return out.astype(np.float32)

    def predict(self, observation: Any) -> NDArray[np.float32]:
        """The deterministic action of one observation (shaped as the observation space)
        or of a batch (one more, leading axis), as ``policy.predict(observation,
        deterministic=True)[0]`` gives it."""
        obs = np.asarray(observation)
        if obs.shape == self.observation_shape:
            batched = False
        elif obs.shape[1:] == self.observation_shape:
            batched = True
        else:
            raise ValueError(f"observation of shape {obs.shape}, the policy takes "
                             f"{self.observation_shape} (or a batch of them)")  # fmt: skip
        actions = self.mean(obs).reshape((-1, *self.action_shape))
        if self.squash:  # stable-baselines3's unscale_action, in float32
            half = np.float32(0.5) * (actions + np.float32(1.0))
            actions = self.low + (half * (self.high - self.low))
        else:
            actions = np.clip(actions, self.low, self.high)
        actions = actions.astype(np.float32, copy=False)
        return actions if batched else actions[0]


def fixed_order_policy(model: Any, deterministic: bool = True) -> FixedOrderPolicy:
    """The fixed-order forward pass of a loaded stable-baselines3 model (or its policy).

    Raises :class:`UnsupportedPolicyError` (why, one line) unless the model's actions are
    the deterministic ones of a PPO or A2C ``MlpPolicy``: the policy class exactly
    ``ActorCriticPolicy``, its actor's features flattened (``FlattenExtractor``), an
    ``MlpExtractor`` whose actor is ``Linear`` layers with ``Tanh`` or ``ReLU``, a
    ``Linear`` ``action_net``, a Gaussian action distribution (gSDE included) over a Box
    action space, and a Box observation space that is not an image.
    """
    if not deterministic:
        raise UnsupportedPolicyError("sampled (non-deterministic) actions are torch's")
    import torch
    from gymnasium import spaces
    from stable_baselines3.common.distributions import (
        DiagGaussianDistribution,
        StateDependentNoiseDistribution,
    )
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.preprocessing import is_image_space
    from stable_baselines3.common.torch_layers import FlattenExtractor, MlpExtractor

    policy = getattr(model, "policy", model)
    kind = type(policy).__name__
    if type(policy) is not ActorCriticPolicy:
        why = f"its policy is a {kind}; the fixed-order pass covers PPO and A2C MlpPolicy"
        raise UnsupportedPolicyError(f"{why} (ActorCriticPolicy) only")
    obs_space, act_space = policy.observation_space, policy.action_space
    if not isinstance(obs_space, spaces.Box):
        why = f"its observation space is a {type(obs_space).__name__}, not a Box"
        raise UnsupportedPolicyError(why)
    if policy.normalize_images and is_image_space(obs_space, check_channels=False):
        raise UnsupportedPolicyError("it observes images")
    if not isinstance(act_space, spaces.Box):
        why = f"its action space is a {type(act_space).__name__}, not a Box"
        raise UnsupportedPolicyError(why)
    extractor = policy.pi_features_extractor
    if type(extractor) is not FlattenExtractor:
        why = f"its feature extractor is a {type(extractor).__name__}, not a FlattenExtractor"
        raise UnsupportedPolicyError(why)
    if type(policy.mlp_extractor) is not MlpExtractor:
        why = f"its MLP extractor is a {type(policy.mlp_extractor).__name__}"
        raise UnsupportedPolicyError(why)
    dist = policy.action_dist
    if type(dist) not in (DiagGaussianDistribution, StateDependentNoiseDistribution):
        raise UnsupportedPolicyError(f"its action distribution is a {type(dist).__name__}")
    squash = bool(policy.squash_output)
    if isinstance(dist, StateDependentNoiseDistribution) and squash != (dist.bijector is not None):
        raise UnsupportedPolicyError("its gSDE squashing and its policy's squash_output differ")
    if isinstance(dist, DiagGaussianDistribution) and squash:
        raise UnsupportedPolicyError("it squashes the output of a Gaussian without gSDE")

    modules = [*policy.mlp_extractor.policy_net, policy.action_net]
    layers: list[tuple[NDArray[Any], NDArray[Any], str | None]] = []
    for module in modules:
        name = type(module).__name__
        if type(module) is torch.nn.Linear:
            if module.bias is None:
                raise UnsupportedPolicyError("a Linear layer of its actor has no bias")
            weight = module.weight.detach().cpu().numpy()
            layers.append((weight, module.bias.detach().cpu().numpy(), None))
        elif name in _ACTIVATIONS and type(module) is getattr(torch.nn, name):
            if not layers or layers[-1][2] is not None:
                why = f"its actor has a {name} that follows no Linear layer"
                raise UnsupportedPolicyError(why)
            weight, bias, _ = layers[-1]
            layers[-1] = (weight, bias, name)
        else:
            known = ", ".join(["Linear", *_ACTIVATIONS])
            why = f"its actor has a {name} (the fixed-order pass computes {known})"
            raise UnsupportedPolicyError(why)
    if layers[-1][2] is not None:
        raise UnsupportedPolicyError("its action_net is followed by an activation")
    try:
        fixed = FixedOrderPolicy(layers, act_space.low, act_space.high, squash,
                                 obs_space.shape, act_space.shape)  # fmt: skip
    except ValueError as exc:
        raise UnsupportedPolicyError(str(exc)) from None
    # a last guard: the same means as torch's on a few observations (no global generator)
    obs = np.random.default_rng(0).normal(size=(16, *fixed.observation_shape))
    obs = obs.astype(np.float32)
    with torch.no_grad():
        mode = policy.get_distribution(torch.as_tensor(obs)).mode().cpu().numpy()
    mode = mode.reshape(len(obs), -1)
    gap = np.abs(fixed.mean(obs) - mode) / np.maximum(1.0, np.abs(mode))
    if not gap.max() <= _AGREEMENT:
        why = f"its fixed-order actions differ from torch's by {gap.max():.2g} (relative)"
        raise UnsupportedPolicyError(why)
    return fixed
