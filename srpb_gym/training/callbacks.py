"""stable-baselines3 callbacks of a training run.

* :class:`EpisodeStatsCallback`: at the end of every training episode, its sum of each
  weighted reward term (``reward/<term>``), every episode SRPB metric of its last info
  (``srpb/<metric>``) and its outcome (``episode/success``, ``episode/collision``,
  ``episode/timeout``) go to the logger as means over the episodes of a rollout; SB3 by
  itself logs only ``is_success``. Recent outcomes feed the progress bar.
* :class:`ProgressCallback`: a tqdm bar of environment steps with the episodes, the success
  and collision rates of the last 100 episodes and the time left.
* :class:`PeriodicEvalCallback`: every ``eval_freq`` steps, saves a checkpoint (model and
  ``VecNormalize`` statistics) and evaluates it with the harness of ``srpb-gym eval`` on
  the checkpoint-selection seeds (:data:`srpb_gym.seeds.CHECKPOINT_SELECTION`, never
  trained on, never test seeds); logs ``eval/...``, appends ``evaluations.csv`` and keeps
  the best checkpoint in ``best/``.
* :class:`SeenRewardCallback`: the reward as the learner sees it (normalised by
  ``VecNormalize``): logs the fraction of clipped rewards (``train/reward_clip_fraction``)
  and checks at every rollout that a collision still costs the learner more than the
  shaping can (``train/collision_margin``, :func:`seen_margin`).
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from tqdm import tqdm

from srpb_gym.evaluation import harness, spec
from srpb_gym.metrics.episode import METRIC_NAMES
from srpb_gym.models.files import VECNORMALIZE
from srpb_gym.models.normalization import save_vecnormalize
from srpb_gym.models.shipped import MODEL_FILE
from srpb_gym.reward import TERMS
from srpb_gym.seeds import CHECKPOINT_SELECTION, check_not_test, check_within

#: the seed of the first evaluation episode (:data:`srpb_gym.seeds.CHECKPOINT_SELECTION`)
EVAL_SEED = CHECKPOINT_SELECTION.start
#: metrics whose median over the evaluation episodes is logged and written, from the
#: tracked people (``m_psi``) and from the true people (``gt_m_psi``)
EVAL_METRICS = ("m_psi", "m_fsi", "m_dir", "m_mef", "m_plin", "m_obs")
TRUTH_METRICS = tuple(f"gt_{m}" for m in EVAL_METRICS)
EVAL_COLUMNS = ("step", "env", "episodes", "success", "collision", "timeout",
                *EVAL_METRICS, *TRUTH_METRICS)  # fmt: skip
#: the median that breaks a tie of success rates between evaluations: ``m_psi`` from the
#: true people (the distance a policy keeps is what it keeps from them; the tracked figure
#: also moves with the tracker's noise)
CHOOSE_BY = "gt_m_psi"


class Outcomes:
    """The outcomes of the most recent ``size`` training episodes (shared by callbacks)."""

    def __init__(self, size: int = 100) -> None:
        self.recent: deque[tuple[bool, bool]] = deque(maxlen=size)
        self.episodes = 0

    def add(self, success: bool, collision: bool) -> None:
        self.recent.append((success, collision))
        self.episodes += 1

    def rates(self) -> tuple[float, float]:
        """Success and collision rates of the recent episodes (NaN before the first)."""
        if not self.recent:
            return math.nan, math.nan
        arr = np.array(self.recent, dtype=np.float64)
        return float(arr[:, 0].mean()), float(arr[:, 1].mean())


class EpisodeStatsCallback(BaseCallback):
    """Logs every reward term, every ``srpb/*`` metric and the outcome of each episode."""

    def __init__(self, outcomes: Outcomes | None = None) -> None:
        super().__init__()
        self.outcomes = outcomes if outcomes is not None else Outcomes()
        self._keys = [f"reward_{t}" for t in TERMS]
        self._sums: np.ndarray | None = None
        self._metric_keys = [f"srpb/{m}" for m in METRIC_NAMES]

    def _on_training_start(self) -> None:
        self._sums = np.zeros((self.training_env.num_envs, len(TERMS)))
        self._collided = np.zeros(self.training_env.num_envs, dtype=bool)

    def _on_step(self) -> bool:
        infos: Sequence[dict[str, Any]] = self.locals["infos"]
        dones = self.locals["dones"]
        sums = self._sums
        assert sums is not None
        for i, info in enumerate(infos):
            row = sums[i]
            for k, key in enumerate(self._keys):
                row[k] += info[key]
            self._collided[i] |= bool(info["collision"])  # any step (collision="continue")
            if not dones[i]:
                continue
            for k, term in enumerate(TERMS):
                self.logger.record_mean(f"reward/{term}", float(row[k]))
            row[:] = 0.0
            for key in self._metric_keys:
                value = info.get(key)
                if value is not None and math.isfinite(value):
                    self.logger.record_mean(key, float(value))
            success, collision = bool(info["is_success"]), bool(self._collided[i])
            self._collided[i] = False
            truncated = bool(info.get("TimeLimit.truncated", False))
            self.logger.record_mean("episode/success", float(success))
            self.logger.record_mean("episode/collision", float(collision))
            self.logger.record_mean("episode/timeout", float(truncated and not success))
            self.outcomes.add(success, collision)
        return True


class ProgressCallback(BaseCallback):
    """A progress bar of environment steps: episodes, recent success and collision rates,
    and the time left (tqdm's estimate)."""

    def __init__(self, total: int, outcomes: Outcomes, start: int = 0, every: float = 1.0) -> None:
        super().__init__()
        self.total, self.outcomes, self.start, self.every = total, outcomes, start, every
        self.bar: Any = None
        self._shown = 0.0

    def _on_training_start(self) -> None:
        self.bar = tqdm(total=self.total, initial=self.start, unit="step", dynamic_ncols=True,
                        smoothing=0.05)  # fmt: skip

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        now = time.monotonic()
        if now - self._shown >= self.every:
            self._shown = now
            success, collision = self.outcomes.rates()
            self.bar.set_postfix_str(
                f"episodes {self.outcomes.episodes}, success {_pct(success)}, "
                f"collision {_pct(collision)} (last 100)", refresh=False)  # fmt: skip
        return True

    def _on_training_end(self) -> None:
        if self.bar is not None:
            self.bar.close()


class WallClockLimit(BaseCallback):
    """Stops training (as a finished run, the model saved) after ``seconds`` of wall time."""

    def __init__(self, seconds: float) -> None:
        super().__init__()
        self.seconds = seconds
        self.reached = False
        self._start = 0.0

    def _on_training_start(self) -> None:
        self._start = time.monotonic()

    def _on_step(self) -> bool:
        self.reached = time.monotonic() - self._start >= self.seconds
        return not self.reached


def _pct(value: float) -> str:
    return "-" if math.isnan(value) else f"{100 * value:.0f}%"


class PeriodicEvalCallback(BaseCallback):
    """Every ``eval_freq`` environment steps: a checkpoint in ``<run>/checkpoints/<step>``,
    evaluated by the ``srpb-gym eval`` harness on ``env_ids`` (``episodes`` episodes each,
    seeds from ``seed``, default :data:`EVAL_SEED`; a test seed, or one outside the
    checkpoint-selection seeds, is an :class:`~srpb_gym.errors.InputError`) into
    ``<run>/eval/<step>``. The best checkpoint (highest success rate over all evaluated
    environments, then lowest median ``m_psi`` from the true people: :func:`eval_score`)
    is copied to ``<run>/best``. Only the latest and the best checkpoints are kept, and
    only the evaluation folders of the latest and the best evaluation (each evaluation's figures
    stay in ``evaluations.csv``; the records of all of them would fill a disk: about 75 MB
    per evaluation of the five-scenario mixture, 4.5 GB in a 3-million-step run). ``env_kwargs``:
    keyword arguments of the evaluated environments (those of training that change what
    the policy sees or meets, e.g. ``observation`` or ``crowd``). ``on_eval``: called with
    the step and the figures by environment after each evaluation (a Ray Tune trial
    reports them: :mod:`srpb_gym.training.tune`)."""

    def __init__(self, run_dir: str, env_ids: Sequence[str], eval_freq: int, episodes: int,
                 log: Any = None, progress: bool = True,
                 env_kwargs: Mapping[str, Any] | None = None,
                 seed: int = EVAL_SEED,
                 on_eval: Callable[[int, dict[str, dict[str, float]]], None] | None = None,
                 ) -> None:  # fmt: skip
        super().__init__()
        self.on_eval = on_eval
        check_not_test(seed, episodes, "periodic evaluation seed")
        check_within(CHECKPOINT_SELECTION, seed, episodes, "periodic evaluation seed")
        self.seed = seed
        self.env_kwargs = dict(env_kwargs or {})
        self.progress = progress
        self.run_dir, self.env_ids = run_dir, list(env_ids)
        self.eval_freq, self.episodes = eval_freq, episodes
        self.log = log or (lambda line: None)
        self.best: tuple[float, float] | None = None
        self._next = eval_freq
        self._latest: str | None = None
        self._latest_eval: str | None = None
        self._best_eval: str | None = None
        self.csv_path = os.path.join(run_dir, "evaluations.csv")

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self.eval_freq + 1) * self.eval_freq

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self._next += self.eval_freq
            self.evaluate()
        return True

    def evaluate(self) -> dict[str, dict[str, float]]:
        """Checkpoint and evaluate now; returns the figures by environment id."""
        step = self.num_timesteps
        ckpt = os.path.join(self.run_dir, "checkpoints", f"step_{step:09d}")
        save_checkpoint(self.model, ckpt)
        folder = os.path.join(self.run_dir, "eval", f"step_{step:09d}")
        config = spec.resolve_config(
            self.env_ids, policies=[os.path.join(ckpt, MODEL_FILE)], episodes=self.episodes,
            seed=self.seed, out=folder,
            warmup=0, log=None, env_kwargs=self.env_kwargs,
        )  # fmt: skip
        outcome = harness.run_evaluation(config, log=self.log, progress=self.progress)
        if outcome.interrupted:  # Ctrl-C or SIGTERM during it: stop training, as it would
            shutil.rmtree(folder, ignore_errors=True)  # a cut-short evaluation scores nothing
            raise KeyboardInterrupt("during a periodic evaluation")
        figures = summarize_results(outcome.results)
        rows = []
        for env_id, fig in figures.items():
            prefix = "eval" if len(figures) == 1 else f"eval/{env_id}"
            for key, value in fig.items():
                if key != "episodes" and math.isfinite(value):
                    self.logger.record(f"{prefix}/{key}", value)
            rows.append({"step": step, "env": env_id, **fig})
        self._append(rows)
        score = eval_score(figures.values())
        success = score[0]
        self.logger.record("eval/mean_success", success)
        previous = {self._latest_eval, self._best_eval}
        if self.best is None or score > self.best:
            self.best = score
            best = os.path.join(self.run_dir, "best")
            shutil.rmtree(best, ignore_errors=True)
            shutil.copytree(ckpt, best)
            self._best_eval = folder
        self._latest_eval = folder
        for path in previous - {folder, self._best_eval, None}:
            shutil.rmtree(path, ignore_errors=True)
        self._prune(ckpt)
        self.log(f"eval at step {step}: success {100 * success:.0f}% "
                 f"(best {100 * self.best[0]:.0f}%)")  # fmt: skip
        if self.on_eval is not None:
            self.on_eval(step, figures)
        return figures

    def _append(self, rows: list[dict[str, Any]]) -> None:
        new = not os.path.exists(self.csv_path)
        with open(self.csv_path, "a", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=EVAL_COLUMNS)
            if new:
                writer.writeheader()
            for row in rows:
                writer.writerow({k: _cell(row[k]) for k in EVAL_COLUMNS})

    def _prune(self, latest: str) -> None:
        if self._latest is not None and self._latest != latest:
            shutil.rmtree(self._latest, ignore_errors=True)
        self._latest = latest


class SeenRewardCallback(BaseCallback):
    """The reward the learner sees, after ``VecNormalize`` divided it by the spread of the
    return (sigma) and clipped it: at the end of every rollout, logs the fraction of its
    steps whose reward was clipped (``train/reward_clip_fraction``) and the smallest
    margin, over the scenarios, by which a collision costs the learner more than the
    shaping can (``train/collision_margin``, in units of the normalised reward:
    :func:`seen_margin`). ``bounds``: each scenario's collision penalty and discounted
    shaping bound, raw (:attr:`srpb_gym.training.checks.RewardCheck.bounds`; empty: no
    bound to check). A margin that is not positive is said once through ``log``: then a
    policy could learn to crash, although the raw reward forbids it."""

    def __init__(self, bounds: Mapping[str, tuple[float, float]], log: Any = None) -> None:
        super().__init__()
        self.bounds = dict(bounds)
        self.log = log or (lambda line: None)
        self.steps = self.clipped = 0
        self.margin = math.inf
        self.warned = False

    def _on_step(self) -> bool:
        venv = self.model.get_vec_normalize_env()
        if venv is None or not venv.norm_reward:
            return True
        raw = np.asarray(venv.get_original_reward(), dtype=np.float64)
        self.steps += raw.size
        self.clipped += int(np.count_nonzero(np.abs(raw) / reward_sigma(venv) > venv.clip_reward))
        return True

    def _on_rollout_end(self) -> None:
        venv = self.model.get_vec_normalize_env()
        if venv is None or not venv.norm_reward:
            return
        self.logger.record("train/reward_clip_fraction", self.clipped / max(self.steps, 1))
        self.steps = self.clipped = 0
        if not self.bounds:
            return
        self.margin = min(seen_margin(venv, p, b) for p, b in self.bounds.values())
        self.logger.record("train/collision_margin", self.margin)
        if self.margin <= 0.0 and not self.warned:
            self.warned = True
            self.log(f"warning: at step {self.num_timesteps} the learner sees a collision "
                     f"as costing {self.margin:.3g} less than the shaping bound (the "
                     f"normalised reward is clipped to {venv.clip_reward:g}): a policy could "
                     "learn to crash")  # fmt: skip


def reward_sigma(venv: Any) -> float:
    """The spread of the discounted return that ``venv`` (a ``VecNormalize``) divides each
    reward by."""
    return float(np.sqrt(venv.ret_rms.var + venv.epsilon))


def seen_margin(venv: Any, penalty: float, bound: float) -> float:
    """How much more a collision costs the learner than the shaping can, as ``venv`` (a
    ``VecNormalize``) normalises the reward now: the normalised (and clipped) collision
    penalty less the shaping bound divided by sigma (a clip only shrinks the shaping's
    steps further). Positive: no policy gains by crashing, as the learner sees it."""
    seen = -float(venv.normalize_reward(np.array([-penalty]))[0])
    return seen - bound / reward_sigma(venv)


def eval_score(figures: Iterable[Mapping[str, float]], psi: str = CHOOSE_BY
               ) -> tuple[float, float]:  # fmt: skip
    """How good one evaluation is, by environment figures (higher is better): the mean
    success rate, then the negated mean of the median m_psi (-inf when none is defined);
    ``psi``: the figure read as that median (default :data:`CHOOSE_BY`, the one from the
    true people; ``"m_psi"``: the tracked one, which chose ``best/`` in runs whose
    ``evaluations.csv`` has no ``gt_m_psi``)."""
    figures = list(figures)
    success = sum(f["success"] for f in figures) / len(figures)
    medians = [f[psi] for f in figures if math.isfinite(f[psi])]
    return success, -sum(medians) / len(medians) if medians else -math.inf


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return value


def summarize_results(results: Sequence[Any]) -> dict[str, dict[str, float]]:
    """Success, collision and timeout rates and the median of :data:`EVAL_METRICS`, by
    environment, of the harness's episode results, from the tracked people (``m_psi``) and
    from the true people (``gt_m_psi``; NaN where no episode has the ground truth)."""
    out: dict[str, dict[str, float]] = {}
    for env_id in dict.fromkeys(r.env for r in results):
        rows = [r for r in results if r.env == env_id]
        fig: dict[str, float] = {
            "episodes": float(len(rows)),
            "success": float(np.mean([r.is_success for r in rows])),
            "collision": float(np.mean([r.collision for r in rows])),
            "timeout": float(np.mean([r.timeout for r in rows])),
        }
        for m in EVAL_METRICS:
            values = [r.metrics[m] for r in rows if math.isfinite(r.metrics.get(m, math.nan))]
            fig[m] = float(np.median(values)) if values else math.nan
        for m in EVAL_METRICS:
            values = [v for v in (r.truth(m) for r in rows) if math.isfinite(v)]
            fig["gt_" + m] = float(np.median(values)) if values else math.nan
        out[env_id] = fig
    return out


def save_checkpoint(model: Any, folder: str) -> None:
    """``model.zip`` and (when training normalises) ``vecnormalize.npz`` in ``folder``."""
    os.makedirs(folder, exist_ok=True)
    model.save(os.path.join(folder, MODEL_FILE))
    venv = model.get_vec_normalize_env()
    if venv is not None:
        save_vecnormalize(venv, os.path.join(folder, VECNORMALIZE))
