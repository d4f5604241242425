"""Rendering: the pass schedule, accumulation, checkpoints and the result object.

:func:`render` splits the film × spp into passes of at most ``lanes_per_pass`` lanes:
ranges of samples of every pixel, and tiles of pixels where the film is larger than a
pass, so the tracing kernel's memory is bounded whatever the film size. Each pass runs one
kernel (:func:`dopplertof.tracing.trace_pass`) and is added, in Float64 on the host, to
per-pixel sums:

* estimates (:data:`~dopplertof.outputs.OUTPUTS` of kind ``estimate``): the sum of the
  group means (a group of correlated samples counts once), and the sums and squares of
  the means of the pixel's independent *replicates* (:mod:`dopplertof.tracing.lanes`),
  whose spread gives the standard error;
* ground truth: sums of value × hit and of hits.

Capture schedules: cameras whose exposure windows differ
(:attr:`~dopplertof.settings.RenderSettings.windows`) are rendered window by window, the
schedule of passes once per window with that window's cameras, times and seed
(:func:`~dopplertof.tracing.lanes.window_seed`), each into sums of its own; cameras of one
window share paths, cameras of different windows are independent.

Random numbers depend on (seed, window, pixel, sample index) only, so the result does not
depend on the tiling or the pass split. A render stopped early (Ctrl-C, or ``stop()`` returning
True between passes) returns what the finished passes hold (``result.interrupted``);
with ``checkpoint=PATH`` its sums are saved there, and a later call with the same
settings continues from them to a result bit-identical to an uninterrupted render.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field

import numpy as np

from .outputs import BY_NAME, ESTIMATES, TRUTH
from .settings import DEFAULT_EXPOSURE_S, RenderSettings, scene_layer

__all__ = ["render", "RenderResult", "RenderSettings", "DEFAULT_EXPOSURE_S"]

MAX_COVARIANCE_CAMERAS = 8  # beyond, the per-pixel camera covariance is not kept (memory)


@dataclass
class RenderResult:
    """What :func:`render` returns.

    ``maps`` holds every output of :data:`dopplertof.outputs.OUTPUTS` and the standard
    errors of the estimates, each also an attribute: ``intensity`` and ``stderr``
    (H, W, 3) or (H, W) in mono, ``measurements`` and ``measurement_stderr``
    (n_cameras, H, W), ``depth``, ``velocity``, ``point_velocity`` (H, W; NaN where no
    sample hit), ``velocity_3d`` (H, W, 3), ``flow`` (H, W, 2), ``coverage`` (H, W) and
    ``instance_id`` (H, W, int32), and, for 2 to ``MAX_COVARIANCE_CAMERAS`` cameras,
    ``measurement_covariance`` (n_cameras, n_cameras, H, W): the covariance of the
    measurements' means (cameras of one exposure window share paths, so their errors
    correlate; cameras of different windows are independent: 0), which
    :func:`dopplertof.reconstruct.velocity` propagates. Images are float32.

    With a capture schedule (cameras in several exposure windows) the measurements are
    each camera's over its own window, in the order of ``cameras``; the intensity, its
    standard error, the ground truth, ``coverage`` and ``instance_id`` are those of the
    *reference* window, the first camera's (``settings.windows[0]``). ``cameras`` are the
    rendered cameras with their window's ``exposure_start`` filled in.
    """

    maps: dict
    settings: RenderSettings
    spp: int  # paths per pixel done (less than asked where interrupted)
    interrupted: bool = False
    info: dict = field(default_factory=dict)  # render time (s), passes, exposure windows [[start, T], ...] (s)

    def __getattr__(self, name):
        maps = self.__dict__.get("maps", {})
        if name in maps:
            return maps[name]
        raise AttributeError(f"RenderResult has no {name!r}")

    @property
    def cameras(self) -> list:
        """The cameras, each with its window's ``exposure_start`` (never None)."""
        return list(self.settings.scheduled_cameras)

    @property
    def seed(self) -> int:
        return self.settings.seed


# ----------------------------------------------------------------------------------------
# The pass schedule


@dataclass(frozen=True)
class Pass:
    first_sample: int
    samples: int
    pixel_start: int
    n_pixels: int


def schedule(n_pixels: int, spp: int, group: int, lanes_per_pass: int) -> list[Pass]:
    """Passes covering ``n_pixels`` × ``spp``: sample ranges (whole groups) outermost,
    tiles of pixels innermost, each pass at most ``lanes_per_pass`` lanes (at least one
    group of one pixel)."""
    samples = min(spp, max(group, (lanes_per_pass // n_pixels) // group * group))
    pixels = min(n_pixels, max(1, lanes_per_pass // samples))
    return [
        Pass(s0, min(samples, spp - s0), p0, min(pixels, n_pixels - p0)) for s0 in range(0, spp, samples) for p0 in range(0, n_pixels, pixels)
    ]


# ----------------------------------------------------------------------------------------
# Accumulation


class Accumulator:
    """Float64 per-pixel sums (module docstring); ``state`` is what a checkpoint holds."""

    def __init__(self, n_pixels, color_channels, n_cameras, n_groups, replicates):
        from .tracing.lanes import replicate_bounds

        self.bounds = replicate_bounds(n_groups, replicates)
        self.color_channels = color_channels
        c, n = color_channels + n_cameras, n_pixels
        self.state = {"passes_done": np.zeros(1, np.int64), "group_sum": np.zeros((c, n)), "groups_done": np.zeros(n, np.int32)}
        self.pairs = []
        if len(self.bounds) > 1:
            self.state.update(open_sum=np.zeros((c, n)), rep_sum=np.zeros((c, n)), rep_sq=np.zeros((c, n)), reps_closed=np.zeros(n, np.int32))
            if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS:  # cameras share paths: their errors correlate
                self.pairs = [(i, j) for i in range(n_cameras) for j in range(i + 1, n_cameras)]
                self.state["rep_cross"] = np.zeros((len(self.pairs), n))
        truth_channels = sum(o.channels for o in TRUTH)
        self.state.update(truth_sum=np.zeros((truth_channels, n)), hits=np.zeros(n, np.int32), samples=np.zeros(n, np.int32))
        self.state["instance_id"] = np.full(n, -1, np.int32)

    def add(self, p: Pass, out: dict, group: int, lanes_per_group: int):
        """Add one pass's per-lane outputs (Dr.Jit arrays), reduced in Float64 on the device.

        Group sums are gathers (Dr.Jit's block reductions over blocks of 2 lanes cost
        several times the reduction itself); replicates that lie wholly in the pass are
        reduced to per-pixel sums of their means, squares and camera products there too,
        so only per-pixel arrays reach the host.
        """
        import drjit as dr
        import mitsuba as mi

        lanes_per_pixel = p.samples // group * lanes_per_group
        intensity = out["intensity"]
        channels = [intensity[c] for c in range(self.color_channels)] + list(out["measurements"])
        truth = [x for o in TRUTH for x in _components(out[o.name], o.channels)] + [out["hits"]]
        dr.eval(channels, truth, out["instance_id"])  # one kernel traces every output (DESIGN §3.3)

        s = self.state
        pix = slice(p.pixel_start, p.pixel_start + p.n_pixels)
        g0, g1 = p.first_sample // group, (p.first_sample + p.samples) // group
        segments = [(max(a, g0), min(a + n, g1), a + n) for a, n in self.bounds if max(a, g0) < min(a + n, g1)]
        sizes = {start + n: n for start, n in self.bounds}
        n_groups = p.n_pixels * (g1 - g0)
        first = dr.arange(mi.UInt32, n_groups) * lanes_per_group

        def group_means(x):
            total = mi.Float64(dr.gather(mi.Float, x, first))
            for k in range(1, lanes_per_group):
                total += mi.Float64(dr.gather(mi.Float, x, first + k))
            return total * (1.0 / lanes_per_group)

        means = [group_means(x) for x in channels]
        truth_sums = [dr.block_sum(mi.Float64(x), lanes_per_pixel) for x in truth]
        equal = len({b - a for a, b, _ in segments}) == 1
        whole = "rep_sum" in s and equal and all(b - a == sizes[end] for a, b, end in segments)
        if whole:  # the usual pass: complete replicates of one size, reduced to per-pixel sums
            size, count = segments[0][1] - segments[0][0], len(segments)
            reps = [dr.block_sum(m, size) * (1.0 / size) if size > 1 else m for m in means]
            cams = reps[self.color_channels :]
            sums = [dr.block_sum(r, count) for r in reps]
            squares = [dr.block_sum(r * r, count) for r in reps]
            cross = [dr.block_sum(cams[i] * cams[j], count) for i, j in self.pairs]
            dr.eval(sums, squares, cross, truth_sums)
            rep_sums = np.stack([np.asarray(x.numpy()) for x in sums])
            s["group_sum"][:, pix] += rep_sums * size
            s["rep_sum"][:, pix] += rep_sums
            s["rep_sq"][:, pix] += np.stack([np.asarray(x.numpy()) for x in squares])
            for k, x in enumerate(cross):
                s["rep_cross"][k, pix] += np.asarray(x.numpy())
            s["reps_closed"][pix] += count
        else:
            dr.eval(means, truth_sums)
            host = np.stack([np.asarray(m.numpy()).reshape(p.n_pixels, g1 - g0) for m in means])  # (channels, pixels, groups)
            parts = np.stack([host[:, :, a - g0 : b - g0].sum(axis=2) for a, b, _ in segments], axis=2)
            s["group_sum"][:, pix] += parts.sum(axis=2)
            if "rep_sum" in s:
                for k, (a, b, end) in enumerate(segments):
                    s["open_sum"][:, pix] += parts[:, :, k]
                    if b == end:  # the replicate is complete: its mean is one independent unit
                        self._close(pix, (s["open_sum"][:, pix] / sizes[end])[:, :, None])
                        s["open_sum"][:, pix] = 0.0
        s["groups_done"][pix] += g1 - g0
        truth_sums = [np.asarray(x.numpy()) for x in truth_sums]
        s["truth_sum"][:, pix] += np.stack(truth_sums[:-1])
        s["hits"][pix] += np.rint(truth_sums[-1]).astype(np.int32)  # counts of hits: whole numbers
        s["samples"][pix] += p.samples
        if p.first_sample == 0:  # the label of the pixel's first sample
            labels = np.asarray(out["instance_id"].numpy()).reshape(p.n_pixels, lanes_per_pixel)[:, 0]
            s["instance_id"][pix] = labels.astype(np.int32)
        s["passes_done"][0] += 1

    def _close(self, pix, rep_means):
        """Add complete replicates: their means, (channels, pixels, replicates)."""
        s = self.state
        s["rep_sum"][:, pix] += rep_means.sum(axis=2)
        s["rep_sq"][:, pix] += np.einsum("cpr,cpr->cp", rep_means, rep_means)
        cams = rep_means[self.color_channels :]
        for j, (i1, i2) in enumerate(self.pairs):
            s["rep_cross"][j, pix] += np.einsum("pr,pr->p", cams[i1], cams[i2])
        s["reps_closed"][pix] += rep_means.shape[2]

    def finish(self, height, width, n_cameras) -> dict:
        """The result's maps (float32). Consumes the state: each Float64 sum is freed as soon
        as its maps are made, so the peak is the sums or the maps, not both."""
        s = self.state
        cc = self.color_channels
        n_pix = height * width

        def image(rows):  # float32 rows (k, pixels) -> (H, W) or (H, W, k)
            return rows[0].reshape(height, width) if len(rows) == 1 else np.stack(rows, axis=-1).reshape(height, width, len(rows))

        with np.errstate(invalid="ignore", divide="ignore"):
            groups = s.pop("groups_done")
            mean = [(row / groups).astype(np.float32) for row in s.pop("group_sum")]
            del groups
            if "rep_sum" in s:
                n = s.pop("reps_closed").astype(np.float64)
                rep_mean = s.pop("rep_sum") / n
                var = np.maximum(s.pop("rep_sq") / n - rep_mean * rep_mean, 0.0) * n / (n - 1)
                err = np.where(n >= 2, np.sqrt(var / n), np.nan).astype(np.float32)
                del var
            else:
                err = np.full((len(mean), n_pix), np.nan, np.float32)
            covariance = None
            if self.pairs:  # covariance of the cameras' means, from the same replicates
                covariance = np.zeros((n_cameras, n_cameras, n_pix), np.float32)
                for i in range(n_cameras):
                    covariance[i, i] = err[cc + i].astype(np.float64) ** 2
                for k, (i, j) in enumerate(self.pairs):
                    cross = (s["rep_cross"][k] / n - rep_mean[cc + i] * rep_mean[cc + j]) * n / (n - 1) / n
                    covariance[i, j] = covariance[j, i] = np.where(n >= 2, cross, np.nan)
                del s["rep_cross"]
            hits = s.pop("hits")
            truth_rows = [(row / hits).astype(np.float32) for row in s.pop("truth_sum")]
            coverage = (hits / s.pop("samples")).astype(np.float32)
        maps = {}
        for o in ESTIMATES:
            if o.channels == "color":
                maps[o.name], maps[o.stderr_name] = image(mean[:cc]), image(list(err[:cc]))
            else:
                maps[o.name] = np.stack(mean[cc:]).reshape(n_cameras, height, width) if n_cameras else np.zeros((0, height, width), np.float32)
                maps[o.stderr_name] = err[cc:].reshape(n_cameras, height, width)
        k = 0
        for o in TRUTH:
            maps[o.name] = image(truth_rows[k : k + o.channels])
            k += o.channels
        maps["coverage"] = coverage.reshape(height, width)
        maps["instance_id"] = s["instance_id"].reshape(height, width)
        if covariance is not None:
            maps["measurement_covariance"] = covariance.reshape(n_cameras, n_cameras, height, width)
        return maps


def _components(value, channels):
    return [value] if channels == 1 else [value[i] for i in range(channels)]


def host_bytes_per_pixel(n_cameras: int) -> int:
    """Host memory of the film's Float64 sums and the float32 result, per pixel (bytes)."""
    estimates = 3 + n_cameras
    truth = sum(o.channels for o in TRUTH)
    pairs = n_cameras * (n_cameras - 1) // 2 if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS else 0
    return 8 * (4 * estimates + truth + pairs) + 4 * (2 * estimates + truth + 6 + n_cameras * n_cameras)


def check_film_memory(width: int, height: int, n_cameras: int, n_windows: int = 1) -> None:
    """ValueError for an empty film, or one whose buffers need more than the available memory
    (each exposure window of a capture schedule keeps sums of its own)."""
    if width < 1 or height < 1:
        raise ValueError(f"the film must be at least 1x1 pixels, got {width}x{height}")
    need = width * height * (host_bytes_per_pixel(n_cameras) + (n_windows - 1) * host_bytes_per_pixel(0))
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            available = next(int(line.split()[1]) * 1024 for line in f if line.startswith("MemAvailable:"))
    except (OSError, StopIteration, ValueError):
        return  # not Linux: no check
    if need > available:
        raise ValueError(f"a {width}x{height} film with {n_cameras} camera(s) needs about {need / 2**30:.1f} GiB of memory for its buffers; {available / 2**30:.1f} GiB are available")


# ----------------------------------------------------------------------------------------
# Checkpoints


def fingerprint(scene, settings: RenderSettings) -> str:
    """What a checkpoint must match to be continued: the settings, the film and the scene."""
    text = json.dumps({"settings": settings.as_dict(), "film": list(scene.resolution), "scene": scene.source, "bodies": len(scene.bodies)}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _checkpoint_names(accs: list) -> list[tuple[str, Accumulator, str]]:
    """(name in the file, accumulator, name in its state) of every array: a single window's
    under their own names, a schedule's prefixed with their window (``w1.group_sum``)."""
    prefix = (lambda k: "") if len(accs) == 1 else (lambda k: f"w{k}.")
    return [(prefix(k) + name, acc, name) for k, acc in enumerate(accs) for name in acc.state]


def _load_checkpoint(path, accs: list, key: str):
    with np.load(path, allow_pickle=False) as data:
        if str(data["fingerprint"]) != key:
            raise ValueError(f"{path}: the checkpoint belongs to a render with other settings or another scene; remove it or render into another folder")
        for stored, acc, name in _checkpoint_names(accs):
            if stored not in data or data[stored].shape != acc.state[name].shape:
                raise ValueError(f"{path}: the checkpoint is damaged ({stored!r} missing or of another shape)")
            acc.state[name] = data[stored].copy()


def save_checkpoint(path, accs: list, key: str):
    """Write the accumulators (one per exposure window) atomically (temporary name, then rename)."""
    from .io import atomic_path

    arrays = {stored: acc.state[name] for stored, acc, name in _checkpoint_names(accs)}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, fingerprint=np.array(key), **arrays)


# ----------------------------------------------------------------------------------------
# Capture schedules


def _merge_windows(finished: list[dict], windows, n_cameras: int, shape: tuple[int, int]) -> dict:
    """One result's maps from the windows' (:meth:`Accumulator.finish` of each): every
    camera's measurement and error from its window, in the cameras' order; everything else
    from the reference window; the covariance block-diagonal (windows are independent)."""
    if len(finished) == 1:
        return finished[0]
    maps = dict(finished[0])
    for o in ESTIMATES:
        if o.channels != "cameras":
            continue
        for name in (o.name, o.stderr_name):
            merged = np.empty((n_cameras, *shape), np.float32)
            for window, window_maps in zip(windows, finished):
                merged[list(window.indices)] = window_maps[name]
            maps[name] = merged
    maps.pop("measurement_covariance", None)
    errors = maps[BY_NAME["measurements"].stderr_name]
    if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS and np.isfinite(errors).any():
        covariance = np.zeros((n_cameras, n_cameras, *shape), np.float32)
        for i in range(n_cameras):
            covariance[i, i] = errors[i].astype(np.float64) ** 2
        for window, window_maps in zip(windows, finished):
            if "measurement_covariance" in window_maps:
                idx = np.array(window.indices)
                covariance[idx[:, None], idx[None, :]] = window_maps["measurement_covariance"]
        maps["measurement_covariance"] = covariance
    return maps


# ----------------------------------------------------------------------------------------
# render()


def render(scene, cameras=None, *, settings: RenderSettings | None = None, progress=False, checkpoint=None, stop=None, **overrides) -> RenderResult:
    """Render the intensity, ground truth and D-ToF measurements of a dynamic scene.

    Parameters
    ----------
    scene : DynamicScene, from :func:`dopplertof.load_scene` (a file or dict) or
        :func:`dopplertof.scenes.build`.
    cameras : list of :class:`~dopplertof.Camera`, optional. Replaces the scene's. Cameras
        with different exposure windows (``exposure_start``, ``exposure``) form a capture
        schedule: each window is traced on its own, with its own random streams
        (:class:`RenderResult` says which maps refer to which window).
    settings : :class:`RenderSettings`, optional. The settings to start from; by default
        the scene's own (:func:`dopplertof.settings.scene_layer`: its ``<integrator>``
        cameras and settings, its sampler's ``sample_count``, its sensor's shutter).
    **overrides
        Any :class:`RenderSettings` field (``spp``, ``seed``, ``max_depth``,
        ``time_sampling``, ``correlation``, …), applied on top.
    progress : bool. Show a progress bar.
    checkpoint : path, optional. Continue from this checkpoint if it exists (same
        settings, else ValueError); save the sums there if the render stops early.
    stop : callable, optional. Checked after every pass; True stops the render there.

    Returns
    -------
    RenderResult
    """
    import time

    from .backend import ensure_variant
    from .tracing import trace_pass
    from .tracing.lanes import LaneSetup, window_seed
    from .tracing.materials import MaterialTables

    ensure_variant()
    if not hasattr(scene, "static"):
        raise ValueError(f"render() takes a scene from dopplertof.load_scene(...) or dopplertof.scenes.build(...), got {type(scene).__name__}")
    if cameras is not None:
        overrides["cameras"] = cameras
    base = scene_layer(scene) if settings is None else {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    settings = RenderSettings.build(base, overrides)

    width, height = scene.resolution
    n_pixels = width * height
    windows = settings.windows
    check_film_memory(width, height, len(settings.cameras), len(windows))
    group = settings.group_size
    tables = MaterialTables.of(scene)
    color_channels = 3 if _is_rgb() else 1
    n_groups = max(settings.spp // group, 1)
    accs = [Accumulator(n_pixels, color_channels, len(w.cameras), n_groups, settings.replicates) for w in windows]
    key = fingerprint(scene, settings)
    if checkpoint is not None and os.path.exists(checkpoint):
        _load_checkpoint(checkpoint, accs, key)
    passes = schedule(n_pixels, settings.spp, group, settings.lanes_per_pass)
    lanes_per_group = 1 if settings.paired else group

    def passes_done():
        return [int(acc.state["passes_done"][0]) for acc in accs]

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(passes) * len(windows), initial=sum(passes_done()), unit="pass", desc="render", leave=False)
    interrupted = False
    start = time.perf_counter()
    try:
        for index, (window, acc, done) in enumerate(zip(windows, accs, passes_done())):
            if interrupted:
                break
            if done == len(passes):
                continue
            # the window's bodies' bounds, cameras and random streams
            scene.set_time_window(window.start_s, window.start_s + window.exposure_s)
            window_settings = dataclasses.replace(settings, cameras=window.cameras, exposure_start=window.start_s)
            seed = window_seed(settings.seed, index)
            for p in passes[done:]:
                if stop is not None and stop():
                    interrupted = True
                    break
                setup = LaneSetup(
                    width=width, height=height, pixel_start=p.pixel_start, n_pixels=p.n_pixels, first_sample=p.first_sample,
                    samples=p.samples, spp_total=settings.spp, n_times=group, replicates=settings.replicates,
                    exposure_start_s=window.start_s, exposure_s=window.exposure_s, seed=seed,
                )  # fmt: skip
                acc.add(p, trace_pass(scene, window_settings, setup, tables), group, lanes_per_group)
                if bar is not None:
                    bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if bar is not None:
            bar.close()
    done = sum(passes_done())
    if done == 0:
        raise KeyboardInterrupt("render interrupted before the first pass finished")
    if checkpoint is not None:
        if interrupted:
            save_checkpoint(checkpoint, accs, key)
        elif os.path.exists(checkpoint):
            os.remove(checkpoint)
    spp_done = min(int(acc.state["samples"].min()) for acc in accs)
    info = {"render_seconds": time.perf_counter() - start, "passes": len(passes) * len(windows), "passes_done": done,
            "windows": [[w.start_s, w.exposure_s] for w in windows]}  # fmt: skip
    finished = [acc.finish(height, width, len(w.cameras)) for w, acc in zip(windows, accs)]
    maps = _merge_windows(finished, windows, len(settings.cameras), (height, width))
    return RenderResult(maps=maps, settings=settings, spp=spp_done, interrupted=interrupted, info=info)


def _is_rgb():
    import mitsuba as mi

    return mi.is_rgb

