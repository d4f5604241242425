"""Estimators over any raw-frame list: measurements from tap read-outs, the two-offset
differential-heterodyne velocity, and multi-frequency phase depth; each with its error.

The homodyne/heterodyne ratio and the per-pixel fit are :func:`dopplertof.reconstruct.velocity`
(``method="ratio"`` / ``"fit"``), which takes the frames as cameras and the measurements'
standard errors from :func:`measurements_from_readout`.

All use the low-pass sinusoid model of :mod:`dopplertof.reconstruct`: one path per pixel,
light at the camera, constant radiance and velocity over the exposure,

    m(h, ψ) = (g1/2) Re{Z e^{iψ} F(2π h + a)},   F(x) = (e^{ix} − 1)/(i x),

with Z = A e^{ikL(0)} and a = k u T the Doppler phase (u = 2v). Frames of one offset h at
phases ψ_j with Σ_j e^{2iψ_j} = 0 (0° and 90°; 0°, 90°, 180°, 270°; 0°, 120°, 240°) give
the complex *quadrature* Q_h = (2/n) Σ_j m_j e^{−iψ_j} / (g1/2) = Z F(2π h + a) exactly.

Two-offset differential heterodyne (:func:`two_offset_velocity`). For offsets h₁ ≠ h₂
(beat cycles per exposure) that differ by a whole number, e^{i(2πh₁ + a)} = e^{i(2πh₂ + a)},
so the ratio of quadratures is real and free of amplitude and depth:

    ρ = Q_{h₁}/Q_{h₂} = (2π h₂ + a)/(2π h₁ + a)   ⇒   a = 2π (h₂ − ρ h₁)/(ρ − 1),

taken as ρ = Re(Q₁ conj Q₂)/|Q₂|² (its least-squares value); v = a c/(4π f T). With
h = ±½ (Hu et al.'s offsets) both quadratures are strong for any velocity
(|F(±π)| = 2/π); whole offsets (h = 1, −1) vanish for a still target (F(2πh) = 0), so
their ratio is ill-conditioned at small a; h = (1, 0) is Heide's homodyne/heterodyne pair.

Error: the delta method through the closed form (σ_v from the measurements' standard
errors). Model error: a radiance changing over the exposure, A(t) = A₀(1 + β(t/T − ½)) (a
surface at distance s moving by Δs = vT brightens as 1/s²: β = −2Δs/s), moves ρ off the
real axis at first order in β, its real part at second: for h = ±½ the velocity is biased
by ≈ β²/(π a) relative, = 2|Δs|/(π k s²) (6·10⁻⁴ for the moving plane at 5 m, 10 m/s,
30 MHz, 1.5 ms; as for Heide's pair). Whole offsets ±1 fare worse: about (β/a)²/2
= 1/(2 k² s²) (5 % there).

Two-capture velocity (:func:`two_capture_velocity`), for chips whose light and pixel share
one clock (no heterodyne offset): two homodyne captures of a quadrature set, the second
the first's frames repeated Δt later (in one window each or frame after frame), give the
change of the depth phase θ = kL between them, so v = Δθ c/(4π f Δt), |v| < c/(4 f Δt)
without ambiguity (motion within a capture alters both captures alike). The phase of Q₀
is the depth phase exactly for the sinusoid in one window; for another correlation (a square wave's triangle,
a code: the "wiggling" of real chips) and for frames taken one after another (the phase
runs on between them) the phase is found by Newton's method through the frames' own
low-pass correlation, which must be monotone in θ, jointly with v. Error: the delta
method, σ_θ = Im(conj(Q) ∂Q/∂m)/(|Q|² ∂φ/∂θ) per capture.

Multi-frequency depth (:func:`multifrequency_depth`): per frequency the phase of Q₀
(homodyne) gives the distance at mid-exposure modulo c/(2f); the distance in
[0, ``max_depth_m``) most consistent with every frequency (weighted by 1/σ²) is chosen by
searching the wrap counts of the most precise frequency, then averaged over the unwrapped
frequencies. Its error: σ = (Σ_f 1/σ_f²)^{−1/2}, valid where the unwrapping is right.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..modulation import SPEED_OF_LIGHT_M_S
from ..reconstruct.model import _camera_set

_PHASE_SUM_TOLERANCE = 1e-9
_MAX_WRAP_CANDIDATES = 100_000


@dataclass
class Measurements:
    """Measurements estimated from a sensor read-out (:func:`measurements_from_readout`).

    Attributes
    ----------
    measurements : ndarray (n, H, W). In rendered units (radiance × the correlation
        weight), as a render's ``measurements``; NaN where a tap saturated.
    stderr : ndarray (n, H, W). Their standard errors from the noise model.
    cameras : list of n frames: the sensor's frames (2 taps), or each frame and its copy
        advanced by 90° (4 taps: taps 0 − 2 and 1 − 3).
    """

    measurements: np.ndarray
    stderr: np.ndarray
    cameras: list


def measurements_from_readout(sensor, dn) -> Measurements:
    """The frames' measurements from a read-out's digital numbers, with standard errors.

    2 taps: m̂ = (DN_A − DN_B) g / (c κ T) (black level and ambient light cancel; g the
    inverse conversion gain, c the contrast, κT the electrons per unit over the exposure).
    4 taps: m̂(ψ) = 2 (DN₀ − DN₂) g / (c κ T) and m̂(ψ + π/2) = 2 (DN₁ − DN₃) g / (c κ T)
    (an antiperiodic demodulation: the sinusoid or a square). The variance of each tap is
    :meth:`~dopplertof.sensors.noise.Silicon.tap_variance_e2` at its observed charge.

    Parameters
    ----------
    sensor : :class:`~dopplertof.sensors.Sensor` with 2 or 4 taps.
    dn : ndarray (frames, taps, H, W). ``sensor.read_out(result, seed=...)``.

    Returns
    -------
    Measurements

    Raises
    ------
    ValueError
        For a 1-tap sensor (a single tap does not separate the signal from the light's
        mean), a 4-tap sensor with a demodulation that is not antiperiodic, or a read-out of
        another shape.
    """
    if sensor.taps == 1:
        raise ValueError("measurements_from_readout: a 1-tap pixel does not separate the modulated signal from the mean light; use a 2- or 4-tap sensor")
    dn = np.asarray(dn)
    if dn.ndim < 2 or dn.shape[:2] != (len(sensor.frames), sensor.taps):
        raise ValueError(f"measurements_from_readout: dn must have shape ({len(sensor.frames)}, {sensor.taps}, ...), got {dn.shape}")
    if sensor.taps == 4:
        skewed = [i for i, f in enumerate(sensor.frames) if f.coded and f.sensor_code.shifted_sum(2) > 1e-9]
        if skewed:
            raise ValueError(f"measurements_from_readout: frames {skewed} demodulate with a code that is not antiperiodic (s(θ + π) = −s(θ)); taps 0 − 2 of a 4-tap pixel then do not give its measurement")
    silicon = sensor.noise
    electrons = (dn.astype(np.float64) - silicon.black_level_dn) * silicon.gain_e_per_dn
    variance = silicon.tap_variance_e2(np.clip(electrons, 0.0, None))
    saturated = (dn >= silicon.max_dn) | (electrons >= silicon.full_well_e)
    # 2 taps: A − B = c κT M; 4 taps: A₀ − A₂ = c κT (M − (−M))/4
    scale = np.array([0.5 * sensor.taps / (silicon.contrast(f.modulation_frequency) * silicon.electrons_per_unit_s * f.exposure) for f in sensor.frames])
    scale = scale.reshape(-1, *([1] * (dn.ndim - 2)))
    pairs = [(0, 1)] if sensor.taps == 2 else [(0, 2), (1, 3)]
    values, errors, cameras = [], [], []
    for k, (i, j) in enumerate(pairs):
        bad = saturated[:, i] | saturated[:, j]
        values.append(np.where(bad, np.nan, (electrons[:, i] - electrons[:, j]) * scale))
        errors.append(np.where(bad, np.nan, np.sqrt(variance[:, i] + variance[:, j]) * scale))
        cameras += [f if k == 0 else _advanced(f) for f in sensor.frames]
    return Measurements(np.concatenate(values), np.concatenate(errors), cameras)


def _advanced(frame):
    return dataclasses.replace(frame, phase=frame.phase + math.pi / 2)


# --------------------------------------------------------------------------- quadratures


def _quadratures(m, cams, indices_by_offset):
    """Q_h per offset (module docstring) and its Jacobian in the measurements:
    {h: (Q (N,), dQ/dm (n, 1) complex)}."""
    out = {}
    for h, idx in indices_by_offset.items():
        psi = cams.phase_rad[idx]
        if abs(np.sum(np.exp(2j * psi))) > _PHASE_SUM_TOLERANCE * len(idx) or len(idx) < 2:
            raise ValueError(
                f"offset h={h:g}: phases {np.degrees(psi).round(6).tolist()} deg do not give a quadrature; "
                "use phases with sum exp(2i psi) = 0 (0 and 90 deg; 0, 90, 180, 270 deg; 0, 120, 240 deg)"
            )
        weights = np.zeros(len(cams), np.complex128)
        weights[idx] = (2.0 / len(idx)) * np.exp(-1j * psi) / cams.half_g1[idx]
        out[h] = weights
    return {h: (weights @ m, weights) for h, weights in out.items()}


def _group_by_offset(cams):
    groups = {}
    for i, h in enumerate(cams.heterodyne):
        groups.setdefault(float(h), []).append(i)
    return {h: np.array(idx) for h, idx in groups.items()}


def _sinusoid_single_window(cams, what):
    others = sorted({w for w in cams.waveforms if w != "sinusoidal"})
    if others:
        raise ValueError(f"{what} uses the sinusoid's closed form; got waveform(s) {others}")
    if np.any(cams.window_offset != 0):
        raise ValueError(f"{what} needs every frame in one exposure window (same exposure_start)")


def _variance(jacobian, stderr):
    """Σ_i J_i² σ_i² per pixel (independent measurements)."""
    return np.sum((jacobian * stderr) ** 2, axis=0)


@dataclass
class TwoOffsetResult:
    """:func:`two_offset_velocity`'s per-pixel maps.

    Attributes
    ----------
    velocity : ndarray. Radial velocity (m/s), positive when the distance grows; NaN
        where invalid.
    velocity_stderr : ndarray or None. Its standard error (m/s) from the measurements'.
    doppler_hz : ndarray. Doppler shift Δf = a/(2πT) (Hz).
    ratio : ndarray. ρ = Q_{h₁}/Q_{h₂}.
    valid : ndarray of bool. Finite, |Q_{h₂}| above ``min_amplitude``.
    """

    velocity: np.ndarray
    velocity_stderr: np.ndarray | None
    doppler_hz: np.ndarray
    ratio: np.ndarray
    valid: np.ndarray


def two_offset_velocity(measurements, cameras, *, measurement_stderr=None, min_amplitude=None) -> TwoOffsetResult:
    """Radial velocity from two whole heterodyne offsets (module docstring), in closed form.

    Parameters
    ----------
    measurements : array_like (n, ...). One image per camera (frame).
    cameras : sequence of n cameras (or raw frames): one f and T, one window, sinusoid,
        exactly two offsets h₁ ≠ h₂ that differ by a whole number (the first in camera
        order is h₁; ±½ recommended), each at phases with Σ e^{2iψ} = 0.
    measurement_stderr : array_like (n, ...), optional. Independent standard errors;
        gives ``velocity_stderr``.
    min_amplitude : float, optional. |Q_{h₂}| (radiance units) at or below which a pixel is
        invalid; default 1e-3 × its 99th percentile over the image.

    Returns
    -------
    TwoOffsetResult

    Raises
    ------
    ValueError
        For cameras that do not form such a set, or shapes that do not match.
    """
    cams = _camera_set(cameras)
    _sinusoid_single_window(cams, "two_offset_velocity")
    m = np.asarray(measurements, dtype=np.float64)
    if m.ndim < 1 or m.shape[0] != len(cams):
        raise ValueError(f"measurements must have shape ({len(cams)}, ...), got {m.shape}")
    groups = _group_by_offset(cams)
    offsets = list(groups)
    if len(offsets) != 2 or abs(offsets[0] - offsets[1] - round(offsets[0] - offsets[1])) > 1e-12:
        raise ValueError(f"two_offset_velocity needs exactly two heterodyne offsets h that differ by whole beat cycles per exposure, got {sorted(offsets)}")
    h1, h2 = offsets
    quad = _quadratures(m.reshape(len(cams), -1), cams, groups)
    (q1, w1), (q2, w2) = quad[h1], quad[h2]
    power = np.abs(q2) ** 2
    amplitude = np.abs(q2)
    threshold = (1e-3 * np.nanpercentile(amplitude, 99)) if min_amplitude is None else float(min_amplitude)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.real(q1 * np.conj(q2)) / power
        a = 2 * math.pi * (h2 - rho * h1) / (rho - 1.0)
    valid = np.isfinite(a) & (amplitude > threshold)
    to_velocity = SPEED_OF_LIGHT_M_S / (4 * math.pi * cams.frequency_hz * cams.exposure_s)
    shape = m.shape[1:]
    stderr = None
    if measurement_stderr is not None:
        sigma = np.asarray(measurement_stderr, dtype=np.float64)
        if sigma.shape != m.shape:
            raise ValueError(f"measurement_stderr must have the measurements' shape {m.shape}, got {sigma.shape}")
        # dρ/dm_i from Q's linearity, then da/dρ = 2π (h₁ − h₂)/(ρ − 1)²
        with np.errstate(divide="ignore", invalid="ignore"):
            d_rho = (np.real(w1[:, None] * np.conj(q2)[None] + q1[None] * np.conj(w2)[:, None]) - 2 * rho[None] * np.real(w2[:, None] * np.conj(q2)[None])) / power[None]
            d_a = 2 * math.pi * (h1 - h2) / (rho - 1.0) ** 2
            stderr = np.sqrt(_variance(d_rho * d_a[None], sigma.reshape(len(cams), -1))) * to_velocity
        stderr = np.where(valid, stderr, np.nan).reshape(shape)
    return TwoOffsetResult(
        velocity=np.where(valid, a * to_velocity, np.nan).reshape(shape),
        velocity_stderr=stderr,
        doppler_hz=np.where(valid, a / (2 * math.pi * cams.exposure_s), np.nan).reshape(shape),
        ratio=rho.reshape(shape),
        valid=valid.reshape(shape),
    )


# --------------------------------------------------------------------------- two captures

_NEWTON_STEPS = 12
_NEWTON_PROBE_RAD = 1e-4


@dataclass
class TwoCaptureResult:
    """:func:`two_capture_velocity`'s per-pixel maps.

    Attributes
    ----------
    velocity : ndarray. Radial velocity (m/s), positive when the distance grows; NaN
        where invalid.
    velocity_stderr : ndarray or None. Its standard error (m/s) from the measurements'.
    phase_change_rad : ndarray. Δθ, the depth phase's change between the captures (rad).
    interval_s : float. Δt, between the two captures (s).
    valid : ndarray of bool. Finite, both captures' |Q₀| above ``min_amplitude``, and a
        phase that grows with the depth there (a correlation that folds has no unique one).
    """

    velocity: np.ndarray
    velocity_stderr: np.ndarray | None
    phase_change_rad: np.ndarray
    interval_s: float
    valid: np.ndarray


def _capture_quadrature(frames, weights, theta, drift):
    """Q₀ of a capture (its quadrature ``weights``) whose depth phase is ``theta`` at its
    first frame and ``theta + drift[j]`` at frame j, from the frames' low-pass correlation
    (unit amplitude)."""
    from ..modulation import lowpass_weight

    return sum(w * np.asarray(lowpass_weight(f, f.phase + theta + d), dtype=np.float64) for f, w, d in zip(frames, weights, drift) if w != 0)


def two_capture_velocity(measurements, cameras, *, measurement_stderr=None, min_amplitude=None) -> TwoCaptureResult:
    """Radial velocity from two homodyne captures Δt apart (module docstring).

    Parameters
    ----------
    measurements : array_like (n, ...). One image per camera (frame).
    cameras : sequence of n cameras (or raw frames) that give ``exposure_start``: one
        frequency f and exposure T, homodyne (h = 0); frames [:n/2] are the first capture,
        at phases with Σ e^{2iψ} = 0 (0°, 90°, 180°, 270°; 0°, 120°, 240°), frames [n/2:]
        the same phases, each a constant Δt after its partner.
    measurement_stderr : array_like (n, ...), optional. Independent standard errors;
        gives ``velocity_stderr``.
    min_amplitude : float, optional. |Q₀| (radiance units) at or below which a pixel is
        invalid in either capture; default 1e-3 × each capture's 99th percentile.

    Returns
    -------
    TwoCaptureResult

    Raises
    ------
    ValueError
        For cameras that do not form such a set, or shapes that do not match.
    """
    frames = list(cameras)
    cams = _camera_set(frames)
    if np.any(cams.heterodyne != 0):
        raise ValueError(f"two_capture_velocity needs homodyne frames (h = 0), got h = {sorted(set(cams.heterodyne.tolist()))}; for heterodyne offsets use two_offset_velocity")
    half = len(frames) // 2
    paired = len(frames) % 2 == 0 and half > 0
    shifts = cams.window_offset[half:] - cams.window_offset[:half] if paired else np.zeros(1)
    same_phases = paired and np.allclose(np.exp(1j * cams.phase_rad[half:]), np.exp(1j * cams.phase_rad[:half]), atol=1e-9)
    if not same_phases or not np.allclose(shifts, shifts[0], rtol=1e-9, atol=1e-12) or not shifts[0] > 0:
        raise ValueError(
            "two_capture_velocity needs two captures of the same phases, the second frame for frame a constant interval after "
            f"the first (frames [:n/2] then [n/2:]); got phases {np.degrees(cams.phase_rad).round(6).tolist()} deg starting at "
            f"{cams.window_offset.round(9).tolist()} x T (give exposure_start, or a result's cameras)"
        )
    idx_1, idx_2, interval = np.arange(half), np.arange(half, len(frames)), float(shifts[0])
    m = np.asarray(measurements, dtype=np.float64)
    if m.ndim < 1 or m.shape[0] != len(cams):
        raise ValueError(f"measurements must have shape ({len(cams)}, ...), got {m.shape}")
    shape = m.shape[1:]
    flat = m.reshape(len(cams), -1)
    quad = _quadratures(flat, cams, {1: idx_1, 2: idx_2})
    to_velocity = SPEED_OF_LIGHT_M_S / (4 * math.pi * cams.frequency_hz * interval * cams.exposure_s)
    sigma = None
    if measurement_stderr is not None:
        sigma = np.asarray(measurement_stderr, dtype=np.float64)
        if sigma.shape != m.shape:
            raise ValueError(f"measurement_stderr must have the measurements' shape {m.shape}, got {sigma.shape}")
        sigma = sigma.reshape(len(cams), -1)
    k_2 = 4 * math.pi * cams.frequency_hz / SPEED_OF_LIGHT_M_S  # d(depth phase)/d(distance): k · 2 (there and back)
    # when frame j of a capture starts after its first: its depth phase runs ahead by k·2·v·that
    lag_s = (cams.window_offset[idx_1] - cams.window_offset[idx_1[0]]) * cams.exposure_s
    observed, ok = [], np.ones(flat.shape[1], bool)
    for key in (1, 2):
        q, w = quad[key]
        amplitude = np.abs(q)
        threshold = (1e-3 * np.nanpercentile(amplitude, 99)) if min_amplitude is None else float(min_amplitude)
        ok &= np.isfinite(amplitude) & (amplitude > threshold)
        observed.append((q, w))
    # Solve arg Q_c(θ_c; v) = arg q_c for θ₁, θ₂ = θ₁ + k·2·v·Δt by Newton on each capture's
    # phase, v from their difference, repeated: exact for any monotone correlation, with
    # the motion between a capture's frames (which shears both captures' phase alike).
    thetas = [np.angle(q) for q, _ in observed]
    velocity = np.zeros(flat.shape[1])
    for _ in range(_NEWTON_STEPS):
        slopes = []
        for c, (q, w) in enumerate(observed):
            frames_c = [frames[i] for i in (idx_1 if c == 0 else idx_2)]
            w_c = w[idx_1 if c == 0 else idx_2]
            drift = [k_2 * velocity * lag for lag in lag_s]
            model = _capture_quadrature(frames_c, w_c, thetas[c], drift)
            ahead = _capture_quadrature(frames_c, w_c, thetas[c] + _NEWTON_PROBE_RAD, drift)
            behind = _capture_quadrature(frames_c, w_c, thetas[c] - _NEWTON_PROBE_RAD, drift)
            slope = np.angle(ahead * np.conj(behind)) / (2 * _NEWTON_PROBE_RAD)
            with np.errstate(divide="ignore", invalid="ignore"):
                thetas[c] = thetas[c] + np.angle(q * np.conj(model)) / slope
            slopes.append(slope)
        with np.errstate(invalid="ignore"):  # NaN where a capture has no light
            change = np.mod(thetas[1] - thetas[0] + math.pi, 2 * math.pi) - math.pi
        velocity = change * to_velocity
    ok &= np.isfinite(velocity) & (slopes[0] > 0) & (slopes[1] > 0)  # a folding correlation has no unique phase
    variances = []
    if sigma is not None:
        for (q, w), slope in zip(observed, slopes):
            with np.errstate(divide="ignore", invalid="ignore"):
                d_phi = np.imag(np.conj(q)[None] * w[:, None]) / (np.abs(q) ** 2)[None]
                variances.append(_variance(d_phi / slope[None], sigma))
    stderr = None if sigma is None else np.where(ok, np.sqrt(variances[0] + variances[1]) * abs(to_velocity), np.nan).reshape(shape)
    return TwoCaptureResult(
        velocity=np.where(ok, velocity, np.nan).reshape(shape),
        velocity_stderr=stderr,
        phase_change_rad=change.reshape(shape),
        interval_s=interval * cams.exposure_s,
        valid=ok.reshape(shape),
    )


# --------------------------------------------------------------------------- depth


@dataclass
class DepthResult:
    """:func:`multifrequency_depth`'s per-pixel maps.

    Attributes
    ----------
    depth : ndarray. Distance (m) at mid-exposure in [0, max_depth_m); NaN where invalid.
    depth_stderr : ndarray or None. Its standard error (m), where the unwrapping is right.
    per_frequency : ndarray (n_frequencies, ...). Each frequency's wrapped distance (m).
    frequencies_hz : tuple. The frequencies, in order of first appearance.
    valid : ndarray of bool.
    """

    depth: np.ndarray
    depth_stderr: np.ndarray | None
    per_frequency: np.ndarray
    frequencies_hz: tuple
    valid: np.ndarray


def _combined_range_m(frequencies_hz) -> float:
    """c/(2 gcd f): the range over which the frequencies' phases repeat together (whole Hz)."""
    g = 0
    for f in frequencies_hz:
        g = math.gcd(g, int(round(f)))
    return SPEED_OF_LIGHT_M_S / (2.0 * g)


def multifrequency_depth(measurements, cameras, *, measurement_stderr=None, max_depth_m=None, min_amplitude=None) -> DepthResult:
    """Phase depth from homodyne frames at one or more frequencies, unwrapped (module docstring).

    Parameters
    ----------
    measurements : array_like (n, ...).
    cameras : sequence of n homodyne (h = 0) sinusoid cameras or raw frames; per frequency
        at least two phases with Σ e^{2iψ} = 0 (a 4-phase or 3-phase set), one exposure T
        per frequency. Frames captured one after another are taken as seeing a still
        target.
    measurement_stderr : array_like (n, ...), optional. Independent standard errors; they
        also weight the frequencies (else weights ∝ f²).
    max_depth_m : float, optional. Search range; default c/(2 gcd f) (the frequencies'
        common ambiguity range), at most ``100000`` wraps of the highest frequency.
    min_amplitude : float, optional. |Q| (radiance units) at or below which a frequency's
        phase is not trusted; default 1e-3 × its 99th percentile.

    Returns
    -------
    DepthResult

    Raises
    ------
    ValueError
        For heterodyne or non-sinusoid frames, a frequency without a quadrature set, or a
        search range with too many wrap candidates (give ``max_depth_m``).
    """
    cameras = list(cameras)
    m = np.asarray(measurements, dtype=np.float64)
    if m.ndim < 1 or m.shape[0] != len(cameras):
        raise ValueError(f"measurements must have shape ({len(cameras)}, ...), got {m.shape}")
    sigma = None if measurement_stderr is None else np.asarray(measurement_stderr, dtype=np.float64)
    if sigma is not None and sigma.shape != m.shape:
        raise ValueError(f"measurement_stderr must have the measurements' shape {m.shape}, got {sigma.shape}")
    by_frequency = {}
    for i, c in enumerate(cameras):
        by_frequency.setdefault(float(c.modulation_frequency), []).append(i)
    frequencies = tuple(by_frequency)
    flat = m.reshape(len(cameras), -1)
    wrapped, variances, ok = [], [], np.ones(flat.shape[1], bool)
    for f, idx in by_frequency.items():
        sub = [cameras[i] for i in idx]
        cams = _camera_set(sub)
        if np.any(cams.heterodyne != 0):
            raise ValueError(f"multifrequency_depth takes homodyne frames (h = 0); at {f:g} Hz got h = {cams.heterodyne.tolist()}")
        others = sorted({w for w in cams.waveforms if w != "sinusoidal"})
        if others:
            raise ValueError(f"multifrequency_depth uses the sinusoid's phase; got waveform(s) {others} at {f:g} Hz")
        cams = _single_window(cams)
        (q, w), = _quadratures(flat[idx], cams, {0.0: np.arange(len(idx))}).values()
        range_m = SPEED_OF_LIGHT_M_S / (2 * f)
        wrapped.append(np.mod(np.angle(q), 2 * math.pi) / (2 * math.pi) * range_m)
        amplitude = np.abs(q)
        threshold = (1e-3 * np.nanpercentile(amplitude, 99)) if min_amplitude is None else float(min_amplitude)
        ok &= np.isfinite(q) & (amplitude > threshold)
        if sigma is not None:
            # dφ/dm_i = Im(conj(Q) dQ/dm_i)/|Q|², d = φ range/2π
            with np.errstate(divide="ignore", invalid="ignore"):
                d_phi = np.imag(np.conj(q)[None] * w[:, None]) / np.abs(q)[None] ** 2
            variances.append(_variance(d_phi, sigma.reshape(len(cameras), -1)[idx]) * (range_m / (2 * math.pi)) ** 2)
        else:
            variances.append(np.full(flat.shape[1], (1.0 / f) ** 2))  # phase noise alike: σ_d ∝ 1/f
    wrapped, variances = np.array(wrapped), np.array(variances)
    ranges = SPEED_OF_LIGHT_M_S / (2 * np.array(frequencies))
    max_depth = _combined_range_m(frequencies) if max_depth_m is None else float(max_depth_m)
    if not (math.isfinite(max_depth) and max_depth > 0):
        raise ValueError(f"max_depth_m must be a finite number > 0, got {max_depth_m!r}")
    best = int(np.argmax(frequencies))
    n_wraps = int(math.ceil(max_depth / ranges[best]))
    if n_wraps > _MAX_WRAP_CANDIDATES:
        raise ValueError(f"a search to {max_depth:g} m spans {n_wraps} wraps of {frequencies[best]:g} Hz; give max_depth_m")
    with np.errstate(divide="ignore", invalid="ignore"):
        weights = np.where(variances > 0, 1.0 / variances, 0.0)
    cost = np.full(flat.shape[1], np.inf)
    choice = np.zeros(flat.shape[1])
    for n in range(n_wraps):
        candidate = wrapped[best] + n * ranges[best]
        residual = np.mod(candidate[None] - wrapped + 0.5 * ranges[:, None], ranges[:, None]) - 0.5 * ranges[:, None]
        c = np.sum(weights * residual**2, axis=0)
        c = np.where(candidate < max_depth, c, np.inf)
        better = c < cost
        cost, choice = np.where(better, c, cost), np.where(better, candidate, choice)
    residual = np.mod(choice[None] - wrapped + 0.5 * ranges[:, None], ranges[:, None]) - 0.5 * ranges[:, None]
    unwrapped = choice[None] - residual
    total = np.sum(weights, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.sum(weights * unwrapped, axis=0) / total
    ok &= np.isfinite(depth) & np.isfinite(cost)
    shape = m.shape[1:]
    stderr = None
    if sigma is not None:
        with np.errstate(divide="ignore"):
            stderr = np.where(ok, 1.0 / np.sqrt(total), np.nan).reshape(shape)
    return DepthResult(
        depth=np.where(ok, depth, np.nan).reshape(shape),
        depth_stderr=stderr,
        per_frequency=wrapped.reshape(len(frequencies), *shape),
        frequencies_hz=frequencies,
        valid=ok.reshape(shape),
    )


def _single_window(cams):
    """Homodyne phases do not depend on when a still target is captured: drop the window
    offsets (the estimator takes the target as still)."""
    return dataclasses.replace(cams, window_offset=np.zeros_like(cams.window_offset))
