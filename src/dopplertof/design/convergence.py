"""Render only as long as it matters: the Monte Carlo error of raw frames against the
sensor's own noise (``dopplertof.render(..., sensor=S, until_noise=RATIO)``).

A tap's electrons are linear in the render's measurements, A = Σ_i C_i M_i
(:meth:`~dopplertof.sensors.Sensor.raw`), so the Monte Carlo standard error of A is at most
Σ_i |C_i| σ_i, σ_i the measurements' standard errors (their strata's or replicates' spread; the bound
holds whatever their correlation). The sensor's own noise is √σ²(μ) of the tap's mean
charge μ (:meth:`~dopplertof.sensors.noise.Silicon.tap_variance_e2`: shot, read and
quantisation noise). :func:`noise_ratio` is the worst tap's ratio per pixel, and a render
stops after the first pass at which its :data:`UNTIL_NOISE_QUANTILE` quantile over the
window's pixels is at most RATIO. Standard errors exist once a stratum (two replicates,
where the times are not stratified) of every pixel is closed, and change as more close:
the check runs after every pass, and can stop a render at any pass that closes one.
"""

from __future__ import annotations

import numpy as np

# The share of a window's pixels whose worst tap must meet the ratio: the rest (silhouettes,
# caustics, the last few percent of slowly converging pixels) may stay noisier.
UNTIL_NOISE_QUANTILE = 0.95


def noise_ratio(sensor, measurements, measurement_stderr, frames=None) -> np.ndarray:
    """Worst tap's (Monte Carlo standard error bound) / (sensor noise), (H, W), over
    ``frames`` (indices; default all) of ``sensor``, from a render's measurements and their
    standard errors (cameras, H, W). NaN where a standard error is unknown.

    Parameters
    ----------
    sensor : Sensor
    measurements : ndarray
        (cameras, H, W), the render's measurements of ``sensor.cameras()``.
    measurement_stderr : ndarray
        (cameras, H, W), their standard errors.
    frames : sequence of int or None, default None
        Frame indices; None: all.

    Returns
    -------
    ndarray
        (H, W) float64.
    """
    m = np.asarray(measurements, dtype=np.float64)
    sigma = np.asarray(measurement_stderr, dtype=np.float64)
    n = m.shape[0]
    unit = np.eye(n).reshape(n, n, *([1] * (m.ndim - 1)))
    # C_i: the taps' electrons per unit of measurement i (the same in every pixel)
    coefficients = np.stack([sensor.raw(unit[i], clip=False) for i in range(n)])  # (cameras, frames, taps, 1, 1)
    mc = np.einsum("cft...,c...->ft...", np.abs(coefficients), sigma)
    raw = np.maximum(sensor.raw(m, clip=False), 0.0)
    own = np.sqrt(sensor.noise.tap_variance_e2(sensor.expected_electrons(raw)))
    ratio = mc / own
    if frames is not None:
        ratio = ratio[list(frames)]
    return ratio.max(axis=(0, 1))


def quantile(ratio: np.ndarray) -> float:
    """The :data:`UNTIL_NOISE_QUANTILE` quantile of a :func:`noise_ratio` map; inf where any
    pixel's ratio is still unknown.

    Parameters
    ----------
    ratio : ndarray
        A :func:`noise_ratio` map.

    Returns
    -------
    float
    """
    if not np.all(np.isfinite(ratio)):
        return float("inf")
    return float(np.quantile(ratio, UNTIL_NOISE_QUANTILE))
