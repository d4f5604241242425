"""Estimators over raw frames: read-out to measurements, two-offset velocity, multi-frequency depth."""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import oracles
from dopplertof import reconstruct as rc
from dopplertof.sensors import RawFrame, Sensor, Silicon
from dopplertof.sensors import estimators as est

T = 1.5e-3
# Hu et al.'s offsets and phases: h = +½ at 270°, 0°; h = −½ at 90°, 180°
HU_FRAMES = [RawFrame(modulation_frequency=30e6, exposure=T, heterodyne=h, phase=p) for h, p in ((0.5, 1.5 * math.pi), (0.5, 0.0), (-0.5, math.pi / 2), (-0.5, math.pi))]


def _cos_axis(n):
    """cos of the angle between each pixel centre's ray and the optical axis (n × n film)."""
    tau = math.tan(math.radians(oracles.PLANE_FOV_DEG) / 2)
    centres = (np.arange(n) + 0.5) / n
    fx, fy = np.meshgrid(centres, centres, indexing="ij")
    return 1 / np.sqrt(((2 * fx - 1) * tau) ** 2 + ((2 * fy - 1) * tau) ** 2 + 1)


def _radial(n, speed):
    """The plane's velocity along each pixel centre's ray: it recedes at v / cos there."""
    return speed / _cos_axis(n)


@pytest.mark.parametrize("offsets", [(0.5, -0.5), (1.0, 0.0), (1.5, -0.5), (1.0, -1.0)])
def test_two_offset_velocity_inverts_the_model_exactly(offsets):
    frames = [RawFrame(modulation_frequency=30e6, exposure=T, heterodyne=h, phase=p) for h in offsets for p in (0.0, math.pi / 2, math.pi, 1.5 * math.pi)]
    velocity = np.array([-300.0, -3.0, 0.7, 25.0, 900.0])
    m = rc.model_measurements(np.full(5, 2.0), np.linspace(0.3, 4.6, 5), velocity, frames)
    # whole offsets: the heterodyne signal ∝ a, below the default threshold at 0.7 m/s
    result = est.two_offset_velocity(m, frames, min_amplitude=0.0)
    np.testing.assert_allclose(result.velocity, velocity, rtol=1e-8)
    assert result.valid.all()


def test_two_offset_velocity_recovers_the_moving_plane_within_its_stated_error():
    """The exact moving-plane measurement (oracles): the only model error is the plane's
    1/s² brightening, a relative bias ≈ 2|Δs|/(π k s²) (estimators module docstring), plus
    the spread of rates within a pixel."""
    n = 16
    k = HU_FRAMES[0].wavenumber
    for speed in (10.0, -40.0):
        m = np.array([oracles.moving_plane_measurement_pixels(f, speed, n) for f in HU_FRAMES])
        result = est.two_offset_velocity(m, HU_FRAMES)
        radial = _radial(n, speed)
        distance = oracles.PLANE_DISTANCE_M / _cos_axis(n)
        stated = 2 * np.abs(radial) * T / (math.pi * k * distance**2)
        assert np.all(np.abs(result.velocity / radial - 1) <= 1.5 * stated)


def test_two_offset_velocity_error_matches_monte_carlo():
    velocity = np.array([5.0, 40.0, -200.0])
    m = rc.model_measurements(np.ones(3), np.array([1.0, 2.0, 3.0]), velocity, HU_FRAMES)
    sigma = np.full_like(m, 2e-3)
    predicted = est.two_offset_velocity(m, HU_FRAMES, measurement_stderr=sigma).velocity_stderr
    rng = np.random.default_rng(1)
    draws = np.array([est.two_offset_velocity(m + rng.normal(0, 2e-3, m.shape), HU_FRAMES).velocity for _ in range(4000)])
    np.testing.assert_allclose(draws.std(axis=0), predicted, rtol=0.06)


@pytest.mark.parametrize(
    "frames,match",
    [
        ([RawFrame(heterodyne=h) for h in (0.5, 0.25)], "differ by whole beat cycles"),
        ([RawFrame(heterodyne=h, phase=p) for h in (0.5, -0.5) for p in (0.0, 0.1)], "do not give a quadrature"),
        ([RawFrame(heterodyne=h, phase=p, waveform="rectangular") for h in (0.5, -0.5) for p in (0.0, math.pi / 2)], "sinusoid"),
        ([RawFrame(heterodyne=h, phase=p, exposure_start=p) for h in (0.5, -0.5) for p in (0.0, 1e-3)], "one exposure window"),
    ],
)
def test_two_offset_velocity_refuses_unsuitable_frames(frames, match):
    with pytest.raises(ValueError, match=match):
        est.two_offset_velocity(np.zeros((len(frames), 2)), frames)


def _depth_frames(frequencies, exposure=1e-3):
    return [RawFrame(modulation_frequency=f, exposure=exposure, phase=p * math.pi / 2) for f in frequencies for p in range(4)]


def _model(frames, depth_m):
    """Each frequency's exact measurements (reconstruct's model takes one frequency at a time)."""
    out = []
    for f in dict.fromkeys(fr.modulation_frequency for fr in frames):
        group = [fr for fr in frames if fr.modulation_frequency == f]
        out.append(rc.model_measurements(np.ones_like(depth_m), depth_m, np.zeros_like(depth_m), group))
    return np.concatenate(out)


def test_multifrequency_depth_unwraps_beyond_each_frequencys_range():
    frames = _depth_frames((50e6, 10e6, 40e6))  # ranges 3.0, 15.0, 3.75 m; together 15 m
    depth = np.array([0.4, 3.1, 7.7, 12.3, 14.8])
    result = est.multifrequency_depth(_model(frames, depth), frames)
    np.testing.assert_allclose(result.depth, depth, atol=1e-9)
    assert result.frequencies_hz == (50e6, 10e6, 40e6)
    np.testing.assert_allclose(result.per_frequency[0], np.mod(depth, rc.ambiguity_range_m(50e6)), atol=1e-9)


def test_multifrequency_depth_of_the_kinect_schedule():
    sensor = dt.sensors.preset("kinect-v2")
    depth = np.array([0.5, 2.0, 5.5, 9.0])
    result = est.multifrequency_depth(_model(sensor.frames, depth), sensor.frames, max_depth_m=12.0)
    np.testing.assert_allclose(result.depth, depth, atol=1e-9)


def test_multifrequency_depth_error_matches_monte_carlo():
    frames = _depth_frames((50e6, 10e6))
    depth = np.array([1.0, 6.0, 11.0])
    m = _model(frames, depth)
    sigma = np.full_like(m, 1e-3)
    predicted = est.multifrequency_depth(m, frames, measurement_stderr=sigma).depth_stderr
    rng = np.random.default_rng(2)
    draws = np.array([est.multifrequency_depth(m + rng.normal(0, 1e-3, m.shape), frames, measurement_stderr=sigma).depth for _ in range(3000)])
    np.testing.assert_allclose(draws.std(axis=0), predicted, rtol=0.06)


def test_multifrequency_depth_refuses_heterodyne_frames_and_huge_searches():
    with pytest.raises(ValueError, match="homodyne frames"):
        est.multifrequency_depth(np.zeros((2, 1)), [RawFrame(heterodyne=1.0, phase=p) for p in (0, math.pi / 2)])
    frames = _depth_frames((50e6 + 1, 50e6))
    with pytest.raises(ValueError, match="give max_depth_m"):
        est.multifrequency_depth(np.zeros((8, 1)), frames)


def test_measurements_from_a_readout():
    """Noiseless silicon with a fine ADC: the read-out gives the rendered measurements back;
    with noise, the stated standard error is the spread over seeds."""
    frames = [RawFrame(modulation_frequency=30e6, exposure=1e-3, phase=p * math.pi / 2) for p in range(2)]
    raw_mean = np.array([[[[6000.0, 9000.0]], [[4000.0, 1000.0]]], [[[5000.0, 5000.0]], [[5000.0, 5000.0]]]])  # (2 frames, 2 taps, 1, 2)
    ideal = Sensor(frames=frames, noise=Silicon(shot_noise=False, gain_e_per_dn=1e-3, adc_bits=32, demodulation_contrast=0.8))
    got = est.measurements_from_readout(ideal, ideal.read_out(raw_mean, seed=0))
    kappa_t = ideal.noise.electrons_per_unit_s * 1e-3
    np.testing.assert_allclose(got.measurements, (raw_mean[:, 0] - raw_mean[:, 1]) / (0.8 * kappa_t), rtol=1e-6)
    assert got.cameras == frames

    noisy = Sensor(frames=frames, noise=Silicon(read_noise_e=20.0, gain_e_per_dn=2.0, black_level_dn=50.0, adc_bits=16, demodulation_contrast=0.8))
    draws = np.array([est.measurements_from_readout(noisy, noisy.read_out(raw_mean, seed=s)).measurements for s in range(3000)])
    stated = est.measurements_from_readout(noisy, noisy.read_out(raw_mean, seed=0)).stderr
    np.testing.assert_allclose(draws.std(axis=0), stated, rtol=0.06)
    np.testing.assert_allclose(draws.mean(axis=0), (raw_mean[:, 0] - raw_mean[:, 1]) / (0.8 * kappa_t), atol=4 * stated.max() / math.sqrt(3000))


def test_measurements_from_four_taps_and_saturation():
    frames = [RawFrame(modulation_frequency=30e6, exposure=1e-3)]
    sensor = Sensor(frames=frames, taps=4, noise=Silicon(shot_noise=False, gain_e_per_dn=1e-3, adc_bits=32, full_well_e=1e4))
    raw = np.array([[[[3000.0, 2e4]], [[2500.0, 0.0]], [[1000.0, 0.0]], [[1500.0, 0.0]]]])
    got = est.measurements_from_readout(sensor, sensor.read_out(raw, seed=0))
    kappa_t = sensor.noise.electrons_per_unit_s * 1e-3
    assert got.measurements[0, 0, 0] == pytest.approx(2 * 2000.0 / kappa_t, rel=1e-6)
    assert got.measurements[1, 0, 0] == pytest.approx(2 * 1000.0 / kappa_t, rel=1e-6)
    assert got.cameras[1].phase == pytest.approx(math.pi / 2)
    # tap 0 at the full well: the 0°/180° difference is lost, the 90°/270° one is not
    assert np.isnan(got.measurements[0, 0, 1]) and got.measurements[1, 0, 1] == 0.0
    with pytest.raises(ValueError, match="1-tap pixel"):
        est.measurements_from_readout(Sensor(frames=frames, taps=1), np.zeros((1, 1, 1, 1)))


def test_reconstruct_velocity_takes_raw_frames_of_a_read_out():
    """The per-pixel fit of dopplertof.reconstruct over the D-ToF prototype's default
    frames, read out with noise: z-scores of unit spread against the plane's velocity."""
    n, speed = 16, 20.0
    sensor = dt.sensors.preset("dtof-prototype")
    result = dt.render(oracles.moving_plane_scene(speed, resolution=n), sensor=sensor, spp=64, max_depth=2, seed=3)
    read = est.measurements_from_readout(sensor, sensor.read_out(result, seed=1))
    stderr = np.sqrt(read.stderr**2 + result.measurement_stderr[: len(sensor.frames)].astype(np.float64) ** 2)
    # each pixel's error (~40 m/s) exceeds the 20 m/s motion: no default threshold accepts it,
    # so every determined pixel is taken (the z-scores are the point)
    estimate = rc.velocity(read.measurements, read.cameras, measurement_stderr=stderr, max_velocity_stderr=1e3)
    assert estimate.method == "fit" and estimate.valid.mean() > 0.95
    z = ((estimate.velocity - _radial(n, speed)) / estimate.velocity_stderr)[estimate.valid]
    assert np.all(np.abs(z) < 4) and abs(z.mean()) < 0.3 and 0.7 < z.std() < 1.3


def test_two_offset_velocity_end_to_end_through_a_noisy_sensor():
    """Render the moving plane with the D-ToF prototype on Hu's schedule, read it out with
    noise, estimate: each pixel within 4 of its stated standard errors (sensor noise and
    the render's Monte Carlo error, taken as independent), and no bias beyond half of one."""
    n, speed = 16, 20.0
    sensor = dt.sensors.preset("dtof-prototype", frames=HU_FRAMES)
    result = dt.render(oracles.moving_plane_scene(speed, resolution=n), sensor=sensor, spp=64, max_depth=2, seed=3)
    read = est.measurements_from_readout(sensor, sensor.read_out(result, seed=1))
    stderr = np.sqrt(read.stderr**2 + result.measurement_stderr[: len(HU_FRAMES)].astype(np.float64) ** 2)
    estimate = est.two_offset_velocity(read.measurements, read.cameras, measurement_stderr=stderr)
    assert estimate.valid.mean() > 0.95
    z = ((estimate.velocity - _radial(n, speed)) / estimate.velocity_stderr)[estimate.valid]
    assert np.all(np.abs(z) < 4)
    assert abs(z.mean()) < 0.5


def test_four_tap_measurements_need_an_antiperiodic_demodulation():
    skewed = np.r_[np.ones(4), -np.ones(4), np.ones(4), -np.ones(4)]  # no mean, but s(θ + π) = s(θ)
    sensor = Sensor(frames=[RawFrame(light_code=np.ones(16), sensor_code=skewed)], taps=4)
    with pytest.raises(ValueError, match=r"frames \[0\] demodulate with a code that is not antiperiodic"):
        est.measurements_from_readout(sensor, np.zeros((1, 4, 1, 1), np.int64))


# ------------------------------------------------------------------ two captures (homodyne chips)


def _captures(phases_deg, waveform="sinusoidal", sequential=True, f=100e6, exposure=1e-3):
    """Two captures of ``phases_deg``, frame after frame (or each capture in one window)."""
    n = len(phases_deg)
    return [RawFrame(modulation_frequency=f, exposure=exposure, phase=math.radians(p), waveform=waveform,
                     exposure_start=(c * n + (j if sequential else 0)) * exposure)
            for c in range(2) for j, p in enumerate(phases_deg)]  # fmt: skip


@pytest.mark.parametrize("phases, sequential", [((0, 90, 180, 270), True), ((0, 120, 240), True), ((0, 90, 180, 270), False)])
def test_two_capture_velocity_inverts_the_sinusoid_model_exactly(phases, sequential):
    frames = _captures(phases, sequential=sequential)
    velocity = np.array([-120.0, -3.0, 0.0, 0.7, 25.0, 80.0])
    m = rc.model_measurements(np.full(6, 2.0), np.linspace(0.3, 9.6, 6), velocity, frames)
    result = est.two_capture_velocity(m, frames)
    np.testing.assert_allclose(result.velocity, velocity, rtol=1e-6, atol=1e-6)
    assert result.interval_s == pytest.approx(len(phases) * 1e-3) and result.valid.all()


@pytest.mark.parametrize("waveform", ["rectangular", "triangular"])
def test_two_capture_velocity_calibrates_a_non_sinusoidal_correlation(waveform):
    """A square wave's triangle correlation bends the 4-phase phase by up to ±36 % in slope
    (the wiggling); the estimator inverts the frames' own correlation."""
    from dopplertof.modulation import lowpass_weight

    frames = _captures((0, 90, 180, 270), waveform=waveform)
    velocity, distance = np.linspace(-60.0, 60.0, 9), np.linspace(0.4, 7.9, 9)
    k = 2 * math.pi * 100e6 / 299_792_458.0
    m = np.array([1.7 * lowpass_weight(fr, fr.phase + 2 * k * (distance + velocity * (fr.exposure_start + fr.exposure / 2))) for fr in frames])
    np.testing.assert_allclose(est.two_capture_velocity(m, frames).velocity, velocity, atol=1e-5)
    naive = est.two_capture_velocity(m, _captures((0, 90, 180, 270)))  # read as if sinusoidal: the wiggling error
    assert np.nanmax(np.abs(naive.velocity - velocity)) > 1.0


def test_two_capture_velocity_stderr_matches_monte_carlo():
    frames = _captures((0, 90, 180, 270))
    n = 20_000
    clean = rc.model_measurements(np.full(n, 1.0), np.full(n, 2.3), np.full(n, 12.0), frames)
    sigma = np.full_like(clean, 0.01)
    noisy = clean + sigma * np.random.default_rng(3).standard_normal(clean.shape)
    result = est.two_capture_velocity(noisy, frames, measurement_stderr=sigma)
    assert np.nanstd(result.velocity) == pytest.approx(np.nanmean(result.velocity_stderr), rel=0.05)
    assert abs(np.nanmean(result.velocity) - 12.0) < 5 * np.nanstd(result.velocity) / math.sqrt(n)


@pytest.mark.parametrize("frames, match", [
    (_captures((0, 90, 180, 270))[:7], "two captures of the same phases"),
    (_captures((0, 90, 180, 270))[:4] + _captures((90, 0, 180, 270))[4:], "two captures of the same phases"),
    ([RawFrame(modulation_frequency=100e6, exposure=1e-3, heterodyne=1.0, phase=p, exposure_start=s) for s in (0.0, 4e-3) for p in (0.0, math.pi / 2)], "needs homodyne frames"),
])
def test_two_capture_velocity_refuses_other_sets(frames, match):
    with pytest.raises(ValueError, match=match):
        est.two_capture_velocity(np.ones((len(frames), 3)), frames)


@pytest.mark.parametrize("waveform, phases", [("rectangular", (0, 90, 180, 270)), ("sinusoidal", (0, 120, 240))])
def test_two_capture_velocity_recovers_the_moving_plane(waveform, phases):
    """The exact moving-plane measurement (oracles), frame after frame: the only model error
    is the plane's 1/s² brightening during a capture (an amplitude ramp of 2vD/s over its
    D = 3–4 ms, which tilts each capture's phase alike to first order): within 2 %."""
    n = 16
    frames = _captures(phases, waveform=waveform)
    for speed in (10.0, -40.0):
        m = np.array([oracles.moving_plane_measurement_pixels(f, speed, n) for f in frames])
        result = est.two_capture_velocity(m, frames)
        assert np.all(np.abs(result.velocity / _radial(n, speed) - 1) < 0.02)


def test_two_capture_velocity_end_to_end_through_a_noisy_sensor():
    """Render the moving plane with the MLX75027 (two captures of 4 square-wave phases, frame
    after frame), read it out with noise, estimate: each pixel within 4 of its stated standard
    errors (sensor noise and the render's Monte Carlo error: every frame is its own window,
    so independent), and no bias beyond half of one."""
    n, speed = 16, 20.0
    frames = _captures((0, 90, 180, 270), waveform="rectangular", exposure=999e-6)
    sensor = dt.sensors.preset("mlx75027", frames=frames)
    scene = oracles.moving_plane_scene(speed, resolution=n, duration=8e-3)  # moving through every frame's window
    result = dt.render(scene, sensor=sensor, spp=64, max_depth=2, seed=3)
    sensor = sensor.with_signal(result.measurements, 0.5 * sensor.noise.full_well_e)
    read = est.measurements_from_readout(sensor, sensor.read_out(sensor.raw(result.measurements), seed=1))
    stderr = np.sqrt(read.stderr**2 + result.measurement_stderr[: len(frames)].astype(np.float64) ** 2)
    estimate = est.two_capture_velocity(read.measurements, read.cameras, measurement_stderr=stderr)
    assert estimate.valid.mean() > 0.95
    z = ((estimate.velocity - _radial(n, speed)) / estimate.velocity_stderr)[estimate.valid]
    assert np.all(np.abs(z) < 4)
    assert abs(z.mean()) < 0.5
