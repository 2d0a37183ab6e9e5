"""Training one policy shared by every robot with RLlib's PPO, on RLlib's new API stack.

The PettingZoo parallel environment (``srpb_gym.parallel_env``) runs in RLlib through its
``ParallelPettingZooEnv`` wrapper; every robot (``robot_0``, ``robot_1``, ...) is mapped to
one policy, ``shared``. A robot that leaves early (goal, collision) gets its last
observation, reward and ``terminated`` in that step and no further ones, and the episode
ends (``__all__``) when every robot has left: RLlib's multi-agent episode then holds only
real transitions of each robot, to its own end, unlike the SB3 recipe
(``training/multi_robot.py``), which cuts every robot's episode at the first robot's end.
:class:`SRPBMetricsCallback` puts each robot's SRPB episode metrics (``srpb/m_psi``, ...,
the success, collision and timeout rates) into RLlib's results under ``env_runners``.

    python -m training.rllib_multi_robot --scenario crowd --robots 3 --env-runners 2 \\
        --envs-per-runner 2 --iterations 200 --out runs/rllib-multi
    python -m training.rllib_multi_robot ... --address head:6379   # on a Ray cluster

Run it from the repository's root (the ``training/`` scripts are not installed). Needs
``pip install "srpb-gym[ray]"``. ``--out`` must be a new or empty folder: it gets
``progress.jsonl`` (a line of figures per iteration), ``run.json`` and the final
checkpoint (``checkpoint/``, RLlib's format; evaluate it with RLlib, as ``srpb-gym eval
--policy`` takes stable-baselines3 models only).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env

import srpb_gym
from srpb_gym.errors import InputError
from srpb_gym.evaluation.outdir import check_out_dir
from srpb_gym.evaluation.ray_pool import connect
from training.multi_robot import check_arguments

PROG = "training.rllib_multi_robot"
ENV_NAME = "srpb_parallel"
POLICY = "shared"
#: the SRPB metrics put into RLlib's results (mean over the robots' episodes)
METRICS = ("m_goal", "m_obs", "m_mef", "m_plin", "m_psi", "m_fsi", "m_dir")


class SRPBParallelRLlibEnv(ParallelPettingZooEnv):
    """RLlib's wrapper of a PettingZoo parallel env, whose episode ends (``__all__``) when
    no robot is left: also when the last robots leave in one step, some terminated and
    the others truncated (the wrapper's ``all(...)`` of each dict alone would miss it)."""

    def step(self, action_dict: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        obs, rewards, terms, truncs, infos = self.par_env.step(action_dict)
        left = not self.par_env.agents
        terms["__all__"] = left and all(terms.values())
        truncs["__all__"] = left and not terms["__all__"]
        return obs, rewards, terms, truncs, infos


def make_env(config: dict[str, Any]) -> SRPBParallelRLlibEnv:
    """The environment of an env runner: ``config`` holds the ``parallel_env`` keywords."""
    return SRPBParallelRLlibEnv(srpb_gym.parallel_env(**config))


class SRPBMetricsCallback(RLlibCallback):
    """At each episode's end, every robot's SRPB metrics (its last ``info``) into the
    results: ``env_runners/srpb/<metric>``, ``srpb/success``, ``srpb/collision`` and
    ``srpb/timeout`` (means over the robot-episodes of the reporting window)."""

    def on_episode_end(self, *, episode: Any, metrics_logger: Any = None, **kwargs: Any) -> None:
        if metrics_logger is None:
            return
        for agent_episode in episode.agent_episodes.values():
            try:
                info = agent_episode.get_infos(-1)
            except IndexError:  # no step of this robot in this chunk
                continue
            if "srpb/m_goal" not in info:
                continue
            values = {f"srpb/{m}": float(info[f"srpb/{m}"]) for m in METRICS}
            values["srpb/success"] = float(bool(info.get("is_success", False)))
            values["srpb/collision"] = float(bool(info.get("collision", False)))
            values["srpb/timeout"] = float(bool(info.get("timeout", False)))
            for key, value in values.items():
                if math.isfinite(value):
                    metrics_logger.log_value(key, value, reduce="mean", window=100)


def build_config(scenario: str, robots: int, env_runners: int, envs_per_runner: int,
                 seed: int = 0, reward: str = "task", batch: int = 4000,
                 minibatch: int = 128, epochs: int = 10) -> PPOConfig:  # fmt: skip
    """PPO on the new API stack: one module, ``shared``, for every robot."""
    register_env(ENV_NAME, make_env)
    return (
        PPOConfig()
        .environment(
            ENV_NAME, env_config={"scenario": scenario, "n_robots": robots, "reward": reward}
        )
        .env_runners(
            num_env_runners=env_runners,
            num_envs_per_env_runner=envs_per_runner,
            num_cpus_per_env_runner=1,
        )
        .multi_agent(policies={POLICY}, policy_mapping_fn=lambda agent_id, episode, **kw: POLICY)
        .training(
            train_batch_size_per_learner=batch,
            minibatch_size=minibatch,
            num_epochs=epochs,
            gamma=0.99,
        )
        .callbacks(SRPBMetricsCallback)
        .debugging(seed=seed)
    )


def summary(result: dict[str, Any]) -> dict[str, Any]:
    """The figures of one iteration kept in ``progress.jsonl``."""
    runners = result.get("env_runners", {})
    agents = runners.get("num_agent_steps_sampled_lifetime")
    out = {"iteration": result.get("training_iteration"),
           "env_steps": runners.get("num_env_steps_sampled_lifetime"),
           "agent_steps": sum(agents.values()) if isinstance(agents, dict) else agents,
           "episode_return_mean": runners.get("episode_return_mean"),
           "time_s": result.get("time_total_s")}  # fmt: skip
    return out | {k: v for k, v in runners.items() if str(k).startswith("srpb/")}


def train(scenario: str, robots: int, env_runners: int, envs_per_runner: int,
          iterations: int, out: str, *, seed: int = 0, reward: str = "task",
          batch: int = 4000, minibatch: int = 128, epochs: int = 10,
          address: str | None = None, log: Any = print) -> dict[str, Any]:  # fmt: skip
    """Train for ``iterations`` RLlib iterations; returns ``run.json``'s record, with the
    throughput (``env_steps_per_s``: environment steps, each moving every robot, and
    ``agent_steps_per_s``: robot-steps, over the iterations' wall time)."""
    check_arguments(scenario, robots, 1, 1, seed, reward)
    for value, option in ((env_runners, "--env-runners"), (iterations, "--iterations")):
        if value < (0 if option == "--env-runners" else 1):
            raise InputError(f"must be at least {0 if option == '--env-runners' else 1}, "
                             f"got {value}", key=option)  # fmt: skip
    if envs_per_runner < 1:
        raise InputError(f"must be at least 1, got {envs_per_runner}", key="--envs-per-runner")
    folder = Path(check_out_dir(out))
    ray, started = connect(address)
    try:
        algo = build_config(scenario, robots, env_runners, envs_per_runner, seed, reward,
                            batch, minibatch, epochs).build_algo()  # fmt: skip
        try:
            began, last = time.perf_counter(), {}
            with open(folder / "progress.jsonl", "w", encoding="utf-8") as f:
                for _ in range(iterations):
                    last = summary(algo.train())
                    f.write(json.dumps(last) + "\n")
                    log(f"iteration {last['iteration']}: {last['env_steps']} env steps, "
                        f"return {last['episode_return_mean']}")  # fmt: skip
            wall = time.perf_counter() - began
            algo.save(str((folder / "checkpoint").resolve()))
        finally:
            algo.stop()
    finally:
        if started:
            ray.shutdown()
    record = {"scenario": scenario, "robots": robots, "env_runners": env_runners,
              "envs_per_runner": envs_per_runner, "iterations": iterations, "seed": seed,
              "reward": reward, "train_batch": batch, "wall_time_s": wall,
              "env_steps": last.get("env_steps"), "agent_steps": last.get("agent_steps"),
              "env_steps_per_s": (last.get("env_steps") or 0) / wall,
              "agent_steps_per_s": (last.get("agent_steps") or 0) / wall,
              "last": last, "command": " ".join(sys.argv)}  # fmt: skip
    (folder / "run.json").write_text(json.dumps(record, indent=1) + "\n")
    return record


def main(argv: list[str] | None = None) -> int:
    """The command line; 0 when trained, 2 (one line on stderr) for a bad argument."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="crowd")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--env-runners", type=int, default=2, help="RLlib env runners (processes)")
    ap.add_argument("--envs-per-runner", type=int, default=1,
                    help="multi-robot environments per env runner")  # fmt: skip
    ap.add_argument("--iterations", type=int, default=100, help="RLlib training iterations")
    ap.add_argument("--batch", type=int, default=4000, help="robot-steps per iteration")
    ap.add_argument("--minibatch", type=int, default=128)
    ap.add_argument("--epochs", type=int, default=10)
    ap.add_argument("--reward", default="task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--address", help="a Ray cluster (default: Ray on this machine)")
    ap.add_argument("--out", default="runs/rllib-multi",
                    help="run folder, new or empty (default: runs/rllib-multi)")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        record = train(args.scenario, args.robots, args.env_runners, args.envs_per_runner,
                       args.iterations, args.out, seed=args.seed, reward=args.reward,
                       batch=args.batch, minibatch=args.minibatch, epochs=args.epochs,
                       address=args.address)  # fmt: skip
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(f"{record['env_steps_per_s']:.0f} env steps/s ({record['agent_steps_per_s']:.0f} "
          f"robot-steps/s); run in {args.out}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
