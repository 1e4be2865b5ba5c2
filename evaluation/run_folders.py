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


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files a killed run left in ``folder`` (and below): the
    ``.NAME.<random>.tmp`` of an atomic write (checkpoints, replay buffers of 11-22 MB,
    figures ``.X.png.PID.tmp``) and ``.NAME.tmp`` folders. One whose name carries the pid
    of a live process other than this one is kept (a writer still at work). Called when
    train.py or evaluate.py uses a run folder again; returns what was removed."""
    removed: list[Path] = []
    if not folder.is_dir():
        return removed
    for path in sorted(folder.rglob(".*.tmp")):
        parts = path.name.split(".")
        pid = int(parts[-2]) if len(parts) >= 4 and parts[-2].isdigit() else None
        if pid is not None and pid != os.getpid() and _pid_alive(pid):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


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
    remove_stale_temporaries(output)
    for name in owned:
        path = output / name
        if path.is_symlink() or path.is_file():
            path.unlink()
        elif path.is_dir():
            shutil.rmtree(path)
