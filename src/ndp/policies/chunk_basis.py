"""Fixed bases for PPO-multi's chunk (``--chunk-basis``): pure NumPy functions and the basis file.

(The option's values are ``ndp.policies.config.CHUNK_BASES``.) PPO-multi's head outputs the k
sub-action means of a decision freely (k numbers per action
dimension). With a chunk basis, each action dimension a gets ``P = 1 + N`` outputs c_a instead
(N: the task's ``n_basis``, the NDP head's number of forcing weights per DoF, so that both heads
have the same parameters per DoF), and its k means are

    m_a = B_a c_a (+ o_a)                     B_a [k, P] fixed, o_a [k] an offset (``dmp`` only)

The exploration is PPO-multi's unchanged (a white Gaussian per sub-action, one learned log std
per action dimension): only the mean is restricted. The bases (the head is
``ndp.policies.heads.ChunkBasisHead``):

- ``dct``: :func:`dct_basis`, the first P orthonormal DCT-II vectors over the k sub-steps;
- ``bspline``: :func:`bspline_basis`, P cubic B-splines with clamped uniform knots
  (:func:`bspline_knots`) sampled at the k sub-steps t_s = s / (k - 1);
- ``pca``: :func:`pca_basis`, the top P right singular vectors per action dimension of chunks of
  sub-action means recorded from trained PPO-multi policies (``ndp rl fit-basis``), kept in a
  basis file (:func:`basis_file_bytes`, :func:`read_basis_file`, :func:`check_basis_file`);
- ``dmp``: the NDP head's own (affine) map from (g, w) to the k sub-actions with the tanh bounds
  removed (``ndp.policies.heads.NDPHead.affine_parts``); it depends on the DMP and the task, so
  it is computed from the head, not here.

A basis cannot have more columns than the chunk has sub-steps: P > k is refused
(:func:`check_columns`).
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ndp.checks import check_int

BSPLINE_DEGREE = 3
"""Degree of the ``bspline`` basis (cubic)."""
BASIS_FILE_FORMAT = "ndp-chunk-basis"
"""``provenance["format"]`` of a basis file."""
BASIS_FILE_VERSION = 1
"""``provenance["version"]`` of a basis file."""


def check_columns(basis: str, columns: int, k: int) -> None:
    """Refuse a basis of more columns than sub-steps.

    Raises:
        ValueError: ``columns > k`` (naming ``chunk_basis``, the columns and k).
    """
    if columns > k:
        raise ValueError(
            f"chunk_basis: the {basis!r} basis has 1 + n_basis = {columns} columns per DoF, more "
            f"than the k = {k} sub-steps of a decision (a basis cannot have more columns than "
            f"k); expected k >= {columns} or a smaller --n-basis"
        )


def dct_basis(k: int, columns: int) -> np.ndarray:
    """The first ``columns`` orthonormal DCT-II vectors over ``k`` samples.

    ``B[s, j] = sqrt((1 if j == 0 else 2) / k) * cos(pi * (2 s + 1) * j / (2 k))``, s = 0..k-1:
    column 0 is the constant, column j a cosine of j half periods over the chunk; ``B.T @ B = I``.

    Returns:
        [k, columns] float64.

    Raises:
        ValueError: ``k`` or ``columns`` below 1, or ``columns > k``.
    """
    _check_sizes(k, columns)
    check_columns("dct", columns, k)
    s = np.arange(k, dtype=np.float64)[:, None]
    j = np.arange(columns, dtype=np.float64)[None, :]
    scale = np.where(j == 0, math.sqrt(1.0 / k), math.sqrt(2.0 / k))
    out: np.ndarray = scale * np.cos(np.pi * (2.0 * s + 1.0) * j / (2.0 * k))
    return out


def bspline_knots(columns: int, degree: int = BSPLINE_DEGREE) -> np.ndarray:
    """Clamped uniform knot vector of ``columns`` B-splines of ``degree`` on [0, 1].

    ``degree + 1`` zeros, the ``columns - degree - 1`` interior knots ``i / (columns - degree)``
    (i = 1..columns-degree-1) and ``degree + 1`` ones: ``columns + degree + 1`` knots. For 7
    cubic columns: [0, 0, 0, 0, 1/4, 1/2, 3/4, 1, 1, 1, 1].

    Raises:
        ValueError: ``columns < degree + 1`` (too few to be clamped at both ends) or
            ``degree < 0``.
    """
    check_int("degree", degree, 0)
    if isinstance(columns, bool) or not isinstance(columns, int) or columns < degree + 1:
        raise ValueError(
            f"columns: a clamped B-spline basis of degree {degree} needs at least {degree + 1} "
            f"functions (1 + n_basis >= {degree + 1}), got {columns!r}"
        )
    inner = np.arange(1, columns - degree, dtype=np.float64) / (columns - degree)
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def bspline_basis(k: int, columns: int, degree: int = BSPLINE_DEGREE) -> np.ndarray:
    """``columns`` B-splines of ``degree`` (:func:`bspline_knots`) at the ``k`` sub-steps.

    Sampled at t_s = s / (k - 1), s = 0..k-1 (the first and last sub-steps at the clamped ends,
    so B[0] and B[k-1] are unit vectors), by the Cox-de Boor recursion; each row sums to 1
    (partition of unity) and every entry is >= 0.

    Returns:
        [k, columns] float64.

    Raises:
        ValueError: ``k < 2``, too few ``columns`` for the degree, or ``columns > k``.
    """
    _check_sizes(k, columns)
    if k < 2:
        raise ValueError(f"k: a B-spline chunk basis needs k >= 2 sub-steps, got {k}")
    knots = bspline_knots(columns, degree)
    check_columns("bspline", columns, k)
    t = np.arange(k, dtype=np.float64) / (k - 1)
    # degree 0: the indicator of [knot_i, knot_i+1); t = 1 belongs to the last non-empty span
    n_spans = len(knots) - 1
    b = np.zeros((k, n_spans))
    for i in range(n_spans):
        b[:, i] = (knots[i] <= t) & (t < knots[i + 1])
    last = max(i for i in range(n_spans) if knots[i] < knots[i + 1])
    b[t >= 1.0, :] = 0.0
    b[t >= 1.0, last] = 1.0
    for p in range(1, degree + 1):
        nxt = np.zeros((k, n_spans - p))
        for i in range(n_spans - p):
            left, right = knots[i + p] - knots[i], knots[i + p + 1] - knots[i + 1]
            if left > 0:
                nxt[:, i] += (t - knots[i]) / left * b[:, i]
            if right > 0:
                nxt[:, i] += (knots[i + p + 1] - t) / right * b[:, i + 1]
        b = nxt
    return b


def pca_basis(chunks: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The top ``columns`` principal directions of chunks, per action dimension (uncentred).

    For each action dimension a, the chunks' k-vectors X_a = chunks[:, :, a] [M, k] are
    decomposed X_a = U S V^T; the basis is the first ``columns`` right singular vectors
    (orthonormal columns), each signed so that its largest-magnitude entry is positive. The
    data are not centred: the basis is linear (c = 0 gives the zero chunk, as for PPO-multi's
    initial policy and the other linear bases), and the mean chunk, where it matters, is
    captured by the leading direction.

    Args:
        chunks: [M, k, A] sub-action means of M decisions.
        columns: P, directions kept per action dimension (1 + N).

    Returns:
        ``(basis [A, k, P], singular values [A, k] (zero-padded where M < k), explained [A]``:
        the fraction of each dimension's sum of squares the P directions hold; 1 for an
        all-zero dimension).

    Raises:
        ValueError: ``chunks`` not [M, k, A] with M >= 1, not finite, or ``columns > k``.
    """
    x = np.asarray(chunks, dtype=np.float64)
    if x.ndim != 3 or x.shape[0] < 1 or 0 in x.shape:
        raise ValueError(f"chunks: expected [M, k, A] with M >= 1, got shape {list(x.shape)}")
    if not np.isfinite(x).all():
        raise ValueError("chunks: expected finite values")
    _, k, a = x.shape
    _check_sizes(k, columns)
    check_columns("pca", columns, k)
    basis = np.zeros((a, k, columns))
    sing = np.zeros((a, k))
    explained = np.ones(a)
    for d in range(a):
        _, s, vt = np.linalg.svd(x[:, :, d], full_matrices=True)  # vt [k, k]
        v = vt[:columns].T  # [k, P]
        top = np.argmax(np.abs(v), axis=0)
        v = v * np.where(v[top, np.arange(columns)] < 0, -1.0, 1.0)
        basis[d] = v
        sing[d, : len(s)] = s
        total = float(np.sum(s**2))
        if total > 0:
            explained[d] = float(np.sum(s[:columns] ** 2)) / total
    return basis, sing, explained


@dataclass(frozen=True)
class BasisFile:
    """A chunk basis read from its file (:func:`read_basis_file`)."""

    basis: np.ndarray
    """[A, k, P] float64: each action dimension's k x P basis."""
    provenance: dict[str, Any]
    """Where it comes from: format, version, task, k, action_dim, n_basis, columns, the runs,
    decisions, date, commit (``ndp rl fit-basis``)."""
    arrays: dict[str, np.ndarray]
    """Every array of the file (``basis``, ``singular_values``, ``explained``, ``mean``)."""


def basis_file_bytes(
    basis: np.ndarray, provenance: Mapping[str, object], **arrays: np.ndarray
) -> bytes:
    """The bytes of a basis file (``.npz``, no pickled objects): ``basis`` [A, k, P],
    ``provenance`` (JSON text) and ``arrays`` (the caller writes them, atomically).

    Raises:
        ValueError: ``basis`` not [A, k, P] finite, or ``provenance`` not JSON-serialisable.
    """
    b = np.asarray(basis, dtype=np.float64)
    if b.ndim != 3 or not np.isfinite(b).all():
        raise ValueError(f"basis: expected finite [A, k, P], got shape {list(b.shape)}")
    content: dict[str, Any] = {name: np.asarray(v) for name, v in arrays.items()}
    content.update(basis=b, provenance=np.array(json.dumps(provenance, sort_keys=True)))
    buf = io.BytesIO()
    np.savez(buf, **content)
    return buf.getvalue()


def read_basis_file(path: str | Path) -> BasisFile:
    """Read a basis file (:func:`basis_file_bytes`; written by ``ndp rl fit-basis``).

    Raises:
        FileNotFoundError: no such file.
        ValueError: not a readable ``.npz`` basis file of this format (one line naming it).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"chunk_basis_file: no such file {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: np.asarray(z[name]) for name in z.files}
    except (OSError, ValueError, EOFError) as exc:
        raise ValueError(
            f"chunk_basis_file: {path} is not a readable .npz basis file ({str(exc)[:120]})"
        ) from None
    if "basis" not in arrays or "provenance" not in arrays:
        raise ValueError(
            f"chunk_basis_file: {path} holds no 'basis' and 'provenance' (expected a file of "
            f"ndp rl fit-basis), got {sorted(arrays)}"
        )
    try:
        prov = json.loads(str(arrays.pop("provenance")))
    except json.JSONDecodeError:
        prov = None
    if not isinstance(prov, dict) or prov.get("format") != BASIS_FILE_FORMAT:
        raise ValueError(
            f"chunk_basis_file: {path}: expected provenance of format {BASIS_FILE_FORMAT!r}"
        )
    if prov.get("version") != BASIS_FILE_VERSION:
        raise ValueError(
            f"chunk_basis_file: {path}: expected version {BASIS_FILE_VERSION}, got "
            f"{prov.get('version')!r}"
        )
    basis = np.asarray(arrays["basis"], dtype=np.float64)
    if basis.ndim != 3 or not np.isfinite(basis).all():
        raise ValueError(
            f"chunk_basis_file: {path}: expected a finite basis [A, k, P], got shape "
            f"{list(basis.shape)}"
        )
    shape = _shape_of(basis)
    differ = [name for name in shape if name in prov and prov[name] != shape[name]]
    if differ:
        raise ValueError(
            f"chunk_basis_file: {path}: its provenance says {[prov[n] for n in differ]} for "
            f"{differ}, its basis has {[shape[n] for n in differ]}"
        )
    return BasisFile(basis, prov, arrays)


def check_basis_file(
    data: BasisFile, path: str | Path, *, task: str, k: int, action_dim: int, columns: int
) -> None:
    """Refuse a basis file that does not fit the run: another task, k, DoF count or number of
    columns (from its provenance and its basis' shape).

    Raises:
        ValueError: the first disagreement, naming the file, what it holds and what the run
            needs.
    """
    want = {"task": task, "k": k, "action_dim": action_dim, "columns": columns}
    have = {"task": data.provenance.get("task"), **_shape_of(data.basis)}
    what = {
        "task": "task",
        "k": "k (sub-steps per decision)",
        "action_dim": "DoF count (action dimensions)",
        "columns": "columns (1 + n_basis)",
    }
    for name, value in want.items():
        if have[name] != value:
            raise ValueError(
                f"chunk_basis_file: {path} was fitted for {what[name]} {have[name]!r}, this run "
                f"needs {value!r}"
            )


def _shape_of(basis: np.ndarray) -> dict[str, int]:
    """``k``, ``action_dim`` and ``columns`` of a basis [A, k, P]."""
    a, k, p = basis.shape
    return {"k": int(k), "action_dim": int(a), "columns": int(p)}


def _check_sizes(k: int, columns: int) -> None:
    for name, v in (("k", k), ("columns", columns)):
        check_int(name, v, 1)
