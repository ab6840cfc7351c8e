"""ndp.envs.render.write_gif: a looping GIF of the frames, small, written atomically."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from ndp.envs.render import GIF_MAX_FPS, write_gif


def _frames(n: int = 12, size: int = 32) -> list[np.ndarray]:
    """A grey scene with a red square moving one pixel per frame."""
    out = []
    for i in range(n):
        f = np.full((size, size, 3), 200, np.uint8)
        f[10:16, i : i + 6] = (220, 20, 20)
        out.append(f)
    return out


def test_the_gif_holds_every_frame_at_the_rate_and_loops(tmp_path):
    frames = _frames()
    path = write_gif(frames, tmp_path / "sub" / "replay.gif", fps=20)
    with Image.open(path) as im:
        assert im.n_frames == len(frames) and im.info["loop"] == 0
        assert im.info["duration"] == 50
        for i in (0, 5, 11):  # the square where it was drawn, in colour
            im.seek(i)
            rgb = np.asarray(im.convert("RGB"))
            assert rgb[12, i + 2, 0] > 150 and rgb[12, i + 2, 1] < 80, i
            assert abs(int(rgb[2, 2, 0]) - 200) < 20
    assert sorted(p.name for p in path.parent.iterdir()) == ["replay.gif"]  # no temp left


def test_bad_input_is_one_line_and_writes_nothing(tmp_path):
    target = tmp_path / "x.gif"
    for kwargs, msg in (
        ({"frames": []}, "frames: expected at least one frame"),
        ({"frames": _frames(), "fps": GIF_MAX_FPS + 1}, "fps: expected an integer in 1..25"),
        ({"frames": [*_frames(2), np.zeros((8, 8, 3), np.uint8)]}, "frames: expected [H, W, 3]"),
    ):
        with pytest.raises(ValueError) as exc:
            write_gif(path=target, **kwargs)
        assert msg in str(exc.value) and "\n" not in str(exc.value)
    assert not target.exists()
