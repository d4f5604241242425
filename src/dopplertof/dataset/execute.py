"""Executors: who renders which shard. Each worker renders whole shards (:func:`render_shard`).

* local, one worker: in this process;
* local, W workers: W processes of the *spawn* start method (Dr.Jit's LLVM/CUDA state must
  never be forked), each with ``cpus // W`` Dr.Jit threads; a worker that dies (killed,
  out of memory) breaks the pool, which is restarted with the unfinished shards, up to
  ``max_retries`` times. ``workers="auto"`` (:func:`auto_workers`, the command's default)
  takes one per CPU: Dr.Jit compiles a sample's kernel on one thread, so with one process
  the other cores wait for each new scene's kernel (a third of a street sample's time);
* Ray: one task per shard (``max_retries`` retries of a killed worker), the driver
  collecting results as they finish; on a cluster with GPUs and a ``cuda_*`` variant, one
  long-lived actor per GPU instead, each importing Mitsuba inside the actor after Ray has
  set ``CUDA_VISIBLE_DEVICES``. Ray workers keep Dr.Jit's kernel cache on node-local disk
  (``DRJIT_CACHE_DIR``, default ``$TMPDIR/drjit-cache-<user>``) unless it is set.

Every executor calls ``on_done(result)`` in the driver for each finished shard, in
completion order, and stops on KeyboardInterrupt (SIGINT, or SIGTERM turned into one by
:func:`dopplertof.dataset.generate`): finished shards stay, unfinished ones are abandoned.

Test hook (fault injection): a job with ``"fault": "<shard index>:<marker path>"`` (from
the environment variable ``DOPPLERTOF_DATASET_FAULT``) makes the worker that starts that
shard while the marker file does not exist create it and exit at once (``os._exit(1)``),
as a killed worker would; the retried attempt finds the marker and renders normally.
"""

from __future__ import annotations

import contextlib
import os
import time

from .. import resources
from ..raytools import gpu_workers, node_local_cache, start_ray
from . import shards

FAULT_ENV = "DOPPLERTOF_DATASET_FAULT"
AUTO = "auto"  # workers="auto": auto_workers
# What workers="auto" sets aside per worker, a rule of thumb with room to spare: 1 GiB, plus
# 2 KiB per pixel of the film (ad hoc: a worker rendering street samples at 64 spp peaked at
# 0.26, 0.39 and 0.65 GiB at 128², 256² and 512², about 0.3 GiB + 1.4 KiB a pixel).
WORKER_MEMORY_BYTES = 1 << 30
WORKER_MEMORY_BYTES_PER_PIXEL = 2048


def auto_workers(shards_to_render: int, variant: str, resolution: int) -> int:
    """The local workers of ``workers="auto"``: one per usable CPU
    (:func:`dopplertof.resources.usable_cpus`), at most one per shard to render and as many
    as the available memory (:func:`dopplertof.resources.available_memory_bytes`) holds at
    :data:`WORKER_MEMORY_BYTES` + :data:`WORKER_MEMORY_BYTES_PER_PIXEL` a pixel each; 1
    (this process) with a ``cuda_*`` variant, whose processes would share one GPU.

    Parameters
    ----------
    shards_to_render : int
    variant : str
        The Mitsuba variant the shards are rendered with.
    resolution : int
        The film's side (pixels).

    Returns
    -------
    int
        ≥ 1.
    """
    if variant.startswith("cuda"):
        return 1
    cpus, available = resources.usable_cpus(), resources.available_memory_bytes()
    by_memory = cpus if available is None else available // (WORKER_MEMORY_BYTES + WORKER_MEMORY_BYTES_PER_PIXEL * resolution**2)
    return max(1, min(cpus, shards_to_render, by_memory))


def _fault(job: dict) -> None:
    spec = job.get("fault")
    if not spec:
        return
    index, _, marker = spec.partition(":")
    if int(index) == job["index"] and not os.path.exists(marker):
        with open(marker, "w") as f:
            f.write(f"worker {os.getpid()} killed itself at the start of shard {job['index']}\n")
        os._exit(1)


def render_shard(job: dict) -> dict:
    """Render and write one shard (runs in a worker).

    Parameters
    ----------
    job : dict
        ``folder``, ``index``, ``first``, ``count``, ``config``, ``seed``, ``variant``,
        ``fields``, and optionally ``threads`` (Dr.Jit threads), ``fault`` (test hook).

    Returns
    -------
    dict
        ``{"record": shard record, "seconds": {...}, "pid": …}``: wall seconds of
        ``startup`` (imports and backend start: in a fresh worker, once), then per phase
        summed over the shard's samples (``record``, ``scene``, ``render``, ``sensor``,
        ``write``) and their ``total`` (start-up excluded).
    """
    _fault(job)
    t_start = time.perf_counter()
    import dopplertof as dt

    from . import sample

    dt.set_variant(job["variant"])
    if job.get("threads"):
        import drjit as dr

        dr.set_thread_count(int(job["threads"]))
    # once per worker process (imports, backend start), not per shard
    seconds = {"startup": time.perf_counter() - t_start, "record": 0.0, "scene": 0.0, "render": 0.0, "sensor": 0.0, "write": 0.0}
    t_start = time.perf_counter()
    samples = []
    for i in range(job["first"], job["first"] + job["count"]):
        t0 = time.perf_counter()
        record = sample.make_record(job["config"], job["seed"], i, job["variant"])
        seconds["record"] += time.perf_counter() - t0
        arrays, derived, spent = sample.render_record(record, job["fields"])
        for k, v in spent.items():
            seconds[k] += v
        samples.append((record["key"], arrays, {**record, "sensor_derived": derived}))
    t0 = time.perf_counter()
    rec = shards.write_shard(job["folder"], job["index"], job["first"], samples)
    seconds["write"] += time.perf_counter() - t0
    seconds["total"] = time.perf_counter() - t_start
    return {"record": rec, "seconds": seconds, "pid": os.getpid()}


# ------------------------------------------------------------------------------------------
# Local


# How often a worker checks that the process that started it is alive, s.
PARENT_CHECK_S = 1.0


def _start_worker(parent: int):
    """A worker's set-up: SIGINT ignored (the driver decides; SIGTERM still kills), and a
    thread that ends the worker once its driver (process ``parent``) is gone: a SIGKILL of
    the driver would otherwise leave it rendering, re-parented, for minutes. The driver
    passes its PID: it may be gone before this runs (a worker imports for seconds first)."""
    import signal
    import threading
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_S)
        os._exit(1)

    threading.Thread(target=watch, name="dopplertof: parent watch", daemon=True).start()


def run_local(jobs: list[dict], workers: int, on_done, max_retries: int = 3) -> None:
    """Render ``jobs`` in this process (``workers == 1``) or in ``workers`` spawned processes.

    Parameters
    ----------
    jobs : list of dict
        One :func:`render_shard` job per shard.
    workers : int
        Processes; 1 renders in this process.
    on_done : callable
        Called in this process with each finished shard's :func:`render_shard` result.
    max_retries : int, default 3
        How often the shards of a worker that died are given to a new one.

    Raises
    ------
    RuntimeError
        A worker died more than ``max_retries`` times; the finished shards stay written.
    """
    if workers == 1:
        for job in jobs:
            on_done(render_shard(job))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    threads = max(1, resources.usable_cpus() // workers)
    pending = {job["index"]: {**job, "threads": job.get("threads") or threads} for job in jobs}
    attempts = 0
    context = multiprocessing.get_context("spawn")
    while pending:
        pool = ProcessPoolExecutor(max_workers=min(workers, len(pending)), mp_context=context, initializer=_start_worker, initargs=(os.getpid(),))
        try:
            futures = {pool.submit(render_shard, job): index for index, job in sorted(pending.items())}
            for future in as_completed(futures):
                result = future.result()
                del pending[futures[future]]
                on_done(result)
        except BrokenProcessPool:
            attempts += 1
            # Shards other workers wrote before the pool broke are on disk: keep them.
            for index, job in sorted(pending.items()):
                if shards.shard_status(job["folder"], index, job["count"]) == "ok":
                    del pending[index]
                    on_done({"record": shards.read_record(job["folder"], index), "seconds": {}, "pid": None})
            if attempts > max_retries and pending:
                raise RuntimeError(f"a worker process died {attempts} times; shards left: {sorted(pending)} (from a script, call generate "
                                   "under 'if __name__ == \"__main__\":': each worker imports the script again)") from None
        except BaseException:
            # Interrupted (or a shard failed): stop now, keep what is finished.
            for process in list(getattr(pool, "_processes", {}).values()):  # no public kill on Python < 3.14
                with contextlib.suppress(Exception):
                    process.kill()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


# ------------------------------------------------------------------------------------------
# Ray


def _ray_render_shard(job: dict) -> dict:
    node_local_cache()  # before the first import of Dr.Jit in this worker
    return render_shard(job)


class _ShardActor:
    """One per GPU: imports Mitsuba once, after Ray has set CUDA_VISIBLE_DEVICES."""

    def __init__(self, variant: str):
        node_local_cache()
        import dopplertof as dt

        dt.set_variant(variant)

    def render(self, job: dict) -> dict:
        return render_shard(job)


def run_ray(jobs: list[dict], on_done, address: str | None = None, max_retries: int = 3, cpus_per_task: int = 1) -> None:
    """Render ``jobs`` on a Ray cluster (``address``; None: the running one, else a local one).

    Tasks (CPU): ``num_cpus=cpus_per_task``, each using that many Dr.Jit threads. With a
    ``cuda_*`` variant and GPUs in the cluster: one actor per GPU (``num_gpus=1``,
    restarted up to ``max_retries`` times), each kept busy with up to two shards.

    Parameters
    ----------
    jobs : list of dict
        One :func:`render_shard` job per shard.
    on_done : callable
        Called in the driver with each finished shard's :func:`render_shard` result.
    address : str or None, default None
        The Ray cluster.
    max_retries : int, default 3
        Retries of a task (or restarts of an actor) whose worker died.
    cpus_per_task : int, default 1
        CPUs (and Dr.Jit threads) of a CPU task.
    """
    ray = start_ray(address)
    variant = jobs[0]["variant"] if jobs else ""
    gpus = gpu_workers(ray, variant)
    refs: dict = {}
    try:
        if gpus > 0:
            actor_cls = ray.remote(num_gpus=1, max_restarts=max_retries, max_task_retries=max_retries)(_ShardActor)
            actors = [actor_cls.remote(variant) for _ in range(gpus)]
            queue = list(jobs)
            load = {i: 0 for i in range(len(actors))}

            def feed():
                for i, actor in enumerate(actors):
                    while queue and load[i] < 2:
                        refs[actor.render.remote(queue.pop(0))] = i
                        load[i] += 1

            feed()
            while refs:
                done, _ = ray.wait(list(refs), num_returns=1, timeout=1.0)
                for ref in done:
                    load[refs.pop(ref)] -= 1
                    on_done(ray.get(ref))
                feed()
        else:
            task = ray.remote(num_cpus=cpus_per_task, max_retries=max_retries)(_ray_render_shard)
            refs = {task.remote({**job, "threads": job.get("threads") or cpus_per_task}): job["index"] for job in jobs}
            while refs:
                done, _ = ray.wait(list(refs), num_returns=1, timeout=1.0)
                for ref in done:
                    refs.pop(ref)
                    on_done(ray.get(ref))
    except BaseException:
        for ref in refs:
            with contextlib.suppress(Exception):
                ray.cancel(ref, force=True)
        raise
