"""sdc-gym on Ray: env registration that works in every worker process, and the cluster.

Ray runs RLlib's env runners, Tune's trials and evaluation tasks in worker processes (on
other machines, too) that never imported ``sdc_gym``, so the plain id
``"sdc_gym/HighwayLoopBehavior-v0"`` fails there with ``NamespaceNotFound: sdc_gym``.
:func:`register_envs` registers every sdc-gym id with Ray Tune's registry
(:func:`ray.tune.registry.register_env`), which Ray keeps in the cluster and RLlib looks
up before Gymnasium's: each worker gets the creator (:func:`make_env`, a function of this
module), and unpickling it imports ``sdc_gym``, which registers the Gymnasium ids there::

    import sdc_gym.ray
    from ray.rllib.algorithms.ppo import PPOConfig

    sdc_gym.ray.register_envs()            # before or after ray.init(): both work
    config = PPOConfig().environment("sdc_gym/HighwayLoopBehavior-v0",
                                     env_config={"highway": {"max_duration": 240.0}})

The ``env_config`` is the env's ``config`` (``gym.make(id, config=env_config)``). Without
Ray's registry, Gymnasium's module prefix does the same for any library that calls
``gym.make`` in a subprocess: ``"sdc_gym:sdc_gym/HighwayLoopBehavior-v0"``.

:func:`ray_session` connects to a running cluster (``"auto"``, an address) or starts a
local one for the duration of a ``with`` block (and shuts it down after, Ctrl-C
included; a watchdog, :mod:`sdc_gym.ray_watchdog`, ends its processes if this process is
killed), with the envs registered; evaluate.py and train.py use it for ``--ray``.

Needs the optional extra: ``pip install -e ".[ray]"``.
"""

from __future__ import annotations

import functools
import os
import socket
import subprocess
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import gymnasium as gym

from sdc_gym import ENV_IDS

LOCAL = "local"
"""The ``address`` of :func:`ray_session` that starts a local cluster for the session."""
START_A_CLUSTER = ("start one with `ray start --head` (then 'auto' finds it), or run "
                   "without an address for a local cluster")


def unreachable(address: str, timeout_s: float = 5.0) -> str | None:
    """Why no Ray cluster answers at ``address`` (``"auto"``: the one the last
    ``ray start`` on this machine recorded, or ``RAY_ADDRESS``), or None when its GCS port
    accepts a connection (or when this Ray has no such lookup: ``ray.init`` decides)."""
    try:
        from ray._private.services import canonicalize_bootstrap_address  # Ray's lookup
    except ImportError:
        return None
    try:
        resolved = canonicalize_bootstrap_address(address)
    except (ValueError, ConnectionError) as error:
        return f"no Ray cluster at {address!r} ({error})"
    if resolved is None:
        return f"no running Ray cluster found for {address!r}"
    host, _, port = resolved.rpartition(":")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except (OSError, ValueError) as error:
        return f"no Ray cluster answers at {resolved} (for {address!r}: {error})"
    return None


def make_env(env_id: str, env_config: Mapping[str, Any] | None = None) -> gym.Env:
    """The env ``env_id`` with ``env_config`` as its config (RLlib's ``EnvContext``, a dict
    with the worker's index as attributes, is taken as the config mapping)."""
    return gym.make(env_id, config=dict(env_config or {}))


def register_envs() -> tuple[str, ...]:
    """Register every sdc-gym env id with Ray Tune's registry (for RLlib and Tune); returns
    the ids. Registering again replaces the entries (harmless)."""
    from ray.tune.registry import register_env

    for env_id in ENV_IDS:
        register_env(env_id, functools.partial(make_env, env_id))
    return ENV_IDS


@contextmanager
def ray_session(address: str = LOCAL, num_cpus: int | None = None,
                **init_options: Any) -> Iterator[dict[str, Any]]:
    """A Ray cluster for the ``with`` block, with the sdc-gym envs registered.

    ``address``: :data:`LOCAL` starts a local cluster (``num_cpus`` cores, default all)
    that is shut down when the block ends, also on an exception or Ctrl-C; ``"auto"``
    (the cluster started on this machine with ``ray start``) or ``"HOST:PORT"``
    connects to a running cluster, which is left running (only this driver disconnects).
    If Ray is already initialised in this process (a test's cluster, a notebook), that one
    is used and left as it is. Yields the cluster's resources (``{"CPU": 2.0, ...}``).
    ``ConnectionError`` (saying what to do) when no cluster answers at ``address``.
    """
    import ray

    if not address:
        raise ValueError(f"address must be {LOCAL!r}, 'auto' or HOST:PORT, got {address!r}")
    owned = not ray.is_initialized()
    if owned:
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                   **init_options}
        if address == LOCAL:
            options["num_cpus"] = num_cpus
        else:
            if num_cpus is not None:
                raise ValueError("num_cpus is for a local cluster: a running cluster has "
                                 "its own resources")
            options["address"] = address
            # ray.init retries an absent cluster for minutes: ask it once, quickly, first.
            problem = unreachable(address)
            if problem is not None:
                raise ConnectionError(f"{problem}; {START_A_CLUSTER}")
    watchdog = start_watchdog() if owned and address == LOCAL else None
    try:
        if owned:
            try:
                ray.init(**options)
            except ConnectionError as error:
                raise ConnectionError(f"cannot reach a Ray cluster at {address!r} ({error}); "
                                      f"{START_A_CLUSTER}") from None
        try:
            register_envs()
            yield dict(ray.cluster_resources())
        finally:
            if owned:
                ray.shutdown()
    finally:
        if watchdog is not None:
            stop_watchdog(watchdog)


def start_watchdog() -> subprocess.Popen[bytes]:
    """:mod:`sdc_gym.ray_watchdog` for this process's local cluster: it ends the cluster's
    processes when this process dies, even by ``kill -9``, or closes its stdin."""
    return subprocess.Popen([sys.executable, "-m", "sdc_gym.ray_watchdog", str(os.getpid())],
                            stdin=subprocess.PIPE, start_new_session=True)


def stop_watchdog(watchdog: subprocess.Popen[bytes], timeout_s: float = 10.0) -> None:
    """Close the watchdog's stdin (it ends what is left of the cluster) and wait for it."""
    assert watchdog.stdin is not None
    watchdog.stdin.close()
    try:
        watchdog.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        watchdog.kill()
        watchdog.wait()


__all__ = ["LOCAL", "make_env", "ray_session", "register_envs", "unreachable"]
