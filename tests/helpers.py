"""Helpers shared by test modules (``from tests.helpers import same``)."""

from __future__ import annotations

import math

import numpy as np


def same(a, b) -> bool:
    """Equal bit for bit: same keys, types and values, NaN equal to NaN."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    return type(a) is type(b) and a == b


CLI_ERROR = "srpb-gym: error: "


def error_line(capsys, strict: bool = False) -> str:
    """The one line of a command's stderr that says ``error`` (other lines, such as notes,
    may surround it), without a traceback, less the ``srpb-gym: error: `` prefix; with
    ``strict`` the line must carry that prefix."""
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines() if "error" in line]
    assert len(lines) == 1 and "Traceback" not in err, err
    if strict:
        assert lines[0].startswith(CLI_ERROR), lines[0]
    return lines[0].removeprefix(CLI_ERROR)
