"""The study registry: one study per data file, the --list order kept, and readings as entry
points resolved when called."""

from __future__ import annotations

import pytest

from ndp.experiments import studies
from ndp.experiments.studies import LIST_ORDER, STUDIES, get_study, resolve
from ndp.experiments.studies.loader import load_study, study_files


def test_every_file_is_registered_once_in_list_order():
    names = [load_study(f).name for f in study_files()]
    assert sorted(names) == sorted(STUDIES)
    assert list(STUDIES) == [n for n in LIST_ORDER if n in STUDIES]


def test_get_study_names_the_close_studies():
    with pytest.raises(ValueError, match="unknown study 'ndp-regime'; close names: ndp-regimes"):
        get_study("ndp-regime")


def test_readings_entry_points_resolve_to_the_report_functions():
    from ndp.experiments.report import offpolicy, regimes

    assert get_study("ndp-regimes").readings_fn() is regimes.regimes_readings
    assert get_study("sac-critic").readings_fn() is offpolicy.critic_study_readings
    assert get_study("paper-five").readings_fn() is None
    for s in STUDIES.values():
        if s.readings is not None:
            assert callable(s.readings_fn())


def test_resolve_refuses_a_bad_entry_naming_it():
    with pytest.raises(ValueError, match="entry: 'nope' is not"):
        resolve("nope")
    with pytest.raises(ValueError, match="does not name a function"):
        resolve("ndp.experiments.report.regimes:no_such_function")
    assert resolve(len) is len


def test_importing_the_studies_imports_neither_the_report_nor_the_sweep():
    import subprocess
    import sys

    code = (
        "import sys, ndp.experiments.studies as s; s.get_study('ndp-regimes').arm_specs(); "
        "print(any(m.startswith(('ndp.experiments.report', 'ndp.experiments.sweep', 'torch')) "
        "for m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert studies.Study is studies.base.Study
