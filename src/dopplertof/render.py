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

Each pass is traced and reduced to per-pixel increments where its scene is
(:class:`PassTracer`, :meth:`Reducer.reduce`) and added here (:meth:`Accumulator.apply`):
with ``executor="ray"`` the passes are traced on Ray workers (:mod:`dopplertof.render_ray`)
and added in the same order, so the result is the same, bit for bit.
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
    info: dict = field(default_factory=dict)  # render time (s), passes, executor, exposure windows [[start, T], ...] (s)

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


class Reducer:
    """How a render's passes reduce to per-pixel increments of the sums (module docstring).

    The half of the accumulation that runs where the pass was traced (this process, or a
    Ray worker: :mod:`dopplertof.render_ray`); :class:`Accumulator` adds the increments.

    ===============  =====  ==========================================================
    color_channels   int    3 (RGB) or 1 (mono)
    n_cameras        int    D-ToF cameras
    spp              int    paths per pixel
    group            int    correlated samples per group (``settings.group_size``)
    lanes_per_group  int    lanes a group takes (1 where primal and partner share a lane)
    replicates       int    independent replicates per pixel (``settings.replicates``)
    ===============  =====  ==========================================================
    """

    def __init__(self, color_channels, n_cameras, spp, group, lanes_per_group, replicates):
        from .tracing.lanes import replicate_bounds

        self.color_channels, self.n_cameras = color_channels, n_cameras
        self.group, self.lanes_per_group = group, lanes_per_group
        self.bounds = replicate_bounds(max(spp // group, 1), replicates)
        self.sizes = {start + n: n for start, n in self.bounds}  # replicate end -> its groups
        self.replicated = len(self.bounds) > 1
        self.pairs = []
        if self.replicated and 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS:  # cameras share paths: their errors correlate
            self.pairs = [(i, j) for i in range(n_cameras) for j in range(i + 1, n_cameras)]

    @staticmethod
    def layout(settings: RenderSettings) -> tuple:
        """The arguments above of a render with ``settings`` (in the active variant)."""
        group = settings.group_size
        return 3 if _is_rgb() else 1, len(settings.cameras), settings.spp, group, 1 if settings.paired else group, settings.replicates

    def groups(self, p: Pass) -> tuple[int, int]:
        """The pass's groups of every pixel: [g0, g1)."""
        return p.first_sample // self.group, (p.first_sample + p.samples) // self.group

    def segments(self, p: Pass) -> list[tuple[int, int, int]]:
        """The pass's groups split at replicate ends: (first group, end group, replicate end)."""
        g0, g1 = self.groups(p)
        return [(max(a, g0), min(a + n, g1), a + n) for a, n in self.bounds if max(a, g0) < min(a + n, g1)]

    def reduce(self, p: Pass, out: dict) -> dict:
        """One pass's per-lane outputs (Dr.Jit arrays), reduced in Float64 on the device to
        per-pixel host increments (numpy), which :meth:`Accumulator.apply` adds.

        Group sums are gathers (Dr.Jit's block reductions over blocks of 2 lanes cost
        several times the reduction itself); replicates that lie wholly in the pass are
        reduced to per-pixel sums of their means, squares and camera products there too,
        so only per-pixel arrays reach the host.
        """
        import drjit as dr
        import mitsuba as mi

        group, lanes_per_group = self.group, self.lanes_per_group
        lanes_per_pixel = p.samples // group * lanes_per_group
        intensity = out["intensity"]
        channels = [intensity[c] for c in range(self.color_channels)] + list(out["measurements"])
        truth = [x for o in TRUTH for x in _components(out[o.name], o.channels)] + [out["hits"]]
        dr.eval(channels, truth, out["instance_id"])  # one kernel traces every output (DESIGN §3.3)

        g0, g1 = self.groups(p)
        segments = self.segments(p)
        n_groups = p.n_pixels * (g1 - g0)
        first = dr.arange(mi.UInt32, n_groups) * lanes_per_group

        def group_means(x):
            total = mi.Float64(dr.gather(mi.Float, x, first))
            for k in range(1, lanes_per_group):
                total += mi.Float64(dr.gather(mi.Float, x, first + k))
            return total * (1.0 / lanes_per_group)

        means = [group_means(x) for x in channels]
        truth_sums = [dr.block_sum(mi.Float64(x), lanes_per_pixel) for x in truth]
        inc = {}
        if self.whole(segments):  # the usual pass: complete replicates of one size, reduced to per-pixel sums
            size, count = segments[0][1] - segments[0][0], len(segments)
            reps = [dr.block_sum(m, size) * (1.0 / size) if size > 1 else m for m in means]
            cams = reps[self.color_channels :]
            sums = [dr.block_sum(r, count) for r in reps]
            squares = [dr.block_sum(r * r, count) for r in reps]
            cross = [dr.block_sum(cams[i] * cams[j], count) for i, j in self.pairs]
            dr.eval(sums, squares, cross, truth_sums)
            inc["rep_sum"] = np.stack([np.asarray(x.numpy()) for x in sums])
            inc["rep_sq"] = np.stack([np.asarray(x.numpy()) for x in squares])
            inc["rep_cross"] = [np.asarray(x.numpy()) for x in cross]
        else:
            dr.eval(means, truth_sums)
            host = np.stack([np.asarray(m.numpy()).reshape(p.n_pixels, g1 - g0) for m in means])  # (channels, pixels, groups)
            inc["parts"] = np.stack([host[:, :, a - g0 : b - g0].sum(axis=2) for a, b, _ in segments], axis=2)
        truth_sums = [np.asarray(x.numpy()) for x in truth_sums]
        inc["truth_sum"] = np.stack(truth_sums[:-1])
        inc["hits"] = np.rint(truth_sums[-1]).astype(np.int32)  # counts of hits: whole numbers
        if p.first_sample == 0:  # the label of the pixel's first sample
            inc["instance_id"] = np.asarray(out["instance_id"].numpy()).reshape(p.n_pixels, lanes_per_pixel)[:, 0].astype(np.int32)
        return inc

    def whole(self, segments) -> bool:
        """Whether a pass's segments are complete replicates of one size."""
        equal = len({b - a for a, b, _ in segments}) == 1
        return self.replicated and equal and all(b - a == self.sizes[end] for a, b, end in segments)


class Accumulator(Reducer):
    """Float64 per-pixel sums (module docstring) of ``n_pixels`` pixels; ``state`` is what a
    checkpoint holds. A pass is added by ``apply(p, reduce(p, out))``, wherever ``reduce``
    ran: the same numpy operations in pass order, so the sums are bit-identical.
    """

    def __init__(self, n_pixels, color_channels, n_cameras, spp, group, lanes_per_group, replicates):
        super().__init__(color_channels, n_cameras, spp, group, lanes_per_group, replicates)
        c, n = color_channels + n_cameras, n_pixels
        self.state = {"passes_done": np.zeros(1, np.int64), "group_sum": np.zeros((c, n)), "groups_done": np.zeros(n, np.int32)}
        if self.replicated:
            self.state.update(open_sum=np.zeros((c, n)), rep_sum=np.zeros((c, n)), rep_sq=np.zeros((c, n)), reps_closed=np.zeros(n, np.int32))
            if self.pairs:
                self.state["rep_cross"] = np.zeros((len(self.pairs), n))
        truth_channels = sum(o.channels for o in TRUTH)
        self.state.update(truth_sum=np.zeros((truth_channels, n)), hits=np.zeros(n, np.int32), samples=np.zeros(n, np.int32))
        self.state["instance_id"] = np.full(n, -1, np.int32)

    def apply(self, p: Pass, inc: dict):
        """Add one pass's increments (from :meth:`Reducer.reduce`) to the sums."""
        s = self.state
        pix = slice(p.pixel_start, p.pixel_start + p.n_pixels)
        if "rep_sum" in inc:
            segments = self.segments(p)
            size, count = segments[0][1] - segments[0][0], len(segments)
            s["group_sum"][:, pix] += inc["rep_sum"] * size
            s["rep_sum"][:, pix] += inc["rep_sum"]
            s["rep_sq"][:, pix] += inc["rep_sq"]
            for k, x in enumerate(inc["rep_cross"]):
                s["rep_cross"][k, pix] += x
            s["reps_closed"][pix] += count
        else:
            parts = inc["parts"]
            s["group_sum"][:, pix] += parts.sum(axis=2)
            if self.replicated:
                for k, (a, b, end) in enumerate(self.segments(p)):
                    s["open_sum"][:, pix] += parts[:, :, k]
                    if b == end:  # the replicate is complete: its mean is one independent unit
                        self._close(pix, (s["open_sum"][:, pix] / self.sizes[end])[:, :, None])
                        s["open_sum"][:, pix] = 0.0
        g0, g1 = self.groups(p)
        s["groups_done"][pix] += g1 - g0
        s["truth_sum"][:, pix] += inc["truth_sum"]
        s["hits"][pix] += inc["hits"]
        s["samples"][pix] += p.samples
        if "instance_id" in inc:
            s["instance_id"][pix] = inc["instance_id"]
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
    text = json.dumps({"settings": settings.as_dict(), "film": list(scene.resolution), "scene": scene.source, "motions": len(scene.motions())}, sort_keys=True, default=str)
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

EXECUTORS = ("local", "ray")


class PassTracer:
    """Traces the passes of one render where its scene is (this process, or a Ray worker:
    :mod:`dopplertof.render_ray`); ``tracer(p)`` is pass ``p``'s increments
    (:meth:`Reducer.reduce`). Fits the scene's time window to the exposure.

    ========  ================  ============================================
    scene     DynamicScene      the scene, its film the render's
    settings  RenderSettings    the render's settings (built, not overrides)
    ========  ================  ============================================
    """

    def __init__(self, scene, settings: RenderSettings):
        from .tracing.materials import MaterialTables

        scene.set_time_window(settings.exposure_start, settings.exposure_start + settings.exposure_s)
        self.scene, self.settings = scene, settings
        self.tables = MaterialTables.of(scene)
        self.reducer = Reducer(*Reducer.layout(settings))

    def __call__(self, p: Pass) -> dict:
        from .tracing import trace_pass
        from .tracing.lanes import LaneSetup

        s = self.settings
        width, height = self.scene.resolution
        setup = LaneSetup(
            width=width, height=height, pixel_start=p.pixel_start, n_pixels=p.n_pixels, first_sample=p.first_sample,
            samples=p.samples, spp_total=s.spp, n_times=s.group_size, replicates=s.replicates,
            exposure_start_s=float(s.exposure_start), exposure_s=float(s.exposure_s), seed=s.seed,
        )  # fmt: skip
        return self.reducer.reduce(p, trace_pass(self.scene, s, setup, self.tables))


def _traced_locally(scene, settings, passes):
    tracer = PassTracer(scene, settings)
    for p in passes:
        yield tracer(p)


def render(
    scene, cameras=None, *, settings: RenderSettings | None = None, progress=False, checkpoint=None, stop=None,
    executor="local", address=None, workers=None, **overrides,
) -> RenderResult:  # fmt: skip
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
    executor : ``"local"`` (default) or ``"ray"``. ``"ray"`` traces the passes on Ray
        workers (:mod:`dopplertof.render_ray`), each rebuilding the scene from its file or
        built-in name (a scene loaded from a dict cannot be: ValueError), and adds them here
        in pass order: the result is bit-identical to the local render's.
    address : str, optional. With ``"ray"``: the cluster (``ray.init(address=…)``); default
        the running Ray, else a new local one.
    workers : int, optional. With ``"ray"``: workers, each with the cluster's CPUs / workers
        Dr.Jit threads (default one per CPU; with a ``cuda_*`` variant, one per GPU).

    Returns
    -------
    RenderResult
    """
    import time

    from .backend import ensure_variant
    from .tracing.lanes import window_seed

    ensure_variant()
    if not hasattr(scene, "static"):
        raise ValueError(f"render() takes a scene from dopplertof.load_scene(...) or dopplertof.scenes.build(...), got {type(scene).__name__}")
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if executor != "ray" and (address is not None or workers is not None):
        raise ValueError("address and workers apply to executor='ray'")
    if cameras is not None:
        overrides["cameras"] = cameras
    base = scene_layer(scene) if settings is None else {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    settings = RenderSettings.build(base, overrides)

    width, height = scene.resolution
    n_pixels = width * height
    windows = settings.windows
    check_film_memory(width, height, len(settings.cameras), len(windows))
    # Each window traces its cameras over its own times, with its own random streams.
    window_settings = [
        dataclasses.replace(settings, cameras=w.cameras, exposure_start=w.start_s, seed=window_seed(settings.seed, k)) for k, w in enumerate(windows)
    ]  # fmt: skip
    accs = [Accumulator(n_pixels, *Reducer.layout(ws)) for ws in window_settings]
    key = fingerprint(scene, settings)
    if checkpoint is not None and os.path.exists(checkpoint):
        _load_checkpoint(checkpoint, accs, key)
    passes = schedule(n_pixels, settings.spp, settings.group_size, settings.lanes_per_pass)

    def passes_done():
        return [int(acc.state["passes_done"][0]) for acc in accs]

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(passes) * len(windows), initial=sum(passes_done()), unit="pass", desc="render", leave=False)
    interrupted = False
    start = time.perf_counter()
    try:
        for index, (acc, done) in enumerate(zip(accs, passes_done())):
            if interrupted:
                break
            if done == len(passes):
                continue
            if executor == "ray":
                from .render_ray import traced_on_ray

                traced = traced_on_ray(scene, window_settings[index], passes[done:], address=address, workers=workers)
            else:
                traced = _traced_locally(scene, window_settings[index], passes[done:])
            try:
                for p in passes[done:]:
                    if stop is not None and stop():
                        interrupted = True
                        break
                    acc.apply(p, next(traced))
                    if bar is not None:
                        bar.update(1)
            finally:
                traced.close()  # a Ray render's workers stop here
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
            "executor": executor, "windows": [[w.start_s, w.exposure_s] for w in windows]}  # fmt: skip
    finished = [acc.finish(height, width, len(w.cameras)) for w, acc in zip(windows, accs)]
    maps = _merge_windows(finished, windows, len(settings.cameras), (height, width))
    return RenderResult(maps=maps, settings=settings, spp=spp_done, interrupted=interrupted, info=info)


def _is_rgb():
    import mitsuba as mi

    return mi.is_rgb

