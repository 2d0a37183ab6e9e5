"""Training hyperparameters: ``configs/train/ppo.yaml``, keyed by environment id.

The file maps environment ids to :class:`TrainConfig` keys, in the style of the RL
Baselines3 Zoo: the ``default`` entry applies to every id and an id's own entry overrides
it key by key; :func:`resolve` then applies command-line overrides (``KEY=VALUE``, each
value read as YAML, safely). Every key is checked: an unknown key, a value of the wrong
type or out of range is an :class:`~srpb_gym.errors.InputError` naming the file, its line
and the key (``ppo.yaml:12: SRPB-Crowd-v0.n_stesp: unknown key; valid keys: ...``), or the
override (``--hyperparams: n_steps: must be >= 2, got 1``).

Imports neither stable-baselines3 nor torch.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.resources import files
from typing import Any

from srpb_gym.config import from_dict, parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.models.files import find_model
from srpb_gym.models.shipped import model_names
from srpb_gym.planners import PLANNERS, REFERENCE_PLANNERS, is_planner
from srpb_gym.seeds import CHECKPOINT_SELECTION, DEMONSTRATIONS
from srpb_gym.yaml_io import read_file, read_yaml

__all__ = ["DEFAULT_KEY", "REWARD_CLIP", "Pretraining", "TrainConfig", "config_file",
           "load_entries", "parse_overrides", "resolve", "rl_zoo_document", "rl_zoo_entry",
           "vecnormalize_kwargs"]  # fmt: skip

DEFAULT_KEY = "default"
VEC_ENVS = ("subproc", "dummy")
ACTIVATIONS = ("tanh", "relu")
#: demonstration episodes of a warm start at most (DAgger rounds included): their seeds
#: stay in :data:`srpb_gym.seeds.DEMONSTRATIONS` (2,000,000-2,999,999)
DEMO_EPISODES_MAX = DEMONSTRATIONS.size
#: the clip of the normalised reward: none. ``VecNormalize`` divides a reward by the spread
#: of the discounted return (sigma) and clips it, by default to +-10; a collision penalty
#: of 25-120 then reaches the learner as at most 10 sigma, which can be less than what the
#: shaping may cost (:func:`srpb_gym.reward.shaping_bound`), so a clip would undo the
#: guarantee that no policy gains by crashing. The rewards are bounded by construction
#: (every term has a per-step bound), so no clip is needed to keep them finite.
REWARD_CLIP = math.inf
#: hyperparameter keys of other tools that ``srpb-gym train`` sets itself, and why
FIXED_KEYS = {
    "clip_reward": "srpb-gym train never clips the normalised reward: a clip of k sigma "
                   "can cut the collision penalty below the shaping bound, so that a policy "
                   "could gain by crashing (docs/training.md, normalisation)",
    "norm_reward": "normalize: true normalises observations and rewards (the reward "
                   "unclipped); normalize: false neither",
}  # fmt: skip
DEFAULT_VALIDATION_EPISODES = 20
"""Episodes per environment on the validation seeds that choose among Ray Tune trials
(``srpb-gym train --backend ray --validation-episodes``)."""
#: the keys passed to ``stable_baselines3.PPO`` as they are
PPO_KEYS = ("learning_rate", "n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda",
            "clip_range", "ent_coef", "vf_coef", "max_grad_norm")  # fmt: skip


#: the prefix of the :class:`TrainConfig` keys that make up its :class:`Pretraining`
PRETRAIN_PREFIX = "pretrain_"


@dataclass(frozen=True)
class Pretraining:
    """The settings of a warm start (:func:`srpb_gym.training.pretrain.pretrain`): the
    ``pretrain_*`` keys of :class:`TrainConfig` without their prefix, which documents and
    checks them (:attr:`TrainConfig.pretraining`)."""

    planner: str = ""
    teachers: Mapping[str, str] = dataclasses.field(default_factory=dict)
    episodes: int = 100
    epochs: int = 30
    noise: float = 0.1
    log_std: float = -1.0
    dagger_rounds: int = 0
    dagger_episodes: int = 200


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run is made with, besides the environment and the seed.

    ``n_timesteps``: environment steps of the run (all environments together);
    ``n_envs``: environments stepped together, in one process each (``vec_env:
    subproc``) or in the training process (``dummy``); ``normalize``: ``VecNormalize``
    of observations and rewards (its statistics are saved beside the model);
    ``policy``: the SB3 policy class name; ``net_arch``, ``activation_fn``: hidden layers
    of the policy and value networks (separate networks of the same shape) and their
    activation; the PPO keys (:data:`PPO_KEYS`) go to ``stable_baselines3.PPO`` as they
    are; ``eval_freq``: environment steps between evaluations through the ``srpb-gym
    eval`` harness (0: none), each over ``eval_episodes`` episodes; ``torch_threads``:
    threads of torch in the training process (0: torch's default, one per core).

    ``pretrain_planner``: the teacher whose ``pretrain_episodes`` demonstrations
    warm-start the policy before PPO (empty: none; :mod:`srpb_gym.training.pretrain`): a
    classical planner (``dwa``, ``social-dwa``, ...), a reference planner handed the true
    people (``oracle-social-dwa``, ...: a privileged teacher), a shipped model's name or a model
    file (or a run folder holding ``model.zip``); ``pretrain_epochs`` passes of behaviour
    cloning, executed actions with Gaussian noise ``pretrain_noise``, then the policy's
    log standard deviation set to ``pretrain_log_std``. ``pretrain_teachers``: for
    ``SRPB-Mix-v0``, a teacher per scenario (scenario name -> teacher, as
    ``pretrain_planner``); the episodes of a scenario it does not name are driven by
    ``pretrain_planner``. ``pretrain_dagger_rounds``: rounds of DAgger after the clone,
    each of ``pretrain_dagger_episodes`` episodes driven by the clone and labelled by the
    teachers, after which the policy is fitted again on every step so far (0: none).
    """

    n_timesteps: int = 1_000_000
    n_envs: int = 2
    vec_env: str = "dummy"
    normalize: bool = True
    policy: str = "MlpPolicy"
    learning_rate: float = 3e-4
    n_steps: int = 512
    batch_size: int = 256
    n_epochs: int = 10
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    net_arch: tuple[int, ...] = (256, 256)
    activation_fn: str = "tanh"
    eval_freq: int = 50_000
    eval_episodes: int = 20
    torch_threads: int = 0
    pretrain_planner: str = ""
    pretrain_teachers: dict[str, str] = dataclasses.field(default_factory=dict)
    pretrain_episodes: int = 100
    pretrain_epochs: int = 30
    pretrain_noise: float = 0.1
    pretrain_log_std: float = -1.0
    pretrain_dagger_rounds: int = 0
    pretrain_dagger_episodes: int = 200

    def __post_init__(self) -> None:
        _at_least("n_timesteps", self.n_timesteps, 1)
        _at_least("n_envs", self.n_envs, 1)
        _at_least("n_steps", self.n_steps, 2)
        _at_least("batch_size", self.batch_size, 2)
        _at_least("n_epochs", self.n_epochs, 1)
        _at_least("eval_freq", self.eval_freq, 0)
        _at_least("eval_episodes", self.eval_episodes, 1)
        if self.eval_episodes > CHECKPOINT_SELECTION.size:
            raise ValueError(f"eval_episodes: at most {CHECKPOINT_SELECTION.size:,} keep the "
                             "periodic evaluations in the checkpoint-selection seeds, got "
                             f"{self.eval_episodes}")  # fmt: skip
        _at_least("torch_threads", self.torch_threads, 0)
        _at_least("pretrain_episodes", self.pretrain_episodes, 1)
        _at_least("pretrain_epochs", self.pretrain_epochs, 1)
        _at_least("pretrain_dagger_rounds", self.pretrain_dagger_rounds, 0)
        _at_least("pretrain_dagger_episodes", self.pretrain_dagger_episodes, 1)
        demos = self.pretrain_episodes + self.pretrain_dagger_rounds * self.pretrain_dagger_episodes
        if demos > DEMO_EPISODES_MAX:
            raise ValueError(f"pretrain_episodes: {demos} demonstration episodes in all (with "
                             f"the DAgger rounds'); at most {DEMO_EPISODES_MAX:,} keep their "
                             "seeds apart from the validation seeds")  # fmt: skip
        if self.pretrain_planner:
            _check_teacher("pretrain_planner", self.pretrain_planner)
        for scenario, teacher in self.pretrain_teachers.items():
            _check_teacher(f"pretrain_teachers.{scenario}", teacher)
        if not 0.0 <= self.pretrain_noise <= 1.0:
            raise ValueError(f"pretrain_noise: must be in [0, 1], got {self.pretrain_noise!r}")
        if not -5.0 <= self.pretrain_log_std <= 1.0:
            raise ValueError(f"pretrain_log_std: must be in [-5, 1], got "
                             f"{self.pretrain_log_std!r}")  # fmt: skip
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env: choose one of {', '.join(VEC_ENVS)}, got {self.vec_env!r}")
        if self.activation_fn not in ACTIVATIONS:
            raise ValueError(f"activation_fn: choose one of {', '.join(ACTIVATIONS)}, got "
                             f"{self.activation_fn!r}")  # fmt: skip
        if self.policy != "MlpPolicy":
            raise ValueError(f"policy: only MlpPolicy fits the flat observation, got "
                             f"{self.policy!r}")  # fmt: skip
        if not self.net_arch or min(self.net_arch) < 1:
            raise ValueError(f"net_arch: expected a list of layer sizes >= 1, got "
                             f"{list(self.net_arch)}")  # fmt: skip
        for name in ("learning_rate", "clip_range", "max_grad_norm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be > 0, got {getattr(self, name)!r}")
        for name in ("gamma", "gae_lambda"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"{name}: must be in (0, 1], got {getattr(self, name)!r}")
        for name in ("ent_coef", "vf_coef"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: must be >= 0, got {getattr(self, name)!r}")
        if self.batch_size > self.n_steps * self.n_envs:
            raise ValueError(f"batch_size: {self.batch_size} is more than the "
                             f"{self.n_steps * self.n_envs} steps of one rollout "
                             "(n_steps x n_envs)")  # fmt: skip

    @property
    def pretraining(self) -> Pretraining | None:
        """The settings of the warm start, or ``None`` when there is none (no teacher in
        ``pretrain_planner`` or ``pretrain_teachers``)."""
        if not (self.pretrain_planner or self.pretrain_teachers):
            return None
        return Pretraining(**{f.name: getattr(self, PRETRAIN_PREFIX + f.name)
                              for f in dataclasses.fields(Pretraining)})  # fmt: skip

    def vecnormalize_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``VecNormalize`` (:func:`vecnormalize_kwargs`)."""
        return vecnormalize_kwargs(self.gamma)

    def ppo_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``stable_baselines3.PPO`` (without env, seed, logging)."""
        from torch import nn

        kwargs: dict[str, Any] = {k: getattr(self, k) for k in PPO_KEYS}
        activation = {"tanh": nn.Tanh, "relu": nn.ReLU}[self.activation_fn]
        kwargs["policy_kwargs"] = {"net_arch": {"pi": list(self.net_arch),
                                                "vf": list(self.net_arch)},
                                   "activation_fn": activation}  # fmt: skip
        return kwargs

    def as_dict(self) -> dict[str, Any]:
        """Plain data (lists for tuples), as written into a run's ``config.yaml``."""
        out = dataclasses.asdict(self)
        out["net_arch"] = list(self.net_arch)
        return out


def vecnormalize_kwargs(gamma: float) -> dict[str, Any]:
    """Keyword arguments of the ``VecNormalize`` of a run discounting by ``gamma``:
    observations and rewards normalised (the return's statistics discounted as the learner
    discounts), the reward never clipped (:data:`REWARD_CLIP`)."""
    return {"norm_obs": True, "norm_reward": True, "clip_reward": REWARD_CLIP, "gamma": gamma}


def _check_teacher(name: str, teacher: str) -> None:
    """A teacher of the warm start: a planner's name, a shipped model or a model file."""
    if is_planner(teacher) or find_model(teacher) is not None:
        return
    planners = ", ".join(sorted(PLANNERS) + sorted(REFERENCE_PLANNERS))
    raise ValueError(f"{name}: {teacher!r} is no planner ({planners}), "
                     f"shipped model ({', '.join(model_names()) or 'none'}), model file or "
                     "run folder holding model.zip")  # fmt: skip


def _at_least(name: str, value: int, low: int) -> None:
    if value < low:
        raise ValueError(f"{name}: must be >= {low}, got {value!r}")


def config_file(algo: str = "ppo") -> Any:
    """The packaged hyperparameter file of ``algo`` (``configs/train/<algo>.yaml``)."""
    return files("srpb_gym.train_configs") / f"{algo}.yaml"


def load_entries(source: Any = None) -> tuple[dict[str, dict[str, Any]], dict[str, int], str]:
    """The entries of a hyperparameter file (default: the packaged one), the line of every
    dotted key and the file's name for errors."""
    source = config_file() if source is None else source
    name = str(source)
    data, lines = read_yaml(read_file(source, name), name)
    if not isinstance(data, Mapping):
        raise InputError("expected a mapping of environment ids to hyperparameters", name)
    for key, entry in data.items():
        if not isinstance(entry, Mapping):
            raise InputError(f"{key}: expected a mapping of hyperparameters, got {entry!r}",
                             name, lines.get(str(key)))  # fmt: skip
    for key, entry in data.items():  # every entry valid, merged with the default
        _build({**data.get(DEFAULT_KEY, {}), **entry}, str(key), name, lines)
    return {str(k): dict(v) for k, v in data.items()}, lines, name


def resolve(
    env_id: str, overrides: Mapping[str, Any] | None = None, source: Any = None
) -> TrainConfig:
    """The configuration of ``env_id``: the file's ``default`` entry, then the id's own
    entry (if any), then ``overrides``."""
    entries, lines, name = load_entries(source)
    merged = {**entries.get(DEFAULT_KEY, {}), **entries.get(env_id, {})}
    base = _build(merged, env_id if env_id in entries else DEFAULT_KEY, name, lines)
    if not overrides:
        return base
    fixed = next((key for key in FIXED_KEYS if key in overrides), None)
    if fixed is not None:
        raise InputError(FIXED_KEYS[fixed], key=f"--hyperparams: {fixed}")
    try:
        return from_dict(TrainConfig, {**base.as_dict(), **dict(overrides)})
    except InputError as exc:
        raise InputError(exc.message, key=f"--hyperparams: {exc.key}" if exc.key else
                         "--hyperparams") from None  # fmt: skip


def _build(data: Mapping[str, Any], entry: str, name: str, lines: Mapping[str, int]) -> TrainConfig:
    try:
        fixed = next((key for key in FIXED_KEYS if key in data), None)
        if fixed is not None:
            raise InputError(f"{fixed}: {FIXED_KEYS[fixed]}", key=entry)
        return from_dict(TrainConfig, data, entry, name)
    except InputError as exc:
        key, message = exc.key or entry, exc.message
        field_name, sep, rest = message.partition(": ")
        if key == entry and sep and field_name.split(".")[0] in _FIELDS | set(FIXED_KEYS):
            key, message = f"{entry}.{field_name}", rest  # a field's check
        line = lines.get(key)
        if line is None:  # a value inherited from the default entry
            line = lines.get(f"{DEFAULT_KEY}.{key.split('.', 1)[-1]}", lines.get(entry))
        raise InputError(f"{key}: {message}", name, line) from None


_FIELDS = frozenset(f.name for f in dataclasses.fields(TrainConfig))


def rl_zoo_entry(config: TrainConfig, env_kwargs: Mapping[str, Any] | None = None) -> dict:
    """``config`` as an entry of an RL Baselines3 Zoo hyperparameter file."""
    activation = {"tanh": "nn.Tanh", "relu": "nn.ReLU"}[config.activation_fn]
    arch = list(config.net_arch)
    entry: dict[str, Any] = {
        "n_envs": config.n_envs,
        "n_timesteps": float(config.n_timesteps),
        "policy": config.policy,
        "normalize": _rl_zoo_normalize(config),
        **{k: getattr(config, k) for k in PPO_KEYS},
        "policy_kwargs": f"dict(net_arch=dict(pi={arch}, vf={arch}), activation_fn={activation})",
    }
    if env_kwargs:
        entry["env_kwargs"] = dict(env_kwargs)
    return entry


def _rl_zoo_normalize(config: TrainConfig) -> str | bool:
    """The Zoo's ``normalize``: the keyword arguments of ``VecNormalize`` as Python text,
    which the Zoo evaluates (it sets ``gamma`` itself, from the entry's), so that it does
    not clip the normalised reward to SB3's default +-10 either."""
    if not config.normalize:
        return False
    kwargs = vecnormalize_kwargs(config.gamma)
    del kwargs["gamma"]
    return "dict(" + ", ".join(f"{k}={_python(v)}" for k, v in kwargs.items()) + ")"


def _python(value: Any) -> str:
    """``value`` as Python text (infinity as ``float('inf')``)."""
    return "float('inf')" if value == math.inf else repr(value)


def rl_zoo_document(source: Any = None) -> str:
    """The RL Baselines3 Zoo hyperparameter file (YAML text) of every environment id of the
    hyperparameter file (default: the packaged one), in its order."""
    import yaml

    entries, _, _ = load_entries(source)
    doc = {env_id: rl_zoo_entry(resolve(env_id, source=source))
           for env_id in entries if env_id != DEFAULT_KEY}  # fmt: skip
    header = ("# Generated from configs/train/ppo.yaml by `python -m training.export_rl_zoo`;\n"
              "# edit that file, not this one. Usage:\n"
              "#   python -m rl_zoo3.train --algo ppo --env SRPB-Corridor-v0 "
              "--gym-packages srpb_gym \\\n"
              "#       --conf-file configs/train/rl_zoo/ppo.yml --vec-env subproc\n"
              "# The Zoo starts from random weights: the warm start from a classical planner\n"
              "# (pretrain_* in configs/train/ppo.yaml) is srpb-gym train's own. `normalize`\n"
              "# never clips the normalised reward, as srpb-gym train (docs/training.md).\n"
              )  # fmt: skip
    return header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=False)
