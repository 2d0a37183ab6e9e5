"""The saved attributes of a stable-baselines3 model file, decoded without running code.

A model ``.zip`` keeps the attributes that JSON cannot hold (the policy class, the spaces,
the learning-rate and clip-range schedules, ...) in its ``data`` entry as pickles
(``{":serialized:": <base64 cloudpickle>}``), and stable-baselines3's ``load`` unpickles
them: a pickle names functions to call, so a crafted model file runs whatever it names.
srpb-gym gives ``load`` every one of them as a ``custom_objects`` entry
(:func:`safe_objects`), so that stable-baselines3 unpickles none:

* an entry is decoded by :class:`DataUnpickler`, which builds only what a model's data is
  made of: numpy arrays, dtypes and random generators, the gymnasium spaces, the classes
  of stable-baselines3's policies, feature extractors, buffers and schedules, torch's
  activation and optimiser classes, deques; any other global it names is refused, before
  anything is called;
* a schedule that cannot be decoded so (``lr_schedule``, ``clip_range``, ... saved as a
  pickled function by older versions, or a crafted one) becomes a constant: the
  constant its JSON description records (``ConstantSchedule(val=0.2)``), else the plain
  ``learning_rate`` for the learning rate, else 0. A model loaded here acts and lends its
  weights; it is not trained further, so its schedules are never called;
* the state of an unfinished rollout (``_last_obs``, the episode buffers, ...) that cannot
  be decoded is dropped (``None``);
* anything else that cannot be decoded (a custom policy class, say) is an
  :class:`UnsafeEntryError`: such a file loads only when the user trusts it
  (``--trust-pickle``).

The tensors (``policy.pth``, ``pytorch_variables.pth``, the optimiser) are read by
``torch.load(..., weights_only=True)``: :func:`~srpb_gym.models.loading.tensors_only`.
"""

from __future__ import annotations

import base64
import binascii
import importlib
import io
import math
import pickle
import re
from typing import Any

__all__ = ["DataUnpickler", "Refused", "UnsafeEntryError", "safe_objects"]

_EXACT: frozenset[tuple[str, str]] = frozenset({
    ("numpy", "dtype"), ("numpy", "ndarray"),
    ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
    ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"), ("numpy.core.multiarray", "scalar"),
    ("numpy.random._pickle", "__generator_ctor"),
    ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"),
    ("numpy.random._pcg64", "PCG64"), ("numpy.random._pcg64", "PCG64DXSM"),
    ("numpy.random._mt19937", "MT19937"), ("numpy.random._philox", "Philox"),
    ("numpy.random._sfc64", "SFC64"),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    ("numpy.random.bit_generator", "SeedSequence"), ("numpy.random._generator", "Generator"),
    ("numpy.random.mtrand", "RandomState"),
    ("collections", "deque"), ("collections", "OrderedDict"),
    ("builtins", "set"), ("builtins", "frozenset"), ("builtins", "slice"),
    ("builtins", "complex"),
    ("stable_baselines3.common.utils", "FloatSchedule"),
    ("stable_baselines3.common.utils", "ConstantSchedule"),
    ("stable_baselines3.common.utils", "LinearSchedule"),
})  # fmt: skip
"""Globals a model's data may name, exactly: numpy's array, dtype and generator
constructors, plain containers, stable-baselines3's schedule classes."""
_CLASS_MODULES = re.compile(
    r"numpy\.dtypes|gymnasium\.spaces(\.\w+)?|torch\.nn\.modules\.activation|"
    r"torch\.optim(\.\w+)?|stable_baselines3\.(common|\w+)\.policies|"
    r"stable_baselines3\.common\.(torch_layers|buffers|noise|type_aliases)"
)
"""Modules whose classes (and only classes defined in their package) a model's data may
name: dtypes, spaces, activations, optimisers, policies, feature extractors, buffers,
action noise, the train frequency."""
SCHEDULES = ("lr_schedule", "learning_rate", "clip_range", "clip_range_vf",
             "exploration_schedule")  # fmt: skip
"""Saved attributes that are schedules: a constant stands for one that cannot be decoded."""
ROLLOUT_STATE = ("_last_obs", "_last_original_obs", "_last_episode_starts",
                 "ep_info_buffer", "ep_success_buffer", "action_noise")  # fmt: skip
"""Saved attributes of an unfinished rollout: dropped when they cannot be decoded."""
_CONSTANT = re.compile(r"ConstantSchedule\(val=([-+0-9.eE]+|inf|nan)\)")


class Refused(pickle.UnpicklingError):
    """A pickle naming a global that :class:`DataUnpickler` does not build."""


class UnsafeEntryError(ValueError):
    """A pickled entry of a model's data that is not decoded without running code;
    ``str()`` says which and why (one line)."""


class DataUnpickler(pickle.Unpickler):
    """An unpickler that builds data only: it finds the globals of :data:`_EXACT` and the
    classes of the modules of :data:`_CLASS_MODULES`, and refuses every other global
    (:class:`Refused`), before calling anything."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _EXACT:
            return getattr(importlib.import_module(module), name)
        if "." not in name and _CLASS_MODULES.fullmatch(module):
            try:
                value = getattr(importlib.import_module(module), name, None)
            except ImportError:
                value = None
            root = module.split(".")[0]
            if isinstance(value, type) and value.__module__.split(".")[0] == root:
                return value
        raise Refused(f"{module}.{name}")


def decode(serialized: str) -> Any:
    """The object of one ``:serialized:`` entry, built by :class:`DataUnpickler`;
    :class:`Refused` when it names a global outside what it builds, ``ValueError`` when it
    is no such entry."""
    try:
        raw = base64.b64decode(serialized.encode(), validate=True)
    except (binascii.Error, ValueError, AttributeError):
        raise ValueError("not base64") from None
    try:
        return DataUnpickler(io.BytesIO(raw)).load()
    except Refused:
        raise
    except Exception as exc:  # truncated or garbled: no object
        raise ValueError(f"not a readable pickle ({type(exc).__name__})") from None


def safe_objects(data: dict[str, Any]) -> dict[str, Any]:
    """A ``custom_objects`` mapping for stable-baselines3's ``load`` of a model file whose
    ``data`` JSON is ``data``: an object for every pickled entry, so that ``load``
    unpickles none (module doc). A pickled entry that is neither data nor a schedule nor
    rollout state is an :class:`UnsafeEntryError` naming it."""
    out: dict[str, Any] = {}
    for key, item in data.items():
        if not (isinstance(item, dict) and ":serialized:" in item):
            continue
        try:
            out[key] = decode(item[":serialized:"])
            continue
        except Refused as exc:
            why = f"names {exc}"
        except ValueError as exc:
            why = str(exc)
        if key in SCHEDULES:
            out[key] = _constant(key, item, data)
        elif key in ROLLOUT_STATE:
            out[key] = None
        else:
            raise UnsafeEntryError(f"its saved {key!r} is a pickled object that {why}, and loading "
                              "it could run code: pass --trust-pickle if you trust where "
                              "this file came from")  # fmt: skip
    return out


def _constant(key: str, item: dict[str, Any], data: dict[str, Any]) -> float | None:
    """The constant standing for the schedule ``key`` that was not decoded (module doc);
    ``None`` for an absent value-function clip range."""
    for text in item.values():
        match = _CONSTANT.search(text) if isinstance(text, str) else None
        if match:
            return float(match[1])
    rate = data.get("learning_rate")
    if key in ("lr_schedule", "learning_rate") and isinstance(rate, (int, float)):
        return float(rate) if math.isfinite(rate) else 0.0
    return None if key == "clip_range_vf" else 0.0
