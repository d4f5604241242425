"""What the Ray executors share (datasets: :mod:`dopplertof.dataset.execute`; one big
render: :mod:`dopplertof.render_ray`): starting Ray, and Dr.Jit's kernel cache on the
workers' node-local disk.

============================  ==============================================================
:func:`require_ray`           the Ray module; ValueError (one line for the CLI) without it
:func:`start_ray`             the Ray module, connected to ``address`` (None: the running
                              Ray, else a new local one), the caller's SIGTERM handler kept
:func:`check_reachable`       ValueError at once (5 s at most) for a ``host:port`` that does
                              not answer, where Ray would retry for minutes
:func:`node_local_cache`      ``DRJIT_CACHE_DIR`` (unless set) to ``$TMPDIR/drjit-cache-<user>``;
                              call it in a worker before Dr.Jit is first imported there
:func:`gpu_workers`           whether a variant runs on the cluster's GPUs, and how many
============================  ==============================================================
"""

from __future__ import annotations

import getpass
import logging
import os
import signal
import socket
import tempfile
import threading

RAY_MISSING = "--ray needs the 'ray' package: pip install 'dopplertof[ray]'"
RAY_CONNECT_TIMEOUT_S = 5.0  # Ray itself retries an unreachable address for minutes


def require_ray():
    """The ``ray`` module; ValueError if it is not installed."""
    try:
        import ray
    except ImportError:
        raise ValueError(RAY_MISSING) from None
    return ray


def start_ray(address: str | None = None):
    """The ``ray`` module, initialised: the running Ray if there is one, else
    ``ray.init(address=address)`` (None: a new local Ray). ValueError if Ray is not installed.

    ``ray.init`` replaces the SIGTERM handler with one that exits at once; a handler the
    caller installed (to stop after the work in progress) is put back.
    """
    ray = require_ray()
    if not ray.is_initialized():
        check_reachable(address)
        previous = signal.getsignal(signal.SIGTERM)
        try:
            # Ray's own notes ("Started a local Ray instance", that token authentication is
            # on) are not the user's business here; its errors still print.
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False, logging_level=logging.ERROR)
        except ConnectionError as exc:  # an OSError: it would read as a file problem
            raise ValueError(f"cannot connect to Ray at {address!r}: {exc}") from None
        if callable(previous) and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, previous)
    return ray


def check_reachable(address: str | None, timeout_s: float = RAY_CONNECT_TIMEOUT_S) -> None:
    """ValueError unless a TCP connection to a ``host:port`` Ray address (also
    ``ray://host:port``) opens within ``timeout_s`` seconds. Other addresses (None, "auto",
    "local") are Ray's to resolve, which it does at once.

    Parameters
    ----------
    address : str or None
        The address given to :func:`start_ray`.
    timeout_s : float
        Seconds to wait for the connection (default :data:`RAY_CONNECT_TIMEOUT_S`).
    """
    host, sep, port = (address or "").rpartition("://")[2].rpartition(":")
    if not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except (OSError, OverflowError) as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else getattr(exc, "strerror", None) or exc
        raise ValueError(f"cannot reach the Ray cluster at {address!r} within {timeout_s:g} s ({why})") from None


def node_local_cache() -> None:
    """Keep Dr.Jit's kernel cache on the node's disk (not a shared home): before Dr.Jit's import."""
    os.environ.setdefault("DRJIT_CACHE_DIR", os.path.join(tempfile.gettempdir(), f"drjit-cache-{getpass.getuser()}"))


def gpu_workers(ray, variant: str) -> int:
    """The cluster's GPUs if ``variant`` is a ``cuda_*`` one (one long-lived actor each), else 0."""
    return int(ray.cluster_resources().get("GPU", 0)) if variant.startswith("cuda") else 0
