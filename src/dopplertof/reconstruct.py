"""Radial velocity and depth from a set of D-ToF measurements (pure numpy).

A rendered D-ToF pixel is the exposure average of the low-pass correlation

    m = (1/T) ∫_0^T (g1/2) Λ(2π h t/T + ψ + k L(t)) A dt,      k = 2π f_g / c,

with L(t) the optical path length (m) and A the radiance of the path. For the sinusoid
(Λ = cos) and one path with constant A and L(t) = L0 + u t this has the closed form

    m = (g1/2) Re{ Z e^{iψ} F(2π h + a) },   Z = A e^{i k L0},   a = k u T,
    F(x) = (e^{ix} − 1)/(i x),   F(0) = 1,

i.e. m = (g1 A/2) [sin(θ + 2πh + a) − sin θ]/(2πh + a) with θ = ψ + k L0. Everything in
this module inverts that model per pixel. With the light co-located with the camera the
path length is twice the distance, so u = 2 v (v the radial velocity, positive when the
distance grows) and the reported depth is d = L/2.

Two estimators:

``"ratio"`` (Heide et al. 2015, the original code's ``calc_velocity_from_homo_hetero(s)``)
    pairs each homodyne camera (h = 0) with a heterodyne one (h = 1) at the same ψ. For the
    sinusoid E/H = a/(a + 2π) *exactly* (the exposure-average of cos over the beat cancels
    the phase), so a = 2π r/(1 − r) with r = E/H, i.e. v = c r / (2 f_g T (1 − r)), the
    original formula; no small-r approximation (c is the exact ``SPEED_OF_LIGHT_M_S``
    here, where the original used 3e8). Several phases are fused by the least-squares
    slope of E against H, r̄ = Σ E_i H_i / Σ H_i², then inverted exactly as above.

    Why not the original r̄ = Σ r_i |H_i| / Σ |H_i|: it assumes the radiance is constant
    during the exposure. If it changes linearly, A(t) = A₀ (1 + β (t/T − ½)) (a surface
    that moves closer brightens as 1/d²), every heterodyne image gains
    β A₀ (g1/2) sin θ_i / 2π at a = 0, so r_i gains β tan θ_i / 2π, which the |H|-weighted
    mean keeps, while Σ E_i H_i gains ∝ β Σ sin 2θ_i, zero as soon as Σ e^{2iψ_i} = 0
    (ψ = 0, π/2; or 0, π/2, π, 3π/2). What is left is second order: the velocity is
    scaled by ≈ 1 − β²/12. (ψ = 0 alone, or 0 and π, cannot tell a brightness change
    from a Doppler shift.) The slope divides by no single H_i, so every pair enters it:
    leaving out pairs by their own r_i (small |H_i|, r_i ≥ 1) would select on noise and
    undo the cancellation. Other waveforms are accepted but the ratio is then only
    approximately a/(a + 2π).
``"fit"``
    any set of ≥ 3 measurements with known (h_i, ψ_i), sinusoid only: for a fixed Doppler
    phase a the model is linear in (Re Z, Im Z) and solved in closed form (2×2 normal
    equations); a is found per pixel by a coarse grid over ``|Δf| ≤ max_doppler_hz``
    followed by variable-projection Gauss-Newton steps with step halving. Covers
    homodyne + heterodyne at several phases and arbitrary heterodyne schemes such as
    Hu et al. 2022 (h ∈ {½, ½, −½, −½}, ψ ∈ {3π/2, 0, π/2, π}).

Depth refers to the middle of the exposure (t = T/2): the phase of the homodyne
correlation is exactly k L(T/2) whatever the velocity, so a 4-phase homodyne depth is
exact at mid-exposure even for a moving target. Depth is reported modulo the ambiguity
range c/(2 f_g).

Capture schedules. Cameras may expose at different times (``exposure_start``, s: a
render's cameras one after another, README "Capture schedules"). The model then takes
each pixel to see *one* path over the whole schedule, its length growing at a constant
rate and its radiance constant: camera i, whose window opens δ_i = (s_i − s_0)/T
exposures after the first camera's, sees the path lengthened by u (s_i − s_0), so its
phase gains a δ_i:

    m_i = (g1_i/2) Re{ Z e^{i(ψ_i + a δ_i)} F(2π h_i + a) },   Z = A e^{i k L(s_0)},

and depth and amplitude refer to the first camera's window. This is exact for a surface
receding at constant speed (up to its 1/d² brightening), and wrong wherever a pixel sees
different surfaces in different windows (a moving edge: the motion artefact of sequential
capture), the motion accelerates, or the radiance changes between windows. Every
estimator uses this model; the ratio pairs a homodyne with a heterodyne camera of the
same window; the fit searches a grid 1 + max δ_i times finer and refines its deepest few
minima, since later windows give distant Doppler phases residuals almost as small as the
true one's. Cameras without ``exposure_start`` (None) share the first window; a set that
mixes None with given starts is refused (pass the render's ``result.cameras``, whose
starts are filled in).

Parameters shared by the public functions:

=====================  ======  ===========================  ===================================
name                   unit    default                      meaning
=====================  ======  ===========================  ===================================
``measurements``       –       required                     array (n_cameras, ...) of rendered
                                                            measurements, one image per camera
``cameras``            –       required                     sequence of n_cameras objects with
                                                            ``modulation_frequency`` (Hz),
                                                            ``exposure`` (s), ``heterodyne``,
                                                            ``phase`` (rad), ``waveform``,
                                                            ``g1``, optionally
                                                            ``exposure_start`` (s); all must
                                                            share f_g and T
``min_amplitude``      meas.   1e-3 × 99th percentile       pixels whose signal amplitude
                               of the image's amplitude     (max_i |H_i| for the ratio,
                                                            |H_i| for a per-phase ratio,
                                                            (g1/2)|Z| for the fit and depth)
                                                            is not above it are invalid
``method``             –       ``"auto"``                   ``"ratio"``, ``"fit"`` or ``"auto"``
                                                            (ratio iff the cameras form matched
                                                            h = 0 / h = 1 pairs)
``max_doppler_hz``     Hz      1/(2T)                       search range of the fit, |Δf|;
                                                            |a| ≤ π at the default
=====================  ======  ===========================  ===================================

Invalid pixels (amplitude too small, r ≥ 1, non-finite input, Doppler outside the search
range, velocity not identifiable at that pixel) have ``valid == False`` and NaN velocity.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .modulation import SPEED_OF_LIGHT_M_S

DEFAULT_RELATIVE_MIN_AMPLITUDE = 1e-3
"""Default ``min_amplitude`` as a fraction of the 99th-percentile amplitude of the image."""

_H_TOLERANCE = 1e-12  # h == 0 and h == 1 are matched to this absolute tolerance
_PHASE_TOLERANCE_RAD = 1e-9
_GRID_POINTS = 65
_SCHEDULE_CANDIDATES = 4  # grid minima refined when the cameras' windows differ
_MAX_GAUSS_NEWTON_ITERATIONS = 60
_MAX_STEP_HALVINGS = 30
_RANK_RTOL = 1e-10  # det(G) / trace(G)^2 below this: the 2x2 normal equations are rank 1
_MIN_SENSITIVITY = 1e-7  # |∂m/∂a ⊥| / (|Z| |g1/2|) below this: a is not identifiable


@dataclass
class VelocityResult:
    """Per-pixel result of :func:`velocity`.

    Attributes
    ----------
    velocity : ndarray, shape (...)
        Radial velocity (m/s), positive when the distance grows, assuming the light is
        co-located with the camera; NaN where ``valid`` is False.
    valid : ndarray of bool, shape (...)
        Where the velocity could be determined.
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
        :func:`velocity`); None when no measurement errors were given.
    """

    velocity: np.ndarray
    valid: np.ndarray
    depth: np.ndarray
    amplitude: np.ndarray
    doppler_hz: np.ndarray
    method: str
    velocity_stderr: np.ndarray | None = None
    depth_stderr: np.ndarray | None = None


@dataclass
class RatioPhaseResult:
    """Per-phase maps of the homodyne/heterodyne ratio method (see
    :func:`ratio_velocity_per_phase`).

    Attributes
    ----------
    phase : ndarray, shape (n_pairs,)
        Phase offset ψ (rad) of each homodyne/heterodyne pair, in camera order.
    ratio : ndarray, shape (n_pairs, ...)
        r = E/H (dimensionless); NaN where invalid.
    velocity : ndarray, shape (n_pairs, ...)
        Radial velocity (m/s) from each pair alone; NaN where invalid.
    doppler_hz : ndarray, shape (n_pairs, ...)
        Doppler shift (Hz) from each pair alone; NaN where invalid.
    valid : ndarray of bool, shape (n_pairs, ...)
        |H| above ``min_amplitude``, r < 1 and finite.
    homodyne_amplitude : ndarray, shape (n_pairs, ...)
        |H| (measurement units); :func:`velocity` fuses the pairs with weights ∝ H².
    """

    phase: np.ndarray
    ratio: np.ndarray
    velocity: np.ndarray
    doppler_hz: np.ndarray
    valid: np.ndarray
    homodyne_amplitude: np.ndarray


@dataclass(frozen=True)
class _CameraSet:
    """The camera attributes the estimators need, as arrays of shape (n_cameras,)."""

    frequency_hz: float
    exposure_s: float
    heterodyne: np.ndarray
    phase_rad: np.ndarray
    half_g1: np.ndarray
    waveforms: tuple[str, ...]
    window_offset: np.ndarray  # δ_i: window start minus the first camera's, in exposures T

    @property
    def wavenumber(self) -> float:
        """k = 2π f_g / c (rad per metre of optical path)."""
        return 2.0 * np.pi * self.frequency_hz / SPEED_OF_LIGHT_M_S

    def __len__(self) -> int:
        return len(self.heterodyne)


# --------------------------------------------------------------------------- model


def _beat_kernel(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of F(x) = (e^{ix} − 1)/(i x), stable at x = 0.

    F(x) = sin(x)/x + i (1 − cos x)/x, written with ``np.sinc`` so that no cancellation
    happens near 0.
    """
    real = np.sinc(x / np.pi)
    imag = np.sin(0.5 * x) * np.sinc(x / (2.0 * np.pi))
    return real, imag


def _beat_kernel_derivative(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of F'(x), with Taylor series near x = 0."""
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)  # placeholder avoids 0/0 in the branch not taken
    x2 = x * x
    real_series = x * (-1.0 / 3.0 + x2 * (1.0 / 30.0 - x2 / 840.0))
    imag_series = 0.5 + x2 * (-1.0 / 8.0 + x2 * (1.0 / 144.0 - x2 / 5760.0))
    real_direct = (xs * np.cos(xs) - np.sin(xs)) / (xs * xs)
    imag_direct = (xs * np.sin(xs) - 2.0 * np.sin(0.5 * xs) ** 2) / (xs * xs)
    return np.where(small, real_series, real_direct), np.where(small, imag_series, imag_direct)


def _design_columns(
    doppler_phase: np.ndarray, cams: _CameraSet, derivative: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Columns of the linear model m = c1 Re Z + c2 Im Z for given Doppler phases a.

    Parameters
    ----------
    doppler_phase : ndarray, shape (N,)
        a = k u T (rad) per pixel.
    derivative : bool
        Return ∂c1/∂a and ∂c2/∂a instead.

    Returns
    -------
    c1, c2 : ndarray, shape (n_cameras, N)
    """
    x = 2.0 * np.pi * cams.heterodyne[:, None] + doppler_phase[None, :]
    delta = cams.window_offset[:, None]
    f_re, f_im = _beat_kernel(x)
    if derivative:  # d/da [e^{i a δ} F(x)] = e^{i a δ} (F'(x) + i δ F(x))
        d_re, d_im = _beat_kernel_derivative(x)
        f_re, f_im = d_re - delta * f_im, d_im + delta * f_re
    phi = cams.phase_rad[:, None] + delta * doppler_phase[None, :]  # ψ + a δ (module docstring)
    cos_psi, sin_psi = np.cos(phi), np.sin(phi)
    # Re{(X + iY) e^{iφ} (f_re + i f_im)} = X p − Y q
    p = cos_psi * f_re - sin_psi * f_im
    q = sin_psi * f_re + cos_psi * f_im
    s = cams.half_g1[:, None]
    return s * p, -s * q


def _exposure_average(amplitude, depth_m, velocity_m_s, cams: _CameraSet) -> np.ndarray:
    """Closed-form measurements (n_cameras, *shape) for the co-located sinusoid model."""
    k = cams.wavenumber
    path_rate = 2.0 * velocity_m_s
    doppler_phase = k * path_rate * cams.exposure_s
    # depth is at mid-exposure; the model is parametrised at t = 0
    path_start_m = 2.0 * depth_m - 0.5 * path_rate * cams.exposure_s
    expand = (slice(None),) + (None,) * np.ndim(amplitude)
    x = 2.0 * np.pi * cams.heterodyne[expand] + doppler_phase
    theta = cams.phase_rad[expand] + k * path_start_m + doppler_phase * cams.window_offset[expand]
    f_re, f_im = _beat_kernel(x)
    return cams.half_g1[expand] * amplitude * (np.cos(theta) * f_re - np.sin(theta) * f_im)


def model_measurements(amplitude, depth_m, velocity_m_s, cameras: Sequence) -> np.ndarray:
    """Forward model: exposure-averaged low-pass sinusoid of one path per pixel.

    The light is co-located with the camera (optical path L = 2 × distance, dL/dt =
    2 × radial velocity), the radiance is constant and the velocity is constant during the
    exposure (over every camera's window: module docstring, capture schedules). The
    inverse of :func:`velocity` and :func:`depth`.

    Parameters
    ----------
    amplitude : array_like, shape (...)
        Radiance A of the path (units of the standard intensity image).
    depth_m : array_like, broadcastable to ``amplitude``
        Distance (m) at mid-exposure, t = T/2 (of the first camera's window).
    velocity_m_s : array_like, broadcastable to ``amplitude``
        Radial velocity (m/s), positive when the distance grows.
    cameras : sequence of camera configurations
        Sinusoidal waveform only; see the module docstring for the attributes.

    Returns
    -------
    ndarray, shape (n_cameras, ...)
        m_i = (g1_i A/2) [sin(θ_i + 2π h_i + a) − sin θ_i]/(2π h_i + a), with
        θ_i = ψ_i + k L(0) + a δ_i, a = 2 k v T, δ_i the camera's window offset.

    Raises
    ------
    ValueError
        If the cameras are invalid or not sinusoidal.
    """
    cams = _camera_set(cameras)
    _require_sinusoid(cams, "model_measurements uses the closed form of the sinusoid")
    amplitude, depth_m, velocity_m_s = np.broadcast_arrays(
        np.asarray(amplitude, dtype=np.float64),
        np.asarray(depth_m, dtype=np.float64),
        np.asarray(velocity_m_s, dtype=np.float64),
    )
    return _exposure_average(amplitude, depth_m, velocity_m_s, cams)


# ---------------------------------------------------------------- input checking


def _camera_set(cameras: Sequence) -> _CameraSet:
    """Read and validate the camera attributes."""
    if hasattr(cameras, "modulation_frequency"):
        cameras = [cameras]
    cameras = list(cameras)
    if not cameras:
        raise ValueError("cameras is empty; need at least one camera configuration")
    try:
        freqs = np.array([float(c.modulation_frequency) for c in cameras])
        exposures = np.array([float(c.exposure) for c in cameras])
        heterodyne = np.array([float(c.heterodyne) for c in cameras])
        phases = np.array([float(c.phase) for c in cameras])
    except AttributeError as err:
        raise ValueError(
            "each camera needs modulation_frequency, exposure, heterodyne and phase "
            f"attributes: {err}"
        ) from err
    g1 = np.array([float(getattr(c, "g1", 0.5)) for c in cameras])
    waveforms = tuple(str(getattr(c, "waveform", "sinusoidal")) for c in cameras)
    for name, values in (
        ("modulation_frequency", freqs),
        ("exposure", exposures),
        ("heterodyne", heterodyne),
        ("phase", phases),
        ("g1", g1),
    ):
        if not np.all(np.isfinite(values)):
            raise ValueError(f"camera {name} must be finite, got {values.tolist()}")
    if np.any(freqs <= 0):
        raise ValueError(f"modulation_frequency must be > 0 Hz, got {freqs.tolist()}")
    if np.any(exposures <= 0):
        raise ValueError(f"exposure must be > 0 s, got {exposures.tolist()}")
    if np.any(g1 <= 0):
        raise ValueError(f"g1 must be > 0, got {g1.tolist()}")
    if not np.allclose(freqs, freqs[0], rtol=1e-12, atol=0.0):
        raise ValueError(
            "all cameras must share one modulation_frequency (f_g), got "
            f"{freqs.tolist()} Hz; reconstruct each frequency separately"
        )
    if not np.allclose(exposures, exposures[0], rtol=1e-12, atol=0.0):
        raise ValueError(
            f"all cameras must share one exposure (T), got {exposures.tolist()} s"
        )
    return _CameraSet(
        frequency_hz=float(freqs[0]),
        exposure_s=float(exposures[0]),
        heterodyne=heterodyne,
        phase_rad=phases,
        half_g1=0.5 * g1,
        waveforms=waveforms,
        window_offset=_window_offsets(cameras, float(exposures[0])),
    )


def _window_offsets(cameras, exposure_s: float) -> np.ndarray:
    """δ_i = (s_i − s_0)/T from the cameras' ``exposure_start`` (module docstring)."""
    starts = [getattr(c, "exposure_start", None) for c in cameras]
    given = [s is not None for s in starts]
    if not any(given):
        return np.zeros(len(cameras))
    if not all(given):
        raise ValueError(
            "some cameras give an exposure_start and others do not (None: the render's), so "
            f"their windows are unknown here: {starts}; pass the RenderResult, or its "
            "result.cameras, whose starts are filled in"
        )
    starts = np.array([float(s) for s in starts])
    if not np.all(np.isfinite(starts)):
        raise ValueError(f"camera exposure_start must be finite, got {starts.tolist()} s")
    return (starts - starts[0]) / exposure_s


def _require_sinusoid(cams: _CameraSet, why: str) -> None:
    others = sorted({w for w in cams.waveforms if w != "sinusoidal"})
    if others:
        raise ValueError(f"{why}; got waveform(s) {others}; use waveform='sinusoidal'")


def _measurement_array(measurements, cams: _CameraSet) -> np.ndarray:
    m = np.asarray(measurements, dtype=np.float64)
    if m.ndim == 0 or m.shape[0] != len(cams):
        raise ValueError(
            f"measurements must have shape (n_cameras, ...) with n_cameras = {len(cams)}, "
            f"got shape {m.shape}"
        )
    return m


def _check_min_amplitude(min_amplitude) -> None:
    if min_amplitude is not None and not (np.isfinite(min_amplitude) and min_amplitude >= 0):
        raise ValueError(f"min_amplitude must be a finite number >= 0, got {min_amplitude!r}")


def _data_amplitude(flat: np.ndarray) -> np.ndarray:
    """Signal amplitude estimated from the data alone, sqrt(2 mean_i m_i²), shape (N,).

    For a sinusoid sampled at spread phases this is ≈ (g1/2)|Z|; unlike the fitted
    amplitude it cannot blow up, so it sets the default threshold's scale.
    """
    return np.sqrt(2.0 * np.mean(flat * flat, axis=0))


def _default_threshold(amplitude: np.ndarray, min_amplitude) -> float:
    if min_amplitude is not None:
        return float(min_amplitude)
    finite = amplitude[np.isfinite(amplitude)]
    if finite.size == 0:
        return 0.0
    return DEFAULT_RELATIVE_MIN_AMPLITUDE * float(np.percentile(finite, 99.0))


def _same_phase(psi_a: float, psi_b: float) -> bool:
    delta = np.angle(np.exp(1j * (psi_a - psi_b)))
    return abs(delta) <= _PHASE_TOLERANCE_RAD


def _ratio_pairs(cams: _CameraSet) -> list[tuple[int, int]] | None:
    """(homodyne, heterodyne) camera indices if every camera is in an h=0/h=1 pair
    with the same ψ and the same exposure window; None otherwise."""
    homodyne = [i for i in range(len(cams)) if abs(cams.heterodyne[i]) <= _H_TOLERANCE]
    heterodyne = [i for i in range(len(cams)) if abs(cams.heterodyne[i] - 1) <= _H_TOLERANCE]
    if not homodyne or len(homodyne) != len(heterodyne) or 2 * len(homodyne) != len(cams):
        return None
    pairs, free = [], list(heterodyne)
    for i in homodyne:
        match = next(
            (j for j in free if _same_phase(cams.phase_rad[i], cams.phase_rad[j]) and cams.window_offset[i] == cams.window_offset[j]),
            None,
        )
        if match is None:
            return None
        free.remove(match)
        pairs.append((i, match))
    return pairs


def _velocity_identifiable(cams: _CameraSet) -> str | None:
    """Why the set cannot determine the Doppler phase, or None if it can (generically)."""
    if len(np.unique(np.round(cams.heterodyne, 12))) < 2:
        return (
            f"all cameras have the same heterodyne ratio h = {cams.heterodyne.tolist()}; the "
            "Doppler shift only changes their common scale, so velocity is not determined: add "
            "cameras with a different h (e.g. h = 1 next to h = 0)"
        )
    # A generic a: the linear part's rank must leave at least one residual degree of freedom.
    c1, c2 = _design_columns(np.array([0.123]), cams)
    if len(cams) <= _column_rank(c1, c2):
        return (
            f"{len(cams)} measurements with h = {cams.heterodyne.tolist()} and "
            f"ψ = {cams.phase_rad.tolist()} rad cannot determine amplitude, phase and Doppler "
            "shift together; use at least 3 measurements (or a homodyne/heterodyne pair at the "
            "same ψ with method='ratio')"
        )
    return None


# ------------------------------------------------------------- linear sub-problem


def _column_rank(c1: np.ndarray, c2: np.ndarray) -> int:
    """Rank of the (n_cameras, 2) design matrix of one Doppler phase."""
    basis = np.concatenate([c1, c2], axis=1)
    scale = np.abs(basis).max()
    return 0 if scale == 0 else int(np.linalg.matrix_rank(basis, tol=1e-9 * scale))


def _solve_normal(g11, g12, g22, full_rank, b1, b2):
    """Minimum-norm solution of the 2×2 symmetric PSD system G z = b (per pixel)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        det = g11 * g22 - g12 * g12
        x_full = (g22 * b1 - g12 * b2) / det
        y_full = (g11 * b2 - g12 * b1) / det
        # rank 1: G = λ v vᵀ, λ = trace, v the dominant column normalised
        trace = g11 + g22
        use_first = g11 >= g22
        v1 = np.where(use_first, g11, g12)
        v2 = np.where(use_first, g12, g22)
        norm2 = v1 * v1 + v2 * v2
        coef = (v1 * b1 + v2 * b2) / (norm2 * trace)
        x_rank1 = np.where(trace > 0, coef * v1, 0.0)
        y_rank1 = np.where(trace > 0, coef * v2, 0.0)
    return np.where(full_rank, x_full, x_rank1), np.where(full_rank, y_full, y_rank1)


def _linear_fit(m: np.ndarray, doppler_phase: np.ndarray, cams: _CameraSet):
    """Best Z for given a per pixel.

    Returns
    -------
    dict with x, y (Re Z, Im Z), residual (n, N), rss (N,), full_rank (N,), and the
    columns and normal matrix needed by the Gauss-Newton step.
    """
    c1, c2 = _design_columns(doppler_phase, cams)
    g11 = np.sum(c1 * c1, axis=0)
    g12 = np.sum(c1 * c2, axis=0)
    g22 = np.sum(c2 * c2, axis=0)
    full_rank = g11 * g22 - g12 * g12 > _RANK_RTOL * (g11 + g22) ** 2
    x, y = _solve_normal(g11, g12, g22, full_rank, np.sum(c1 * m, axis=0), np.sum(c2 * m, axis=0))
    residual = m - (c1 * x + c2 * y)
    return {
        "x": x,
        "y": y,
        "residual": residual,
        "rss": np.sum(residual * residual, axis=0),
        "full_rank": full_rank,
        "c1": c1,
        "c2": c2,
        "g": (g11, g12, g22),
    }


def _projected_sensitivity(fit: dict, doppler_phase: np.ndarray, cams: _CameraSet):
    """∂m/∂a at fixed Z, minus its projection on the columns (variable projection)."""
    d1, d2 = _design_columns(doppler_phase, cams, derivative=True)
    jac = d1 * fit["x"] + d2 * fit["y"]
    c1, c2 = fit["c1"], fit["c2"]
    g11, g12, g22 = fit["g"]
    alpha, beta = _solve_normal(
        g11, g12, g22, fit["full_rank"], np.sum(c1 * jac, axis=0), np.sum(c2 * jac, axis=0)
    )
    return jac, jac - (c1 * alpha + c2 * beta)


def _grid_points(cams: _CameraSet) -> int:
    """Grid points of the coarse search: the model's phases vary with a as fast as
    1 + max|δ_i| (windows later by δ_i exposures gain a δ_i), so the grid is that much
    finer for the same resolution of the residual's landscape."""
    return (_GRID_POINTS - 1) * int(np.ceil(1.0 + np.max(np.abs(cams.window_offset)))) + 1


def _grid_search(m: np.ndarray, cams: _CameraSet, max_phase: float, candidates: int = 1) -> np.ndarray:
    """Coarse per-pixel minimisers of the projected residual over a ∈ [−max, max]: the
    ``candidates`` deepest local minima of the grid, deepest first, each refined by a
    parabola (shape (candidates, N); where a pixel has fewer, its deepest repeats)."""
    grid = np.linspace(-max_phase, max_phase, _grid_points(cams))
    rss = np.empty((grid.size, m.shape[1]))
    for j, a in enumerate(grid):
        # The columns do not depend on the pixel here: one projector for all pixels.
        c1, c2 = _design_columns(np.array([a]), cams)
        basis = np.concatenate([c1, c2], axis=1)
        projector = basis @ np.linalg.pinv(basis, rcond=1e-10)
        residual = m - projector @ m
        rss[j] = np.sum(residual * residual, axis=0)
    if candidates == 1:
        order = np.argmin(rss, axis=0)[None]
    else:
        padded = np.pad(rss, ((1, 1), (0, 0)), constant_values=np.inf)
        minimum = (rss <= padded[:-2]) & (rss <= padded[2:])
        order = np.argsort(np.where(minimum, rss, np.inf), axis=0, kind="stable")[:candidates]
        depth = np.take_along_axis(np.where(minimum, rss, np.inf), order, axis=0)
        order = np.where(np.isfinite(depth), order, order[:1])
    return np.stack([_parabola(grid, rss, best) for best in order])


def _parabola(grid: np.ndarray, rss: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Grid points ``best`` (per pixel) moved to the vertex of the parabola through their
    neighbours' residuals, kept inside one grid step."""
    start = grid[best]
    spacing = grid[1] - grid[0]
    inner = (best > 0) & (best < grid.size - 1)
    cols = np.arange(rss.shape[1])
    r_lo = rss[np.clip(best - 1, 0, grid.size - 1), cols]
    r_0 = rss[best, cols]
    r_hi = rss[np.clip(best + 1, 0, grid.size - 1), cols]
    curvature = r_lo - 2.0 * r_0 + r_hi
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = 0.5 * spacing * (r_lo - r_hi) / curvature
    ok = inner & (curvature > 0) & np.isfinite(shift)
    return start + np.where(ok, np.clip(shift, -spacing, spacing), 0.0)


def _gauss_newton(m, start, cams: _CameraSet, max_step: float, max_phase: float) -> np.ndarray:
    """Refine the Doppler phase per pixel by safeguarded variable-projection Gauss-Newton.

    Steps are limited to ``max_step`` and a stays in [−max_phase, max_phase]: outside the
    search range the model has degenerate points (e.g. F(2π) = 0 for homodyne cameras at
    a = 2π) where the fitted amplitude diverges.
    """
    a = np.clip(start, -max_phase, max_phase)
    rss = _linear_fit(m, a, cams)["rss"]
    active = np.arange(a.size)
    for _ in range(_MAX_GAUSS_NEWTON_ITERATIONS):
        if active.size == 0:
            break
        ma, aa = m[:, active], a[active]
        fit = _linear_fit(ma, aa, cams)
        jac, jac_perp = _projected_sensitivity(fit, aa, cams)
        curvature = np.sum(jac_perp * jac_perp, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.sum(jac * fit["residual"], axis=0) / curvature
        step = np.where(np.isfinite(step), np.clip(step, -max_step, max_step), 0.0)
        step = np.clip(aa + step, -max_phase, max_phase) - aa
        accepted = np.zeros(active.size, dtype=bool)
        pending = np.flatnonzero(step != 0.0)
        for _ in range(_MAX_STEP_HALVINGS):
            if pending.size == 0:
                break
            trial = aa[pending] + step[pending]
            trial_rss = _linear_fit(ma[:, pending], trial, cams)["rss"]
            better = trial_rss < fit["rss"][pending]
            won = pending[better]
            aa[won] = trial[better]
            fit["rss"][won] = trial_rss[better]
            accepted[won] = True
            pending = pending[~better]
            step[pending] *= 0.5
        a[active] = aa
        rss[active] = fit["rss"]
        tiny = np.abs(step) <= 1e-15 + 1e-13 * np.abs(aa)
        active = active[accepted & ~tiny]
    return a


# ---------------------------------------------------------------------- estimators


def _flatten(m: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
    """(n, ...) → (n, N) with non-finite pixels zeroed, the pixel shape and a finite mask."""
    shape = m.shape[1:]
    flat = m.reshape(m.shape[0], -1)
    finite = np.all(np.isfinite(flat), axis=0)
    return np.where(finite, flat, 0.0), shape, finite


def _depth_and_amplitude(m, doppler_phase, cams: _CameraSet):
    """Mid-exposure depth (m), amplitude A and (g1/2)|Z| from the linear fit at known a."""
    fit = _linear_fit(m, doppler_phase, cams)
    z = fit["x"] + 1j * fit["y"]
    amplitude = np.abs(z)
    mid_phase = np.mod(np.angle(z) + 0.5 * doppler_phase, 2.0 * np.pi)
    depth = mid_phase / (2.0 * cams.wavenumber)
    signal = np.mean(cams.half_g1) * amplitude
    return depth, amplitude, signal, fit


def _doppler_to_velocity(doppler_phase, cams: _CameraSet):
    """(velocity m/s, Δf Hz) from a = k u T, co-located light (u = 2 v)."""
    path_rate = doppler_phase / (cams.wavenumber * cams.exposure_s)
    return 0.5 * path_rate, doppler_phase / (2.0 * np.pi * cams.exposure_s)


def _ratio_per_phase(m, cams: _CameraSet, pairs, min_amplitude):
    """Per pair: H and E with g1/2 divided out, r = E/H, validity and |H| (measurement
    units), all shaped (n_pairs, N), and the |H| threshold."""
    hom = np.stack([m[i] / cams.half_g1[i] for i, _ in pairs])
    het = np.stack([m[j] / cams.half_g1[j] for _, j in pairs])
    hom_amp = np.stack([np.abs(m[i]) for i, _ in pairs])
    threshold = _default_threshold(hom_amp, min_amplitude)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = het / hom
    valid = (hom_amp > threshold) & np.isfinite(ratio) & (ratio < 1.0)
    return {"homodyne": hom, "heterodyne": het, "ratio": ratio, "valid": valid,
            "homodyne_amplitude": hom_amp, "threshold": threshold}


def _ratio_to_doppler_phase(ratio):
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 * np.pi * ratio / (1.0 - ratio)


def ratio_velocity_per_phase(measurements, cameras: Sequence, *, min_amplitude=None):
    """Velocity from each homodyne/heterodyne pair separately (no fusion).

    Parameters
    ----------
    measurements : array_like, shape (n_cameras, ...)
    cameras : sequence of n_cameras camera configurations
        Must consist of pairs: h = 0 and h = 1 at the same ψ (any order).
    min_amplitude : float, optional
        |H| threshold (measurement units); default 1e-3 × 99th percentile of |H| over all
        homodyne images.

    Returns
    -------
    RatioPhaseResult
        Maps of shape (n_pairs, ...); pairs in the order of their homodyne cameras.

    Raises
    ------
    ValueError
        On shape mismatch, differing f_g or T, or cameras that do not form pairs.
    """
    cams = _camera_set(cameras)
    m = _measurement_array(measurements, cams)
    _check_min_amplitude(min_amplitude)
    pairs = _require_pairs(cams)
    flat, shape, finite = _flatten(m)
    per_pair = _ratio_per_phase(flat, cams, pairs, min_amplitude)
    ratio, hom_amp = per_pair["ratio"], per_pair["homodyne_amplitude"]
    valid = per_pair["valid"] & finite
    doppler_phase = _ratio_to_doppler_phase(np.where(valid, ratio, 0.0))
    vel, dopp = _doppler_to_velocity(doppler_phase, cams)

    def out(a):
        return np.where(valid, a, np.nan).reshape((len(pairs),) + shape)

    return RatioPhaseResult(
        phase=np.array([cams.phase_rad[i] for i, _ in pairs]),
        ratio=out(ratio),
        velocity=out(vel),
        doppler_hz=out(dopp),
        valid=valid.reshape((len(pairs),) + shape),
        homodyne_amplitude=hom_amp.reshape((len(pairs),) + shape),
    )


def _require_pairs(cams: _CameraSet):
    pairs = _ratio_pairs(cams)
    if pairs is None:
        raise ValueError(
            "method='ratio' needs every camera in a homodyne (h=0) / heterodyne (h=1) pair "
            f"with the same phase and exposure window; got h = {cams.heterodyne.tolist()}, "
            f"ψ = {cams.phase_rad.tolist()} rad, window offsets {cams.window_offset.tolist()} T"
        )
    return pairs


def _velocity_ratio(flat, cams, min_amplitude):
    pairs = _require_pairs(cams)
    per_pair = _ratio_per_phase(flat, cams, pairs, min_amplitude)
    # The least-squares slope of E against H over all pairs, blind to a linear brightness
    # change (module docstring); a pair with H ≈ 0 adds ≈ 0 to both sums.
    hom, het = per_pair["homodyne"], per_pair["heterodyne"]
    total = np.sum(hom * hom, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        fused = np.sum(het * hom, axis=0) / total
    signal = np.max(per_pair["homodyne_amplitude"], axis=0) > per_pair["threshold"]
    ok = signal & (total > 0) & np.isfinite(fused) & (fused < 1.0)
    doppler_phase = _ratio_to_doppler_phase(np.where(ok, fused, 0.0))
    return doppler_phase, ok


def _velocity_fit(flat, cams, min_amplitude, max_doppler_hz):
    _require_sinusoid(cams, "method='fit' assumes the low-pass sinusoid model")
    reason = _velocity_identifiable(cams)
    if reason is not None:
        raise ValueError(reason)
    max_phase = 2.0 * np.pi * max_doppler_hz * cams.exposure_s
    spacing = 2.0 * max_phase / (_grid_points(cams) - 1)
    # Windows at different times give the residual several deep minima, whose depths on
    # the grid can mislead: refine the deepest few and keep the best.
    candidates = 1 if not np.any(cams.window_offset) else _SCHEDULE_CANDIDATES
    doppler_phase, best_rss = None, None
    for start in _grid_search(flat, cams, max_phase, candidates):
        a = _gauss_newton(flat, start, cams, max_step=spacing, max_phase=max_phase)
        if doppler_phase is None:
            doppler_phase, best_rss = a, _linear_fit(flat, a, cams)["rss"]
            continue
        rss = _linear_fit(flat, a, cams)["rss"]
        better = rss < best_rss
        doppler_phase, best_rss = np.where(better, a, doppler_phase), np.where(better, rss, best_rss)
    # Per-pixel identifiability: the data must respond to a beyond what Z can absorb.
    fit = _linear_fit(flat, doppler_phase, cams)
    _, jac_perp = _projected_sensitivity(fit, doppler_phase, cams)
    z_abs = np.hypot(fit["x"], fit["y"])
    scale = z_abs * np.sqrt(np.sum(cams.half_g1**2))
    with np.errstate(divide="ignore", invalid="ignore"):
        sensitivity = np.sqrt(np.sum(jac_perp * jac_perp, axis=0)) / scale
    signal = np.mean(cams.half_g1) * z_abs
    threshold = _default_threshold(_data_amplitude(flat), min_amplitude)
    ok = (
        (signal > threshold)
        & (sensitivity > _MIN_SENSITIVITY)
        & (np.abs(doppler_phase) < max_phase)  # at the bound: outside the search range
        & np.isfinite(doppler_phase)
    )
    return doppler_phase, ok, threshold


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
) -> VelocityResult:
    """Per-pixel radial velocity (and depth, amplitude) from D-ToF measurements.

    Parameters
    ----------
    measurements : array_like, shape (n_cameras, ...), or a RenderResult
        Rendered (or sensor-reconstructed) measurements, one image per camera, in the
        units of the standard image times g1/2. A :class:`~dopplertof.render.RenderResult`
        gives its measurements, cameras, standard errors and covariance at once.
    cameras : sequence of n_cameras camera configurations
        Sharing f_g (Hz) and T (s). See the module docstring. Cameras in different
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
        invalid. Default 5 % of the unambiguous speed c/(4 f_g T) (83 m/s at 30 MHz,
        1.5 ms).
    min_amplitude : float, optional
        Signal amplitude (measurement units) at or below which a pixel is invalid:
        the largest |H_i| over the phases for the ratio, (g1/2)|Z| for the fit (g1/2
        averaged over the cameras). Default: 1e-3 × the 99th percentile over the image of
        |H_i| (ratio) or of the data amplitude sqrt(2 mean_i m_i²) (fit; unlike the fitted
        amplitude it cannot be inflated by ill-conditioned pixels).
    method : {"auto", "ratio", "fit"}
        ``"auto"`` uses the ratio when the cameras are matched h=0/h=1 pairs, else the fit.
    max_doppler_hz : float, optional
        Fit only: the search range |Δf| (Hz); default 1/(2T), i.e. |a| ≤ π. At f_g = 30
        MHz, T = 1.5 ms that is |v| ≤ 1665 m/s.

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
        only homodyne), ``method="fit"`` is used with a non-sinusoidal waveform, or
        ``method="ratio"`` with cameras that are not matched pairs.

    Examples
    --------
    The model's own measurements of a surface 2 m away receding at 10 m/s give 10 m/s back:

    >>> import math, dopplertof as dt
    >>> cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    >>> m = dt.reconstruct.model_measurements([1.0], 2.0, 10.0, cameras)
    >>> result = dt.reconstruct.velocity(m, cameras)
    >>> result.method, round(float(result.velocity[0]), 6)
    ('ratio', 10.0)
    """
    if hasattr(measurements, "measurements"):  # a RenderResult
        result = measurements
        cameras = result.cameras if cameras is None else cameras
        measurements = result.measurements
        if measurement_stderr is None and measurement_covariance is None:
            measurement_covariance = result.maps.get("measurement_covariance")
            measurement_stderr = result.measurement_stderr
    if cameras is None:
        raise ValueError("velocity() needs the cameras (or a RenderResult)")
    cams = _camera_set(cameras)
    m = _measurement_array(measurements, cams)
    _check_min_amplitude(min_amplitude)
    if method not in ("auto", "ratio", "fit"):
        raise ValueError(f"method must be 'auto', 'ratio' or 'fit', got {method!r}")
    if max_doppler_hz is None:
        max_doppler_hz = 0.5 / cams.exposure_s
    if not (np.isfinite(max_doppler_hz) and max_doppler_hz > 0):
        raise ValueError(f"max_doppler_hz must be a finite number > 0, got {max_doppler_hz!r}")
    if method == "auto":
        method = "ratio" if _ratio_pairs(cams) is not None else "fit"

    flat, shape, finite = _flatten(m)
    if method == "ratio":
        doppler_phase, ok = _velocity_ratio(flat, cams, min_amplitude)
        depth_threshold = None
    else:
        doppler_phase, ok, depth_threshold = _velocity_fit(
            flat, cams, min_amplitude, max_doppler_hz
        )
    ok &= finite
    vel, dopp = _doppler_to_velocity(doppler_phase, cams)

    # Depth and amplitude: the linear part at the recovered Doppler phase.
    a_for_depth = np.where(ok, doppler_phase, 0.0)
    depth_m, amplitude, signal, fit = _depth_and_amplitude(flat, a_for_depth, cams)
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
    )
    covariance = _covariance(measurement_stderr, measurement_covariance, m.shape)
    if covariance is None:
        return result
    options = dict(min_amplitude=min_amplitude, method=method, max_doppler_hz=max_doppler_hz)
    v_err, d_err = _propagated_errors(m, cameras, covariance, options)
    limit = 0.05 * unambiguous_speed_m_s(cams) if max_velocity_stderr is None else float(max_velocity_stderr)
    if not (np.isfinite(limit) and limit > 0):
        raise ValueError(f"max_velocity_stderr must be a finite number of m/s > 0, got {max_velocity_stderr!r}")
    keep = result.valid & np.isfinite(v_err) & (v_err <= limit)
    result.valid = keep
    result.velocity = np.where(keep, result.velocity, np.nan)
    result.doppler_hz = np.where(keep, result.doppler_hz, np.nan)
    result.velocity_stderr = np.where(keep, v_err, np.nan)
    result.depth_stderr = np.where(np.isfinite(result.depth), d_err, np.nan)
    return result


def unambiguous_speed_m_s(cams) -> float:
    """The radial speed c/(4 f_g T) at which the Doppler phase over the exposure reaches π."""
    cams = cams if isinstance(cams, _CameraSet) else _camera_set(cams)
    return SPEED_OF_LIGHT_M_S / (4.0 * cams.frequency_hz * cams.exposure_s)


def _covariance(stderr, covariance, shape):
    """(n, n, pixels...) covariance from either argument, or None."""
    n = shape[0]
    if covariance is not None:
        c = np.asarray(covariance, dtype=np.float64)
        if c.shape != (n, n) + shape[1:]:
            raise ValueError(f"measurement_covariance must have shape {(n, n) + shape[1:]}, got {c.shape}")
        return c
    if stderr is None:
        return None
    e = np.asarray(stderr, dtype=np.float64)
    if e.shape != shape:
        raise ValueError(f"measurement_stderr must have the measurements' shape {shape}, got {e.shape}")
    c = np.zeros((n, n) + shape[1:])
    for i in range(n):
        c[i, i] = e[i] ** 2
    return c


def _propagated_errors(m, cameras, covariance, options):
    """Delta method: the velocity's and depth's Jacobians in the measurements by central
    differences (steps of 1e-3 standard errors, where the estimators are locally linear),
    then σ² = J Σ Jᵀ per pixel."""
    n = m.shape[0]
    sigma = np.sqrt(np.maximum(np.einsum("ii...->i...", covariance), 0.0))
    step = 1e-3 * np.where(sigma > 0, sigma, 1.0)
    jac_v = np.empty_like(m)
    jac_d = np.empty_like(m)
    for i in range(n):
        up, down = m.copy(), m.copy()
        up[i] += step[i]
        down[i] -= step[i]
        plus = velocity(up, cameras, **options)
        minus = velocity(down, cameras, **options)
        jac_v[i] = (plus.velocity - minus.velocity) / (2 * step[i])
        jac_d[i] = (plus.depth - minus.depth) / (2 * step[i])
    var_v = np.einsum("i...,ij...,j...->...", jac_v, covariance, jac_v)
    var_d = np.einsum("i...,ij...,j...->...", jac_d, covariance, jac_d)
    return np.sqrt(np.maximum(var_v, 0.0)), np.sqrt(np.maximum(var_d, 0.0))





def depth(measurements, cameras: Sequence, *, min_amplitude: float | None = None) -> np.ndarray:
    """Per-pixel distance (m) at mid-exposure, modulo the ambiguity range c/(2 f_g).

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
    measurements : array_like, shape (n_cameras, ...)
    cameras : sequence of n_cameras camera configurations (shared f_g, T)
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
    cams = _camera_set(cameras)
    m = _measurement_array(measurements, cams)
    _check_min_amplitude(min_amplitude)
    sinusoid = all(w == "sinusoidal" for w in cams.waveforms)
    determines_velocity = _ratio_pairs(cams) is not None or _velocity_identifiable(cams) is None
    # generic Doppler phase when it is fitted, a = 0 when it is not
    probe = np.array([0.123 if sinusoid and determines_velocity else 0.0])
    if _column_rank(*_design_columns(probe, cams)) < 2:
        raise ValueError(
            "depth needs at least two independent phase measurements (e.g. homodyne at "
            f"ψ = 0 and π/2); got h = {cams.heterodyne.tolist()}, "
            f"ψ = {cams.phase_rad.tolist()} rad"
        )
    if sinusoid and determines_velocity:
        return velocity(m, cameras, min_amplitude=min_amplitude).depth
    flat, shape, finite = _flatten(m)
    depth_m, _, signal, fit = _depth_and_amplitude(flat, np.zeros(flat.shape[1]), cams)
    threshold = _default_threshold(_data_amplitude(flat), min_amplitude)
    ok = finite & fit["full_rank"] & (signal > threshold)
    return np.where(ok, depth_m, np.nan).reshape(shape)


def ambiguity_range_m(modulation_frequency_hz: float) -> float:
    """Unambiguous depth range c/(2 f_g) (m) of a co-located ToF camera."""
    if not (np.isfinite(modulation_frequency_hz) and modulation_frequency_hz > 0):
        raise ValueError(
            f"modulation_frequency_hz must be > 0, got {modulation_frequency_hz!r}"
        )
    return SPEED_OF_LIGHT_M_S / (2.0 * modulation_frequency_hz)
