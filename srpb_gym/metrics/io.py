"""Loading an episode from any supported file: srpb-gym ``.npz`` records or SRPB native logs."""

from __future__ import annotations

import os
from pathlib import Path

from srpb_gym.errors import InputError
from srpb_gym.metrics.io_native import read_native, sibling_logs
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.metrics.record import EpisodeRecord

PathLike = str | os.PathLike


def load_episode(
    path: PathLike,
    people_path: PathLike | bool | None = None,
    groups_path: PathLike | bool | None = None,
) -> EpisodeRecord:
    """Load an episode, choosing the reader by the suffix of ``path``.

    - ``.npz``: an srpb-gym record (:mod:`srpb_gym.metrics.io_npz`); no other file may be
      given.
    - anything else: an SRPB native robot log (:mod:`srpb_gym.metrics.io_native`). When
      ``people_path`` / ``groups_path`` are not given and the robot log is named
      ``*_robot.txt``, existing ``*_people.txt`` / ``*_groups.txt`` siblings are used; a
      log that is neither given nor found is refused (the social metrics cannot be
      computed without it), and ``False`` reads a run that truly logged none.

    Raises :class:`InputError` for missing or malformed files.
    """
    if Path(path).suffix.lower() == ".npz":
        if people_path is not None or groups_path is not None:
            msg = "an .npz record holds people and groups itself; give no other log"
            raise InputError(msg, path)
        return load_record(path)
    if people_path is None and groups_path is None:
        people_path, groups_path = sibling_logs(path)
    return read_native(path, people_path, groups_path)
