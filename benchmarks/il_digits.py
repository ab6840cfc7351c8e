"""Digit-writing benchmark: NDP vs CNN vs CNN-DMP under the paper's protocol.

For each data set (the synthetic S-MNIST equivalent with the paper's split: first 12,000 samples
shuffled into 10,000 train / 2,000 test; then Pendigits with a writer-disjoint split) and each
model, one worker process trains with Adam 1e-3, batch 100, for ``--epochs`` epochs (paper: 71)
and evaluates on the full train and test splits. Each worker's result (errors, wall time, peak
resident memory of the worker process) is written as JSON under ``--out`` as soon as it finishes;
the table is generated from those files.

Examples::

    python benchmarks/il_digits.py --epochs 71                    # full protocol, both sets
    python benchmarks/il_digits.py --epochs 5 --datasets synthetic
    python benchmarks/il_digits.py --table-only --out runs/bench_il --docs docs/imitation.md
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

MODELS = ("ndp", "cnn", "cnn-dmp")
DATASETS = ("synthetic", "pendigits")


def _worker(args: argparse.Namespace) -> int:
    import torch

    from ndp.il.models import ModelConfig
    from ndp.il.train import DataConfig, TrainConfig, evaluate, train

    torch.set_num_threads(args.threads)
    data = DataConfig(
        source=args.dataset,
        data_dir=args.data_dir,
        split="writer" if args.dataset == "pendigits" else "paper",
        split_seed=args.seed,
        pendigits_path=args.pendigits_path,
    )
    tag = _tag(args.model, args.forcing_param)
    run_dir = Path(args.out) / f"{args.dataset}-{tag}"
    cfg = TrainConfig(
        run_dir=str(run_dir),
        data=data,
        model=ModelConfig(kind=args.model, forcing_param=args.forcing_param),
        epochs=args.epochs,
        batch_size=100,
        lr=1e-3,
        seed=args.seed,
        threads=args.threads,
        progress=False,
        eval_every=args.eval_every,
    )
    t0 = time.perf_counter()
    summary = train(cfg, resume=args.resume and (run_dir / "checkpoint.pt").exists())
    train_s = time.perf_counter() - t0
    ev = evaluate(run_dir, dtw=True, threads=args.threads, include_train=True)
    hist = json.loads(json.dumps(summary["final"]))
    epoch_times = []
    import csv

    with (run_dir / "metrics.csv").open() as f:
        for row in csv.DictReader(f):
            epoch_times.append(float(row["time/epoch_s"]))
    result = {
        "dataset": args.dataset,
        "model": tag,
        "forcing_param": args.forcing_param,
        "epochs": args.epochs,
        "seed": args.seed,
        "n_train": ev["n_train"],
        "n_test": ev["n_test"],
        "train_mse_px2": ev["train_mse_px2"],
        "test_mse_px2": ev["test_mse_px2"],
        "test_dtw_px": ev["test_dtw_px"],
        "wall_s_train": sum(epoch_times),
        "wall_s_this_process": train_s,
        "epoch_s_median": sorted(epoch_times)[len(epoch_times) // 2] if epoch_times else None,
        "epoch_s_min": min(epoch_times) if epoch_times else None,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "threads": args.threads,
        "final_epoch": hist,
        "png": ev["png"],
    }
    out = Path(args.out) / f"result-{args.dataset}-{tag}.json"
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    os.replace(tmp, out)
    return 0


def data_checks(n: int, seed: int, pendigits_path: str) -> str:
    """The spec's data checks on ``n`` generated digits, as a Markdown table."""
    import numpy as np
    import torch
    from sklearn.datasets import load_digits
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.svm import SVC

    from ndp.dmp import DMPConfig, DMPLayer, fit_dmp
    from ndp.il.data import load_pendigits
    from ndp.il.realism import optdigits_features, trajectory_features
    from ndp.il.synthetic import SyntheticConfig, generate_synthetic
    from ndp.il.train import DEFAULT_PENDIGITS

    images, trajs, labels = generate_synthetic(SyntheticConfig(n_samples=n, seed=seed))
    images = images.astype(np.float32) / 255.0
    lo, hi = trajs.min(axis=1), trajs.max(axis=1)
    off = np.abs(0.5 * (lo + hi) - 20.0).max(axis=1)
    c = np.floor(trajs).astype(int)
    on_ink = images[np.arange(n)[:, None], c[..., 1], c[..., 0]]
    near = []
    for i in range(n):
        r, cc = np.nonzero(images[i] > 0.5)
        p = np.stack([cc + 0.5, r + 0.5], axis=1)
        near.append((np.linalg.norm(p[:, None] - trajs[i][None], axis=2).min(axis=1) < 1.5).mean())
    x, y = load_digits(return_X_y=True)
    img_pred = SVC(gamma=0.001).fit(x, y).predict(optdigits_features(images))
    pen = load_pendigits(pendigits_path or DEFAULT_PENDIGITS / "pendigits-train")
    knn = KNeighborsClassifier(5).fit(trajectory_features(pen.trajs), pen.labels)
    tr_pred = knn.predict(trajectory_features(trajs))
    rev_pred = knn.predict(trajectory_features(trajs[:, ::-1]))
    cfg = DMPConfig(n_basis=30, a_z=25.0, steps=300)
    demo = torch.tensor(trajs, dtype=torch.float64)
    g, w = fit_dmp(demo, cfg)
    fit_err = ((DMPLayer(cfg)(g, w, demo[:, 0]).pos - demo) ** 2).mean(dim=(1, 2)).numpy()
    again = generate_synthetic(SyntheticConfig(n_samples=n, seed=seed))
    same = all(
        a.tobytes() == b.tobytes()
        for a, b in zip(
            again, generate_synthetic(SyntheticConfig(n_samples=n, seed=seed)), strict=True
        )
    )

    def per_class(pred: np.ndarray) -> str:
        return " ".join(f"{k}:{(pred[labels == k] == k).mean():.0%}" for k in range(10))

    rows = [
        ("samples, seed", f"{n}, {seed}"),
        ("trajectory inside the frame", f"{bool(trajs.min() > 0 and trajs.max() < 40)}"),
        ("box centre offset from (20, 20)",
         f"median {np.median(off):.2f} px, {np.mean(off < 3):.0%} within 3 px, "
         f"max {off.max():.2f}"),
        ("value of the pixel under each trajectory point", f"min {on_ink.min():.2f}"),
        ("ink pixels (> 0.5) within 1.5 px of the path",
         f"mean {np.mean(near):.2%}, worst image {np.min(near):.2%}"),
        ("SVM on real 8x8 digits (sklearn), accuracy",
         f"{(img_pred == labels).mean():.1%} ({per_class(img_pred)})"),
        ("5-NN on real Pendigits strokes, accuracy",
         f"{(tr_pred == labels).mean():.1%} ({per_class(tr_pred)})"),
        ("same, strokes reversed", f"{(rev_pred == labels).mean():.1%}"),
        ("DMP N=30 least-squares fit MSE",
         f"mean {fit_err.mean():.4f}, max {fit_err.max():.4f} px^2"),
        ("same seed, same bytes", f"{same}"),
    ]  # fmt: skip
    out = ["| check | measured |", "|---|---|"]
    out += [f"| {k} | {v} |" for k, v in rows]
    return "\n".join(out)


def _tag(model: str, forcing_param: str) -> str:
    """Run name: the model, with '-weights' for the paper's raw-weight DMP output."""
    return model if model == "cnn" or forcing_param == "amplitude" else f"{model}-weights"


def _fmt(s: dict) -> str:
    return f"{s['mean']:.3f} +- {s['std']:.3f}"


def make_table(out: Path) -> str:
    """Markdown tables from the ``result-*.json`` files in ``out``."""
    lines = []
    for ds in DATASETS:
        rows = []
        for m in MODELS:
            for fp in ("amplitude", "weights"):
                p = out / f"result-{ds}-{_tag(m, fp)}.json"
                if p.exists() and not (m == "cnn" and fp == "weights"):
                    rows.append(json.loads(p.read_text()))
        if not rows:
            continue
        r0 = rows[0]
        split = "paper split" if ds == "synthetic" else "writer-disjoint split"
        lines.append(
            f"**{ds}** ({split}, {r0['n_train']} train / {r0['n_test']} test, "
            f"{r0['epochs']} epochs, seed {r0['seed']}, {r0['threads']} torch threads)\n"
        )
        lines.append(
            "| model | train MSE px^2 | test MSE px^2 | test DTW px | train wall s (sum) | "
            "epoch s median / min | peak RSS MiB |"
        )
        lines.append("|---|---|---|---|---|---|---|")
        for r in rows:
            lines.append(
                f"| {r['model']} | {_fmt(r['train_mse_px2'])} | {_fmt(r['test_mse_px2'])} | "
                f"{_fmt(r['test_dtw_px'])} | {r['wall_s_train']:.0f} | "
                f"{r['epoch_s_median']:.1f} / {r['epoch_s_min']:.1f} | {r['peak_rss_mib']:.0f} |"
            )
        by = {r["model"]: r["test_mse_px2"]["mean"] for r in rows}
        if all(k in by for k in MODELS):
            ratio = min(by["cnn"], by["cnn-dmp"]) / by["ndp"]
            lines.append(f"\nBest baseline / NDP test MSE: {ratio:.1f}x\n")
        else:
            lines.append("")
    return "\n".join(lines)


def _replace_block(path: Path, text: str, block: str = "main") -> None:
    """Replace the text between the ``il-table:<block>`` markers in ``path`` (atomically)."""
    start, end = f"<!-- il-table:{block}:start -->", f"<!-- il-table:{block}:end -->"
    doc = path.read_text()
    if start not in doc or end not in doc:
        raise SystemExit(f"{path} has no {start} ... {end} block")
    head, rest = doc.split(start, 1)
    _, tail = rest.split(end, 1)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(f"{head}{start}\n{text}\n{end}{tail}")
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--epochs", type=int, default=71, help="epochs per model (paper: 71)")
    p.add_argument("--datasets", nargs="+", default=list(DATASETS), choices=DATASETS)
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    p.add_argument("--seed", type=int, default=0, help="split, initialisation and order seed")
    p.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch threads per worker (2 threads beside another busy process thrash)",
    )
    p.add_argument("--jobs", type=int, default=1, help="workers run at the same time")
    p.add_argument(
        "--forcing-param",
        default="amplitude",
        choices=("amplitude", "weights"),
        help="DMP head output of NDP / CNN-DMP (weights: the paper's raw w; runs get -weights)",
    )
    p.add_argument("--out", default="runs/bench_il", help="run and result folder")
    p.add_argument("--data-dir", default="data", help="synthetic cache folder")
    p.add_argument("--pendigits-path", default="", help="Pendigits UNIPEN file")
    p.add_argument("--eval-every", type=int, default=0, help="test MSE every n epochs (0: end)")
    p.add_argument("--resume", action="store_true", help="continue runs with checkpoints")
    p.add_argument("--table-only", action="store_true", help="only print the table")
    p.add_argument("--markdown", default=None, help="also write the table to this file")
    p.add_argument(
        "--docs",
        default=None,
        help="replace the text between the il-table markers of this Markdown file",
    )
    p.add_argument("--docs-block", default="main", help="marker name: il-table:<name>:start")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--dataset", default="synthetic", help=argparse.SUPPRESS)
    p.add_argument("--model", default="ndp", help=argparse.SUPPRESS)
    p.add_argument(
        "--data-checks",
        type=int,
        default=0,
        help="only run the spec's data checks on this many generated digits",
    )
    args = p.parse_args(argv)
    if args.worker:
        return _worker(args)
    if args.data_checks:
        table = data_checks(args.data_checks, args.seed, args.pendigits_path)
        header = (
            f"<!-- generated by: python benchmarks/il_digits.py "
            f"{' '.join(argv or sys.argv[1:])} -->\n"
        )
        print(header + table)
        if args.docs:
            _replace_block(Path(args.docs), header + table, args.docs_block)
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if not args.table_only:
        jobs: list[tuple[str, list[str]]] = []
        for ds in args.datasets:
            for m in args.models:
                cmd = [
                    sys.executable, __file__, "--worker", "--dataset", ds, "--model", m,
                    "--epochs", str(args.epochs), "--seed", str(args.seed),
                    "--threads", str(args.threads), "--out", str(out),
                    "--data-dir", args.data_dir, "--pendigits-path", args.pendigits_path,
                    "--eval-every", str(args.eval_every), "--forcing-param", args.forcing_param,
                ]  # fmt: skip
                if args.resume:
                    cmd.append("--resume")
                jobs.append((f"{ds} / {m}", cmd))
        if "synthetic" in args.datasets:  # generate the cache once before parallel workers
            from ndp.il.data import load_synthetic
            from ndp.il.synthetic import SyntheticConfig

            load_synthetic(SyntheticConfig(n_samples=20000, seed=0), args.data_dir)
        running: list[tuple[str, subprocess.Popen]] = []
        failed = 0
        while jobs or running:
            while jobs and len(running) < args.jobs:
                name, cmd = jobs.pop(0)
                print(f"[il_digits] start {name}: {args.epochs} epochs", flush=True)
                running.append((name, subprocess.Popen(cmd)))
            time.sleep(1.0)
            for name, proc in list(running):
                if proc.poll() is not None:
                    running.remove((name, proc))
                    print(f"[il_digits] done {name}: exit code {proc.returncode}", flush=True)
                    failed += proc.returncode != 0
        if failed:
            return 1
    from ndp.experiments.provenance import git_commit

    commit = git_commit()
    table = make_table(out)
    header = (
        f"<!-- generated by: python benchmarks/il_digits.py {' '.join(argv or sys.argv[1:])} -->\n"
        f"Commit {commit}, {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs visible.\n\n"
    )
    print(header + table)
    if args.markdown:
        Path(args.markdown).write_text(header + table + "\n")
    if args.docs:
        _replace_block(Path(args.docs), header + table, args.docs_block)
    return 0


if __name__ == "__main__":
    sys.exit(main())
