"""The report's own deterministic evaluation of each finished RL run's final policy
(``ndp report --eval-episodes N --eval-seed S``): how many episodes, from which reset seed, the
file in the run that holds it, and whether its seeds overlap the periodic evaluation's."""

from __future__ import annotations

from dataclasses import dataclass

from ndp.checks import check_int
from ndp.experiments.rows import det_eval_name
from ndp.rl.config import EVAL_SEED, TrainConfig

PERIODIC_EVAL_EPISODES: int = TrainConfig.eval_episodes
"""Episodes of the periodic deterministic evaluation by default (``TrainConfig.eval_episodes``):
its fixed seeds are ``EVAL_SEED .. EVAL_SEED + PERIODIC_EVAL_EPISODES - 1``."""


@dataclass(frozen=True)
class FreshEval:
    """The report's own deterministic evaluation of each finished RL run's final policy:
    ``episodes`` episodes (0: none) from reset seed ``seed`` (seeds ``seed .. seed + episodes -
    1``). With ``seed`` :data:`ndp.rl.config.EVAL_SEED` it is cached in the run as
    ``eval-det-e<episodes>.json``; with another seed it is the file ``ndp rl eval --episodes N
    --seed S --mode deterministic --save`` writes, ``eval-det-e<N>-s<S>.json``.

    Raises:
        ValueError: a negative count or seed, or a seed other than the default without episodes
            (each naming ``eval_episodes`` / ``eval_seed``).
    """

    episodes: int = 0
    seed: int = EVAL_SEED

    def __post_init__(self) -> None:
        check_int("eval_episodes", self.episodes, 0)
        check_int("eval_seed", self.seed, 0, note="(the first episode seed)")
        if self.seed != EVAL_SEED and not self.episodes:
            raise ValueError(
                f"eval_seed: needs eval_episodes > 0 (the seeds of the report's own evaluation), "
                f"got eval_seed={self.seed} and no episodes"
            )

    @property
    def cache_name(self) -> str:
        """The file in the run that holds this evaluation
        (:func:`ndp.experiments.rows.det_eval_name`)."""
        return det_eval_name(self.episodes, self.seed)

    @property
    def last_seed(self) -> int:
        """The last episode's reset seed."""
        return self.seed + self.episodes - 1

    def overlaps_periodic(self, periodic: int = PERIODIC_EVAL_EPISODES) -> bool:
        """Whether its seeds share any with the periodic evaluation's ``periodic`` fixed ones."""
        return self.seed < EVAL_SEED + periodic and EVAL_SEED < self.seed + self.episodes


NO_FRESH_EVAL = FreshEval()
"""No deterministic evaluation of the report's own (the default)."""


def fresh_eval(episodes: int = 0, seed: int | None = None) -> FreshEval:
    """The :class:`FreshEval` of the report's ``eval_episodes`` and ``eval_seed`` arguments
    (None: :data:`ndp.rl.config.EVAL_SEED`); a seed given without episodes is refused, the
    default one included (ValueError naming ``eval_seed``)."""
    if seed is not None and not (isinstance(episodes, int) and episodes > 0):
        check_int("eval_episodes", episodes, 0)
        raise ValueError(
            f"eval_seed: needs eval_episodes > 0 (the seeds of the report's own evaluation), "
            f"got eval_seed={seed} and eval_episodes={episodes}"
        )
    return FreshEval(episodes, EVAL_SEED if seed is None else seed)
