"""``srpb-gym eval``: planners and learned policies run on scenarios
(:mod:`srpb_gym.evaluation`), their tables printed and every file written into ``--out``.
Exit status 130 when the evaluation is interrupted (Ctrl-C; what finished is kept,
``--resume`` goes on)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from srpb_gym.cli.common import PROG, stderr
from srpb_gym.config import parse_overrides
from srpb_gym.errors import InputError
from srpb_gym.evaluation import resolve_config, run_evaluation
from srpb_gym.evaluation.figures import video_support
from srpb_gym.evaluation.spec import BACKENDS, DEFAULT_WARMUP, ENV_IDS
from srpb_gym.metrics.params import PRESETS, SEMANTICS
from srpb_gym.planners import PLANNERS, REFERENCE_PLANNERS
from srpb_gym.planners.config import planner_settings


def add_eval_command(subparsers: Any) -> None:
    """Register ``eval``: run planners and policies on scenarios, write the results."""
    p = subparsers.add_parser(
        "eval",
        help="evaluate planners and learned policies on scenarios",
        description=(
            "Run every planner on every scenario for N episodes (episode i uses seed S+i), "
            "print one table per scenario (median [95 % CI] of every SRPB metric, from the "
            "tracked people and for the social metrics also from ground truth; success, "
            "collision and timeout rates [Wilson 95 % CI]), with two planners or more paired "
            "comparisons against the first (paired.md, paired.json), and write episodes, "
            "tables, figures and the configuration into --out. Without --env/--planner/--policy: "
            "SRPB-Corridor-v0 with every registered planner, 5 episodes."
        ),
        epilog=f"environment ids: {', '.join(ENV_IDS)}; or a scenario file "
        "(envs/my_lab.yaml), run as SRPB-Custom-v0 and labelled by its scenario name",
    )
    many = {"action": "extend", "nargs": "+"}
    p.add_argument("--env", metavar="ID|FILE", **many,
                   help="environment id(s) or scenario file(s) (.yaml)")  # fmt: skip
    p.add_argument("--planner", metavar="NAME", **many,
                   help="registered planner(s): " + ", ".join(PLANNERS) + "; or the "
                        "reference planner(s) handed the true people instead of the "
                        "tracker's, run only when named: "
                        + ", ".join(REFERENCE_PLANNERS))  # fmt: skip
    p.add_argument("--planner-config", metavar="FILE",
                   help="YAML file of planner settings: {NAME: {FIELD: VALUE}}, nested "
                        "configs as nested mappings (see docs/planners.md)")  # fmt: skip
    p.add_argument("--planner-param", metavar="NAME.FIELD=VALUE", action="append", default=[],
                   help="set one planner setting, e.g. dwa.horizon=2.5 or "
                        "dwa.global_planner.spacing=0.2 (repeatable; applied over "
                        "--planner-config)")  # fmt: skip
    p.add_argument("--policy", metavar="PATH", **many, default=[],
                   help="stable-baselines3 model .zip file(s), srpb-gym train run "
                        "folder(s) (their model.zip) or shipped model name(s), each named "
                        "after the file, folder or name")  # fmt: skip
    p.add_argument("--policy-algo", default=None, metavar="ALGO",
                   help="force the algorithm of the --policy files: PPO, A2C, SAC, TD3, DDPG "
                        "or DQN (default: read from each file)")  # fmt: skip
    p.add_argument("--vecnormalize", default="auto", metavar="FILE",
                   help="observation-normalisation statistics of the --policy files, or "
                        "'none' for raw observations (default: vecnormalize.npz or .pkl "
                        "where srpb-gym train or the RL Zoo put it, see "
                        "docs/evaluation.md)")  # fmt: skip
    p.add_argument("--trust-pickle", action="store_true",
                   help="let the --policy files' pickles run: a vecnormalize.pkl and the "
                        "pickled attributes of a model.zip (a pickle is code; without it "
                        "a .pkl is refused and a model's attributes are read as data "
                        "only)")  # fmt: skip
    p.add_argument("--episodes", type=int, default=5, metavar="N", help="per pair (default: 5)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="first seed (default: 0)")
    p.add_argument("--out", metavar="DIR",
                   help="output folder, new or empty (default: runs/eval-<time>)")  # fmt: skip
    p.add_argument("--resume", action="store_true",
                   help="continue the interrupted run in --out (same options; finished "
                        "episodes are kept, the others run)")  # fmt: skip
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes (default: 1; at most the CPU count and the "
                        "number of episodes); with --backend ray the episodes running at "
                        "once (default: every CPU of the Ray cluster)")  # fmt: skip
    p.add_argument("--backend", choices=BACKENDS, default="process",
                   help="where the episodes run: process (this process or --workers "
                        "worker processes, default) or ray (Ray tasks: a local Ray, or the "
                        "cluster at --address; needs pip install \"srpb-gym[ray]\")")  # fmt: skip
    p.add_argument("--address", metavar="ADDR",
                   help="the Ray cluster to run on (with --backend ray), e.g. "
                        "ray://head:10001 or head:6379 (default: start Ray on this "
                        "machine)")  # fmt: skip
    p.add_argument("--warmup", type=int, default=DEFAULT_WARMUP, metavar="STEPS",
                   help="untimed control steps of each planner before its first timed "
                        f"episode, in each process (default: {DEFAULT_WARMUP}; 0: none)",
                   )  # fmt: skip
    p.add_argument("--video", type=int, nargs="?", const=1, default=0, metavar="K",
                   help="film the first K episodes of each pair (default K: 1)")  # fmt: skip
    p.add_argument("--video-stride", type=int, default=1, metavar="K",
                   help="film every K-th control step, played at the render rate / K, so "
                        "in real time (default: 1; the last step is always filmed)",
                   )  # fmt: skip
    p.add_argument("--robots", type=int, default=1, metavar="N",
                   help="robots per episode (default: 1). N > 1 runs the multi-robot "
                        "(PettingZoo) environment: a planner instance per robot, a --policy "
                        "shared by all; results per robot and pooled")  # fmt: skip
    p.add_argument("--semantics", choices=SEMANTICS, default="paper",
                   help="metric semantics (default: paper)")  # fmt: skip
    p.add_argument("--preset", choices=tuple(PRESETS), default="paper",
                   help="metric parameter preset (default: paper)")  # fmt: skip
    p.add_argument("--env-kwargs", **many, default=[], metavar="KEY=VALUE",
                   help="keyword arguments of every environment, values in YAML, e.g. "
                        "'crowd={robot_reaction: 0.0}' (as srpb-gym train --env-kwargs); "
                        "a model of srpb-gym train observes with the observation settings "
                        "it records")  # fmt: skip
    p.set_defaults(func=run_eval)


def run_eval(args: argparse.Namespace) -> int:
    """Run the evaluation described by ``args``; 130 when interrupted."""
    if args.video:
        missing = video_support()
        if missing:
            raise InputError(missing, key="--video")
    if args.address is not None and args.backend != "ray":
        raise InputError("a Ray cluster's address needs --backend ray", key="--address")
    workers = args.workers if args.workers is not None else (0 if args.backend == "ray" else 1)
    if args.resume and not args.out:
        raise InputError("give the folder of the run to continue with --out", key="--resume")
    config = resolve_config(
        args.env, args.planner, args.policy, policy_algo=args.policy_algo,
        vecnormalize=args.vecnormalize, episodes=args.episodes, seed=args.seed, out=args.out,
        workers=workers, video=args.video, semantics=args.semantics, preset=args.preset,
        planner_settings=planner_settings(args.planner_config, args.planner_param),
        argv=getattr(args, "argv", ()), warmup=args.warmup, resume=args.resume, log=stderr,
        robots=args.robots, env_kwargs=parse_overrides(args.env_kwargs, "--env-kwargs"),
        video_stride=args.video_stride, trust_pickle=args.trust_pickle,
        backend=args.backend, address=args.address,
    )  # fmt: skip
    try:
        outcome = run_evaluation(config, log=stderr)
    except KeyboardInterrupt:  # outside the episodes (set-up, figures)
        print(f"{PROG}: interrupted; partial results in {config.out}", file=sys.stderr)
        return 130
    if outcome.text:
        print(outcome.text)
    if outcome.interrupted:
        print(f"{PROG}: interrupted: {outcome.finished} of {outcome.planned} episodes "
              f"finished; results so far in {config.out} (--resume continues)",
              file=sys.stderr)  # fmt: skip
        return 130
    print(f"\nresults in {config.out}")
    return 0
