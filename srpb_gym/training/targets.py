"""What a model trained on an environment is evaluated on: the periodic evaluations of its
training run, the ``srpb-gym eval`` command ``srpb-gym train`` prints at the end and the
tests of a shipped model. Imports neither stable-baselines3 nor torch."""

from __future__ import annotations

import os
import shlex
from collections.abc import Mapping, Sequence
from typing import Any

from srpb_gym.registration import CUSTOM_ID, ENV_IDS, MIX_ID, MIX_SCENARIOS

#: env kwargs of training that an evaluation of the model leaves out: the reward (which
#: evaluation does not use), the time limit (evaluations run the scenario's), and what
#: the evaluation sets itself (metric settings, records, rendering)
TRAINING_ONLY_KWARGS = frozenset({
    "reward", "reward_weights", "reward_people", "max_episode_steps", "metrics", "record_dir",
    "render_mode",
})  # fmt: skip
#: kwargs of SRPB-Mix-v0 that change only how often each scenario is drawn in training:
#: periodic evaluation runs each scenario of the mixture as often as the others, as the
#: test seeds do
MIX_DRAW_KWARGS = frozenset({"weights"})


def eval_setup(
    env_id: str, env_kwargs: Mapping[str, Any] | None = None
) -> tuple[list[str], dict[str, Any]]:
    """What a model trained on ``env_id`` with ``env_kwargs`` is evaluated on: the
    environments (registered ids, or scenario files) and their keyword arguments.

    ``SRPB-Mix-v0`` is evaluated on each of its scenarios (``scenarios``, default the
    packaged ones), each as often as the others; any other id on its ``scenario`` when one
    is given (``SRPB-Custom-v0``: default corridor), else as itself. The kwargs are those of
    training but :data:`TRAINING_ONLY_KWARGS` and the mixture's (``scenarios``,
    ``weights``) or the scenario. Scenarios are names or files, as the environments
    (which training makes first) accept them."""
    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k not in TRAINING_ONLY_KWARGS}
    if env_id == MIX_ID:
        for key in MIX_DRAW_KWARGS:
            kwargs.pop(key, None)
        scenarios = kwargs.pop("scenarios", None)
        items = MIX_SCENARIOS if scenarios is None else scenarios
        return [_eval_target(item) for item in items], kwargs
    if env_id == CUSTOM_ID or "scenario" in kwargs:
        return [_eval_target(kwargs.pop("scenario", "corridor"))], kwargs
    return [env_id], kwargs


def _eval_target(scenario: str | os.PathLike[str]) -> str:
    """The id of a packaged scenario's name, or a scenario file's path."""
    return ENV_IDS.get(os.fspath(scenario), os.fspath(scenario))


def eval_env_ids(env_id: str) -> list[str]:
    """The ids a model trained on ``env_id`` with no env kwargs is evaluated on: the id
    itself, or every packaged scenario's id for the mixture (see :func:`eval_setup`)."""
    return eval_setup(env_id)[0]


def eval_command(env_ids: Sequence[str], env_kwargs: Mapping[str, Any], policy: str,
                 **options: int) -> str:  # fmt: skip
    """The ``srpb-gym eval`` command line that evaluates ``policy`` on ``env_ids`` with
    ``env_kwargs`` (as :func:`eval_setup` gives them) and ``options`` (``episodes=100``,
    ``seed=...``, ``warmup=0``: ``--episodes 100`` ...), quoted for a POSIX shell."""
    words = ["srpb-gym", "eval", "--env", *env_ids, "--policy", policy]
    for name, value in options.items():
        words += [f"--{name.replace('_', '-')}", str(value)]
    if env_kwargs:
        words += ["--env-kwargs", *(f"{k}={yaml_flow(v)}" for k, v in env_kwargs.items())]
    return shlex.join(words)


def yaml_flow(value: Any) -> str:
    """``value`` in YAML's flow style, on one line, as ``--env-kwargs`` reads it."""
    import yaml

    text = yaml.safe_dump(value, default_flow_style=True, width=1 << 30)
    return text.removesuffix("...\n").strip()  # a scalar document ends with '...'
