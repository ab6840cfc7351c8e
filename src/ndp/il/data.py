"""Digit-writing data sets in one schema, with caching, loaders and splits.

Schema (:class:`DigitData`): ``images`` [n, H, W] float32 in [0, 1], ``trajs`` [n, T, 2] float32
pixel coordinates (x right, y down) of the H x W frame, ``labels`` [n] int64 (-1 when unknown),
``writers`` [n] int64 (-1 when unknown). T is 301 for the paper's data.

Sources:

- :func:`load_synthetic`: the S-MNIST-equivalent generator (:mod:`ndp.il.synthetic`), cached as
  ``<data_dir>/smnist-<hash>.npz`` where the hash covers every generator setting.
- :func:`load_pendigits`: real pen trajectories in UNIPEN text (the Pendigits files).
- :func:`load_npz`: a user's own demonstrations, ``images`` [n, H, W] and ``trajectories``
  [n, T, 2] in one ``.npz`` file.
"""

from __future__ import annotations

import hashlib
import json
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator

from ndp.il.synthetic import (
    FRAME,
    H_UNITS,
    N_POINTS,
    UNITS_TO_PX,
    SyntheticConfig,
    generate_synthetic,
    render_points,
)
from ndp.io import atomic_save_npz


@dataclass
class DigitData:
    """Images with the pen trajectories that write them.

    Attributes:
        images: [n, H, W] float32 in [0, 1].
        trajs: [n, T, 2] float32 pixel coordinates (x, y), y pointing down.
        labels: [n] int64 digit class, -1 when unknown.
        writers: [n] int64 writer id, -1 when unknown.
        name: a short description of the source.
        meta: free-form provenance (settings, paths).
    """

    images: np.ndarray
    trajs: np.ndarray
    labels: np.ndarray
    writers: np.ndarray
    name: str = "data"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.images.shape[0]
        if self.images.ndim != 3:
            raise ValueError(f"images must be [n, H, W], got shape {self.images.shape}")
        if self.trajs.ndim != 3 or self.trajs.shape[2] != 2:
            raise ValueError(f"trajectories must be [n, T, 2], got shape {self.trajs.shape}")
        if self.trajs.shape[0] != n or self.labels.shape != (n,) or self.writers.shape != (n,):
            raise ValueError(
                f"sample counts differ: images {n}, trajectories {self.trajs.shape[0]}, "
                f"labels {self.labels.shape}, writers {self.writers.shape}"
            )

    def __len__(self) -> int:
        return int(self.images.shape[0])

    @property
    def n_points(self) -> int:
        """T, points per trajectory."""
        return int(self.trajs.shape[1])

    @property
    def frame(self) -> tuple[int, int]:
        """(H, W) of the image frame the trajectories live in."""
        return int(self.images.shape[1]), int(self.images.shape[2])

    def subset(self, idx: np.ndarray) -> DigitData:
        """The samples at ``idx`` (a new object; arrays are copied by fancy indexing)."""
        idx = np.asarray(idx)
        return DigitData(
            self.images[idx],
            self.trajs[idx],
            self.labels[idx],
            self.writers[idx],
            name=self.name,
            meta=dict(self.meta),
        )


# --------------------------------------------------------------------------------------------
# Atomic file helpers
# --------------------------------------------------------------------------------------------


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Read every array of an ``.npz`` with clear errors for missing or corrupt files."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"data: no such file {path}")
    if path.is_dir():
        raise ValueError(f"data: expected an .npz file, got a directory: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: np.asarray(z[k]) for k in z.files}
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, KeyError) as exc:
        raise ValueError(
            f"data: cannot read {path} as an .npz file ({type(exc).__name__}: {exc})"
        ) from exc


# --------------------------------------------------------------------------------------------
# Synthetic digits
# --------------------------------------------------------------------------------------------


def synthetic_cache_path(cfg: SyntheticConfig, data_dir: Path) -> Path:
    """Cache file of a synthetic set: ``<data_dir>/smnist-<sha1 of the settings>[:12].npz``."""
    key = json.dumps(cfg.as_dict(), sort_keys=True)
    digest = hashlib.sha1(key.encode()).hexdigest()[:12]
    return Path(data_dir) / f"smnist-{digest}.npz"


def load_synthetic(
    cfg: SyntheticConfig | None = None,
    data_dir: Path | str = "data",
    progress: bool = False,
    regenerate: bool = False,
) -> DigitData:
    """Load the synthetic set from its cache, generating (and caching) it when needed.

    A cache whose stored settings differ from ``cfg`` or that cannot be read is regenerated.

    Args:
        cfg: generator settings (default: 20,000 samples, seed 0).
        data_dir: cache folder.
        progress: progress bar while generating.
        regenerate: ignore an existing cache.

    Returns:
        The data set; ``writers`` is -1 (no writers), ``meta['config']`` the settings.
    """
    cfg = cfg or SyntheticConfig()
    path = synthetic_cache_path(cfg, Path(data_dir))
    arrays = None
    if path.exists() and not regenerate:
        try:
            arrays = _read_npz(path)
            stored = json.loads(str(arrays["config"]))
            if stored != json.loads(json.dumps(cfg.as_dict())):
                arrays = None
        except (ValueError, KeyError):
            arrays = None
    if arrays is None:
        images, trajs, labels = generate_synthetic(cfg, progress=progress)
        atomic_save_npz(
            path,
            images=images,
            trajectories=trajs,
            labels=labels,
            config=np.array(json.dumps(cfg.as_dict(), sort_keys=True)),
        )
        arrays = {"images": images, "trajectories": trajs, "labels": labels}
    images = arrays["images"].astype(np.float32) / 255.0
    n = images.shape[0]
    return DigitData(
        images=images,
        trajs=arrays["trajectories"].astype(np.float32),
        labels=arrays["labels"].astype(np.int64),
        writers=np.full(n, -1, dtype=np.int64),
        name="synthetic",
        meta={"config": cfg.as_dict(), "cache": str(path)},
    )


# --------------------------------------------------------------------------------------------
# Pendigits (UNIPEN text)
# --------------------------------------------------------------------------------------------


@dataclass
class PenDigit:
    """One raw UNIPEN digit: label, writer, sample number and its pen-down strokes.

    Attributes:
        label: digit class.
        writer: writer id.
        sample: the writer's sample number.
        strokes: list of [m_k, 2] integer tablet coordinates (y up).
    """

    label: int
    writer: int
    sample: int
    strokes: list[np.ndarray]


_SEGMENT = re.compile(r'^\.SEGMENT\s+DIGIT\s+\S+\s+\S+\s+"(\d)"')


def parse_unipen(path: Path | str) -> list[PenDigit]:
    """Parse a UNIPEN digit file (``.SEGMENT DIGIT``, ``.COMMENT``, ``.PEN_DOWN`` / ``.PEN_UP``).

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the file is not UNIPEN digit text (no digit found, or malformed lines).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"Pendigits file not found: {path}")
    if path.is_dir():
        raise ValueError(f"expected a UNIPEN text file, got a directory: {path}")
    digits: list[PenDigit] = []
    cur: PenDigit | None = None
    stroke: list[list[int]] | None = None
    try:
        text = path.read_text(encoding="ascii")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path} is not UNIPEN text (non-ASCII bytes)") from exc
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith(".SEGMENT"):
            m = _SEGMENT.match(line)
            if m is None:
                raise ValueError(f"{path}:{lineno}: malformed .SEGMENT line: {line!r}")
            cur = PenDigit(label=int(m.group(1)), writer=-1, sample=-1, strokes=[])
            digits.append(cur)
        elif line.startswith(".COMMENT") and cur is not None:
            parts = line.split()
            if len(parts) >= 4:
                cur.writer, cur.sample = int(parts[2]), int(parts[3])
        elif line.startswith(".PEN_DOWN"):
            if cur is None:
                raise ValueError(f"{path}:{lineno}: .PEN_DOWN before any .SEGMENT")
            stroke = []
        elif line.startswith(".PEN_UP"):
            if cur is not None and stroke:
                cur.strokes.append(np.asarray(stroke, dtype=np.float64))
            stroke = None
        elif line.startswith("."):
            continue
        elif stroke is not None:
            parts = line.split()
            if len(parts) != 2:
                raise ValueError(f"{path}:{lineno}: expected 'x y', got {line!r}")
            try:
                stroke.append([int(parts[0]), int(parts[1])])
            except ValueError as exc:
                raise ValueError(f"{path}:{lineno}: expected integers, got {line!r}") from exc
    digits = [d for d in digits if d.strokes]
    if not digits:
        raise ValueError(f"no digits with pen strokes found in {path}: is it a UNIPEN file?")
    return digits


def pen_digit_to_sample(
    digit: PenDigit, n_points: int = N_POINTS, thickness: float = 1.0, size: int = FRAME
) -> tuple[np.ndarray, np.ndarray]:
    """Convert one raw pen digit to the S-MNIST schema.

    Steps: flip y (tablet y points up); join the strokes so that the pen-up travel is part of the
    path (the gap is filled at the digit's median pen speed); scale uniformly so the digit is as
    tall as a synthetic one (4/7 of the frame; narrower if it would be wider than 3/4 of it) and
    centre its bounding box; resample in time to ``n_points`` by PCHIP; render the pen-down parts.

    Returns:
        image [size, size] float32 in {0, 1}, trajectory [n_points, 2] float32 pixel coordinates.
    """
    parts: list[np.ndarray] = []
    down: list[np.ndarray] = []
    steps = [np.linalg.norm(np.diff(s, axis=0), axis=1) for s in digit.strokes if len(s) > 1]
    all_steps = np.concatenate(steps) if steps else np.array([])
    speed = float(np.median(all_steps[all_steps > 0])) if np.any(all_steps > 0) else 1.0
    for k, s in enumerate(digit.strokes):
        if k > 0:
            prev = parts[-1][-1]
            gap = float(np.linalg.norm(s[0] - prev))
            n_gap = int(np.ceil(gap / speed)) - 1
            if n_gap > 0:
                lam = np.linspace(0, 1, n_gap + 2)[1:-1, None]
                parts.append(prev + lam * (s[0] - prev))
                down.append(np.zeros(n_gap, dtype=bool))
        parts.append(s)
        down.append(np.ones(len(s), dtype=bool))
    pts = np.concatenate(parts, axis=0)
    pen = np.concatenate(down)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = np.maximum(hi - lo, 1e-9)
    scale = min(H_UNITS * UNITS_TO_PX / extent[1], 0.75 * size / extent[0])
    pts = (pts - 0.5 * (lo + hi)) * scale * np.array([1.0, -1.0]) + size / 2  # flip: y down
    t_src = np.arange(len(pts), dtype=float)
    t_dst = np.linspace(0.0, t_src[-1], n_points)
    if len(pts) == 1:
        traj = np.repeat(pts, n_points, axis=0)
        pen_dst = np.ones(n_points, dtype=bool)
    else:
        traj = PchipInterpolator(t_src, pts, axis=0)(t_dst)
        # A resampled point is pen-down when both neighbouring raw samples are pen-down.
        j = np.clip(np.floor(t_dst).astype(int), 0, len(pts) - 2)
        pen_dst = pen[j] & pen[j + 1]
        pen_dst |= np.isclose(t_dst, np.round(t_dst)) & pen[np.round(t_dst).astype(int)]
    img = render_points(traj, thickness, size=size, mask=pen_dst)
    return img, traj.astype(np.float32)


def load_pendigits(path: Path | str, n_points: int = N_POINTS, thickness: float = 1.0) -> DigitData:
    """Load a Pendigits UNIPEN file into the S-MNIST schema, keeping writer ids.

    Args:
        path: the UNIPEN text file (for example ``../shared/data/pendigits/pendigits-train``).
        n_points: points per resampled trajectory.
        thickness: ink radius when rendering the pen-down parts.

    Returns:
        The data set in file order, with ``labels`` and ``writers`` filled in.
    """
    digits = parse_unipen(path)
    n = len(digits)
    images = np.zeros((n, FRAME, FRAME), dtype=np.float32)
    trajs = np.zeros((n, n_points, 2), dtype=np.float32)
    for i, d in enumerate(digits):
        images[i], trajs[i] = pen_digit_to_sample(d, n_points, thickness)
    return DigitData(
        images=images,
        trajs=trajs,
        labels=np.array([d.label for d in digits], dtype=np.int64),
        writers=np.array([d.writer for d in digits], dtype=np.int64),
        name="pendigits",
        meta={"path": str(Path(path).resolve()), "n_points": n_points},
    )


# --------------------------------------------------------------------------------------------
# A user's own demonstrations (.npz)
# --------------------------------------------------------------------------------------------

_TRAJ_KEYS = ("trajectories", "trajs", "trajectory")


def resample_trajectories(trajs: np.ndarray, n_points: int) -> np.ndarray:
    """Resample [n, T, 2] trajectories to [n, n_points, 2] by linear interpolation in time."""
    t_src = np.linspace(0.0, 1.0, trajs.shape[1])
    t_dst = np.linspace(0.0, 1.0, n_points)
    idx = np.clip(np.searchsorted(t_src, t_dst, side="right") - 1, 0, trajs.shape[1] - 2)
    lam = ((t_dst - t_src[idx]) / (t_src[idx + 1] - t_src[idx]))[None, :, None]
    out: np.ndarray = (1 - lam) * trajs[:, idx] + lam * trajs[:, idx + 1]
    return out


def load_npz(
    path: Path | str, n_points: int | None = N_POINTS, resample: bool = False
) -> DigitData:
    """Load a user's demonstrations from an ``.npz`` file.

    Expected arrays: ``images`` [n, H, W] (values in [0, 1], or 0..255 for integer types) and
    ``trajectories`` [n, T, 2] (pixel coordinates of the H x W frame, x right, y down; ``trajs``
    is accepted as a synonym). Optional: ``labels`` [n] and ``writers`` [n] integers.

    Args:
        path: the ``.npz`` file.
        n_points: required points per trajectory (None: accept any T >= 2).
        resample: when T differs from ``n_points``, resample linearly in time instead of refusing.

    Raises:
        FileNotFoundError: missing file.
        ValueError: unreadable file, missing or mis-shaped arrays, non-finite values, or a
            trajectory length other than ``n_points`` without ``resample``.
    """
    path = Path(path)
    z = _read_npz(path)
    tkey = next((k for k in _TRAJ_KEYS if k in z), None)
    if "images" not in z or tkey is None:
        raise ValueError(
            f"data: {path} must contain arrays 'images' [n, H, W] and 'trajectories' [n, T, 2]; "
            f"found {sorted(z)}"
        )
    images, trajs = z["images"], z[tkey]
    if images.ndim == 4 and images.shape[1] == 1:
        images = images[:, 0]
    if images.ndim != 3:
        raise ValueError(f"data: {path}: 'images' must be [n, H, W], got shape {images.shape}")
    if trajs.ndim != 3 or trajs.shape[2] != 2:
        raise ValueError(f"data: {path}: '{tkey}' must be [n, T, 2], got shape {trajs.shape}")
    if images.shape[0] != trajs.shape[0]:
        raise ValueError(
            f"data: {path}: {images.shape[0]} images but {trajs.shape[0]} trajectories"
        )
    if images.shape[0] == 0 or trajs.shape[1] < 2:
        raise ValueError(f"data: {path}: no samples, or trajectories with fewer than 2 points")
    if not (np.issubdtype(images.dtype, np.number) and np.issubdtype(trajs.dtype, np.number)):
        raise ValueError(f"data: {path}: 'images' and '{tkey}' must be numeric arrays")
    if np.issubdtype(images.dtype, np.integer):
        images = images.astype(np.float32) / 255.0
    images = images.astype(np.float32)
    trajs = trajs.astype(np.float64)
    if not (np.isfinite(images).all() and np.isfinite(trajs).all()):
        raise ValueError(f"data: {path}: images or trajectories contain NaN or Inf")
    if images.min() < 0.0 or images.max() > 1.0:
        raise ValueError(
            f"data: {path}: float images must lie in [0, 1], got [{images.min()}, {images.max()}]"
        )
    if n_points is not None and trajs.shape[1] != n_points:
        if not resample:
            raise ValueError(
                f"data: {path}: trajectories have {trajs.shape[1]} points, expected {n_points}; "
                "pass resample=True (CLI: --resample) to resample them in time"
            )
        trajs = resample_trajectories(trajs, n_points)
    n = images.shape[0]
    labels = z.get("labels", np.full(n, -1)).astype(np.int64).reshape(-1)
    writers = z.get("writers", np.full(n, -1)).astype(np.int64).reshape(-1)
    if labels.shape != (n,) or writers.shape != (n,):
        raise ValueError(f"data: {path}: 'labels' / 'writers' must have shape ({n},)")
    return DigitData(
        images=images,
        trajs=trajs.astype(np.float32),
        labels=labels,
        writers=writers,
        name=path.stem,
        meta={"path": str(path.resolve())},
    )


# --------------------------------------------------------------------------------------------
# Splits
# --------------------------------------------------------------------------------------------


def paper_split(
    n_total: int, n_train: int = 10000, n_test: int = 2000, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """The paper's protocol: shuffle the first ``n_train + n_test`` samples with ``seed``.

    Returns:
        (train indices [n_train], test indices [n_test]), disjoint.

    Raises:
        ValueError: the set has fewer than ``n_train + n_test`` samples.
    """
    need = n_train + n_test
    if n_train <= 0 or n_test <= 0:
        raise ValueError(
            f"split: a train / test split needs at least one sample on each side, got "
            f"n_train={n_train} and n_test={n_test} (of {n_total} samples; a file of one "
            "sample can only be trained on whole: --split all)"
        )
    if need > n_total:
        raise ValueError(f"split needs {need} samples but the data set has {n_total}")
    perm = np.random.default_rng(seed).permutation(need)
    return np.sort(perm[:n_train]), np.sort(perm[n_train:])


def writer_split(
    writers: np.ndarray, test_fraction: float = 0.2, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Writer-disjoint split: a random ``test_fraction`` of the writers forms the test set.

    Returns:
        (train indices, test indices); no writer appears in both.

    Raises:
        ValueError: fewer than two writers, unknown writers (-1), or a bad fraction.
    """
    writers = np.asarray(writers)
    if not 0.0 < test_fraction < 1.0:
        raise ValueError(f"test_fraction must be in (0, 1), got {test_fraction}")
    if np.any(writers < 0):
        raise ValueError("writer-disjoint split needs writer ids for every sample")
    ids = np.unique(writers)
    if len(ids) < 2:
        raise ValueError(f"writer-disjoint split needs at least 2 writers, got {len(ids)}")
    n_test = min(len(ids) - 1, max(1, round(test_fraction * len(ids))))
    test_ids = np.random.default_rng(seed).choice(ids, size=n_test, replace=False)
    is_test = np.isin(writers, test_ids)
    return np.flatnonzero(~is_test), np.flatnonzero(is_test)
