"""Gradients of a sensor's raw frames and precision with respect to its parameters.

Read out of a response record (:mod:`dopplertof.design.record`), a camera's measurement is
M = c₀ Ī + Re Σ_m a_m e^{imψ} R(mf, mh), a_m = g₁ K_m, K_m = c^s_m conj(c^g_m) / 2 for
Fourier codes x(θ) = Re Σ c_m e^{imθ} (the sinusoid: a₁ = g₁/2). Its derivatives are exact
expressions in the record:

=====================  ===============================================  ==================
parameter              ∂M                                               needs
=====================  ===============================================  ==================
``phase`` ψ (rad)      Re Σ i m a_m e^{imψ} R                           the record
``sensor_code`` c^s_n  Re g₁ e^{inψ} conj(c^g_n)/2 R(nf, nh) (∂/∂Re;     the record
                       i × that for ∂/∂Im)
``light_code`` c^g_n   Re g₁ e^{inψ} c^s_n/2 R(nf, nh) (∂/∂Re; −i ×     the record
                       that for ∂/∂Im)
``heterodyne`` h       Re Σ a_m e^{imψ} 2πi m R₁(mf, mh)                first moments
f (Hz), the            Re Σ a_m e^{imψ} m ∂R/∂F(mf, mh), and the        slopes (and for
modulation frequency   silicon's contrast slope c'(f)/c × M             bounds, ∂R₁/∂F)
``exposure`` T (s),    c₀ ∂Ī/∂θ + Re Σ a_m e^{imψ} ∂R/∂θ(mf, mh) of      window slopes
``exposure_start``     the frame's window; T also scales the frame's    (``window_slopes``;
(s)                    electrons, signal, ambient and dark current      for bounds, with
                       (∝ T)                                            ``doppler``)
=====================  ===============================================  ==================

and so are those of ∂M/∂L and ∂M/∂L̇ (:mod:`dopplertof.design.precision`), so the Fisher
information and the bounds are differentiated in forward mode (dF from the derivatives of
the taps' means and variances, d(F⁻¹) = −F⁻¹ dF F⁻¹). The code gradients are with respect
to the harmonics n ≥ 1 of Fourier codes (the code's mean also sets the mean light and the
taps' shares: not differentiated here); the frequency's ignores the jumps of a band-limited
light code's harmonic count. An exposure or a start moves one frame's window: frames that
share the window keep theirs (the derivative is of the frame's own taps), and the heterodyne
stays h beat cycles per exposure (its offset in Hz follows 1/T). Not available, and refused
by name: the heterodyne gradient of a bound (it needs second moments).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .precision import contract, fisher_from_taps, inverse_fisher, moving_pixels, record_of, reference_time, sensor_derivatives, tap_terms
from .record import Record, measure, readout_terms

PARAMETER_KINDS = ("phase", "heterodyne", "modulation_frequency", "sensor_code", "light_code", "exposure", "exposure_start")
WINDOW_KINDS = ("exposure", "exposure_start")
OBJECTIVES = ("raw", "velocity_crb", "depth_crb")


@dataclass
class Gradient:
    """What :func:`gradient` returns.

    Attributes
    ----------
    objective : str.
    value : the objective: raw electrons (frames, taps, H, W), or the bound's mean over the
        moving pixels where it is finite (m/s or m).
    by_parameter : dict {(kind, frame index): derivative}. Scalar parameters: an array like
        ``value`` (raw) or a float; codes: one entry per harmonic n = 1 … M, complex,
        ∂/∂Re c_n + i ∂/∂Im c_n, stacked first.
    """

    objective: str
    value: object
    by_parameter: dict


def gradient(record_or_result, sensor, objective: str = "velocity_crb", parameters=None, *, reference_time_s=None) -> Gradient:
    """Derivatives of ``objective`` for ``sensor`` with respect to its frames' parameters.

    Parameters
    ----------
    record_or_result : :class:`~dopplertof.design.Record` (or a render made with
        ``record=``); bounds and the heterodyne need first moments (``doppler=True``).
    sensor : :class:`dopplertof.Sensor`.
    objective : str. ``"raw"``: the noiseless raw electrons; ``"velocity_crb"`` (m/s) or
        ``"depth_crb"`` (m): the mean bound over the moving pixels where it is finite
        (:func:`~dopplertof.design.crb`). Default ``"velocity_crb"``.
    parameters : list of (kind, frame index), optional. Kinds of :data:`PARAMETER_KINDS`
        (``exposure`` and ``exposure_start`` in s, ``modulation_frequency`` in Hz, phases
        in rad); default every phase, and the codes of coded frames (and, for ``"raw"``,
        every heterodyne). The frequency needs ``slopes=True``, the exposure and start
        ``window_slopes=True``.
    reference_time_s : float, s, optional. As for :func:`~dopplertof.design.crb`; the
        exposure and start gradients hold it fixed.

    Returns
    -------
    Gradient

    Raises
    ------
    ValueError
        Naming the parameter, for unknown kinds or frames, refused kinds (module
        docstring), codes that are not Fourier coefficients, or what the record lacks.
    """
    from ..sensors import Sensor

    record = record_of(record_or_result, "gradient")
    if not isinstance(sensor, Sensor):
        raise ValueError(f"gradient: 'sensor' must be a dopplertof.Sensor, got {sensor!r}")
    if objective not in OBJECTIVES:
        raise ValueError(f"gradient: unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}")
    parameters = _parameters(sensor, objective, parameters)
    cameras = sensor.cameras()
    t_ref = reference_time(record, reference_time_s)
    if objective == "raw":
        measurements = np.stack([measure(record, c, f"gradient: camera {i} ({c.label()})") for i, c in enumerate(cameras)])
        value = sensor.raw(measurements, clip=False)
        out = {}
        for kind, frame in parameters:
            tangents = _tangents(record, sensor, kind, frame, t_ref, need_rate=False)
            # raw is linear in the measurements; a tangent leaves the mean light (Ī) alone,
            # but for a window's (then only the frame's own taps change)
            columns = [sensor.raw(t[0], clip=False) for t in tangents]
            if kind in WINDOW_KINDS:
                columns = [_frame_only(c, frame, value if kind == "exposure" else None, sensor) for c in columns]
            out[(kind, frame)] = _stack(columns, kind)
        return Gradient(objective, value, out)
    m, d_length, d_rate = sensor_derivatives(record, sensor, t_ref, "gradient")
    jac, weight, mean_e = tap_terms(sensor, m, [m, d_length, d_rate])
    fisher = fisher_from_taps(jac, weight)
    index = 2 if objective == "velocity_crb" else 1
    covariance, ok = inverse_fisher(fisher)
    bound = np.where(ok, 0.5 * np.sqrt(np.clip(covariance[..., index, index], 0.0, None)), np.inf)
    mask = moving_pixels(record) & np.isfinite(bound)
    if not mask.any():
        raise ValueError(f"gradient: the {objective} is infinite (or no pixel moves) everywhere; no gradient")
    shot = 1.0 if sensor.noise.shot_noise else 0.0
    out = {}
    for kind, frame in parameters:
        columns = []
        for t_m, t_length, t_rate in _tangents(record, sensor, kind, frame, t_ref, need_rate=True):
            d_jac = tap_terms(sensor, m, [t_m, t_length, t_rate])[0]
            d_mean = d_jac[0]
            if kind in WINDOW_KINDS:  # the frame's own taps; T also scales its charge, all ∝ T
                explicit = kind == "exposure"
                d_mean = _frame_only(d_mean, frame, mean_e if explicit else None, sensor)
                d_jac = np.stack([_frame_only(d_jac[p], frame, jac[p] if explicit else None, sensor) for p in range(3)])
            d_weight = -(weight**2) * shot * d_mean  # σ² = μ + read² + q²/12: dσ² = dμ
            cross = np.einsum("aftyx,bftyx,ftyx->yxab", d_jac, jac, weight)
            d_fisher = cross + np.swapaxes(cross, -1, -2) + fisher_from_taps(jac, d_weight)
            d_cov = -np.einsum("...ij,...jk,...kl->...il", covariance, d_fisher, covariance)[..., index, index]
            d_bound = d_cov / np.where(mask, 8.0 * bound, 1.0)  # d(½√C) = dC / (4√C), √C = 2 · bound
            columns.append(float(np.mean(d_bound[mask])))
        out[(kind, frame)] = _stack(columns, kind)
    return Gradient(objective, float(np.mean(bound[mask])), out)


def _stack(columns, kind):
    """Code gradients as complex ∂/∂Re + i ∂/∂Im per harmonic; scalars as they are."""
    if not kind.endswith("_code"):
        return columns[0]
    values = np.asarray(columns)
    return values[0::2] + 1j * values[1::2]


def _parameters(sensor, objective, parameters):
    if parameters is None:
        out = [("phase", i) for i in range(len(sensor.frames))]
        out += [(kind, i) for i, f in enumerate(sensor.frames) if f.coded for kind in ("sensor_code", "light_code")]
        if objective == "raw":
            out += [("heterodyne", i) for i in range(len(sensor.frames))]
        return out
    checked = []
    for item in parameters:
        if not (isinstance(item, (tuple, list)) and len(item) == 2):
            raise ValueError(f"gradient: a parameter is (kind, frame index), got {item!r}")
        kind, frame = item
        if kind not in PARAMETER_KINDS:
            raise ValueError(f"gradient: unknown parameter {kind!r}; choose one of {', '.join(PARAMETER_KINDS)}")
        if isinstance(frame, bool) or not isinstance(frame, int) or not 0 <= frame < len(sensor.frames):
            raise ValueError(f"gradient: parameter ({kind!r}, {frame!r}): the sensor has frames 0 to {len(sensor.frames) - 1}")
        if kind == "heterodyne" and objective != "raw":
            raise ValueError(f"gradient: parameter ('heterodyne', {frame}): the {objective} needs second moments the record does not hold; its raw frames have a heterodyne gradient")
        if kind.endswith("_code"):
            f = sensor.frames[frame]
            if not f.coded or f.sensor_code.fourier is None or f.light_code.fourier is None:
                raise ValueError(f"gradient: parameter ({kind!r}, {frame}): code gradients are with respect to Fourier coefficients; give the frame's codes with dopplertof.codes.fourier")
        checked.append((kind, frame))
    return checked


def _frame_only(d, frame, scaled, sensor):
    """``d`` (frames, taps, …) with every frame but ``frame`` zeroed, plus, where ``scaled``
    is given (a quantity ∝ the frame's exposure T, like ``d``), its frame's part / T: the
    explicit derivative with respect to T."""
    out = np.zeros_like(d)
    out[frame] = d[frame]
    if scaled is not None:
        out[frame] += scaled[frame] / sensor.frames[frame].exposure
    return out


def _frame_cameras(sensor, frame):
    """Indices of ``sensor.cameras()`` that are ``frame`` (and its 4-tap phase copies)."""
    n = len(sensor.frames)
    return [frame + j * n for j in range(4 if sensor.taps == 4 else 1)]


def _tangents(record: Record, sensor, kind, frame, t_ref, need_rate):
    """Per direction (one for a scalar; Re and Im of every harmonic for a code): the
    derivatives (cameras, H, W) of (M, ∂M/∂L, ∂M/∂L̇) of every camera of ``sensor``."""
    cameras = sensor.cameras()
    shape = (len(cameras), *record.luminance.shape[1:])
    directions = 1
    if kind.endswith("_code"):
        directions = 2 * (len(getattr(sensor.frames[frame], kind).fourier) - 1)
    out = [tuple(np.zeros(shape) for _ in range(3)) for _ in range(directions)]
    for index in _frame_cameras(sensor, frame):
        camera = cameras[index]
        where = f"gradient: {kind} of frame {frame}"
        w, _, terms = readout_terms(record, camera, where)
        if kind == "phase":
            tangent_terms = [[(m, 1j * m * a, j, b) for m, a, j, b in terms]]
        elif kind == "modulation_frequency":
            t = _frequency_tangent(record, sensor, w, camera, terms, t_ref, need_rate, where)
            for part in range(3):
                out[0][part][index] = t[part]
            continue
        elif kind == "heterodyne":
            derivative = _heterodyne_tangent(record, w, camera, terms)
            out[0][0][index], out[0][1][index] = derivative
            continue
        elif kind in WINDOW_KINDS:
            t = _window_tangent(record, w, camera, terms, kind, t_ref, need_rate, where)
            for part in range(3):
                out[0][part][index] = t[part]
            # the mean light of the frame's window moves with it (only the frame's taps see it: _frame_only)
            windows = sensor._windows()
            out[0][0][len(cameras) - len(windows) + windows.index((camera.exposure_start, camera.exposure))] = _window_luminance(record, w, kind, where)
            continue
        else:
            tangent_terms = _code_tangent_terms(record, camera, kind, where)
        for direction, located in enumerate(tangent_terms):
            if located is None:
                continue  # a harmonic the band-limited light does not pass: no effect
            t = contract(record, w, 0.0, located, camera.wavenumber, t_ref, where) if need_rate else _without_rate(record, w, located, camera.wavenumber)
            for part in range(3):
                out[direction][part][index] = t[part]
    return out


def _window_luminance(record, w, kind, where):
    """∂Ī/∂θ (H, W) of window ``w``, θ its exposure or start; ValueError without window slopes."""
    if record.luminance_slopes is None:
        raise ValueError(f"{where}: the record holds no window slopes; render it with record=dict(window_slopes=True, ...)")
    return record.luminance_slopes[WINDOW_KINDS.index(kind), w].astype(np.float64)


def _window_tangent(record, w, camera, terms, kind, t_ref, need_rate, where):
    """∂/∂θ of (M, ∂M/∂L, ∂M/∂L̇) of ``camera`` (module docstring), θ its window's exposure
    or start: the window slopes of Ī, R and R₁, and, in ∂M/∂L̇ = Re Σ i m k a x with
    x = (start − t_ref) R + T R₁ (:func:`~dopplertof.design.precision.contract`), the
    explicit dependence of x on the start and T."""
    from .record import harmonics

    name = "exposure" if kind == "exposure" else "start"
    slopes = getattr(record, f"{name}_slopes")
    moment_slopes = getattr(record, f"{name}_moment_slopes")
    if slopes is None or (need_rate and moment_slopes is None):
        need = "window_slopes=True, doppler=True" if need_rate else "window_slopes=True"
        raise ValueError(f"{where}: the record holds no window slopes; render it with record=dict({need}, ...)")
    start_s, exposure_s = record.windows[w]
    d_m = harmonics(camera, where)[0] * _window_luminance(record, w, kind, where)
    d_length, d_rate = np.zeros_like(d_m), np.zeros_like(d_m)
    for order, coefficient, j, b in terms:
        ik = 1j * order * camera.wavenumber * coefficient
        r_theta = slopes[w, j, b].astype(np.complex128)
        d_m += (coefficient * r_theta).real
        d_length += (ik * r_theta).real
        if need_rate:
            r, r1 = record.phasors[w, j, b].astype(np.complex128), record.moments[w, j, b].astype(np.complex128)
            r1_theta = moment_slopes[w, j, b].astype(np.complex128)
            x_theta = (start_s - t_ref) * r_theta + exposure_s * r1_theta + (r1 if kind == "exposure" else r)
            d_rate += (ik * x_theta).real
    return d_m, d_length, d_rate


def _without_rate(record, w, located, wavenumber):
    """(M, ∂M/∂L, 0) of ``located`` terms, for records without moments."""
    m = np.zeros(record.luminance.shape[1:])
    d_length = np.zeros_like(m)
    for order, coefficient, j, b in located:
        r = record.phasors[w, j, b].astype(np.complex128)
        m += (coefficient * r).real
        d_length += (1j * order * wavenumber * coefficient * r).real
    return m, d_length, np.zeros_like(m)


def _frequency_tangent(record, sensor, w, camera, terms, t_ref, need_rate, where):
    """∂/∂f of (M, ∂M/∂L, ∂M/∂L̇) of ``camera`` (module docstring): the phasors' slopes, k's
    own derivative 2π/c in the path-length derivatives, and the contrast slope c'/c, which
    scales the frame's share of the raw electrons as a change of M would."""
    from ..modulation import SPEED_OF_LIGHT_M_S

    if record.slopes is None or (need_rate and record.moment_slopes is None):
        need = "slopes=True, doppler=True" if need_rate else "slopes=True"
        raise ValueError(f"{where}: the record holds no frequency slopes; render it with record=dict({need}, ...)")
    start_s, exposure_s = record.windows[w]
    dk = 2 * math.pi / SPEED_OF_LIGHT_M_S
    k = camera.wavenumber
    shape = record.luminance.shape[1:]
    d_m, d_length, d_rate = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for order, coefficient, j, b in terms:
        r, r_f = record.phasors[w, j, b].astype(np.complex128), record.slopes[w, j, b].astype(np.complex128)
        d_m += (coefficient * order * r_f).real
        d_length += (coefficient * 1j * order * (dk * r + k * order * r_f)).real
        if need_rate:
            r1, r1_f = record.moments[w, j, b].astype(np.complex128), record.moment_slopes[w, j, b].astype(np.complex128)
            x = (start_s - t_ref) * r + exposure_s * r1
            x_f = (start_s - t_ref) * r_f + exposure_s * r1_f
            d_rate += (coefficient * 1j * order * (dk * x + k * order * x_f)).real
    slope = _contrast_slope(sensor.noise, camera.modulation_frequency) / sensor.noise.contrast(camera.modulation_frequency)
    if slope:
        base = contract(record, w, 0.0, terms, k, t_ref, where) if need_rate else _without_rate(record, w, terms, k)
        base = (base[0] + _constant_part(record, w, camera, where), base[1], base[2])
        d_m, d_length, d_rate = d_m + slope * base[0], d_length + slope * base[1], d_rate + slope * base[2]
    return d_m, d_length, d_rate


def _constant_part(record, w, camera, where):
    """c₀ Ī of ``camera``: the part of M without harmonics."""
    from .record import harmonics

    return harmonics(camera, where)[0] * record.luminance[w].astype(np.float64)


def _contrast_slope(silicon, frequency_hz: float) -> float:
    """dc/df (1/Hz) of the demodulation contrast: its table's slope (central within 1 Hz,
    as a central difference sees it at a knot); 0 for a constant."""
    table = silicon.demodulation_contrast
    if isinstance(table, float):
        return 0.0
    xs, ys = np.array(table).T
    low, high = max(frequency_hz - 1.0, xs[0]), min(frequency_hz + 1.0, xs[-1])
    return float((np.interp(high, xs, ys) - np.interp(low, xs, ys)) / (high - low))


def _heterodyne_tangent(record, w, camera, terms):
    if record.moments is None:
        raise ValueError(f"gradient: heterodyne of {camera.label()}: the record holds no first moments; render it with record=dict(doppler=True, ...)")
    m = np.zeros(record.luminance.shape[1:])
    d_length = np.zeros_like(m)
    for order, coefficient, j, b in terms:
        dr = 2j * math.pi * order * record.moments[w, j, b].astype(np.complex128)  # ∂R(F, mh)/∂h
        m += (coefficient * dr).real
        d_length += (1j * order * camera.wavenumber * coefficient * dr).real
    return m, d_length


def _code_tangent_terms(record, camera, kind, where):
    """Located terms of ∂a_n e^{inψ} for Re and Im of every harmonic n of the code."""
    sensor_c = np.asarray(camera.sensor_code.fourier)
    light_c = np.asarray(camera.light.fourier)
    order = min(sensor_c.size, light_c.size) - 1  # the correlation's harmonics
    out = []
    for n in range(1, sensor_c.size if kind == "sensor_code" else np.asarray(camera.light_code.fourier).size):
        if n > order:
            out += [None, None]
            continue
        if kind == "sensor_code":
            d_re = np.conj(light_c[n]) / 2
            d_im = 1j * d_re
        else:
            d_re = sensor_c[n] / 2
            d_im = -1j * d_re
        j = record.frequency_index(n * camera.modulation_frequency, where)
        b = record.beat_index(n * camera.heterodyne, where)
        phase = np.exp(1j * n * camera.phase) * camera.g1
        out += [[(n, phase * d_re, j, b)], [(n, phase * d_im, j, b)]]
    return out
