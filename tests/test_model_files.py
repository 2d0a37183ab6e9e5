"""Model files never run code unless told: a crafted ``model.zip`` or ``vecnormalize.pkl``
is refused or read as data, the statistics are numbers (``vecnormalize.npz``) and found only
where training puts them."""

from __future__ import annotations

import base64
import io
import json
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.cli import main
from srpb_gym.evaluation import resolve_config
from srpb_gym.models import (
    PolicyFileError,
    VecNormalizeError,
    convert_vecnormalize,
    find_vecnormalize,
    load_model,
    load_vecnormalize,
    model_names,
    model_path,
    model_steps,
    save_vecnormalize,
    stray_vecnormalize,
)
from tests.helpers import error_line

pytest.importorskip("stable_baselines3")

ENV = "SRPB-Corridor-v0"


class Payload:
    """Unpickled, it opens ``path`` for writing: the file appears (a harmless stand-in for
    any command a pickle may run)."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def _error(capsys) -> str:
    return error_line(capsys)


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A tiny PPO model of the corridor with its statistics, as srpb-gym writes them and as
    stable-baselines3 pickles them."""
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    folder = tmp_path_factory.mktemp("trained")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]))
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, device="cpu", seed=0,
                policy_kwargs={"net_arch": [8]})  # fmt: skip
    model.learn(16)
    model.save(folder / "model.zip")
    save_vecnormalize(venv, folder / "vecnormalize.npz")
    venv.save(str(folder / "vecnormalize.pkl"))
    return folder


def _rewrite(src: Path, dst: Path, **entries: bytes) -> None:
    """Copy the zip ``src`` to ``dst`` with the members ``entries`` replaced."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            zout.writestr(name, entries.get(name, zin.read(name)))


def _crafted(trained: Path, folder: Path, key: str, marker: Path) -> Path:
    """A copy of the model whose saved ``key`` is a pickle that creates ``marker``."""
    folder.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(trained / "model.zip") as z:
        data = json.loads(z.read("data"))
    serialized = base64.b64encode(pickle.dumps(Payload(marker))).decode()
    data[key] = {":type:": "<class 'function'>", ":serialized:": serialized}
    path = folder / "model.zip"
    _rewrite(trained / "model.zip", path, data=json.dumps(data).encode())
    shutil.copy(trained / "vecnormalize.npz", folder / "vecnormalize.npz")
    return path


def test_a_crafted_schedule_is_never_unpickled(trained, tmp_path, capsys):
    marker = tmp_path / "marker"
    path = _crafted(trained, tmp_path / "run", "lr_schedule", marker)
    model, algo = load_model(path)
    assert algo == "PPO" and not marker.exists()
    assert model.lr_schedule(1.0) == pytest.approx(3e-4)  # the plain learning rate stands in
    code = main(["eval", "--env", ENV, "--policy", str(path), "--episodes", "1", "--warmup",
                 "0", "--out", str(tmp_path / "eval")])  # fmt: skip
    assert code == 0 and not marker.exists()
    # the proof that the file does run code when unpickled: trusted, it does
    load_model(path, trust_pickle=True)
    assert marker.exists()


def test_a_crafted_policy_class_is_refused_unless_trusted(trained, tmp_path):
    marker = tmp_path / "marker"
    path = _crafted(trained, tmp_path / "run", "observation_space", marker)
    with pytest.raises(PolicyFileError) as err:
        load_model(path)
    assert not marker.exists()
    assert str(err.value) == (f"{path}: its saved 'observation_space' is a pickled object that "
                              "names io.open, and loading it could run code: pass "
                              "--trust-pickle if you trust where this file came from")  # fmt: skip


def test_crafted_tensors_are_never_unpickled(trained, tmp_path, capsys):
    import torch

    marker = tmp_path / "marker"
    buffer = io.BytesIO()
    torch.save({"weight": Payload(marker)}, buffer)
    path = tmp_path / "model.zip"
    _rewrite(trained / "model.zip", path, **{"policy.pth": buffer.getvalue()})
    with pytest.raises(PolicyFileError):
        load_model(path)
    assert not marker.exists()
    assert main(["train", "--env", ENV, "--steps", "64", "--init", str(path), "--out",
                 str(tmp_path / "run"), "--no-progress"]) == 2  # fmt: skip
    assert _error(capsys).startswith(f"{path}: --init: its tensors cannot be read (")
    assert not marker.exists() and not (tmp_path / "run").exists()


def test_a_pickled_vecnormalize_is_refused_unless_trusted(trained, tmp_path, capsys):
    marker = tmp_path / "marker"
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(trained / "model.zip", run / "model.zip")
    (run / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    args = ["eval", "--env", ENV, "--policy", str(run), "--out", str(tmp_path / "eval")]
    assert main(args) == 2
    assert _error(capsys).startswith(f"{run / 'vecnormalize.pkl'}: vecnormalize: a pickle, and "
                                     "loading a pickle runs the code it names")  # fmt: skip
    assert not marker.exists()
    with pytest.raises(VecNormalizeError):
        load_vecnormalize(run / "vecnormalize.pkl")
    assert not marker.exists()
    # a pickle named .npz is a corrupt archive, never unpickled
    shutil.copy(run / "vecnormalize.pkl", run / "vecnormalize.npz")
    with pytest.raises(VecNormalizeError, match="not a numpy archive"):
        load_vecnormalize(run / "vecnormalize.npz", trust_pickle=True)
    assert not marker.exists()
    (run / "vecnormalize.npz").unlink()
    # told to trust it, it runs (and then holds no statistics)
    assert main(["train", "--env", ENV, "--steps", "64", "--init", str(run / "model.zip"),
                 "--out", str(tmp_path / "t"), "--trust-pickle", "--no-progress"]) == 2  # fmt: skip
    assert marker.exists()
    assert "not a VecNormalize file (holds TextIOWrapper)" in _error(capsys)


def test_statistics_are_numbers_with_the_same_normalisation(trained, tmp_path):
    import pickle as pkl

    with open(trained / "vecnormalize.pkl", "rb") as f:
        original = pkl.load(f)
    stats = load_vecnormalize(trained / "vecnormalize.npz")
    converted = load_vecnormalize(convert_vecnormalize(trained / "vecnormalize.pkl",
                                                       tmp_path / "c.npz"))  # fmt: skip
    obs = np.random.default_rng(0).normal(size=(7, 80)).astype(np.float32) * 3
    expected = original.normalize_obs(obs)
    for got in (stats, converted):
        assert np.array_equal(got.normalize_obs(obs), expected)
        assert got.observation_space == original.observation_space
    with np.load(trained / "vecnormalize.npz", allow_pickle=False) as archive:
        assert str(archive["format"]) == "srpb-gym vecnormalize 1"
    assert model_steps(trained / "model.zip") == 16


def test_every_shipped_model_keeps_its_statistics_as_numbers():
    for name in model_names():
        folder = model_path(name).parent
        assert (folder / "vecnormalize.npz").is_file()
        assert not (folder / "vecnormalize.pkl").exists()
        assert find_vecnormalize(model_path(name)) == str(folder / "vecnormalize.npz")
        load_vecnormalize(folder / "vecnormalize.npz")


def test_another_models_statistics_are_never_taken(trained, tmp_path, capsys):
    zoo = tmp_path / "zoo"
    (zoo / "other").mkdir(parents=True)
    shutil.copy(trained / "model.zip", zoo / "policyA.zip")
    shutil.copy(trained / "vecnormalize.npz", zoo / "other" / "vecnormalize.npz")
    assert find_vecnormalize(zoo / "policyA.zip") is None
    assert stray_vecnormalize(zoo / "policyA.zip") == [zoo / "other" / "vecnormalize.npz"]
    args = ["eval", "--env", ENV, "--policy", str(zoo / "policyA.zip"), "--out",
            str(tmp_path / "eval")]  # fmt: skip
    assert main(args) == 2
    assert _error(capsys) == (f"{zoo / 'policyA.zip'}: --policy: no statistics where training "
                              f"puts them, but {zoo / 'other' / 'vecnormalize.npz'} lies in "
                              "another folder and may be another model's: give the model's "
                              "statistics with --vecnormalize FILE, or --vecnormalize none for "
                              "raw observations")  # fmt: skip
    given = str(zoo / "other" / "vecnormalize.npz")
    config = resolve_config([ENV], None, [str(zoo / "policyA.zip")], vecnormalize=given,
                            out=str(tmp_path / "o"), log=None)  # fmt: skip
    assert config.planners[0].vecnormalize == given
    # the RL Zoo's layout still counts: <run>/<env_id>/ beside <run>/best_model.zip
    (zoo / "other").rename(zoo / ENV)
    assert find_vecnormalize(zoo / "policyA.zip", [ENV]) == str(zoo / ENV / "vecnormalize.npz")


def test_without_stable_baselines3_loading_names_the_extra():
    """Without the train extra a model is not decoded at all: the error names the extra,
    not a pickled class that could not be found."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('torch', 'stable_baselines3'):\n"
        "            raise ImportError(name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "from srpb_gym.models import load_model, model_path\n"
        "try:\n"
        "    load_model(model_path('ppo-corridor-srpb'))\n"
        "except ImportError as exc:\n"
        "    print(exc)\n"
    )
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert out.stdout.strip() == (
        'learned policies need stable-baselines3 and torch: pip install "srpb-gym[train]"'
    ), out.stderr
