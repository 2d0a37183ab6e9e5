"""Reading YAML input files safely, with every failure located in the file.

:func:`read_file` reads at most ``MAX_BYTES`` and decodes UTF-8; :func:`read_yaml` turns
the text into plain data (mappings with string keys, lists, scalars) and the 1-based line
of every dotted key. Bad input raises :class:`~srpb_gym.errors.InputError` naming the
file and, where known, the line: a file too big, binary data or text not in UTF-8, a YAML
syntax error, an unknown tag, a value YAML cannot construct, nesting deeper than
``MAX_DEPTH`` or more than ``MAX_NODES`` values. Aliases (``*name``) are refused: they
are not needed in these files, and nested ones expand exponentially ("billion laughs").

Imports nothing of ``srpb_gym`` but :mod:`srpb_gym.errors`.
"""

from __future__ import annotations

import codecs
import re
from typing import Any

import yaml

from srpb_gym.errors import InputError

MAX_BYTES = 1 << 20  # a larger file is refused before it is parsed
MAX_DEPTH = 32  # levels of nested mappings and lists
MAX_NODES = 100_000  # values (scalars, mappings, lists) in one file
_PLAIN_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq")
_WIDE_BOMS = (codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE, codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)


def read_file(source: Any, file: str | None = None) -> str:
    """The text of ``source`` (a path, or a ``Traversable`` of package data), which must be
    UTF-8 and at most ``MAX_BYTES`` long; ``file`` names it in errors (default: the path)."""
    file = str(source) if file is None else file
    try:
        with source.open("rb") if hasattr(source, "open") else open(source, "rb") as stream:
            data = stream.read(MAX_BYTES + 1)
    except IsADirectoryError:
        raise InputError("is a folder, not a file", file) from None
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}", file) from None
    if len(data) > MAX_BYTES:
        raise InputError(f"the file is larger than {MAX_BYTES} bytes", file)
    return decode(data, file)


def decode(data: bytes, file: str | None = None) -> str:
    """``data`` decoded as UTF-8 (a leading byte-order mark dropped); binary data and other
    encodings are refused with the line of the first bad byte."""
    if data.startswith(_WIDE_BOMS):
        raise InputError("the file is UTF-16 or UTF-32 text; save it as UTF-8", file)
    if b"\x00" in data:
        line = data.count(b"\n", 0, data.index(b"\x00")) + 1
        raise InputError("binary data, not YAML text (a NUL byte)", file, line=line)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(
            f"not UTF-8 text (byte 0x{data[exc.start]:02x}); save the file as UTF-8", file, line
        ) from None
    return text.removeprefix("\ufeff")


class _Loader(yaml.SafeLoader):
    """The safe loader, refusing aliases, deep nesting and too many values as it composes."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.depth = 0
        self.nodes = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            raise _Refused(f"aliases (*{event.anchor}) are not supported; write the value out",
                           event.start_mark)  # fmt: skip
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise _Refused(f"more than {MAX_NODES} values in one file", event.start_mark)
        if self.depth >= MAX_DEPTH:
            raise _Refused(f"nested more than {MAX_DEPTH} levels deep", event.start_mark)
        self.depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


# YAML 1.1 (PyYAML) reads 1e-4 and 1.0e4 as strings: its floats need a dot and a signed
# exponent. Numbers with an exponent are floats here, as in YAML 1.2 and Python.
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+.0123456789"),
)


class _Refused(yaml.MarkedYAMLError):
    """Valid YAML that these files do not accept."""

    def __init__(self, problem: str, mark: Any) -> None:
        super().__init__(problem=problem, problem_mark=mark)


def read_yaml(text: str | bytes, file: str | None = None) -> tuple[Any, dict[str, int]]:
    """Plain data from YAML text (one document, not empty; bytes must be UTF-8) and the
    1-based line of every dotted key in it (``""`` for the top level, ``"a.b[2]"`` for an
    item)."""
    if isinstance(text, (bytes, bytearray)):
        text = decode(bytes(text), file)
    try:
        loader = _Loader(text)
        try:
            root = loader.get_single_node()
            if root is None:
                raise InputError("the file is empty (no YAML document)", file)
            lines: dict[str, int] = {}
            return _node_data(root, "", lines, loader, file), lines
        finally:
            loader.dispose()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = None if mark is None else mark.line + 1
        what = "" if isinstance(exc, _Refused) else "invalid YAML: "
        problem = ", ".join(p for p in (exc.context, exc.problem) if p) or str(exc)
        raise InputError(f"{what}{problem}", file, line=line) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        what = f" U+{exc.character:04X}" if isinstance(exc.character, int) else ""
        raise InputError(f"invalid YAML: the character{what} is not allowed in YAML text",
                         file, line) from None  # fmt: skip
    except yaml.YAMLError as exc:
        raise InputError(f"invalid YAML: {exc}", file) from None


def _node_data(node: yaml.Node, key: str, lines: dict[str, int], cons: Any, file: Any) -> Any:
    line = node.start_mark.line + 1
    lines.setdefault(key, line)
    if isinstance(node, yaml.CollectionNode) and node.tag not in _PLAIN_TAGS:
        where = f"{key}: " if key else ""
        raise InputError(f"{where}the tag {node.tag!r} is not supported", file, line=line,
                         key=key or None)  # fmt: skip
    if isinstance(node, yaml.MappingNode):
        cons.flatten_mapping(node)
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            line = key_node.start_mark.line + 1
            name = _scalar(key_node, key, line, cons, file)
            if not isinstance(name, str):
                raise InputError(f"{key or 'top level'}: keys must be strings", file, line=line)
            dotted = f"{key}.{name}" if key else name
            if name in out:
                raise InputError(f"{dotted}: duplicate key", file, line=line, key=dotted)
            lines[dotted] = line
            out[name] = _node_data(value_node, dotted, lines, cons, file)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [
            _node_data(item, f"{key}[{i}]", lines, cons, file) for i, item in enumerate(node.value)
        ]
    return _scalar(node, key, line, cons, file)


def _scalar(node: yaml.Node, key: str, line: int, cons: Any, file: Any) -> Any:
    """A constructed scalar (or a key node of any kind); a value YAML's own constructors
    cannot build (an unknown tag, a date like 2020-13-01) is a located error."""
    try:
        return cons.construct_object(node, deep=True)
    except (yaml.YAMLError, ValueError, OverflowError) as exc:
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        where = f"{key}: " if key else ""
        raise InputError(f"{where}cannot read the value: {problem}", file, line=line,
                         key=key or None) from None  # fmt: skip


def load_file(source: Any, file: str | None = None) -> Any:
    """The plain data of a YAML file (see :func:`read_file` and :func:`read_yaml`)."""
    file = str(source) if file is None else file
    return read_yaml(read_file(source, file), file)[0]
