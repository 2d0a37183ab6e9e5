"""``eval --policy``: the algorithm read from the model file, normalisation statistics found
where training puts them (and said), spaces checked, every bad file named."""

from __future__ import annotations

import csv
import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.cli import main
from srpb_gym.evaluation import resolve_config
from tests.helpers import error_line

pytest.importorskip("stable_baselines3")

ENV = "SRPB-Corridor-v0"


def _error(capsys) -> str:
    return error_line(capsys, strict=True)


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    """An untrained PPO and SAC model of the corridor, and VecNormalize statistics as
    srpb-gym writes them (vecnormalize.npz) and as stable-baselines3 pickles them
    (vecnormalize.pkl)."""
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from srpb_gym.models import save_vecnormalize

    folder = tmp_path_factory.mktemp("models")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]))
    PPO("MlpPolicy", venv, n_steps=32, batch_size=32, device="cpu", seed=0).save(folder / "ppo.zip")
    SAC("MlpPolicy", venv, buffer_size=100, device="cpu", seed=0).save(folder / "sac.zip")
    venv.save(str(folder / "vecnormalize.pkl"))
    save_vecnormalize(venv, folder / "vecnormalize.npz")
    (folder / "other").mkdir()
    PPO("MlpPolicy", "Pendulum-v1", n_steps=32, batch_size=32, device="cpu").save(
        folder / "other" / "pend.zip"
    )
    return folder


def _resolve(tmp_path, *policies, **kwargs):
    return resolve_config([ENV], None, [str(p) for p in policies], out=str(tmp_path / "o"),
                          log=None, **kwargs)  # fmt: skip


def test_rl_zoo_layout(models, tmp_path, capsys):
    run = tmp_path / "logs" / "ppo" / f"{ENV}_1"
    (run / ENV).mkdir(parents=True)
    shutil.copy(models / "ppo.zip", run / f"{ENV}.zip")
    shutil.copy(models / "ppo.zip", run / "best_model.zip")
    shutil.copy(models / "vecnormalize.pkl", run / ENV / "vecnormalize.pkl")
    config = _resolve(tmp_path, run / f"{ENV}.zip", run / "best_model.zip", trust_pickle=True)
    assert [s.vecnormalize for s in config.planners] == [str(run / ENV / "vecnormalize.pkl")] * 2
    out = tmp_path / "eval"
    args = ["eval", "--env", ENV, "--policy", str(run / "best_model.zip"), "--episodes", "1",
            "--out", str(out)]  # fmt: skip
    assert main(args) == 2  # the Zoo's statistics are a pickle: refused unless trusted
    assert _error(capsys) == (f"{run / ENV / 'vecnormalize.pkl'}: vecnormalize: a pickle, and "
                              "loading a pickle runs the code it names; srpb-gym reads "
                              "normalisation statistics from vecnormalize.npz (numbers only): "
                              "pass --trust-pickle if you trust where this file came "
                              "from")  # fmt: skip
    assert not out.exists() or not any(out.iterdir())
    assert main([*args, "--trust-pickle"]) == 0
    err = capsys.readouterr().err
    assert (f"srpb-gym: note: policy best_model: PPO model (read from the file); observations "
            f"normalised with {run / ENV / 'vecnormalize.pkl'}\n") in err  # fmt: skip
    planner = json.loads((out / "config.json").read_text())["planners"][0]
    assert planner["algo"] == "PPO"
    assert planner["vecnormalize"] == str(run / ENV / "vecnormalize.pkl")


def test_train_layout_and_none_found(models, tmp_path):
    run = tmp_path / "train"
    run.mkdir()
    shutil.copy(models / "ppo.zip", run / "model.zip")
    shutil.copy(models / "vecnormalize.npz", run / "vecnormalize.npz")
    spec = _resolve(tmp_path, run / "model.zip").planners[0]
    assert spec.vecnormalize == str(run / "vecnormalize.npz")
    (run / "vecnormalize.npz").unlink()
    lines: list[str] = []
    config = resolve_config([ENV], None, [str(run / "model.zip")], out=str(tmp_path / "o2"),
                            log=lines.append)  # fmt: skip
    assert config.planners[0].vecnormalize is None
    places = [f"{run}/model_vecnormalize", f"{run}/vecnormalize", f"{run}/model/vecnormalize",
              f"{run}/{ENV}/vecnormalize"]  # fmt: skip
    looked = ", ".join(f"{p}.{ext}" for p in places for ext in ("npz", "pkl"))
    assert lines == [f"note: policy model: PPO model (read from the file); no statistics "
                     f"found (looked for {looked}): raw observations"]  # fmt: skip
    described = config.planners[0].describe()
    assert described["vecnormalize"] is None and len(described["vecnormalize_searched"]) == 8
    raw = _resolve(tmp_path, models / "ppo.zip", vecnormalize="none").planners[0]
    assert raw.vecnormalize is None


def _run(folder: Path, models: Path) -> Path:
    folder.mkdir(parents=True)
    shutil.copy(models / "ppo.zip", folder / "model.zip")
    shutil.copy(models / "vecnormalize.npz", folder / "vecnormalize.npz")
    return folder


def test_run_folders_and_the_names_that_tell_policies_apart(models, tmp_path, capsys):
    a, b = tmp_path / "runs" / "a", tmp_path / "runs" / "b"
    for folder in (a, a / "best", b / "best"):
        _run(folder, models)
    c = _run(tmp_path / "runs" / "c", models)
    config = _resolve(tmp_path, a, a / "best", b / "best", models / "ppo.zip", c / "model.zip")
    assert [s.name for s in config.planners] == ["a", "a-best", "b-best", "ppo", "model"]
    assert [str(s.policy) for s in config.planners[:3]] == [
        str(f / "model.zip") for f in (a, a / "best", b / "best")
    ]
    assert [s.vecnormalize for s in config.planners[:3]] == [
        str(f / "vecnormalize.npz") for f in (a, a / "best", b / "best")
    ]
    # two files whose stems and folders agree up to a higher folder
    x, y = (
        _run(tmp_path / "x" / "run" / "best", models),
        _run(tmp_path / "y" / "run" / "best", models),
    )
    config = _resolve(tmp_path, x / "model.zip", y / "model.zip")
    assert [s.name for s in config.planners] == ["x-run-best-model", "y-run-best-model"]
    # two files of one stem: <folder>-<stem>, as before
    shutil.copy(models / "ppo.zip", tmp_path / "ppo.zip")
    config = _resolve(tmp_path, models / "ppo.zip", tmp_path / "ppo.zip")
    assert [s.name for s in config.planners] == [f"{models.name}-ppo", f"{tmp_path.name}-ppo"]
    out = tmp_path / "eval"
    assert main(["eval", "--env", ENV, "--policy", str(a), "--episodes", "1",
                 "--out", str(out)]) == 0  # fmt: skip
    assert (f"srpb-gym: note: policy a: PPO model (read from the file); observations "
            f"normalised with {a / 'vecnormalize.npz'}\n") in capsys.readouterr().err  # fmt: skip
    assert json.loads((out / "config.json").read_text())["planners"][0]["name"] == "a"


def test_a_folder_without_a_model_and_a_model_given_twice_are_refused(models, tmp_path, capsys):
    run = _run(tmp_path / "run", models)
    (tmp_path / "empty").mkdir()
    assert main(["eval", "--env", ENV, "--policy", str(tmp_path / "empty"),
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert _error(capsys) == (f"{tmp_path / 'empty'}: --policy: a folder without model.zip: "
                              "give the model file (.zip) of the run")  # fmt: skip
    assert main(["eval", "--env", ENV, "--policy", str(run), str(run / "model.zip"),
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert _error(capsys) == f"{run / 'model.zip'}: --policy: the same model is given twice"


def test_algorithm_is_read_from_the_file(models, tmp_path, capsys):
    assert _resolve(tmp_path, models / "sac.zip").planners[0].algo == "SAC"
    forced = _resolve(tmp_path, models / "ppo.zip", policy_algo="a2c").planners[0]
    assert forced.algo == "A2C"
    assert main(["eval", "--env", ENV, "--policy", str(models / "sac.zip"), "--policy-algo",
                 "PPO", "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    line = _error(capsys)
    assert line.startswith(f"{models}/sac.zip: --policy: cannot be loaded as a "
                           "stable-baselines3 PPO model (")  # fmt: skip
    assert line.endswith("; the file holds a SAC model")


def test_spaces_must_match(models, tmp_path, capsys):
    pendulum = models / "other" / "pend.zip"
    assert main(["eval", "--env", ENV, "--policy", str(pendulum), "--out",
                 str(tmp_path / "x")]) == 2  # fmt: skip
    line = _error(capsys)
    assert line.startswith(f"--policy: {pendulum}: trained for the observation space Box(3,) "
                           "float32 in [-8, 8], the environment has Box(")  # fmt: skip
    assert line.endswith(f"({ENV})")
    shutil.copy(models / "vecnormalize.npz", tmp_path / "vecnormalize.npz")
    shutil.copy(pendulum, tmp_path / "pend.zip")
    assert main(["eval", "--env", ENV, "--policy", str(tmp_path / "pend.zip"), "--out",
                 str(tmp_path / "x")]) == 2  # fmt: skip
    assert _error(capsys).startswith(f"{tmp_path}/vecnormalize.npz: vecnormalize: statistics "
                                     "of the observation space Box(")  # fmt: skip


def test_a_corrupt_vecnormalize_file_is_named(models, tmp_path, capsys):
    (tmp_path / "model.zip").write_bytes((models / "ppo.zip").read_bytes())
    args = ["eval", "--env", ENV, "--policy", str(tmp_path / "model.zip"), "--out",
            str(tmp_path / "x")]  # fmt: skip
    (tmp_path / "vecnormalize.npz").write_bytes(b"garbage")
    assert main(args) == 2
    assert _error(capsys) == (f"{tmp_path}/vecnormalize.npz: vecnormalize: corrupt statistics "
                              "file (not a numpy archive)")  # fmt: skip
    np.savez(tmp_path / "vecnormalize.npz", obs_mean=np.zeros(3))
    assert main(args) == 2
    assert _error(capsys) == (f"{tmp_path}/vecnormalize.npz: vecnormalize: not a statistics "
                              "file of srpb-gym (no 'format' entry)")  # fmt: skip
    (tmp_path / "vecnormalize.npz").unlink()
    (tmp_path / "vecnormalize.pkl").write_bytes(b"\x80\x04garbage")
    assert main([*args, "--trust-pickle"]) == 2
    assert _error(capsys).startswith(f"{tmp_path}/vecnormalize.pkl: vecnormalize: corrupt "
                                     "VecNormalize file (")  # fmt: skip
    (tmp_path / "vecnormalize.pkl").write_bytes(b"\x80\x04K\x01.")  # pickled int 1
    assert main([*args, "--trust-pickle"]) == 2
    assert _error(capsys) == (f"{tmp_path}/vecnormalize.pkl: vecnormalize: not a VecNormalize "
                              "file (holds int)")  # fmt: skip
    assert (
        main(
            [
                "eval",
                "--env",
                ENV,
                "--policy",
                str(tmp_path / "model.zip"),
                "--vecnormalize",
                str(tmp_path / "none.pkl"),
                "--out",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    assert _error(capsys) == f"{tmp_path}/none.pkl: --vecnormalize: no such file"


def test_policies_stay_lazy():
    code = (
        "import sys, srpb_gym, srpb_gym.cli, srpb_gym.evaluation, srpb_gym.planners.learned; "
        "print(sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.stdout.strip() == "[]", done.stderr


def test_a_model_observes_as_it_was_trained(models, tmp_path, capsys):
    """A model that records its observation settings (here the lidar encoding, which keeps
    the space's shape) builds its own observation: the same episodes in an environment that
    observes otherwise, said in the note; a model without a record takes the environment's."""
    from stable_baselines3 import PPO

    from srpb_gym.models import record_observation
    from srpb_gym.observation import ObservationConfig

    model = PPO.load(models / "ppo.zip", device="cpu")
    record_observation(model, ObservationConfig(lidar_encoding="log"))
    folder = tmp_path / "run"
    folder.mkdir()
    model.save(folder / "model.zip")
    shutil.copy(models / "vecnormalize.npz", folder / "vecnormalize.npz")
    shutil.copy(models / "ppo.zip", tmp_path / "plain.zip")
    shutil.copy(models / "vecnormalize.npz", tmp_path / "vecnormalize.npz")
    args = ["eval", "--env", ENV, "--episodes", "2", "--warmup", "0", "--policy", str(folder),
            str(tmp_path / "plain.zip")]  # fmt: skip
    kwargs = ["--env-kwargs", "observation={lidar_encoding: log}"]
    assert main([*args, "--out", str(tmp_path / "linear")]) == 0
    err = capsys.readouterr().err
    assert ("; it observes with its own settings observation={lidar_encoding: log} (the "
            "environments': {lidar_encoding: linear})") in err  # fmt: skip
    assert err.count("observes with its own settings") == 1
    assert main([*args, *kwargs, "--out", str(tmp_path / "log")]) == 0
    assert "observes with its own settings" not in capsys.readouterr().err

    def rows(out: str) -> dict[tuple[str, str], dict[str, str]]:
        with open(tmp_path / out / "episodes.csv", newline="") as f:
            return {(r["planner"], r["seed"]): r for r in csv.DictReader(f)}

    linear, log = rows("linear"), rows("log")
    for seed in ("0", "1"):
        a, b = linear[("run", seed)], log[("run", seed)]
        for key in ("is_success", "m_mef", "m_plin", "m_chc", "m_psi", "m_obs"):
            assert a[key] == b[key], key
            # the plain model (the same weights) takes the environment's observation: in
            # the log environment it drives as the recorded model does in both
            assert log[("plain", seed)][key] == a[key], key
    assert any(linear[("plain", s)]["m_chc"] != log[("plain", s)]["m_chc"] for s in "01")


def test_observation_records_are_compared_setting_by_setting():
    from srpb_gym.models import observation_mismatch
    from srpb_gym.observation import ObservationConfig

    default = ObservationConfig()
    assert observation_mismatch(None, default) is None
    assert observation_mismatch({"type": "flat"}, default) is None  # missing: the defaults
    two = observation_mismatch({"people": 4, "goal_scale": 2.0}, default)
    assert two == ("it was trained with observation={people: 4, goal_scale: 2.0}, this run "
                   "observes with observation={people: 6, goal_scale: 20.0}")  # fmt: skip
    assert observation_mismatch({"history": 4}, default) == (
        "it was trained with observation settings this version does not know: history"
    )
    assert "is invalid" in observation_mismatch({"people": -1}, default)
    assert "not a mapping" in observation_mismatch(["flat"], default)


def test_a_model_without_a_record_is_stamped_once(models, tmp_path):
    from stable_baselines3 import PPO

    from srpb_gym.models import OBSERVATION_RECORD, PolicyFileError, stamp_observation
    from srpb_gym.observation import ObservationConfig

    path = tmp_path / "model.zip"
    shutil.copy(models / "ppo.zip", path)
    log = ObservationConfig(lidar_encoding="log")
    assert stamp_observation(path, log) is True
    assert getattr(PPO.load(path), OBSERVATION_RECORD)["lidar_encoding"] == "log"
    assert stamp_observation(path, log) is False  # already says so: left as it is
    with pytest.raises(PolicyFileError, match=r"trained with observation=\{lidar_encoding: log\}"):
        stamp_observation(path, ObservationConfig())


def test_a_recorded_model_needs_as_many_lidar_beams_as_its_sectors(models, tmp_path, capsys):
    """Refused before the first episode, naming the model and its recorded settings."""
    from stable_baselines3 import PPO

    from srpb_gym.models import record_observation
    from srpb_gym.observation import ObservationConfig
    from srpb_gym.planners.learned import LearnedPolicy

    model = PPO.load(models / "ppo.zip", device="cpu")
    record_observation(model, ObservationConfig())  # 30 sectors
    model.save(tmp_path / "rec.zip")
    out = tmp_path / "e"
    args = ["eval", "--env", ENV, "--policy", str(tmp_path / "rec.zip"), "--vecnormalize",
            "none", "--env-kwargs", "sensors={lidar: {n_beams: 20}}",
            "observation={lidar_bins: 10}", "--out", str(out)]  # fmt: skip
    assert main(args) == 2
    assert _error(capsys) == (f"--policy: {tmp_path}/rec.zip: it observes 30 lidar sectors (its "
                              "recorded observation settings), the environment's lidar has 20 "
                              f"beams ({ENV})")  # fmt: skip
    assert not out.exists()
    policy = LearnedPolicy(tmp_path / "rec.zip", vecnormalize=None)
    with pytest.raises(TypeError, match="needs the Knowledge snapshot"):
        policy.act(np.zeros(80, np.float32), None)  # type: ignore[arg-type]


LIDAR = {"sensors": {"lidar": {"range_min": 0.3, "n_beams": 90}}}  # not the defaults


@pytest.mark.parametrize(
    ("make", "observation", "kwargs"),
    [
        ("SRPB-Corridor-v0", {}, {}),
        ("SRPB-Crowd-v0", {"lidar_encoding": "log"}, LIDAR),
        ("SRPB-Crowd-v0", {"type": "dict", "people": 3, "lidar_encoding": "log"}, {}),
        ("SRPB-Crowd-v0", {"lidar_encoding": "log"}, {"robot": {"v_max": 0.8, "w_max": 2.0}}),
        ("SRPB-Mix-v0", {"lidar_encoding": "log", "lidar_bins": 12}, {}),
        ("parallel", {"lidar_encoding": "log"}, LIDAR),
        ("SRPB-Crowd-v0", {"lidar_encoding": "log", "lidar_groups": 0.01}, {}),
        ("parallel", {"lidar_groups": 0.05, "group_distance": 2.8}, LIDAR),
    ],
)
def test_the_own_observation_equals_the_environments(models, make, observation, kwargs):
    """Built from the Knowledge snapshot, a recorded model's observation is the one an
    environment with its settings gives, value for value, robot by robot."""
    import gymnasium as gym

    import srpb_gym
    from srpb_gym.observation import ObservationConfig
    from srpb_gym.planners.learned import LearnedPolicy

    policy = LearnedPolicy(models / "ppo.zip", vecnormalize=None)
    config = ObservationConfig.from_spec(observation)
    policy.observation_config = config
    without_groups = LearnedPolicy(models / "ppo.zip", vecnormalize=None)
    without_groups.observation_config = dataclasses.replace(config, lidar_groups=0.0)
    drawn = 0  # steps where an O-space shows in the lidar (lidar_groups)

    def own_observation(k):
        nonlocal drawn
        own = policy._observer(k).build(k.pose, k.goal, k.velocity, k.scan, k.tracks)
        if config.lidar_groups:
            plain = without_groups._observer(k).build(k.pose, k.goal, k.velocity, k.scan,
                                                      k.tracks)  # fmt: skip
            drawn += not np.array_equal(own, plain)
        return own

    rng = np.random.default_rng(0)
    if make == "parallel":
        env = srpb_gym.parallel_env(scenario="crowd", n_robots=3, observation=observation,
                                    **kwargs)  # fmt: skip
        obs, _ = env.reset(seed=3)
        for _ in range(40):
            for agent in env.agents:
                np.testing.assert_array_equal(own_observation(env.knowledge(agent)), obs[agent])
            obs, *_ = env.step({a: rng.uniform(-1, 1, 2) for a in env.agents})
        assert drawn > 0 or not config.lidar_groups
        return
    env = gym.make(make, observation=observation, **kwargs)
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        for _ in range(60):
            own = own_observation(env.unwrapped.knowledge())
            if isinstance(obs, dict):
                assert own.keys() == obs.keys()
                for key in obs:
                    np.testing.assert_array_equal(own[key], obs[key], err_msg=key)
            else:
                np.testing.assert_array_equal(own, obs)
            obs, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2))
            if terminated or truncated:
                break
    assert drawn > 0 or not config.lidar_groups
