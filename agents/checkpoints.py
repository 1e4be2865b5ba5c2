"""stable-baselines3 models and replay buffers written atomically, and the checkpoint to
resume from.

SB3 writes ``model.save(path)`` straight into ``path``: a run killed while it saves leaves
a torn zip (``--resume`` then failed with "No data found in the saved file"). Here every
file goes to a temporary file in the same folder, is flushed to disk (``fsync``) and
renamed over the target (``os.replace``, atomic on POSIX), so a file is either the old one
or the complete new one. A checkpoint's replay buffer is written *before* its model: a
model checkpoint on disk always had its buffer written first.

:func:`resume_point` picks the newest checkpoint that loads: a torn one (from a run
before this, a full disk, a copy cut short) is skipped with a note saying why, and for an
off-policy algorithm its replay buffer must be there too; a model whose buffer is missing
is refused with a clear message unless the caller allows resuming without it.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

CHECKPOINT_SUFFIX = "_steps.zip"


@contextlib.contextmanager
def atomic_file(path: Path) -> Iterator[IO[bytes]]:
    """A binary file handle whose content replaces ``path`` atomically when the block ends
    without an exception (temporary file in the same folder, fsync, ``os.replace``, fsync
    of the folder); on an exception ``path`` is left as it was."""
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                             suffix=".tmp")
    try:
        with open(descriptor, "wb") as handle:  # a BufferedWriter, as SB3 requires
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    try:
        folder = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(folder)  # the rename itself on disk
    except OSError:
        pass
    finally:
        os.close(folder)


def sync_folder(folder: Path) -> None:
    """Every file and folder below ``folder`` flushed to disk (``fsync``), before a rename
    makes it a checkpoint: a folder written by another library (RLlib's ``save_to_path``)
    is then whole on disk once it has its final name."""
    for root, _, files in os.walk(folder):
        for name in files:
            descriptor = os.open(os.path.join(root, name), os.O_RDONLY)
            try:
                os.fsync(descriptor)
            finally:
                os.close(descriptor)
        descriptor = os.open(root, os.O_RDONLY)
        try:
            os.fsync(descriptor)
        except OSError:  # a file system without directory fsync
            pass
        finally:
            os.close(descriptor)


def save_model(model: Any, path: Path) -> None:
    """``model.save`` to ``path`` (a ``.zip``), atomically."""
    with atomic_file(path) as handle:
        model.save(handle)


def save_replay_buffer(model: Any, path: Path) -> None:
    """``model.save_replay_buffer`` to ``path`` (a ``.pkl``), atomically."""
    with atomic_file(path) as handle:
        model.save_replay_buffer(handle)


def checkpoint_steps(path: Path) -> int | None:
    """The timesteps in a checkpoint's name ``<prefix>_<steps>_steps.zip``, else None."""
    if not path.name.endswith(CHECKPOINT_SUFFIX):
        return None
    steps = path.name[:-len(CHECKPOINT_SUFFIX)].rsplit("_", 1)[-1]
    return int(steps) if steps.isdigit() else None


def buffer_path(checkpoints: Path, prefix: str, steps: int) -> Path:
    """Where :class:`AtomicCheckpointCallback` puts the replay buffer of a checkpoint."""
    return checkpoints / f"{prefix}_replay_buffer_{steps}_steps.pkl"


def model_problem(path: Path) -> str | None:
    """Why the model zip cannot be loaded (``None``: it is whole): SB3's files are zips
    with a ``data`` member, every member's CRC intact."""
    try:
        with zipfile.ZipFile(path) as archive:
            if "data" not in archive.namelist():
                # A cut-short SB3 zip can end inside one of its members (policy.pth is a
                # zip itself), which then reads as a zip without SB3's 'data'.
                return "not a whole SB3 model zip (no 'data' member: cut short?)"
            bad = archive.testzip()
            return None if bad is None else f"member {bad!r} is corrupt"
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        return f"not a whole SB3 model zip ({error})"


def buffer_problem(path: Path) -> str | None:
    """Why the replay buffer pickle cannot be loaded (``None``: it loads)."""
    try:
        with path.open("rb") as handle:
            pickle.load(handle)
    except FileNotFoundError:
        return "missing"
    except Exception as error:  # a torn pickle raises any of several errors
        return f"torn ({type(error).__name__}: {error})"
    return None


@dataclass(frozen=True)
class ResumePoint:
    """The checkpoint to resume from, its replay buffer (or None), and what was skipped."""

    model: Path
    steps: int
    replay_buffer: Path | None
    notes: tuple[str, ...]

    def report(self) -> list[str]:
        """What ``--resume`` says: what was skipped, and where it goes on from."""
        buffer = f", replay buffer {self.replay_buffer.name}" if self.replay_buffer else ""
        return [f"--resume: {note}" for note in self.notes] + [
            f"--resume: from {self.model} ({self.steps} steps{buffer})"]


def sb3_checkpoints(checkpoints: Path, prefix: str) -> list[tuple[int, Path]]:
    """``(steps, path)`` of the SB3 checkpoint zips in ``checkpoints``, newest first."""
    return sorted(((steps, path) for path in checkpoints.glob(f"{prefix}_*{CHECKPOINT_SUFFIX}")
                   if (steps := checkpoint_steps(path)) is not None), reverse=True)


def resume_point(checkpoints: Path, prefix: str, off_policy: bool, *,
                 without_buffer: bool = False,
                 check_buffer: Callable[[Path], str | None] = buffer_problem,
                 found: list[tuple[int, Path]] | None = None,
                 check_model: Callable[[Path], str | None] = model_problem,
                 buffer_of: Callable[[Path, int], Path] | None = None
                 ) -> ResumePoint | None:
    """The newest checkpoint in ``checkpoints`` that can be resumed (see the module
    docstring); ``None`` when there is no checkpoint at all.

    Raises ``ValueError`` when checkpoints exist but none can be resumed: every model is
    torn, or (off-policy, without ``without_buffer``) every whole model lacks a loadable
    replay buffer; the message names each file and its problem.

    SB3's layout by default; another trainer's (RLlib's checkpoint folders) gives its
    checkpoints ``found`` (``(steps, path)``, newest first), ``check_model`` (why one
    cannot be loaded, or None) and ``buffer_of(path, steps)`` (where its buffer is).
    """
    if found is None:
        found = sb3_checkpoints(checkpoints, prefix)
    if buffer_of is None:
        def buffer_of(path: Path, steps: int) -> Path:
            return buffer_path(checkpoints, prefix, steps)
    if not found:
        return None
    notes: list[str] = []
    missing_buffers: list[Path] = []
    for steps, path in found:
        problem = check_model(path)
        if problem is not None:
            notes.append(f"skipped {path.name}: {problem}")
            continue
        if not off_policy:
            return ResumePoint(path, steps, None, tuple(notes))
        buffer = buffer_of(path, steps)
        buffer_issue = check_buffer(buffer)
        if buffer_issue is None:
            return ResumePoint(path, steps, buffer, tuple(notes))
        if without_buffer:
            notes.append(f"{path.name}: its replay buffer {buffer.name} is {buffer_issue}; "
                         "resuming with an empty replay buffer (--resume-without-buffer)")
            return ResumePoint(path, steps, None, tuple(notes))
        notes.append(f"skipped {path.name}: its replay buffer {buffer.name} is {buffer_issue}")
        missing_buffers.append(path)
    detail = "; ".join(notes)
    if missing_buffers:
        raise ValueError(f"no checkpoint in {checkpoints} can be resumed with its replay buffer "
                         f"({detail}). Resuming without it would start from an empty buffer: "
                         "pass --resume-without-buffer to do that anyway")
    raise ValueError(f"no checkpoint in {checkpoints} can be loaded ({detail})")


def checkpoint_callback(save_freq: int, folder: Path, prefix: str,
                        with_replay_buffer: bool) -> Any:
    """An SB3 ``CheckpointCallback`` that writes atomically, the buffer before the model."""
    from stable_baselines3.common.callbacks import CheckpointCallback

    class AtomicCheckpointCallback(CheckpointCallback):
        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq == 0:
                if (self.save_replay_buffer
                        and getattr(self.model, "replay_buffer", None) is not None):
                    save_replay_buffer(self.model, buffer_path(folder, prefix,
                                                               self.num_timesteps))
                save_model(self.model, Path(self._checkpoint_path(extension="zip")))
            return True

    return AtomicCheckpointCallback(save_freq, str(folder), name_prefix=prefix,
                                    save_replay_buffer=with_replay_buffer)


def evaluation_line(timesteps: int, returns: list[float],
                    summaries: list[dict[str, Any]]) -> str:
    """One evaluation's driving figures as a line, printed beside SB3's own ``Eval ...``
    lines: the mean return, mean speed and incidents per episode (by kind when any)."""
    line = (f"Eval num_timesteps={timesteps}: {len(returns)} episode(s), return "
            f"{np.mean(returns):.2f} +/- {np.std(returns):.2f}")
    speeds = [summary["mean_speed_mph"] for summary in summaries
              if summary.get("mean_speed_mph") is not None]
    if speeds:
        line += f", mean speed {np.mean(speeds):.2f} mph"
    if summaries:
        kinds: dict[str, int] = {}
        for summary in summaries:
            for kind, count in summary.get("incidents", {}).items():
                kinds[kind] = kinds.get(kind, 0) + count
        total = sum(kinds.values())
        line += f", incidents {total / len(summaries):.2f} per episode"
        if total:
            line += " (" + ", ".join(f"{kind} {count}" for kind, count in kinds.items()
                                     if count) + ")"
    return line


def eval_callback(eval_env: Any, folder: Path, **kwargs: Any) -> Any:
    """An SB3 ``EvalCallback`` writing ``best_model.zip`` and ``evaluations.npz`` in
    ``folder``, each atomically. With ``verbose=1`` it prints, at each evaluation, SB3's
    lines and :func:`evaluation_line` (return, mean mph, incidents); the driving figures
    also go to the logger (``eval/mean_speed_mph``, ``eval/incidents_per_episode``)."""
    from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

    class SaveBest(BaseCallback):
        def _on_step(self) -> bool:
            save_model(self.model, folder / "best_model.zip")
            return True

    class AtomicEvalCallback(EvalCallback):
        """SB3 saves the evaluations with ``np.savez`` to ``log_path``: a temporary name
        here, renamed over ``evaluations.npz`` after each evaluation."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.summaries: list[dict[str, Any]] = []  # the evaluation's episodes

        def _log_success_callback(self, locals_: dict[str, Any],
                                  globals_: dict[str, Any]) -> None:
            super()._log_success_callback(locals_, globals_)
            summary = locals_["info"].get("summary") if locals_["done"] else None
            if summary is not None:  # recorded before SB3 dumps the evaluation's log
                self.summaries.append(summary)
                self.logger.record_mean("eval/incidents_per_episode",
                                        sum(summary.get("incidents", {}).values()))
                if summary.get("mean_speed_mph") is not None:
                    self.logger.record_mean("eval/mean_speed_mph", summary["mean_speed_mph"])

        def _on_step(self) -> bool:
            evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
            self.summaries = []
            keep_going = super()._on_step()
            if evaluating and self.verbose >= 1 and self.evaluations_results:
                print(evaluation_line(self.num_timesteps, self.evaluations_results[-1],
                                      self.summaries), flush=True)
            written = Path(f"{self.log_path}.npz")
            if written.is_file():  # complete: np.savez has returned
                with written.open("rb+") as handle:
                    os.fsync(handle.fileno())
                os.replace(written, folder / "evaluations.npz")
            return keep_going

    callback = AtomicEvalCallback(eval_env, callback_on_new_best=SaveBest(),
                                  log_path=str(folder), best_model_save_path=None, **kwargs)
    callback.log_path = str(folder / ".evaluations.partial")
    return callback
