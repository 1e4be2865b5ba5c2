"""A worker of :class:`~sdc_gym.envs.split_vector.SplitVectorEnv`: one block of a batch.

    python -m sdc_gym.envs.split_worker FD OWNER_PID

``FD`` is this process's end of a socket pair with the owner, spoken as a
:class:`multiprocessing.connection.Connection` (pickled messages). The owner first sends
``(entry_point, num_envs, kwargs)``; the worker builds that batch and answers ``("ok",
(observation space, action space, metadata))``, then each ``(command, payload)``
(``reset``, ``step``, ``close``) with ``("ok", result)`` or ``("error",
exception)``.

A plain ``python -m`` process, not a ``multiprocessing`` one: ``spawn`` would run the
owner's main script again in the worker (a script without ``if __name__ == "__main__"``
would build batches recursively), and a fork would copy a process that may hold torch's or
numba's threads. The worker ends with its owner: when the owner closes the connection or
says ``close``, and, through ``PR_SET_PDEATHSIG``, when the owner is killed.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import traceback
from multiprocessing.connection import Connection
from typing import Any

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>: the signal a process gets when its parent dies


class WorkerError(RuntimeError):
    """A worker's exception that could not be sent back as itself (not picklable), or a
    worker that ended without answering."""


def die_with_owner(owner: int) -> None:
    """SIGKILL this process when its parent dies (Linux); exit now if it already has."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the connection's end is the signal
        pass
    if os.getppid() != owner:
        os._exit(0)


def send_error(connection: Connection, error: BaseException) -> None:
    """``error`` to the owner: itself, or a :class:`WorkerError` with its type, message
    and trace when it does not pickle."""
    try:
        connection.send(("error", error))
    except Exception:
        connection.send(("error", WorkerError(
            f"{type(error).__name__}: {error}\n{''.join(traceback.format_exception(error))}")))


def serve(connection: Connection) -> None:
    """Build the block's batch, then answer commands until ``close`` or the owner's end."""
    from gymnasium.envs.registration import load_env_creator

    entry_point, num_envs, kwargs = connection.recv()
    try:
        vector = load_env_creator(entry_point)(num_envs=num_envs, **kwargs)
        connection.send(("ok", (vector.single_observation_space,
                                vector.single_action_space, vector.metadata)))
    except Exception as error:  # raised in the owner
        send_error(connection, error)
        return
    while True:
        try:
            command, payload = connection.recv()
        except (EOFError, OSError):  # the owner is gone
            return
        try:
            if command == "step":
                answer: Any = vector.step(payload)
            elif command == "reset":
                answer = vector.reset(**payload)
            elif command == "close":
                vector.close()
                connection.send(("ok", None))
                return
            else:
                raise ValueError(f"unknown command {command!r}")
        except Exception as error:  # raised in the owner
            send_error(connection, error)
            continue
        connection.send(("ok", answer))


def main(argv: list[str]) -> None:
    descriptor, owner = int(argv[0]), int(argv[1])
    die_with_owner(owner)
    connection = Connection(descriptor)
    try:
        serve(connection)
    except (EOFError, OSError, KeyboardInterrupt):
        pass
    finally:
        connection.close()


if __name__ == "__main__":
    main(sys.argv[1:])
