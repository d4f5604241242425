"""The measurement model of :mod:`dopplertof.reconstruct`: the camera set, the exposure
kernels F, G, H (beat, radiance ramp, radiance curvature), the linear design of one pixel
for given Doppler phase and brightness slope, the forward model, and reading the data."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..modulation import SPEED_OF_LIGHT_M_S
from .frequencies import _frequency_groups


DEFAULT_RELATIVE_MIN_AMPLITUDE = 1e-3
"""Default ``min_amplitude`` as a fraction of the 99th-percentile amplitude of the image."""


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
    first_start_s: float | None = None  # the first camera's exposure_start (s; None: the render's)

    @property
    def depth_range_m(self) -> float:
        """c/(2 f_g): the depth is known modulo this (m)."""
        return ambiguity_range_m(self.frequency_hz)

    @property
    def wavenumber(self) -> float:
        """k = 2π f_g / c (rad per metre of optical path)."""
        return 2.0 * np.pi * self.frequency_hz / SPEED_OF_LIGHT_M_S

    def __len__(self) -> int:
        return len(self.heterodyne)


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


def _ramp_kernel(x: np.ndarray) -> np.ndarray:
    """G(x) = ∫_0^1 (s − ½) e^{ixs} ds: the response to a radiance ramp (complex).

    G = (e^{ix} − F(x))/(ix) − F(x)/2, with its Taylor series near 0, where that cancels
    (G(x) = Σ_n (ix)^n/n! · n/(2(n+1)(n+2))).
    """
    x = np.asarray(x, dtype=np.float64)
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)  # placeholder avoids 0/0 in the branch not taken
    f_re, f_im = _beat_kernel(xs)
    f = f_re + 1j * f_im
    direct = (np.exp(1j * xs) - f) / (1j * xs) - 0.5 * f
    ix = 1j * x
    series = ix / 12.0 + ix**2 / 24.0 + ix**3 / 80.0 + ix**4 / 360.0 + ix**5 / 2016.0
    return np.where(small, series, direct)


def _curvature_kernel(x: np.ndarray) -> np.ndarray:
    """H(x) = ∫_0^1 (s − ½)² e^{ixs} ds = e^{ix/2} J(x), J(x) = ∫_{-½}^{½} u² cos(xu) du
    (complex), with J's Taylor series near 0, where its closed form cancels."""
    x = np.asarray(x, dtype=np.float64)
    small = np.abs(x) < 0.1
    xs = np.where(small, 1.0, x)  # placeholder avoids 0/0 in the branch not taken
    half = 0.5 * xs
    direct = np.sin(half) / (2.0 * xs) + 2.0 * np.cos(half) / xs**2 - 4.0 * np.sin(half) / xs**3
    series = 1.0 / 12.0 - x**2 / 160.0 + x**4 / 10752.0
    return np.exp(0.5j * x) * np.where(small, series, direct)


def _kernel(doppler_phase: np.ndarray, cams: _CameraSet, brightness=0.0, wrt: str | None = None) -> np.ndarray:
    """K_i, shape (n_cameras, N): camera i measures (g1_i/2) Re{Z K_i} (module docstring,
    brightness).

    With τ = δ_i + s the time in exposures from the first window's opening, the radiance
    A(τ)/A_mid = 1 + β (τ − ½) + q (τ − ½)², q = ¾ β² (the inverse-square law of a
    surface lit from the camera whose distance changes linearly, to second order), so

        K_i = e^{i(ψ_i + a δ_i)} [(1 + β δ_i + q δ_i²) F(x_i) + (β + 2 q δ_i) G(x_i) + q H(x_i)],

    x_i = 2π h_i + a, F the beat kernel, G and H the ramp and curvature kernels.

    Parameters
    ----------
    doppler_phase : ndarray, shape (N,)
        a = k u T (rad) per pixel.
    brightness : float or ndarray, shape (N,)
        β, the relative change of radiance over one exposure (dimensionless).
    wrt : {None, "a", "beta"}
        Return ∂K/∂a or ∂K/∂β instead.
    """
    a = np.asarray(doppler_phase, dtype=np.float64)[None, :]
    beta = np.broadcast_to(np.asarray(brightness, dtype=np.float64), a.shape[1:])[None, :]
    x = 2.0 * np.pi * cams.heterodyne[:, None] + a
    delta = cams.window_offset[:, None]
    f_re, f_im = _beat_kernel(x)
    f = f_re + 1j * f_im
    g, h = _ramp_kernel(x), _curvature_kernel(x)
    rotation = np.exp(1j * (cams.phase_rad[:, None] + delta * a))
    q = 0.75 * beta * beta
    if wrt == "beta":
        dq = 1.5 * beta
        return rotation * ((delta + dq * delta * delta) * f + (1.0 + 2.0 * dq * delta) * g + dq * h)
    inner = (1.0 + beta * delta + q * delta * delta) * f + (beta + 2.0 * q * delta) * g + q * h
    if wrt is None:
        return rotation * inner
    d_re, d_im = _beat_kernel_derivative(x)
    step = 1e-5  # G', H' by central differences: ample for Gauss-Newton steps, which only need a descent direction
    g_prime = (_ramp_kernel(x + step) - _ramp_kernel(x - step)) / (2.0 * step)
    h_prime = (_curvature_kernel(x + step) - _curvature_kernel(x - step)) / (2.0 * step)
    return rotation * ((1.0 + beta * delta + q * delta * delta) * (d_re + 1j * d_im)
                       + (beta + 2.0 * q * delta) * g_prime + q * h_prime + 1j * delta * inner)


def _design_columns(doppler_phase: np.ndarray, cams: _CameraSet, brightness=0.0, wrt: str | None = None):
    """Columns of the linear model m = c1 Re Z + c2 Im Z for given a and β (or their
    derivatives, ``wrt``), each of shape (n_cameras, N)."""
    k = _kernel(doppler_phase, cams, brightness, wrt)
    s = cams.half_g1[:, None]
    return s * k.real, -s * k.imag


def _exposure_average(amplitude, depth_m, velocity_m_s, brightness, cams: _CameraSet) -> np.ndarray:
    """Closed-form measurements (n_cameras, *shape) for the co-located sinusoid model."""
    shape = amplitude.shape
    path_rate = 2.0 * velocity_m_s.ravel()
    doppler_phase = cams.wavenumber * path_rate * cams.exposure_s
    # depth is at mid-exposure; the model is parametrised at t = 0
    path_start_m = 2.0 * depth_m.ravel() - 0.5 * path_rate * cams.exposure_s
    z = amplitude.ravel() * np.exp(1j * cams.wavenumber * path_start_m)
    kernel = _kernel(doppler_phase, cams, brightness.ravel())
    return (cams.half_g1[:, None] * (z[None, :] * kernel).real).reshape((len(cams),) + shape)


def model_measurements(amplitude, depth_m, velocity_m_s, cameras: Sequence, brightness=0.0) -> np.ndarray:
    """Forward model: exposure-averaged low-pass sinusoid of one path per pixel.

    The light is co-located with the camera (optical path L = 2 × distance, dL/dt =
    2 × radial velocity), the velocity is constant and the radiance follows the
    inverse-square law to second order in β (over every camera's window: module
    docstring). The inverse of :func:`velocity` and :func:`depth`.

    Parameters
    ----------
    amplitude : array_like, shape (...)
        Radiance A of the path at mid-exposure (units of the standard intensity image).
    depth_m : array_like, broadcastable to ``amplitude``
        Distance (m) at mid-exposure, t = T/2 (of the first camera's window).
    velocity_m_s : array_like, broadcastable to ``amplitude``
        Radial velocity (m/s), positive when the distance grows.
    cameras : sequence of camera configurations
        Sinusoidal waveform only; see the module docstring for the attributes. Cameras at
        different modulation frequencies are modelled frequency by frequency, each from the
        window of its first camera.
    brightness : array_like, broadcastable to ``amplitude``, default 0
        β: the radiance is A (1 + β τ' + ¾ β² τ'²), τ' = t/T − ½ with t from the first
        window's opening (dimensionless; −2 v T/d for a surface lit from the camera: the
        inverse-square law to second order).

    Returns
    -------
    ndarray, shape (n_cameras, ...)
        m_i = (g1_i/2) Re{A e^{i k L(0)} K_i} (K_i: ``_kernel``), a = 2 k v T, δ_i the
        camera's window offset; at β = 0: (g1_i A/2) [sin(θ_i + 2π h_i + a) − sin θ_i]/(2π h_i
        + a), θ_i = ψ_i + k L(0) + a δ_i.

    Raises
    ------
    ValueError
        If the cameras are invalid or not sinusoidal.
    """
    cameras = [cameras] if hasattr(cameras, "modulation_frequency") else list(cameras)
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (amplitude, depth_m, velocity_m_s, brightness)))
    out = np.empty((len(cameras),) + arrays[0].shape)
    for group in _frequency_groups(cameras):
        cams = _camera_set([cameras[i] for i in group])
        _require_sinusoid(cams, "model_measurements uses the closed form of the sinusoid")
        out[group] = _exposure_average(*arrays, cams)
    return out


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
        first_start_s=getattr(cameras[0], "exposure_start", None),
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


def _flatten(m: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
    """(n, ...) → (n, N) with non-finite pixels zeroed, the pixel shape and a finite mask."""
    shape = m.shape[1:]
    flat = m.reshape(m.shape[0], -1)
    finite = np.all(np.isfinite(flat), axis=0)
    return np.where(finite, flat, 0.0), shape, finite


def _fits_brightness(cams: _CameraSet) -> bool:
    """Whether the estimators fit the brightness slope β: for sinusoids in one window. Across
    windows β would make several Doppler phases fit exactly (four unknowns, and four cameras
    in the usual schedule), so the radiance is taken as constant there (module docstring)."""
    return not np.any(cams.window_offset) and all(w == "sinusoidal" for w in cams.waveforms)


def _doppler_to_velocity(doppler_phase, cams: _CameraSet):
    """(velocity m/s, Δf Hz) from a = k u T, co-located light (u = 2 v)."""
    path_rate = doppler_phase / (cams.wavenumber * cams.exposure_s)
    return 0.5 * path_rate, doppler_phase / (2.0 * np.pi * cams.exposure_s)


def ambiguity_range_m(modulation_frequency_hz: float) -> float:
    """Unambiguous depth range c/(2 f_g) (m) of a co-located ToF camera.

    Parameters
    ----------
    modulation_frequency_hz : float, Hz

    Returns
    -------
    float
        m.
    """
    if not (np.isfinite(modulation_frequency_hz) and modulation_frequency_hz > 0):
        raise ValueError(
            f"modulation_frequency_hz must be > 0, got {modulation_frequency_hz!r}"
        )
    return SPEED_OF_LIGHT_M_S / (2.0 * modulation_frequency_hz)
