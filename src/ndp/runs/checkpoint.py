"""The one checkpoint format: an atomic ``torch.save`` of a dict naming its trainer's ``kind``."""

from __future__ import annotations

import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypeAlias

from ndp.io import atomic_torch_save
from ndp.runs.layout import CHECKPOINT_NAME
from ndp.runs.signals import deferred_stops

if TYPE_CHECKING:
    import numpy as np
    import torch

__all__ = [
    "INT",
    "REAL",
    "SCHEMA_VERSION",
    "FiniteTensor",
    "Holds",
    "MayLack",
    "OptimizerState",
    "Rule",
    "Spec",
    "StateDict",
    "check_state",
    "load_checkpoint",
    "policy_schema",
    "running_stats",
    "save_checkpoint",
    "schema_version",
]


def save_checkpoint(path: str | Path, state: dict[str, Any], kind: str) -> None:
    """``torch.save({**state, 'kind': kind, 'schema_version': SCHEMA_VERSION})`` to ``path``
    atomically.

    A crash (even SIGKILL) mid-write leaves the previous checkpoint intact; a SIGTERM or Ctrl-C
    under ``stop_on_sigterm`` is held until the write is complete (``deferred_stops``).

    Args:
        path: file to write (``<run_dir>/checkpoint.pt``).
        state: the trainer's state (tensors, numbers, plain containers).
        kind: the trainer, 'rl' or 'il'; :func:`load_checkpoint` checks it.
    """
    with deferred_stops():
        atomic_torch_save({**state, "kind": kind, "schema_version": SCHEMA_VERSION}, Path(path))


def _legacy_kind(state: dict[str, Any]) -> str | None:
    """The trainer of a checkpoint written before ``kind`` was stored."""
    cfg = state.get("config")
    if isinstance(cfg, dict) and "algo" in cfg:
        return "rl"
    if isinstance(cfg, dict) and "model" in state and "data" in cfg:
        return "il"
    if "actor_critic" in state or "policy" in state:
        return "rl"
    return None


def load_checkpoint(path: str | Path, kind: str | None = None) -> dict[str, Any]:
    """Load a checkpoint written by :func:`save_checkpoint` (a run directory or the file).

    Args:
        path: the checkpoint file, or a run directory holding ``checkpoint.pt``.
        kind: expected trainer ('rl', 'il'); None accepts any.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        ValueError: the file is empty, truncated, not a checkpoint of this package, of
            another trainer than ``kind``, or of a newer :data:`SCHEMA_VERSION` (one line naming
            the file).
    """
    import torch

    path = Path(path)
    if path.is_dir():
        path = path / CHECKPOINT_NAME
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint: no such file {path}")
    try:
        state = torch.load(path, map_location="cpu", weights_only=False)
    except (EOFError, RuntimeError, OSError, ValueError, ImportError, AttributeError) as exc:
        raise ValueError(
            f"checkpoint: cannot read {path} ({type(exc).__name__}: {str(exc)[:120]}); the file "
            "is empty, truncated or not a checkpoint of this package"
        ) from None
    except Exception as exc:  # unpickling garbage raises many kinds
        raise ValueError(
            f"checkpoint: cannot read {path} ({type(exc).__name__}); the file is not a "
            "checkpoint of this package"
        ) from None
    if not isinstance(state, dict):
        raise ValueError(f"checkpoint: {path} is not a checkpoint of this package (not a dict)")
    schema_version(state, path)
    found = state.get("kind") or _legacy_kind(state)
    if kind is not None and found != kind:
        from ndp.runs.layout import RUN_KINDS

        names = {"rl": "an RL", "il": "an imitation"}
        what = names.get(str(found), "not a known")
        readers = RUN_KINDS.get(str(found), ("", ""))[1].replace("RUN", str(path.parent))
        hint = f"; read it with {readers}" if readers else ""
        raise ValueError(
            f"checkpoint: {path} is {what} checkpoint; expected {names.get(kind, kind)} one{hint}"
        )
    return state


# --------------------------------------------------------------------------- validation
SCHEMA_VERSION = 1
"""The checkpoint layout this code writes (``schema_version`` in every new checkpoint) and the
newest it reads. A checkpoint without the key was written before it was stored: version 1."""


class _Mismatch(Exception):
    """A value that does not match its schema: the key path and what was expected."""

    def __init__(self, path: str, what: str) -> None:
        super().__init__(path, what)
        self.path, self.what = path, what


def _fail(path: str, what: str) -> NoReturn:
    raise _Mismatch(path, what)


class Rule:
    """A check of one value of a checkpoint that a plain type cannot state (see :data:`Spec`)."""

    expected = "a value"
    """What the value should be, in words (the error message's 'expected ...')."""

    def check(self, value: object, path: str) -> None:
        """Raise (through :func:`check_state`) where ``value``, at key path ``path``, is wrong."""


Spec: TypeAlias = type | tuple[type, ...] | Mapping[str, "Spec"] | Rule
"""What one entry of a checkpoint must be: a type or tuple of types (``isinstance``), a section
(a mapping: key -> its spec; the value must be a dict holding every key not marked
:class:`MayLack`), or a :class:`Rule`."""

INT = numbers.Integral
"""An integer count (a Python or numpy integer; not a bool)."""
REAL = numbers.Real
"""A real number (not a bool)."""


@dataclass(frozen=True)
class MayLack(Rule):
    """An optional key: absent in older checkpoints; when present it must match ``spec``."""

    spec: Spec

    def check(self, value: object, path: str) -> None:
        """Check ``value`` against :attr:`spec`."""
        _check(value, self.spec, path)


@dataclass(frozen=True)
class Holds(Rule):
    """A value judged by ``problem`` (None: fine; else what is wrong, in words)."""

    problem: Callable[[object], str | None]
    expected: str = "a value"

    def check(self, value: object, path: str) -> None:
        """Fail with :attr:`problem`'s words when it finds one."""
        what = self.problem(value)
        if what is not None:
            _fail(path, what)


def _finite_tensor(value: object, path: str, like: torch.Tensor | np.ndarray | None = None) -> None:
    """``value`` is a tensor (or array), finite where it is a float, shaped (and of the float
    or integer kind) like ``like`` where given."""
    import numpy as np
    import torch

    if isinstance(value, np.ndarray | numbers.Real) and not isinstance(value, bool):
        value = torch.as_tensor(value)
    if not isinstance(value, torch.Tensor):
        _fail(path, f"expected a tensor, got {type(value).__name__}")
    if like is not None:
        like = torch.as_tensor(like)
        if tuple(value.shape) != tuple(like.shape):
            _fail(path, f"expected shape {tuple(like.shape)}, got {tuple(value.shape)}")
        if value.is_floating_point() != like.is_floating_point():
            _fail(path, f"expected dtype {like.dtype}, got {value.dtype}")
    if value.is_floating_point() and not bool(torch.isfinite(value).all()):
        _fail(path, "holds NaN/Inf (expected finite values)")


@dataclass(frozen=True)
class FiniteTensor(Rule):
    """A tensor (or array) of finite values, shaped like ``like`` where given."""

    like: torch.Tensor | np.ndarray | None = None
    expected = "a tensor"

    def check(self, value: object, path: str) -> None:
        """Type, shape and finiteness."""
        _finite_tensor(value, path, self.like)


@dataclass(frozen=True)
class StateDict(Rule):
    """A module's state dict: the keys of ``like`` (when given) with their shapes, finite
    floats."""

    like: Mapping[str, torch.Tensor] | None = None
    expected = "a state dict of tensors"

    def check(self, value: object, path: str) -> None:
        """Keys, then every tensor."""
        if not isinstance(value, Mapping):
            _fail(path, f"expected {self.expected}, got {type(value).__name__}")
        if self.like is not None:
            missing = [k for k in self.like if k not in value]
            if missing:
                _fail(f"{path}.{missing[0]}", f"missing ({len(missing)} tensor(s) missing)")
            extra = [k for k in value if k not in self.like]
            if extra:
                _fail(f"{path}.{extra[0]}", f"unexpected ({len(extra)} tensor(s) the model lacks)")
        for key, t in value.items():
            _finite_tensor(t, f"{path}.{key}", None if self.like is None else self.like[key])


@dataclass(frozen=True)
class OptimizerState(Rule):
    """A ``torch.optim`` state dict: ``state`` and ``param_groups``, finite moments; with
    ``opt``, as many groups and parameters as it has, and moments shaped like its parameters."""

    opt: torch.optim.Optimizer | None = None
    expected = "an optimiser state"

    def check(self, value: object, path: str) -> None:
        """Structure, finiteness and (with :attr:`opt`) shapes."""
        _check(value, {"state": dict, "param_groups": list}, path)
        assert isinstance(value, dict)
        groups = value["param_groups"]
        for i, g in enumerate(groups):
            if not isinstance(g, dict) or not isinstance(g.get("params"), list):
                _fail(f"{path}.param_groups.{i}", "expected a dict with a 'params' list")
        params: dict[object, Any] = {}
        if self.opt is not None:
            now = self.opt.param_groups
            if [len(g["params"]) for g in groups] != [len(g["params"]) for g in now]:
                _fail(f"{path}.param_groups", f"expected {len(now)} group(s) of "
                      f"{[len(g['params']) for g in now]} parameter(s), got "
                      f"{[len(g['params']) for g in groups]}")  # fmt: skip
            for saved, cur in zip(groups, now, strict=True):
                params.update(zip(saved["params"], cur["params"], strict=True))
        for pid, entry in value["state"].items():
            if not isinstance(entry, dict):
                _fail(f"{path}.state.{pid}", f"expected a dict, got {type(entry).__name__}")
            p = params.get(pid)
            for key, t in entry.items():
                shaped = p if p is not None and getattr(t, "ndim", 0) > 0 else None
                _finite_tensor(t, f"{path}.state.{pid}.{key}", shaped)


def _check(value: object, spec: Spec, path: str) -> None:
    if isinstance(spec, Rule):
        spec.check(value, path)
    elif isinstance(spec, Mapping):
        if not isinstance(value, Mapping):
            _fail(path, f"expected a dict, got {type(value).__name__}")
        for key, sub in spec.items():
            where = f"{path}.{key}" if path else key
            if key in value:
                _check(value[key], sub, where)
            elif not isinstance(sub, MayLack):
                _fail(where, f"missing (expected {_expected(sub)})")
    elif not isinstance(value, spec) or (isinstance(value, bool) and spec in (INT, REAL)):
        _fail(path, f"expected {_expected(spec)}, got {type(value).__name__} {_short(value)}")


def _expected(spec: Spec) -> str:
    if isinstance(spec, Rule):
        return spec.expected
    if isinstance(spec, Mapping):
        return f"a dict with {', '.join(spec)}"
    if spec == INT:
        return "an integer"
    if spec == REAL:
        return "a number"
    names = [t.__name__ for t in (spec if isinstance(spec, tuple) else (spec,))]
    return " or ".join(names)


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _where(source: str | Path | None) -> str:
    return f"checkpoint {source}: " if source is not None else "checkpoint: "


def policy_schema(model: Mapping[str, torch.Tensor], obs_dim: int) -> dict[str, Spec]:
    """The policy keys every RL learner's checkpoint holds (``ndp.rl.methods.
    POLICY_CHECKPOINT_KEYS`` less ``config``, which the session checks): the model's state dict
    (shaped like ``model``), the observation statistics for ``obs_dim`` inputs, the counters."""
    return {
        "model": StateDict(model),
        "obs_norm": running_stats((obs_dim,)),
        "obs_dim": INT,
        "update": INT,
        "global_step": INT,
    }


def running_stats(shape: tuple[int, ...]) -> dict[str, Spec]:
    """A running mean / variance of values of ``shape`` (``ndp.rl.normalize.RunningMeanStd``)."""
    return {"mean": FiniteTensor(_zeros(shape)), "var": FiniteTensor(_zeros(shape)), "count": REAL}


def _zeros(shape: tuple[int, ...]) -> torch.Tensor:
    import torch

    return torch.zeros(shape)


def schema_version(state: Mapping[str, Any], source: str | Path | None = None) -> int:
    """The checkpoint's ``schema_version`` (1 where absent: written before it was stored).

    Raises:
        ValueError: not a positive integer, or newer than :data:`SCHEMA_VERSION` (a checkpoint
            of a newer version of this package), one line naming the file.
    """
    v = state.get("schema_version", 1)
    if isinstance(v, bool) or not isinstance(v, INT) or int(v) < 1:
        raise ValueError(f"{_where(source)}schema_version: expected a positive integer, got {v!r}")
    if int(v) > SCHEMA_VERSION:
        raise ValueError(
            f"{_where(source)}schema_version {v} is newer than this version of ndp reads "
            f"({SCHEMA_VERSION}); it was written by a newer ndp: upgrade to read or resume it"
        )
    return int(v)


def check_state(
    state: Mapping[str, Any], schema: Mapping[str, Spec], source: str | Path | None = None
) -> None:
    """Validate a loaded checkpoint (or a part of one) against ``schema`` (a section, see
    :data:`Spec`), and its :func:`schema_version`.

    Args:
        state: the checkpoint's dict.
        schema: key -> spec of what the learner reads.
        source: the file, for the message.

    Raises:
        ValueError: one line naming the file, the key path (``sac.critic_opt``) and what was
            expected.
    """
    schema_version(state, source)
    try:
        _check(state, schema, "")
    except _Mismatch as m:
        raise ValueError(f"{_where(source)}{m.path}: {m.what}") from None
