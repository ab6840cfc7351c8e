"""The synthetic digit generator against the checks of docs/smnist-spec.md, and the loaders."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from ndp.il.data import (
    DigitData,
    load_npz,
    load_synthetic,
    paper_split,
    parse_unipen,
    resample_trajectories,
    synthetic_cache_path,
    writer_split,
)
from ndp.il.realism import optdigits_features, trajectory_features
from ndp.il.synthetic import (
    SyntheticConfig,
    generate_synthetic,
    make_sample,
    min_jerk_progress,
    render_points,
    time_stroke,
)

N_CHECK = 400  # samples for the statistical checks (40 per class)


@pytest.fixture(scope="module")
def synth() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    images, trajs, labels = generate_synthetic(SyntheticConfig(n_samples=N_CHECK, seed=3))
    return images.astype(np.float32) / 255.0, trajs, labels


# ---------------------------------------------------------------------------------- generator


def test_shapes_ranges_and_labels(synth) -> None:
    images, trajs, labels = synth
    assert images.shape == (N_CHECK, 40, 40)
    assert trajs.shape == (N_CHECK, 301, 2)
    assert images.min() >= 0.0 and images.max() <= 1.0
    assert np.array_equal(labels, np.arange(N_CHECK) % 10)
    # every image has ink, and the trajectory stays inside the frame
    assert (images.reshape(N_CHECK, -1).max(axis=1) == 1.0).all()
    assert trajs.min() > 0.0 and trajs.max() < 40.0


def test_digits_centred_and_sized(synth) -> None:
    _, trajs, _ = synth
    lo, hi = trajs.min(axis=1), trajs.max(axis=1)
    centre = 0.5 * (lo + hi)
    # translation is +-3 px per axis; rotation (+-8 deg), shear and scale of the 23 x 11 px digit
    # about the frame centre move its bounding-box centre by up to about 2 px more
    assert np.abs(centre - 20.0).max() < 5.0
    assert np.mean(np.abs(centre - 20.0) < 3.0) > 0.9
    assert np.abs(centre.mean(axis=0) - 20.0).max() < 0.5
    height = hi[:, 1] - lo[:, 1]
    assert 19.0 < np.median(height) < 27.0  # about 23 px tall
    width = hi[:, 0] - lo[:, 0]
    assert np.median(width) < np.median(height)


def test_ink_path_consistency(synth) -> None:
    images, trajs, _ = synth
    n = images.shape[0]
    # every trajectory point lies on ink: the pixel containing it is clearly inked
    c = np.floor(trajs).astype(int)
    v = images[np.arange(n)[:, None], c[..., 1], c[..., 0]]
    assert v.min() >= 0.25
    # nearly all ink lies near the path
    near = []
    for i in range(n):
        r, cc = np.nonzero(images[i] > 0.5)
        p = np.stack([cc + 0.5, r + 0.5], axis=1)
        d = np.linalg.norm(p[:, None] - trajs[i][None], axis=2).min(axis=1)
        near.append((d < 1.5).mean())
    assert np.mean(near) > 0.995
    assert np.min(near) > 0.95


def test_min_jerk_timing() -> None:
    s = min_jerk_progress(301)
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0)
    v = np.diff(s)
    assert (v >= 0).all()
    assert v[0] < 1e-5 and v[-1] < 1e-5  # starts and ends at rest
    peak = int(np.argmax(v))
    assert abs(peak - 150) <= 1  # one bell, peak in the middle
    assert (np.diff(v[:peak]) >= 0).all() and (np.diff(v[peak + 1 :]) <= 0).all()
    # a straight stroke is timed by exactly that profile
    traj = time_stroke(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]), 301)
    assert np.allclose(traj[:, 0], 3.0 * s, atol=1e-9)


def test_one_bell_speed_per_digit(synth) -> None:
    _, trajs, _ = synth
    speed = np.linalg.norm(np.diff(trajs, axis=1), axis=2)
    assert (speed[:, :3].max(axis=1) < 0.05).all() and (speed[:, -3:].max(axis=1) < 0.05).all()
    assert (speed[:, 140:160].mean(axis=1) > speed[:, :30].mean(axis=1)).all()


def test_render_points_rule() -> None:
    img = render_points(np.array([[10.5, 20.5]]), thickness=1.0)
    assert img.sum() == 1.0 and img[20, 10] == 1.0  # only the pixel whose centre is the point
    img = render_points(np.array([[10.0, 20.0]]), thickness=1.0)
    assert img.sum() == 4.0  # four centres at distance 0.707
    img = render_points(np.array([[10.5, 20.5]]), thickness=1.5)
    assert img.sum() == 9.0  # 3 x 3 block (diagonals at 1.414)
    img = render_points(np.array([[10.5, 20.5]]), mask=np.array([False]))
    assert img.sum() == 0.0


def test_determinism_same_seed_same_bytes() -> None:
    cfg = SyntheticConfig(n_samples=30, seed=11)
    a = generate_synthetic(cfg)
    b = generate_synthetic(cfg)
    for x, y in zip(a, b, strict=True):
        assert x.tobytes() == y.tobytes()
    c = generate_synthetic(SyntheticConfig(n_samples=30, seed=12))
    assert a[1].tobytes() != c[1].tobytes()
    # sample i does not depend on the set size
    small = generate_synthetic(SyntheticConfig(n_samples=10, seed=11))
    assert small[1].tobytes() == a[1][:10].tobytes()


def test_thickness_jitter_changes_ink() -> None:
    base = SyntheticConfig(n_samples=20, seed=5)
    jit = SyntheticConfig(n_samples=20, seed=5, thickness_jitter=True)
    ink_a = generate_synthetic(base)[0].astype(float).sum(axis=(1, 2))
    ink_b = generate_synthetic(jit)[0].astype(float).sum(axis=(1, 2))
    assert np.abs(ink_a - ink_b).max() > 0


def test_affine_warp_moves_image_with_trajectory() -> None:
    cfg = SyntheticConfig(n_samples=1, seed=0, rotation_deg=0, scale=0, shear=0)
    img, traj, _, affine = make_sample(7, cfg)
    shift = affine[:, 2]
    plain = SyntheticConfig(n_samples=1, seed=0, rotation_deg=0, scale=0, shear=0, translation_px=0)
    img0, traj0, _, _ = make_sample(7, plain)

    # translation only: image ink centroid moves with the trajectory
    def centroid(im: np.ndarray) -> np.ndarray:
        r, c = np.nonzero(im)
        w = im[r, c]
        return np.array([(w * (c + 0.5)).sum(), (w * (r + 0.5)).sum()]) / w.sum()

    assert np.allclose(traj - traj0, shift, atol=1e-9)
    assert np.allclose(centroid(img) - centroid(img0), shift, atol=0.3)


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="n_samples"):
        SyntheticConfig(n_samples=0)
    with pytest.raises(ValueError, match="thickness"):
        SyntheticConfig(thickness=-1)


# ------------------------------------------------------------------------------ class realism


def test_class_realism_images_sklearn_digits(synth) -> None:
    from sklearn.datasets import load_digits
    from sklearn.svm import SVC

    x, y = load_digits(return_X_y=True)  # REAL handwritten digits, 8 x 8
    clf = SVC(gamma=0.001).fit(x, y)
    images, _, labels = synth
    acc = (clf.predict(optdigits_features(images)) == labels).mean()
    assert acc > 0.6, f"generated images recognised at {acc:.2f} (chance 0.10)"


def test_class_realism_trajectories_pendigits(synth, pendigits) -> None:
    from sklearn.neighbors import KNeighborsClassifier

    clf = KNeighborsClassifier(5).fit(trajectory_features(pendigits.trajs), pendigits.labels)
    _, trajs, labels = synth
    acc = (clf.predict(trajectory_features(trajs)) == labels).mean()
    acc_rev = (clf.predict(trajectory_features(trajs[:, ::-1])) == labels).mean()
    assert acc > 0.6, f"generated strokes recognised at {acc:.2f} (chance 0.10)"
    assert acc_rev < 0.5 * acc, "a digit drawn backwards must look different"


# ------------------------------------------------------------------------------ DMP reproduces


def test_dmp_with_30_basis_reproduces_trajectories(synth) -> None:
    torch = pytest.importorskip("torch")
    dmp = pytest.importorskip("ndp.dmp")
    cfg = dmp.DMPConfig(n_basis=30, a_z=25.0, steps=300)
    _, trajs, _ = synth
    demo = torch.tensor(trajs[:100], dtype=torch.float64)
    goal, weights = dmp.fit_dmp(demo, cfg)
    pos = dmp.DMPLayer(cfg)(goal, weights, demo[:, 0]).pos
    err = ((pos - demo) ** 2).mean(dim=(1, 2))
    assert float(err.max()) < 0.1, f"worst DMP fit {float(err.max()):.3f} px^2"


# ------------------------------------------------------------------------------------- cache


def test_cache_keyed_by_settings(tmp_path: Path) -> None:
    cfg = SyntheticConfig(n_samples=20, seed=1)
    d1 = load_synthetic(cfg, tmp_path)
    path = synthetic_cache_path(cfg, tmp_path)
    assert path.exists() and len(d1) == 20
    mtime = path.stat().st_mtime_ns
    d2 = load_synthetic(cfg, tmp_path)
    assert path.stat().st_mtime_ns == mtime  # read back, not regenerated
    assert d2.images.tobytes() == d1.images.tobytes()
    assert np.array_equal(d2.trajs, d1.trajs)
    other = SyntheticConfig(n_samples=20, seed=2)
    assert synthetic_cache_path(other, tmp_path) != path
    d3 = load_synthetic(other, tmp_path)
    assert not np.array_equal(d3.trajs, d1.trajs)
    assert len(list(tmp_path.glob("smnist-*.npz"))) == 2
    assert not list(tmp_path.glob("*.tmp"))  # atomic writes leave no temporary files


def test_corrupt_cache_is_regenerated(tmp_path: Path) -> None:
    cfg = SyntheticConfig(n_samples=10, seed=4)
    path = synthetic_cache_path(cfg, tmp_path)
    path.write_bytes(b"not a zip file")
    data = load_synthetic(cfg, tmp_path)
    assert len(data) == 10
    assert np.load(path)["images"].shape == (10, 40, 40)


# ---------------------------------------------------------------------------------- Pendigits


def test_pendigits_parse_matches_readme(pendigits_path: Path) -> None:
    digest = hashlib.sha256(pendigits_path.read_bytes()).hexdigest()
    assert digest == "a66225d68d7d68591e62944df1ad33b3f5aa608e2df2505844b41f5568a80da4"
    digits = parse_unipen(pendigits_path)
    assert len(digits) == 7494
    counts = np.bincount([d.label for d in digits], minlength=10)
    assert counts.tolist() == [780, 779, 780, 719, 780, 720, 720, 778, 719, 719]
    assert len({d.writer for d in digits}) == 30
    n_strokes = np.bincount([len(d.strokes) for d in digits])
    assert n_strokes[1:4].tolist() == [5564, 1921, 9]
    n_pts = [sum(len(s) for s in d.strokes) for d in digits]
    assert (min(n_pts), max(n_pts)) == (9, 185)


def test_pendigits_converted_schema(pendigits) -> None:
    d = pendigits
    assert d.images.shape == (7494, 40, 40) and d.trajs.shape == (7494, 301, 2)
    assert d.trajs.min() >= 0.0 and d.trajs.max() <= 40.0
    height = d.trajs[..., 1].max(axis=1) - d.trajs[..., 1].min(axis=1)
    assert np.median(height) == pytest.approx(40 * 4 / 7, abs=0.1)
    # y is flipped: a "7" starts with its top bar, so its first point is high (small y)
    sevens = d.trajs[d.labels == 7]
    assert np.mean(sevens[:, 0, 1] < sevens[:, -1, 1]) > 0.9
    # pen-down points lie on ink
    c = np.clip(np.floor(d.trajs[:200, 0]).astype(int), 0, 39)
    assert (d.images[np.arange(200), c[:, 1], c[:, 0]] == 1.0).all()


def test_pendigits_pen_up_travel_not_inked(tmp_path: Path) -> None:
    from ndp.il.data import load_pendigits

    text = (
        '.SEGMENT DIGIT 0 ? "4"\n.COMMENT 4 7 1\n.PEN_DOWN\n100 400\n100 300\n200 300\n.PEN_UP\n'
        ".PEN_DOWN\n200 400\n200 100\n.PEN_UP\n"
    )
    p = tmp_path / "one.txt"
    p.write_text(text)
    d = load_pendigits(p)
    assert len(d) == 1 and d.labels[0] == 4 and d.writers[0] == 7
    traj = d.trajs[0]
    # travel from (200, 300) to (200, 400) is on the path but not drawn
    assert np.linalg.norm(np.diff(traj, axis=0), axis=1).max() < 1.0
    ink_rows = np.nonzero(d.images[0].sum(axis=1))[0]
    assert ink_rows.min() <= 10  # the tall stroke reaches the top


def test_writer_split_disjoint(pendigits) -> None:
    tr, te = writer_split(pendigits.writers, test_fraction=0.2, seed=0)
    assert len(tr) + len(te) == len(pendigits)
    assert not set(pendigits.writers[tr]) & set(pendigits.writers[te])
    assert len(set(pendigits.writers[te])) == 6
    _tr2, te2 = writer_split(pendigits.writers, test_fraction=0.2, seed=0)
    assert np.array_equal(te, te2)
    with pytest.raises(ValueError, match="writer ids"):
        writer_split(np.full(10, -1))


def test_parse_unipen_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        parse_unipen(tmp_path / "missing")
    bad = tmp_path / "bad.txt"
    bad.write_text("hello world\n")
    with pytest.raises(ValueError, match="no digits"):
        parse_unipen(bad)
    bad.write_text('.SEGMENT DIGIT 0 ? "1"\n.PEN_DOWN\n1 2 3\n.PEN_UP\n')
    with pytest.raises(ValueError, match="expected 'x y'"):
        parse_unipen(bad)


# ------------------------------------------------------------------------------- splits / npz


def test_paper_split() -> None:
    tr, te = paper_split(20000, 10000, 2000, seed=0)
    assert len(tr) == 10000 and len(te) == 2000
    assert not set(tr) & set(te)
    assert max(tr.max(), te.max()) < 12000
    tr2, _ = paper_split(20000, 10000, 2000, seed=1)
    assert not np.array_equal(tr, tr2)
    with pytest.raises(ValueError, match="needs 12000"):
        paper_split(500)


def _write_npz(path: Path, **arrays: np.ndarray) -> Path:
    np.savez(path, **arrays)
    return path


def test_npz_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    imgs = (rng.random((5, 32, 32)) * 255).astype(np.uint8)
    trajs = rng.random((5, 301, 2)) * 32
    p = _write_npz(tmp_path / "mine.npz", images=imgs, trajectories=trajs, labels=np.arange(5))
    d = load_npz(p)
    assert isinstance(d, DigitData)
    assert d.images.dtype == np.float32 and d.images.max() <= 1.0
    assert d.frame == (32, 32) and d.n_points == 301
    assert np.allclose(d.trajs, trajs, atol=1e-5)
    assert d.labels.tolist() == [0, 1, 2, 3, 4] and (d.writers == -1).all()


def test_npz_bad_inputs(tmp_path: Path) -> None:
    imgs = np.zeros((4, 40, 40), np.float32)
    with pytest.raises(FileNotFoundError, match=r"^data: no such file .*nope\.npz"):
        load_npz(tmp_path / "nope.npz")
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(ValueError, match="cannot read"):
        load_npz(corrupt)
    wrong = _write_npz(tmp_path / "wrong.npz", pictures=imgs, paths=np.zeros((4, 301, 2)))
    with pytest.raises(ValueError, match="must contain arrays 'images'"):
        load_npz(wrong)
    shape = _write_npz(tmp_path / "shape.npz", images=imgs, trajectories=np.zeros((4, 301, 3)))
    with pytest.raises(ValueError, match=r"\[n, T, 2\]"):
        load_npz(shape)
    count = _write_npz(tmp_path / "count.npz", images=imgs, trajectories=np.zeros((3, 301, 2)))
    with pytest.raises(ValueError, match="4 images but 3 trajectories"):
        load_npz(count)
    nan = np.zeros((4, 301, 2))
    nan[1, 5, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        load_npz(_write_npz(tmp_path / "nan.npz", images=imgs, trajectories=nan))


def test_npz_other_length_refused_or_resampled(tmp_path: Path) -> None:
    t = np.linspace(0, 1, 51)
    trajs = np.stack([np.stack([10 + 20 * t, 5 + 30 * t], axis=1)] * 2)
    p = _write_npz(tmp_path / "short.npz", images=np.zeros((2, 40, 40)), trajectories=trajs)
    with pytest.raises(ValueError, match=r"51 points, expected 301.*resample"):
        load_npz(p)
    d = load_npz(p, resample=True)
    assert d.trajs.shape == (2, 301, 2)
    t301 = np.linspace(0, 1, 301)
    assert np.allclose(d.trajs[0, :, 0], 10 + 20 * t301, atol=1e-4)
    r = resample_trajectories(trajs, 51)
    assert np.allclose(r, trajs)


def test_cache_stores_settings(tmp_path: Path) -> None:
    cfg = SyntheticConfig(n_samples=10, seed=9)
    load_synthetic(cfg, tmp_path)
    stored = json.loads(str(np.load(synthetic_cache_path(cfg, tmp_path))["config"]))
    assert stored["seed"] == 9 and stored["n_samples"] == 10
