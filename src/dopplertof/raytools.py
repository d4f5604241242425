"""What the Ray executors share (datasets: :mod:`dopplertof.dataset.execute`; one big
render: :mod:`dopplertof.render_ray`): starting Ray, and Dr.Jit's kernel cache on the
workers' node-local disk.

============================  ==============================================================
:func:`require_ray`           the Ray module; ValueError (one line for the CLI) without it
:func:`start_ray`             the Ray module, connected to ``address`` (None: the running
                              Ray, else a new local one), the caller's SIGTERM handler kept
:func:`node_local_cache`      ``DRJIT_CACHE_DIR`` (unless set) to ``$TMPDIR/drjit-cache-<user>``;
                              call it in a worker before Dr.Jit is first imported there
:func:`gpu_workers`           whether a variant runs on the cluster's GPUs, and how many
============================  ==============================================================
"""

from __future__ import annotations

import getpass
import os
import signal
import tempfile
import threading

RAY_MISSING = "--ray needs the 'ray' package: pip install 'dopplertof[ray]'"


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
        previous = signal.getsignal(signal.SIGTERM)
        ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
        if callable(previous) and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, previous)
    return ray


def node_local_cache() -> None:
    """Keep Dr.Jit's kernel cache on the node's disk (not a shared home): before Dr.Jit's import."""
    os.environ.setdefault("DRJIT_CACHE_DIR", os.path.join(tempfile.gettempdir(), f"drjit-cache-{getpass.getuser()}"))


def gpu_workers(ray, variant: str) -> int:
    """The cluster's GPUs if ``variant`` is a ``cuda_*`` one (one long-lived actor each), else 0."""
    return int(ray.cluster_resources().get("GPU", 0)) if variant.startswith("cuda") else 0
