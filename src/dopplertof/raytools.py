"""What the Ray executors share (datasets: :mod:`dopplertof.dataset.execute`; one big
render: :mod:`dopplertof.render_ray`): starting Ray, and Dr.Jit's kernel cache on the
workers' node-local disk.

============================  ==============================================================
:func:`start_ray`             the Ray module, connected to ``address`` (None: the running
                              Ray, else a new local one); ValueError without the package
:func:`node_local_cache`      ``DRJIT_CACHE_DIR`` (unless set) to ``$TMPDIR/drjit-cache-<user>``;
                              call it in a worker before Dr.Jit is first imported there
:func:`gpu_workers`           whether a variant runs on the cluster's GPUs, and how many
============================  ==============================================================
"""

from __future__ import annotations

import getpass
import os
import tempfile

RAY_MISSING = "--ray needs the 'ray' package: pip install 'dopplertof[ray]'"


def start_ray(address: str | None = None):
    """The ``ray`` module, initialised: the running Ray if there is one, else
    ``ray.init(address=address)`` (None: a new local Ray). ValueError if Ray is not installed."""
    try:
        import ray
    except ImportError:
        raise ValueError(RAY_MISSING) from None
    if not ray.is_initialized():
        ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    return ray


def node_local_cache() -> None:
    """Keep Dr.Jit's kernel cache on the node's disk (not a shared home): before Dr.Jit's import."""
    os.environ.setdefault("DRJIT_CACHE_DIR", os.path.join(tempfile.gettempdir(), f"drjit-cache-{getpass.getuser()}"))


def gpu_workers(ray, variant: str) -> int:
    """The cluster's GPUs if ``variant`` is a ``cuda_*`` one (one long-lived actor each), else 0."""
    return int(ray.cluster_resources().get("GPU", 0)) if variant.startswith("cuda") else 0
