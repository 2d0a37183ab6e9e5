"""The README is a landing page, and its examples print what it says they print."""

from __future__ import annotations

import re

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


def test_links_lead_to_files():
    """On a repository's page the README's relative links lead to files (the site's pages
    generated at build time do not exist there; the home page's links are rewritten)."""
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)[^)]*\)", text) + re.findall(r'src="([^"]+)"', text)
    for target in targets:
        if "://" not in target:
            assert (ROOT / target).exists(), f"README.md links to {target}, which does not exist"
