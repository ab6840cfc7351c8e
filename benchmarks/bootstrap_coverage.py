"""Coverage of the report's 95% intervals at few seeds, by simulation (prints JSON).

The report (``ndp report``, :mod:`ndp.experiments.report.stats`) gives per task a **percentile
bootstrap** interval of the mean over seeds and, for the headline number, the **t-interval**;
over tasks the **stratified-bootstrap** interval of the IQM. This script measures how often each
covers its true value when the per-run scores are drawn from distributions like ours:

- **Scores**: one Beta distribution per cell of the 10-seed headline table
  (``docs/results/ndp_regimes/headline.csv``: the deterministic success area of NDP, PPO-multi
  and PPO on push-v3 and Throw), fitted by moments to the cell's mean and sample standard
  deviation (means 0.19-0.48, standard deviations 0.08-0.19 over 10 runs).
- **Mean** (per cell): ``--sims`` experiments of n runs each; the percentile bootstrap interval
  with ``--reps`` replicates and the Student t-interval (n - 1 degrees of freedom); the true
  value is the Beta's mean. Beside the headline cells, two strongly skewed reference Betas
  (:data:`REFERENCE`, mean 0.09: arms that rarely learn, such as the off-policy learners on
  push-v3 at 0.01-0.14), where the bootstrap covers least.
- **IQM** (per method, over its two tasks): ``--sims`` experiments of n runs per task; the
  stratified-bootstrap interval of the IQM of all runs (``--reps`` replicates); the true value
  is the interquartile mean of the two tasks' equal mixture (the 25%-trimmed mean of the
  mixture distribution, computed by quadrature).
- at n = 3 and n = 10 (``--ns``).

Every interval is computed as the report computes it: the bootstrap draws are the library's
own (the same generator, seed 0, and order as :func:`stats.bootstrap_ci` and
:func:`stats.stratified_bootstrap_ci`, checked against them on the first experiments), so the
numbers are the coverage of the intervals the tables print. The coverage's Monte-Carlo standard
error is about sqrt(c (1 - c) / sims), 0.006 at 4,000 simulations. Seeds are fixed (``--seed``):
the same command prints the same JSON.

Usage::

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/bootstrap_coverage.py \\
        --out docs/results/bootstrap_coverage/bootstrap_coverage.json

Options: ``--sims`` (experiments per setting, 4000), ``--reps`` (bootstrap replicates, the
report's 5000), ``--ns`` (seeds per cell, 3 10), ``--seed`` (the data's seed, 0), ``--cells``
(the CSV the Betas are fitted to), ``--out`` (also write the JSON there, with the command,
commit and date).
"""

from __future__ import annotations

import argparse
import csv
import datetime as dt
import json
import math
import shlex
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CELLS = ROOT / "docs" / "results" / "ndp_regimes" / "headline.csv"
KEY = "det_success_area"
CONF = 0.95
REFERENCE = (("skewed, mean 0.09, sd 0.11", 0.5, 5.0), ("skewed, mean 0.09, sd 0.14", 0.3, 3.0))
"""(name, alpha, beta) of the reference Betas beside the fitted cells (mean coverage only)."""


def beta_cells(path: Path, key: str = KEY) -> list[dict[str, float | str | int]]:
    """One Beta per row of a report CSV, fitted by moments to the row's mean and sample
    variance of ``key`` (the CSV gives the population std over ``n_seeds`` runs)."""
    out = []
    with path.open() as fh:
        for r in csv.DictReader(fh):
            n = int(r["n_seeds"])
            mu = float(r[f"{key}_mean"])
            var = float(r[f"{key}_std"]) ** 2 * n / (n - 1)
            common = mu * (1 - mu) / var - 1
            out.append({"task": r["task"], "method": r["method"], "n_runs": n, "mean": mu,
                        "sd": math.sqrt(var), "alpha": mu * common,
                        "beta": (1 - mu) * common})  # fmt: skip
    return out


def mixture_iqm(params: list[tuple[float, float]]) -> float:
    """The interquartile mean (25%-trimmed mean) of the equal mixture of Betas ``params``."""
    from scipy import integrate, optimize
    from scipy import stats as sps

    dists = [sps.beta(a, b) for a, b in params]

    def cdf(x: float) -> float:
        return float(np.mean([d.cdf(x) for d in dists]))

    q1 = optimize.brentq(lambda x: cdf(x) - 0.25, 0.0, 1.0, xtol=1e-13)
    q3 = optimize.brentq(lambda x: cdf(x) - 0.75, 0.0, 1.0, xtol=1e-13)
    part, _ = integrate.quad(lambda x: x * float(np.mean([d.pdf(x) for d in dists])), q1, q3,
                             epsabs=1e-12, epsrel=1e-10, limit=200)  # fmt: skip
    return part / 0.5


def _quantiles(boot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = (1 - CONF) / 2
    return np.quantile(boot, a, axis=-1), np.quantile(boot, 1 - a, axis=-1)


def mean_coverage(
    alpha: float, beta: float, n: int, sims: int, reps: int, data_rng: np.random.Generator
) -> dict[str, float]:
    """Coverage of the percentile bootstrap and t-intervals of the mean of n Beta draws."""
    from scipy import stats as sps

    truth = alpha / (alpha + beta)
    x = data_rng.beta(alpha, beta, size=(sims, n))
    idx = np.random.default_rng(0).integers(0, n, size=(reps, n))  # stats.bootstrap_ci's draws
    lo, hi = np.empty(sims), np.empty(sims)
    for s in range(0, sims, 200):
        lo[s : s + 200], hi[s : s + 200] = _quantiles(x[s : s + 200][:, idx].mean(-1))
    half = sps.t.ppf(0.5 + CONF / 2, n - 1) * x.std(1, ddof=1) / math.sqrt(n)
    m = x.mean(1)
    return {
        "bootstrap": float(np.mean((lo <= truth) & (truth <= hi))),
        "t": float(np.mean((m - half <= truth) & (truth <= m + half))),
        "bootstrap_width": float(np.mean(hi - lo)),
        "t_width": float(np.mean(2 * half)),
    }


def iqm_coverage(
    params: list[tuple[float, float]], n: int, sims: int, reps: int, data_rng: np.random.Generator
) -> dict[str, float]:
    """Coverage of the stratified-bootstrap interval of the IQM of n runs per task."""
    truth = mixture_iqm(params)
    m = len(params)
    x = np.stack([data_rng.beta(a, b, size=(sims, n)) for a, b in params], axis=-1)  # [S, n, m]
    idx = np.random.default_rng(0).integers(0, n, size=(reps, n, m))  # stratified draws
    cut = int(0.25 * n * m)
    lo, hi = np.empty(sims), np.empty(sims)
    for s in range(0, sims, 50):
        chunk = x[s : s + 50][:, idx, np.arange(m)].reshape(-1, reps, n * m)
        chunk.sort(-1)
        lo[s : s + 50], hi[s : s + 50] = _quantiles(chunk[..., cut : n * m - cut].mean(-1))
    return {"bootstrap": float(np.mean((lo <= truth) & (truth <= hi))),
            "true_iqm": truth, "bootstrap_width": float(np.mean(hi - lo))}  # fmt: skip


def check_against_library(params: list[tuple[float, float]], reps: int) -> None:
    """The vectorised intervals above equal the library's on a few draws (same generator)."""
    from ndp.experiments.report import stats

    rng = np.random.default_rng(123)
    for n in (3, 10):
        x = np.stack([rng.beta(a, b, size=n) for a, b in params], axis=-1)
        idx = np.random.default_rng(0).integers(0, n, size=(reps, n))
        mine = _quantiles(x[:, 0][idx].mean(-1))
        assert np.allclose(mine, stats.bootstrap_ci(x[:, 0], reps=reps)), "bootstrap_ci differs"
        m = x.shape[1]
        idx3 = np.random.default_rng(0).integers(0, n, size=(reps, n, m))
        b = np.sort(x[idx3, np.arange(m)].reshape(reps, -1), -1)
        cut = int(0.25 * n * m)
        mine = _quantiles(b[:, cut : n * m - cut].mean(-1))
        lib = stats.stratified_bootstrap_ci(x, stats.iqm, reps=reps)
        assert np.allclose(mine, lib), "stratified_bootstrap_ci differs"


def _span(values: list[float]) -> dict[str, float]:
    return {"min": min(values), "max": max(values), "mean": float(np.mean(values))}


def run(cells_csv: Path, ns: list[int], sims: int, reps: int, seed: int) -> dict[str, object]:
    cells = beta_cells(cells_csv)
    by_method: dict[str, list[tuple[float, float]]] = {}
    for c in cells:
        by_method.setdefault(str(c["method"]), []).append((float(c["alpha"]), float(c["beta"])))
    check_against_library(next(iter(by_method.values())), reps)
    ss = np.random.SeedSequence(seed)
    out: dict[str, object] = {
        "distributions": cells,
        "reference": [{"name": n, "alpha": a, "beta": b} for n, a, b in REFERENCE],
    }
    mean_out: dict[str, object] = {}
    iqm_out: dict[str, object] = {}
    for n in ns:
        per = {}
        for c, child in zip(cells, ss.spawn(len(cells)), strict=True):
            rng = np.random.default_rng(child)
            per[f"{c['task']} {c['method']}"] = mean_coverage(
                float(c["alpha"]), float(c["beta"]), n, sims, reps, rng
            )
        ref = {}
        for (name, a, b), child in zip(REFERENCE, ss.spawn(len(REFERENCE)), strict=True):
            ref[name] = mean_coverage(a, b, n, sims, reps, np.random.default_rng(child))
        mean_out[str(n)] = {
            "cells": per,
            "bootstrap": _span([v["bootstrap"] for v in per.values()]),
            "t": _span([v["t"] for v in per.values()]),
            "reference": ref,
        }
        per_iqm = {}
        for (method, params), child in zip(by_method.items(), ss.spawn(len(by_method)),
                                           strict=True):  # fmt: skip
            per_iqm[method] = iqm_coverage(params, n, sims, reps, np.random.default_rng(child))
        iqm_out[str(n)] = {
            "methods": per_iqm,
            "bootstrap": _span([v["bootstrap"] for v in per_iqm.values()]),
        }
    out["mean"], out["iqm"] = mean_out, iqm_out
    out["settings"] = {
        "sims": sims, "bootstrap_replicates": reps, "conf": CONF, "ns": ns, "seed": seed,
        "cells": str(cells_csv.relative_to(ROOT)) if cells_csv.is_relative_to(ROOT)
        else cells_csv.name, "key": KEY,
        "mc_standard_error_at_0.8": math.sqrt(0.8 * 0.2 / sims),
    }  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sims", type=int, default=4000, help="experiments per setting (4000)")
    p.add_argument("--reps", type=int, default=5000, help="bootstrap replicates (the report's)")
    p.add_argument("--ns", type=int, nargs="+", default=[3, 10], help="seeds per cell (3 10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated scores (0)")
    p.add_argument("--cells", type=Path, default=CELLS, help="the CSV the Betas are fitted to")
    p.add_argument("--out", type=Path, help="also write the JSON here")
    args = p.parse_args(argv)
    if args.sims < 1 or args.reps < 1 or any(n < 2 for n in args.ns):
        p.error("--sims and --reps must be >= 1, --ns >= 2")
    from ndp.provenance import git_commit, portable_command

    res = run(args.cells.resolve(), args.ns, args.sims, args.reps, args.seed)
    argv_ = sys.argv[1:] if argv is None else argv
    res = {
        "command": "python benchmarks/bootstrap_coverage.py " + shlex.join(portable_command(argv_)),
        "commit": git_commit(),
        "date": dt.datetime.now().strftime("%Y-%m-%d %H:%M"),
        **res,
    }
    text = json.dumps(res, indent=2) + "\n"
    print(text, end="")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
