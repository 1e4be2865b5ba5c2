"""Run folders that are never overwritten without being asked.

By default each evaluation gets a new folder ``results/<YYYY-mm-dd_HH-MM-SS>`` (a ``-2``,
``-3``... suffix when two start in the same second), and ``results/latest`` is a symbolic
link to the newest, replaced atomically (a new link under a temporary name, then a
rename over the old one), so ``results/latest/report.html`` is always a complete run.
An explicit ``--output`` folder that exists and holds anything is refused unless
``--overwrite`` is given; then the files an evaluation writes are removed first, so that
nothing of the old run (an ``incidents.json`` the new run would not write) is left to be
mistaken for the new one, while other files in the folder are kept.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Iterable
from pathlib import Path

RESULTS_ROOT = Path("results")
LATEST = "latest"
TIMESTAMP_FORMAT = "%Y-%m-%d_%H-%M-%S"


def new_run_folder(root: Path = RESULTS_ROOT, now: float | None = None) -> Path:
    """Create and return a fresh timestamped folder under ``root`` (never an existing one)."""
    root.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime(TIMESTAMP_FORMAT, time.localtime(now))
    for attempt in range(1, 1000):
        folder = root / (stamp if attempt == 1 else f"{stamp}-{attempt}")
        try:
            folder.mkdir()  # atomic: two runs never get the same folder
        except FileExistsError:
            continue
        return folder
    raise RuntimeError(f"no free run folder for {stamp} under {root}")


def point_latest_at(folder: Path, root: Path = RESULTS_ROOT) -> Path:
    """Make ``root/latest`` a relative symbolic link to ``folder`` (which must be in
    ``root``), atomically. A real folder named ``latest`` (from before run folders were
    timestamped) is first renamed to a timestamped name of its own, never deleted."""
    link = root / LATEST
    if link.is_dir() and not link.is_symlink():
        kept = new_run_folder(root, link.stat().st_mtime)
        kept.rmdir()
        os.replace(link, kept)
    temporary = root / f".{LATEST}.{os.getpid()}.tmp"
    temporary.unlink(missing_ok=True)
    os.symlink(folder.name, temporary)
    os.replace(temporary, link)
    return link


def is_empty_folder(path: Path) -> bool:
    return path.is_dir() and not any(path.iterdir())


def prepare_output(output: Path, overwrite: bool, owned: Iterable[str]) -> None:
    """Check an explicit ``--output``: refuse an existing non-empty folder unless
    ``overwrite``, and then remove the ``owned`` names (files or folders an evaluation
    writes) from it. Raises ``SystemExit`` with the reason."""
    if output.exists() and not output.is_dir():
        raise SystemExit(f"--output {output} exists and is not a folder")
    if not output.exists() or is_empty_folder(output):
        output.mkdir(parents=True, exist_ok=True)
        return
    if not overwrite:
        raise SystemExit(f"--output {output} already holds files (a previous run?); pass "
                         "--overwrite to replace its results, or choose another folder "
                         f"(without --output each run gets its own under {RESULTS_ROOT}/)")
    for name in owned:
        path = output / name
        if path.is_symlink() or path.is_file():
            path.unlink()
        elif path.is_dir():
            shutil.rmtree(path)
