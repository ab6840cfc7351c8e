"""A report's output paths: the stem (``--out`` without ``.md`` / ``.csv``), the files beside
it, and the guard that a report replaces only an earlier generated report."""

from __future__ import annotations

from pathlib import Path


def report_stem(out: str | Path) -> Path:
    """The report's stem: ``--out`` as given, without a trailing ``.md`` / ``.csv`` (so
    ``--out r.md`` writes ``r.md``, as before); a dot inside a name is kept (``--out v1.2``
    writes ``v1.2.md`` and ``v1.2-<task>.png``, not ``v1.md`` beside ``v1.2-*.png``)."""
    out = Path(out)
    return out.with_suffix("") if out.suffix in (".md", ".csv") else out


def with_ext(stem: Path, ext: str) -> Path:
    """``<stem><ext>``: the extension appended to the stem's name, never replacing a part of
    it."""
    return stem.with_name(stem.name + ext)


def _is_generated_md(head: str) -> bool:
    """The package's generated markdown: a ``Command: `...``` line, then ``Commit: ...``, in
    its first 10 lines (``ndp report``, ``ndp sweep --report``, the benchmarks' tables)."""
    from itertools import pairwise

    return any(
        a.startswith("Command: `") and b.startswith("Commit: ")
        for a, b in pairwise(head.splitlines()[:10])
    )


def _is_generated_csv(head: str) -> bool:
    """The package's generated CSV: a ``command`` column in its header."""
    return bool(head) and "command" in head.splitlines()[0].split(",")


def check_report_stem(out: Path) -> None:
    """A report replaces an earlier generated table of the same stem (the regeneration every
    committed table relies on) and nothing else: an existing ``<out>.md`` without the
    ``Command:`` / ``Commit:`` lines, or ``<out>.csv`` without a ``command`` column, is
    refused (FileExistsError naming ``out``) before any run is read."""
    checks = ((with_ext(out, ".md"), _is_generated_md),
              (with_ext(out, ".csv"), _is_generated_csv))  # fmt: skip
    for path, is_report in checks:
        if not path.is_file():
            continue
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                head = f.read(4096)
        except OSError:
            head = ""
        if not is_report(head):
            raise FileExistsError(
                f"out: {path} exists and is not an ndp report; choose another --out (a report "
                f"replaces only an earlier report of the same stem)"
            )
