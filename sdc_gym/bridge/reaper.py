"""The planner's parent: it starts the planner, and ends the planner's whole process tree.

    python sdc_gym/bridge/reaper.py OWNER STATUS_FD -- COMMAND [ARGUMENT ...]

:class:`~sdc_gym.bridge.process.PlannerProcess` does not start a planner itself: it starts
this small script (standard library only), which becomes a *child subreaper* (Linux's
``PR_SET_CHILD_SUBREAPER``) and then starts the planner. Every process the planner starts,
even one that leaves the planner's session with ``setsid`` and outlives the planner, stays a
descendant of this process: an orphan below it is re-parented to it, not to init. So
ending "every descendant of the reaper" is exactly ending the planner's tree, found by one
scan of ``/proc``, with no process of anyone else in it.

Why a subreaper and not a cgroup: a cgroup would also hold the tree, but creating one
needs write access to a delegated part of ``/sys/fs/cgroup`` (root, or systemd's user
delegation), which containers and CI runners often mount read-only; the subreaper flag
needs no privilege (Linux 3.4 and later). Where it is missing (other systems), the
planner's process group and the descendants still linked to it are ended, as before.

The tree is ended (SIGTERM to every descendant, up to ``GRACE_S`` for them to exit, then
SIGKILL, repeated until none is left) when

* its owner asks: the owner closes our standard input, a pipe only it writes to;
* its owner dies (``kill -9``, an out-of-memory kill, a crashed worker): the kernel closes
  that pipe for it, and we notice that our parent process id changed (a fork of the owner
  could hold the pipe open; the parent id catches that case too);
* we get SIGTERM.

Status lines go to the file descriptor ``STATUS_FD`` (a pipe to the owner): ``started PID``
once the planner runs (or ``error ERRNO MESSAGE`` if it cannot start), ``exit CODE`` when it
exits (negative: killed by that signal, like :attr:`subprocess.Popen.returncode`).
"""

from __future__ import annotations

import ctypes
import errno
import os
import select
import signal
import subprocess
import sys
import time
from typing import Final

POLL_S: Final = 0.1  # how often the owner and the planner are checked
GRACE_S: Final = 2.0  # between SIGTERM and SIGKILL, as PlannerProcess.stop
PR_SET_CHILD_SUBREAPER: Final = 36  # <linux/prctl.h>
SWEEP_ROUNDS: Final = 50  # SIGKILL rounds for a tree that keeps forking while it is ended


def prctl(option: int, value: int) -> bool:
    """Linux's ``prctl(option, value)`` through libc; whether it worked (False elsewhere)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(option, value, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def become_subreaper() -> bool:
    """Make orphaned descendants ours instead of init's (Linux); whether it worked."""
    return prctl(PR_SET_CHILD_SUBREAPER, 1)


def descendants(root: int) -> list[int]:
    """Live (not zombie) descendants of ``root`` from ``/proc``; [] where there is none."""
    children: dict[int, list[int]] = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as handle:
                stat = handle.read()
        except OSError:
            continue  # exited meanwhile
        fields = stat[stat.rfind(b")") + 2:].split()  # after "pid (name) "
        if len(fields) < 2 or fields[0] in (b"Z", b"X"):
            continue
        children.setdefault(int(fields[1]), []).append(int(entry))
    found: list[int] = []
    stack = [root]
    while stack:
        for child in children.get(stack.pop(), ()):
            found.append(child)
            stack.append(child)
    return found


def reap(planner: subprocess.Popen[bytes] | None) -> None:
    """Collect every exited child: orphans re-parented to us, and the planner through its
    Popen (which keeps its exit status). ``waitid(WNOWAIT)`` looks before reaping."""
    while True:
        try:
            info = os.waitid(os.P_ALL, 0, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:
            return
        if info is None:
            return
        if planner is not None and info.si_pid == planner.pid:
            planner.poll()
            if planner.returncode is None:  # cannot happen: it is waitable
                return
        else:
            try:
                os.waitpid(info.si_pid, os.WNOHANG)
            except ChildProcessError:
                pass


def _signal(pid: int, signum: int, *, group: bool = False) -> None:
    try:
        (os.killpg if group else os.kill)(pid, signum)
    except (ProcessLookupError, PermissionError):
        pass


class Planner:
    """The planner process and the status pipe to the owner."""

    def __init__(self, status_fd: int, command: list[str]) -> None:
        self.status = os.fdopen(status_fd, "w", buffering=1)
        self.popen: subprocess.Popen[bytes] | None = None
        self.exit_reported = False
        try:
            # Its own session: a terminal's Ctrl-C reaches it only through its owner.
            self.popen = subprocess.Popen(command, stdin=subprocess.DEVNULL,
                                          start_new_session=True)
        except OSError as error:
            self.say(f"error {error.errno or 0} {error.strerror or error}")
            return
        self.say(f"started {self.popen.pid}")

    def say(self, line: str) -> None:
        try:
            self.status.write(line + "\n")
        except OSError:
            pass  # the owner is gone: nobody to tell

    def poll(self) -> None:
        """Collect exited children; report the planner's exit once."""
        reap(self.popen)
        if self.popen is not None and not self.exit_reported \
                and self.popen.returncode is not None:
            self.exit_reported = True
            self.say(f"exit {self.popen.returncode}")

    def end_tree(self) -> None:
        """SIGTERM to the whole tree, ``GRACE_S`` to exit, then SIGKILL until none is left."""
        me = os.getpid()
        group = self.popen.pid if self.popen is not None else None
        for signum in (signal.SIGTERM, signal.SIGKILL):
            rounds = 1 if signum == signal.SIGTERM else SWEEP_ROUNDS
            for _ in range(rounds):
                tree = descendants(me)
                if group is not None:
                    _signal(group, signum, group=True)
                for pid in tree:
                    _signal(pid, signum)
                if signum == signal.SIGKILL:
                    time.sleep(0.01)
                    self.poll()
                    if not descendants(me) and (group is None or not _group_alive(group)):
                        return
            deadline = time.monotonic() + GRACE_S
            while signum == signal.SIGTERM and time.monotonic() < deadline:
                self.poll()
                if not descendants(me) and (group is None or not _group_alive(group)):
                    return
                time.sleep(0.02)


def _group_alive(group: int) -> bool:
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def watch(planner: Planner, owner: int) -> None:
    """Return when the owner asks for the end, dies, or sends SIGTERM."""
    stop = False

    def on_term(signum: int, frame: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_term)
    control = sys.stdin.fileno()
    while not stop:
        try:
            readable, _, _ = select.select([control], [], [], POLL_S)
        except InterruptedError:
            continue
        if readable:
            try:
                if not os.read(control, 4096):
                    return  # EOF: the owner closed the pipe, or died
            except OSError as error:
                if error.errno != errno.EINTR:
                    return
        if os.getppid() != owner:
            return
        planner.poll()


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 4 or args[2] != "--" or not args[0].isdigit() or not args[1].isdigit():
        print("usage: reaper.py OWNER STATUS_FD -- COMMAND [ARGUMENT ...]", file=sys.stderr)
        return 2
    owner, status_fd, command = int(args[0]), int(args[1]), args[3:]
    # A Ctrl-C meant for the owner must not end us before the planner: the owner stops us.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    become_subreaper()
    planner = Planner(status_fd, command)
    if planner.popen is None:
        return 3
    try:
        watch(planner, owner)
    finally:
        planner.end_tree()
        planner.poll()
    return 0


if __name__ == "__main__":
    sys.exit(main())
