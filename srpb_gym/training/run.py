"""One PPO training run and its run folder.

:func:`train` makes ``n_envs`` environments (``gym.make(env_id, reward=preset,
**env_kwargs)`` in a ``Monitor``, one process each with ``vec_env: subproc``), wraps them
in ``VecNormalize`` when the configuration says so, trains ``stable_baselines3.PPO`` with
the callbacks of :mod:`srpb_gym.training.callbacks` and writes into the run folder:

| file | what |
| --- | --- |
| ``model.zip``, ``vecnormalize.pkl`` | the final policy and its observation statistics |
| ``best/`` | the checkpoint with the best periodic evaluation |
| ``config.yaml`` | every resolved setting: env id, preset, env kwargs, seed, hyperparameters |
| ``command.txt`` | the command line |
| ``run.json`` | reward weights of each scenario, seed, versions, machine, steps, wall time |
| ``progress.csv``, ``tb/`` | the SB3 logger (CSV and TensorBoard) |
| ``evaluations.csv``, ``eval/`` | the periodic evaluations (``srpb-gym eval`` run folders) |

Ctrl-C, or SIGTERM (what a batch scheduler or ``kill`` sends), stops training after the
current step and still saves a usable ``model.zip`` and ``vecnormalize.pkl`` (``run.json``
says ``"interrupted": true``). Subprocess environments ignore Ctrl-C, so that only the
training process handles it.
"""

from __future__ import annotations

import dataclasses
import json
import os
import platform
import shlex
import shutil
import signal
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import yaml

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.errors import InputError, env_kwargs_error
from srpb_gym.evaluation.harness import versions
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.observation import ObservationConfig
from srpb_gym.planners.learned import (
    record_observation,
    recorded_observation,
    settings_mismatch,
    settings_text,
)
from srpb_gym.registration import CUSTOM_ID, MIX_ID, MIX_SCENARIOS, SCENARIO_IDS
from srpb_gym.reward import PRESET_GAMMA, TERMS, preset_names, shaping_bound
from srpb_gym.training.callbacks import (
    EpisodeStatsCallback,
    Outcomes,
    PeriodicEvalCallback,
    ProgressCallback,
    WallClockLimit,
    save_checkpoint,
)
from srpb_gym.training.config import TrainConfig

#: env kwargs of training that an evaluation of the model leaves out: the reward (which
#: evaluation does not use), the time limit (evaluations run the scenario's), and what
#: the evaluation sets itself (metric settings, records, rendering)
TRAINING_ONLY_KWARGS = frozenset({
    "reward", "reward_weights", "max_episode_steps", "metrics", "record_dir", "render_mode",
})  # fmt: skip
#: kwargs of SRPB-Mix-v0 that change only how often each scenario is drawn in training:
#: periodic evaluation runs each scenario of the mixture as often as the others, as the
#: test seeds do
MIX_DRAW_KWARGS = frozenset({"weights"})


@dataclass
class TrainResult:
    """What a run produced: its folder, the steps done, the wall time [s] and whether
    Ctrl-C stopped it."""

    out: str
    steps: int
    wall_time: float
    interrupted: bool


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


#: the registered id of each packaged scenario, by name
_SCENARIO_ID = {name: env_id for env_id, name in SCENARIO_IDS.items()}


def _eval_target(scenario: str | os.PathLike[str]) -> str:
    """The id of a packaged scenario's name, or a scenario file's path."""
    return _SCENARIO_ID.get(os.fspath(scenario), os.fspath(scenario))


def eval_env_ids(env_id: str) -> list[str]:
    """The ids a model trained on ``env_id`` with no env kwargs is evaluated on: the id
    itself, or every packaged scenario's id for the mixture (see :func:`eval_setup`)."""
    return eval_setup(env_id)[0]


def default_out(env_id: str, preset: str, now: float | None = None) -> str:
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    return os.path.join("runs", "train", f"{env_id}-{preset}-{stamp}")


def _env_factory(env_id: str, kwargs: Mapping[str, Any], quiet_sigint: bool) -> Callable:
    def make() -> gym.Env:
        from stable_baselines3.common.monitor import Monitor

        if quiet_sigint:  # runs in the worker process: Ctrl-C is the trainer's
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        return Monitor(gym.make(env_id, **kwargs), info_keywords=("is_success",))

    return make


def make_vec_env(env_id: str, config: TrainConfig, env_kwargs: Mapping[str, Any],
                 seed: int) -> Any:  # fmt: skip
    """The training ``VecEnv`` (seeded: environment i starts with ``seed + i``)."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    subproc = config.vec_env == "subproc" and config.n_envs > 1
    fns = [_env_factory(env_id, env_kwargs, subproc) for _ in range(config.n_envs)]
    venv = SubprocVecEnv(fns, start_method="forkserver") if subproc else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


def check_env_args(env_id: str, preset: str, env_kwargs: Mapping[str, Any],
                   gamma: float = PRESET_GAMMA) -> dict[str, dict[str, float]]:  # fmt: skip
    """Refuse an unknown id or preset, env kwargs the environment refuses and a reward that
    the discount ``gamma`` makes gameable (a collision worth more than going on), now.
    Returns the reward weights of each scenario, as :func:`reward_weights`."""
    if env_id not in gym.registry or not env_id.startswith("SRPB-"):
        ids = sorted(k for k in gym.registry if k.startswith("SRPB-"))
        raise InputError(f"unknown environment {env_id!r}; choose one of: {', '.join(ids)}",
                         key="--env")  # fmt: skip
    if preset not in preset_names():
        raise InputError(f"choose one of: {', '.join(preset_names())}", key="--reward")
    try:
        env = gym.make(env_id, reward=preset, **env_kwargs)
    except (TypeError, ValueError) as exc:
        raise env_kwargs_error(env_id, exc) from None
    try:
        base = env.unwrapped
        weights_of = _weights_of(base)
        if base.task.collision_mode != "terminate":
            return weights_of
        for scenario, task in _scenario_tasks(base):  # a mixture's, each with its weights
            weights = task.reward_fn.weights
            penalty = -float(weights[TERMS.index("collision")])
            bound = shaping_bound(weights, scenario.time_limit, base.sim.config.control_dt,
                                  base.sim.robot_config, gamma)  # fmt: skip
            if bound > 0.0 and bound >= penalty:
                raise InputError(
                    f"with gamma {gamma:g} the shaping of the {preset!r} reward in scenario "
                    f"{scenario.name!r} can cost up to {bound:.3g} (discounted) from any "
                    f"state, not less than the collision penalty {penalty:g}: a policy could "
                    "learn to crash. Lower gamma or the shaping weights, or raise "
                    "'collision'", key="--hyperparams: gamma")  # fmt: skip
        return weights_of
    finally:
        env.close()


def _scenario_tasks(base: Any) -> list[tuple[Any, Any]]:
    """(scenario, robot task) of each scenario of an environment (one unless a mixture)."""
    names = getattr(base, "scenarios", None)
    if names is None:
        return [(base.scenario, base.task)]
    return [(base.scenario_of(n), base.task_of(n)) for n in names]


def reward_weights(
    env_id: str, preset: str, env_kwargs: Mapping[str, Any] | None = None
) -> dict[str, dict[str, float]]:
    """The reward weights (non-zero ones, by term) that ``env_id`` with ``preset`` and
    ``env_kwargs`` pays in each of its scenarios, by scenario name: the preset's, re-weighted
    by the scenario's ``reward`` section and by ``reward_weights``. ``env_kwargs`` may be
    a run's (its ``config.yaml``): its ``reward`` is ``preset``, and records and rendering,
    which do not change the reward, are left out."""
    skip = ("reward", "record_dir", "render_mode")
    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k not in skip}
    env = gym.make(env_id, reward=preset, **kwargs)
    try:
        return _weights_of(env.unwrapped)
    finally:
        env.close()


def _weights_of(base: Any) -> dict[str, dict[str, float]]:
    return {scenario.name: {t: float(w) for t, w in zip(TERMS, task.reward_fn.weights) if w}
            for scenario, task in _scenario_tasks(base)}  # fmt: skip


def check_eval_targets(env_id: str, eval_ids: Sequence[str]) -> None:
    """Refuse, before any training, periodic evaluations that the evaluation harness
    cannot run: it runs the packaged ids and scenario files, not an id registered
    elsewhere."""
    from srpb_gym.evaluation.spec import ENV_IDS

    for target in eval_ids:
        if target not in ENV_IDS and not os.path.isfile(target):
            raise InputError(
                f"{env_id} is not a packaged environment, and the periodic evaluation runs "
                f"those ({', '.join(ENV_IDS)}) and scenario files only: train "
                "SRPB-Custom-v0 with --env-kwargs scenario=FILE, or set "
                "--hyperparams eval_freq=0", key="--env")  # fmt: skip


def train(
    env_id: str,
    config: TrainConfig,
    *,
    preset: str = "srpb",
    seed: int = 0,
    out: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = True,
    argv: Sequence[str] = (),
    log: Callable[[str], None] = print,
    device: str = "cpu",
    max_minutes: float | None = None,
    init: str | None = None,
    init_new_observation: bool = False,
) -> TrainResult:
    """Train PPO on ``env_id`` with reward preset ``preset``; see the module docstring.
    ``max_minutes``: stop after this much wall time even if steps remain (``run.json``
    then says ``"time_limit_reached": true``). ``init``: start from the weights and
    observation statistics of a trained model (its ``model.zip``, the run folder holding
    it, or a shipped model's name) instead of random weights; the reward statistics start
    afresh, as the reward may differ (fine-tuning a ``task`` model with ``srpb``). A model
    recorded with other observation settings is refused unless ``init_new_observation``
    (the shapes must match either way: a fine-tune to the new settings; ``run.json`` keeps
    the model's settings as ``init.observation``)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.logger import Logger, make_output_format
    from stable_baselines3.common.vec_env import VecNormalize

    env_kwargs = dict(env_kwargs or {})
    if "reward" in env_kwargs:
        raise InputError("set the preset with --reward, not in the env kwargs", key="reward")
    weights = check_env_args(env_id, preset, env_kwargs, config.gamma)
    eval_ids, eval_kwargs = eval_setup(env_id, env_kwargs) if config.eval_freq > 0 else ([], {})
    check_eval_targets(env_id, eval_ids)
    if init is not None and (config.pretrain_planner or config.pretrain_teachers):
        raise InputError("start from a trained model or from demonstrations "
                         "(pretrain_planner, pretrain_teachers), not both",
                         key="--init")  # fmt: skip
    if init_new_observation and init is None:
        raise InputError("names no model to start from (--init)", key="--init-new-observation")
    init_model = None if init is None else resolve_init(init)
    kwargs = {"reward": preset, **env_kwargs}
    if config.torch_threads > 0:
        import torch

        torch.set_num_threads(config.torch_threads)
    out = check_out_dir(out or default_out(env_id, preset))
    os.makedirs(out, exist_ok=True)
    _write_run_files(out, env_id, preset, kwargs, seed, config, argv, weights)

    venv = make_vec_env(env_id, config, kwargs, seed)
    bar: ProgressCallback | None = None
    try:
        if config.normalize:
            venv = VecNormalize(venv, gamma=config.gamma)
        model = PPO(config.policy, venv, seed=seed, device=device, verbose=0,
                    **config.ppo_kwargs())  # fmt: skip
        observation = venv.get_attr("observation_config", [0])[0]
        record_observation(model, observation)
        if init_model is not None:
            try:
                init_observation = _load_init(model, venv, *init_model, observation,
                                              init_new_observation)  # fmt: skip
            except InputError:  # nothing trained: leave no run folder behind
                shutil.rmtree(out, ignore_errors=True)
                raise
            _update_run_json(out, {"init": {"model": init_model[0],
                                            "vecnormalize": init_model[1],
                                            "steps": model_steps(init_model[0]),
                                            "observation": init_observation}})  # fmt: skip
            log(f"starting from {init_model[0]}")
            if init_observation is None:
                named = settings_text(observation, ObservationConfig())
                log(f"note: {init_model[0]} records no observation settings (not saved by "
                    f"srpb-gym train): taken to observe as this run does, "
                    f"observation={named if named != '{}' else 'default'}, and the new "
                    "model records these settings")  # fmt: skip
        if config.pretrain_planner or config.pretrain_teachers:
            from srpb_gym.training.pretrain import pretrain

            try:
                report = pretrain(model, venv, env_id, kwargs, planner=config.pretrain_planner,
                                  episodes=config.pretrain_episodes,
                                  epochs=config.pretrain_epochs, noise=config.pretrain_noise,
                                  log_std=config.pretrain_log_std, gamma=config.gamma, log=log,
                                  teachers=config.pretrain_teachers,
                                  dagger_rounds=config.pretrain_dagger_rounds,
                                  dagger_episodes=config.pretrain_dagger_episodes)  # fmt: skip
            except InputError:  # nothing trained: leave no run folder behind
                shutil.rmtree(out, ignore_errors=True)
                raise
            teachers = {"teachers": config.pretrain_teachers} if config.pretrain_teachers else {}
            _update_run_json(out, {"warm_start": {"planner": config.pretrain_planner,
                                                  **teachers, **report}})  # fmt: skip
        tensorboard = make_output_format("tensorboard", os.path.join(out, "tb"))
        model.set_logger(Logger(out, [make_output_format("csv", out), tensorboard]))
        outcomes = Outcomes()
        callbacks: list[Any] = [EpisodeStatsCallback(outcomes)]
        if progress:
            bar = ProgressCallback(config.n_timesteps, outcomes)
            callbacks.append(bar)
        if config.eval_freq > 0:
            callbacks.append(PeriodicEvalCallback(out, eval_ids, config.eval_freq,
                                                  config.eval_episodes, log, progress,
                                                  env_kwargs=eval_kwargs))  # fmt: skip
        limit = None if max_minutes is None else WallClockLimit(60.0 * max_minutes)
        if limit is not None:
            callbacks.append(limit)
        started = time.perf_counter()
        interrupted = False
        previous = _stop_on_sigterm()
        try:
            model.learn(config.n_timesteps, callback=CallbackList(callbacks), log_interval=1,
                        tb_log_name="tb", progress_bar=False)  # fmt: skip
        except KeyboardInterrupt:
            interrupted = True
            log(f"interrupted at step {model.num_timesteps}: saving the model")
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
            wall = time.perf_counter() - started
            save_checkpoint(model, out)
            _finish_run_json(out, model.num_timesteps, wall, interrupted,
                             limit is not None and limit.reached)  # fmt: skip
            model.logger.close()
    finally:
        if bar is not None and bar.bar is not None:
            bar.bar.close()
        venv.close()
    return TrainResult(out, int(model.num_timesteps), wall, interrupted)


def resolve_init(given: str) -> tuple[str, str | None]:
    """The ``model.zip`` and ``vecnormalize.pkl`` (or ``None``) that ``--init`` names: a
    file, a folder holding ``model.zip``, or a shipped model's name."""
    from srpb_gym.models import find_model
    from srpb_gym.planners.learned import find_vecnormalize

    path = find_model(given)
    if path is None:
        raise InputError(f"no model file, run folder with model.zip or shipped model "
                         f"named {given!r}", key="--init")  # fmt: skip
    return path, find_vecnormalize(path)


def model_steps(path: str) -> int:
    """The training steps a saved SB3 model had taken (its ``num_timesteps``)."""
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(path, device="cpu", load_data=True)
    return int(data.get("num_timesteps", 0))


def _load_init(model: Any, venv: Any, path: str, vecnormalize: str | None,
               observation: ObservationConfig, new_observation: bool = False,
               ) -> dict[str, Any] | None:  # fmt: skip
    """Load ``path``'s weights and statistics into ``model`` and ``venv``; returns the
    model's recorded observation settings, every one (``None``: no record).
    ``new_observation``: accept a record that differs from ``observation``."""
    from stable_baselines3.common.vec_env import VecNormalize

    from srpb_gym.planners.learned import (
        OBSERVATION_RECORD,
        PolicyFileError,
        load_vecnormalize,
        model_data,
    )

    try:
        record = model_data(path).get(OBSERVATION_RECORD)
    except PolicyFileError as exc:
        raise InputError(exc.reason, exc.path, key="--init") from None
    recorded, why = None, None
    if record is not None:
        try:
            recorded = recorded_observation(record)
        except ValueError as exc:  # an invalid record: say why
            raise InputError(f"{path}: {exc}", key="--init") from None
        why = settings_mismatch(recorded, observation)
    if why is not None and not new_observation:
        hint = settings_text(recorded, observation)
        raise InputError(f"{path}: {why} (start from it with --env-kwargs "
                         f"'observation={hint}'); --init-new-observation fine-tunes it "
                         "to this run's settings", key="--init")  # fmt: skip
    settings = None if recorded is None else dataclasses.asdict(recorded)
    try:
        model.set_parameters(path, exact_match=True, device=model.device)
    except (RuntimeError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: its networks do not fit this run's spaces and net_arch "
                         f"({str(exc).splitlines()[0]})", key="--init") from None  # fmt: skip
    if not isinstance(venv, VecNormalize):
        if vecnormalize is not None:
            raise InputError(f"{path}: trained on observations normalised by "
                             f"{vecnormalize}; this run does not normalise (normalize: false)",
                             key="--init")  # fmt: skip
        return settings
    if vecnormalize is None:
        raise InputError(f"{path}: no vecnormalize.pkl beside it, and this run normalises "
                         "observations (normalize: true)", key="--init")  # fmt: skip
    saved = load_vecnormalize(vecnormalize)
    if saved.obs_rms.mean.shape != venv.obs_rms.mean.shape:
        raise InputError(f"{vecnormalize}: statistics of {saved.obs_rms.mean.shape} "
                         f"observations, this environment has {venv.obs_rms.mean.shape}",
                         key="--init")  # fmt: skip
    venv.obs_rms = saved.obs_rms.copy()
    return settings


def _stop_on_sigterm() -> Any:
    """Make SIGTERM stop training as Ctrl-C does (in the main thread only, where Python
    delivers signals); returns the handler to restore, or ``None``."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, stop)


def _write_run_files(out: str, env_id: str, preset: str, env_kwargs: Mapping[str, Any],
                     seed: int, config: TrainConfig, argv: Sequence[str],
                     weights: Mapping[str, Mapping[str, float]]) -> None:  # fmt: skip
    doc = {"algo": "PPO", "env": env_id, "reward": preset, "env_kwargs": dict(env_kwargs),
           "seed": seed, "hyperparams": config.as_dict()}  # fmt: skip
    with open(os.path.join(out, "config.yaml"), "w", encoding="utf-8") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    with open(os.path.join(out, "command.txt"), "w", encoding="utf-8") as f:
        f.write(shlex.join(["srpb-gym", *argv]) + "\n")
    run = {"env": env_id, "reward": preset, "reward_weights": weights, "seed": seed,
           "versions": versions(), "machine": machine(),
           "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}  # fmt: skip
    with open(os.path.join(out, "run.json"), "w", encoding="utf-8") as f:
        json.dump(run, f, indent=2)


def _finish_run_json(out: str, steps: int, wall: float, interrupted: bool,
                     time_limit_reached: bool) -> None:  # fmt: skip
    _update_run_json(out, {"steps": int(steps), "wall_time_s": round(wall, 1),
                           "interrupted": interrupted,
                           "time_limit_reached": time_limit_reached})  # fmt: skip


def _update_run_json(out: str, values: Mapping[str, Any]) -> None:
    path = os.path.join(out, "run.json")
    with open(path, encoding="utf-8") as f:
        run = json.load(f)
    run |= dict(values)
    with open(path, "w", encoding="utf-8") as f:
        json.dump(run, f, indent=2)


def machine() -> dict[str, Any]:
    """The machine a run trained on: processor, logical cores, operating system."""
    import torch

    return {"processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(), "system": platform.platform(),
            "torch_threads": torch.get_num_threads()}  # fmt: skip
