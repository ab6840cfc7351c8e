"""ndp sweep: tiny toy grids end to end (local pool, Ray), resume after Ctrl-C and kill -9,
retry then report of a failing run, refusal of bad input, the named studies."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from ndp.cli import main
from ndp.experiments import sweep as sw
from ndp.experiments.run_kinds import il_data_args
from ndp.experiments.studies import REGIME_1M_ARMS, STUDIES, get_study
from ndp.experiments.study import Arm
from ndp.experiments.sweep import driver as sw_driver
from ndp.experiments.sweep import runner as sw_runner

# two updates of 512 env steps per run (NDP: 520, k = 5): a few seconds each, mostly start-up
TINY = ["--tasks", "point-mass", "--steps", "1024", "-o", "steps_per_update=512"]


def _rows(run: Path) -> list[dict[str, str]]:
    with (run / "metrics.csv").open() as fh:
        return list(csv.DictReader(fh))


def _check_grid(runs: Path, out: str) -> None:
    for algo in ("ppo", "ndp"):
        for seed in (0, 1):
            run = runs / f"point-mass-{algo}-s{seed}"
            arm = json.loads((run / "arm.json").read_text())
            assert arm["task"] == "point-mass" and arm["seed"] == seed and arm["algo"] == algo
            assert [int(r["update"]) for r in _rows(run)] == [1, 2]
            assert not (run / sw.FAILED_NAME).exists()
    assert "4/4 finished (4 trained now, 0 already finished), 0 failed" in out
    assert "ETA" in out and "running" in out


def test_local_grid_2x2_end_to_end(tmp_path, capsys):
    runs = tmp_path / "runs"
    argv = ["sweep", *TINY, "--methods", "ppo", "ndp", "--seeds", "0", "1", "--jobs", "2",
            "--vector", "sync", "--runs-dir", str(runs),
            "--report", str(tmp_path / "r")]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    _check_grid(runs, out)
    assert "on local, 2 at once" in out
    md = (tmp_path / "r.md").read_text()
    assert "| point-mass | ppo | 2 |" in md and "| point-mass | ndp | 2 |" in md
    assert (tmp_path / "r-point-mass.png").stat().st_size > 5_000
    # a second sweep skips every finished run
    assert main(argv[:-2]) == 0
    assert "4/4 finished (0 trained now, 4 already finished)" in capsys.readouterr().out


def test_ray_grid_2x2_end_to_end_with_ctrl_c_and_resume(tmp_path, capsys):
    """Each run a Ray task on a local Ray started (and shut down) by the sweep, 2 CPUs; Ctrl-C
    while the first seed trains: exit 130, Ray gone, those runs at their checkpoint; the same
    command finishes the grid (the interrupted runs resumed, not restarted)."""
    ray = pytest.importorskip("ray")
    runs = tmp_path / "runs"
    # 8 updates per run: long enough that Ctrl-C after the first checkpoint lands mid-run even
    # on a loaded machine (2 updates finished before the signal on a busy CI once)
    n = 8
    tiny = ["--tasks", "point-mass", "--steps", str(512 * n), "-o", "steps_per_update=512"]
    argv = ["sweep", *tiny, "-o", "checkpoint_every=1", "--methods", "ppo", "ndp",
            "--seeds", "0", "1", "--backend", "ray", "--jobs", "2",
            "--runs-dir", str(runs)]  # fmt: skip
    first = [runs / "point-mass-ppo-s0", runs / "point-mass-ndp-s0"]

    def interrupt_when_checkpointed() -> None:
        t0 = time.time()
        while time.time() - t0 < 120:
            if any((r / "checkpoint.pt").is_file() for r in first):
                os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C of the sweep
                return
            time.sleep(0.05)

    try:
        watcher = threading.Thread(target=interrupt_when_checkpointed, daemon=True)
        watcher.start()
        assert main(argv) == 130
        watcher.join()
        out = capsys.readouterr().out
        assert "on ray (a local Ray instance), 2 at once" in out and "interrupted" in out
        assert not ray.is_initialized()
        # at least the run that triggered the Ctrl-C stopped mid-budget at a checkpoint; the
        # other may have been stopped before its first one (it then restarts)
        stopped = [r for r in first if not (r / "metrics.csv").is_file() or len(_rows(r)) < n]
        resumable = [r for r in stopped if (r / "checkpoint.pt").is_file()]
        assert resumable
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert not ray.is_initialized()
        for algo in ("ppo", "ndp"):
            for seed in (0, 1):
                run = runs / f"point-mass-{algo}-s{seed}"
                assert [int(r["update"]) for r in _rows(run)] == list(range(1, n + 1))
                arm = json.loads((run / "arm.json").read_text())
                assert arm["task"] == "point-mass" and arm["seed"] == seed
        for r in stopped:
            events = [p["event"] for p in json.loads((r / "provenance.json").read_text())]
            # a run stopped at a checkpoint resumed; one stopped before it (possibly before its
            # trainer wrote anything) started afresh
            assert events[0] == "start"
            if r in resumable:
                assert events[-1] == "resume" and len(events) >= 2, events
            else:
                assert events[-1] == "start", events
        assert "4/4 finished" in out and "0 failed" in out
    finally:
        if ray.is_initialized():
            ray.shutdown()


def _start(argv: list[str], log: Path) -> subprocess.Popen:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    fh = log.open("w")
    return subprocess.Popen([sys.executable, "-m", "ndp.cli", *argv], stdout=fh,
                            stderr=subprocess.STDOUT, env=env)  # fmt: skip


# a bound, not a speed check: polled every 0.1 s; 60 s ran out once under a load of 10 on 2 cores
# (the first run took 34 s of it, the second had not checkpointed when the wait gave up)
def _wait_for(cond, proc: subprocess.Popen, log: Path, timeout: float = 180.0) -> None:
    t0 = time.time()
    while not cond():
        if proc.poll() is not None or time.time() - t0 > timeout:
            proc.kill()
            pytest.fail(f"condition not reached (rc {proc.poll()}): {log.read_text()[-2000:]}")
        time.sleep(0.1)


def test_resume_skips_finished_and_continues_interrupted_and_killed_runs(tmp_path, capsys):
    """Ctrl-C: exit 130, every run at its last checkpoint; kill -9 of the sweep and its
    trainer: the lock goes with them; each next sweep skips the finished run and continues the
    other from its checkpoint; the result has every update exactly once."""
    runs = tmp_path / "runs"
    argv = ["sweep", "--tasks", "point-mass", "--methods", "ppo", "ndp", "--seeds", "0",
            "--steps", "2600", "-o", "steps_per_update=512", "-o", "checkpoint_every=1",
            "--jobs", "1", "--vector", "sync", "--runs-dir", str(runs)]  # fmt: skip
    ppo, ndp = runs / "point-mass-ppo-s0", runs / "point-mass-ndp-s0"
    log = tmp_path / "sweep1.log"
    proc = _start(argv, log)  # jobs 1, seed-major: ppo trains first, then ndp
    _wait_for(lambda: (ndp / "checkpoint.pt").is_file(), proc, log)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130
    text = log.read_text()
    assert "interrupted" in text and "Run the same command again to continue" in text
    assert len(_rows(ppo)) == 6  # ppo (512 env steps per update): finished
    n1 = len(_rows(ndp))
    assert 1 <= n1 < 4  # ndp (520 env steps per update, 5 updates): stopped part way

    log2 = tmp_path / "sweep2.log"
    proc = _start(argv, log2)
    _wait_for(lambda: len(_rows(ndp)) > n1 and "trainer pid" in (ndp / sw.LOCK_NAME).read_text(),
              proc, log2)  # fmt: skip
    trainer = int((ndp / sw.LOCK_NAME).read_text().split("trainer pid")[-1].split()[0])
    proc.kill()  # kill -9 of the sweep, then of its trainer (they are in separate sessions)
    proc.wait()
    os.kill(trainer, signal.SIGKILL)
    for _ in range(100):
        if sw.is_busy(ndp) is None:
            break
        time.sleep(0.1)
    assert sw.is_busy(ndp) is None
    assert "skipped     point-mass ppo s0" in log2.read_text()

    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "skipped     point-mass ppo s0" in out and "done        point-mass ndp s0" in out
    assert [int(r["update"]) for r in _rows(ndp)] == [1, 2, 3, 4, 5]
    prov = json.loads((ndp / "provenance.json").read_text())
    events = [p["event"] for p in prov]
    assert events[0] == "start" and "resume" in events


def test_failed_run_is_retried_once_then_reported(tmp_path, monkeypatch, capsys):
    calls = []

    def failing(self):
        calls.append(self.name)
        return [sys.executable, "-c", "import sys; print('ndp: error: boom'); sys.exit(3)"]

    monkeypatch.setattr(sw.Job, "command", failing)
    jobs = sw.make_jobs(["point-mass"], [Arm("ppo", "ppo")], [0], 512, tmp_path)
    res = sw.run_sweep(jobs, workers=1, progress_every=60)
    assert len(calls) == 2 and not res.interrupted
    (o,) = res.failed
    assert o.attempts == 2 and o.returncode == 3 and "ndp: error: boom" in o.error
    rec = json.loads((jobs[0].run_dir / sw.FAILED_NAME).read_text())
    assert rec["attempts"] == 2 and "boom" in rec["error"]
    out = capsys.readouterr().out
    assert "retrying   point-mass ppo s0 (attempt 2/2)" in out
    assert "FAILED point-mass ppo s0 after 2 attempt(s): exit 3: ndp: error: boom" in out
    # through the command: exit 1, and the error is named
    assert main(["sweep", "--tasks", "point-mass", "--methods", "ppo", "--steps", "512",
                 "--runs-dir", str(tmp_path), "--jobs", "1"]) == 1  # fmt: skip
    assert "FAILED point-mass ppo s0" in capsys.readouterr().out


def test_a_locked_run_is_not_trained_twice(tmp_path):
    (job,) = sw.make_jobs(["point-mass"], [Arm("ppo", "ppo")], [0], 512, tmp_path)
    held = sw_runner._RunLock.take(job.run_dir)
    try:
        assert isinstance(held, sw_runner._RunLock)
        out = sw.execute(job)
        assert out.status == "busy" and "being trained by pid" in out.error
        assert sw.job_state(job) == "running"
    finally:
        held.close()
    assert sw.is_busy(job.run_dir) is None


def test_a_sweep_waits_for_a_run_another_process_trains_then_takes_it_over(
    tmp_path, monkeypatch, capsys
):
    """Two sweeps over one directory: a run held by another process is polled after this
    sweep's own runs; when that process goes away unfinished, this sweep continues it."""
    monkeypatch.setattr(sw_driver, "BUSY_POLL_S", 0.2)  # where the driver reads it
    held_job, free_job = sw.make_jobs(
        ["point-mass"], [Arm("ppo", "ppo")], [0, 1], 512, tmp_path, vector="sync"
    )
    held = sw_runner._RunLock.take(held_job.run_dir)
    assert isinstance(held, sw_runner._RunLock)
    released = threading.Timer(3.0, held.close)  # "the other sweep" dies after 3 s
    released.start()
    try:
        res = sw.run_sweep([held_job, free_job], workers=1, progress_every=1.0)
    finally:
        released.cancel()
        held.close()
    out = capsys.readouterr().out
    assert [o.status for o in res.outcomes] == ["done", "done"] and res.exit_code == 0
    assert not res.failed and not res.busy
    assert out.count("busy        point-mass ppo s0") == 1  # noted once, however often polled
    assert "waiting for it after this sweep's other runs" in out and "busy elsewhere" in out
    assert out.index("done        point-mass ppo s1") < out.index("done        point-mass ppo s0")
    assert "2/2 finished (2 trained now, 0 already finished), 0 failed" in out


def test_no_wait_busy_reports_the_run_as_busy_not_failed(tmp_path, capsys):
    (job,) = sw.make_jobs(["point-mass"], [Arm("ppo", "ppo")], [0], 512, tmp_path)
    held = sw_runner._RunLock.take(job.run_dir)
    try:
        res = sw.run_sweep([job], workers=1, wait_busy=False)
    finally:
        held.close()
    out = capsys.readouterr().out
    assert [o.status for o in res.outcomes] == ["busy"] and res.exit_code == 1
    assert res.failed == [] and len(res.busy) == 1
    assert "0 failed, 1 busy elsewhere" in out and "BUSY point-mass ppo s0" in out
    assert "FAILED" not in out and not (job.run_dir / sw.FAILED_NAME).exists()


@pytest.mark.parametrize(
    ("argv", "bad", "close"),
    [
        (["paper-fiv"], "'paper-fiv'", "paper-five"),
        (["--tasks", "pusj-v3", "--methods", "ndp"], "'pusj-v3'", "push-v3"),
        (["--tasks", "point-mass", "--methods", "ndq"], "'ndq'", "ndp"),
        (["--tasks", "point-mass", "--methods", "ndp", "-o", "n_basiss=3"], "'n-basiss'",
         "n-basis"),
        (["paper-five", "--tasks", "throw", "sokcer-v3"], "'sokcer-v3'", "soccer-v3"),
        (["ablations", "--arms", "ndp", "n66"], "'n66'", "n6"),
        (["--tasks", "point-mass", "--methods", "ppo", "-o", "lr=abc"], "--lr abc", "float"),
        (["--tasks", "point-mass", "--methods", "ppo", "-o", "seed=3"], "'seed'", "--seeds"),
        (["--tasks", "pendigits", "--methods", "il-cnn", "-o", "pendigits_path=/nope"],
         "/nope does not exist", "pendigits_path"),
        (["--tasks", "mnist", "--methods", "il-cnn"], "'mnist'", "synthetic-N"),
    ],
)  # fmt: skip
def test_bad_input_is_refused_before_anything_starts(tmp_path, capsys, argv, bad, close):
    runs = tmp_path / "runs"
    assert main(["sweep", *argv, "--runs-dir", str(runs)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ndp: error:") and bad in err and close in err, err
    assert not runs.exists()


def test_an_arm_with_an_option_the_trainer_lacks_is_refused_up_front(tmp_path, capsys):
    future = Arm("future", "ndp", ("--not-yet", "3"), "an arm ahead of the trainer",
                 requires="the not-yet option of a later change")  # fmt: skip
    with pytest.raises(sw.UnknownOptionError) as err:
        sw.check_arms([Arm("ndp", "ndp"), future], ["throw"], "study")
    msg = str(err.value)
    assert "study: arm 'future' uses --not-yet, which `ndp rl train` does not know" in msg
    assert "needs the not-yet option of a later change" in msg and "--skip-unavailable" in msg
    # the ablations study names --learn-az and --only-g, which another change adds to the trainer
    runs = tmp_path / "runs"
    has = "--learn-az" in sw.train_options() and "--only-g" in sw.train_options()
    rc = main(["sweep", "ablations", "--runs-dir", str(runs), "--dry-run", "--seeds", "0"])
    out, err_text = capsys.readouterr()
    if has:
        assert rc == 0 and "throw learn-az s0" in out and "throw only-g s0" in out
    else:
        assert rc == 2 and not runs.exists()
        assert "arm 'learn-az' uses --learn-az, which `ndp rl train` does not know" in err_text
        assert "learned-a_z option" in err_text
    assert main(["sweep", "ablations", "--runs-dir", str(runs), "--dry-run", "--seeds", "0",
                 "--skip-unavailable"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert ("arm 'learn-az' left out: --learn-az is unknown" in out) != has
    assert "throw k3 s0" in out and "--k 3" in out and "throw rbf-linear s0" in out
    # a run directory holding another arm's run refuses the sweep before it starts
    (runs / "throw-ndp-s0").mkdir(parents=True)
    (runs / "throw-ndp-s0" / "arm.json").write_text(
        json.dumps({"label": "ndp", "algo": "ppo", "args": [], "steps": 300000})
    )
    assert main(["sweep", "ablations", "--runs-dir", str(runs), "--seeds", "0",
                 "--arms", "ndp"]) == 2  # fmt: skip
    assert "holds another run (algo 'ppo' where this sweep has 'ndp')" in capsys.readouterr().err


def test_studies_are_defined_and_their_arms_accepted(capsys):
    assert set(STUDIES) == {
        "paper-five",
        "mt50",
        "ablations",
        "digits-data",
        "release-conditions",
        "release-goals-1m",
        "digits-converged",
        "ndp-head-ablation",
        "ppo-vs-sb3",
        "sb3-ndp",
        "il-robot",
        "release-explained",
        "ndp-regimes",
        "ndp-regimes-1m",
        "ndp-settings",
        "digits-head",
        "mt50-attribution",
        "sac-vs-sb3",
        "td3-vs-sb3",
        "off-policy",
        "sac-critic",
        "ndp-mechanism",
    }
    # the new studies: every arm accepted on its tasks; every condition's arms exist and run
    # the condition's method
    for name in ("release-explained", "ndp-regimes", "ndp-regimes-1m", "ndp-settings"):
        st = get_study(name)
        arms = {a.label: a for a in st.arm_specs()}
        sw.check_arms([a.arm() for a in arms.values()], list(st.task_list()), name)
        for cond in st.conditions:
            assert all(lb in arms and arms[lb].algo == m for m, lb in cond.methods), cond.name
    # ndp-mechanism: its default arms (the pca arm needs a fitted basis file) are accepted,
    # the reward arms' --reward among them
    st = get_study("ndp-mechanism")
    mech = {a.label: a for a in st.arm_specs() if a.in_default}
    sw.check_arms([a.arm() for a in mech.values()], list(st.task_list()), "ndp-mechanism")
    assert mech["ndp-sparse"].args == ("--reward", "sparse", "--no-stale-world")
    assert mech["ppo-smooth"].args == ("--reward", "smooth")  # k = 1: no stale rule to turn off
    rx = {a.label: a for a in get_study("release-explained").arm_specs()}
    assert rx["ndp-rall"].tasks == ("push-v3", "soccer-v3", "faucet-open-v3")
    assert "--execution" in rx["ndp-rall"].args and "--execution" not in rx["ppo-rall"].args
    rg = {a.label: a for a in get_study("ndp-regimes").arm_specs()}
    assert rg["ndp-k20"].args == ("--k", "20", "--minibatches", "8")
    assert [a for a in rg if a.startswith("ndp-ar1-k") and rg[a].in_default] == ["ndp-ar1-k5"]
    # the 1M chunk-size study reuses ndp-regimes' arms unchanged, on push-v3 only
    r1m = get_study("ndp-regimes-1m")
    assert r1m.steps == 1_000_000 and tuple(r1m.task_list()) == ("push-v3",)
    assert {a.label: a.args for a in r1m.arm_specs()} == {lb: rg[lb].args for lb in REGIME_1M_ARMS}
    # the benchmarks' grids, as named studies
    for name in ("ndp-head-ablation", "ppo-vs-sb3", "sb3-ndp", "il-robot", "sac-vs-sb3",
                 "td3-vs-sb3", "off-policy", "sac-critic"):  # fmt: skip
        st = get_study(name)
        sw.check_arms([a.arm() for a in st.arm_specs()], list(st.task_list()), name)
    # the off-policy table takes its on-policy arms from ndp-regimes' runs: each arm exists there
    op = {a.label: a for a in get_study("off-policy").arm_specs()}
    for cond in get_study("off-policy").conditions:
        assert all(lb in op or lb in rg for _, lb in cond.methods), cond.name
    for name in ("release-conditions", "release-goals-1m"):  # every condition's arms exist
        st = get_study(name)
        arms = {a.label: a for a in st.arm_specs()}
        sw.check_arms([a.arm() for a in arms.values()], list(st.task_list()), name)
        for cond in st.conditions:
            assert [m for m, _ in cond.methods] == ["ndp", "ppo-multi", "ppo"]
            assert all(lb in arms and arms[lb].algo == m for m, lb in cond.methods)
            assert all(lb in arms and arms[lb].algo == m for _, m, lb in cond.overrides)
        assert [c.name for c in st.conditions if c.unequal] == (
            ["release-goals", "release-goals per task"]
            if name == "release-conditions"
            else ["release-goals"]
        )
    bc = get_study("il-robot")
    labels = [a.label for a in bc.arm_specs() if a.in_default]
    assert labels == [f"{m}-n{n}" for n in (25, 100, 400) for m in ("ndp", "nn")]
    g1m = get_study("release-goals-1m")
    assert g1m.steps == 1_000_000 and g1m.task_list() == ("push-v3", "throw")
    assert dict(g1m.conditions[1].methods) == {"ndp": "ndp-fixed", "ppo-multi": "ppo-multi-fixed",
                                               "ppo": "ppo"}  # fmt: skip
    rc = get_study("release-conditions")
    arms = {a.label: a for a in rc.arm_specs()}
    assert len(arms) == 12 and rc.task_list() == ("push-v3", "soccer-v3", "faucet-open-v3")
    sw.check_arms([a.arm() for a in arms.values()], list(rc.task_list()), "release-conditions")
    for cond in rc.conditions:  # every condition names one arm per method, all in the study
        assert [m for m, _ in cond.methods] == ["ndp", "ppo-multi", "ppo"]
        assert all(lb in arms and arms[lb].algo == m for m, lb in cond.methods)
    goals = dict(next(c for c in rc.conditions if c.name == "release-goals").methods)
    assert goals == {"ndp": "ndp-v1-fixed", "ppo-multi": "ppo-multi-v1-fixed", "ppo": "ppo-v1"}
    assert [c.name for c in rc.conditions if c.unequal] == [
        "release-goals",
        "release-goals per task",
    ]
    per_task = next(c for c in rc.conditions if c.name == "release-goals per task")
    assert per_task.overrides == (("faucet-open-v3", "ppo", "ppo-v1-fixed"),)
    # at 1M the release's rule per task too: PPO random on push, fixed with the others on Throw
    r1m = get_study("release-goals-1m")
    arms_1m = {a.label: a for a in r1m.arm_specs()}
    goals_1m = next(c for c in r1m.conditions if c.name == "release-goals")
    assert dict(goals_1m.methods)["ppo"] == "ppo" and goals_1m.unequal
    assert goals_1m.overrides == (("throw", "ppo", "ppo-fixed"),)
    assert arms_1m["ppo-fixed"].tasks == ("throw",)
    assert arms_1m["ppo-fixed"].args == arms_1m["ndp-fixed"].args  # the same goal rule
    pf = get_study("paper-five")
    assert pf.task_list() == ("throw", "pick", "push-v3", "soccer-v3", "faucet-open-v3")
    keep, pending = pf.available()
    assert [a.label for a in keep][:3] == ["ndp", "ppo", "ppo-multi"]
    assert {a.label for a, _ in pending} | {a.label for a in keep} >= {"vices", "dyne"}
    assert [a.label for a in pf.arm_specs() if not a.in_default] == ["vices-pos", "vices-low-freq"]
    arms = [a.arm() for a in keep]
    sw.check_arms(arms, sw.check_tasks(pf.task_list()), "paper-five")  # every run would start
    mt = get_study("mt50")
    assert len(mt.task_list()) == 50 and [a.algo for a in mt.arm_specs()] == ["ndp", "ppo"]
    ab = {a.label: a for a in get_study("ablations").arm_specs()}
    assert {f"n{n}" for n in (2, 6, 10, 15, 20)} <= set(ab)
    assert {f"steps{s}" for s in (15, 25, 45)} <= set(ab) and "steps35" not in ab  # = ndp
    assert {f"k{k}" for k in (3, 7, 10, 15)} <= set(ab) and "k5" not in ab  # = ndp
    assert ab["learn-az"].args == ("--learn-az",) and ab["only-g"].args == ("--only-g",)
    assert ab["learn-az"].requires and ab["only-g"].requires
    assert {"vices-pos", "vices-low-freq"} <= set(ab) and "rbf-multiquadric" in ab
    opts, methods = sw.train_options(), sw.known_methods()
    ready = [
        a.arm()
        for a in ab.values()
        if all(o in opts for o in a.args if o.startswith("--")) and a.algo in methods
    ]
    sw.check_arms(ready, ["throw"], "ablations")
    dd = get_study("digits-data")
    assert dd.kind == "il" and dd.seeds == (0, 1, 2)
    assert [il_data_args(t)[1] for t in dd.task_list()] == ["pendigits", *["synthetic"] * 4]
    assert il_data_args("synthetic-300")[-2:] == ["--n-train", "300"]
    from ndp.il.train import DEFAULT_PENDIGITS

    have_pd = (DEFAULT_PENDIGITS / "pendigits-train").is_file()
    tasks = [t for t in dd.task_list() if t != "pendigits" or have_pd]
    sw.check_arms([a.arm() for a in dd.arm_specs()], tasks, "digits-data")
    assert main(["sweep", "--list"]) == 0
    assert "mt50: All 50 Meta-World tasks" in capsys.readouterr().out


def test_overrides_make_grid_axes():
    ov = sw.parse_overrides(["k=3,7", "param_noise=true", "lr=1e-3"])
    assert ov[0] == ("--k", [["--k", "3"], ["--k", "7"]])
    assert ov[1] == ("--param-noise", [["--param-noise"]])
    arms = sw.apply_overrides([Arm("ndp", "ndp"), Arm("sb3-ppo", "sb3-ppo")], ov, ["--no-norm-obs"])
    assert [a.label for a in arms] == ["ndp-k3", "ndp-k7", "sb3-ppo"]
    assert arms[0].args == ("--k", "3", "--param-noise", "--lr", "1e-3", "--no-norm-obs")
    assert arms[2].args == ()
    with pytest.raises(ValueError, match="boolean"):
        sw.parse_overrides(["param_noise=maybe"])
    opts = sw.train_options("rl")
    assert {"--n-basis", "--no-param-noise", "--steps-per-update", "--k"} <= set(opts)
    assert "--head" not in opts  # hidden: follows the method
    il = sw.train_options("il")
    assert {"--model", "--data", "--out", "--n-train", "--no-dtw"} <= set(il)


def test_run_grid_of_the_benchmarks_runs_on_the_sweep(tmp_path, monkeypatch):
    """ndp.experiments.sweep.grid.run_grid (benchmarks/ndp_ablation.py, ppo_vs_sb3.py) goes through
    the sweep: every run once, seed-major, a failure raised after the others finished."""
    from ndp.experiments.sweep.grid import run_grid

    ran = []

    def fake(self):
        ran.append(self.name)
        if self.arm.label == "bad":
            return [sys.executable, "-c", "import sys; sys.exit(1)"]
        code = "import pathlib, sys; pathlib.Path(sys.argv[1], 'done.json').write_text('{}')"
        return [sys.executable, "-c", code, str(self.run_dir)]

    monkeypatch.setattr(sw.Job, "command", fake)
    arms = [Arm("a", "ndp"), Arm("b", "ppo")]
    dirs = run_grid(["point-mass"], arms, [0, 1], 512, tmp_path, jobs=1, vector="sync")
    assert ran == ["point-mass a s0", "point-mass b s0", "point-mass a s1", "point-mass b s1"]
    assert all((d / "done.json").is_file() for d in dirs)
    with pytest.raises(RuntimeError, match="point-mass bad s0"):
        run_grid(["point-mass"], [Arm("bad", "ppo")], [0], 512, tmp_path, jobs=1)


def test_pack_and_unpack_carry_finished_runs_to_a_fresh_runs_directory(tmp_path, capsys):
    """--pack writes the finished runs without checkpoints; --unpack on a fresh machine (an
    empty runs directory) restores them, the sweep counts them finished, the report reads them;
    the archive grows across sessions and refuses members that are not run files."""
    import tarfile

    from ndp.experiments.report import report
    from ndp.experiments.sweep.archive import unpack

    runs, fresh, archive = tmp_path / "runs", tmp_path / "fresh", tmp_path / "a" / "runs.tar.gz"
    base = ["sweep", *TINY, "--methods", "ppo", "--jobs", "1", "--vector", "sync"]
    assert main([*base, "--seeds", "0", "--runs-dir", str(runs), "--pack", str(archive)]) == 0
    assert "pack: 1 finished runs of this sweep written" in capsys.readouterr().out
    with tarfile.open(archive) as tf:
        names = sorted(tf.getnames())
    assert "point-mass-ppo-s0/metrics.csv" in names and "point-mass-ppo-s0/done.json" in names
    assert not any(n.endswith("checkpoint.pt") for n in names)
    # another session, another machine: seed 1 added to the same archive
    other = tmp_path / "runs2"
    assert main([*base, "--seeds", "1", "--runs-dir", str(other), "--pack", str(archive)]) == 0
    assert "(2 runs in the archive)" in capsys.readouterr().out
    # a fresh machine: unpack, and the sweep trains nothing
    argv = [*base, "--seeds", "0", "1", "--runs-dir", str(fresh), "--unpack", str(archive)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "unpack: 2 runs restored" in out and "(0 unfinished" in out
    assert "2/2 finished (0 trained now, 2 already finished)" in out
    assert _rows(fresh / "point-mass-ppo-s0") == _rows(runs / "point-mass-ppo-s0")
    res = report([fresh], tmp_path / "rep", "ndp report fresh")
    assert [r["n_seeds"] for r in res["rows"]] == [2]
    # unpacking again leaves the existing directories alone
    assert unpack(archive, fresh) == ([], ["point-mass-ppo-s0", "point-mass-ppo-s1"])
    bad = tmp_path / "bad.tar.gz"
    with tarfile.open(bad, "w:gz") as tf:
        tf.add(archive, arcname="../escape/metrics.csv")
    with pytest.raises(ValueError, match="not a run file"):
        unpack(bad, tmp_path / "x")
    assert not (tmp_path / "escape").exists() and not (tmp_path / "x").exists()
    # --pack onto a file that is not a run archive, or a folder: refused, the file untouched
    from ndp.experiments.sweep.archive import pack

    notes = tmp_path / "notes.tar.gz"
    notes.write_text("my notes\n")
    with pytest.raises(ValueError, match=r"^pack: .*notes.tar.gz exists and is not a readable"):
        pack([runs / "point-mass-ppo-s0"], notes)
    assert notes.read_text() == "my notes\n"
    with pytest.raises(ValueError, match=r"holds '\.\./escape/metrics\.csv', not a run file"):
        pack([runs / "point-mass-ppo-s0"], bad)  # a tar of other files is not merged into
    with pytest.raises(ValueError, match="is a folder, not an archive file"):
        pack([runs / "point-mass-ppo-s0"], tmp_path / "a")


def test_a_failed_run_shows_the_trainers_reason_not_the_parser_box(tmp_path):
    """tyro draws a box around an option error; the sweep's failure line carries its text."""
    log = tmp_path / "train.log"
    log.write_text(
        "╭─ Value error ──────────────────╮\n"
        "│ Error parsing --lr: could not convert string to float: 'abc' │\n"
        "│ ────────────────────────────── │\n"
        "│ For full helptext, see ndp rl train --help │\n"
        "╰────────────────────────────────╯\n"
    )
    tail = sw_runner._log_tail(log, 0)
    assert "Error parsing --lr: could not convert string to float: 'abc'" in tail
    assert "╭" not in tail and "│" not in tail


def test_a_sweep_that_fails_to_start_leaves_no_empty_runs_directory(tmp_path, monkeypatch, capsys):
    """A backend that cannot start (a Ray cluster out of reach) must not leave the runs folder
    it just made behind, empty; a folder that existed before is kept."""

    def unreachable(*args, **kwargs):
        raise ConnectionError("Failed to connect to Ray cluster at 10.0.0.1:6379")

    monkeypatch.setattr(sw, "run_sweep", unreachable)
    new = tmp_path / "new"
    assert main(["sweep", *TINY, "--methods", "ppo", "--runs-dir", str(new)]) != 0
    assert not new.exists()
    old = tmp_path / "old"
    old.mkdir()
    assert main(["sweep", *TINY, "--methods", "ppo", "--runs-dir", str(old)]) != 0
    assert old.is_dir()
    capsys.readouterr()


def test_a_failed_unpack_leaves_no_folder_it_made(tmp_path, monkeypatch):
    """A full disk while restoring the first run: the runs directory (and the parents) that
    unpack made are removed again, not left empty; the error is one line naming the run."""
    import errno
    import tarfile

    from ndp.experiments.sweep.archive import unpack

    src = tmp_path / "src" / "point-mass-ppo-s0"
    src.mkdir(parents=True)
    (src / "metrics.csv").write_text("update,global_step\n1,64\n")
    archive = tmp_path / "a.tar.gz"
    with tarfile.open(archive, "w:gz") as tf:
        tf.add(src / "metrics.csv", arcname="point-mass-ppo-s0/metrics.csv")

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", full)
    target = tmp_path / "new" / "runs"
    with pytest.raises(ValueError, match=r"^unpack: cannot restore point-mass-ppo-s0 from "):
        unpack(archive, target)
    assert not (tmp_path / "new").exists()
    existing = tmp_path / "mine"
    existing.mkdir()
    with pytest.raises(ValueError):
        unpack(archive, existing)
    assert existing.is_dir() and not list(existing.iterdir())  # the user's folder stays
