"""The package's house rules, read from the source: imports point down the layer table,
no import circle (imports inside functions counted), few deferred imports, short modules.

The layer table is the architecture of the README and ``docs/architecture.md``: a module
may import its own layer and the layers above it in this list, never one below.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "srpb_gym"

#: from the ground floor up; a name is a module or a subpackage of srpb_gym
LAYERS: tuple[tuple[str, ...], ...] = (
    ("_version", "errors", "angles", "yaml_io", "resources", "data", "seeds"),
    ("config", "reward_terms", "registration"),
    ("metrics",),
    ("sim",),
    ("perception",),
    ("scenarios",),
    ("recording", "observation", "reward", "simulation"),
    ("knowledge", "task", "render"),
    ("settings", "episode_setup"),
    ("env", "mix", "pettingzoo_env"),
    ("models",),
    ("planners",),
    ("evaluation",),
    ("training",),
    ("cli", "__main__"),
    ("__init__",),  # the package itself: imports what it exports, imported by no module
)
#: imports of srpb_gym modules inside functions: only to defer an optional dependency
MAX_DEFERRED = 12
MAX_LINES = 600


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _layer(module: str) -> int:
    top = module.split(".")[0]
    for i, names in enumerate(LAYERS):
        if top in names:
            return i
    raise AssertionError(f"srpb_gym.{module} is in no layer of LAYERS: add it")


def _target(module: str, node: ast.ImportFrom | ast.Import, name: str) -> str | None:
    """The srpb_gym module (relative name, ``__init__`` for the package) an import names."""
    if isinstance(node, ast.Import):
        full = name
    else:
        base = node.module or ""
        if node.level:
            is_package = MODULES[module].name == "__init__.py"
            parts = module.split(".") if module != "__init__" else []
            parts = parts if is_package else parts[:-1]
            parts = parts[: len(parts) - node.level + 1]
            full = ".".join(["srpb_gym", *parts, *([base] if base else [])])
        else:
            full = base
        candidate = f"{full}.{name}"
        if candidate.startswith("srpb_gym.") and candidate[9:] in MODULES:
            return candidate[9:]
    if full == "srpb_gym":
        return "__init__"
    if not full.startswith("srpb_gym."):
        return None
    rel = full[9:]
    while rel not in MODULES and "." in rel:
        rel = rel.rsplit(".", 1)[0]
    return rel if rel in MODULES else None


def _imports() -> list[tuple[str, str, int, bool]]:
    """(importer, imported, line, inside a function) for every import of the package."""
    found = []
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))

        def visit(node: ast.AST, in_function: bool, module: str = module) -> None:
            for child in ast.iter_child_nodes(node):
                deeper = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for alias in child.names:
                        target = _target(module, child, alias.name)
                        if target is not None and target != module:
                            found.append((module, target, child.lineno, deeper))
                visit(child, deeper)

        visit(tree, False)
    return found


IMPORTS = _imports()


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            connect(v)
    return found


def test_every_module_has_a_layer():
    for module in MODULES:
        _layer(module)


def test_the_import_graph_has_no_circle():
    edges: dict[str, set[str]] = {}
    for source, target, _, _ in IMPORTS:
        if not target.startswith(f"{source}."):  # a package importing its own modules
            edges.setdefault(source, set()).add(target)
    assert _cycles(edges) == []


def test_imports_point_down():
    upward = [f"srpb_gym.{s} (line {n}) imports srpb_gym.{t}"
              for s, t, n, _ in IMPORTS if _layer(t) > _layer(s)]  # fmt: skip
    assert upward == []


def test_deferred_imports_are_few_and_say_why():
    deferred = [(s, t, n) for s, t, n, inside in IMPORTS if inside]
    lines = {(s, n) for s, _, n in deferred}
    assert len(lines) <= MAX_DEFERRED, sorted(lines)
    unexplained = []
    for module, line in sorted(lines):
        text = MODULES[module].read_text(encoding="utf-8").splitlines()
        comment, i = [text[line - 1]], line - 2  # the import line and the comments above it
        while i >= 0 and text[i].strip().startswith("#"):
            comment.append(text[i])
            i -= 1
        if not any("# deferred:" in c for c in comment):
            unexplained.append(f"srpb_gym.{module} line {line}")
    assert unexplained == [], "a deferred import needs a '# deferred: <why>' comment"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_are_short(module):
    lines = MODULES[module].read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"srpb_gym.{module}: {lines} lines"


def test_the_checker_sees_a_circle():
    """The guard itself: a circle through a function-level import is found."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
