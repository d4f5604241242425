"""Standard errors of the reconstruction (:mod:`dopplertof.reconstruct`, errors): the
measurements' covariance, the delta method, and the default validity threshold."""

from __future__ import annotations

import numpy as np

from .model import _CameraSet, _design_columns, _doppler_to_velocity, _fits_brightness


DEFAULT_RELATIVE_MAX_VELOCITY_STDERR = 0.1
"""Default ``max_velocity_stderr`` as a fraction of the scene's speed scale
(:func:`default_max_velocity_stderr`)."""

_NUMERICAL_DOPPLER_PHASE_RAD = 1e-12  # resolution of the estimators, added to the propagated error
_DETECTION_Z = 5.0  # |v| above this many standard errors: motion detected (noise: 2e-4 of pixels, t with 15 dof)
_MIN_DETECTED = (10, 1e-3)  # a speed scale needs this many detected pixels, or this fraction of them
UNSCALED_MAX_VELOCITY_STDERR_M_S = 0.01
"""Default ``max_velocity_stderr`` (m/s) where the scene gives no speed scale: a tenth of
0.1 m/s, slower than the motions D-ToF cameras are built for (:func:`default_max_velocity_stderr`)."""


def default_max_velocity_stderr(velocity_m_s, velocity_stderr_m_s) -> tuple[float, str]:
    """The default threshold on a pixel's velocity standard error (m/s), and why.

    A tenth of the scene's speed scale: the 90th percentile of |v| over the pixels whose
    velocity differs from 0 by more than five standard errors (the motion the cameras
    actually detect; not the maximum, which silhouettes make wild, nor the median, which
    the small velocities multipath puts on static walls pull down). A valid pixel then
    knows its velocity to 10 % of the motion in view, enough to keep its sign and its
    colour on a map of the scene; the scale comes from the scene, so it suits a 1 m/s hand
    as well as a 30 m/s car (the speed range of the cameras, c/(4 f_g T), 1.7 km/s at
    30 MHz and 1.5 ms, says nothing about either). Where too few pixels move detectably for a
    scale (fewer than 10, and than 0.1 % of them: noise alone gives ~0.02 %), the scene
    gives none: whatever moves is below the noise, and a threshold from the speed range
    would state noise valid (5 % of it, 83 m/s, kept 85 % of the glossy scene's pixels at
    256 spp with an RMSE of 8.7 m/s beside a sphere rolling at 2 m/s). The threshold is then
    :data:`UNSCALED_MAX_VELOCITY_STDERR_M_S`, 0.01 m/s: the valid pixels are those known to
    be still (or moving) to a centimetre a second, and ``max_velocity_stderr`` accepts
    noisier ones.

    Parameters
    ----------
    velocity_m_s, velocity_stderr_m_s : ndarray
        Velocity estimates and their standard errors (m/s); NaN where not determined.

    Returns
    -------
    (threshold_m_s, reason) : (float, str)
    """
    v = np.asarray(velocity_m_s, dtype=np.float64)
    sigma = np.asarray(velocity_stderr_m_s, dtype=np.float64)
    known = np.isfinite(v) & np.isfinite(sigma)
    moving = known & (np.abs(v) > _DETECTION_Z * sigma)
    if moving.sum() >= max(_MIN_DETECTED[0], _MIN_DETECTED[1] * known.sum()):
        scale = float(np.percentile(np.abs(v[moving]), 90.0))
        return DEFAULT_RELATIVE_MAX_VELOCITY_STDERR * scale, (
            f"{DEFAULT_RELATIVE_MAX_VELOCITY_STDERR:.0%} of the scene's speed scale {scale:.3g} m/s "
            f"(90th percentile of |v| where |v| > {_DETECTION_Z:g} standard errors)")
    return UNSCALED_MAX_VELOCITY_STDERR_M_S, (
        f"too few pixels move detectably for a speed scale (any motion is below the noise): "
        f"{UNSCALED_MAX_VELOCITY_STDERR_M_S:g} m/s; render more paths, or give max_velocity_stderr "
        f"(--max-velocity-stderr) to accept noisier pixels")


def covariance_from_errors(stderr, covariance, shape):
    """The measurements' covariance from either description of their errors.

    Parameters
    ----------
    stderr : array_like, shape ``shape``, or None
        Per-camera standard errors (uncorrelated cameras); NaN where unknown.
    covariance : array_like, shape (n, n) + ``shape[1:]``, or None
        The full covariance; it wins over ``stderr``.
    shape : tuple
        (n_cameras, pixels...) of the measurements.

    Returns
    -------
    ndarray, shape (n, n) + ``shape[1:]``, or None
        None where neither is given.

    Raises
    ------
    ValueError
        A shape that is not the measurements', or a negative standard error.
    """
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
    if (e < 0).any():  # NaN (no error known) passes
        raise ValueError(f"measurement_stderr must be >= 0 (standard errors), got {int((e < 0).sum())} negative values, e.g. {float(e[e < 0].flat[0])!r}")
    c = np.zeros((n, n) + shape[1:])
    for i in range(n):
        c[i, i] = e[i] ** 2
    return c


def _gradients(flat, cams: _CameraSet, doppler_phase, brightness, fit, doppler_gradient=None):
    """Gradients of the velocity (m/s) and depth (m) estimates in the measurements, shape
    (N, n_cameras) each: the delta method's g in σ² = g Σ gᵀ (:func:`_stderr`).

    The fit's gradient is the Gauss-Newton linearisation of the least-squares solution,
    (JᵀJ)⁻¹Jᵀ with J = ∂m/∂(Re Z, Im Z, a[, β]) at the solution (exact when the set has as
    many measurements as unknowns); another estimator gives its own ∂a/∂m,
    ``doppler_gradient`` (N, n_cameras); the depth, arg Z + a/2 over 2k, comes from the
    same linearisation for both.
    """
    count = flat.shape[1]
    d1, d2 = _design_columns(doppler_phase, cams, brightness, "a")
    columns = [fit["c1"], fit["c2"], d1 * fit["x"] + d2 * fit["y"]]
    if _fits_brightness(cams):
        d1, d2 = _design_columns(doppler_phase, cams, brightness, "beta")
        columns.append(d1 * fit["x"] + d2 * fit["y"])
    jac = np.moveaxis(np.stack(columns, axis=-1), 1, 0)  # (N, n, k)
    with np.errstate(all="ignore"):
        solve = np.linalg.pinv(np.where(np.isfinite(jac), jac, 0.0))  # (N, k, n)
        z2 = fit["x"] ** 2 + fit["y"] ** 2
        w_depth = np.zeros((count, jac.shape[2]))
        w_depth[:, 0], w_depth[:, 1], w_depth[:, 2] = -fit["y"] / z2, fit["x"] / z2, 0.5
        grad_depth = np.einsum("pk,pkn->pn", w_depth, solve) / (2.0 * cams.wavenumber)
    grad_a = solve[:, 2, :] if doppler_gradient is None else doppler_gradient
    return grad_a / (2.0 * cams.wavenumber * cams.exposure_s), grad_depth  # v = a/(2 k T)


def _stderr(gradient, covariance) -> np.ndarray:
    """sqrt(g Σ gᵀ) per pixel: ``gradient`` (N, n), ``covariance`` (n, n, N)."""
    with np.errstate(all="ignore"):
        variance = np.einsum("pi,ijp,pj->p", gradient, covariance, gradient)
    return np.sqrt(np.maximum(variance, 0.0))


def _velocity_floor_m_s(cams: _CameraSet) -> float:
    """The estimators converge to ~1e-13 rad of Doppler phase: pixels whose measurements are
    exact (a static surface: E = 0 with antithetic replay) are known to this, not to 0."""
    return float(_doppler_to_velocity(_NUMERICAL_DOPPLER_PHASE_RAD, cams)[0])
