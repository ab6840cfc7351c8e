"""Rendering helpers: collect upright rgb_array frames and write mp4 files (imageio-ffmpeg).

Headless rendering needs ``MUJOCO_GL=egl`` (or ``osmesa``) set before MuJoCo's renderer is
first used; the Makefile exports it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ndp.io import check_output_path


def check_video_size(name: str, value: int) -> int:
    """``value`` if the mp4 encoder accepts it as a frame side: H.264 in yuv420p, which every
    player reads, stores colour at half resolution and so needs even widths and heights.

    Raises:
        ValueError: ``width: expected an even number of px for the mp4 video (H.264 / yuv420p
            needs even sizes), got 3``.
    """
    if int(value) % 2:
        raise ValueError(
            f"{name}: expected an even number of px for the mp4 video (H.264 / yuv420p needs "
            f"even sizes), got {value}"
        )
    return int(value)


def check_frames(frames: Sequence[np.ndarray]) -> tuple[int, ...]:
    """The shape of ``frames``, which must be at least one [H, W, 3] uint8 frame, all of one
    size (ValueError, one line naming ``frames``, otherwise)."""
    if len(frames) == 0:
        raise ValueError("frames: expected at least one frame, got none")
    shape = np.asarray(frames[0]).shape
    for f in frames:
        f = np.asarray(f)
        if f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3 or f.shape != shape:
            raise ValueError(
                f"frames: expected [H, W, 3] uint8 frames of shape {shape}, got {f.dtype} {f.shape}"
            )
    return tuple(shape)


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, fps: int = 25) -> Path:
    """Write RGB frames to an H.264 mp4.

    Args:
        frames: Sequence of [H, W, 3] uint8 frames (all the same size).
        path: Output file; parent folders are created.
        fps: Frames per second.

    Returns:
        The written path.

    Raises:
        ValueError: no frames, frames that are not [H, W, 3] uint8 of one size, or of an odd
            width or height (:func:`check_video_size`).
        OSError: the encoder wrote nothing (one line naming the path); nothing is left behind.
    """
    import imageio.v2 as imageio

    shape = check_frames(frames)
    check_video_size("height", shape[0])
    check_video_size("width", shape[1])
    path = check_output_path(path, "path")
    # written beside the target, then moved into place: a failed write leaves no partial file
    # and an existing video intact
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        # macro_block_size=1 keeps odd sizes as they are instead of resizing them.
        # (entered as its own name: imageio's stubs type ``__enter__`` as the base reader/writer)
        w = imageio.get_writer(str(tmp), fps=fps, codec="libx264", macro_block_size=1)
        with w:
            for f in frames:
                w.append_data(np.asarray(f))
        if not tmp.is_file() or tmp.stat().st_size == 0:  # never a 0-byte video called success
            raise OSError(f"the encoder wrote no bytes ({len(frames)} frames of {shape})")
        os.replace(tmp, path)
    except OSError as exc:
        raise OSError(f"path: cannot write the video {path}: {exc.strerror or exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


GIF_MAX_FPS = 25
"""The highest rate a GIF plays at as written (browsers slow frames under 20 ms to 100 ms)."""


def write_gif(frames: Sequence[np.ndarray], path: str | Path, fps: int = GIF_MAX_FPS) -> Path:
    """Write RGB frames to a looping GIF (Pillow): one 64-colour palette for every frame, fitted
    to the first, middle and last frames, without dithering, so that consecutive frames differ
    only where the scene moves and the file stays small (about 90 kB for 40 frames of 160 px).

    Args:
        frames: Sequence of [H, W, 3] uint8 frames (all the same size).
        path: Output file (``.gif``); parent folders are created.
        fps: Frames per second, 1 to :data:`GIF_MAX_FPS`.

    Returns:
        The written path (written beside it first, then moved into place).

    Raises:
        ValueError: no frames, frames that are not [H, W, 3] uint8 of one size, or ``fps``
            outside 1..GIF_MAX_FPS.
    """
    from PIL import Image

    check_frames(frames)
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= GIF_MAX_FPS:
        raise ValueError(f"fps: expected an integer in 1..{GIF_MAX_FPS}, got {fps!r}")
    strip = np.concatenate([np.asarray(frames[i]) for i in (0, len(frames) // 2, -1)], axis=1)
    palette = Image.fromarray(strip).quantize(colors=64, method=Image.Quantize.MEDIANCUT)
    images = [
        Image.fromarray(np.asarray(f)).quantize(palette=palette, dither=Image.Dither.NONE)
        for f in frames
    ]
    path = check_output_path(path, "path")
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        images[0].save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=round(1000 / fps),
            loop=0,
            optimize=True,
        )
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
