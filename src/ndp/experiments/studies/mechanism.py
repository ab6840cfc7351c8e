"""Why NDP loses: the action map's conditioning, the chunk basis, and rewards that favour
trajectories (docs/rl-mechanism.md)."""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Condition, Study
from ndp.experiments.studies.regimes import _k_args

MECHANISM_TASKS = ("push-v3", "throw", "reach-v3")
"""Tasks of ndp-mechanism: the conditioning set on push-v3 and Throw, the basis set on push-v3,
the rewards pilot on reach-v3 and push-v3 (each arm on its tasks)."""


MECHANISM_BASES = ("dmp", "dct", "bspline")
"""The fixed chunk bases of the basis set run by default ('pca' needs a file fitted on the free
PPO-multi arm's runs first: its arm runs only when named, with ``--chunk-basis-file``)."""


LIVE = ("--no-stale-world",)
"""The env's own reward at every sub-step (docs/rl-release.md part 3: the fair-live rule)."""


def _mechanism_arms() -> tuple[ArmSpec, ...]:
    """The arms of ndp-mechanism (docs/rl-mechanism.md, readings committed before the runs)."""
    both, push = ("push-v3", "throw"), ("push-v3",)
    arms = [
        ArmSpec("ndp-linear", "ndp", ("--param-map", "linear", *LIVE),
                "NDP, k = 5, live reward, goal and weights linear in the outputs (no tanh)",
                tasks=both),
        ArmSpec("ndp-whitened", "ndp", ("--param-map", "whitened", *LIVE),
                "NDP, k = 5, live reward, outputs whitened through the action map at rest",
                tasks=both),
    ]  # fmt: skip
    for k in (10, 20):
        ka = (*_k_args(k), *LIVE)
        arms += [
            ArmSpec(f"ppo-multi-live-k{k}", "ppo-multi", ka, f"PPO-multi, k = {k}, live reward",
                    tasks=push),
            ArmSpec(f"ndp-live-k{k}", "ndp", ka, f"NDP, k = {k}, live reward", tasks=push),
            *[ArmSpec(f"ppo-multi-{b}-k{k}", "ppo-multi", (*ka, "--chunk-basis", b),
                      f"PPO-multi, k = {k}, live reward, chunk in the {b} basis (1 + N per DoF)",
                      tasks=push) for b in MECHANISM_BASES],
            ArmSpec(f"ppo-multi-pca-k{k}", "ppo-multi", (*ka, "--chunk-basis", "pca"),
                    f"PPO-multi, k = {k}, live reward, chunk in a PCA basis of the free arm's "
                    "chunks (give --chunk-basis-file)", in_default=False, tasks=push),
        ]  # fmt: skip
    rewards = ("reach-v3", "push-v3")
    for variant in ("sparse", "smooth"):
        rv = ("--reward", variant)
        arms += [
            ArmSpec(f"ndp-{variant}", "ndp", (*rv, *LIVE), f"NDP, k = 5, {variant} reward",
                    requires="--reward", tasks=rewards),
            ArmSpec(f"ppo-multi-{variant}", "ppo-multi", (*rv, *LIVE),
                    f"PPO-multi, k = 5, {variant} reward", requires="--reward", tasks=rewards),
            ArmSpec(f"ppo-{variant}", "ppo", rv, f"PPO, {variant} reward", requires="--reward",
                    tasks=rewards),
        ]  # fmt: skip
    return tuple(arms)


def _mechanism_conditions() -> tuple[Condition, ...]:
    """ndp-mechanism's tables; the fair-live arms (ndp-nostale, ppo-multi-nostale, ppo) are
    ndp-regimes' runs (read with both run directories)."""
    conds = [
        Condition("conditioning, k = 5", "NDP's head with tanh (default), linear and whitened "
                  "maps beside PPO-multi and PPO, every method on the live reward",
                  (("ndp", "ndp-nostale"), ("ndp (linear)", "ndp-linear"),
                   ("ndp (whitened)", "ndp-whitened"), ("ppo-multi", "ppo-multi-nostale"),
                   ("ppo", "ppo"))),
    ]  # fmt: skip
    for k in (10, 20):
        conds.append(
            Condition(f"basis, k = {k}", f"PPO-multi free and restricted to a fixed basis of "
                      f"1 + N functions per DoF, and NDP, at k = {k}, live reward (push-v3)",
                      (("ppo-multi", f"ppo-multi-live-k{k}"),
                       *[(f"ppo-multi ({b})", f"ppo-multi-{b}-k{k}")
                         for b in (*MECHANISM_BASES, "pca")],
                       ("ndp", f"ndp-live-k{k}")))
        )  # fmt: skip
    for variant in ("sparse", "smooth"):
        conds.append(
            Condition(f"{variant} reward", f"every method on the {variant} reward variant "
                      "(--reward), k = 5 for the chunked methods, live world",
                      (("ndp", f"ndp-{variant}"), ("ppo-multi", f"ppo-multi-{variant}"),
                       ("ppo", f"ppo-{variant}")))
        )  # fmt: skip
    return tuple(conds)


STUDIES: tuple[Study, ...] = (
    Study(
        name="ndp-mechanism",
        title="Why NDP loses: the action map's conditioning, the chunk basis, and rewards "
        "that favour trajectories",
        doc=(
            "docs/rl-mechanism.md (readings committed before the runs). Conditioning: NDP "
            "with --param-map linear / whitened on push-v3 and Throw (k = 5, live reward), "
            "read beside ndp-regimes' ndp-nostale, ppo-multi-nostale and ppo (ndp report "
            "RUNS/ndp_mechanism RUNS/fair10). Basis: PPO-multi free and restricted to the "
            "dmp / dct / bspline (/ pca) chunk basis, and NDP, at k = 10 and 20 on push-v3. "
            "Rewards pilot: NDP, PPO-multi, PPO under --reward sparse / smooth on reach-v3 "
            "and push-v3. 300k env steps, seeds 0-2 (the conditioning arms 0-9)."
        ),
        tasks=lambda: MECHANISM_TASKS,
        arms=_mechanism_arms,
        steps=300_000,
        conditions=_mechanism_conditions(),
        readings="ndp.experiments.report.mechanism:mechanism_readings",
    ),
)
"""This module's studies, in ``ndp sweep --list`` order."""
