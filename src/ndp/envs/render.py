"""Rendering helpers: collect upright rgb_array frames and write mp4 files (imageio-ffmpeg).

Headless rendering needs ``MUJOCO_GL=egl`` (or ``osmesa``) set before MuJoCo's renderer is
first used; the Makefile exports it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, fps: int = 25) -> Path:
    """Write RGB frames to an H.264 mp4.

    Args:
        frames: Sequence of [H, W, 3] uint8 frames (all the same size).
        path: Output file; parent folders are created.
        fps: Frames per second.

    Returns:
        The written path.

    Raises:
        ValueError: no frames, or frames that are not [H, W, 3] uint8 of one size.
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
    path = check_output_path(path)
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
        os.replace(tmp, path)
    except OSError as exc:
        raise OSError(f"path: cannot write the video {path}: {exc.strerror or exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def check_output_path(path: str | Path) -> Path:
    """Make ``path``'s folder (if needed) and check that a file can be written there, before
    any expensive work; raises ``OSError`` in one line naming the path and the cause."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OSError(f"path: {path.parent} is a file, not a folder") from None
    except OSError as exc:
        raise OSError(f"path: cannot create {path.parent}: {exc.strerror or exc}") from None
    if path.is_dir():
        raise OSError(f"path: {path} is a folder; give a file name")
    if not os.access(path.parent, os.W_OK):
        raise OSError(f"path: {path.parent} is not writable")
    return path
