"""The public estimators of :mod:`dopplertof.reconstruct`: :func:`velocity` and :func:`depth`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..modulation import SPEED_OF_LIGHT_M_S
from ..validation import checked
from .errors import _gradients, _stderr, _velocity_floor_m_s, covariance_from_errors, default_max_velocity_stderr
from .fit import _depth_and_amplitude, _velocity_fit
from .frequencies import _frequency_groups, beat_range_m, inverse_variance_weights, unwrap_depth
from .identify import _PROBE_DOPPLER_PHASE, _column_rank, _velocity_identifiable
from .model import _CameraSet, _camera_set, _check_min_amplitude, _data_amplitude, _default_threshold, _design_columns, _doppler_to_velocity, _flatten, _measurement_array
from .ratio import _ratio_doppler_gradient, _velocity_ratio


@dataclass
class VelocityResult:
    """Per-pixel result of :func:`velocity`.

    Attributes
    ----------
    velocity : ndarray, shape (...)
        Radial velocity (m/s), positive when the distance grows, assuming the light is
        co-located with the camera; NaN where ``valid`` is False.
    valid : ndarray of bool, shape (...)
        Where the velocity is determined and, with measurement errors, its standard error
        is at most ``max_velocity_stderr_m_s``.
    depth : ndarray, shape (...)
        Distance (m) at mid-exposure (of the first camera's window), modulo the ambiguity
        range c/(2 f_g); NaN where it is not determined (for example a single phase offset).
    amplitude : ndarray, shape (...)
        Radiance A of the path (units of the standard intensity image: the g1/2 factor is
        divided out); NaN where not determined.
    doppler_hz : ndarray, shape (...)
        Doppler shift of the modulation frequency, Δf = f_g u / c = a / (2π T) (Hz), where
        u = dL/dt is the rate of the optical path length; NaN where ``valid`` is False.
    method : str
        ``"ratio"`` or ``"fit"``: the estimator that was used.
    velocity_stderr, depth_stderr : ndarray, shape (...), or None
        Standard errors (m/s, m) propagated from the measurements' errors (delta method,
        :func:`velocity`); None when no measurement errors were given. Monte Carlo error
        only, about the estimator's infinite-spp limit: a pixel that sees several paths
        (multipath, a silhouette, a slanted surface) is biased by them against a render's
        ground truth (the mean hit distance and speed of its camera rays).
        ``depth_stderr`` is NaN for cameras that are not all sinusoidal: their depth has the
        waveform's cyclic (wiggling) error, centimetres, which is not in it.
    max_velocity_stderr_m_s : float or None
        The threshold on ``velocity_stderr`` that ``valid`` applied (m/s); None without
        measurement errors.
    stderr_dof : int or None
        The degrees of freedom of the measurements' errors (None: not known); below
        :data:`MIN_STDERR_DOF` no pixel is valid (:func:`velocity`).
    threshold_reason : str
        How that threshold was chosen (given, or derived from the scene: :func:`velocity`).
    depth_range_m : float
        Unambiguous depth range (m): ``depth`` is the distance modulo it; c/(2 f_g), or
        c/(2 |f_1 − f_2|) for cameras at two frequencies.
    frequencies_hz : tuple of float
        The cameras' modulation frequencies f_g (Hz), one or two.
    brightness : ndarray, shape (...)
        β, the relative change of the path's radiance over the exposure (−2 v T/d for a
        diffuse surface lit from the camera); 0 where it is not fitted (several windows,
        non-sinusoidal waveforms), NaN where ``valid`` is False.
    """

    velocity: np.ndarray
    valid: np.ndarray
    depth: np.ndarray
    amplitude: np.ndarray
    doppler_hz: np.ndarray
    method: str
    velocity_stderr: np.ndarray | None = None
    depth_stderr: np.ndarray | None = None
    max_velocity_stderr_m_s: float | None = None
    threshold_reason: str = "no measurement errors given: validity from the signal amplitude only"
    depth_range_m: float = float("nan")
    brightness: np.ndarray | None = None
    frequencies_hz: tuple = ()
    stderr_dof: int | None = None


def velocity(
    measurements,
    cameras: Sequence | None = None,
    *,
    min_amplitude: float | None = None,
    method: str = "auto",
    max_doppler_hz: float | None = None,
    measurement_stderr=None,
    measurement_covariance=None,
    max_velocity_stderr: float | None = None,
    stderr_dof: int | None = None,
) -> VelocityResult:
    """Per-pixel radial velocity (and depth, amplitude) from D-ToF measurements.

    Parameters
    ----------
    measurements : array_like, shape (n_cameras, ...), or a RenderResult
        Rendered (or sensor-reconstructed) measurements, one image per camera, in the
        units of the standard image times g1/2. A :class:`~dopplertof.render.RenderResult` (of a
        sensor: its frames' cameras, not those of the windows' mean light)
        gives its measurements, cameras, standard errors and covariance at once.
    cameras : sequence of n_cameras camera configurations
        Sharing T (s), at one or two f_g (Hz: the depth is then unwrapped, module
        docstring). See the module docstring. Cameras in different
        exposure windows (``exposure_start``) are taken to see one path moving at a
        constant rate over the whole schedule, with constant radiance (module docstring,
        capture schedules): false at moving edges, under acceleration or brightness
        changes between windows, where the result is wrong (a motion artefact).
    measurement_stderr : array_like, shape (n_cameras, ...), optional
        Standard errors of the measurements; taken as independent between cameras unless
        ``measurement_covariance`` is given.
    measurement_covariance : array_like, shape (n_cameras, n_cameras, ...), optional
        Covariance of the measurements (of their means: a render's
        ``measurement_covariance``); cameras rendered from the same paths are correlated.
    max_velocity_stderr : float, optional
        With errors given: pixels whose velocity standard error (m/s) exceeds this are
        invalid. Default: a tenth of the scene's speed scale, 0.01 m/s where too few
        pixels move detectably for one (:func:`default_max_velocity_stderr`); the value used is
        ``result.max_velocity_stderr_m_s``. A pixel is also invalid where no camera
        measures its signal at :data:`MIN_MEASUREMENT_SNR` (3) standard errors or more: too
        few samples contributed for their errors to bound the velocity's (from a single
        sample the propagated error is zero), and where every camera with h ≠ 0 is exact
        (error 0: no sampled path changed during the exposure) beside a pixel where some
        sampled path did (its own samples missed the motion). Where the model holds (one
        surface per pixel, direct light) fewer than 2 % of the valid pixels are off by more
        than three standard errors (``tests/test_reconstruct_render.py``), but on moving
        surfaces more (4–7 % of the Cornell box's at 256 spp: the errors of h ≠ 0 cameras are
        heavy-tailed there, ``docs/estimators.md``). Multipath and silhouettes bias beyond
        the standard error.
    stderr_dof : int, optional
        The degrees of freedom the measurements' errors are estimated from (a render's
        ``info["stderr_dof"]``, taken from a RenderResult). Below :data:`MIN_STDERR_DOF` (15)
        no pixel is valid: an error estimated from few degrees of freedom is itself noisy,
        and the pixels whose error came out small by chance are the ones a threshold keeps
        (on the Cornell box's moving faces, direct light, a quarter of the valid pixels were
        off by more than three standard errors at 16 spp (4 degrees of freedom), 4 % at 32,
        1.4 % at 64 and at 256). None: not known, not checked.
    min_amplitude : float, optional
        Signal amplitude (measurement units) at or below which a pixel is invalid:
        the largest |H_i| over the phases for the ratio, (g1/2)|Z| for the fit (g1/2
        averaged over the cameras). Default: 1e-3 × the 99th percentile over the image of
        |H_i| (ratio) or of the data amplitude sqrt(2 mean_i m_i²) (fit; unlike the fitted
        amplitude it cannot be inflated by ill-conditioned pixels).
    method : {"auto", "ratio", "fit"}
        ``"auto"`` uses the fit for sinusoidal cameras, else the ratio.
    max_doppler_hz : float, optional
        Fit only: the search range |Δf| (Hz); default 1/(2T), i.e. |a| ≤ π. At f_g = 30
        MHz, T = 1.5 ms that is |v| ≤ 1666 m/s.

    Returns
    -------
    VelocityResult
        Arrays of shape ``measurements.shape[1:]``. The ratio method also returns depth and
        amplitude when its pairs span two phases (linear fit at the recovered Doppler).

    Raises
    ------
    ValueError
        If the number of measurements differs from the number of cameras, the cameras
        differ in f_g or T, ``method`` is unknown, the set cannot determine velocity (e.g.
        only homodyne, or it cannot tell the brightness change from a Doppler shift: the
        message names the cameras to add), ``method="fit"`` is used with a non-sinusoidal
        waveform, ``method="ratio"`` with cameras that are not matched pairs or whose phases
        do not balance, or ``max_velocity_stderr`` is not a number > 0 or comes without
        measurement errors.

    Examples
    --------
    The model's own measurements of a surface 2 m away receding at 10 m/s give 10 m/s back:

    >>> import math, dopplertof as dt
    >>> cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    >>> m = dt.reconstruct.model_measurements([1.0], 2.0, 10.0, cameras)
    >>> result = dt.reconstruct.velocity(m, cameras)
    >>> result.method, round(float(result.velocity[0]), 6)
    ('fit', 10.0)
    """
    measurements, cameras, result = _unpacked(measurements, cameras, "velocity")
    if result is not None and measurement_stderr is None and measurement_covariance is None:
        frames = len(measurements)
        measurement_covariance = result.maps.get("measurement_covariance")
        measurement_covariance = None if measurement_covariance is None else measurement_covariance[:frames, :frames]
        measurement_stderr = result.measurement_stderr[:frames]
        stderr_dof = result.info.get("stderr_dof") if stderr_dof is None else stderr_dof
    groups = _frequency_groups(cameras)
    sets = [_camera_set([cameras[i] for i in group]) for group in groups]
    m = _measurement_array(measurements, cameras)
    _check_min_amplitude(min_amplitude)
    if method not in ("auto", "ratio", "fit"):
        raise ValueError(f"method must be 'auto', 'ratio' or 'fit', got {method!r}")
    if max_doppler_hz is not None and not (np.isfinite(max_doppler_hz) and max_doppler_hz > 0):
        raise ValueError(f"max_doppler_hz must be a finite number > 0, got {max_doppler_hz!r}")
    if stderr_dof is not None:
        stderr_dof = checked("stderr_dof", stderr_dof, "int")
        if stderr_dof < 0:
            raise ValueError(f"stderr_dof must be >= 0 (degrees of freedom), got {stderr_dof!r}")
    if max_velocity_stderr is not None:
        max_velocity_stderr = checked("max_velocity_stderr", max_velocity_stderr, "float")
        if not max_velocity_stderr > 0:
            raise ValueError(f"max_velocity_stderr must be > 0 m/s, got {max_velocity_stderr!r}")
    if len(sets) > 1:
        _check_frequency_pair(sets)
    covariance = covariance_from_errors(measurement_stderr, measurement_covariance, m.shape)
    if covariance is None and max_velocity_stderr is not None:
        raise ValueError(
            f"max_velocity_stderr={max_velocity_stderr!r} m/s needs the measurements' errors "
            "(measurement_stderr or measurement_covariance, or pass the RenderResult)"
        )
    flat_covariance = None if covariance is None else covariance.reshape(covariance.shape[:2] + (-1,))
    parts = []
    for group, cams in zip(groups, sets):
        part_covariance = None if covariance is None else flat_covariance[np.ix_(group, group)]
        try:
            parts.append(_estimate(m[group], cams, part_covariance, method, min_amplitude, max_doppler_hz))
        except ValueError as exc:
            if len(sets) == 1:
                raise
            others = ", ".join(f"{other.frequency_hz / 1e6:g}" for other in sets if other is not cams)
            raise ValueError(f"the cameras at modulation_frequency = {cams.frequency_hz / 1e6:g} MHz "
                             f"(beside {others} MHz, reconstructed on their own): {exc}") from None
    result = parts[0][0] if len(parts) == 1 else _combine_frequencies(parts, groups, sets, flat_covariance)
    if covariance is None:
        return result
    v_err = result.velocity_stderr
    if max_velocity_stderr is None:
        limit, result.threshold_reason = default_max_velocity_stderr(result.velocity, v_err)
    else:
        limit, result.threshold_reason = max_velocity_stderr, "given"
    result.max_velocity_stderr_m_s = limit
    keep = result.valid & np.isfinite(v_err) & (v_err <= limit) & _resolved_signal(m, covariance) & _motion_sampled(cameras, covariance)
    result.stderr_dof = stderr_dof
    if stderr_dof is not None and stderr_dof < MIN_STDERR_DOF:
        keep = np.zeros_like(keep)
    result.valid = keep
    result.velocity = np.where(keep, result.velocity, np.nan)
    result.doppler_hz = np.where(keep, result.doppler_hz, np.nan)
    result.brightness = np.where(keep, result.brightness, np.nan)
    result.velocity_stderr = np.where(keep, v_err, np.nan)
    result.depth_stderr = np.where(np.isfinite(result.depth), result.depth_stderr, np.nan)
    if any(w != "sinusoidal" for cams in sets for w in cams.waveforms):
        # Depth inverts the sinusoid's phase: another waveform's cyclic error (centimetres)
        # is not Monte Carlo error and would be stated as millimetres.
        result.depth_stderr = np.full_like(result.depth_stderr, np.nan)
    return result


# Fewest degrees of freedom of the measurements' errors with which a pixel may be valid
# (:func:`velocity`'s ``stderr_dof``): the default 16 replicates give 15, antithetic times
# at the default 64 spp 16.
MIN_STDERR_DOF = 15

# A pixel is valid only where some camera measures its signal at this many of its standard
# errors or more. An error estimated from k contributing samples gives |m| / σ ≤ √k, so this
# asks for about 9 samples: from one, the covariance is m mᵀ and the velocity (which does not
# change when every measurement is scaled) gets a propagated error of zero.
MIN_MEASUREMENT_SNR = 3.0


def _resolved_signal(measurements, covariance) -> np.ndarray:
    """Pixels where some camera's |measurement| is at least :data:`MIN_MEASUREMENT_SNR` of
    its standard error (or exact: error 0 and a signal).

    Parameters
    ----------
    measurements : ndarray, shape (n_cameras, ...)
    covariance : ndarray, shape (n_cameras, n_cameras, ...)

    Returns
    -------
    ndarray of bool, shape (...)
    """
    variance = np.stack([covariance[i, i] for i in range(covariance.shape[0])])
    with np.errstate(invalid="ignore"):
        resolved = np.abs(measurements) >= MIN_MEASUREMENT_SNR * np.sqrt(np.maximum(variance, 0.0))
    return (resolved & (np.abs(measurements) > 0)).any(axis=0)


def _motion_sampled(cameras, covariance) -> np.ndarray:
    """Pixels whose velocity error means something: where some camera with h ≠ 0 has an
    error above zero, or, where all of them are exact (error 0: with antithetic times a
    static path cancels exactly, so no sampled path changed during the exposure), where no
    neighbouring pixel sampled motion either. Exact pixels beside sampled motion (a moving
    silhouette, a mirror's moving reflection) hold motion their own samples missed: there
    the velocity, 0, would be stated with an error of zero however fast the paths not
    sampled move (a rotating rim at 45 m/s read 0 ± 5e-10 m/s at 16 spp). Far from any
    sampled motion (a wall lit directly) an exact 0 is the static scene's.

    Parameters
    ----------
    cameras : sequence of Camera
    covariance : ndarray, shape (n_cameras, n_cameras, ...), the pixels' axes last

    Returns
    -------
    ndarray of bool, shape (...)
    """
    moving = [i for i, c in enumerate(cameras) if c.heterodyne != 0]
    if not moving:
        return np.ones(covariance.shape[2:], bool)
    sampled = np.stack([covariance[i, i] > 0 for i in moving]).any(axis=0)
    padded = np.pad(sampled, 1, constant_values=False)
    near = np.zeros_like(sampled)
    for offset in np.ndindex(*(3,) * sampled.ndim):  # the pixel and its neighbours, on every axis
        near |= padded[tuple(slice(o, o + n) for o, n in zip(offset, sampled.shape))]
    return sampled | ~near


def _estimate(m, cams: _CameraSet, covariance, method, min_amplitude, max_doppler_hz):
    """:func:`velocity` for cameras of one frequency, with the errors (``covariance``, shape
    (n, n, N), given) but no threshold on them; and the gradients of velocity and depth in
    the measurements (:func:`~dopplertof.reconstruct.errors._gradients`), or None."""
    reason = _velocity_identifiable(cams)
    if reason is not None:
        raise ValueError(reason)
    if method == "auto":  # the fit models the inverse-square brightening exactly; the ratio to first order
        method = "fit" if all(w == "sinusoidal" for w in cams.waveforms) else "ratio"
    if max_doppler_hz is None:
        max_doppler_hz = 0.5 / cams.exposure_s

    flat, shape, finite = _flatten(m)
    if method == "ratio":
        doppler_phase, brightness, ok = _velocity_ratio(flat, cams, min_amplitude)
        depth_threshold = None
    else:
        doppler_phase, brightness, ok, depth_threshold = _velocity_fit(flat, cams, min_amplitude, max_doppler_hz)
    ok &= finite
    vel, dopp = _doppler_to_velocity(doppler_phase, cams)

    # Depth and amplitude: the linear part at the recovered Doppler phase and brightness slope.
    a_for_depth = np.where(ok, doppler_phase, 0.0)
    depth_m, amplitude, signal, fit = _depth_and_amplitude(flat, a_for_depth, cams, np.where(ok, brightness, 0.0))
    if depth_threshold is None:
        depth_threshold = _default_threshold(_data_amplitude(flat), min_amplitude)
    depth_ok = ok & fit["full_rank"] & (signal > depth_threshold)

    def out(values, mask):
        return np.where(mask, values, np.nan).reshape(shape)

    result = VelocityResult(
        velocity=out(vel, ok),
        valid=ok.reshape(shape),
        depth=out(depth_m, depth_ok),
        amplitude=out(amplitude, depth_ok),
        doppler_hz=out(dopp, ok),
        method=method,
        depth_range_m=cams.depth_range_m,
        brightness=out(brightness, ok),
        frequencies_hz=(cams.frequency_hz,),
    )
    if covariance is None:
        return result, None
    gradients = _gradients(flat, cams, a_for_depth, np.where(ok, brightness, 0.0), fit,
                           _ratio_doppler_gradient(flat, cams) if method == "ratio" else None)
    result.velocity_stderr = np.hypot(_stderr(gradients[0], covariance), _velocity_floor_m_s(cams)).reshape(shape)
    result.depth_stderr = _stderr(gradients[1], covariance).reshape(shape)
    return result, gradients


def _check_frequency_pair(sets) -> None:
    """Two frequencies combine when their cameras share the exposure and the first window."""
    frequencies = ", ".join(f"{cams.frequency_hz / 1e6:g}" for cams in sets)
    if len(sets) > 2:
        raise ValueError(f"cameras at {len(sets)} modulation frequencies ({frequencies} MHz): velocity() "
                         "combines two; reconstruct the others separately")
    if sets[0].exposure_s != sets[1].exposure_s:
        raise ValueError(f"the cameras at {frequencies} MHz differ in exposure ({sets[0].exposure_s!r} and "
                         f"{sets[1].exposure_s!r} s); all cameras must share one exposure (T)")
    if sets[0].first_start_s != sets[1].first_start_s:
        raise ValueError(f"the cameras at {frequencies} MHz open their first windows at different times "
                         f"({sets[0].first_start_s!r} and {sets[1].first_start_s!r} s): their depths refer to "
                         "different instants; give both frequencies the same first window")


def _combine_frequencies(parts, groups, sets, covariance) -> VelocityResult:
    """One result from two frequencies' (:mod:`.frequencies`): velocity and brightness
    averaged with inverse-variance weights (equal without errors), whose error takes in the
    covariance between the frequencies (the same paths render both); depth unwrapped to the
    beat range (its error the finer frequency's); amplitude and Doppler shift of the first."""
    (first, first_gradients), (second, _) = parts
    results = [p[0] for p in parts]
    stderrs = None if covariance is None else [r.velocity_stderr for r in results]
    weights = inverse_variance_weights([r.velocity for r in results], stderrs)
    velocity = np.sum([w * np.nan_to_num(r.velocity) for w, r in zip(weights, results)], axis=0)
    brightness = np.sum([w * np.nan_to_num(r.brightness) for w, r in zip(weights, results)], axis=0)
    valid = first.valid | second.valid
    depth = unwrap_depth(first.depth, first.depth_range_m, second.depth, second.depth_range_m)
    finer = min(results, key=lambda r: r.depth_range_m)
    combined = VelocityResult(
        velocity=np.where(valid, velocity, np.nan),
        valid=valid,
        depth=depth,
        amplitude=np.where(np.isfinite(depth), first.amplitude, np.nan),
        doppler_hz=first.doppler_hz,
        method="/".join(dict.fromkeys(r.method for r in results)),
        depth_range_m=beat_range_m(first.depth_range_m, second.depth_range_m),
        brightness=np.where(valid, brightness, np.nan),
        frequencies_hz=first.frequencies_hz + second.frequencies_hz,
    )
    if covariance is not None:
        gradient = np.zeros((valid.size, covariance.shape[0]))
        for w, group, (_, (grad_v, _)) in zip(weights, groups, parts):
            gradient[:, group] += w.reshape(-1, 1) * np.nan_to_num(grad_v)
        floor = min(_velocity_floor_m_s(cams) for cams in sets)
        combined.velocity_stderr = np.hypot(_stderr(gradient, covariance), floor).reshape(valid.shape)
        combined.depth_stderr = np.where(np.isfinite(depth), finer.depth_stderr, np.nan)
    return combined


def unambiguous_speed_m_s(cams) -> float:
    """The radial speed c/(4 f_g T) at which the Doppler phase over the exposure reaches π.

    Parameters
    ----------
    cams : sequence of Camera
        Cameras of one modulation frequency f_g and exposure T.

    Returns
    -------
    float
        m/s.

    Raises
    ------
    ValueError
        Cameras that do not share f_g and T.
    """
    cams = cams if isinstance(cams, _CameraSet) else _camera_set(cams)
    return SPEED_OF_LIGHT_M_S / (4.0 * cams.frequency_hz * cams.exposure_s)


def _unpacked(measurements, cameras, what: str):
    """(measurements, cameras as a list, the RenderResult or None) of what :func:`velocity`
    or :func:`depth` (``what``) was given: a RenderResult gives its frames' measurements
    and, unless ``cameras`` are given, their cameras (a sensor's render ends with one camera
    per window measuring its mean light, g1 = 0: left out)."""
    result = None
    if hasattr(measurements, "measurements"):  # a RenderResult
        result = measurements
        frames = len(result.cameras) if getattr(result, "sensor", None) is None else result.sensor.frame_cameras
        cameras = result.cameras[:frames] if cameras is None else cameras
        measurements = result.measurements[:frames]
    if cameras is None:
        raise ValueError(f"{what}() needs the cameras (or a RenderResult)")
    return measurements, ([cameras] if hasattr(cameras, "modulation_frequency") else list(cameras)), result


def depth(measurements, cameras: Sequence | None = None, *, min_amplitude: float | None = None) -> np.ndarray:
    """Per-pixel distance (m) at mid-exposure, modulo the ambiguity range c/(2 f_g), or
    modulo c/(2 |f_1 − f_2|) when the cameras use two modulation frequencies (each
    determining depth on its own; :mod:`dopplertof.reconstruct.frequencies`).

    If the cameras determine the velocity, this is ``velocity(...).depth`` (the Doppler
    shift is fitted and accounted for). Otherwise (for example homodyne cameras only) the
    linear model is solved with no Doppler shift: for 4-phase homodyne (ψ = 0, π/2, π,
    3π/2) that is the classic φ = atan2(m₃ − m₁, m₀ − m₂), d = c φ / (4π f_g). Its phase is
    exact at mid-exposure even for a moving target when the cameras share a window (only
    the amplitude is reduced by sinc(a/2)); phases captured one after another take the
    target as still between the windows, and its motion biases the depth. For non-sinusoidal waveforms this homodyne path is accepted but has the
    usual cyclic (wiggling) error.

    Parameters
    ----------
    measurements : array_like, shape (n_cameras, ...), or a RenderResult
        A :class:`~dopplertof.render.RenderResult` gives its measurements and cameras.
    cameras : sequence of n_cameras camera configurations (one or two f_g, shared T)
        Needed unless ``measurements`` is a RenderResult.
    min_amplitude : float, optional
        (g1/2)|Z| threshold (measurement units); default 1e-3 × the 99th percentile of
        the data amplitude sqrt(2 mean_i m_i²).

    Returns
    -------
    ndarray, shape (...)
        Depth (m) in [0, c/(2 f_g)); NaN where not determined.

    Raises
    ------
    ValueError
        On shape/camera mismatch, or when the phases cannot determine depth (fewer than
        two independent phase offsets).
    """
    measurements, cameras, _ = _unpacked(measurements, cameras, "depth")
    groups = _frequency_groups(cameras)
    if len(groups) > 1:  # each frequency's depth, then the pair's (module frequencies)
        sets = [_camera_set([cameras[i] for i in group]) for group in groups]
        _check_frequency_pair(sets)
        m = _measurement_array(measurements, cameras)
        depths = [depth(m[group], [cameras[i] for i in group], min_amplitude=min_amplitude) for group in groups]
        return unwrap_depth(depths[0], sets[0].depth_range_m, depths[1], sets[1].depth_range_m)
    cams = _camera_set(cameras)
    m = _measurement_array(measurements, cams)
    _check_min_amplitude(min_amplitude)
    sinusoid = all(w == "sinusoidal" for w in cams.waveforms)
    determines_velocity = sinusoid and _velocity_identifiable(cams) is None
    # generic Doppler phase when it is fitted, a = 0 when it is not
    probe = np.array([_PROBE_DOPPLER_PHASE if determines_velocity else 0.0])
    if _column_rank(*_design_columns(probe, cams)) < 2:
        raise ValueError(
            "depth needs at least two independent phase measurements (e.g. homodyne at "
            f"ψ = 0 and π/2); got h = {cams.heterodyne.tolist()}, "
            f"ψ = {cams.phase_rad.tolist()} rad"
        )
    if determines_velocity:
        return velocity(m, cameras, min_amplitude=min_amplitude).depth
    flat, shape, finite = _flatten(m)
    depth_m, _, signal, fit = _depth_and_amplitude(flat, np.zeros(flat.shape[1]), cams)
    threshold = _default_threshold(_data_amplitude(flat), min_amplitude)
    ok = finite & fit["full_rank"] & (signal > threshold)
    return np.where(ok, depth_m, np.nan).reshape(shape)
