"""The chunked env's DMP-start keys in one place (ndp.chunk_info): the env reports both frames
under those keys, and every reader goes through them."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import ndp
from ndp.chunk_info import DMP_START_KEYS, dmp_start, dmp_start_keys, frame_of_keys

SRC = Path(ndp.__file__).resolve().parent


def test_the_env_reports_both_frames_under_the_protocols_keys():
    env = ndp.make_env("push-v3", k=5)
    _, info = env.reset(seed=0)
    _, *_, info2 = env.step(np.zeros((5, 4)))
    for frame in DMP_START_KEYS:
        for i in (info, info2):
            y0, dy0 = dmp_start(i, frame)
            assert y0.shape == dy0.shape == (4,) and y0.dtype == np.float64
    assert not np.array_equal(dmp_start(info2, "commanded")[0], dmp_start(info2, "measured")[0])
    env.close()


def test_keys_frames_and_errors():
    assert dmp_start_keys("commanded") == ("cmd_y0", "cmd_dy0")
    assert frame_of_keys("dmp_y0") == "measured"
    with pytest.raises(ValueError, match="dmp_state: expected one of commanded, measured"):
        dmp_start_keys("both")
    with pytest.raises(ValueError, match="info: expected the chunked env's 'cmd_y0'"):
        dmp_start({"success": True}, "commanded")
    y0, _dy0 = dmp_start({"dmp_y0": np.ones((2, 3)), "dmp_dy0": np.zeros((2, 3))}, "measured", 2)
    assert y0.shape == (2, 3)


def test_no_reader_spells_the_keys_itself():
    """Outside the env that writes them (chunked, vector) and this module, no code names the
    keys in a string literal (docstrings aside)."""
    writers = {"chunk_info.py", "envs/chunked.py", "envs/vector.py"}
    keys = {k for pair in DMP_START_KEYS.values() for k in pair}
    bad = []
    for f in SRC.rglob("*.py"):
        rel = str(f.relative_to(SRC))
        if rel in writers:
            continue
        tree = ast.parse(f.read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef))
                and n.body and isinstance(n.body[0], ast.Expr)}  # fmt: skip
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and node.value in keys and id(node) not in docs:
                bad.append(f"{rel}:{node.lineno}")
    assert not bad, bad


def test_the_step_info_is_the_schema_key_by_key_with_its_shapes_and_dtypes():
    """ChunkInfo is the one declaration of the step info: the env builds its info from it, and
    the worker vector env's shared arrays come from info_schema (the same shapes and dtypes)."""
    from ndp.chunk_info import CHUNK_INFO_KEYS, info_schema

    env = ndp.make_env("push-v3", k=5)
    env.reset(seed=0)
    *_, info = env.step(np.zeros((5, 4)))
    env.close()
    assert tuple(info) == CHUNK_INFO_KEYS
    schema = info_schema(5, 4)
    for key, (shape, dtype) in schema.items():
        value = np.asarray(info[key])
        assert value.shape == shape, key
        assert np.can_cast(value.dtype, dtype, "same_kind"), (key, value.dtype, dtype)
    assert schema["robot_pos"][0] == (6, 4) and schema["n_substeps"] == ((), np.int64)
    from ndp.envs import vector

    assert vector.info_schema is info_schema  # the vector env derives its arrays from it
