"""Synthetic digit-writing data (an S-MNIST equivalent), built from docs/smnist-spec.md.

Every digit is one continuous pen stroke made of straight segments and elliptic arcs in abstract
units (height h = 4, width w = 2, y pointing up), centred on its bounding box. The stroke is timed
by a minimum-jerk progress profile over tau = 3 s at dt = 0.01 s (301 points), mapped to the
pixel frame ``p = traj / 7 * 40 + 20`` of a 40 x 40 image (y pointing down), rendered (a pixel is
ink when its centre lies within ``thickness`` of one of the 301 points), and finally warped, image
(bilinear) and trajectory together, by a random affine map about the frame centre.

Pixel convention: pixel (row r, column c) covers [c, c + 1) x [r, r + 1) of the continuous frame,
so its centre is (x, y) = (c + 0.5, r + 0.5); the frame is [0, 40] x [0, 40].

Sample i uses its own random generator ``numpy.random.default_rng([seed, i])``, so sample i is
the same whatever the data-set size: the first 12,000 samples of a 20,000-sample set equal a
12,000-sample set.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator

from ndp.checks import plain_numbers

H_UNITS = 4.0
"""Digit height in abstract units."""
W_UNITS = 2.0
"""Digit width in abstract units."""
FRAME = 40
"""Side of the square image frame in pixels."""
UNITS_TO_PX = 40.0 / 7.0
"""Pixels per abstract unit (p = traj / 7 * 40 + 20)."""
N_POINTS = 301
"""Points per trajectory (tau = 3 s at dt = 0.01 s, end points included)."""

_ARC_STEP_DEG = 7.5  # waypoint spacing along arcs


@dataclass(frozen=True)
class SyntheticConfig:
    """Settings of the synthetic digit generator; the cache key is derived from all of them."""

    n_samples: int = 20000
    """Number of samples (digit of sample i is i mod 10)."""
    seed: int = 0
    """Master seed; sample i uses numpy.random.default_rng([seed, i])."""
    thickness: float = 1.0
    """Ink radius in pixels: a pixel is ink if its centre is closer than this to a point."""
    thickness_jitter: bool = False
    """If true the radius is thickness * (1 + 0.5 U(-1, 1)) per sample."""
    rotation_deg: float = 8.0
    """Affine warp: rotation uniform in +- this many degrees."""
    translation_px: float = 3.0
    """Affine warp: translation uniform in +- this many pixels, independently in x and y."""
    scale: float = 0.1
    """Affine warp: independent x and y scale factors uniform in 1 +- this."""
    shear: float = 0.1
    """Affine warp: y-shear (y += shear * x) uniform in +- this."""
    tau: float = 3.0
    """Duration of the stroke in seconds."""
    dt: float = 0.01
    """Sampling interval in seconds (tau / dt + 1 points)."""
    version: int = 1
    """Generator version; bump when the construction changes so caches regenerate."""

    def __post_init__(self) -> None:
        plain_numbers(self)  # numpy scalars -> Python numbers; NaN and non-bool flags refused
        if self.n_samples <= 0:
            raise ValueError(f"n_samples must be positive, got {self.n_samples}")
        if not 0.0 < self.thickness < 3.0:
            raise ValueError(f"thickness must be in (0, 3) px, got {self.thickness}")
        steps = self.tau / self.dt
        if self.tau <= 0 or self.dt <= 0 or abs(steps - round(steps)) > 1e-6:
            raise ValueError(f"tau / dt must be a positive integer, got {self.tau} / {self.dt}")
        for name in ("rotation_deg", "translation_px", "scale", "shear"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    @property
    def n_points(self) -> int:
        """Points per trajectory, tau / dt + 1."""
        return round(self.tau / self.dt) + 1

    def as_dict(self) -> dict[str, Any]:
        """All settings as a plain dict (the cache key is a hash of it)."""
        return asdict(self)


# --------------------------------------------------------------------------------------------
# Stroke construction (abstract units, y up)
# --------------------------------------------------------------------------------------------


def _u(rng: np.random.Generator, half: float) -> float:
    """Uniform jitter in [-half, half]."""
    return float(rng.uniform(-half, half))


def _rel(rng: np.random.Generator, frac: float = 0.1) -> float:
    """Multiplicative jitter 1 +- frac (the spec's unspecified 'small' jitter)."""
    return 1.0 + _u(rng, frac)


def _arc(
    centre: tuple[float, float], rx: float, ry: float, a0_deg: float, a1_deg: float
) -> np.ndarray:
    """Points of an elliptic arc from angle a0 to a1 (degrees; a1 < a0 means clockwise).

    Returns:
        [n, 2] points including both ends.
    """
    n = max(2, math.ceil(abs(a1_deg - a0_deg) / _ARC_STEP_DEG) + 1)
    ang = np.deg2rad(np.linspace(a0_deg, a1_deg, n))
    return np.stack([centre[0] + rx * np.cos(ang), centre[1] + ry * np.sin(ang)], axis=1)


def _seg(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """A straight segment as [3, 2] points (ends and midpoint)."""
    p0 = np.asarray(p0, dtype=float)
    p1 = np.asarray(p1, dtype=float)
    return np.stack([p0, 0.5 * (p0 + p1), p1])


def _polar(p: np.ndarray, length: float, deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.asarray(p, dtype=float) + length * np.array([math.cos(a), math.sin(a)])


def _join(*parts: np.ndarray) -> np.ndarray:
    """Concatenate stroke parts, dropping a part's first point when it repeats the last one."""
    out = [np.asarray(parts[0], dtype=float)]
    for part in parts[1:]:
        part = np.asarray(part, dtype=float)
        if np.linalg.norm(part[0] - out[-1][-1]) < 1e-9:
            part = part[1:]
        out.append(part)
    return np.concatenate(out, axis=0)


def _digit0(rng: np.random.Generator) -> np.ndarray:
    rx = W_UNITS / 2 + _u(rng, 0.2)
    ry = H_UNITS / 2 + _u(rng, 0.1)
    # 16 points at angles 2 pi k / 16, k = 0..15, counter-clockwise from angle 0 (not closed).
    ang = 2 * np.pi * np.arange(16) / 16
    return np.stack([rx * np.cos(ang), ry * np.sin(ang)], axis=1)


def _digit1(rng: np.random.Generator) -> np.ndarray:
    p0 = np.zeros(2)
    p1 = _polar(p0, H_UNITS / 2 + _u(rng, 0.1), 58 + _u(rng, 10))
    p2 = _polar(p1, H_UNITS + _u(rng, 0.3), -90 + _u(rng, 5))
    return _join(_seg(p0, p1), _seg(p1, p2))


def _digit2(rng: np.random.Generator) -> np.ndarray:
    rx = W_UNITS / 2 * _rel(rng)
    ry = 0.9 * _rel(rng)
    arc = _arc((0.0, H_UNITS / 2 - ry), rx, ry, 155 + _u(rng, 10), -35 + _u(rng, 10))
    bottom_left = np.array([-W_UNITS / 2 * _rel(rng), -H_UNITS / 2])
    bar_end = _polar(bottom_left, W_UNITS + _u(rng, 0.3), _u(rng, 5))
    return _join(arc, _seg(arc[-1], bottom_left), _seg(bottom_left, bar_end))


def _digit3(rng: np.random.Generator) -> np.ndarray:
    r = W_UNITS / 2
    ry = H_UNITS / 4
    top = _arc((0.0, ry), r * _rel(rng), ry * _rel(rng), 150 + _u(rng, 10), -100)
    bot = _arc((0.0, -ry), r * _rel(rng), ry * _rel(rng), 100, -150 + _u(rng, 10))
    return _join(top, bot)


def _digit4(rng: np.random.Generator) -> np.ndarray:
    y_bar = -0.6 + _u(rng, 0.2)
    p0 = np.array([W_UNITS / 2 * _rel(rng), y_bar])
    p1 = _polar(p0, W_UNITS * _rel(rng), 180 + _u(rng, 5))
    x_v = 0.35 + _u(rng, 0.15)
    p2 = np.array([x_v, H_UNITS / 2])
    p3 = _polar(p2, H_UNITS * _rel(rng, 0.05), -90 + _u(rng, 3))
    return _join(_seg(p0, p1), _seg(p1, p2), _seg(p2, p3))


def _digit5(rng: np.random.Generator) -> np.ndarray:
    p0 = np.array([0.9 * _rel(rng), H_UNITS / 2])
    p1 = np.array([-0.7 * _rel(rng), H_UNITS / 2 + _u(rng, 0.1)])
    p2 = np.array([p1[0], 0.3 * _rel(rng)])
    rx, ry = 1.0 * _rel(rng), 1.1 * _rel(rng)
    a0 = 105 + _u(rng, 5)
    centre = (0.0, p2[1] - ry * math.sin(math.radians(a0)))
    bowl = _arc(centre, rx, ry, a0, a0 - (240 + _u(rng, 12)))
    p3 = bowl[0]
    return _join(_seg(p0, p1), _seg(p1, p2), _seg(p2, p3), bowl)


def _digit6(rng: np.random.Generator) -> np.ndarray:
    r = W_UNITS / 2 * _rel(rng)
    ry = H_UNITS / 4 * _rel(rng)
    cy = -H_UNITS / 2 + ry
    # Entry arc: part of a tall ellipse that meets the circle's leftmost point going down.
    erx = 1.2 * _rel(rng)
    ery = H_UNITS - ry
    ecx = -r + erx
    entry = _arc((ecx, cy), erx, ery, 70 + _u(rng, 10), 180)
    circle = _arc((0.0, cy), r, ry, 180, 540)
    return _join(entry, circle)


def _digit7(rng: np.random.Generator) -> np.ndarray:
    p0 = np.array([-W_UNITS / 2, H_UNITS / 2])
    p1 = _polar(p0, W_UNITS * _rel(rng), _u(rng, 10))
    p2 = np.array([-0.2 + _u(rng, 0.3), -H_UNITS / 2])
    return _join(_seg(p0, p1), _seg(p1, p2))


def _digit8(rng: np.random.Generator) -> np.ndarray:
    rx_t = W_UNITS / 2 + _u(rng, 0.1)
    ry_t = H_UNITS / 4 + _u(rng, 0.1)
    rx_b = W_UNITS / 2 + _u(rng, 0.1)
    ry_b = H_UNITS / 4 + _u(rng, 0.1)
    ct = (0.0, ry_t)
    cb = (0.0, -ry_b)
    a0 = 60 + _u(rng, 10)
    upper_left = _arc(ct, rx_t, ry_t, a0, 270)
    lower = _arc(cb, rx_b, ry_b, 90, -270)
    upper_right = _arc(ct, rx_t, ry_t, 270, a0 + 330)
    return _join(upper_left, lower, upper_right)


def _digit9(rng: np.random.Generator) -> np.ndarray:
    r = W_UNITS / 2 * _rel(rng)
    ry = H_UNITS / 4 * _rel(rng)
    cy = H_UNITS / 2 - ry
    circle = _arc((0.0, cy), r, ry, 0, 360)
    trx = 1.0 * _rel(rng)
    try_ = cy + H_UNITS / 2
    tail = _arc((r - trx, cy), trx, try_, 0, -(130 + _u(rng, 10)))
    return _join(circle, tail)


DIGIT_BUILDERS: tuple[Callable[[np.random.Generator], np.ndarray], ...] = (
    _digit0,
    _digit1,
    _digit2,
    _digit3,
    _digit4,
    _digit5,
    _digit6,
    _digit7,
    _digit8,
    _digit9,
)


def min_jerk_progress(n_points: int) -> np.ndarray:
    """Minimum-jerk progress s(u) = 10 u^3 - 15 u^4 + 6 u^5 at ``n_points`` equal time steps.

    Returns:
        [n_points] values from 0 to 1 (bell-shaped speed, zero velocity at both ends).
    """
    u = np.linspace(0.0, 1.0, n_points)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def time_stroke(waypoints: np.ndarray, n_points: int) -> np.ndarray:
    """Time a stroke: chord-length parameter, minimum-jerk progress, PCHIP interpolation.

    Args:
        waypoints: [M, 2] points along the stroke (M >= 2, consecutive duplicates allowed).
        n_points: number of output samples.

    Returns:
        [n_points, 2] trajectory with a single bell-shaped speed profile.
    """
    pts = np.asarray(waypoints, dtype=float)
    d = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], d > 1e-9])
    pts = pts[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    if pts.shape[0] < 2 or s[-1] <= 0:
        raise ValueError("a stroke needs at least two distinct waypoints")
    s = s / s[-1]
    interp = PchipInterpolator(s, pts, axis=0)
    out: np.ndarray = interp(min_jerk_progress(n_points))
    return out


def units_to_pixels(traj: np.ndarray) -> np.ndarray:
    """Abstract units (y up, origin at the digit centre) -> pixels of the 40 x 40 frame (y down).

    Args:
        traj: [..., 2] points in abstract units.

    Returns:
        [..., 2] pixel coordinates (x, y).
    """
    out = np.empty_like(traj, dtype=float)
    out[..., 0] = traj[..., 0] * UNITS_TO_PX + FRAME / 2
    out[..., 1] = -traj[..., 1] * UNITS_TO_PX + FRAME / 2
    return out


def render_points(
    points: np.ndarray, thickness: float = 1.0, size: int = FRAME, mask: np.ndarray | None = None
) -> np.ndarray:
    """Binary image: a pixel is ink (1.0) if its centre is closer than ``thickness`` to a point.

    Args:
        points: [T, 2] pixel coordinates (x, y); pixel (r, c) has centre (c + 0.5, r + 0.5).
        thickness: ink radius in pixels (< 3).
        size: image side in pixels.
        mask: optional [T] bool; only points where it is true are drawn (pen-down parts).

    Returns:
        [size, size] float32 image with values in {0, 1}.
    """
    pts = np.asarray(points, dtype=float)
    if mask is not None:
        pts = pts[np.asarray(mask, dtype=bool)]
    img = np.zeros((size, size), dtype=np.float32)
    if pts.shape[0] == 0:
        return img
    reach = math.ceil(thickness) + 1
    offs = np.arange(-reach, reach + 1)
    base_c = np.floor(pts[:, 0]).astype(int)
    base_r = np.floor(pts[:, 1]).astype(int)
    cc = base_c[:, None, None] + offs[None, None, :]  # [T, 1, K]
    rr = base_r[:, None, None] + offs[None, :, None]  # [T, K, 1]
    dx = cc + 0.5 - pts[:, 0, None, None]
    dy = rr + 0.5 - pts[:, 1, None, None]
    hit = dx * dx + dy * dy < thickness * thickness
    cc, rr = np.broadcast_to(cc, hit.shape), np.broadcast_to(rr, hit.shape)
    inside = hit & (cc >= 0) & (cc < size) & (rr >= 0) & (rr < size)
    img[rr[inside], cc[inside]] = 1.0
    return img


def random_affine(rng: np.random.Generator, cfg: SyntheticConfig) -> np.ndarray:
    """Draw the 2 x 3 affine map (pixel coordinates) about the frame centre.

    The map is ``p' = A (p - c) + c + t`` with ``A = R(theta) @ Shear_y(k) @ diag(sx, sy)``.

    Returns:
        [2, 3] matrix [A | b] acting on (x, y, 1).
    """
    theta = math.radians(_u(rng, cfg.rotation_deg))
    tx, ty = _u(rng, cfg.translation_px), _u(rng, cfg.translation_px)
    sx, sy = 1.0 + _u(rng, cfg.scale), 1.0 + _u(rng, cfg.scale)
    k = _u(rng, cfg.shear)
    rot = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    shear = np.array([[1.0, 0.0], [k, 1.0]])
    a = rot @ shear @ np.diag([sx, sy])
    c = np.array([FRAME / 2, FRAME / 2])
    b = c + np.array([tx, ty]) - a @ c
    return np.concatenate([a, b[:, None]], axis=1)


def apply_affine(points: np.ndarray, affine: np.ndarray) -> np.ndarray:
    """Apply a [2, 3] affine map to [..., 2] points."""
    out: np.ndarray = points @ affine[:, :2].T + affine[:, 2]
    return out


def warp_image(image: np.ndarray, affine: np.ndarray) -> np.ndarray:
    """Warp an image by ``affine`` with bilinear sampling (zeros outside).

    The output pixel with centre q takes the input's bilinear value at ``affine^-1(q)``, so a
    point p drawn in the input appears at ``affine(p)`` in the output, like the trajectory.

    Args:
        image: [S, S] image.
        affine: [2, 3] forward map in pixel coordinates.

    Returns:
        [S, S] float32 image.
    """
    size = image.shape[0]
    a_inv = np.linalg.inv(affine[:, :2])
    b = affine[:, 2]
    centres = np.arange(size) + 0.5
    qx, qy = np.meshgrid(centres, centres)  # [S, S] each, qx varies along columns
    q = np.stack([qx, qy], axis=-1) - b
    src = q @ a_inv.T  # continuous source coordinates
    fx = src[..., 0] - 0.5  # to index space (centre of pixel c at index c)
    fy = src[..., 1] - 0.5
    x0 = np.floor(fx).astype(int)
    y0 = np.floor(fy).astype(int)
    wx = fx - x0
    wy = fy - y0
    padded = np.zeros((size + 2, size + 2), dtype=np.float64)
    padded[1:-1, 1:-1] = image

    def at(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        r = np.clip(r + 1, 0, size + 1)
        c = np.clip(c + 1, 0, size + 1)
        v: np.ndarray = padded[r, c]
        return v

    out: np.ndarray = (
        at(y0, x0) * (1 - wx) * (1 - wy)
        + at(y0, x0 + 1) * wx * (1 - wy)
        + at(y0 + 1, x0) * (1 - wx) * wy
        + at(y0 + 1, x0 + 1) * wx * wy
    )
    return out.astype(np.float32)


def make_sample(index: int, cfg: SyntheticConfig) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """Generate sample ``index`` of the set described by ``cfg``.

    Returns:
        image [40, 40] float32 in [0, 1], trajectory [T, 2] float64 pixel coordinates,
        label (index mod 10), and the [2, 3] affine map that was applied.
    """
    rng = np.random.default_rng([cfg.seed, index])
    label = index % 10
    way = DIGIT_BUILDERS[label](rng)
    traj_u = time_stroke(way, cfg.n_points)
    lo, hi = traj_u.min(axis=0), traj_u.max(axis=0)
    traj_u = traj_u - 0.5 * (lo + hi)  # centred on its bounding box
    traj = units_to_pixels(traj_u)
    thick = cfg.thickness
    if cfg.thickness_jitter:
        thick = cfg.thickness * (1.0 + 0.5 * _u(rng, 1.0))
    img = render_points(traj, thick)
    affine = random_affine(rng, cfg)
    return warp_image(img, affine), apply_affine(traj, affine), label, affine


def generate_synthetic(
    cfg: SyntheticConfig, progress: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Generate the whole set (no caching; see :func:`ndp.il.data.load_synthetic`).

    Args:
        cfg: generator settings.
        progress: show a tqdm progress bar.

    Returns:
        images [n, 40, 40] uint8 (ink 0..255), trajectories [n, T, 2] float32 pixel coordinates,
        labels [n] int64.
    """
    n = cfg.n_samples
    images = np.zeros((n, FRAME, FRAME), dtype=np.uint8)
    trajs = np.zeros((n, cfg.n_points, 2), dtype=np.float32)
    labels = np.zeros(n, dtype=np.int64)
    it = range(n)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="generating digits", unit="digit")
    for i in it:
        img, traj, lab, _ = make_sample(i, cfg)
        images[i] = np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)
        trajs[i] = traj
        labels[i] = lab
    return images, trajs, labels
