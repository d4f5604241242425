"""Tests of dopplertof.reconstruct on synthetic closed-form measurements."""

from __future__ import annotations

import math


import numpy as np
import pytest

import dopplertof as dt
from dopplertof import reconstruct as rc
from dopplertof.reconstruct import SPEED_OF_LIGHT_M_S as C

from camera_stub import T, Cam  # noqa: E402
FREQUENCIES = (30e6, 150e6)
VELOCITIES = np.concatenate([np.linspace(-20.0, -0.5, 40), np.linspace(0.5, 20.0, 40)])


def cams_from(f, pairs, **kw):
    return [Cam(modulation_frequency=f, heterodyne=h, phase=p, **kw) for h, p in pairs]


def ratio_set(f, phases):
    return cams_from(f, [(h, p) for p in phases for h in (0.0, 1.0)])


def hu_set(f):
    return cams_from(f, zip((0.5, 0.5, -0.5, -0.5), (1.5 * np.pi, 0.0, 0.5 * np.pi, np.pi)))


def scene(n, seed=0, max_depth=4.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.2, 2.0, n), rng.uniform(0.3, max_depth, n)


def depth_error(estimate, truth, f):
    """Distance between depths modulo the ambiguity range."""
    span = C / (2 * f)
    return np.abs((estimate - truth + span / 2) % span - span / 2)


def numeric_exposure_average(amplitude, depth_mid, v, cam, n=200_001):
    """(1/T)∫(g1/2) cos(2π h t/T + ψ + k L(t)) A dt by the trapezoid rule, L(t) = 2 d(t)."""
    t = np.linspace(0.0, cam.exposure, n)
    k = 2 * np.pi * cam.modulation_frequency / C
    distance = depth_mid + v * (t - cam.exposure / 2)
    phase = 2 * np.pi * cam.heterodyne * t / cam.exposure + cam.phase + k * 2 * distance
    integrand = 0.5 * cam.g1 * amplitude * np.cos(phase)
    return np.trapezoid(integrand, t) / cam.exposure


# ------------------------------------------------------------------ forward model


@pytest.mark.parametrize("h, psi", [(0, 0), (1, 0.3), (0.5, 1.5 * np.pi), (-0.5, 2.0), (2.7, 1)])
def test_model_matches_numerical_integral(h, psi):
    cam = Cam(modulation_frequency=150e6, heterodyne=h, phase=psi)
    for v in (-17.0, 3.0, 250.0):
        expected = numeric_exposure_average(1.3, 2.345, v, cam)
        got = rc.model_measurements(1.3, 2.345, v, [cam])[0]
        assert got == pytest.approx(expected, abs=1e-9)


def test_model_static_homodyne_is_half_g1_amplitude_cos():
    cam = Cam(heterodyne=0.0, phase=0.4, g1=0.8)
    k = 2 * np.pi * cam.modulation_frequency / C
    got = rc.model_measurements(2.0, 1.7, 0.0, [cam])[0]
    assert got == pytest.approx(0.4 * 2.0 * np.cos(0.4 + 2 * k * 1.7), rel=1e-12)


def test_model_output_shape():
    amp = np.ones((3, 5))
    m = rc.model_measurements(amp, 1.0, np.zeros((3, 5)), ratio_set(30e6, [0, 1]))
    assert m.shape == (4, 3, 5)


@pytest.mark.parametrize("f", FREQUENCIES)
def test_heterodyne_over_homodyne_is_exact(f):
    """E/H = a/(a + 2π) for the sinusoid, no small-a approximation."""
    amp, dist = scene(VELOCITIES.size)
    h, e = rc.model_measurements(amp, dist, VELOCITIES, ratio_set(f, [0.7]))
    a = 2 * np.pi * f / C * 2 * VELOCITIES * T
    np.testing.assert_allclose(e / h, a / (a + 2 * np.pi), rtol=1e-9)


# ------------------------------------------------------------------ ratio method


@pytest.mark.parametrize("f", FREQUENCIES)
@pytest.mark.parametrize("phases", [[0.0, 0.5 * np.pi], [0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi]])
def test_ratio_recovers_velocity(f, phases):
    amp, dist = scene(VELOCITIES.size, seed=1)
    cams = ratio_set(f, phases)
    m = rc.model_measurements(amp, dist, VELOCITIES, cams)
    res = rc.velocity(m, cams, method="ratio")
    assert res.method == "ratio"
    assert res.valid.all()
    np.testing.assert_allclose(res.velocity, VELOCITIES, rtol=1e-6)
    # the original code's formula, v = c r / (2 f_g T (1 − r)), on each pair's ratio
    r = m[1] / m[0]
    np.testing.assert_allclose(res.velocity, C * r / (2 * f * T * (1 - r)), rtol=1e-6)
    np.testing.assert_allclose(res.doppler_hz, 2 * f * VELOCITIES / C, rtol=1e-6)
    assert np.all(depth_error(res.depth, dist, f) < 1e-9)
    np.testing.assert_allclose(res.amplitude, amp, rtol=1e-6)


def test_ratio_per_phase_maps():
    f = 30e6
    amp, dist = scene(VELOCITIES.size, seed=2)
    cams = [Cam(f, heterodyne=1, phase=0.5 * np.pi), Cam(f, heterodyne=0, phase=0.0),
            Cam(f, heterodyne=0, phase=0.5 * np.pi), Cam(f, heterodyne=1, phase=0.0)]
    m = rc.model_measurements(amp, dist, VELOCITIES, cams)
    per = rc.ratio_velocity_per_phase(m, cams)
    np.testing.assert_allclose(per.phase, [0.0, 0.5 * np.pi])
    assert per.velocity.shape == (2, VELOCITIES.size)
    # pair 0 is (camera 1, camera 3), pair 1 is (camera 2, camera 0)
    np.testing.assert_allclose(per.ratio[0][per.valid[0]], (m[3] / m[1])[per.valid[0]])
    np.testing.assert_allclose(per.ratio[1][per.valid[1]], (m[0] / m[2])[per.valid[1]])
    for i in range(2):
        ok = per.valid[i]
        np.testing.assert_allclose(per.velocity[i][ok], VELOCITIES[ok], rtol=1e-6)
    np.testing.assert_allclose(per.homodyne_amplitude, np.abs(m[[1, 2]]))


def test_ratio_fusion_is_least_squares_slope_of_e_against_h():
    """r̄ = Σ E_i H_i / Σ H_i², checked on inconsistent (noisy-like) data."""
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    m = np.array([[2.0], [0.02], [-0.5], [-0.0025]])  # r_0 = 0.01, r_1 = 0.005
    res = rc.velocity(m, cams, method="ratio")
    r_bar = (0.01 * 2.0**2 + 0.005 * 0.5**2) / (2.0**2 + 0.5**2)
    expected = C * r_bar / (2 * 30e6 * T * (1 - r_bar))
    assert res.velocity[0] == pytest.approx(expected, rel=1e-12)


def linear_radiance_measurements(amplitude_mid, slope, depth_mid, v, cams):
    """Closed-form measurements when the radiance changes linearly during the exposure.

    A(t) = A_mid (1 + β (t/T − ½)), β = ``slope`` (relative change over the exposure), so
    m = (g1/2) Re{A_mid e^{i θ} ∫_0^1 (1 + β (s − ½)) e^{i x s} ds} with x = 2π h + a and
    θ = ψ + k L(0); the integral is (1 − β/2) (e^{ix} − 1)/(ix) + β ∫_0^1 s e^{ixs} ds,
    ∫_0^1 s e^{ixs} ds = e^{ix}/(ix) + (e^{ix} − 1)/x² (x ≠ 0).
    """
    out = []
    for cam in cams:
        k = 2 * np.pi * cam.modulation_frequency / C
        a = k * 2 * v * cam.exposure
        x = 2 * np.pi * cam.heterodyne + a
        e = np.exp(1j * x)
        integral = (1 - slope / 2) * (e - 1) / (1j * x) + slope * (e / (1j * x) + (e - 1) / x**2)
        path_start = 2 * depth_mid - v * cam.exposure
        out.append(0.5 * cam.g1 * np.real(amplitude_mid * np.exp(1j * (cam.phase + k * path_start)) * integral))
    return np.array(out)


def test_linear_radiance_closed_form_matches_numerical_integral():
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    got = linear_radiance_measurements(1.3, 0.2, 2.345, -3.0, cams)
    for cam, value in zip(cams, got):
        t = np.linspace(0.0, T, 200_001)
        k = 2 * np.pi * cam.modulation_frequency / C
        path = 2 * (2.345 - 3.0 * (t - T / 2))
        radiance = 1.3 * (1 + 0.2 * (t / T - 0.5))
        integrand = 0.5 * cam.g1 * radiance * np.cos(2 * np.pi * cam.heterodyne * t / T + cam.phase + k * path)
        assert value == pytest.approx(np.trapezoid(integrand, t) / T, abs=1e-9)


def test_ratio_fusion_ignores_a_linear_brightness_change():
    """A surface that approaches brightens (1/d²): 0.5 % over the exposure, as the short box
    of the Cornell box. The E/H ratio of each phase then carries β tan θ_i / 2π besides the
    Doppler term, which the |H|-weighted fusion of the original code keeps; Σ E_i H_i / Σ H_i²
    cancels it for quadrature phases and leaves a relative error of β²/12."""
    f, slope = 30e6, 0.005
    amp, dist = scene(VELOCITIES.size, seed=5)
    cams = ratio_set(f, [0.0, 0.5 * np.pi])
    brightening = -np.sign(VELOCITIES) * slope
    m = linear_radiance_measurements(amp, brightening, dist, VELOCITIES, cams)

    res = rc.velocity(m, cams, method="ratio")
    assert res.valid.all()
    np.testing.assert_allclose(res.velocity, VELOCITIES, rtol=slope**2)
    # the fit models the inverse-square brightening itself: exact on such data
    inverse_square = rc.model_measurements(amp, dist, VELOCITIES, cams, brightness=-2 * VELOCITIES * T / dist)
    fit = rc.velocity(inverse_square, cams, method="fit")
    np.testing.assert_allclose(fit.velocity, VELOCITIES, rtol=1e-6)

    # the original fusion, r̄ = Σ r_i |H_i| / Σ |H_i| over the pairs valid alone
    per = rc.ratio_velocity_per_phase(m, cams)
    weight = np.where(per.valid, per.homodyne_amplitude, 0.0)
    r_old = np.sum(weight * np.nan_to_num(per.ratio), axis=0) / np.sum(weight, axis=0)
    v_old = C * r_old / (2 * f * T * (1 - r_old))
    assert np.median(np.abs(v_old / VELOCITIES - 1)) > 0.1


def test_ratio_per_phase_masks_ill_conditioned_pixels():
    f = 30e6
    k = 2 * np.pi * f / C
    cams = ratio_set(f, [0.0])
    v = np.array([5.0, 5.0, 5.0, 5.0])
    amp = np.array([1.0, 0.0, 1.0, 1.0])
    # pixel 2: cos θ ≈ 0 over the exposure, i.e. k L(T/2) = π/2 exactly
    d_quadrature = (np.pi / 2) / (2 * k)
    dist = np.array([1.0, 1.0, d_quadrature, 1.0])
    m = rc.model_measurements(amp, dist, v, cams)
    m[:, 3] = [1.0, 1.5]  # r = 1.5 ≥ 1: no physical solution
    res = rc.ratio_velocity_per_phase(m, cams)
    assert res.valid[0].tolist() == [True, False, False, False]
    assert np.isnan(res.velocity[0, 1:]).all()
    assert np.isnan(res.doppler_hz[0, 1:]).all()
    assert res.velocity[0, 0] == pytest.approx(5.0, rel=1e-6)
    # without the mask the quadrature pixel's "velocity" is far from the truth
    assert abs(C * (m[1, 2] / m[0, 2]) / (2 * f * T * (1 - m[1, 2] / m[0, 2])) - 5.0) > 1.0


def test_ratio_fusion_keeps_pairs_that_are_invalid_alone():
    """A pair is invalid on its own when r ≥ 1 or |H| is small, but the fusion divides by no
    single H: selecting pairs by their own ratio would select on noise."""
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    # pixel 0: phase 0 has r = 1.2; pixel 1: phase 0 has |H| = 1e-6, below the threshold
    m = np.array([[0.5, 1e-6], [0.6, 0.3], [2.0, -1.0], [0.02, -0.01]])
    per = rc.ratio_velocity_per_phase(m, cams)
    assert per.valid.tolist() == [[False, False], [True, True]]
    res = rc.velocity(m, cams, method="ratio")
    assert res.valid.tolist() == [True, True]
    r_bar = np.sum(m[1::2] * m[::2], axis=0) / np.sum(m[::2] ** 2, axis=0)
    np.testing.assert_allclose(res.velocity, C * r_bar / (2 * 30e6 * T * (1 - r_bar)), rtol=1e-12)


def test_ratio_second_phase_rescues_quadrature_pixel():
    f = 30e6
    k = 2 * np.pi * f / C
    cams = ratio_set(f, [0.0, 0.5 * np.pi])
    dist = np.array([(np.pi / 2) / (2 * k), 1.0])
    m = rc.model_measurements(np.ones(2), dist, np.array([-7.0, 3.0]), cams)
    res = rc.velocity(m, cams, method="ratio")
    assert res.valid.all()
    np.testing.assert_allclose(res.velocity, [-7.0, 3.0], rtol=1e-6)


def test_non_finite_input_is_masked():
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    m = rc.model_measurements(np.ones(3), np.array([1.0, 2.0, 3.0]), np.ones(3), cams)
    m[0, 1] = np.nan
    m[3, 2] = np.inf
    for method in ("ratio", "fit"):
        res = rc.velocity(m, cams, method=method)
        assert res.valid.tolist() == [True, False, False]
        assert np.isnan(res.velocity[1:]).all()


def test_explicit_min_amplitude():
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    m = rc.model_measurements(np.array([1.0, 0.1]), 1.0, 2.0, cams)
    assert rc.velocity(m, cams).valid.all()
    only_bright = rc.velocity(m, cams, min_amplitude=0.5 * abs(m[[0, 2]]).max())
    assert only_bright.valid.tolist() == [True, False]


def test_ratio_accepts_other_waveforms():
    """Documented as approximate; it must run and follow the sign of the motion."""
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    for c in cams:
        c.waveform = "rectangular"
    m = np.array([[1.0, 1.0], [0.01, -0.01], [0.5, 0.5], [0.005, -0.005]])
    res = rc.velocity(m, cams)
    assert res.valid.all() and res.velocity[0] > 0 > res.velocity[1]


# ------------------------------------------------------------------ general fit


@pytest.mark.parametrize("f", FREQUENCIES)
@pytest.mark.parametrize("kind", ["homo_hetero_0_90", "hu"])
def test_fit_recovers_velocity_and_depth(f, kind):
    amp, dist = scene(VELOCITIES.size, seed=3, max_depth=C / (2 * f) * 0.999)
    cams = ratio_set(f, [0.0, 0.5 * np.pi]) if kind != "hu" else hu_set(f)
    m = rc.model_measurements(amp, dist, VELOCITIES, cams)
    res = rc.velocity(m, cams, method="fit")
    assert res.method == "fit"
    assert res.valid.all()
    np.testing.assert_allclose(res.velocity, VELOCITIES, rtol=1e-6)
    np.testing.assert_allclose(res.doppler_hz, 2 * f * VELOCITIES / C, rtol=1e-6)
    np.testing.assert_allclose(res.depth, dist, rtol=1e-6)
    np.testing.assert_allclose(res.amplitude, amp, rtol=1e-6)


def test_fit_matches_ratio_on_quadrature_pairs():
    cams = ratio_set(150e6, [0.3, 0.3 + 0.5 * np.pi])
    amp, dist = scene(VELOCITIES.size, seed=7)
    m = rc.model_measurements(amp, dist, VELOCITIES, cams)
    fit = rc.velocity(m, cams, method="fit")
    ratio = rc.velocity(m, cams, method="ratio")
    assert fit.valid.all()
    np.testing.assert_allclose(fit.velocity, ratio.velocity, rtol=1e-6)
    np.testing.assert_allclose(fit.velocity, VELOCITIES, rtol=1e-6)


def test_fit_auto_selects_fit_for_hu_set():
    cams = hu_set(30e6)
    m = rc.model_measurements(np.ones(2), np.array([1.0, 2.0]), np.array([1.0, -1.0]), cams)
    assert rc.velocity(m, cams).method == "fit"
    # sinusoids: the fit, whatever the set (it models the brightening to second order)
    assert rc.velocity(m, ratio_set(30e6, [0.0, 0.5 * np.pi])).method == "fit"
    rectangular = ratio_set(30e6, [0.0, 0.5 * np.pi])
    for c in rectangular:
        c.waveform = "rectangular"
    assert rc.velocity(m, rectangular).method == "ratio"
    # pairs whose phases do not balance (Σ e^{2iψ} ≠ 0) cannot cancel a brightness change
    with pytest.raises(ValueError, match="must balance"):
        rc.velocity(m, ratio_set(30e6, [0.0, 1.0]), method="ratio")


def test_fit_large_doppler_and_arbitrary_set():
    """Velocities of hundreds of m/s (a ~ 1 rad), 3 cameras with fractional/negative h."""
    f = 150e6
    cams = cams_from(f, [(0.25, 0.1), (-1.3, 2.0), (0.0, 4.0), (0.8, 5.5)])
    v = np.array([-300.0, -40.0, 0.3, 150.0, 310.0])
    amp, dist = scene(v.size, seed=4)
    m = rc.model_measurements(amp, dist, v, cams)
    res = rc.velocity(m, cams)
    assert res.valid.all()
    np.testing.assert_allclose(res.velocity, v, rtol=1e-6)
    assert np.all(depth_error(res.depth, dist, f) < 1e-8)


def test_fit_with_noise_is_unbiased_on_average():
    f = 150e6
    cams = ratio_set(f, [0.0, 0.5 * np.pi])
    n = 20_000
    m = rc.model_measurements(np.ones(n), np.full(n, 1.234), np.full(n, 12.0), cams)
    m = m + np.random.default_rng(5).normal(0.0, 1e-3, m.shape)
    res = rc.velocity(m, cams, method="fit")
    assert res.valid.mean() > 0.99
    v = res.velocity[res.valid]
    assert abs(v.mean() - 12.0) < 5 * v.std() / np.sqrt(v.size)


def test_fit_masks_zero_amplitude_and_out_of_range():
    f = 30e6
    cams = hu_set(f)
    k = 2 * np.pi * f / C
    v_too_fast = 0.97 * np.pi / (2 * k * T)  # a = 0.97π, outside the search range 0.9π
    v = np.array([3.0, 3.0, v_too_fast])
    m = rc.model_measurements(np.array([1.0, 0.0, 1.0]), 1.0, v, cams)
    res = rc.velocity(m, cams, max_doppler_hz=0.9 / (2 * T))
    assert res.valid.tolist() == [True, False, False]
    assert np.isnan(res.velocity[1:]).all()
    assert res.velocity[0] == pytest.approx(3.0, rel=1e-6)


def test_fit_masks_faint_pixels_by_default():
    cams = hu_set(30e6)
    m = rc.model_measurements(np.array([1.0, 1e-5]), 1.0, 3.0, cams)
    assert rc.velocity(m, cams).valid.tolist() == [True, False]
    # the faint pixel is exact data: it is the threshold, not the fit, that masks it
    res = rc.velocity(m, cams, min_amplitude=0.0)
    np.testing.assert_allclose(res.velocity, [3.0, 3.0], rtol=1e-6)


def test_all_zero_image_is_all_invalid():
    cams = hu_set(30e6)
    res = rc.velocity(np.zeros((4, 3, 3)), cams)
    assert not res.valid.any() and np.isnan(res.velocity).all() and np.isnan(res.depth).all()


# ------------------------------------------------------------------ depth


@pytest.mark.parametrize("f", FREQUENCIES)
def test_four_phase_homodyne_depth(f):
    cams = cams_from(f, [(0.0, p) for p in (0, 0.5 * np.pi, np.pi, 1.5 * np.pi)])
    amp, dist = scene(VELOCITIES.size, seed=6, max_depth=C / (2 * f) * 0.999)
    m = rc.model_measurements(amp, dist, VELOCITIES, cams)
    got = rc.depth(m, cams)
    # exact at mid-exposure despite the motion
    np.testing.assert_allclose(got, dist, rtol=1e-6)
    # the classic closed form
    phi = np.mod(np.arctan2(m[3] - m[1], m[0] - m[2]), 2 * np.pi)
    np.testing.assert_allclose(got, C * phi / (4 * np.pi * f), rtol=1e-9)


def test_depth_wraps_at_ambiguity_range():
    f = 30e6
    span = rc.ambiguity_range_m(f)
    assert span == pytest.approx(C / (2 * f))
    cams = cams_from(f, [(0.0, 0.0), (0.0, 0.5 * np.pi), (0.0, np.pi)])
    m = rc.model_measurements(1.0, span + 0.75, 0.0, cams)
    assert rc.depth(m, cams) == pytest.approx(0.75, rel=1e-9)
    # the velocity's result states the range its depth is taken modulo
    quad = ratio_set(30e6, [0.0, 0.5 * np.pi])
    res = rc.velocity(rc.model_measurements(np.ones(1), 5.75, 1.0, quad), quad)
    assert res.depth_range_m == pytest.approx(C / (2 * 30e6)) == rc.ambiguity_range_m(30e6)
    assert res.depth[0] == pytest.approx(5.75 - res.depth_range_m, rel=1e-9)


def test_depth_uses_fit_when_velocity_is_determined():
    f = 150e6
    cams = hu_set(f)
    m = rc.model_measurements(np.ones(2), np.array([0.4, 0.6]), np.array([-15.0, 15.0]), cams)
    np.testing.assert_allclose(rc.depth(m, cams), [0.4, 0.6], rtol=1e-9)


def test_velocity_from_homodyne_only_set_raises():
    cams = cams_from(30e6, [(0.0, p) for p in (0, 0.5 * np.pi, np.pi, 1.5 * np.pi)])
    m = rc.model_measurements(np.ones(2), 1.0, 1.0, cams)
    with pytest.raises(ValueError, match="velocity is not determined"):
        rc.velocity(m, cams)


# ------------------------------------------------------------------ validation


def test_count_mismatch_raises():
    cams = ratio_set(30e6, [0.0])
    with pytest.raises(ValueError, match=r"n_cameras = 2.*\(3, 4\)"):
        rc.velocity(np.zeros((3, 4)), cams)
    with pytest.raises(ValueError, match="n_cameras = 2"):
        rc.depth(np.zeros((3, 4)), cams)


@pytest.mark.parametrize("attribute, value, match", [
    ("modulation_frequency", 60e6, r"modulation_frequency = 30 MHz \(beside 60 MHz.*add h=1,psi=90deg$"),
    ("exposure", 2e-3, "exposure.*0.002"),
])
def test_mismatched_cameras_raise(attribute, value, match):
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    setattr(cams[3], attribute, value)
    with pytest.raises(ValueError, match=match):
        rc.velocity(np.ones((4, 2)), cams)


def test_fit_rejects_non_sinusoid():
    cams = hu_set(30e6)
    cams[2].waveform = "triangular"
    with pytest.raises(ValueError, match=r"sinusoid.*triangular"):
        rc.velocity(np.ones((4, 2)), cams, method="fit")


def test_ratio_rejects_unpaired_cameras():
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi]) + [Cam(heterodyne=0.0, phase=1.0)]
    with pytest.raises(ValueError, match="pair"):
        rc.velocity(np.ones((5, 2)), cams, method="ratio")
    mismatched = ratio_set(30e6, [0.0, 0.5 * np.pi])
    mismatched[1].phase = 0.5
    with pytest.raises(ValueError, match="pair"):
        rc.velocity(np.ones((4, 2)), mismatched, method="ratio")


def test_underdetermined_fit_raises():
    cams = cams_from(30e6, [(0.0, 0.0), (1.0, 0.5 * np.pi)])
    with pytest.raises(ValueError, match="cannot determine velocity"):
        rc.velocity(np.ones((2, 2)), cams)


def test_bad_arguments_raise():
    cams = ratio_set(30e6, [0.0])
    m = np.ones((2, 2))
    with pytest.raises(ValueError, match="method"):
        rc.velocity(m, cams, method="magic")
    with pytest.raises(ValueError, match="min_amplitude"):
        rc.velocity(m, cams, min_amplitude=-1.0)
    with pytest.raises(ValueError, match="max_doppler_hz"):
        rc.velocity(m, cams, max_doppler_hz=0.0)
    quad = ratio_set(30e6, [0.0, 0.5 * np.pi])
    m4, stderr = np.ones((4, 2)), np.full((4, 2), 0.01)
    for bad in (0.0, -1.0, float("nan"), "1 m/s"):
        with pytest.raises(ValueError, match="max_velocity_stderr"):
            rc.velocity(m4, quad, measurement_stderr=stderr, max_velocity_stderr=bad)
    with pytest.raises(ValueError, match=r"max_velocity_stderr=0.5 m/s needs the measurements' errors"):
        rc.velocity(m4, quad, max_velocity_stderr=0.5)
    with pytest.raises(ValueError, match="exposure"):
        rc.velocity(m, [Cam(exposure=-1.0), Cam(exposure=-1.0, heterodyne=1)])
    with pytest.raises(ValueError, match="depth needs at least two"):
        rc.depth(np.ones((1, 2)), [Cam()])
    with pytest.raises(ValueError, match="depth needs at least two"):
        rc.depth(np.ones((2, 2)), cams)  # one homodyne/heterodyne pair: a single phase
    with pytest.raises(ValueError, match="sinusoid"):
        rc.model_measurements(1.0, 1.0, 1.0, [Cam(waveform="rectangular")])


# ------------------------------------------------------------------ brightness change


def test_three_camera_set_is_refused_with_what_to_add():
    """h=0 at one phase and h=1 at two: three measurements for four unknowns (amplitude,
    depth phase, Doppler shift, brightness change), so a brightening surface reads as a
    Doppler shift. The refusal names the camera that completes the set."""
    cams = cams_from(30e6, [(0.0, 0.0), (1.0, 0.0), (1.0, 0.5 * np.pi)])
    m = rc.model_measurements(np.ones(2), 1.0, -10.0, cams)
    for method in ("auto", "fit"):
        with pytest.raises(ValueError, match=r"cannot determine velocity.*brightness.*add h=0,psi=90deg$"):
            rc.velocity(m, cams, method=method)
    single_pair = cams_from(30e6, [(0.0, 0.0), (1.0, 0.0)])
    for method in ("auto", "ratio", "fit"):
        with pytest.raises(ValueError, match=r"add h=0,psi=90deg and h=1,psi=90deg$"):
            rc.velocity(m[:2], single_pair, method=method)
    completed = cams + cams_from(30e6, [(0.0, 0.5 * np.pi)])
    assert rc.velocity(rc.model_measurements(np.ones(2), 1.0, -10.0, completed), completed).valid.all()


def test_three_cameras_cannot_tell_brightening_from_doppler():
    """Why the set above is refused: two different velocities give the same three
    measurements once the brightness may change (here found by the four-parameter model
    itself: the fourth camera, h=0 at 90°, is what tells them apart)."""
    f = 30e6
    cams = cams_from(f, [(0.0, 0.0), (1.0, 0.0), (1.0, 0.5 * np.pi), (0.0, 0.5 * np.pi)])
    truth = rc.model_measurements(1.0, 1.1, -10.0, cams, brightness=0.0)
    # Another scene: receding at +10 m/s. Its amplitude, depth and brightness slope are chosen
    # so that the first three measurements agree (three equations, three unknowns).
    def mismatch(p):
        return rc.model_measurements(p[0], p[1], 10.0, cams, brightness=p[2])[:3] - truth[:3]

    p = np.array([1.0, 1.1, 0.0])
    for _ in range(20):  # Newton's method, Jacobian by central differences
        jac = np.stack([(mismatch(p + e) - mismatch(p - e)) / 2e-7 for e in 1e-7 * np.eye(3)], axis=1)
        p = p - np.linalg.solve(jac, mismatch(p))
    assert np.max(np.abs(mismatch(p))) < 1e-13  # the three cameras cannot tell them apart
    assert abs(p[2]) < 0.5  # with a plausible brightening
    fourth = rc.model_measurements(p[0], p[1], 10.0, cams, brightness=p[2])[3]
    assert abs(fourth - truth[3]) > 1e-3 * abs(truth[0])  # h=0 at 90° can


@pytest.mark.parametrize("kind", ["pairs 0/60deg", "hu", "five"])
def test_fit_separates_brightness_change_from_doppler(kind):
    """A diffuse surface lit from the camera brightens as 1/d²: β = −2 v T/d. Sets whose
    phases do not balance (so the ratio would be biased) are fitted with β as an unknown and
    recover the velocity and depth exactly."""
    f = 30e6
    cams = {
        "pairs 0/60deg": ratio_set(f, [0.0, np.pi / 3]),
        "hu": hu_set(f),
        "five": cams_from(f, [(0.0, 0.0), (0.0, 2.0), (1.0, 0.3), (1.0, 2.0), (0.5, 1.0)]),
    }[kind]
    amp, dist = scene(VELOCITIES.size, seed=11, max_depth=4.9)
    beta = -2.0 * VELOCITIES * T / dist
    m = rc.model_measurements(amp, dist, VELOCITIES, cams, brightness=beta)
    res = rc.velocity(m, cams)
    assert res.method == "fit" and res.valid.all()
    np.testing.assert_allclose(res.velocity, VELOCITIES, rtol=1e-6)
    assert np.all(depth_error(res.depth, dist, f) < 1e-8)


@pytest.mark.parametrize("method", ["ratio", "fit"])
def test_propagated_errors_match_the_spread_of_noisy_estimates(method):
    """Correlated Gaussian noise of a known covariance on exact measurements: the stated
    velocity and depth errors equal the spread of the estimates over noise draws."""
    f, n = 30e6, 4000
    cams = ratio_set(f, [0.0, 0.5 * np.pi])
    dist, v = 2.3, -10.0
    m = rc.model_measurements(np.ones(n), dist, v, cams, brightness=-2 * v * T / dist)
    rng = np.random.default_rng(2)
    root = rng.normal(size=(4, 4)) * 2e-4
    cov = root @ root.T  # correlated cameras, as from shared paths
    noisy = m + (root @ rng.normal(size=(4, n)))
    res = rc.velocity(noisy, cams, method=method, measurement_covariance=np.repeat(cov[:, :, None], n, axis=2),
                      max_velocity_stderr=1e3)
    assert res.valid.all()
    stated_v, stated_d = np.median(res.velocity_stderr), np.median(res.depth_stderr)
    assert np.std(res.velocity) == pytest.approx(stated_v, rel=0.06)  # 4000 draws: ±2.2 % (1σ)
    assert np.std(res.depth) == pytest.approx(stated_d, rel=0.06)
    assert abs(np.mean(res.velocity) - v) < 4 * stated_v / np.sqrt(n) + 1e-3 * abs(v)


def test_inverse_square_curvature_biases_the_ratio_not_the_fit():
    """The README's figure: on inverse-square data the ratio reads +0.0046 m/s too high at
    ±10 m/s and 5 m (∝ v²/d²: the curvature ¾β² it does not model); the fit is exact."""
    cams = ratio_set(30e6, [0.0, 0.5 * np.pi])
    for v, d in ((10.0, 5.0), (-10.0, 5.0), (40.0, 5.0), (10.0, 2.5)):
        m = rc.model_measurements(np.ones(1), d, v, cams, brightness=-2 * v * T / d)
        ratio = rc.velocity(m, cams, method="ratio").velocity[0]
        assert ratio - v == pytest.approx(0.0046 * (v / 10.0) ** 2 * (5.0 / d) ** 2, rel=0.03)
        assert rc.velocity(m, cams, method="fit").velocity[0] == pytest.approx(v, rel=1e-9)


def test_default_threshold_is_a_tenth_of_the_detected_speeds_else_a_centimetre_a_second():
    rng = np.random.default_rng(4)
    sigma = np.full(10_000, 0.2)
    static = rng.standard_t(15, sigma.size) * sigma  # noise alone: a few |v| > 5 σ by chance
    limit, reason = rc.default_max_velocity_stderr(static, sigma)
    assert limit == rc.UNSCALED_MAX_VELOCITY_STDERR_M_S == 0.01 and "too few pixels move detectably" in reason
    moving = static.copy()
    moving[:500] = rng.uniform(8.0, 12.0, 500)  # 5 % of the pixels move at 8 to 12 m/s
    limit, reason = rc.default_max_velocity_stderr(moving, sigma)
    assert limit == pytest.approx(0.1 * np.percentile(moving[:500], 90), rel=0.02) and "speed scale" in reason
    unknown = np.full(4, np.nan)  # nothing determined: no scale either
    assert rc.default_max_velocity_stderr(unknown, unknown)[0] == 0.01


def test_a_render_whose_motion_is_below_the_noise_marks_no_noisy_pixel_valid():
    """The glossy scene at 32², 256 spp: the sphere rolling at 2 m/s is not detected at five
    standard errors anywhere, so there is no speed scale. The threshold used to be 5 % of
    the speed range (83 m/s): 85 % of the pixels were valid, with an RMSE of 8.7 m/s. Valid
    pixels now know their velocity to 1 cm/s, and their errors are the stated ones."""
    result = dt.render(dt.scenes.glossy(resolution=32), cameras=[dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)], spp=256, seed=1)
    v = rc.velocity(result)
    assert "too few pixels move detectably" in v.threshold_reason and v.max_velocity_stderr_m_s == 0.01
    assert 0.05 < v.valid.mean() < 0.6
    assert np.all(v.velocity_stderr[v.valid] <= 0.01)
    error = (v.velocity - result.maps["velocity"])[v.valid]
    assert np.sqrt(np.mean(error**2)) < 0.01


# ------------------------------------------------------------------ two frequencies


def two_frequency_set():
    return ratio_set(30e6, [0.0, 0.5 * np.pi]) + ratio_set(20e6, [0.0, 0.5 * np.pi])


def test_two_frequencies_unwrap_depth_to_the_beat_range():
    """30 and 20 MHz: each depth is known modulo 5 m and 7.5 m, the pair's modulo
    c/(2 × 10 MHz) = 15 m; velocity is both frequencies' (exact data: the same)."""
    cams = two_frequency_set()
    n = VELOCITIES.size
    dist = np.linspace(0.3, 14.7, n)
    m = rc.model_measurements(np.ones(n), dist, VELOCITIES, cams, brightness=-2 * VELOCITIES * T / dist)
    res = rc.velocity(m, cams)
    assert res.valid.all() and res.frequencies_hz == (30e6, 20e6)
    assert res.depth_range_m == pytest.approx(C / (2 * 10e6))
    np.testing.assert_allclose(res.velocity, VELOCITIES, rtol=1e-6)
    np.testing.assert_allclose(res.depth, dist, rtol=1e-9)
    assert np.all(dist > rc.ambiguity_range_m(30e6)) == np.all(res.depth > 5.0)  # beyond each range
    np.testing.assert_allclose(rc.depth(m, cams), dist, rtol=1e-9)
    homodyne = [c for c in cams if c.heterodyne == 0]  # classic two-frequency AMCW: homodyne only
    np.testing.assert_allclose(rc.depth(m[[i for i, c in enumerate(cams) if c.heterodyne == 0]], homodyne), dist, atol=2e-3)


def test_two_frequencies_combine_their_errors():
    """Noise of a known covariance: the combined velocity error is the inverse-variance
    one, and it matches the spread over noise draws; depth errors are the finer frequency's."""
    cams = two_frequency_set()
    n = 4000
    m = rc.model_measurements(np.ones(n), 6.3, -10.0, cams, brightness=2 * 10.0 * T / 6.3)
    cov = np.diag(np.full(8, 1e-4**2))
    noisy = m + np.random.default_rng(3).normal(0.0, 1e-4, m.shape)
    res = rc.velocity(noisy, cams, measurement_covariance=np.repeat(cov[:, :, None], n, axis=2), max_velocity_stderr=1e3)
    alone = [rc.velocity(noisy[g], [cams[i] for i in g], measurement_covariance=np.repeat(cov[:4, :4, None], n, axis=2),
                         max_velocity_stderr=1e3) for g in ([0, 1, 2, 3], [4, 5, 6, 7])]
    expected = 1.0 / np.sqrt(sum(1.0 / np.median(a.velocity_stderr) ** 2 for a in alone))
    assert np.median(res.velocity_stderr) == pytest.approx(expected, rel=1e-3)
    assert np.std(res.velocity) == pytest.approx(expected, rel=0.06)
    assert np.mean(np.abs(res.depth - 6.3) < 0.05) > 0.999  # unwrapped right: 6.3 m is beyond 5 m


def test_two_frequencies_refusals():
    cams = two_frequency_set()
    m = np.ones((8, 2))
    with pytest.raises(ValueError, match=r"modulation_frequency = 20 MHz \(beside 30 MHz.*add h=1,psi=90deg$"):
        rc.velocity(m[:7], cams[:7])  # the 20 MHz cameras lack h=1 at 90°
    three = cams + cams_from(50e6, [(0.0, 0.0), (1.0, 0.0), (0.0, 0.5 * np.pi), (1.0, 0.5 * np.pi)])
    with pytest.raises(ValueError, match=r"3 modulation frequencies \(30, 20, 50 MHz\).*combines two"):
        rc.velocity(np.ones((12, 2)), three)
    later = [Cam(modulation_frequency=c.modulation_frequency, heterodyne=c.heterodyne, phase=c.phase) for c in cams]
    for c in later:
        c.exposure_start = 0.0 if c.modulation_frequency == 30e6 else 1e-3
    with pytest.raises(ValueError, match="different times"):
        rc.velocity(m, later)


def test_unwrap_depth_refuses_an_unsure_choice():
    fine, coarse = 5.0, 7.5
    truth = np.array([0.2, 4.9, 5.1, 9.0, 14.8])
    got = rc.frequencies.unwrap_depth(np.mod(truth, fine), fine, np.mod(truth, coarse), coarse)
    np.testing.assert_allclose(got, truth, atol=1e-12)
    # the 7.5 m depth off by 1.25 m: the phase difference points between two choices of 5 m
    assert np.isnan(rc.frequencies.unwrap_depth(np.array([1.0]), fine, np.array([2.25]), coarse)).all()


def test_a_pixel_measured_by_one_sample_is_not_valid():
    """One contributing sample: each mean is its stderr and the covariance is m mᵀ, so the
    velocity (unchanged when every measurement is scaled) got a propagated error of zero and
    the pixel was valid, whatever its answer. Many samples of the same signal stay valid."""
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    m = dt.reconstruct.model_measurements([1.0], 2.0, 3.0, cameras)  # (4, 1)
    one_sample = np.einsum("ip,jp->ijp", m, m)
    assert not dt.reconstruct.velocity(m, cameras, measurement_covariance=one_sample, max_velocity_stderr=100.0).valid.any()
    many = one_sample / 400.0 + np.eye(4)[:, :, None] * 1e-6  # |m| / σ = 20
    assert dt.reconstruct.velocity(m, cameras, measurement_covariance=many, max_velocity_stderr=100.0).valid.all()


def test_exact_heterodyne_measurements_beside_sampled_motion_are_not_valid():
    """With antithetic times a static path cancels exactly at h = 1: a pixel whose samples all
    missed a moving surface reads 0 ± 0 m/s (a rotating rim at 45 m/s did at 16 spp). Beside
    a pixel that sampled motion such a pixel is not valid; away from any (a wall lit directly),
    its exact 0 is. A row of 6 pixels: 0-1 sampled motion, 2-5 are static and exact."""
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    m = dt.reconstruct.model_measurements(np.ones(6), 2.0, np.array([5.0, 5.0, 0, 0, 0, 0]), cameras)
    covariance = np.zeros((4, 4, 6))
    for i in range(4):
        covariance[i, i] = 1e-12  # σ = 1e-6: the h = 1 signal, 3e-4, resolved
    covariance[2, 2, 2:] = covariance[3, 3, 2:] = 0.0  # no sampled path changed: h = 1 exact
    result = dt.reconstruct.velocity(m, cameras, measurement_covariance=covariance, max_velocity_stderr=1.0)
    np.testing.assert_array_equal(result.valid, [True, True, False, True, True, True])
    assert abs(result.velocity[3]) < 1e-9 and result.velocity_stderr[3] < 1e-6
    # the same along an image's rows and columns
    image = dt.reconstruct.velocity(m.reshape(4, 3, 2), cameras, measurement_covariance=covariance.reshape(4, 4, 3, 2), max_velocity_stderr=1.0)
    np.testing.assert_array_equal(image.valid, [[True, True], [False, False], [True, True]])  # diagonal neighbours count


def test_depth_of_non_sinusoidal_cameras_states_no_standard_error():
    """Square-wave cameras' depth has the waveform's cyclic error (3.6 cm median on a static
    scene) that the Monte Carlo error (4.8 mm) does not hold: 78 % of pixels were off by more
    than three of those; the error is now not stated."""
    cameras = [dt.Camera(heterodyne=h, phase=p, waveform="rectangular") for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    m = np.array([[0.3, 0.2], [0.1, 0.25], [0.05, 0.02], [0.04, 0.03]])
    result = dt.reconstruct.velocity(m, cameras, measurement_stderr=np.full_like(m, 1e-4))
    assert result.depth_stderr is not None and np.isnan(result.depth_stderr).all()


def test_negative_standard_errors_are_refused():
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    m = dt.reconstruct.model_measurements([1.0], 2.0, 3.0, cameras)
    with pytest.raises(ValueError, match="measurement_stderr must be >= 0"):  # the sign was dropped
        dt.reconstruct.velocity(m, cameras, measurement_stderr=-np.full_like(m, 1e-3))
