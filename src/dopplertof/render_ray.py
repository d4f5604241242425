"""One big render on Ray: ``render(..., executor="ray")`` and ``dopplertof render … --ray``.

The render's passes (:func:`dopplertof.passes.schedule`) are traced by Ray actors, each of
which rebuilds the scene from its recipe (:func:`dopplertof.scenes.from_recipe`: a file's
path, ``$name`` values and film size, or a built-in scene's name and arguments; a scene
file must be readable at the same path on every node) and reduces every pass to per-pixel
Float64 increments on its device (:meth:`dopplertof.passes.Reducer.reduce`). The driver
adds them to its sums strictly in pass order, buffering the ones that finish early: the
very numpy additions of the local render, in the same order, so the result is
bit-identical to it, and a stop (``stop()``, Ctrl-C, SIGTERM) keeps a prefix of the passes
that a checkpoint continues from, with either executor.

Scheduling: each worker that has started is kept busy with up to two passes, and no pass
more than two per worker ahead of the next one to add is started, which bounds the
increments waiting in the driver's memory. A worker that dies is restarted and its passes
retried (``max_retries``); passes are deterministic, so a retry gives the same bytes.

============  =====================================================================
workers       W actors, each with ``cluster CPUs // W`` CPUs and as many Dr.Jit
              threads (default: one per CPU); with a ``cuda_*`` variant and GPUs in
              the cluster, one GPU each (default: one per GPU)
kernel cache  ``DRJIT_CACHE_DIR`` on node-local disk (:func:`dopplertof.raytools.node_local_cache`)
============  =====================================================================
"""

from __future__ import annotations

from .raytools import gpu_workers, node_local_cache, start_ray

NO_RECIPE = (
    "the Ray executor builds the scene again on every worker, from its file or built-in name; "
    "this scene was loaded from a dict (save it as a Mitsuba XML file, or render it locally)"
)


class _PassWorker:
    """A Ray actor: the scene built again from its recipe, tracing passes (:class:`PassTracer`)."""

    def __init__(self, recipe, digest, traversal, settings, variant, threads):
        node_local_cache()  # before the first import of Dr.Jit in this worker
        from .backend import set_variant

        set_variant(variant)
        if threads:
            import drjit as dr

            dr.set_thread_count(threads)
        from .passes import PassTracer
        from .scenes import from_recipe

        import socket

        self.error = None
        try:
            scene = from_recipe(recipe)
        except ValueError as exc:  # e.g. the scene file is not at its path on this node
            self.error = f"a Ray worker on {socket.gethostname()} cannot build the scene: {exc}"
            return
        if scene.content_digest != digest:  # the file changed since the driver loaded it
            self.error = (f"a Ray worker on {socket.gethostname()} built another scene than the one loaded: "
                          f"{recipe[1]} changed since (its content differs); load it again")
            return
        scene.traversal = traversal
        self.tracer = PassTracer(scene, settings)

    def ready(self) -> str | None:
        """None once the worker can trace, else why it cannot."""
        return self.error

    def trace(self, p) -> dict:
        return self.tracer(p)


def traced_on_ray(scene, settings, passes, address=None, workers=None, max_retries=3):
    """The increments of ``passes`` (:meth:`~dopplertof.passes.Reducer.reduce`), traced on
    Ray, yielded in pass order (a generator; closing it stops the workers).

    Parameters
    ----------
    scene : DynamicScene with a ``recipe`` (from a file or :func:`dopplertof.scenes.build`),
        else ValueError.
    settings : RenderSettings, built.
    passes : list of :class:`~dopplertof.passes.Pass`.
    address : str, optional. Ray cluster address; default the running Ray, else a local one.
    workers : int, optional. Ray actors (module docstring).
    max_retries : int. Restarts of a dead worker, and retries of its passes.
    """
    from .backend import ensure_variant

    if scene.recipe is None:
        raise ValueError(NO_RECIPE)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    variant = ensure_variant()
    ray = start_ray(address)
    gpus = gpu_workers(ray, variant)
    if gpus:
        count, resources, threads = workers or gpus, {"num_gpus": 1}, None
    else:
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        count = workers or cpus
        threads = max(1, cpus // count)
        resources = {"num_cpus": threads}
    actor = ray.remote(**resources, max_restarts=max_retries, max_task_retries=max_retries)(_PassWorker)
    actors = [actor.remote(scene.recipe, scene.content_digest, scene.traversal, settings, variant, threads) for _ in range(min(count, len(passes)))]
    return _in_pass_order(ray, actors, passes)


def _in_pass_order(ray, actors, passes):
    """Yield each pass's increments in pass order (module docstring: scheduling)."""
    ahead = 2 * len(actors)
    starting = {a.ready.remote(): i for i, a in enumerate(actors)}
    ready, load, running, finished = [], [0] * len(actors), {}, {}
    submitted = yielded = 0
    try:
        while yielded < len(passes):
            for i in ready:
                while load[i] < 2 and submitted < min(len(passes), yielded + ahead):
                    running[actors[i].trace.remote(passes[submitted])] = (submitted, i)
                    load[i] += 1
                    submitted += 1
            done, _ = ray.wait([*starting, *running], num_returns=1, timeout=1.0)
            for ref in done:
                if ref in starting:
                    error = ray.get(ref)
                    if error:
                        raise ValueError(error)
                    ready.append(starting.pop(ref))
                    continue
                index, i = running.pop(ref)
                load[i] -= 1
                finished[index] = ray.get(ref)
            while yielded in finished:
                yield finished.pop(yielded)
                yielded += 1
    finally:
        for a in actors:
            ray.kill(a)
