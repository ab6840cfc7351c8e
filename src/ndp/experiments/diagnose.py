"""``python -m ndp.experiments.diagnose``: the NDP head's diagnostics under their earlier name.

They live in :mod:`ndp.rl.diagnose` (``ndp rl diagnose``, the same options: the handicaps of a
rollout, or ``--jacobian`` the conditioning of the head's map), so that the ``ndp rl`` command,
a layer below the experiments, runs them too.
"""

from __future__ import annotations

import sys

from ndp.rl.cli import diagnose_main as main
from ndp.rl.diagnose import diagnose, jacobian_diagnostic

__all__ = ["diagnose", "jacobian_diagnostic", "main"]

if __name__ == "__main__":
    sys.exit(main())
