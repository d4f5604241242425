"""Tests of dopplertof.sensor: tap normalisation, noise statistics, saturation, ADC."""

from __future__ import annotations


import numpy as np
import pytest

from dopplertof import reconstruct as rc
from dopplertof.sensor import SensorModel, luminance

from camera_stub import T, Cam  # noqa: E402
N_SAMPLES = 400_000


def mean_and_variance_bounds(samples, mean, variance, z=5.0):
    """Assert sample mean and variance agree with theory within z standard errors.

    The standard error of the sample variance uses the fourth central moment of the
    samples themselves: Var(s²) ≈ (μ₄ − σ⁴)/n.
    """
    n = samples.size
    centred = samples - samples.mean()
    mu4 = np.mean(centred**4)
    assert abs(samples.mean() - mean) < z * np.sqrt(variance / n)
    assert abs(samples.var(ddof=1) - variance) < z * np.sqrt((mu4 - variance**2) / n)


# ------------------------------------------------------------------ expected taps


def test_expected_taps_normalisation():
    sensor = SensorModel(electrons_per_unit=2e6, quantum_efficiency=0.8,
                         ambient_electrons_per_s=3e5)
    cam = Cam(g0=0.6)
    intensity = np.array([0.5, 1.0, 2.0])
    m = np.array([0.1, -0.2, 0.0])
    a, b = sensor.expected_taps(intensity, m, cam)
    kappa_t = 2e6 * 0.8 * T
    np.testing.assert_allclose((a - b) / kappa_t, m, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a + b, kappa_t * 0.6 * intensity + 2 * 3e5 * T, rtol=1e-12)
    assert sensor.electrons_per_unit_exposure(cam) == pytest.approx(kappa_t)


def test_expected_taps_clip_negative_expectation():
    sensor = SensorModel(electrons_per_unit=1e6)
    a, b = sensor.expected_taps(1.0, 0.9, Cam(g0=0.5))  # |m| > g0 I: inconsistent render
    assert b == 0.0 and a > 0


def test_expected_taps_broadcast():
    sensor = SensorModel(electrons_per_unit=1e6)
    a, b = sensor.expected_taps(np.ones((4, 5)), np.zeros(5), Cam())
    assert a.shape == b.shape == (4, 5)


# ------------------------------------------------------------------ noise statistics


@pytest.mark.parametrize("shot_noise", [True, False])
def test_tap_mean_and_variance_match_poisson_plus_gaussian(shot_noise):
    gain = 0.5
    sensor = SensorModel(electrons_per_unit=4e6, ambient_electrons_per_s=2e5,
                         read_noise_e=4.0, gain_e_per_dn=gain, full_well_e=1e5,
                         adc_bits=16, black_level_dn=100.0, shot_noise=shot_noise)
    cam = Cam()
    intensity = np.full(N_SAMPLES, 1.0)
    m = np.full(N_SAMPLES, 0.15)
    expected_a, expected_b = sensor.expected_taps(intensity, m, cam)
    tap_a, tap_b = sensor.sample_taps(intensity, m, cam, np.random.default_rng(11))
    for taps, lam in ((tap_a, expected_a[0]), (tap_b, expected_b[0])):
        variance_e = (lam if shot_noise else 0.0) + 4.0**2
        # quantisation adds LSB²/12 (uniform rounding error; the signal spans many LSBs)
        variance_dn = variance_e / gain**2 + 1.0 / 12.0
        mean_and_variance_bounds(taps.astype(np.float64), lam / gain + 100.0, variance_dn)


def test_measurement_noise_matches_theory_and_is_unbiased():
    sensor = SensorModel(electrons_per_unit=2e6, ambient_electrons_per_s=1e5,
                         read_noise_e=3.0, gain_e_per_dn=1.0, full_well_e=1e5, adc_bits=16)
    cam = Cam()
    intensity = np.full(N_SAMPLES, 1.2)
    m = np.full(N_SAMPLES, -0.2)
    noisy = sensor.noisy_measurements(intensity, m[None], [cam], seed=3)[0]
    std = sensor.measurement_std(1.2, -0.2, cam)
    mean_and_variance_bounds(noisy, -0.2, float(std) ** 2)


def test_zero_light_gives_ambient_and_read_noise_only():
    gain = 0.25
    sensor = SensorModel(electrons_per_unit=1e7, ambient_electrons_per_s=4e4,
                         read_noise_e=2.5, gain_e_per_dn=gain, adc_bits=16,
                         black_level_dn=200.0)
    cam = Cam()
    zeros = np.zeros(N_SAMPLES)
    tap_a, tap_b = sensor.sample_taps(zeros, zeros, cam, rng=5)
    ambient_e = 4e4 * T  # 60 electrons per tap
    for taps in (tap_a, tap_b):
        variance_dn = (ambient_e + 2.5**2) / gain**2 + 1.0 / 12.0
        mean_and_variance_bounds(taps.astype(np.float64), ambient_e / gain + 200.0, variance_dn)
    # ambient light cancels in the difference: the measurement is zero on average
    measured = sensor.taps_to_measurement(tap_a, tap_b, cam)
    assert abs(measured.mean()) < 5 * measured.std() / np.sqrt(N_SAMPLES)


def test_zero_light_no_ambient_no_read_noise_is_exactly_black_level():
    sensor = SensorModel(electrons_per_unit=1e7, read_noise_e=0.0, black_level_dn=64.0)
    tap_a, tap_b = sensor.sample_taps(np.zeros(1000), np.zeros(1000), Cam(), rng=0)
    assert np.all(tap_a == 64) and np.all(tap_b == 64)


# ------------------------------------------------------------------ saturation, ADC


def test_saturation_clips_exactly_at_full_well():
    # κT = 48 000 e⁻: tap A gets 0.375 κT = 18 000 e⁻ (saturates), tap B 0.125 κT = 6 000 e⁻
    sensor = SensorModel(electrons_per_unit=3.2e7, read_noise_e=0.0, full_well_e=12_000.0,
                         gain_e_per_dn=4.0, adc_bits=12)
    cam = Cam()
    intensity = np.array([1.0, 1.0, 1e-6])
    m = np.array([0.25, -0.25, 0.0])
    tap_a, tap_b = sensor.sample_taps(intensity, m, cam, rng=1)
    assert tap_a[0] == 3000 and tap_b[0] < 3000
    assert tap_a[1] < 3000 and tap_b[1] == 3000
    assert tap_a[2] < 3000 and tap_b[2] < 3000
    # far beyond the full well: still exactly the full well, every sample
    many_a, many_b = sensor.sample_taps(np.full(10_000, 100.0), 0.0, cam, rng=2)
    assert np.all(many_a == 3000) and np.all(many_b == 3000)


def test_adc_clips_at_max_code():
    sensor = SensorModel(electrons_per_unit=1e9, read_noise_e=0.0, full_well_e=1e5,
                         gain_e_per_dn=1.0, adc_bits=10)
    tap_a, _ = sensor.sample_taps(np.ones(100), 0.0, Cam(), rng=1)
    assert sensor.max_dn == 1023
    assert np.all(tap_a == 1023)


def test_quantisation_is_integer_in_range_and_round_trip_within_half_lsb():
    gain = 3.7
    sensor = SensorModel(electrons_per_unit=5e6, read_noise_e=0.0, shot_noise=False,
                         gain_e_per_dn=gain, full_well_e=50_000.0, adc_bits=14)
    cam = Cam()
    rng = np.random.default_rng(0)
    intensity = rng.uniform(0.0, 4.0, 50_000)
    m = 0.25 * intensity * rng.uniform(-1.0, 1.0, intensity.size)
    tap_a, tap_b = sensor.sample_taps(intensity, m, cam, rng=rng)
    assert np.issubdtype(tap_a.dtype, np.integer) and np.issubdtype(tap_b.dtype, np.integer)
    for taps in (tap_a, tap_b):
        assert taps.min() >= 0 and taps.max() <= 2**14 - 1
    expected_a, expected_b = sensor.expected_taps(intensity, m, cam)
    assert expected_a.max() < 50_000  # nothing saturates, so rounding is the only error
    assert np.max(np.abs(tap_a * gain - expected_a)) <= gain / 2 + 1e-9
    assert np.max(np.abs(tap_b * gain - expected_b)) <= gain / 2 + 1e-9
    # the difference of two taps: at most one LSB, in measurement units gain/(κT)
    lsb = gain / sensor.electrons_per_unit_exposure(cam)
    error = sensor.taps_to_measurement(tap_a, tap_b, cam) - m
    assert np.max(np.abs(error)) <= lsb + 1e-12
    assert np.max(np.abs(error)) > 0.25 * lsb  # the quantisation is really there


# ------------------------------------------------------------------ seeds


def test_same_seed_same_noise_different_seed_different_noise():
    sensor = SensorModel(electrons_per_unit=1e6)
    cams = [Cam(heterodyne=h, phase=p) for p in (0.0, 0.5 * np.pi) for h in (0.0, 1.0)]
    intensity = np.full((8, 8), 1.0)
    m = rc.model_measurements(intensity, 1.0, 5.0, cams)
    first = sensor.noisy_measurements(intensity, m, cams, seed=42)
    again = sensor.noisy_measurements(intensity, m, cams, seed=42)
    other = sensor.noisy_measurements(intensity, m, cams, seed=43)
    assert first.shape == (4, 8, 8)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)
    ta = sensor.sample_taps(intensity, m[0], cams[0], rng=7)
    tb = sensor.sample_taps(intensity, m[0], cams[0], rng=np.random.default_rng(7))
    np.testing.assert_array_equal(ta[0], tb[0])


def test_cameras_get_independent_noise():
    sensor = SensorModel(electrons_per_unit=1e6)
    cams = [Cam(), Cam()]  # identical cameras, identical inputs
    intensity = np.ones(20_000)
    m = np.full((2, 20_000), 0.1)
    noisy = sensor.noisy_measurements(intensity, m, cams, seed=1)
    assert abs(np.corrcoef(noisy[0], noisy[1])[0, 1]) < 5 / np.sqrt(20_000)


def test_noisy_measurements_feed_velocity_reconstruction():
    """End to end: bright noisy measurements still give the velocity on average."""
    sensor = SensorModel(electrons_per_unit=1e8, full_well_e=1e6, adc_bits=20)
    cams = [Cam(modulation_frequency=150e6, heterodyne=h, phase=p)
            for p in (0.0, 0.5 * np.pi) for h in (0.0, 1.0)]
    intensity = np.ones(5_000)
    m = rc.model_measurements(intensity, 1.1, 10.0, cams)
    noisy = sensor.noisy_measurements(intensity, m, cams, seed=9)
    v = rc.velocity(noisy, cams).velocity
    assert abs(np.nanmean(v) - 10.0) < 5 * np.nanstd(v) / np.sqrt(np.isfinite(v).sum())
    assert np.nanstd(v) > 0  # noise really reached the reconstruction


# ------------------------------------------------------------------ validation, helpers


@pytest.mark.parametrize("name, value", [
    ("electrons_per_unit", 0.0),
    ("electrons_per_unit", np.nan),
    ("quantum_efficiency", 0.0),
    ("quantum_efficiency", 1.5),
    ("ambient_electrons_per_s", -1.0),
    ("read_noise_e", -0.1),
    ("full_well_e", 0.0),
    ("gain_e_per_dn", -2.0),
    ("adc_bits", 0),
    ("adc_bits", 12.5),
    ("adc_bits", 40),
    ("black_level_dn", -1.0),
    ("black_level_dn", 5000.0),
    ("shot_noise", "yes"),
])
def test_invalid_parameters_raise_naming_the_parameter(name, value):
    kwargs = {"electrons_per_unit": 1e6, name: value}
    with pytest.raises(ValueError, match=name) as info:
        SensorModel(**kwargs)
    assert repr(value) in str(info.value)


def test_invalid_camera_and_shapes_raise():
    sensor = SensorModel(electrons_per_unit=1e6)
    with pytest.raises(ValueError, match="exposure"):
        sensor.expected_taps(1.0, 0.0, Cam(exposure=0.0))
    with pytest.raises(ValueError, match="g0"):
        sensor.expected_taps(1.0, 0.0, Cam(g0=-0.5))
    with pytest.raises(ValueError, match=r"n_cameras = 2.*\(3, 4\)"):
        sensor.noisy_measurements(np.ones(4), np.zeros((3, 4)), [Cam(), Cam()], seed=0)


def test_luminance():
    rgb = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    np.testing.assert_allclose(luminance(rgb), [0.2126, 0.7152, 0.0722, 1.0])
    assert luminance(np.ones((2, 3, 3))).shape == (2, 3)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        luminance(np.ones((4, 4)))


# ------------------------------------------------------------------ an alias onto Silicon


def _old_chain(sensor_kwargs, intensity, m, cam, seed):
    """The tap chain as SensorModel computed it before it became an alias (frozen here):
    κ = electrons_per_unit × QE, N = κT(g0 I ± m)/2 + qT, tap A then tap B through digitize."""
    from dopplertof.sensors.noise import digitize

    kw = {"quantum_efficiency": 1.0, "ambient_electrons_per_s": 0.0, "read_noise_e": 3.0, "full_well_e": 20_000.0,
          "adc_bits": 12, "gain_e_per_dn": 5.0, "black_level_dn": 0.0, "shot_noise": True, **sensor_kwargs}
    kappa_t = kw["electrons_per_unit"] * kw["quantum_efficiency"] * cam.exposure
    ambient = kw["ambient_electrons_per_s"] * cam.exposure
    taps = [np.maximum(0.5 * kappa_t * (cam.g0 * intensity + sign * m) + ambient, 0.0) for sign in (1, -1)]
    rng = np.random.default_rng(seed)
    return [digitize(t, rng, full_well_e=kw["full_well_e"], read_noise_e=kw["read_noise_e"], gain_e_per_dn=kw["gain_e_per_dn"],
                     black_level_dn=kw["black_level_dn"], max_dn=(1 << kw["adc_bits"]) - 1, shot_noise=kw["shot_noise"]) for t in taps]


@pytest.mark.parametrize("kwargs", [
    dict(electrons_per_unit=2e6, quantum_efficiency=0.8, ambient_electrons_per_s=3e5, read_noise_e=4.0, black_level_dn=50.0),
    dict(electrons_per_unit=3.2e7, read_noise_e=0.0, full_well_e=12_000.0, gain_e_per_dn=4.0),
    dict(electrons_per_unit=5e6, shot_noise=False, gain_e_per_dn=3.7, full_well_e=50_000.0, adc_bits=14),
])
def test_old_calls_give_the_same_digital_numbers(kwargs):
    cam = Cam(g0=0.6)
    rng = np.random.default_rng(0)
    intensity = rng.uniform(0.0, 2.0, 20_000)
    m = 0.3 * intensity * rng.uniform(-1.0, 1.0, intensity.size)  # |m| < g0 I: no clipping
    new = SensorModel(**kwargs).sample_taps(intensity, m, cam, rng=12)
    old = _old_chain(kwargs, intensity, m, cam, seed=12)
    for tap_new, tap_old in zip(new, old):
        np.testing.assert_array_equal(tap_new, tap_old)


def test_sensor_model_is_a_one_frame_two_tap_sensor_on_its_silicon():
    import dopplertof as dt

    model = SensorModel(electrons_per_unit=2e6, quantum_efficiency=0.8, ambient_electrons_per_s=3e5, read_noise_e=4.0)
    assert model.silicon.electrons_per_unit_s == pytest.approx(2e6 * 0.8, rel=1e-15)
    assert model.silicon.ambient_e_per_s == 6e5 and model.silicon.read_noise_e == 4.0 and model.silicon.gain_e_per_dn == 5.0
    frame = dt.RawFrame(exposure=T, g0=0.6)
    sensor = dt.Sensor(frames=[frame], taps=2, noise=model.silicon)
    intensity = np.linspace(0.1, 2.0, 50)
    m = 0.2 * intensity * np.cos(np.arange(50.0))
    electrons = sensor.expected_electrons(sensor.raw(np.stack([m, intensity]), clip=False))
    np.testing.assert_allclose(np.stack(model.expected_taps(intensity, m, frame)), electrons[0], rtol=1e-12)
    np.testing.assert_allclose(model.measurement_std(intensity, m, frame) * model.electrons_per_unit_exposure(frame),
                               np.sqrt(model.silicon.tap_variance_e2(electrons[0]).sum(axis=0)), rtol=1e-12)
