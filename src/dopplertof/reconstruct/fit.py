"""The per-pixel fit (:mod:`dopplertof.reconstruct`, ``"fit"``): the linear sub-problem in Z,
a coarse grid over the Doppler phase, and variable-projection Gauss-Newton in (a, β)."""

from __future__ import annotations

import numpy as np

from .model import _CameraSet, _data_amplitude, _default_threshold, _design_columns, _fits_brightness, _require_sinusoid


_GRID_POINTS = 65
_SCHEDULE_CANDIDATES = 4  # grid minima refined when the cameras' windows differ
_MAX_GAUSS_NEWTON_ITERATIONS = 60
_MAX_STEP_HALVINGS = 30
_RANK_RTOL = 1e-10  # det(G) / trace(G)^2 below this: the 2x2 normal equations are rank 1
_MIN_SENSITIVITY = 1e-7  # |∂m/∂a ⊥| / (|Z| |g1/2|) below this: a is not identifiable
_MAX_BRIGHTNESS_STEP = 0.5  # largest change of β in one Gauss-Newton step


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


def _linear_fit(m: np.ndarray, doppler_phase: np.ndarray, cams: _CameraSet, brightness=0.0):
    """Best Z for given a and β per pixel.

    Returns
    -------
    dict with x, y (Re Z, Im Z), residual (n, N), rss (N,), full_rank (N,), and the
    columns and normal matrix needed by the Gauss-Newton step.
    """
    c1, c2 = _design_columns(doppler_phase, cams, brightness)
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


def _projected_sensitivity(fit: dict, doppler_phase: np.ndarray, cams: _CameraSet, brightness=0.0, wrt="a"):
    """∂m/∂a (or ∂m/∂β) at fixed Z, and the same minus its projection on the columns
    (variable projection)."""
    d1, d2 = _design_columns(doppler_phase, cams, brightness, wrt)
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


def _gauss_newton(m, start, cams: _CameraSet, max_step: float, max_phase: float, fit_doppler: bool = True,
                  fit_brightness: bool = True):
    """Refine the Doppler phase a and the brightness slope β per pixel by safeguarded
    variable-projection Gauss-Newton, from (``start``, 0); returns (a, β).

    Steps of a are limited to ``max_step`` and a stays in [−max_phase, max_phase]: outside
    the search range the model has degenerate points (e.g. F(2π) = 0 for homodyne cameras
    at a = 2π) where the fitted amplitude diverges. β stays in [−2, 2] (a radiance that
    stays ≥ 0 over the exposure). ``fit_doppler=False`` keeps a at ``start`` and fits β;
    ``fit_brightness=False`` keeps β at 0.
    """
    a = np.clip(start, -max_phase, max_phase)
    beta = np.zeros_like(a)
    active = np.arange(a.size)
    for _ in range(_MAX_GAUSS_NEWTON_ITERATIONS):
        if active.size == 0:
            break
        ma, aa, bb = m[:, active], a[active], beta[active]
        fit = _linear_fit(ma, aa, cams, bb)
        _, pa = _projected_sensitivity(fit, aa, cams, bb, "a")
        _, pb = _projected_sensitivity(fit, aa, cams, bb, "beta")
        r = fit["residual"]  # orthogonal to the columns: J·r = J⊥·r
        ga, gb = np.sum(pa * r, axis=0), np.sum(pb * r, axis=0)
        haa, hab, hbb = np.sum(pa * pa, axis=0), np.sum(pa * pb, axis=0), np.sum(pb * pb, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            det = haa * hbb - hab * hab
            joint = fit_doppler & fit_brightness & (det > _RANK_RTOL * haa * hbb)
            step_a = np.where(joint, (hbb * ga - hab * gb) / det, ga / haa) if fit_doppler else np.zeros_like(aa)
            step_b = np.where(joint, (haa * gb - hab * ga) / det, 0.0 if fit_doppler else gb / hbb)
        step_a = np.where(np.isfinite(step_a), np.clip(step_a, -max_step, max_step), 0.0)
        step_b = np.where(np.isfinite(step_b) & fit_brightness, np.clip(step_b, -_MAX_BRIGHTNESS_STEP, _MAX_BRIGHTNESS_STEP), 0.0)
        step_a = np.clip(aa + step_a, -max_phase, max_phase) - aa
        step_b = np.clip(bb + step_b, -2.0, 2.0) - bb
        accepted = np.zeros(active.size, dtype=bool)
        pending = np.flatnonzero((step_a != 0.0) | (step_b != 0.0))
        for _ in range(_MAX_STEP_HALVINGS):
            if pending.size == 0:
                break
            trial_a, trial_b = aa[pending] + step_a[pending], bb[pending] + step_b[pending]
            trial_rss = _linear_fit(ma[:, pending], trial_a, cams, trial_b)["rss"]
            better = trial_rss < fit["rss"][pending]
            won = pending[better]
            aa[won], bb[won] = trial_a[better], trial_b[better]
            fit["rss"][won] = trial_rss[better]
            accepted[won] = True
            pending = pending[~better]
            step_a[pending] *= 0.5
            step_b[pending] *= 0.5
        a[active], beta[active] = aa, bb
        # converged far below any noise: 1e-13 rad of Doppler phase is 5e-11 m/s at 30 MHz, 1.5 ms
        tiny = (np.abs(step_a) <= 1e-13 + 1e-11 * np.abs(aa)) & (np.abs(step_b) <= 1e-12)
        active = active[accepted & ~tiny]
    return a, beta


def _depth_and_amplitude(m, doppler_phase, cams: _CameraSet, brightness=0.0):
    """Mid-exposure depth (m), amplitude A and (g1/2)|Z| from the linear fit at known a, β."""
    fit = _linear_fit(m, doppler_phase, cams, brightness)
    z = fit["x"] + 1j * fit["y"]
    amplitude = np.abs(z)
    mid_phase = np.mod(np.angle(z) + 0.5 * doppler_phase, 2.0 * np.pi)
    depth = mid_phase / (2.0 * cams.wavenumber)
    signal = np.mean(cams.half_g1) * amplitude
    return depth, amplitude, signal, fit


def _velocity_fit(flat, cams, min_amplitude, max_doppler_hz):
    _require_sinusoid(cams, "method='fit' assumes the low-pass sinusoid model")
    max_phase = 2.0 * np.pi * max_doppler_hz * cams.exposure_s
    spacing = 2.0 * max_phase / (_grid_points(cams) - 1)
    # Windows at different times give the residual several deep minima, whose depths on
    # the grid can mislead: refine the deepest few and keep the best.
    candidates = _SCHEDULE_CANDIDATES if np.any(cams.window_offset) else 1
    fit_brightness = _fits_brightness(cams)
    best = None
    for start in _grid_search(flat, cams, max_phase, candidates):
        a, beta = _gauss_newton(flat, start, cams, max_step=spacing, max_phase=max_phase, fit_brightness=fit_brightness)
        rss = _linear_fit(flat, a, cams, beta)["rss"]
        if best is None:
            best = [a, beta, rss]
            continue
        better = rss < best[2]
        best = [np.where(better, new, old) for new, old in zip((a, beta, rss), best)]
    doppler_phase, brightness = best[0], best[1]
    # Per-pixel identifiability: the data must respond to a beyond what Z and β can absorb.
    fit = _linear_fit(flat, doppler_phase, cams, brightness)
    _, pa = _projected_sensitivity(fit, doppler_phase, cams, brightness, "a")
    _, pb = _projected_sensitivity(fit, doppler_phase, cams, brightness, "beta")
    with np.errstate(divide="ignore", invalid="ignore"):
        if fit_brightness:
            pa = pa - pb * np.nan_to_num(np.sum(pa * pb, axis=0) / np.sum(pb * pb, axis=0))
        z_abs = np.hypot(fit["x"], fit["y"])
        sensitivity = np.sqrt(np.sum(pa * pa, axis=0)) / (z_abs * np.sqrt(np.sum(cams.half_g1**2)))
    signal = np.mean(cams.half_g1) * z_abs
    threshold = _default_threshold(_data_amplitude(flat), min_amplitude)
    ok = (
        (signal > threshold)
        & (sensitivity > _MIN_SENSITIVITY)
        & (np.abs(doppler_phase) < max_phase)  # at the bound: outside the search range
        & np.isfinite(doppler_phase)
    )
    return doppler_phase, brightness, ok, threshold
