"""``srpb-gym eval`` and ``srpb-gym compare``, end to end."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.cli import main
from srpb_gym.evaluation import resolve_config, run_episode
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.evaluation.stats import (
    CSV_COLUMNS,
    GT_COLUMNS,
    PEOPLE_METRICS,
    PUSHED_BACK_LABEL,
    cell,
    latex_escape,
    metric_rows,
    number,
)
from srpb_gym.metrics import METRIC_NAMES, MetricParams, evaluate
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.planners import PLANNERS, GoToGoal

ENV = "SRPB-Corridor-v0"
TIMING = ("m_cef", "m_cre", "gt_m_cef", "gt_m_cre")  # measured times
PNG = b"\x89PNG\r\n\x1a\n"


def _eval(out: Path, *extra: str) -> int:
    return main(["eval", "--env", ENV, "--planner", "go-to-goal", "--out", str(out), *extra])


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("eval") / "run"
    assert _eval(out, "--episodes", "2") == 0
    return out


@pytest.fixture(scope="module")
def run_workers(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("eval") / "workers"
    assert _eval(out, "--episodes", "2", "--workers", "2") == 0
    return out


# ---------------------------------------------------------------------------- artifacts
def test_every_artifact_is_written(run):
    rows = _rows(run)
    with open(run / "episodes.csv", newline="") as f:
        assert next(csv.reader(f)) == list(CSV_COLUMNS)
    assert [(r["env"], r["planner"], r["seed"]) for r in rows] == [
        (ENV, "go-to-goal", "0"),
        (ENV, "go-to-goal", "1"),
    ]
    assert all(r[k] in ("0", "1") for r in rows for k in ("is_success", "collision", "timeout"))

    summary = json.loads((run / "summary.json").read_text())
    entry = summary["results"][ENV]["go-to-goal"]
    assert summary["episodes_finished"] == 2 and summary["interrupted"] is False
    assert {"episodes", "success_rate", "collision_rate", "timeout_rate"} <= set(entry)
    assert set(entry["metrics"]) == set(METRIC_NAMES)
    assert {"median", "q1", "q3", "n", "ci_low", "ci_high"} <= set(entry["metrics"]["m_psi"])
    assert set(entry["metrics_gt"]) == set(METRIC_NAMES) and "metrics_gt" in summary["statistics"]
    assert entry["success_rate_ci"] == list(wilson(round(entry["success_rate"] / 50), 2))
    assert not (run / "paired.json").exists() and not (run / "paired.md").exists()  # 1 planner

    config = json.loads((run / "config.json").read_text())
    assert {"envs", "planners", "episodes", "seeds", "semantics", "preset"} <= set(config)
    assert config["seeds"] == [0, 1] and config["envs"][0]["id"] == ENV
    assert config["planners"][0]["params"] == {"k_turn": 2.0, "slow_radius": 1.0}

    command = (run / "command.txt").read_text().split()
    assert command[:2] == ["srpb-gym", "eval"] and "--episodes" in command
    versions = json.loads((run / "versions.json").read_text())
    for key in ("python", "srpb-gym", "numpy", "scipy", "numba", "gymnasium", "pymunk", "cpu"):
        assert versions[key]

    for png in (f"trajectories_{ENV}_go-to-goal.png", f"bars_{ENV}.png"):
        assert (run / png).read_bytes()[:8] == PNG
    for seed in (0, 1):
        folder = run / "episodes" / ENV / "go-to-goal"
        for suffix in ("_robot.txt", "_people.txt", "_groups.txt", ".npz"):
            assert (folder / f"corridor_seed{seed}{suffix}").is_file()


def test_tables_in_three_formats(run, capsys):
    lines = (run / f"table_{ENV}.md").read_text().splitlines()
    assert lines[2] == "| metric | unit | go-to-goal |"
    assert (
        lines[0]
        == f"## {ENV}: median [95 % CI] (rates: Wilson 95 % CI) over 2 episodes per planner"
    )
    body = [line.split(" | ")[0].strip("| ") for line in lines[4:]]
    labels = [label for label, _, _ in metric_rows()]
    assert body == ["episodes", "success", "collision", "timeout", PUSHED_BACK_LABEL, *labels]
    assert labels[labels.index("m_psi (tracked)") + 1] == "m_psi (ground truth)"
    assert "m_obs" in labels and len(labels) == len(METRIC_NAMES) + len(PEOPLE_METRICS)
    tex = (run / f"table_{ENV}.tex").read_text()
    assert "\\begin{tabular}{llr}" in tex and "\\end{tabular}" in tex
    assert "m\\_psi (tracked) & \\% &" in tex and tex.count("\\\\") == 1 + 5 + len(labels)
    with open(run / f"table_{ENV}.csv", newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == ["metric", "unit", *(f"go-to-goal {k}" for k in ("median", "q1", "q3", "n")),
                        "go-to-goal ci_low", "go-to-goal ci_high"]  # fmt: skip
    assert table[5][0] == PUSHED_BACK_LABEL
    assert [r[0] for r in table[6:]] == [*METRIC_NAMES, *GT_COLUMNS]
    assert all(len(r) == 8 for r in table)
    assert cell({"median": 12.3, "q1": 10.1, "q3": 14.0}) == "12.3 [10.1-14.0]"
    # not 0, yet below the last decimal: said so, not printed as 0
    assert cell({"median": 0.000149, "q1": 0.0, "q3": 0.0004}) == "<0.001 [0-<0.001]"
    assert number(-0.0002) == ">-0.001" and number(0.0) == "0" and number(0.0012) == "0.001"
    assert latex_escape("<0.001 [0-<0.001]") == r"\textless{}0.001 [0-\textless{}0.001]"


def test_csv_row_equals_the_recorded_episode(run):
    params = json.loads((run / "config.json").read_text())["envs"][0]["metric_params"]
    for row in _rows(run):
        record = load_record(
            run / "episodes" / ENV / "go-to-goal" / f"corridor_seed{row['seed']}.npz"
        )
        values = evaluate(record, "paper", MetricParams(**params))
        for name in METRIC_NAMES:  # m_cef, m_cre included: the recorded planning time
            assert _same(float(row[name]), values[name]), name
        truth = load_record(
            run / "episodes" / ENV / "go-to-goal" / f"corridor_seed{row['seed']}_gt.npz"
        )
        values = evaluate(truth, "paper", MetricParams(**params))
        for name in METRIC_NAMES:  # the ground truth: the people as they were
            assert _same(float(row[f"gt_{name}"]), values[name]), name
            if name not in PEOPLE_METRICS:  # computed from the robot alone: the same
                assert _same(float(row[f"gt_{name}"]), float(row[name])), name


def test_an_episode_replays_alone(run, tmp_path):
    assert _eval(tmp_path / "one", "--episodes", "1", "--seed", "1") == 0
    assert _without_timing(_rows(tmp_path / "one")) == _without_timing(_rows(run))[1:]
    a = load_record(run / "episodes" / ENV / "go-to-goal" / "corridor_seed1.npz")
    b = load_record(tmp_path / "one" / "episodes" / ENV / "go-to-goal" / "corridor_seed1.npz")
    assert np.array_equal(a.robot[:, :-1], b.robot[:, :-1]) and np.array_equal(a.people, b.people)


def test_workers_give_the_same_episodes(run, run_workers):
    assert _without_timing(_rows(run_workers)) == _without_timing(_rows(run))


def test_defaults_resolve(tmp_path):
    config = resolve_config(out=str(tmp_path / "d"))
    assert config.envs == (ENV,) and config.episodes == 5 and config.seed == 0
    assert [p.name for p in config.planners] == list(PLANNERS)


def test_planner_settings_are_used_and_stored(tmp_path):
    settings = tmp_path / "planners.yaml"
    settings.write_text("go-to-goal:\n  k_turn: 3\n  slow_radius: 0.5\ndwa:\n  horizon: 1.5\n")
    out = tmp_path / "settings"
    assert _eval(out, "--episodes", "1", "--planner-config", str(settings),
                 "--planner-param", "go-to-goal.slow_radius=0.8") == 0  # fmt: skip
    planner = json.loads((out / "config.json").read_text())["planners"][0]
    assert planner["config"] == {"k_turn": 3, "slow_radius": 0.8}
    assert planner["params"] == {"k_turn": 3.0, "slow_radius": 0.8}
    settings = {"dwa": {"global_planner": {"spacing": 0.2}}}
    spec = resolve_config([ENV], ["dwa"], out=str(tmp_path / "r"), planner_settings=settings)
    dwa = spec.planners[0].build()
    assert dwa.planner.config.spacing == 0.2
    assert spec.planners[0].describe(dwa)["params"]["global_planner"]["spacing"] == 0.2


def test_run_episode_options_and_timing():
    import gymnasium as gym

    env = gym.make(ENV)
    times: list[float] = []
    out = run_episode(env, GoToGoal(), 3, options={"people": False}, on_act=times.append)
    assert out["info"]["is_success"] and len(times) == out["steps"] > 0
    assert all(t >= 0.0 for t in times) and out["reset_time"] >= 0.0
    assert env.unwrapped.knowledge().tracks.xy.shape[0] == 0
    env.close()


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--env", "SRPB-Nowhere-v0"], "--env: unknown environment id 'SRPB-Nowhere-v0'"),
        (["--planner", "teleport"], "--planner: unknown planner 'teleport'; choose one of"),
        (["--policy", "missing.zip"], "missing.zip: --policy: no such file or shipped model ("),
        (["--policy", "garbage.zip"], "garbage.zip: --policy: not a stable-baselines3 model (not"),
        (["--out", "a_file.txt"], "--out: a_file.txt is an existing file"),
        (["--episodes", "0"], "--episodes: must be at least 1, got 0"),
        (["--planner-param", "go-to-goal.k_turnn=3"], "planner.go-to-goal.k_turnn: unknown key"),
        (["--planner-param", "go-to-goal.k_turn=-3"], "planner.go-to-goal.k_turn: must be a"),
        (["--planner-param", "k_turn=3"], "--planner-param: expected PLANNER.FIELD=VALUE"),
        (["--planner-param", "teleport.x=1"], "planner.teleport: unknown planner 'teleport'"),
        (["--planner-config", "missing.yaml"], "missing.yaml: --planner-config: cannot read"),
    ],
)
def test_bad_arguments_exit_2(args, expected, tmp_path, monkeypatch, capsys):
    if "garbage.zip" in args:
        pytest.importorskip("stable_baselines3")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file.txt").write_text("x")
    (tmp_path / "garbage.zip").write_bytes(b"not a zip file")
    assert main(["eval", "--out", "out", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("srpb-gym: error: ") and expected in err
    if "--env" in args:
        assert "SRPB-Crowd-v0" in err
    if "--planner" in args:
        assert "go-to-goal" in err


# ---------------------------------------------------------------------------- interrupt
class _Interrupting(GoToGoal):
    """Finishes its first episode, then Ctrl-C arrives during the second (the first reset
    is the warm-up's, which stops before t = 1 s)."""

    name = "interrupting"
    episodes = 0

    def reset(self, knowledge):
        type(self).episodes += 1

    def act(self, observation, knowledge):
        if type(self).episodes > 2 and knowledge.t > 1.0:
            raise KeyboardInterrupt
        return super().act(observation, knowledge)


def test_interrupt_keeps_finished_episodes(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(PLANNERS, "interrupting", _Interrupting)
    out = tmp_path / "int"
    code = main(["eval", "--env", ENV, "--planner", "interrupting", "--episodes", "3",
                 "--out", str(out)])  # fmt: skip
    assert code == 130
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == (
        f"srpb-gym: interrupted: 1 of 3 episodes finished; results so far in {out} "
        "(--resume continues)"
    )
    assert [r["seed"] for r in _rows(out)] == ["0"]
    folder = out / "episodes" / ENV / "interrupting"
    assert sorted(p.name for p in folder.iterdir() if "seed0" not in p.name) == []
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and summary["episodes_finished"] == 1
    assert (out / f"table_{ENV}.md").is_file()


def _sigint_default() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_sigint_stops_a_parallel_run(tmp_path):
    # far more episodes than a loaded machine finishes before the signal. The run starts
    # with Ctrl-C at its default: a test run started in the background of a shell ignores
    # SIGINT, its children inherit that, and Python then installs no handler for it
    out = tmp_path / "sig"
    cmd = [sys.executable, "-m", "srpb_gym", "eval", "--env", ENV, "--planner", "go-to-goal",
           "--episodes", "5000", "--workers", "2", "--out", str(out)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_sigint_default)  # fmt: skip
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "episodes.csv").is_file() and len(_rows(out)) >= 1:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted:" in err.strip().splitlines()[-1]
    rows = _rows(out)
    assert 1 <= len(rows) < 5000
    folder = out / "episodes" / ENV / "go-to-goal"
    recorded = sorted(int(p.name[len("corridor_seed") : -4]) for p in folder.glob("*[0-9].npz"))
    assert recorded == sorted(int(r["seed"]) for r in rows)


# ---------------------------------------------------------------------------- compare
def test_compare_two_runs(run, run_workers, tmp_path, capsys):
    assert main(["compare", str(run), str(run_workers), "--out", str(tmp_path / "cmp")]) == 0
    out = capsys.readouterr().out
    assert "go-to-goal@run" in out and "go-to-goal@workers" in out
    assert out.splitlines()[1].split()[:2] == ["metric", "unit"]
    merged = _rows(tmp_path / "cmp")
    assert len(merged) == 4 and (tmp_path / "cmp" / f"table_{ENV}.tex").is_file()
    assert main(["compare", str(tmp_path / "nothing")]) == 2


# ---------------------------------------------------------------------------- policy, video
def test_learned_policy_evaluates(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from srpb_gym.models import save_vecnormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]))
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, device="cpu", seed=0)
    model.learn(64)
    model.save(tmp_path / "tiny_ppo.zip")
    save_vecnormalize(venv, tmp_path / "tiny_ppo_vecnormalize.npz")
    out = tmp_path / "policy"
    assert main(["eval", "--env", ENV, "--policy", str(tmp_path / "tiny_ppo.zip"),
                 "--episodes", "1", "--out", str(out)]) == 0  # fmt: skip
    assert [r["planner"] for r in _rows(out)] == ["tiny_ppo"]
    planner = json.loads((out / "config.json").read_text())["planners"][0]
    assert planner["algo"] == "PPO" and planner["vecnormalize"].endswith(
        "tiny_ppo_vecnormalize.npz"
    )
    assert (out / "episodes" / ENV / "tiny_ppo" / "corridor_seed0.npz").is_file()


def test_video_of_the_first_episode(tmp_path):
    pytest.importorskip("pygame")
    out = tmp_path / "video"
    assert _eval(out, "--episodes", "2", "--video") == 0
    videos = sorted(os.listdir(out / "videos"))
    assert len(videos) == 1 and videos[0].startswith(f"{ENV}_go-to-goal_seed0.")
    head = (out / "videos" / videos[0]).read_bytes()[:12]
    assert head.startswith(b"GIF89a") or head[4:8] == b"ftyp"


def _gif_frames(path: Path) -> tuple[list[int], list[np.ndarray]]:
    """The duration [ms] and the RGB pixels of each frame of a GIF."""
    from PIL import Image

    durations, pixels = [], []
    with Image.open(path) as image:
        for i in range(image.n_frames):
            image.seek(i)
            durations.append(image.info["duration"])
            pixels.append(np.asarray(image.convert("RGB")))
    return durations, pixels


@pytest.mark.parametrize("lazy", [False, True])
@pytest.mark.parametrize(("added", "stride", "kept"), [
    (7, 1, [0, 1, 2, 3, 4, 5, 6]), (7, 3, [0, 3, 6]), (8, 3, [0, 3, 6, 7]), (1, 4, [0]),
    (5, 2, [0, 2, 4]), (6, 2, [0, 2, 4, 5]),
])  # fmt: skip
def test_video_stride_keeps_every_kth_frame_and_the_last(tmp_path, monkeypatch, added,
                                                          stride, kept, lazy):  # fmt: skip
    """``add`` takes drawn frames; ``film`` takes the drawing and draws only the frames it
    keeps (the last one at ``close``)."""
    pytest.importorskip("PIL")
    from srpb_gym.evaluation import figures

    monkeypatch.setattr(figures, "video_format", lambda: "gif")
    writer = figures.VideoWriter(str(tmp_path / "clip"), fps=10, stride=stride)
    legend = np.repeat(np.arange(0, 36 * added, 36, dtype=np.uint8), 3).reshape(1, added, 3)
    drawn: list[int] = []

    def draw(i: int) -> np.ndarray:  # frame i: grey level 36 * i under a strip of every level
        drawn.append(i)
        return np.concatenate([legend, np.full((1, added, 3), 36 * i, np.uint8)])

    for i in range(added):
        if lazy:
            writer.film(lambda i=i: draw(i))
        else:
            writer.add(draw(i))
    writer.add(None)  # skipped, not counted
    path = writer.close()
    assert drawn == (kept if lazy else list(range(added)))
    assert writer.frames == len(kept) and path.endswith(".gif")
    durations, pixels = _gif_frames(Path(path))
    assert len(durations) == len(kept) and set(durations) == {100 * stride}
    levels = [int(frame[1, 0, 0]) for frame in pixels]
    assert [round(level / 36) for level in levels] == kept  # the palette is approximate


def test_the_processor_is_recorded(monkeypatch):
    """The processor, torch's kernels when torch is loaded and MKL_CBWR when set: a learned
    policy's figures may depend on them."""
    import types

    from srpb_gym.evaluation.harness import cpu

    monkeypatch.delenv("MKL_CBWR", raising=False)
    monkeypatch.delitem(sys.modules, "torch", raising=False)
    plain = cpu()
    assert set(plain) == {"cpu"} and plain["cpu"]
    backends = types.SimpleNamespace(cpu=types.SimpleNamespace(get_cpu_capability=lambda: "AVX2"))
    monkeypatch.setitem(sys.modules, "torch", types.SimpleNamespace(backends=backends))
    monkeypatch.setenv("MKL_CBWR", "COMPATIBLE")
    assert cpu() == {**plain, "torch_cpu_capability": "AVX2", "MKL_CBWR": "COMPATIBLE"}


def test_video_stride_is_checked():
    from srpb_gym.evaluation.figures import VideoWriter

    with pytest.raises(ValueError, match="stride must be at least 1, got 0"):
        VideoWriter("unused", stride=0)


def test_video_stride_end_to_end(tmp_path, capsys):
    pytest.importorskip("pygame")
    clips = {}
    for stride in (1, 4):
        out = tmp_path / f"stride{stride}"
        assert _eval(out, "--episodes", "1", "--video", "--video-stride", str(stride)) == 0
        (video,) = os.listdir(out / "videos")
        assert json.loads((out / "config.json").read_text())["video_stride"] == stride
        clips[stride] = out / "videos" / video
    if clips[1].suffix == ".gif":  # Pillow merges equal frames, adding their durations
        steps = sum(_gif_frames(clips[1])[0]) // 100 - 1  # the reset's frame, one per step
        written = steps // 4 + 1 + (steps % 4 != 0)
        assert steps > 8 and sum(_gif_frames(clips[4])[0]) == 400 * written
    assert _eval(tmp_path / "bad", "--video", "--video-stride", "0") == 2
    assert "--video-stride: must be at least 1, got 0" in capsys.readouterr().err
