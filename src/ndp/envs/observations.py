"""The observation layout of every task family, index by index (docs/observations.md).

A policy trained here reads the observation its env returns; to feed it from another simulator
or a real robot, build the same vector. :data:`LAYOUTS` is the one statement of that layout;
``tests/envs/test_observations.py`` checks it against the environments, and
docs/observations.md against it.
"""

from __future__ import annotations

LAYOUTS: dict[str, tuple[tuple[int, int, str], ...]] = {
    "metaworld": (
        (0, 3, "hand position xyz (m): the body `hand`, the robot state's first three DoF"),
        (3, 4, "gripper opening (metaworld's normalised finger distance, about 1 open, 0 shut)"),
        (4, 7, "first object's position xyz (m): the task's object (puck, ball, faucet handle...)"),
        (7, 11, "first object's orientation, quaternion (w, x, y, z)"),
        (11, 14, "second object's position xyz (m); zeros where the task has one object"),
        (14, 18, "second object's quaternion; zeros where the task has one object"),
        (18, 36, "the same 18 values one env step (0.0125 s) earlier"),
        (36, 39, "goal position xyz (m): the task's target (visible: not partially observed)"),
    ),
    "release9": (
        (0, 3, "hand position xyz (m) (the Meta-World observation's 0:3)"),
        (3, 6, "first object's position xyz (m) (its 4:7)"),
        (6, 9, "goal position xyz (m) (its 36:39)"),
    ),
    "jaco": (
        (0, 6, "arm joint angles (rad), joints 1-6 (MuJoCo qpos, measured)"),
        (6, 9, "finger joint angles (rad), fingers 1-3"),
        (9, 15, "arm joint velocities (rad/s)"),
        (15, 18, "finger joint velocities (rad/s)"),
        (18, 21, "cube position xyz (m)"),
        (21, 25, "cube orientation, quaternion (w, x, y, z)"),
        (25, 28, "cube linear velocity xyz (m/s)"),
        (28, 31, "grip-site position xyz (m)"),
        (
            31,
            34,
            "target xyz (m): the basket centre (Throw), the lift target above the cube's "
            "start (Pick)",
        ),
    ),
    "toy": (
        (0, 2, "point position xy (box units, in [-1, 1])"),
        (2, 4, "point velocity xy (units/s)"),
        (4, 6, "goal xy (units)"),
    ),
}
"""Family (and the release's 9-D Meta-World observation) -> (start, stop, meaning) of each
block; the blocks tile the observation. Every entry is float64; Jaco's are clipped to
``ndp.envs.jaco.OBS_BOUND``. The 3-D point mass (``point-mass-3d``) has the toy layout with 3
values per block."""


def layout_markdown() -> str:
    """The tables of docs/observations.md's layout section (one per family)."""
    out = []
    for family, rows in LAYOUTS.items():
        out += [f"### `{family}` ({rows[-1][1]} values)", "", "| index | meaning |", "|---|---|"]
        out += [
            f"| {a} | {what} |" if b == a + 1 else f"| {a}:{b} | {what} |" for a, b, what in rows
        ]
        out.append("")
    return "\n".join(out)
