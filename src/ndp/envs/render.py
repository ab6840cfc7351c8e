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

    if len(frames) == 0:
        raise ValueError("frames: expected at least one frame, got none")
    shape = np.asarray(frames[0]).shape
    for f in frames:
        f = np.asarray(f)
        if f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3 or f.shape != shape:
            raise ValueError(
                f"frames: expected [H, W, 3] uint8 frames of shape {shape}, got {f.dtype} {f.shape}"
            )
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
