"""Every example of the documentation prints what its page says it prints
(``tests/doc_examples.py`` says what an example is)."""

from __future__ import annotations

import pytest

from tests.doc_examples import ROOT, Example, check, doc_files, examples, matches

PAGES = [path for path in doc_files() if path.name != "README.md"]
EXAMPLES = [example for path in PAGES for example in examples(path)]


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda e: e.name)
def test_example_output(example: Example, tmp_path):
    check(example, tmp_path)


def test_every_page_follows_the_rules():
    """Every block names its language; output follows its code or is an excerpt."""
    for path in doc_files():
        examples(path)  # a ValueError names the block
    assert EXAMPLES, f"no examples found under {ROOT / 'docs'}"


def test_ellipsis():
    assert matches("a\n...\nz\n", "a\nb\nc\nz\n")
    assert matches("t = ... s\n", "t = 1.5 s\n")
    assert not matches("a\nz\n", "a\nb\nz\n")
    assert not matches("t = 1 s\n", "t = 2 s\n")
