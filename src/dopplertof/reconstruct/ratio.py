"""The homodyne/heterodyne ratio (:mod:`dopplertof.reconstruct`, ``"ratio"``): pairing,
balance of the phases, the fused slope Σ E_i H_i / Σ H_i², and per-phase maps."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .fit import _gauss_newton
from .identify import _phase_spec
from .model import _CameraSet, _camera_set, _check_min_amplitude, _default_threshold, _doppler_to_velocity, _fits_brightness, _flatten, _measurement_array


_H_TOLERANCE = 1e-12  # h == 0 and h == 1 are matched to this absolute tolerance
_PHASE_TOLERANCE_RAD = 1e-9
_BALANCE_TOLERANCE = 1e-6  # |Σ e^{2iψ}| / n_pairs below this: the ratio's pairs are balanced


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


def _balanced(cams: _CameraSet, pairs) -> bool:
    """Σ e^{2iψ} = 0 over the pairs: the ratio's fusion is then blind to a brightness change
    (module docstring)."""
    psi = np.array([cams.phase_rad[i] for i, _ in pairs])
    return abs(np.sum(np.exp(2j * psi))) <= _BALANCE_TOLERANCE * len(pairs)


def _require_pairs(cams: _CameraSet):
    pairs = _ratio_pairs(cams)
    if pairs is None:
        raise ValueError(
            "method='ratio' needs every camera in a homodyne (h=0) / heterodyne (h=1) pair "
            f"with the same phase and exposure window; got h = {cams.heterodyne.tolist()}, "
            f"ψ = {cams.phase_rad.tolist()} rad, window offsets {cams.window_offset.tolist()} T"
        )
    return pairs


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
    """Velocity from each homodyne/heterodyne pair separately (no fusion): the original
    formula per phase, a diagnostic. A pair alone cannot tell the brightness change of a
    moving surface from a Doppler shift (module docstring): each pair's ratio carries
    β tan θ_i / 2π besides a/(a + 2π), so its velocity is biased wherever cos θ_i is small.

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


def _fuse(hom, het):
    """Σ H_i² and the least-squares slope of E against H over all pairs, Σ E_i H_i / Σ H_i²
    (g1/2 divided out): blind to a linear brightness change (module docstring); a pair with
    H ≈ 0 adds ≈ 0 to both sums."""
    total = np.sum(hom * hom, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return total, np.sum(het * hom, axis=0) / total


def _ratio_doppler_gradient(flat, cams: _CameraSet):
    """∂a/∂m_i, shape (N, n_cameras), of the fused ratio's a = 2π r/(1 − r): for the delta
    method (:func:`~dopplertof.reconstruct.errors._gradients`)."""
    pairs = _require_pairs(cams)
    per_pair = _ratio_per_phase(flat, cams, pairs, None)
    hom, het = per_pair["homodyne"], per_pair["heterodyne"]
    total, r = _fuse(hom, het)
    gradient = np.zeros((flat.shape[1], flat.shape[0]))
    with np.errstate(divide="ignore", invalid="ignore"):
        for (i, j), h_i, e_i in zip(pairs, hom, het):
            gradient[:, j] = h_i / (total * cams.half_g1[j])
            gradient[:, i] = (e_i - 2.0 * r * h_i) / (total * cams.half_g1[i])
        return gradient * (2.0 * np.pi / (1.0 - r) ** 2)[:, None]


def _velocity_ratio(flat, cams, min_amplitude):
    """Doppler phase a (the fused ratio), brightness slope β at that a (for an unbiased Z,
    depth; 0 where :func:`_fits_brightness` says not) and validity, shape (N,) each."""
    pairs = _require_pairs(cams)
    if not _balanced(cams, pairs):
        phases = [_phase_spec(cams.phase_rad[i]) for i, _ in pairs]
        raise ValueError(
            f"method='ratio' with pairs at {', '.join(phases)} would read the brightness change "
            "of a moving surface as velocity: the pairs' phases must balance (Σ e^{2iψ} = 0, e.g. "
            "psi=0 and 90deg, or four phases 90deg apart); use method='fit'"
        )
    per_pair = _ratio_per_phase(flat, cams, pairs, min_amplitude)
    total, fused = _fuse(per_pair["homodyne"], per_pair["heterodyne"])
    signal = np.max(per_pair["homodyne_amplitude"], axis=0) > per_pair["threshold"]
    ok = signal & (total > 0) & np.isfinite(fused) & (fused < 1.0)
    doppler_phase = _ratio_to_doppler_phase(np.where(ok, fused, 0.0))
    if _fits_brightness(cams):
        _, brightness = _gauss_newton(flat, doppler_phase, cams, max_step=0.0, max_phase=np.inf, fit_doppler=False)
    else:
        brightness = np.zeros_like(doppler_phase)
    return doppler_phase, brightness, ok
