"""Generate a dataset: plan the shards, skip the finished ones, render the rest, keep the manifest.

See :func:`generate`. The layout on disk is in :mod:`dopplertof.dataset.shards`, the fields in
:mod:`dopplertof.dataset.schema`, the knobs in :mod:`dopplertof.dataset.config`.
"""

from __future__ import annotations

import os
import time

from ..backend import Stopped, signals_as_interrupt  # noqa: F401  (Stopped: what generate raises)
from ..differences import differences
from ..folder import check_writable, refuse_other_output
from . import config as config_mod
from . import execute, schema, shards

DEFAULT_SHARD_SIZE = 16
RGB_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")
# sensor_models: the sensors' own descriptions, so that a sensor file edited between runs is not mixed into one dataset
_IDENTITY_KEYS = ("format", "format_version", "samples", "seed", "shard_size", "variant", "versions", "config", "fields", "sensor_models")


def _positive_int(name, value, minimum=1):
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{name} must be an integer ≥ {minimum}, got {value!r}")
    return value


def parse_shard_range(text: str, total: int) -> range:
    """Shard indices of ``"a:b"`` (b excluded; either end may be empty), within ``total``.

    Parameters
    ----------
    text : str
        ``"a:b"``.
    total : int
        Shards of the dataset.

    Returns
    -------
    range

    Raises
    ------
    ValueError
        Not ``a:b``, or outside ``0:total``.
    """
    a, sep, b = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        lo = int(a) if a.strip() else 0
        hi = int(b) if b.strip() else total
    except ValueError:
        raise ValueError(f"shard range must be 'a:b' (shard indices, b excluded), got {text!r}") from None
    if not 0 <= lo < hi <= total:
        raise ValueError(f"shard range {text!r} is outside the dataset's {total} shards (0:{total})")
    return range(lo, hi)


def _resolve_config(config, resolution, spp) -> dict:
    overrides = {}
    if resolution is not None:
        overrides.setdefault("render", {})["resolution"] = resolution
    if spp is not None:
        overrides.setdefault("render", {})["spp"] = spp
    if config is None or isinstance(config, (str, os.PathLike)):
        return config_mod.load_config(config, overrides)
    if isinstance(config, dict):
        merged = {sec: dict(values) if isinstance(values, dict) else values for sec, values in config.items()}
        for sec, values in overrides.items():
            merged.setdefault(sec, {}).update(values)
        return config_mod.validate(merged)
    raise ValueError(f"config must be a TOML file path, a dict or None, got {type(config).__name__}")


def _variant(variant) -> str:
    from ..backend import ensure_variant, set_variant

    name = set_variant(variant) if variant else ensure_variant()
    if name not in RGB_VARIANTS:
        raise ValueError(f"datasets are rendered with an RGB variant ({', '.join(RGB_VARIANTS)}), not {name!r}")
    return name


def header_for(cfg: dict, samples: int, seed: int, shard_size: int, variant: str) -> dict:
    """The manifest's fixed part: identity, schema, record documentation.

    Parameters
    ----------
    cfg : dict
        The validated configuration.
    samples : int
        Samples of the dataset.
    seed : int
        The dataset's seed.
    shard_size : int
        Samples per shard.
    variant : str
        The Mitsuba variant rendered with.

    Returns
    -------
    dict
    """
    from .sample import versions

    from ..sensors.files import load_sensor, sensor_toml

    res = cfg["render"]["resolution"]
    n_cameras = len(cfg["camera"]["heterodyne"])
    models = {name: load_sensor(name) for name in cfg["sensor"]["model"]}
    fields, missing = schema.available_fields(n_cameras, sensor_model=bool(models))
    layouts = {(len(s.frames), s.taps) for s in models.values()}
    frames, taps = layouts.pop() if len(layouts) == 1 else (None, None)
    # only with sensors: the manifest of a dataset without one keeps its bytes
    described = {"sensor_models": {name: sensor_toml(s) for name, s in models.items()}} if models else {}
    return {
        "format": schema.FORMAT_NAME,
        "format_version": schema.FORMAT_VERSION,
        "samples": samples,
        "seed": seed,
        "shard_size": shard_size,
        "shard_count": len(shards.plan(samples, shard_size)),
        "variant": variant,
        "versions": versions(variant),
        "config": cfg,
        "fields": fields,
        "missing_fields": missing,
        "schema": schema.schema_table(fields, n_cameras, res, res, frames, taps),
        "record": schema.RECORD,
        **described,
    }


def generate(
    output,
    samples: int,
    seed: int = 0,
    config=None,
    *,
    resolution: int | None = None,
    spp: int | None = None,
    shard_size: int = DEFAULT_SHARD_SIZE,
    workers: int | str = 1,
    ray: bool = False,
    address: str | None = None,
    shards_range: str | None = None,
    variant: str | None = None,
    max_retries: int = 3,
    progress: bool = False,
) -> dict:
    """Generate (or complete) the dataset of ``samples`` samples with seed ``seed`` in ``output``.

    Sample i depends only on (seed, i) and the configuration, so the files are byte-identical
    whatever the number of workers, their order, the executor, or how often the run was
    interrupted and resumed. Shards already complete in ``output`` (their sha256 checked) are
    skipped; missing, incomplete or corrupt ones are (re)generated.

    Parameters
    ----------
    output : str or path
        Dataset folder (created if needed).
    samples : int
        Number of samples (≥ 1).
    seed : int
        Dataset seed S (≥ 0).
    config : str, path, dict or None
        A TOML file, a nested dict of overrides, or None for the defaults
        (:mod:`dopplertof.dataset.config`).
    resolution, spp : int, optional
        Override ``render.resolution`` and ``render.spp``.
    shard_size : int
        Samples per shard (default 16).
    workers : int or "auto"
        Local worker processes (spawned; default 1: this process). ``"auto"``: one per CPU,
        at most one per shard to render and as many as the available memory holds (1 GiB
        and 2 KiB a pixel each), 1 with a ``cuda_*`` variant
        (:func:`~dopplertof.dataset.execute.auto_workers`; the command's default). More than
        one spawns processes that import the calling script again: call ``generate`` under
        ``if __name__ == "__main__":`` (hence the default of 1 here).
    ray : bool
        Render on Ray (one task per shard; one actor per GPU with a ``cuda_*`` variant); a
        number of ``workers`` is then refused.
    address : str, optional
        Ray cluster address (``ray.init(address=…)``); default: the running Ray, else a local one.
    shards_range : str, optional
        ``"a:b"``: only shards a … b−1 (e.g. one Slurm array task); the rest are left alone.
    variant : str, optional
        Mitsuba variant (``llvm_ad_rgb`` or ``cuda_ad_rgb``); default dopplertof's.
    max_retries : int
        Retries of a shard whose worker died.
    progress : bool
        Show a progress bar (samples).

    Returns
    -------
    dict
        ``manifest`` (the dataset.json content), ``generated`` and ``skipped`` (shard
        names), ``seconds`` (wall time per phase summed over the generated shards: record,
        scene, render, sensor, write, total), ``wall_s`` and ``executor`` (what rendered
        the shards: ``"this process"``, ``"N worker processes"``, ``"Ray"``, or None when
        none was left to render).

    Raises
    ------
    ValueError
        Bad arguments or configuration (naming the value), an unwritable folder, or a folder
        holding another dataset (other seed, size, configuration or versions).
    KeyboardInterrupt
        On SIGINT, or SIGTERM or SIGHUP (a :class:`Stopped` with the signal's number),
        after recording the finished shards.
    """
    started = time.perf_counter()
    samples = _positive_int("samples", samples)
    seed = _positive_int("seed", seed, minimum=0)
    if seed >= 1 << 63:
        raise ValueError(f"seed must be < 2**63, got {seed!r}")
    shard_size = _positive_int("shard_size", shard_size)
    if workers != execute.AUTO:
        try:
            _positive_int("workers", workers)
        except ValueError:
            raise ValueError(f"workers must be an integer ≥ 1 or {execute.AUTO!r}, got {workers!r}") from None
    if ray and workers not in (1, execute.AUTO):
        raise ValueError(f"workers={workers} counts local processes; with Ray each shard is a task of its own (give one or the other)")
    max_retries = _positive_int("max_retries", max_retries, minimum=0)
    cfg = _resolve_config(config, resolution, spp)
    layout = shards.plan(samples, shard_size)
    wanted = parse_shard_range(shards_range, len(layout)) if shards_range is not None else range(len(layout))
    output = os.fspath(output)
    refuse_other_output(output, "dataset")
    check_writable(output)
    name = _variant(variant)
    header = header_for(cfg, samples, seed, shard_size, name)

    with shards.manifest_lock(output):
        existing = shards.read_manifest(output)
        if existing is not None:
            differ = [k for k in _IDENTITY_KEYS if existing.get(k) != header.get(k)]
            if differ:
                raise ValueError(f"{output} holds another dataset (it differs in {', '.join(differences({k: existing.get(k) for k in differ}, {k: header.get(k) for k in differ}))}); use another folder")
        shards.rebuild_manifest(output, header, layout)

    todo, skipped = [], []
    for index in wanted:
        _, first, count = layout[index]
        (skipped if shards.shard_status(output, index, count) == "ok" else todo).append(index)
    shards.remove_stale_temporaries(output, todo)
    fault = os.environ.get(execute.FAULT_ENV)
    jobs = [{"folder": os.path.abspath(output), "index": i, "first": layout[i][1], "count": layout[i][2], "config": cfg, "seed": seed,
             "variant": name, "fields": header["fields"], "fault": fault} for i in todo]

    seconds: dict = {}
    generated = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=sum(j["count"] for j in jobs), unit="sample", desc="dataset", dynamic_ncols=True)

    def on_done(result):
        record = result["record"]
        with shards.manifest_lock(output):
            shards.rebuild_manifest(output, header, layout)
        generated.append(record["name"])
        for k, v in result.get("seconds", {}).items():
            seconds[k] = seconds.get(k, 0.0) + v
        if bar is not None:
            bar.update(record["count"])

    executor = None
    try:
        with signals_as_interrupt():
            if jobs and ray:
                executor = "Ray"
                execute.run_ray(jobs, on_done, address=address, max_retries=max_retries)
            elif jobs:
                local = execute.auto_workers(len(jobs), name, cfg["render"]["resolution"]) if workers == execute.AUTO else workers
                executor = "this process" if local == 1 else f"{local} worker processes"
                execute.run_local(jobs, local, on_done, max_retries=max_retries)
    finally:
        if bar is not None:
            bar.close()
        shards.remove_stale_temporaries(output, todo)
        with shards.manifest_lock(output):
            manifest = shards.rebuild_manifest(output, header, layout)
    return {"manifest": manifest, "generated": sorted(generated), "skipped": [shards.shard_name(i) for i in skipped], "seconds": seconds,
            "wall_s": time.perf_counter() - started, "executor": executor}
