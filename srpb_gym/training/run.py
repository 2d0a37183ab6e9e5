"""One PPO training run and its run folder, in three phases.

:func:`train` runs them: :func:`set_up` checks every setting, writes the run folder's first
files (:mod:`srpb_gym.training.run_folder`), makes ``n_envs`` environments
(``gym.make(env_id, reward=preset, **env_kwargs)`` in a ``Monitor``, one process each with
``vec_env: subproc``), wraps them in ``VecNormalize`` when the configuration says so
(:func:`normalize`: the reward never clipped, so that the learner sees a collision's full
penalty), makes
the ``stable_baselines3.PPO`` model and starts it from a trained model (``--init``) or from
demonstrations (:mod:`srpb_gym.training.pretrain`); :func:`learn` trains it with the
callbacks of :mod:`srpb_gym.training.callbacks`; :func:`save` writes the model and the
last facts. The run folder:

| file | what |
| --- | --- |
| ``model.zip``, ``vecnormalize.npz`` | the final policy and its observation statistics |
| ``best/`` | the checkpoint with the best periodic evaluation |
| ``config.yaml`` | every resolved setting: env id, preset, env kwargs, seed, hyperparameters |
| ``command.txt`` | the command line |
| ``run.json`` | reward weights of each scenario, seed, versions, machine, steps, wall time |
| ``progress.csv``, ``tb/`` | the SB3 logger (CSV and TensorBoard) |
| ``evaluations.csv``, ``eval/`` | the periodic evaluations (``srpb-gym eval`` run folders) |

Ctrl-C, or SIGTERM (what a batch scheduler or ``kill`` sends), stops training after the
current step and still saves a usable ``model.zip`` and ``vecnormalize.npz`` (``run.json``
says ``"interrupted": true``). Subprocess environments ignore Ctrl-C, so that only the
training process handles it.

The statistics are numbers (:mod:`srpb_gym.models.normalization`), not the pickle of
``VecNormalize.save``. A model to start from (``--init``) is read before the run folder
is made, its pickles never unpickled unless ``trust_pickle`` (``--trust-pickle``); a
start that fails leaves nothing behind (a folder that was there, empty, stays, empty).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shutil
import signal
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from srpb_gym.errors import InputError
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.models.files import resolve_model
from srpb_gym.models.loading import (
    PolicyFileError,
    VecNormalizeError,
    model_steps,
    tensors_only,
)
from srpb_gym.models.normalization import Normalization, load_vecnormalize
from srpb_gym.models.record import (
    describe_space,
    read_record,
    record_observation,
    recorded_observation,
    settings_mismatch,
    settings_text,
)
from srpb_gym.observation import ObservationConfig
from srpb_gym.seeds import TRAINING, check_within
from srpb_gym.training.callbacks import (
    EpisodeStatsCallback,
    Outcomes,
    PeriodicEvalCallback,
    ProgressCallback,
    SeenRewardCallback,
    WallClockLimit,
    save_checkpoint,
)
from srpb_gym.training.checks import check_eval_targets, check_reward
from srpb_gym.training.config import Pretraining, TrainConfig
from srpb_gym.training.pretrain import pretrain
from srpb_gym.training.run_folder import (
    default_out,
    finish_run_json,
    update_run_json,
    write_run_files,
)
from srpb_gym.training.targets import eval_setup


@dataclass
class TrainResult:
    """What a run produced: its folder, the steps done, the wall time [s] and whether
    Ctrl-C stopped it."""

    out: str
    steps: int
    wall_time: float
    interrupted: bool


@dataclass
class Run:
    """A run set up (:func:`set_up`): its folder, configuration, model and environments
    (``env_kwargs`` with the preset as ``reward``; ``observation``: their observation
    settings, which the model records), what the periodic evaluations run and each
    scenario's collision penalty and shaping bound (``bounds``, checked on the reward the
    learner sees: :class:`~srpb_gym.training.callbacks.SeenRewardCallback`);
    then what :func:`learn` did (its start, wall time, whether Ctrl-C or SIGTERM stopped
    it, its progress bar and wall-clock limit)."""

    out: str
    env_id: str
    env_kwargs: dict[str, Any]
    config: TrainConfig
    model: Any
    venv: Any
    observation: ObservationConfig
    eval_ids: list[str]
    eval_kwargs: dict[str, Any]
    bounds: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    started: float | None = None
    wall: float = 0.0
    interrupted: bool = False
    bar: ProgressCallback | None = None
    limit: WallClockLimit | None = None

    def result(self) -> TrainResult:
        return TrainResult(self.out, int(self.model.num_timesteps), self.wall, self.interrupted)

    def close(self) -> None:
        """Close the progress bar and the environments."""
        if self.bar is not None and self.bar.bar is not None:
            self.bar.bar.close()
        self.venv.close()


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
    trust_pickle: bool = False,
    on_eval: Callable[[int, dict[str, dict[str, float]]], None] | None = None,
) -> TrainResult:
    """Train PPO on ``env_id`` with reward preset ``preset``; see the module docstring.
    ``max_minutes``: stop after this much wall time even if steps remain (``run.json``
    then says ``"time_limit_reached": true``). ``init``: start from the weights and
    observation statistics of a trained model (its ``model.zip``, the run folder holding
    it, or a shipped model's name) instead of random weights; the reward statistics start
    afresh, as the reward may differ (fine-tuning a ``task`` model with ``srpb``). A model
    recorded with other observation settings is refused unless ``init_new_observation``
    (the shapes must match either way: a fine-tune to the new settings; ``run.json`` keeps
    the model's settings as ``init.observation``). ``trust_pickle``: let the pickles of
    ``init`` and of the warm start's teachers be unpickled (``--trust-pickle``).
    ``on_eval``: called with the step and the figures of each periodic evaluation."""
    run = set_up(env_id, config, preset=preset, seed=seed, out=out, env_kwargs=env_kwargs,
                 argv=argv, log=log, device=device, init=init,
                 init_new_observation=init_new_observation,
                 trust_pickle=trust_pickle)  # fmt: skip
    try:
        try:
            learn(run, progress=progress, log=log, max_minutes=max_minutes, on_eval=on_eval)
        finally:
            if run.started is not None:  # saved however learning ended
                save(run)
    finally:
        run.close()
    return run.result()


def set_up(
    env_id: str,
    config: TrainConfig,
    *,
    preset: str = "srpb",
    seed: int = 0,
    out: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    argv: Sequence[str] = (),
    log: Callable[[str], None] = print,
    device: str = "cpu",
    init: str | None = None,
    init_new_observation: bool = False,
    trust_pickle: bool = False,
) -> Run:
    """Check the settings and read the model ``init`` (before anything is written), write
    ``config.yaml``, ``command.txt`` and ``run.json``, make the environments and the
    model, and start the model from ``init`` or from the warm start of ``config`` (see
    :func:`train`). A start that fails leaves no run folder behind (a folder that was
    there stays, empty)."""
    from stable_baselines3 import PPO

    env_kwargs = dict(env_kwargs or {})
    if "reward" in env_kwargs:
        raise InputError("set the preset with --reward, not in the env kwargs", key="reward")
    check_within(TRAINING, seed, config.n_envs, "--seed")  # environment i: seed + i
    checked = check_reward(env_id, preset, env_kwargs, config.gamma)
    eval_ids, eval_kwargs = eval_setup(env_id, env_kwargs) if config.eval_freq > 0 else ([], {})
    check_eval_targets(env_id, eval_ids)
    pretraining = config.pretraining
    if init is not None and pretraining is not None:
        raise InputError("start from a trained model or from demonstrations "
                         "(pretrain_planner, pretrain_teachers), not both",
                         key="--init")  # fmt: skip
    if init_new_observation and init is None:
        raise InputError("names no model to start from (--init)", key="--init-new-observation")
    init_model = None if init is None else read_init(init, trust_pickle)
    kwargs = {"reward": preset, **env_kwargs}
    if config.torch_threads > 0:
        import torch

        torch.set_num_threads(config.torch_threads)
    out = out or default_out(env_id, preset)
    existed = os.path.isdir(out)
    out = check_out_dir(out)
    try:
        write_run_files(out, env_id, preset, kwargs, seed, config, argv, checked.weights)
        venv = make_vec_env(env_id, config, kwargs, seed)
    except InputError:
        discard_run(out, existed)
        raise
    try:
        if config.normalize:
            venv = normalize(venv, config)
        model = PPO(config.policy, venv, seed=seed, device=device, verbose=0,
                    **config.ppo_kwargs())  # fmt: skip
        observation = venv.get_attr("observation_config", [0])[0]
        record_observation(model, observation)
        run = Run(out, env_id, kwargs, config, model, venv, observation, eval_ids, eval_kwargs,
                  checked.bounds)  # fmt: skip
        try:
            if init_model is not None:
                _start_from(run, init_model, init_new_observation, log)
            if pretraining is not None:
                _warm_start(run, pretraining, log, trust_pickle)
        except InputError:  # nothing trained: leave no run folder behind
            discard_run(out, existed)
            raise
    except BaseException:
        venv.close()
        raise
    return run


def discard_run(out: str, existed: bool) -> None:
    """Remove what a run that failed to start wrote: the folder ``out``, or, when it
    ``existed`` (empty) before, only what it holds now."""
    if not existed:
        shutil.rmtree(out, ignore_errors=True)
        return
    for entry in os.scandir(out):
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path, ignore_errors=True)
        else:
            os.remove(entry.path)


@dataclass(frozen=True)
class InitModel:
    """A trained model to start from (``--init``), read before anything is written: its
    file, its statistics file (or ``None``) and their numbers, its observation record (a
    mapping, or ``None``), its tensors and the steps it took."""

    path: str
    vecnormalize: str | None
    stats: Normalization | None
    record: Any
    params: dict[str, Any]
    steps: int


def read_init(given: str, trust_pickle: bool = False) -> InitModel:
    """Read the model that ``given`` names (:func:`resolve_model`) and its statistics:
    tensors only (``weights_only``), a pickled statistics file only with
    ``trust_pickle``. Every failure is an :class:`InputError` naming the file, key
    ``--init``."""
    from stable_baselines3.common.save_util import load_from_zip_file

    path, vecnormalize = resolve_model(given, "--init")
    try:
        record = read_record(path)
        steps = model_steps(path)
        loader = contextlib.nullcontext() if trust_pickle else tensors_only()
        with loader:
            _, params, _ = load_from_zip_file(path, device="cpu", load_data=False)
    except PolicyFileError as exc:
        raise InputError(exc.reason, exc.path, key="--init") from None
    except Exception as exc:  # a damaged zip, or tensors that are not only tensors
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"its tensors cannot be read ({why})", path, key="--init") from None
    if not params:
        raise InputError("holds no tensors (policy.pth)", path, key="--init")
    stats = None
    if vecnormalize is not None:
        try:
            stats = load_vecnormalize(vecnormalize, trust_pickle)
        except VecNormalizeError as exc:
            raise InputError(exc.reason, exc.path, key="--init") from None
    return InitModel(path, vecnormalize, stats, record, params, steps)


def _start_from(run: Run, init: InitModel, new_observation: bool,
                log: Callable[[str], None]) -> None:  # fmt: skip
    """Start the model from the trained one read into ``init`` (``--init``), and say so in
    ``run.json``."""
    observation, path = run.observation, init.path
    init_observation = load_init(run.model, run.venv, init, observation, new_observation)
    update_run_json(run.out, {"init": {"model": path, "vecnormalize": init.vecnormalize,
                                       "steps": init.steps,
                                       "observation": init_observation}})  # fmt: skip
    log(f"starting from {path}")
    if init_observation is None:
        named = settings_text(observation, ObservationConfig())
        log(f"note: {path} records no observation settings (not saved by "
            f"srpb-gym train): taken to observe as this run does, "
            f"observation={named if named != '{}' else 'default'}, and the new "
            "model records these settings")  # fmt: skip


def _warm_start(run: Run, settings: Pretraining, log: Callable[[str], None],
                trust_pickle: bool = False) -> None:  # fmt: skip
    """Start the model from demonstrations (:func:`pretrain`), and say so in ``run.json``."""
    report = pretrain(run.model, run.venv, run.env_id, run.env_kwargs, settings,
                      gamma=run.config.gamma, log=log, trust_pickle=trust_pickle)  # fmt: skip
    teachers = {"teachers": dict(settings.teachers)} if settings.teachers else {}
    update_run_json(run.out, {"warm_start": {"planner": settings.planner,
                                             **teachers, **report}})  # fmt: skip


def learn(run: Run, *, progress: bool = True, log: Callable[[str], None] = print,
          max_minutes: float | None = None,
          on_eval: Callable[[int, dict[str, dict[str, float]]], None] | None = None,
          ) -> None:  # fmt: skip
    """Train the model of ``run`` for its ``n_timesteps``, with the logger (``progress.csv``,
    ``tb/``) and callbacks of a run, until the steps are done, ``max_minutes`` have passed
    or Ctrl-C or SIGTERM stops it (``run.interrupted``)."""
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.logger import Logger, make_output_format

    model, config, out = run.model, run.config, run.out
    tensorboard = make_output_format("tensorboard", os.path.join(out, "tb"))
    model.set_logger(Logger(out, [make_output_format("csv", out), tensorboard]))
    outcomes = Outcomes()
    callbacks: list[Any] = [EpisodeStatsCallback(outcomes), SeenRewardCallback(run.bounds, log)]
    if progress:
        run.bar = ProgressCallback(config.n_timesteps, outcomes)
        callbacks.append(run.bar)
    if config.eval_freq > 0:
        callbacks.append(PeriodicEvalCallback(out, run.eval_ids, config.eval_freq,
                                              config.eval_episodes, log, progress,
                                              env_kwargs=run.eval_kwargs,
                                              on_eval=on_eval))  # fmt: skip
    run.limit = None if max_minutes is None else WallClockLimit(60.0 * max_minutes)
    if run.limit is not None:
        callbacks.append(run.limit)
    run.started = time.perf_counter()
    previous = _stop_on_sigterm()
    try:
        model.learn(config.n_timesteps, callback=CallbackList(callbacks), log_interval=1,
                    tb_log_name="tb", progress_bar=False)  # fmt: skip
    except KeyboardInterrupt:
        run.interrupted = True
        log(f"interrupted at step {model.num_timesteps}: saving the model")
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        run.wall = time.perf_counter() - run.started


def save(run: Run) -> None:
    """Save the model and its statistics (``model.zip``, ``vecnormalize.npz``), finish
    ``run.json`` and close the logger."""
    save_checkpoint(run.model, run.out)
    finish_run_json(run.out, run.model.num_timesteps, run.wall, run.interrupted,
                    run.limit is not None and run.limit.reached)  # fmt: skip
    run.model.logger.close()


def _env_factory(env_id: str, kwargs: Mapping[str, Any], quiet_sigint: bool) -> Callable:
    def make() -> gym.Env:
        from stable_baselines3.common.monitor import Monitor

        if quiet_sigint:  # runs in the worker process: Ctrl-C is the trainer's
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        return Monitor(gym.make(env_id, **kwargs), info_keywords=("is_success",))

    return make


def normalize(venv: Any, config: TrainConfig) -> Any:
    """``venv`` in the ``VecNormalize`` of a run: observations and rewards normalised, the
    return's statistics discounted by ``config.gamma``, the reward divided by their sigma
    and never clipped (:data:`~srpb_gym.training.config.REWARD_CLIP`)."""
    from stable_baselines3.common.vec_env import VecNormalize

    return VecNormalize(venv, **config.vecnormalize_kwargs())


def make_vec_env(env_id: str, config: TrainConfig, env_kwargs: Mapping[str, Any],
                 seed: int) -> Any:  # fmt: skip
    """The training ``VecEnv`` (seeded: environment i starts with ``seed + i``)."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    subproc = config.vec_env == "subproc" and config.n_envs > 1
    fns = [_env_factory(env_id, env_kwargs, subproc) for _ in range(config.n_envs)]
    venv = SubprocVecEnv(fns, start_method="forkserver") if subproc else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


def load_init(model: Any, venv: Any, init: InitModel, observation: ObservationConfig,
              new_observation: bool = False) -> dict[str, Any] | None:  # fmt: skip
    """Load the weights and statistics of ``init`` (:func:`read_init`) into ``model`` and
    ``venv``; returns the model's recorded observation settings, every one (``None``: no
    record). ``new_observation``: accept a record that differs from ``observation``."""
    from stable_baselines3.common.vec_env import VecNormalize

    path, vecnormalize = init.path, init.vecnormalize
    recorded, why = None, None
    if init.record is not None:
        try:
            recorded = recorded_observation(init.record)
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
        model.set_parameters(init.params, exact_match=True, device=model.device)
    except (RuntimeError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: its networks do not fit this run's spaces and net_arch "
                         f"({state_dict_mismatch(exc)})", key="--init") from None  # fmt: skip
    if not isinstance(venv, VecNormalize):
        if vecnormalize is not None:
            raise InputError(f"{path}: trained on observations normalised by "
                             f"{vecnormalize}; this run does not normalise (normalize: false)",
                             key="--init")  # fmt: skip
        return settings
    if init.stats is None:
        raise InputError(f"{path}: no vecnormalize.npz beside it, and this run normalises "
                         "observations (normalize: true)", key="--init")  # fmt: skip
    saved = init.stats.obs_rms
    if isinstance(saved, dict) or isinstance(venv.obs_rms, dict):
        same = isinstance(saved, dict) and isinstance(venv.obs_rms, dict) and all(
            k in saved and saved[k].mean.shape == v.mean.shape for k, v in venv.obs_rms.items()
        )  # fmt: skip
        shapes = "another observation space"
    else:
        same = saved.mean.shape == venv.obs_rms.mean.shape
        shapes = f"{saved.mean.shape} observations"
    if not same:
        raise InputError(f"{vecnormalize}: statistics of {shapes}, this environment has "
                         f"{describe_space(venv.observation_space)}", key="--init")  # fmt: skip
    venv.obs_rms = saved
    return settings


def state_dict_mismatch(exc: BaseException, shown: int = 2) -> str:
    """Why weights do not fit a network, in one line: torch's first ``shown`` reasons
    (the layers and shapes that differ) after its heading, and how many more."""
    lines = [" ".join(line.split()) for line in str(exc).splitlines()]
    lines = [line for line in lines if line]
    if not lines:
        return type(exc).__name__
    reasons = lines[1:] if len(lines) > 1 else lines
    more = f" and {len(reasons) - shown} more" if len(reasons) > shown else ""
    return "; ".join(reasons[:shown]) + more


def _stop_on_sigterm() -> Any:
    """Make SIGTERM stop training as Ctrl-C does (in the main thread only, where Python
    delivers signals); returns the handler to restore, or ``None``."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, stop)
