"""The documentation site's sources: a picture for every environment, the checker's input."""

from __future__ import annotations

import subprocess
import sys

from srpb_gym.registration import MIX_ID, SCENARIO_IDS
from tests.doc_examples import ROOT


def test_every_environment_has_its_picture():
    """``python scripts/render_env_figures.py`` draws them; the pages show them."""
    pictures = ROOT / "docs" / "figures" / "envs"
    for name in (*SCENARIO_IDS, MIX_ID, "srpb_v0-parallel"):
        assert (pictures / f"{name}.png").is_file(), f"run scripts/render_env_figures.py ({name})"


def test_docs_check_without_a_site(tmp_path):
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "docs_check.py"),
                           str(tmp_path / "site")], capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"docs_check: error: {tmp_path / 'site'}: no index.html; build the site first (make docs)"
    ]
