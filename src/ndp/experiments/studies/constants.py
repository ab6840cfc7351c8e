"""Names for parts of the study files that code and tests read (re-exported by
:mod:`ndp.experiments.studies`).

Two kinds, by where the value lives:

- read from the data (a study's tasks, its conditions, its arm labels): the file is the one
  source, these names only read it when the package is imported;
- named here (an option bundle written into several arms, a grid axis, a reference setting):
  the files spell the values out, and ``tests/experiments/studies/test_data.py`` checks that
  they agree with these (a value changed on one side only fails there).
"""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Condition
from ndp.experiments.studies.registry import get_study


def _tasks(study: str) -> tuple[str, ...]:
    return get_study(study).task_list()


def _conditions(study: str) -> tuple[Condition, ...]:
    return get_study(study).conditions


def _arm(study: str, label: str) -> ArmSpec:
    return next(a for a in get_study(study).arm_specs() if a.label == label)


# --- read from the data -------------------------------------------------------------------

PAPER_FIVE_TASKS = _tasks("paper-five")
"""Throw, Pick (Jaco), Push, Soccer, Faucet-open (Meta-World v3): the paper's five tasks."""

MT50_ATTRIBUTION_TASKS = _tasks("mt50-attribution")
"""The Meta-World tasks where NDP's and PPO's final success differed by more than 0.1 at seed 0
in docs/results/mt50_100k/mt50_100k.csv (100k env steps), fixed before any run of
mt50-attribution."""

RELEASE_TASKS = _tasks("release-conditions")
"""Meta-World tasks of the release-conditions study (the paper's three Meta-World tasks)."""

RELEASE_1M_TASKS = _tasks("release-goals-1m")
"""The 1M-step stage of the release-conditions study: a Meta-World task and a Jaco task."""

EXPLAINED_TASKS = _tasks("release-explained")
"""Tasks of release-explained: the paper's three Meta-World tasks and Throw."""

RELEASE_CONDITIONS = _conditions("release-conditions")
"""The conditions of the release-conditions study, each a method -> arm map over shared runs."""

RELEASE_1M_CONDITIONS = _conditions("release-goals-1m")
"""The conditions of release-goals-1m (release-goals is UNEQUAL on purpose, and labelled so)."""

EXPLAINED_CONDITIONS = _conditions("release-explained")
"""The conditions of release-explained (release-all is UNEQUAL on push and soccer: PPO draws
random goals there, as in the release)."""

RELEASE_METHODS = tuple(method for method, _ in RELEASE_CONDITIONS[0].methods)
"""The methods of the release studies, in table order (those of release-conditions' fair
condition)."""

REGIME_TASKS = _tasks("ndp-regimes")
"""Tasks of ndp-regimes (a Meta-World task and a Jaco task; never used to tune NDP)."""

REGIME_1M_ARMS = tuple(a.label for a in get_study("ndp-regimes-1m").arm_specs())
"""The arms of ndp-regimes-1m, in priority order: the chunk-size arms (white noise) and PPO."""

MECHANISM_TASKS = _tasks("ndp-mechanism")
"""Tasks of ndp-mechanism: the conditioning set on push-v3 and Throw, the basis set on push-v3,
the rewards pilot on reach-v3 and push-v3 (each arm on its tasks)."""

OFF_POLICY_TASKS = _tasks("off-policy")
"""Tasks of the off-policy study (those of ndp-regimes, whose fair on-policy arms it is read
beside)."""

OFF_POLICY_CONDITIONS = _conditions("off-policy")
"""The off-policy study's table: its SAC arms beside ndp-regimes' fair on-policy arms."""

PPO_VS_SB3_TASKS = _tasks("ppo-vs-sb3")
"""The five Meta-World tasks of ppo-vs-sb3."""

BC_TASKS = _tasks("il-robot")
"""Tasks of the behaviour-cloning study (the paper's five robot tasks, each with a scripted
expert: ndp.bc.experts)."""

DIGITS_TASKS = _tasks("digits-data")
"""The data sets of digits-data: Pendigits and the synthetic set at four sizes."""


# --- named here, checked against the data ---------------------------------------------------

THROW_DEFAULTS = {"n_basis": 5, "k": 5, "dmp_steps": 35}
"""Throw's reference NDP (its preset: N 5, a_z 5; k 5, 35 integration steps per decision): the
``ndp`` arm of ablations; an ablation value equal to it is that arm, not a second run."""

HEAD_ABLATION_COMMANDED = ("--dmp-state", "commanded", "--dmp-velocity", "zero")
"""The frame the NDP head's handicap fixes were measured from (the default before the
per-task frame): the ndp-commanded arm of ndp-head-ablation, and the start of its one-fix arms."""

RELEASE_V1 = ("--reward-version", "v1")
"""The release's v1 shaped rewards."""

RELEASE_FIXED = ("--goals", "fixed")
"""One fixed goal per run."""

RELEASE_OPTIMISER = ("--ent-coef", "0.01", "--clip-value-loss")
"""The release's PPO settings that differ from ours: entropy 0.01, the clipped value loss."""

RELEASE_ALL_MW = (
    *RELEASE_V1,
    "--goals", "as-release",
    "--observation", "release9",
    *RELEASE_OPTIMISER,
    "--steps-per-update", "500",
)  # fmt: skip
"""Every release condition our code has, for one method on a Meta-World task: v1 rewards, the
release's goals for this method on this task (ndp.envs.release.release_goals), the 9-D
observation, entropy 0.01 and the clipped value loss, 500 env steps per update. Chunked methods
add the first-held execution and keep the stale-world reward: the release built NDP and
PPO-multi alike with ``reward_delay=T`` (its main_rl.py). The first release-all arm of PPO-multi
(``ppo-multi-rall``) took the live reward instead, on the mistaken reading that the stale rule
was NDP's only: it is kept, labelled as that deviation. Not reproducible here: the linear lr
decay over 25,000 updates (at 300k env steps it would have lowered the lr by 2.4%), the vendored
pre-v1 Meta-World and push's 4x timestep."""

FIRST_HELD = ("--execution", "first-held")
"""Only a decision's first sub-action executed, held k env steps (the release's execution)."""

RELEASE_RATIO = ("--first-held-ratio", "release")
"""The release's PPO ratio under first-held execution, pi_j,new(a_0) / pi_0,old(a_0)."""

REGIME_KS = (5, 10, 20)
"""Decision lengths of the chunk-size arms (NDP's basis count stays at the task's preset, so a
larger k compresses more env steps into the same parameters)."""

PARAM_NOISE_LOG_STD = "0.0"
"""init_log_std of the calibrated parameter-noise arms: the value at which the executed
(clipped) sub-actions of a fresh NDP policy vary as much as under the white arm's std 1
(benchmarks/param_noise_calibration.py,
docs/results/param_noise_calibration/param_noise_calibration.json: 0.01 to 0.05 on push-v3,
-0.12 to -0.09 on Throw, for k = 5, 10, 20)."""

PARAM_NOISE_DISPLACEMENT = {5: "-1.5", 10: "-2.0", 20: "-2.3"}
"""init_log_std at which parameter noise moves a decision's summed displacement as much as the
white arm (the same benchmark: push-v3 -1.57 / -1.98 / -2.35, Throw -1.46 / -1.84 / -2.19):
the smaller calibration, by the other reading of "as much noise"."""

AR1_CORR = "0.8"
"""Correlation of consecutive env steps' AR(1) noise in the correlated-noise arms."""


def k_args(k: int) -> tuple[str, ...]:
    """Options of a k-step arm of ndp-regimes and ndp-mechanism: k, and the mini-batch count
    that keeps about 13 decisions per mini-batch at 2,048 env steps per update (32 at k = 5,
    the default: no options; 16 at k = 10, 8 at k = 20)."""
    if k == 5:
        return ()
    return ("--k", str(k), "--minibatches", str(32 * 5 // k))


NDP_SETTINGS_AXES = (
    ("lr", ("1e-4", "1e-3")),
    ("n-basis", ("3", "10")),
    ("a-z", ("5", "25")),
    ("init-log-std", ("-1.0", "-0.5")),
)
"""NDP's own settings, one axis at a time from the defaults (lr 3e-4, reach-v3's preset N 6 and
a_z 15, init_log_std 0): the pre-registered sweep of ndp-settings (docs/rl-regimes.md)."""

MECHANISM_BASES = ("dmp", "dct", "bspline")
"""The fixed chunk bases of the basis set run by default ('pca' needs a file fitted on the free
PPO-multi arm's runs first: its arm runs only when named, with ``--chunk-basis-file``)."""

LIVE = ("--no-stale-world",)
"""The env's own reward at every sub-step (docs/rl-release.md part 3: the fair-live rule)."""

OFF_POLICY_UTD1 = ("--sac-updates-per-step", "0.2")
"""One gradient step per stored decision at k = 5 (0.2 per env step; the default is k)."""

BC_DEMOS = (25, 100, 400)
"""Demonstration counts of the behaviour-cloning study (the first n of one recording per task)."""

CONVERGED_LRS = ("3e-4", "1e-3", "3e-3")
"""The learning-rate grid of the converged digit study (the same for every model)."""

CONVERGED_ARGS = ("--val-fraction", "0.1", "--patience", "20", "--eval-every", "0")
"""Every converged run: 10% of the training split for validation, stop after 20 epochs without
a lower validation MSE, the test split scored once at the end (on the best weights)."""

CONVERGED_MODELS = (("ndp", "il-ndp"), ("cnn", "il-cnn"), ("cnn-dmp", "il-cnn-dmp"))
"""(label, method) of the digit models of digits-converged and digits-head."""

HEAD_LRS = ("1e-3", "3e-3", "1e-2")
"""The learning-rate grid of digits-head (NDP's best converged lr sat at the top of the old
grid, 3e-3, on several sizes)."""

HEADS = (("lin", ()), ("paper", ("--network", "paper")))
"""digits-head's head axis: the linear head and the release's 100-200-128-64 MLP."""
