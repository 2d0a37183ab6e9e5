"""The README is a landing page, and its examples print what it says they print."""

from __future__ import annotations

import pytest

from tests.doc_examples import ROOT, check, examples

README = ROOT / "README.md"
#: the README is the project's landing page; everything else lives in docs/
MAX_LINES = 250


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"README.md has {lines} lines; move sections into docs/"


@pytest.mark.parametrize("example", examples(README), ids=lambda e: e.name)
def test_example_output(example, tmp_path):
    check(example, tmp_path)
