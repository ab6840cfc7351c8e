"""The decision replay buffer of the SAC family: :class:`ndp.rl.offpolicy.replay.DecisionReplay`
(the off-policy learners' shared one), re-exported here."""

from __future__ import annotations

from ndp.rl.offpolicy.replay import FIELDS as FIELDS
from ndp.rl.offpolicy.replay import DecisionReplay as DecisionReplay
