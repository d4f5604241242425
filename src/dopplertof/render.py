"""Rendering: passes, seeds, accumulation, progress and the result object.

:func:`render` splits ``spp`` into passes of about ``lanes_per_pass`` lanes, runs one
kernel per pass (:func:`dopplertof.integrator.trace`), and accumulates per pixel, in
Float64 on the host, Σx and Σx² over *independent* units: the mean of each group of
correlated samples (an antithetic pair counts once), so the standard errors are honest.
Random numbers depend on (seed, pixel, sample index) only, so the result does not depend
on how the samples are split into passes.

Ctrl-C during a render returns what the finished passes hold (``result.interrupted``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .correlation import Correlation
from .modulation import Camera
from .timesampling import ANALYTIC, METHODS, validate

DEFAULT_EXPOSURE_S = 1.5e-3
DEFAULT_LANES_PER_PASS = 1 << 21


@dataclass(frozen=True)
class TimeSampling:
    """How the exposure time of each path is drawn (:mod:`dopplertof.timesampling`).

    method : ``uniform`` | ``stratified`` | ``antithetic`` | ``antithetic_mirror``
    n_times : correlated times per group (2 = antithetic pair); spp counts paths, so a
        group uses ``n_times`` of the pixel's spp
    shift : antithetic shift ``a`` in units of T (default ½)
    stratify_intervals : stratify each interval over the pixel's groups
    """

    method: str = "antithetic"
    n_times: int = 2
    shift: float = 0.5
    stratify_intervals: bool = True

    def __post_init__(self):
        validate(self.method, self.n_times, self.shift)


@dataclass
class RenderResult:
    """What :func:`render` returns. Images are numpy float32, shape (H, W[, 3]).

    intensity : (H, W, 3) standard image (radiance, units of a Mitsuba render)
    stderr : (H, W, 3) standard error of ``intensity``
    measurements : (n_cameras, H, W) D-ToF measurements (luminance of (1/T)∫ W f dt)
    measurement_stderr : (n_cameras, H, W)
    depth : (H, W) camera-ray hit distance, m (NaN where no sample hit)
    velocity : (H, W) radial velocity as the camera sees it, m/s: d/dt of the hit distance
        along the fixed camera ray, positive receding (NaN where no sample hit)
    point_velocity : (H, W) v·d̂ of the hit surface point, m/s (NaN where no hit)
    coverage : (H, W) fraction of samples whose camera ray hit a surface
    """

    intensity: np.ndarray
    stderr: np.ndarray
    measurements: np.ndarray
    measurement_stderr: np.ndarray
    depth: np.ndarray
    velocity: np.ndarray
    point_velocity: np.ndarray
    coverage: np.ndarray
    cameras: list
    spp: int
    seed: int
    settings: dict = field(default_factory=dict)
    interrupted: bool = False


class _Accumulator:
    """Float64 per-pixel sums over independent units."""

    def __init__(self, n_pixels, n_cameras, channels):
        self.units = 0
        self.samples = 0
        self.sum_i = np.zeros((n_pixels, channels))
        self.sq_i = np.zeros((n_pixels, channels))
        self.sum_m = np.zeros((n_cameras, n_pixels))
        self.sq_m = np.zeros((n_cameras, n_pixels))
        self.gt = np.zeros((4, n_pixels))  # hits, depth, velocity, point velocity (sums)


def _validate_positive_int(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _block_moments(values, group, per_pixel):
    """(Σ, Σ²) per pixel of group means of a per-lane array (Dr.Jit)."""
    import drjit as dr
    import mitsuba as mi

    values = mi.Float64(values)  # Σx² of low-variance pixels cancels badly in float32
    g = dr.block_sum(values, group) * (1.0 / group) if group > 1 else values
    return dr.block_sum(g, per_pixel), dr.block_sum(g * g, per_pixel)


def render(
    scene,
    cameras=None,
    spp=64,
    seed=0,
    max_depth=5,
    rr_depth=5,
    time_sampling="antithetic",
    correlation="replay",
    correlation_depth=None,
    n_times=2,
    antithetic_shift=0.5,
    stratify_intervals=True,
    exposure=None,
    exposure_start=0.0,
    hide_emitters=False,
    reconnection_threshold=0.5,
    lanes_per_pass=DEFAULT_LANES_PER_PASS,
    progress=False,
) -> RenderResult:
    """Render the intensity, ground truth and D-ToF measurements of a dynamic scene.

    Parameters
    ----------
    scene : DynamicScene (from :func:`dopplertof.load_scene`) or a path / dict to load
    cameras : list of :class:`Camera`, optional. All share one exposure T.
    spp : int. Paths per pixel (a group of ``n_times`` correlated times uses ``n_times``).
    seed : int. Same seed, same image, whatever the pass split.
    max_depth, rr_depth : int. Path depth (Mitsuba semantics) and Russian-roulette start.
    time_sampling : str or :class:`TimeSampling`. ``uniform``, ``stratified``,
        ``antithetic`` (default), ``antithetic_mirror``, or ``analytic`` (biased closed-form
        integration between the exposure's ends, low-pass sinusoid only; see
        :mod:`dopplertof.paired`).
    correlation : str or :class:`Correlation`. ``none``, ``pixel``, ``replay`` (default),
        ``reconnection`` or ``adaptive`` (the last two trace primal and partner together,
        :mod:`dopplertof.paired`; they need pairs of times, ``n_times = 2``, and use no
        Russian roulette).
    correlation_depth : int, optional. Replay cut-off (see :mod:`dopplertof.correlation`).
    reconnection_threshold : float. ``adaptive``: reconnect where both surfaces are rougher
        than this GGX/Beckmann α (diffuse counts as ∞). Default 0.5.
    n_times, antithetic_shift, stratify_intervals : see :class:`TimeSampling`.
    exposure : float, s. Exposure T when no camera is given (default 1.5 ms).
    exposure_start : float, s. Scene time at which the exposure opens (default 0).
    lanes_per_pass : int. Lanes per kernel launch (≥ 2M recommended on CPU).
    progress : bool. Show a progress bar.
    """
    from .backend import ensure_variant
    from .integrator import LaneSetup, trace
    from .loader import load_scene

    ensure_variant()
    if not hasattr(scene, "static"):
        scene = load_scene(scene)
    cameras = list(cameras or [])
    for c in cameras:
        if not isinstance(c, Camera):
            raise ValueError(f"cameras must be dopplertof.Camera objects, got {type(c).__name__}")
    spp = _validate_positive_int("spp", spp)
    max_depth = int(max_depth)
    if max_depth == 0 or max_depth < -1:
        raise ValueError(f"max_depth must be positive or -1 (unbounded), got {max_depth}")
    if cameras:
        exposures = {c.exposure for c in cameras}
        if len(exposures) > 1:
            raise ValueError(f"all cameras of one render must share the exposure, got {sorted(exposures)}")
        if exposure is not None and float(exposure) not in exposures:
            raise ValueError(f"exposure={exposure!r} differs from the cameras' exposure {exposures.pop()!r}")
        exposure = cameras[0].exposure
    exposure = DEFAULT_EXPOSURE_S if exposure is None else exposure
    if not isinstance(exposure, (int, float)) or not math.isfinite(exposure) or exposure <= 0:
        raise ValueError(f"exposure must be > 0 seconds, got {exposure!r}")
    if isinstance(correlation, str):
        correlation = Correlation(correlation, correlation_depth, reconnection_threshold)
    if isinstance(time_sampling, str):
        if time_sampling == "uniform" and n_times == 2 and not correlation.paired:
            n_times = 1  # independent times need no grouping
        time_sampling = TimeSampling(time_sampling, n_times, antithetic_shift, stratify_intervals)
    n = time_sampling.n_times
    analytic = time_sampling.method == ANALYTIC
    paired = correlation.paired or analytic
    if analytic:
        if correlation.mode not in ("replay", "reconnection", "adaptive") or correlation.depth is not None:
            raise ValueError(f"analytic time integration needs a fully correlated partner (replay, reconnection or adaptive), got {correlation.mode!r}")
        bad = [f"{c.label()} ({c.waveform}{'' if c.low_pass else ', full waveform'})" for c in cameras if not (c.low_pass and c.waveform == "sinusoidal")]
        if bad:
            raise ValueError(f"analytic time integration is implemented for the low-pass sinusoid only; cameras {', '.join(bad)} are not")
    if correlation.paired and n != 2:
        raise ValueError(f"correlation={correlation.mode!r} pairs two times (n_times=2), got n_times={n}")
    if spp % n:
        raise ValueError(f"spp={spp} must be a multiple of the {n} correlated times per group ({time_sampling.method})")

    width, height = scene.resolution
    n_pixels = width * height
    scene.set_time_window(exposure_start, exposure_start + exposure)
    spp_pass = max(n, min(spp, (lanes_per_pass // n_pixels) // n * n))
    channels = 3 if _is_rgb() else 1
    acc = _Accumulator(n_pixels, len(cameras), channels)
    roughness = None
    if paired:
        from .paired import roughness_table, trace_pair

        roughness = roughness_table(scene)

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=spp, unit="spp", desc="render", leave=False)
    interrupted = False
    try:
        done = 0
        while done < spp:
            this_pass = min(spp_pass, spp - done)
            setup = LaneSetup(
                n_pixels=n_pixels,
                width=width,
                height=height,
                samples_per_pixel_pass=this_pass,
                first_sample=done,
                spp_total=spp,
                n_times=n,
                exposure_start_s=float(exposure_start),
                exposure_s=float(exposure),
                seed=int(seed),
            )
            if paired:  # one lane per pair, holding the pair's mean
                out = trace_pair(scene, setup, cameras, time_sampling, correlation, max_depth, hide_emitters, roughness)
                _accumulate_pass(acc, out, 1, this_pass // n, this_pass, channels)
            else:
                out = trace(scene, setup, cameras, time_sampling, correlation, max_depth, rr_depth, hide_emitters)
                _accumulate_pass(acc, out, n, this_pass, this_pass, channels)
            done += this_pass
            if bar is not None:
                bar.update(this_pass)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if bar is not None:
            bar.close()
    if acc.units == 0:
        raise KeyboardInterrupt("render interrupted before the first pass finished")
    settings = dict(
        max_depth=max_depth,
        time_sampling=time_sampling.method,
        n_times=n,
        antithetic_shift=time_sampling.shift,
        stratify_intervals=time_sampling.stratify_intervals,
        correlation=correlation.mode,
        correlation_depth=correlation.depth,
        reconnection_threshold=correlation.threshold,
        rr_depth=rr_depth,
        hide_emitters=hide_emitters,
        exposure=exposure,
        exposure_start=exposure_start,
    )
    return _finish(acc, cameras, height, width, seed, settings, interrupted)


def _is_rgb():
    import mitsuba as mi

    return mi.is_rgb


def _accumulate_pass(acc, out, n, lanes_per_pixel, samples_per_pixel, channels):
    """Add one pass: ``n`` consecutive lanes form an independent unit (their mean)."""
    import drjit as dr

    per_pixel = lanes_per_pixel // n
    # One kernel traces every output; the block reductions below would otherwise each
    # re-run the whole path tracer for their own input (DESIGN §3.3).
    dr.eval(out["intensity"], out["measurements"], out["hit"], out["depth"], out["velocity"], out["point_velocity"])
    intensity = out["intensity"]
    parts = []
    for c in range(channels):
        parts.extend(_block_moments(intensity[c], n, per_pixel))
    for m in out["measurements"]:
        parts.extend(_block_moments(m, n, per_pixel))
    hit = out["hit"]
    gts = [dr.block_sum(hit, lanes_per_pixel)] + [dr.block_sum(out[k] * hit, lanes_per_pixel) for k in ("depth", "velocity", "point_velocity")]
    parts.extend(gts)
    dr.eval(parts)
    arrays = [np.asarray(p.numpy(), dtype=np.float64) for p in parts]
    k = 0
    for c in range(channels):
        acc.sum_i[:, c] += arrays[k]
        acc.sq_i[:, c] += arrays[k + 1]
        k += 2
    for i in range(acc.sum_m.shape[0]):
        acc.sum_m[i] += arrays[k]
        acc.sq_m[i] += arrays[k + 1]
        k += 2
    for j in range(4):
        acc.gt[j] += arrays[k + j]
    acc.units += per_pixel
    acc.samples += samples_per_pixel


def _mean_and_stderr(total, total_sq, units):
    mean = total / units
    if units < 2:
        return mean, np.full_like(mean, np.nan)
    var = np.maximum(total_sq / units - mean * mean, 0.0) * units / (units - 1)
    return mean, np.sqrt(var / units)


def _finish(acc, cameras, height, width, seed, settings, interrupted):
    mean_i, err_i = _mean_and_stderr(acc.sum_i, acc.sq_i, acc.units)
    mean_m, err_m = _mean_and_stderr(acc.sum_m, acc.sq_m, acc.units)
    hits = acc.gt[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        gt = np.where(hits > 0, acc.gt[1:] / hits, np.nan)
    channels = mean_i.shape[1]
    shape = (height, width, channels) if channels > 1 else (height, width)

    def img(a):
        return a.reshape(shape).astype(np.float32)

    return RenderResult(
        intensity=img(mean_i),
        stderr=img(err_i),
        measurements=mean_m.reshape(len(cameras), height, width).astype(np.float32),
        measurement_stderr=err_m.reshape(len(cameras), height, width).astype(np.float32),
        depth=gt[0].reshape(height, width).astype(np.float32),
        velocity=gt[1].reshape(height, width).astype(np.float32),
        point_velocity=gt[2].reshape(height, width).astype(np.float32),
        coverage=(hits / acc.samples).reshape(height, width).astype(np.float32),
        cameras=cameras,
        spp=acc.samples,
        seed=seed,
        settings=settings,
        interrupted=interrupted,
    )


__all__ = ["render", "RenderResult", "TimeSampling", "METHODS"]
