"""Imitation: behaviour cloning on the robot tasks and digit writing (docs/experiments.md)."""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Study

BC_TASKS = ("throw", "pick", "push-v3", "soccer-v3", "faucet-open-v3")
"""Tasks of the behaviour-cloning study (the paper's five robot tasks, each with a scripted
expert: ndp.bc.experts)."""


BC_DEMOS = (25, 100, 400)
"""Demonstration counts of the behaviour-cloning study (the first n of one recording per task)."""


def _bc_arms() -> tuple[ArmSpec, ...]:
    """NDP and the plain network (the PPO-multi actor) at each demonstration count; the PPO
    actor (one action per step) and NDP starting from the commanded velocity only by name."""
    models = (
        ("ndp", "bc-ndp", (), "NDP: (g, w) -> DMP -> inverse controller -> k actions", True),
        ("nn", "bc-nn", (), "NN: k raw actions per decision (the PPO-multi actor)", True),
        ("nn-step", "bc-nn-step", (), "NN: one action per env step (the PPO actor)", False),
        ("ndp-vstate", "bc-ndp", ("--dmp-velocity", "state"),
         "NDP whose DMP starts from the commanded velocity", False),
    )  # fmt: skip
    return tuple(
        ArmSpec(
            f"{label}-n{n}",
            algo,
            (*args, "--episodes", str(n)),
            f"{note}; {n} demos",
            in_default=default,
        )
        for n in BC_DEMOS
        for label, algo, args, note, default in models
    )


DIGITS_TASKS = ("pendigits", "synthetic-300", "synthetic-1000", "synthetic-3000", "synthetic")


def _digits_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("ndp", "il-ndp", (), "NDP: CNN -> (g, w) -> DMP layer"),
        ArmSpec("cnn", "il-cnn", (), "CNN: 301 x 2 points directly"),
        ArmSpec("cnn-dmp", "il-cnn-dmp", (), "CNN-DMP: regress fitted DMP parameters"),
    )


CONVERGED_LRS = ("3e-4", "1e-3", "3e-3")
"""The learning-rate grid of the converged digit study (the same for every model)."""


CONVERGED_ARGS = ("--val-fraction", "0.1", "--patience", "20", "--eval-every", "0")
"""Every converged run: 10% of the training split for validation, stop after 20 epochs without
a lower validation MSE, the test split scored once at the end (on the best weights)."""


CONVERGED_MODELS = (("ndp", "il-ndp"), ("cnn", "il-cnn"), ("cnn-dmp", "il-cnn-dmp"))


def _converged_arms() -> tuple[ArmSpec, ...]:
    return tuple(
        ArmSpec(
            f"{m}-lr{lr}",
            algo,
            ("--lr", lr, *CONVERGED_ARGS),
            f"{m}, Adam lr {lr}, early stopping on validation",
        )
        for m, algo in CONVERGED_MODELS
        for lr in CONVERGED_LRS
    )


HEAD_LRS = ("1e-3", "3e-3", "1e-2")
"""The learning-rate grid of digits-head (NDP's best converged lr sat at the top of the old
grid, 3e-3, on several sizes)."""


HEADS = (("lin", ()), ("paper", ("--network", "paper")))
"""digits-head's head axis: the linear head and the release's 100-200-128-64 MLP."""


def _head_arms() -> tuple[ArmSpec, ...]:
    return tuple(
        ArmSpec(
            f"{m}-{h}-lr{lr}",
            algo,
            ("--lr", lr, *args, *CONVERGED_ARGS),
            f"{m}, {'the release head 100-200-128-64' if args else 'linear head'}, Adam lr {lr}",
        )
        for m, algo in CONVERGED_MODELS
        for h, args in HEADS
        for lr in HEAD_LRS
    )


def _head_selection() -> tuple[tuple[str, tuple[str, ...]], ...]:
    """Per model: the best of both heads and every lr; and each head alone (equal capacity)."""
    out = []
    for m, _ in CONVERGED_MODELS:
        out.append((m, tuple(f"{m}-{h}-lr{lr}" for h, _ in HEADS for lr in HEAD_LRS)))
    for h, _ in HEADS:
        for m, _ in CONVERGED_MODELS:
            out.append((f"{m} ({h} head)", tuple(f"{m}-{h}-lr{lr}" for lr in HEAD_LRS)))
    return tuple(out)


STUDIES: tuple[Study, ...] = (
    Study(
        name="il-robot",
        title="Behaviour cloning on the robot tasks: NDP vs NN",
        doc=(
            "The five robot tasks x NDP and the plain network (the PPO-multi actor) cloned "
            "from the first 25 / 100 / 400 successful episodes of one scripted-expert "
            "recording per task (reset seeds from 0), 100 epochs, 3 seeds; each cloned "
            "policy evaluated closed loop over 50 episodes with seeds disjoint from the "
            "demonstrations'. The report gives success, the cloning's validation loss and "
            "the smoothness (jerk, SPARC) of the executed arm path. nn-step-nN (the PPO "
            "actor) and ndp-vstate-nN (NDP starting from the commanded velocity) run only "
            "when named with --arms."
        ),
        tasks=lambda: BC_TASKS,
        arms=_bc_arms,
        steps=100,
        kind="bc",
    ),
    Study(
        name="digits-data",
        title="Digit writing: NDP vs CNN vs CNN-DMP, by training-set size",
        doc=(
            "ndp il train runs (budget in epochs, the paper's 71): Pendigits with the "
            "writer-disjoint split, and the synthetic set (paper split) at 300, 1000, 3000 "
            "and all (10,000) training digits; 3 seeds. The synthetic test set is 2,000 "
            "digits drawn with the training digits from the first n_train + 2,000 samples "
            "(the paper split), so it differs between sizes (same distribution). The "
            "report gives the test MSE (px^2) per data set and model."
        ),
        tasks=lambda: DIGITS_TASKS,
        arms=_digits_arms,
        steps=71,
        kind="il",
    ),
    Study(
        name="digits-head",
        title="Digit writing: the head as an axis every model shares (linear vs the "
        "release's 100-200-128-64 MLP)",
        doc=(
            "synthetic-300, synthetic-1000 and Pendigits' writers x NDP, CNN, CNN-DMP x "
            "{linear head, the 2021 release's head (--network paper)} x Adam lr 1e-3 / "
            "3e-3 / 1e-2, the converged protocol of digits-converged (validation split, "
            "patience 20, at most 500 epochs, best-validation weights, test scored once); "
            "3 seeds. The report selects per data set each model's head and lr on "
            "validation alone (rows 'ndp', 'cnn', 'cnn-dmp'), and each model's lr within "
            "one head (rows 'ndp (lin head)', ... 'cnn-dmp (paper head)'): the comparison "
            "at equal capacity."
        ),
        tasks=lambda: ("synthetic-300", "synthetic-1000", "pendigits"),
        arms=_head_arms,
        steps=500,
        kind="il",
        selection=_head_selection(),
    ),
    Study(
        name="digits-converged",
        title="Digit writing at convergence: NDP vs CNN vs CNN-DMP, selected on validation",
        doc=(
            "The digits-data sets (300 / 1,000 / 3,000 / 10,000 synthetic training digits "
            "and Pendigits' writers) x NDP, CNN, CNN-DMP x Adam lr 3e-4 / 1e-3 / 3e-3, each "
            "run stopped on a validation split (10% of its training split, the same for "
            "every model; patience 20 epochs, at most 500) and its best-validation weights "
            "kept; 3 seeds. The report picks each model's learning rate per data set on the "
            "validation MSE alone and gives that arm's test MSE (scored once, at the end) "
            "with its 95% bootstrap interval, epochs to best and wall time, and the DMP's "
            "floor (least-squares DMP fits to every test trajectory, N 10 / 20 / 30)."
        ),
        tasks=lambda: (
            "synthetic-300",
            "synthetic-1000",
            "synthetic-3000",
            "synthetic",
            "pendigits",
        ),
        arms=_converged_arms,
        steps=500,
        kind="il",
        selection=tuple(
            (m, tuple(f"{m}-lr{lr}" for lr in CONVERGED_LRS)) for m, _ in CONVERGED_MODELS
        ),
    ),
)
"""This module's studies, in ``ndp sweep --list`` order."""
