"""Errors raised for bad user input (malformed logs, unknown files, bad parameters)."""

from __future__ import annotations

import os
import re


class InputError(ValueError):
    """Bad user input, located as precisely as possible.

    Attributes:
        message: what is wrong, one line.
        path: the offending file, or ``None``.
        line: the 1-based line number in ``path``, or ``None``.
        key: the offending key, column or option name when there is no line, or ``None``.

    ``str()`` gives ``path:line: message``, ``path: key: message``, ``path: message`` or
    just ``message``, depending on what is known.
    """

    def __init__(
        self,
        message: str,
        path: str | os.PathLike[str] | None = None,
        line: int | None = None,
        key: str | None = None,
    ) -> None:
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.key = key
        super().__init__(str(self))

    def __str__(self) -> str:
        where = ""
        if self.path is not None:
            where = self.path if self.line is None else f"{self.path}:{self.line}"
        if self.key is not None and self.line is None:
            where = f"{where}: {self.key}" if where else self.key
        return f"{where}: {self.message}" if where else self.message

    def __reduce__(self):  # keep the attributes when pickled (e.g. across processes)
        return (type(self), (self.message, self.path, self.line, self.key))


_UNEXPECTED = re.compile(r"unexpected keyword argument '([^']+)'")


def env_kwargs_error(env_id: str, exc: Exception, option: str = "--env-kwargs") -> InputError:
    """The :class:`InputError` for ``gym.make(env_id, **kwargs)`` failing with ``exc``: an
    unknown keyword is named (not Gymnasium's message with every keyword argument); an
    :class:`InputError` keeps its location, under ``option``."""
    if isinstance(exc, InputError):
        if exc.path is not None:  # located in a file (a scenario): say where in it
            return InputError(f"{env_id}: {exc}", key=option)
        key = f"{option}: {exc.key}" if exc.key else option
        return InputError(f"{env_id}: {exc.message}", key=key)
    match = _UNEXPECTED.search(str(exc))
    if isinstance(exc, TypeError) and match:
        return InputError(f"{env_id} takes no such argument", key=f"{option}: {match[1]}")
    return InputError(f"{env_id}: {exc}", key=option)
