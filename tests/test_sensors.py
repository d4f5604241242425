"""Sensors: raw frames, tap layouts, raw electrons from one render, and the noise chain."""

import dataclasses
import re
import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import codes
from dopplertof.sensor import luminance
from dopplertof.sensors import RawFrame, Sensor, Silicon

T = 1e-3
SILICON = Silicon(radiance_unit=1e-3, demodulation_contrast=((10e6, 0.9), (50e6, 0.7)))


@pytest.fixture(scope="module")
def cornell():
    return dt.scenes.cornell_box(resolution=12)


def _frames(n=4, **kw):
    return [RawFrame(modulation_frequency=30e6, phase=k * 2 * math.pi / n, exposure=T, **kw) for k in range(n)]


def test_two_taps_sum_to_the_exposure_weighted_intensity_and_differ_by_the_contrast(cornell):
    sensor = Sensor(frames=_frames(), taps=2, noise=SILICON)
    result = dt.render(cornell, sensor=sensor, spp=8, max_depth=3, seed=1)
    assert result.raw.shape == (4, 2, 12, 12) and result.sensor is sensor
    kappa_t = SILICON.electrons_per_unit_s * T
    contrast = SILICON.contrast(30e6)
    assert contrast == pytest.approx(0.8)
    a, b = result.raw[:, 0].astype(np.float64), result.raw[:, 1].astype(np.float64)
    # light = g1·0 + g0 (sinusoid: zero mean) times the window's luminance
    expected_sum = kappa_t * 0.5 * luminance(result.intensity)
    np.testing.assert_allclose(a + b, np.broadcast_to(expected_sum, a.shape), rtol=1e-4, atol=1e-4 * expected_sum.max())
    expected_difference = contrast * kappa_t * result.measurements[:4]
    np.testing.assert_allclose(a - b, expected_difference, atol=1e-5 * np.abs(expected_difference).max())
    assert np.abs(expected_difference).max() > 1e-3 * expected_sum.max()  # the test sees a signal


def test_four_taps_and_one_tap(cornell):
    frames = _frames(2)
    four = Sensor(frames=frames, taps=4, noise=SILICON)
    one = Sensor(frames=frames, taps=1, noise=SILICON)
    r4 = dt.render(cornell, sensor=four, spp=8, max_depth=3, seed=2)
    r1 = dt.render(cornell, sensor=one, spp=8, max_depth=3, seed=2)
    kappa_t, c = SILICON.electrons_per_unit_s * T, SILICON.contrast(30e6)
    light = kappa_t * 0.5 * luminance(r4.intensity)
    raw4 = r4.raw.astype(np.float64)
    np.testing.assert_allclose(raw4.sum(axis=1), np.broadcast_to(light, (2, 12, 12)), rtol=1e-4, atol=1e-4 * light.max())
    m = r4.measurements[:2].astype(np.float64)  # taps 0 of each frame: the frames themselves
    # the sinusoid is antiperiodic: tap 0 − tap 2 = (κT c / 4)(M − (−M))
    np.testing.assert_allclose(raw4[:, 0] - raw4[:, 2], 0.5 * c * kappa_t * m, atol=1e-5 * light.max())
    light1 = kappa_t * 0.5 * luminance(r1.intensity)
    np.testing.assert_allclose(r1.raw[:, 0], 0.5 * (light1 + c * kappa_t * r1.measurements[:2]), rtol=1e-4, atol=1e-4 * light1.max())


def test_raw_frames_in_a_capture_schedule_use_their_own_window(cornell):
    frames = [RawFrame(exposure=T, exposure_start=k * T, phase=k * math.pi / 2) for k in range(2)]
    sensor = Sensor(frames=frames, noise=SILICON)
    result = dt.render(cornell, sensor=sensor, spp=8, max_depth=2, seed=3)
    assert [c.exposure_start for c in result.cameras] == [0.0, T, 0.0, T]  # frames, then each window's luminance
    light = SILICON.electrons_per_unit_s * T * 0.5 * result.measurements[2:].astype(np.float64)
    np.testing.assert_allclose(result.raw.sum(axis=1), light, rtol=1e-5, atol=1e-5 * light.max())


def test_coded_frames_render_their_light_mean(cornell):
    """A coded frame's light has a mean (a 0/1 pulse train): A + B counts it."""
    pulse = np.r_[np.ones(4), np.zeros(12)]
    square = np.sign(np.cos(2 * np.pi * (np.arange(16) + 0.5) / 16))
    frame = RawFrame(exposure=T, light_code=pulse, sensor_code=square, g1=1.0, g0=0.0)
    result = dt.render(cornell, sensor=Sensor(frames=[frame], noise=SILICON), spp=4, max_depth=2)
    light = SILICON.electrons_per_unit_s * T * 0.25 * luminance(result.intensity)
    np.testing.assert_allclose(result.raw[0].sum(axis=0), light, rtol=1e-4, atol=1e-4 * light.max())


def test_raw_frame_heterodyne_in_hz_or_h():
    assert RawFrame(exposure=1.5e-3, heterodyne_hz=666.6).heterodyne == pytest.approx(0.9999)
    assert RawFrame().heterodyne == 0.0  # a raw frame is homodyne unless told
    frame = RawFrame(exposure=2e-3, heterodyne_hz=500.0)
    assert dataclasses.replace(frame, phase=1.0).heterodyne == pytest.approx(1.0)
    with pytest.raises(ValueError, match="not both"):
        RawFrame(heterodyne=0.3, heterodyne_hz=500.0, exposure=1e-3)
    with pytest.raises(ValueError, match="'heterodyne_hz' must be a finite number"):
        RawFrame(heterodyne_hz=float("inf"))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(frames=[]), "non-empty list"),
        (dict(frames=[RawFrame()], taps=3), "'taps' must be one of 1, 2, 4"),
        (dict(frames=[RawFrame()], noise=1.0), "'noise' must be"),
        (dict(frames=[RawFrame(light_code=np.ones(8), sensor_code=2 * np.cos(np.arange(8)))]), r"frame 0 .*spans \[-\d"),
        (dict(frames=[RawFrame(light_code=np.ones(8), sensor_code=np.r_[np.ones(2), -np.ones(6)])], taps=4), "4-tap pixel needs"),
        (dict(frames=[RawFrame(modulation_frequency=80e6)], noise=SILICON), r"frame 0 .*tabulated for 1e\+07 to 5e\+07 Hz, not 8e\+07"),
    ],
)
def test_sensor_refuses_what_its_pixel_cannot_do(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Sensor(**kwargs)


def test_render_takes_cameras_or_a_sensor(cornell):
    with pytest.raises(ValueError, match="give cameras or sensor, not both"):
        dt.render(cornell, cameras=[dt.Camera()], sensor=Sensor(frames=[RawFrame()]), spp=2)


# ------------------------------------------------------------------------------ noise chain


def test_photo_electrons_follow_the_camera_equation():
    silicon = Silicon(pixel_pitch_m=10e-6, fill_factor=0.5, f_number=2.0, wavelength_m=940e-9, radiance_unit=3.0, quantum_efficiency=((850e-9, 0.51), (940e-9, 0.28)))
    assert silicon.qe == pytest.approx(0.28)
    photons = math.pi * 3.0 / (4 * 4.0) * 1e-10 * 0.5 / (6.62607015e-34 * 299792458.0 / 940e-9)
    assert silicon.electrons_per_unit_s == pytest.approx(0.28 * photons, rel=1e-12)


def _noisy_sensor(**noise):
    silicon = Silicon(**{**dict(dark_current_e_per_s=2e5, read_noise_e=7.0, gain_e_per_dn=3.0, black_level_dn=100.0, ambient_e_per_s=4e5, adc_bits=16), **noise})
    return Sensor(frames=[RawFrame(exposure=T), RawFrame(exposure=T / 2)], taps=2, noise=silicon)


def test_tap_variance_is_shot_dark_read_and_quantisation():
    sensor = _noisy_sensor()
    raw = np.empty((2, 2, 100, 100))  # 10⁴ draws of each of four taps
    raw[:, 0], raw[:, 1] = 3000.0, 800.0
    dn = sensor.read_out(raw, seed=11).astype(np.float64)
    mean_e = sensor.expected_electrons(raw)[..., 0, 0]
    for f in range(2):
        for tap in range(2):
            variance_e2 = dn[f, tap].var() * sensor.noise.gain_e_per_dn**2
            expected = sensor.noise.tap_variance_e2(mean_e[f, tap])
            assert variance_e2 == pytest.approx(expected, rel=0.03)
            standard_error_dn = math.sqrt(expected / dn[f, tap].size) / sensor.noise.gain_e_per_dn
            assert dn[f, tap].mean() == pytest.approx(mean_e[f, tap] / 3.0 + 100.0, abs=5 * standard_error_dn)
    # shot + dark + read + quantisation, spelled out for the first tap
    assert mean_e[0, 0] == pytest.approx(3000 + 0.5 * 4e5 * T + 2e5 * T)
    assert sensor.noise.tap_variance_e2(mean_e[0, 0]) == pytest.approx(mean_e[0, 0] + 49.0 + 9.0 / 12)


def test_saturation_clips_at_the_full_well_and_the_adc():
    sensor = _noisy_sensor(full_well_e=6000.0, read_noise_e=0.0, ambient_e_per_s=0.0, dark_current_e_per_s=0.0)
    raw = np.full((2, 2, 10, 10), 1e6)
    assert np.all(sensor.read_out(raw, seed=1) == round(6000 / 3 + 100))
    small_adc = _noisy_sensor(adc_bits=10, read_noise_e=0.0)
    assert np.all(small_adc.read_out(raw, seed=1) == 1023)


def test_seeds_reproduce_and_the_fixed_pattern_repeats():
    sensor = _noisy_sensor(tap_gain_mismatch=0.05, tap_offset_mismatch_e=30.0, pattern_seed=4)
    raw = np.full((2, 2, 50, 50), 2000.0)
    first = sensor.read_out(raw, seed=5)
    np.testing.assert_array_equal(first, sensor.read_out(raw, seed=5))
    second = sensor.read_out(raw, seed=6)
    assert np.any(first != second)
    # the pattern is the sensor's, not the seed's: averaged over seeds it stays
    mean = np.mean([sensor.read_out(raw, seed=s).astype(float) for s in range(20)], axis=0)
    gain, offset = sensor.noise.pattern((2, 50, 50))
    expected = (gain * (2000.0 + 0.5 * 4e5 * np.array([T, T / 2])[:, None, None, None]) + 2e5 * np.array([T, T / 2])[:, None, None, None] + offset) / 3.0 + 100.0
    assert np.corrcoef(mean.ravel(), expected.ravel())[0, 1] > 0.95


def test_readout_modes():
    sensor = _noisy_sensor()
    raw = np.random.default_rng(0).uniform(100, 5000, (2, 2, 8, 8))
    taps = sensor.read_out(raw, seed=3)
    np.testing.assert_array_equal(sensor.read_out(raw, seed=3, mode="A-B"), taps[:, 0] - taps[:, 1])
    np.testing.assert_array_equal(sensor.read_out(raw, seed=3, mode="A+B"), taps[:, 0] + taps[:, 1])
    np.testing.assert_array_equal(sensor.read_out(raw, seed=3, mode="B"), taps[:, 1])
    with pytest.raises(ValueError, match="unknown mode 'C'"):
        sensor.read_out(raw, mode="C")
    four = Sensor(frames=[RawFrame()], taps=4)
    with pytest.raises(ValueError, match="mode 'A-B' needs a 2-tap pixel"):
        four.read_out(np.zeros((1, 4, 2, 2)), mode="A-B")
    with pytest.raises(ValueError, match=r"raw must have shape \(2, 2, \.\.\.\)"):
        sensor.read_out(np.zeros((3, 2, 2, 2)))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(quantum_efficiency=1.5), r"'quantum_efficiency' must be in \(0, 1\]"),
        (dict(demodulation_contrast=((50e6, 0.5), (10e6, 0.9))), "strictly increasing"),
        (dict(wavelength_m=940e-9, quantum_efficiency=((850e-9, 0.5), (900e-9, 0.4))), r"not 9\.4e-07 m"),
        (dict(read_noise_e=-1.0), "'read_noise_e' must be >= 0"),
        (dict(adc_bits=40), r"'adc_bits' must be in \[1, 32\]"),
        (dict(black_level_dn=70000.0), r"'black_level_dn' must be in \[0, 65535\)"),
        (dict(shot_noise="yes"), "'shot_noise' must be a boolean"),
    ],
)
def test_silicon_refuses_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Silicon(**kwargs)


def test_a_fourier_demodulation_in_four_taps():
    """Four taps of a sinusoid given as Fourier coefficients: accepted (no 4th harmonic)."""
    frame = RawFrame(light_code=codes.fourier([0, 1]), sensor_code=codes.fourier([0, 1]))
    assert len(Sensor(frames=[frame], taps=4).cameras()) == 5


def test_an_interrupted_schedule_keeps_its_electrons_and_reads_out_nothing_half_done(cornell, tmp_path):
    """Stopped before the second window: its frames are NaN; the read-out refuses them by
    name, and the folder keeps the electrons (no raw_dn.npy) rather than losing the render."""
    import json

    from dopplertof import folder

    frames = [RawFrame(exposure=T, exposure_start=k * T) for k in range(2)]
    sensor = Sensor(frames=frames, noise=SILICON)
    calls = iter(range(100))
    result = dt.render(cornell, sensor=sensor, spp=4, max_depth=2, lanes_per_pass=1024, stop=lambda: next(calls) >= 1)
    assert result.interrupted
    assert np.isfinite(result.raw[0]).all() and np.isnan(result.raw[1]).all()
    with pytest.raises(ValueError, match=r"raw frames \[1\] hold no charge estimate"):
        sensor.read_out(result, seed=0)
    written = folder.write_result(result, str(tmp_path))
    names = {p.split("/")[-1] for p in written}
    assert "raw_electrons.npy" in names and "raw_dn.npy" not in names
    assert json.loads((tmp_path / "metadata.json").read_text())["sensor"]["readout_seed"] is None
    with pytest.raises(ValueError, match="must be finite"):
        SILICON.digitize(np.array([np.nan]), np.random.default_rng(0))


def test_ambient_light_splits_as_the_taps_mean_shares():
    """A 0/1 gate has s̄ = ½: tap A takes (1 + c/2)/2 of unmodulated light, B the rest."""
    gate = np.r_[np.ones(8), np.zeros(8)]
    frame = RawFrame(exposure=T, light_code=gate, sensor_code=gate)
    sensor = Sensor(frames=[frame], noise=Silicon(ambient_e_per_s=1e6, demodulation_contrast=0.8))
    ambient = sensor.expected_electrons(np.zeros((1, 2, 1, 1)))[0, :, 0, 0]
    np.testing.assert_allclose(ambient, [1e6 * T * (1 + 0.4) / 2, 1e6 * T * (1 - 0.4) / 2])
    named = Sensor(frames=[RawFrame(exposure=T)], taps=4, noise=Silicon(ambient_e_per_s=1e6))
    np.testing.assert_allclose(named.expected_electrons(np.zeros((1, 4, 1, 1)))[0, :, 0, 0], 1e6 * T / 4)


@pytest.mark.parametrize("bounds, value, message", [
    (dict(above=0), 0.0, "'x' must be > 0, got 0.0"),
    (dict(at_least=0), -1, "'x' must be >= 0, got -1.0"),
    (dict(above=0, at_most=1), 1.5, "'x' must be in (0, 1], got 1.5"),
    (dict(at_least=0, below=0.5, unit="m"), 0.5, "'x' must be in [0, 0.5) m, got 0.5"),
    (dict(at_most=3, kind="int"), 4, "'x' must be <= 3, got 4"),
    (dict(above=0), "2", "'x' must be a finite number, got '2'"),
])
def test_checked_in_range_messages(bounds, value, message):
    from dopplertof.validation import checked_in_range

    with pytest.raises(ValueError) as info:
        checked_in_range("x", value, where="Thing", **bounds)
    assert str(info.value) == f"Thing: {message}"
    assert checked_in_range("x", 0.25, at_least=0, below=0.5) == 0.25


def test_with_signal_sets_the_light_level_in_electrons():
    sensor = dt.sensors.preset("mlx75027")
    rng = np.random.default_rng(0)
    intensity = rng.uniform(0.0, 3.0, (16, 16))
    measurements = np.concatenate([0.2 * intensity[None] * rng.uniform(-1, 1, (4, 16, 16)), intensity[None]])
    scaled = sensor.with_signal(measurements, 40_000.0)
    assert np.percentile(scaled.raw(measurements)[0].astype(np.float64).sum(axis=0), 99) == pytest.approx(40_000.0, rel=1e-5)
    assert scaled.noise.radiance_unit != sensor.noise.radiance_unit
    assert dataclasses.replace(scaled.noise, radiance_unit=1.0) == sensor.noise  # nothing else changes
    assert sensor.with_signal(np.zeros_like(measurements), 1e3) == sensor  # no light: unscaled
    with pytest.raises(ValueError, match="Sensor.with_signal: 'electrons' must be > 0, got -1.0"):
        sensor.with_signal(measurements, -1.0)


def test_a_sensor_file_that_is_not_utf8_is_refused(tmp_path):
    from dopplertof.sensors.files import load_sensor, loads_sensor, sensor_toml

    path = tmp_path / "bad.toml"
    path.write_bytes(b'taps = 2\n# \xff\xfe\n')
    with pytest.raises(ValueError, match=r"bad\.toml: not valid TOML \(not UTF-8 text"):
        load_sensor(str(path))
    sensor = dt.sensors.preset("kinect-v2")
    assert loads_sensor(sensor_toml(sensor)) == sensor
    with pytest.raises(ValueError, match="^my text: not valid TOML"):
        loads_sensor("taps = [", where="my text")


@pytest.mark.parametrize("seed,message", [("x", "'seed' must be an integer, got 'x'"), (1.5, "'seed' must be an integer, got 1.5"), (-1, "'seed' must be >= 0, got -1")])
def test_read_out_names_a_bad_seed(seed, message):
    sensor = dt.Sensor(frames=[dt.RawFrame(modulation_frequency=30e6)], taps=2)
    with pytest.raises(ValueError, match=re.escape(f"Sensor.read_out: {message}")):
        sensor.read_out(np.full((1, 2, 2, 2), 100.0), seed=seed)
