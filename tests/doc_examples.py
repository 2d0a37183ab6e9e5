"""The examples of the README and of the documentation: code blocks that show output.

Every fenced block of a page names its language. Two kinds of block are examples, run by
the tests and compared with what they show:

* a ```` ```python ```` block followed by a ```` ```text ```` block (prose between them,
  no heading and no other block): the code runs in a fresh interpreter and its standard
  output must be the text block;
* a ```` ```console ```` block: lines starting with ``$ `` are commands, run one after
  the other by bash in one folder; the other lines are what they print, standard output
  and, for a command that fails, its standard error.

Both run in an empty temporary folder, with this checkout's package first on the path.
In what a block shows, a line ``...`` stands for any lines and ``...`` within a line for
any text (timings, a run folder's time stamp). A ```` ```text ```` block that follows no
example must be titled as an excerpt (```` ```text title="Excerpt: ..." ````): output of a
run too long for the tests (a training run, a benchmark over hundreds of episodes).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^(\s*)(`{3,})(.*)$")
EXCERPT = 'title="Excerpt'
TIMEOUT = 600  # s, for one example


@dataclass(frozen=True)
class Block:
    """One fenced block of a page."""

    path: Path
    line: int  # of the opening fence, from 1
    info: str  # the fence's info string: language and attributes
    text: str
    after_heading: bool  # a heading lies between the previous block and this one

    @property
    def language(self) -> str:
        return self.info.split()[0] if self.info else ""


@dataclass(frozen=True)
class Example:
    """Code and the output a page shows for it."""

    path: Path
    line: int
    kind: str  # "python" or "console"
    code: str
    shown: str

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of a Markdown file, in order."""
    out: list[Block] = []
    lines = path.read_text(encoding="utf-8").splitlines()
    heading = False
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            heading = heading or lines[i].startswith("#")
            i += 1
            continue
        indent, fence, info = m.groups()
        body: list[str] = []
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            body.append(lines[j][len(indent) :] if lines[j].startswith(indent) else lines[j])
            j += 1
        out.append(Block(path, i + 1, info.strip(), "\n".join(body) + "\n", heading))
        heading = False
        i = j + 1
    return out


def examples(path: Path) -> list[Example]:
    """The examples of a Markdown file; a ValueError names a block that breaks the rules."""
    found: list[Example] = []
    previous: Block | None = None
    for block in blocks(path):
        where = f"{path.relative_to(ROOT)}:{block.line}"
        if not block.language:
            raise ValueError(f"{where}: a code block without a language")
        if block.language == "console":
            code = "\n".join(s[2:] for s in block.text.splitlines() if s.startswith("$ "))
            shown = "".join(s + "\n" for s in block.text.splitlines() if not s.startswith("$ "))
            found.append(Example(path, block.line, "console", code, shown))
        elif block.language == "text" and EXCERPT not in block.info:
            if previous is None or previous.language != "python" or block.after_heading:
                hint = f'title it as an excerpt (```text {EXCERPT}: ...") if it cannot run'
                raise ValueError(f"{where}: output that follows no ```python block; {hint}")
            found.append(Example(path, previous.line, "python", previous.text, block.text))
        previous = block
    return found


def doc_files() -> list[Path]:
    """The README and every page of the documentation."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _pattern(shown: str) -> re.Pattern[str]:
    parts = []
    for line in shown.splitlines():
        if line.strip() == "...":
            parts.append(r"(?:[^\n]*\n)*?")
        else:
            parts.append(".*".join(re.escape(p) for p in line.rstrip().split("...")) + r"\n")
    return re.compile("".join(parts))


def _normalised(text: str) -> str:
    return "".join(line.rstrip() + "\n" for line in text.splitlines())


def matches(shown: str, output: str) -> bool:
    """Whether ``output`` is what ``shown`` shows (``...`` standing for anything)."""
    return _pattern(_normalised(shown)).fullmatch(_normalised(output)) is not None


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["NO_COLOR"] = "1"
    return env


def run(example: Example, folder: Path) -> str:
    """What the example prints, run in ``folder``."""
    env = _environment()
    if example.kind == "python":
        done = subprocess.run([sys.executable, "-c", example.code], cwd=folder, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT)  # fmt: skip
        if done.returncode != 0:
            raise AssertionError(f"{example.name} failed:\n{done.stderr}")
        return done.stdout
    output = []
    for command in example.code.splitlines():
        done = subprocess.run(["bash", "-c", command], cwd=folder, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT)  # fmt: skip
        output.append(done.stdout + (done.stderr if done.returncode != 0 else ""))
    return "".join(output)


def check(example: Example, folder: Path) -> None:
    """Run the example and compare its output with what the page shows."""
    output = run(example, folder)
    assert matches(example.shown, output), (
        f"{example.name}: the page shows\n{example.shown}\nthe example prints\n{output}"
    )
