"""Sensor design: the response record (render once, read out any sensor in its band)."""

import dataclasses
import math
import re

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import codes
from dopplertof.design import RecordSpec, evaluate
from dopplertof.sensors import RawFrame, Sensor, Silicon

T = 1e-3
LATE_START_S, LATE_T = 0.4e-3, 0.8e-3  # a second exposure window (a capture schedule)
SILICON = Silicon(radiance_unit=1e-3, demodulation_contrast=((10e6, 0.9), (150e6, 0.7)))
SPEC = RecordSpec(band_hz=(10e6, 120e6), step_hz=10e6, beats=(0.0, 1.0, 2.0, 3.0, 0.5, -1.0), cameras_per_render=128, doppler=True)
RENDER = dict(spp=8, max_depth=3, seed=11)


@pytest.fixture(scope="module")
def cornell():
    return dt.scenes.cornell_box(resolution=12, exposure=T)


@pytest.fixture(scope="module")
def recorded(cornell):
    """A record of the two windows, in the order every random sensor below uses them."""
    cameras = [dt.Camera(exposure=T, exposure_start=0.0), dt.Camera(exposure=LATE_T, exposure_start=LATE_START_S)]
    return dt.render(cornell, cameras=cameras, record=SPEC, **RENDER)


def _random_frame(rng, window):
    start, exposure = window
    kind = rng.choice(["sinusoid", "fourier", "chips"])
    psi = float(rng.uniform(-math.pi, math.pi))
    if kind == "sinusoid":
        return RawFrame(
            modulation_frequency=10e6 * int(rng.integers(1, 13)), heterodyne=float(rng.choice([0.0, 1.0, 2.0, 3.0, 0.5, -1.0])),
            phase=psi, exposure=exposure, exposure_start=start, g1=float(rng.uniform(0.2, 1.0)), g0=0.5,
        )  # fmt: skip
    if kind == "fourier":  # a band-limited code pair of order 2 or 3 (harmonics m f, beats m h)
        order = int(rng.integers(2, 4))
        light = [0.5] + list(0.5 * rng.uniform(0.2, 1.0, order) * np.exp(1j * rng.uniform(0, 2 * math.pi, order)) / order)
        sensor = [0.0] + list(0.9 * rng.uniform(0.2, 1.0, order) * np.exp(1j * rng.uniform(0, 2 * math.pi, order)) / order)
        f = 10e6 * int(rng.integers(1, 120 // (10 * order) + 1))
        return RawFrame(
            modulation_frequency=f, heterodyne=float(rng.choice([0.0, 1.0])), phase=psi, exposure=exposure, exposure_start=start,
            light_code=codes.fourier(light), sensor_code=codes.fourier(sensor), g1=1.0, g0=0.2,
        )  # fmt: skip
    # binary chips through a source of finite bandwidth: its correlation has 3 harmonics
    chips = rng.integers(0, 2, 8).astype(float)
    chips[:2] = (0.0, 1.0)  # not constant
    f = 10e6 * int(rng.integers(1, 5))
    return RawFrame(
        modulation_frequency=f, heterodyne=1.0, phase=psi, exposure=exposure, exposure_start=start,
        light_code=chips, sensor_code=2 * chips[::-1] - 1, light_bandwidth=3 * f, g1=1.0, g0=0.0,
    )  # fmt: skip


def _random_sensor(rng):
    windows = [(0.0, T), (LATE_START_S, LATE_T)]
    n = int(rng.integers(1, 4))
    # the first frame opens the first window: the windows keep the record's order, hence its seeds
    frames = [_random_frame(rng, windows[0])] + [_random_frame(rng, windows[int(rng.integers(0, 2))]) for _ in range(n - 1)]
    chips = any(f.coded and f.sensor_code.samples is not None for f in frames)  # a mean: no 4-tap layout
    return Sensor(frames=frames, taps=int(rng.choice([1, 2] if chips else [1, 2, 4])), noise=SILICON)


def test_a_record_reads_out_twenty_random_sensors_as_their_direct_renders(cornell, recorded):
    record = recorded.record
    rng = np.random.default_rng(2026)
    kinds = set()
    # the declared non-integer and negative beats, then random sensors
    fixed = Sensor(frames=[RawFrame(modulation_frequency=50e6, heterodyne=h, phase=0.4, exposure=T, exposure_start=0.0) for h in (0.5, -1.0)], noise=SILICON)
    for index in range(21):
        sensor = fixed if index == 0 else _random_sensor(rng)
        kinds |= {("code" if f.coded else "sin", f.heterodyne % 1 != 0) for f in sensor.frames} | {f.exposure_start for f in sensor.frames} | {sensor.taps}
        direct = dt.render(cornell, sensor=sensor, **RENDER)
        read = evaluate(record, sensor)
        scale = np.abs(direct.measurements).max()
        assert scale > 0
        np.testing.assert_allclose(read.measurements, direct.measurements, rtol=0, atol=1e-4 * scale, err_msg=f"sensor {index}: {sensor}")
        np.testing.assert_allclose(read.raw, direct.raw, rtol=0, atol=1e-4 * np.abs(direct.raw).max(), err_msg=f"sensor {index}")
        # the signal is not the mean light alone: the modulated part is seen
        assert np.abs(direct.measurements[: sensor.frame_cameras]).max() > 1e-3 * scale
    # codes, non-integer heterodyne, both windows and every tap layout were tried
    assert {("code", False), ("sin", True), ("sin", False), 0.0, LATE_START_S, 1, 2, 4} <= kinds


def test_the_record_keeps_the_truth_and_states_its_size(recorded):
    record = recorded.record
    assert record.phasors.shape == record.moments.shape == (2, 12, 6, 12, 12) and record.phasors.dtype == np.complex64
    assert record.nbytes == 12 * 12 * SPEC.bytes_per_pixel(n_windows=2)
    np.testing.assert_array_equal(record.maps["depth"], recorded.depth)
    np.testing.assert_array_equal(record.maps["velocity"], recorded.velocity)
    # 256² of 10–300 MHz at 1 MHz, beats 0 and 1: within the 2 GB
    assert 256 * 256 * RecordSpec(band_hz=(10e6, 300e6), step_hz=1e6).bytes_per_pixel() < 2 * 2**30


def test_recording_leaves_the_render_itself_unchanged(cornell, recorded):
    cameras = [dt.Camera(exposure=T, exposure_start=0.0), dt.Camera(exposure=LATE_T, exposure_start=LATE_START_S)]
    plain = dt.render(cornell, cameras=cameras, **RENDER)
    for name in ("intensity", "measurements", "measurement_stderr", "depth", "velocity"):
        np.testing.assert_array_equal(recorded.maps[name], plain.maps[name], err_msg=name)


def test_a_record_written_and_read_gives_the_same_readout(recorded, tmp_path):
    path = dt.io.write_record(tmp_path / "scene.record.npz", recorded.record)
    back = dt.io.read_record(path)
    assert back.windows == recorded.record.windows and back.spec == recorded.record.spec and back.spp == recorded.record.spp
    sensor = Sensor(frames=[RawFrame(modulation_frequency=40e6, heterodyne=1.0, phase=0.3, exposure=T, exposure_start=0.0)], noise=SILICON)
    np.testing.assert_array_equal(evaluate(back, sensor).raw, evaluate(recorded.record, sensor).raw)
    (tmp_path / "other.npz").write_bytes(b"not a record")
    with pytest.raises(ValueError, match="other.npz"):
        dt.io.read_record(tmp_path / "other.npz")
    np.savez(tmp_path / "arrays.npz", phasors=np.zeros(3))
    with pytest.raises(ValueError, match="not a dopplertof response record"):
        dt.io.read_record(tmp_path / "arrays.npz")
    with pytest.raises(TypeError, match="write_record: 'record' must be a dopplertof.design.Record .*got RenderResult"):
        dt.io.write_record(tmp_path / "result.npz", recorded)  # the result, not its .record
    assert not (tmp_path / "result.npz").exists()


def test_a_record_band_below_100_khz_is_honoured_with_a_warning():
    from dopplertof.design import RecordSpec

    with pytest.warns(UserWarning, match=r"record: band_hz=\(10.0, 100.0\) Hz is below 100 kHz; the unit is Hz \(10 MHz is 10e6\)"):
        spec = RecordSpec(band_hz=(10, 100), step_hz=10)
    assert spec.band_hz == (10.0, 100.0)


@pytest.mark.parametrize(
    "camera, message",
    [
        (dt.Camera(modulation_frequency=35e6, exposure=T, exposure_start=0.0), "frequency 35000000 Hz"),
        (dt.Camera(modulation_frequency=130e6, exposure=T, exposure_start=0.0), r"frequency 130000000 Hz.*\[1e\+07, 1.2e\+08\]"),
        (dt.Camera(modulation_frequency=30e6, heterodyne=0.25, exposure=T, exposure_start=0.0), "beat 0.25"),
        (dt.Camera(modulation_frequency=30e6, exposure=T, exposure_start=0.2e-3), "window"),
        (dt.Camera(modulation_frequency=30e6, exposure=T, waveform="rectangular", exposure_start=0.0), "rectangular waveform has unbounded"),
        (dt.Camera(modulation_frequency=30e6, exposure=T, low_pass=False, exposure_start=0.0), "full-waveform"),
        (dt.Camera(modulation_frequency=30e6, exposure=T, light_code=[0, 1] * 4, sensor_code=[1, -1] * 4, exposure_start=0.0), "light_bandwidth"),
        # harmonics 1..4 of 40 MHz: 160 MHz is beyond the band
        (dt.Camera(modulation_frequency=40e6, exposure=T, light_code=[0, 1] * 4, sensor_code=[1, -1] * 4, light_bandwidth=160e6, exposure_start=0.0), "frequency 1.2e\\+08 Hz|frequency 160000000 Hz"),
    ],
)
def test_a_record_refuses_what_it_cannot_give(recorded, camera, message):
    with pytest.raises(ValueError, match=message) as info:
        evaluate(recorded.record, [camera])
    assert "camera 0" in str(info.value)


@pytest.mark.parametrize(
    "spec, message",
    [
        (dict(band_hz=(100e6, 10e6)), "band_hz"),
        (dict(band_hz=(11e6, 19e6)), "no multiple"),
        (dict(step_hz=0.0), "step_hz"),
        (dict(band_hz=(1.0, 1e9), step_hz=1e-3), "4096"),  # 10¹² frequencies: counted, never made (7 TiB)
        (dict(beats=(0, 0)), "twice"),
        (dict(beats="01"), "beats"),
        (dict(bandwidth=1), "unknown key"),
        ("yes", "record must be True"),
    ],
)
def test_a_record_spec_refuses_bad_values(cornell, spec, message):
    with pytest.raises(ValueError, match=message):
        dt.render(cornell, spp=2, record=spec)


def test_a_stopped_record_continues_from_its_checkpoint_to_the_same_record(cornell, tmp_path):
    """A record's render kept no checkpoint: a stop lost every pass. Its sums are now in the
    render's checkpoint, and the record finished from it is the uninterrupted one, bit for
    bit, also where a further run of frequencies traces the passes again."""
    spec = RecordSpec(band_hz=(10e6, 400e6), step_hz=10e6, beats=(0.0, 1.0))  # 40 frequencies: two kernels
    common = dict(cameras=[dt.Camera(exposure=T)], record=spec, spp=32, max_depth=3, seed=6, lanes_per_pass=1024)
    whole = dt.render(cornell, **common).record
    checkpoint, calls = tmp_path / "c.npz", []
    stopped = dt.render(cornell, **common, checkpoint=checkpoint, stop=lambda: calls.append(1) or len(calls) > 2)
    assert stopped.interrupted and stopped.record is None and checkpoint.exists()
    resumed = dt.render(cornell, **common, checkpoint=checkpoint).record
    assert not checkpoint.exists()
    for name in ("phasors", "luminance"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(whole, name), err_msg=name)
    with pytest.raises(ValueError, match="rendered locally"):
        dt.render(cornell, spp=2, record=True, executor="ray")
    with pytest.raises(ValueError, match="probe cameras, without a checkpoint"):
        dt.render(cornell, spp=2, record=True, correlation="reconnection", checkpoint=tmp_path / "p.npz")


def test_square_waves_through_a_finite_bandwidth_read_out_as_their_direct_renders(cornell):
    """The MLX75027 drives square waves: with the source's bandwidth (harmonics 1 and 3 at
    30 MHz, within the record's band) its preset accepts them and the record reads them out."""
    from dopplertof.sensors import preset

    exposure = 0.5e-3  # the chip integrates less than 1 ms per raw frame
    record = dt.render(cornell, cameras=[dt.Camera(exposure=exposure, exposure_start=0.0)], record=dict(band_hz=(10e6, 120e6), beats=(0.0,)), **RENDER).record
    frames = [RawFrame(modulation_frequency=30e6, phase=k * math.pi / 2, exposure=exposure, exposure_start=0.0, waveform="rectangular", light_bandwidth=100e6) for k in range(4)]
    sensor = preset("mlx75027", frames, radiance_unit=1e-3)
    direct = dt.render(cornell, sensor=sensor, **RENDER)
    np.testing.assert_allclose(evaluate(record, sensor).raw, direct.raw, rtol=0, atol=1e-4 * np.abs(direct.raw).max())
    with pytest.raises(ValueError, match="rectangular waveform has unbounded harmonics; give it the source's light_bandwidth"):
        evaluate(record, preset("mlx75027", [dataclasses.replace(f, light_bandwidth=None, light_code=None, sensor_code=None) for f in frames]))


def test_a_record_wider_than_one_kernel_traces_the_same_paths_for_every_run_of_frequencies(cornell):
    from dopplertof.design.record import FREQUENCIES_PER_KERNEL

    spec = RecordSpec(band_hz=(10e6, 400e6), step_hz=10e6, beats=(0.0, 1.0), doppler=True, slopes=True)
    assert spec.frequencies_hz.size > FREQUENCIES_PER_KERNEL
    record = dt.render(cornell, cameras=[dt.Camera(exposure=T)], record=spec, spp=4, max_depth=3, seed=5).record
    assert record.info["kernels"] == 2 and record.slopes.shape == record.moment_slopes.shape == record.phasors.shape
    # the first run of frequencies and the last (its own kernel) against direct renders
    cameras = [dt.Camera(modulation_frequency=f, heterodyne=h, phase=0.3, exposure=T, exposure_start=0.0) for f, h in ((20e6, 0.0), (390e6, 1.0))]
    direct = dt.render(cornell, cameras=cameras, spp=4, max_depth=3, seed=5)
    np.testing.assert_allclose(evaluate(record, cameras).measurements, direct.measurements, rtol=0, atol=1e-4 * np.abs(direct.measurements).max())
    # the slopes are the exact derivative: against a central difference of two records' phasors
    delta = 1e5
    ends = [dt.render(cornell, cameras=[dt.Camera(exposure=T)], record=dict(band_hz=(390e6 + d, 390e6 + d), step_hz=390e6 + d, beats=(0.0,)), spp=4, max_depth=3, seed=5).record.phasors[0, 0, 0] for d in (delta, -delta)]
    difference = (ends[0].astype(np.complex128) - ends[1]) / (2 * delta)
    np.testing.assert_allclose(record.slopes[0, record.frequency_index(390e6, "test"), 0], difference, rtol=0, atol=1e-3 * np.abs(difference).max())


def test_a_record_does_not_depend_on_how_the_film_and_spp_are_split_into_passes():
    scene = dt.scenes.cornell_box(resolution=40, exposure=T)
    spec = RecordSpec(band_hz=(10e6, 60e6), step_hz=10e6, beats=(0.0, 1.0), doppler=True)
    whole = dt.render(scene, cameras=[dt.Camera(exposure=T)], record=spec, spp=8, max_depth=3, seed=4).record
    # 1024 lanes per pass: tiles of 512 pixels and 2 samples, 16 passes
    split = dt.render(scene, cameras=[dt.Camera(exposure=T)], record=spec, spp=8, max_depth=3, seed=4, lanes_per_pass=1024).record
    for name in ("phasors", "moments", "luminance"):
        a, b = getattr(whole, name), getattr(split, name)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-6 * np.abs(a).max(), err_msg=name)


def test_a_paired_tracer_records_through_probe_cameras(cornell):
    spec = RecordSpec(band_hz=(10e6, 60e6), step_hz=10e6, beats=(0.0, 1.0))
    render = dict(spp=4, max_depth=3, seed=3, correlation="reconnection")
    record = dt.render(cornell, cameras=[dt.Camera(exposure=T)], record=spec, **render).record
    assert "probe_cameras" in record.info
    sensor = Sensor(frames=[RawFrame(modulation_frequency=40e6, heterodyne=h, phase=0.7, exposure=T) for h in (0.0, 1.0)], noise=SILICON)
    direct = dt.render(cornell, sensor=sensor, **render)
    np.testing.assert_allclose(evaluate(record, sensor).raw, direct.raw, rtol=0, atol=1e-4 * np.abs(direct.raw).max())


def test_evaluate_refuses_what_is_not_a_record_or_a_sensor(recorded):
    with pytest.raises(ValueError, match="'record' must be"):
        evaluate(recorded, [dt.Camera()])
    with pytest.raises(ValueError, match="'sensor' must be"):
        evaluate(recorded.record, "mlx75027")


# ----------------------------------------------------------------------------------------
# Precision maps: the Cramér–Rao bound on the moving plane

PLANE_SPEED_M_S, PLANE_RES, PLANE_F = 10.0, 8, 30e6
PLANE_SILICON = Silicon(radiance_unit=1.6, read_noise_e=20.0, full_well_e=1e6, adc_bits=20)


def _plane_sensor(frames=((0.0, 0.0), (0.0, math.pi / 2), (1.0, 0.0), (1.0, math.pi / 2))):
    from dopplertof.oracles import PLANE_EXPOSURE_S

    return Sensor(frames=[RawFrame(modulation_frequency=PLANE_F, heterodyne=h, phase=p, exposure=PLANE_EXPOSURE_S) for h, p in frames], noise=PLANE_SILICON)


@pytest.fixture(scope="module")
def plane_record():
    from dopplertof import oracles

    scene = oracles.moving_plane_scene(PLANE_SPEED_M_S, resolution=PLANE_RES)
    spec = dict(band_hz=(PLANE_F, PLANE_F), step_hz=PLANE_F, beats=(0.0, 1.0), doppler=True)
    return dt.render(scene, spp=512, max_depth=2, seed=1, record=spec).record


def _single_path_fisher(sensor, amplitude):
    """The closed form (reference §2.6, estimators' model): one path per pixel of length
    L(t) = L0 + L̇ t, m(h, ψ) = (g1/2) Re{A e^{ikL0} e^{iψ} F(2πh + kL̇T)},
    F(x) = (e^{ix} − 1)/(ix), differentiated by hand; the Fisher information through the
    sensor's taps."""
    from dopplertof import oracles
    from dopplertof.design.precision import fisher_information

    tau = math.tan(math.radians(oracles.PLANE_FOV_DEG) / 2)
    f = (np.arange(PLANE_RES) + 0.5) / PLANE_RES
    fx, fy = np.meshgrid(f, f)
    cos_axis = 1 / np.sqrt(((2 * fx - 1) * tau) ** 2 + ((2 * fy - 1) * tau) ** 2 + 1)
    l0, rate = 2 * oracles.PLANE_DISTANCE_M / cos_axis, 2 * PLANE_SPEED_M_S / cos_axis
    m, d_l, d_rate = [], [], []
    for frame in sensor.frames:
        k, T = frame.wavenumber, frame.exposure
        z = 0.5 * frame.g1 * amplitude * np.exp(1j * (k * l0 + frame.phase))
        x = 2 * math.pi * frame.heterodyne + k * rate * T
        F = (np.exp(1j * x) - 1) / (1j * x)
        dF = (x * np.exp(1j * x) + 1j * np.exp(1j * x) - 1j) / x**2
        m.append((z * F).real)
        d_l.append((1j * k * z * F).real)
        d_rate.append((z * dF * k * T).real)
    m.append(amplitude), d_l.append(0 * amplitude), d_rate.append(0 * amplitude)  # the mean light
    return fisher_information(sensor, np.array(m), [np.array(m), np.array(d_l), np.array(d_rate)])


@pytest.mark.parametrize("frames", [((0.0, 0.0), (0.0, math.pi / 2), (1.0, 0.0), (1.0, math.pi / 2)), ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))])
def test_the_bound_of_the_record_equals_the_closed_form_on_the_moving_plane(plane_record, frames):
    from dopplertof.design import crb
    from dopplertof.design.precision import bounds

    sensor = _plane_sensor(frames)
    precision = crb(plane_record, sensor)
    closed = 0.5 * bounds(_single_path_fisher(sensor, plane_record.luminance[0].astype(np.float64)))
    assert precision.moving.all() and precision.velocity_crb.shape == (PLANE_RES, PLANE_RES)
    np.testing.assert_allclose(precision.velocity_crb, closed[..., 2], rtol=0.05)
    np.testing.assert_allclose(precision.depth_crb, closed[..., 1], rtol=0.05)
    assert np.mean(precision.velocity_crb / closed[..., 2]) == pytest.approx(1.0, abs=0.01)
    # shot-noise limited: 100 times the light, a tenth of the bound (read noise aside)
    brighter = dataclasses.replace(sensor, noise=dataclasses.replace(PLANE_SILICON, radiance_unit=160.0, read_noise_e=0.0, full_well_e=1e9, adc_bits=32))
    dimmer = dataclasses.replace(sensor, noise=dataclasses.replace(PLANE_SILICON, read_noise_e=0.0, full_well_e=1e9, adc_bits=32))
    ratio = crb(plane_record, brighter).velocity_crb / crb(plane_record, dimmer).velocity_crb
    np.testing.assert_allclose(ratio, 0.1, rtol=1e-3)


def test_the_ratio_estimator_reaches_the_bound_and_never_beats_it(plane_record):
    from dopplertof.design import achieved_rmse, crb

    sensor = _plane_sensor()
    bound = crb(plane_record, sensor).velocity_crb
    rmse = achieved_rmse(plane_record, sensor, draws=200, seed=5, method="ratio")
    assert np.isfinite(rmse).all()
    # over 64 pixels x 200 draws the RMS ratio is known to ~1 %: efficient to 10 %, not below
    ratio = np.sqrt(np.mean(rmse**2) / np.mean(bound**2))
    assert 0.97 <= ratio <= 1.10


def test_precision_needs_a_record_with_first_moments(recorded, plane_record):
    from dopplertof.design import crb

    without = dt.design.Record(**{**recorded.record.__dict__, "moments": None})
    with pytest.raises(ValueError, match="no first moments"):
        crb(without, Sensor(frames=[RawFrame(modulation_frequency=30e6, exposure=T, exposure_start=0.0)], noise=SILICON))
    with pytest.raises(ValueError, match="needs a response record"):
        crb(np.zeros((2, 2)), _plane_sensor())
    with pytest.raises(ValueError, match="'sensor' must be"):
        crb(plane_record, [dt.Camera()])


def test_a_record_with_first_moments_is_written_and_read_whole(plane_record, tmp_path):
    back = dt.io.read_record(dt.io.write_record(tmp_path / "plane.npz", plane_record))
    np.testing.assert_array_equal(back.moments, plane_record.moments)
    assert back.nbytes == plane_record.nbytes == PLANE_RES**2 * plane_record.spec.bytes_per_pixel()


# ----------------------------------------------------------------------------------------
# Gradients with respect to sensor parameters, against central differences

GRAD_BEATS = (0.0, 1.0, 2.0, 0.99, 1.01, 1.98, 2.02)  # h = 1 ± 0.01 for its central difference


@pytest.fixture(scope="module")
def gradient_case():
    from dopplertof import oracles

    scene = oracles.moving_plane_scene(PLANE_SPEED_M_S, resolution=6)
    spec = dict(band_hz=(PLANE_F, 3 * PLANE_F), step_hz=PLANE_F, beats=GRAD_BEATS, doppler=True, cameras_per_render=128)
    record = dt.render(scene, spp=16, max_depth=2, seed=1, record=spec).record
    sensor_code, light_code = codes.fourier([0, 0.6, 0.3j]), codes.fourier([0.5, 0.3, 0.1 + 0.1j])
    frames = [
        RawFrame(modulation_frequency=PLANE_F, heterodyne=h, phase=p, exposure=oracles.PLANE_EXPOSURE_S, light_code=light_code, sensor_code=sensor_code, g1=1.0, g0=0.2)
        for h, p in ((0.0, 0.0), (1.0, 0.3), (1.0, 1.9))
    ]  # fmt: skip
    return record, Sensor(frames=frames, noise=PLANE_SILICON)


def _with(sensor, frame, **change):
    frames = list(sensor.frames)
    frames[frame] = dataclasses.replace(frames[frame], **change)
    return dataclasses.replace(sensor, frames=frames)


def _central_differences(record, sensor, objective, kind, frame):
    """The objective's central differences, read out of the record at perturbed parameters
    (exact there: the record holds the perturbed beats and every code in its band)."""
    from dopplertof.design import gradient

    def value(s):
        return gradient(record, s, objective, parameters=[]).value

    original = sensor.frames[frame]
    if kind in ("phase", "heterodyne"):
        step = 1e-4 if kind == "phase" else 0.01
        x = getattr(original, kind)
        return (value(_with(sensor, frame, **{kind: x + step})) - value(_with(sensor, frame, **{kind: x - step}))) / (2 * step)
    c = np.asarray(getattr(original, kind).fourier)
    out = []
    for n in range(1, c.size):
        parts = []
        for unit in (1.0, 1j):
            up, down = c.copy(), c.copy()
            up[n] += 1e-4 * unit
            down[n] -= 1e-4 * unit
            parts.append((value(_with(sensor, frame, **{kind: codes.fourier(up)})) - value(_with(sensor, frame, **{kind: codes.fourier(down)}))) / 2e-4)
        out.append(parts[0] + 1j * parts[1])
    return np.asarray(out)


@pytest.mark.parametrize("objective", ["raw", "velocity_crb", "depth_crb"])
def test_gradients_match_central_differences_for_every_parameter_kind(gradient_case, objective):
    from dopplertof.design import gradient

    record, sensor = gradient_case
    result = gradient(record, sensor, objective)
    kinds = {kind for kind, _ in result.by_parameter}
    assert kinds == ({"phase", "sensor_code", "light_code", "heterodyne"} if objective == "raw" else {"phase", "sensor_code", "light_code"})
    for (kind, frame), analytic in result.by_parameter.items():
        if kind == "heterodyne" and sensor.frames[frame].heterodyne == 0:
            continue  # h = 0 ± 0.01 is not in the record's beats
        numeric = _central_differences(record, sensor, objective, kind, frame)
        assert np.abs(numeric).max() > 0, (kind, frame)
        error = np.abs(np.asarray(analytic) - numeric).max() / np.abs(numeric).max()
        assert error <= 0.01, (kind, frame, error)


@pytest.mark.parametrize("objective", ["raw", "velocity_crb", "depth_crb"])
def test_frequency_gradients_match_central_differences(objective):
    """The slopes' gradient against a record that holds f ± 10 kHz (the same paths: same
    seed and window); the silicon's contrast falls with frequency, which the gradient sees.
    The error is relative to the gradient's largest component: the homodyne frame's
    frequency moves the velocity bound 100 times less than the others', below what central
    differences of the float32 record resolve on their own."""
    from dopplertof import oracles
    from dopplertof.design import gradient

    scene = oracles.moving_plane_scene(PLANE_SPEED_M_S, resolution=6)
    step = 1e4
    common = dict(spp=16, max_depth=2, seed=1)
    with_slopes = dt.render(scene, record=dict(band_hz=(PLANE_F, PLANE_F), step_hz=PLANE_F, beats=(0.0, 1.0), doppler=True, slopes=True), **common).record
    around = dt.render(scene, record=dict(band_hz=(PLANE_F - step, PLANE_F + step), step_hz=step, beats=(0.0, 1.0), doppler=True), **common).record
    silicon = dataclasses.replace(PLANE_SILICON, demodulation_contrast=((10e6, 0.9), (100e6, 0.6)))
    frames = [RawFrame(modulation_frequency=PLANE_F, heterodyne=h, phase=p, exposure=oracles.PLANE_EXPOSURE_S) for h, p in ((0.0, 0.0), (1.0, 0.3), (1.0, 1.9))]
    sensor = Sensor(frames=frames, noise=silicon)
    result = gradient(with_slopes, sensor, objective, [("modulation_frequency", i) for i in range(3)])
    analytic, numeric = [], []
    for frame in range(3):
        up, down = (gradient(around, _with(sensor, frame, modulation_frequency=PLANE_F + d), objective, parameters=[]).value for d in (step, -step))
        numeric.append((np.asarray(up) - np.asarray(down)) / (2 * step))
        analytic.append(np.asarray(result.by_parameter[("modulation_frequency", frame)]))
    analytic, numeric = np.array(analytic), np.array(numeric)
    assert np.abs(numeric).max() > 0
    assert np.abs(analytic - numeric).max() <= 0.01 * np.abs(numeric).max()


def _joined(base, moved):
    """``base`` with the windows of ``moved`` appended: a record whose moved windows were
    traced with the same random numbers as base's (each rendered alone, as window 0)."""
    arrays = {name: np.concatenate([getattr(base, name), getattr(moved, name)]) for name in ("phasors", "luminance", "moments")}
    spec = dataclasses.replace(base.spec, window_slopes=False)
    return dt.design.Record(spec=spec, windows=base.windows + moved.windows, settings=base.settings, maps=base.maps, spp=base.spp, **arrays)


@pytest.mark.parametrize("objective", ["raw", "velocity_crb", "depth_crb"])
def test_exposure_and_start_gradients_match_central_differences(objective, tmp_path):
    """Each frame's exposure and start against the objective with that frame's window moved
    by ± δ, traced with the same random numbers (the other frames keep theirs). δ is the
    record's own step: where a moving edge crosses a pixel, the common-random-number
    difference of the window's paths has jumps, so differences at another δ scatter by a few
    per cent at 16 spp; at the same δ the comparison checks everything the gradient adds
    (T's scaling of the charge, the frame's own taps, the moments, the bounds' forward mode)."""
    from dopplertof import oracles
    from dopplertof.design import gradient
    from dopplertof.design.record import WINDOW_STEP

    scene = oracles.moving_plane_scene(PLANE_SPEED_M_S, resolution=6)
    exposure_s = oracles.PLANE_EXPOSURE_S

    def window_record(start_s, t_s, **extra):
        spec = dict(band_hz=(PLANE_F, PLANE_F), step_hz=PLANE_F, beats=(0.0, 1.0), doppler=True, **extra)
        return dt.render(scene, cameras=[dt.Camera(exposure=t_s, exposure_start=start_s)], record=spec, spp=16, max_depth=2, seed=1).record

    base = window_record(0.0, exposure_s, window_slopes=True)
    if objective == "raw":  # the window slopes are written and read whole
        back = dt.io.read_record(dt.io.write_record(tmp_path / "slopes.npz", base))
        for name in ("exposure_slopes", "start_slopes", "exposure_moment_slopes", "start_moment_slopes", "luminance_slopes"):
            np.testing.assert_array_equal(getattr(back, name), getattr(base, name), err_msg=name)
        assert back.nbytes == base.nbytes == 6 * 6 * base.spec.bytes_per_pixel()
    frames = [RawFrame(modulation_frequency=PLANE_F, heterodyne=h, phase=p, exposure=exposure_s, exposure_start=0.0) for h, p in ((0.0, 0.0), (1.0, 0.3), (1.0, 1.9))]
    sensor = Sensor(frames=frames, noise=PLANE_SILICON)
    parameters = [(kind, frame) for kind in ("exposure", "exposure_start") for frame in range(3)]
    result = gradient(base, sensor, objective, parameters, reference_time_s=0.0)
    step = WINDOW_STEP * exposure_s
    for kind, frame in parameters:
        values = []
        for d in (step, -step):
            start_s, t_s = (0.0, exposure_s + d) if kind == "exposure" else (d, exposure_s)
            moved = _with(sensor, frame, exposure=t_s, exposure_start=start_s)
            values.append(np.asarray(gradient(_joined(base, window_record(start_s, t_s)), moved, objective, parameters=[], reference_time_s=0.0).value))
        numeric = (values[0] - values[1]) / (2 * step)
        analytic = np.asarray(result.by_parameter[(kind, frame)])
        assert np.abs(numeric).max() > 0, (kind, frame)
        error = np.abs(analytic - numeric).max() / np.abs(numeric).max()
        assert error <= 0.01, (kind, frame, error)


@pytest.mark.parametrize(
    "objective, parameters, message",
    [
        ("velocity_crb", [("modulation_frequency", 0)], "no frequency slopes"),
        ("raw", [("exposure", 1)], "no window slopes"),
        ("velocity_crb", [("heterodyne", 1)], "second moments"),
        ("raw", [("phase", 3)], "frames 0 to 2"),
        ("raw", [("gain", 0)], "unknown parameter 'gain'"),
        ("raw", ["phase"], r"\(kind, frame index\)"),
        ("snr", None, "unknown objective 'snr'"),
    ],
)
def test_gradient_refuses_what_it_cannot_differentiate(gradient_case, objective, parameters, message):
    from dopplertof.design import gradient

    record, sensor = gradient_case
    with pytest.raises(ValueError, match=message):
        gradient(record, sensor, objective, parameters)


def test_code_gradients_need_fourier_coefficients(recorded):
    from dopplertof.design import gradient

    chips = RawFrame(modulation_frequency=10e6, exposure=T, exposure_start=0.0, light_code=[0, 1] * 4, sensor_code=[1, -1] * 4, light_bandwidth=30e6)
    with pytest.raises(ValueError, match="Fourier coefficients"):
        gradient(recorded, Sensor(frames=[chips], noise=SILICON), "raw", [("sensor_code", 0)])


# ----------------------------------------------------------------------------------------
# Sweeps and optimisation


def test_an_optimisation_from_a_poor_start_reaches_the_best_grid_value(tmp_path):
    from dopplertof import oracles
    from dopplertof.design.search import optimize, record_spec, sweep
    from dopplertof.sensors import preset

    scene = oracles.moving_plane_scene(PLANE_SPEED_M_S, resolution=6)
    frames = [RawFrame(modulation_frequency=10e6, heterodyne=h, phase=p, exposure=oracles.PLANE_EXPOSURE_S) for h, p in ((0.0, 0.0), (1.0, 0.0), (1.0, math.pi / 2))]
    poor = preset("dtof-prototype", frames, radiance_unit=1.0)
    spec, cameras = record_spec(poor, [], optimize=["modulation_frequency"])
    assert spec.band_hz == (10e6, 100e6) and spec.step_hz == 1e6  # the chip's range, 1 MHz apart
    record = dt.render(scene, cameras=cameras, spp=16, max_depth=2, seed=3, record=spec).record
    grid = sweep(record, poor, [("modulation_frequency", np.arange(10e6, 100e6 + 1, 5e6))])
    best_grid = min(r["objective"] for r in grid if r["status"] == "ok")
    best, history = optimize(record, poor, ["modulation_frequency", "phase"])
    assert history[-1]["objective"] < 0.5 * history[0]["objective"]  # a real improvement
    assert history[-1]["objective"] <= 1.05 * best_grid
    assert dt.design.crb(record, best).summary()["velocity_crb_mean"] == pytest.approx(history[-1]["objective"])


def test_a_sweep_lists_what_the_chip_refuses(recorded):
    from dopplertof.design.search import sweep
    from dopplertof.sensors import preset

    frames = [RawFrame(modulation_frequency=40e6, heterodyne=h, phase=p, exposure=T, exposure_start=0.0) for h, p in ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0))]
    prototype = preset("dtof-prototype", frames, radiance_unit=1e-3)  # 10-100 MHz
    rows = sweep(recorded.record, prototype, [("modulation_frequency", np.array([40e6, 110e6]))])
    assert rows[0]["status"] == "ok" and rows[0]["objective"] > 0
    assert rows[1]["status"].startswith("refused") and "1.1e+08 Hz outside" in rows[1]["status"] and math.isnan(rows[1]["objective"])
    # light enough to saturate every pixel: no moving pixel has a finite bound, and the row says so (it said "ok")
    blinding = preset("dtof-prototype", frames, radiance_unit=1e9)
    (row,) = sweep(recorded.record, blinding, [("modulation_frequency", np.array([40e6]))])
    assert math.isnan(row["objective"]) and row["status"].startswith("no bound: velocity_crb is infinite at every moving pixel"), row


@pytest.mark.parametrize("text, message", [("f=1:2", "KEY=LO:HI:N"), ("gain=1:2:3", "unknown key 'gain'"), ("f=2:1:3", "LO <= HI"), ("f10", "expected KEY=LO:HI:N")])
def test_a_sweep_refuses_bad_grids(text, message):
    from dopplertof.design.search import parse_sweep

    with pytest.raises(ValueError, match=message):
        parse_sweep(text)


def test_a_sensor_written_as_toml_is_read_back_the_same(tmp_path):
    from dopplertof.sensors import preset
    from dopplertof.sensors.files import load_sensor, sensor_toml

    custom = Sensor(
        frames=[RawFrame(modulation_frequency=20e6, heterodyne_hz=500.0, exposure=T, light_code=codes.fourier([0.5, 0.3j]), sensor_code=[1, -1] * 4, light_bandwidth=40e6)],
        noise=SILICON,
    )  # fmt: skip
    for sensor in (preset("mlx75027"), preset("dtof-prototype"), custom):
        path = tmp_path / f"{sensor.name}.toml"
        path.write_text(sensor_toml(sensor))
        assert load_sensor(str(path)) == sensor


# ----------------------------------------------------------------------------------------
# Render only as long as it matters


def test_until_noise_stops_at_the_first_pass_that_reaches_the_ratio():
    from dopplertof.design.convergence import noise_ratio, quantile
    from dopplertof.sensors import preset

    sensor = preset("dtof-prototype", radiance_unit=1e-3)
    # 16 spp per pass (1024 lanes over 64 pixels), 4 strata per pass: the error is known after every pass
    result = dt.render(dt.scenes.cornell_box(resolution=8), sensor=sensor, spp=2048, lanes_per_pass=1024, max_depth=3, seed=2, until_noise=0.3)
    info = result.info["until_noise"]
    history = info["history"][0]
    assert not result.interrupted and result.spp == info["spp"][0] == history[-1][0] < 2048
    assert history[-1][1] <= 0.3 < history[-2][1] and history[-1][0] - history[-2][0] == 16  # stopped within one pass
    # the ratio reached, recomputed from the result itself
    assert quantile(noise_ratio(sensor, result.measurements, result.measurement_stderr)) == pytest.approx(info["reached"][0], rel=1e-5)
    # and it falls as 1/sqrt(spp): the error bound follows the render
    (spp_a, a), (spp_b, b) = history[len(history) // 2], history[-1]
    assert b / a == pytest.approx(math.sqrt(spp_a / spp_b), rel=0.2)


def test_until_noise_checks_after_every_replicate_even_when_one_pass_would_hold_the_whole_render():
    from dopplertof.sensors import preset

    sensor = preset("dtof-prototype", radiance_unit=1e-3)
    # 8x8 x 2048 spp fit in one pass of the default size: until_noise must still see the error grow small
    result = dt.render(dt.scenes.cornell_box(resolution=8), sensor=sensor, spp=2048, max_depth=3, seed=2, until_noise=1.0)
    history = result.info["until_noise"]["history"][0]
    assert len(history) >= 1 and history[-1][1] <= 1.0 and result.spp == history[-1][0] < 2048
    assert result.settings.lanes_per_pass == 64 * 2048 // 16  # one replicate (of the default 16) per pass


def test_until_noise_on_a_tiny_film_checks_after_passes_of_the_smallest_size():
    from dopplertof.sensors import preset

    # 16² at 8 spp: a replicate is 512 lanes, below the smallest pass (it was refused: "'lanes_per_pass' must be >= 1024")
    result = dt.render(dt.scenes.cornell_box(resolution=16), sensor=preset("dtof-prototype"), spp=8, max_depth=2, until_noise=0.5)
    assert result.settings.lanes_per_pass == 1024 and result.spp in (4, 8)


def test_a_render_resumed_with_until_noise_continues_the_checkpoints_passes(tmp_path):
    from dopplertof.sensors import preset

    sensor = preset("dtof-prototype", radiance_unit=1e-3)
    scene = dt.scenes.cornell_box(resolution=8)
    checkpoint = str(tmp_path / "c.npz")
    common = dict(sensor=sensor, spp=2048, max_depth=3, seed=2, lanes_per_pass=16384, checkpoint=checkpoint)
    calls = iter(range(100))
    partial = dt.render(scene, stop=lambda: next(calls) >= 2, **common)  # 2 of 8 passes of 256 spp
    assert partial.interrupted and partial.spp == 512
    # until_noise alone would check after every replicate (128 spp passes): it takes the checkpoint's 256
    result = dt.render(scene, until_noise=1.0, **common)
    assert result.settings.lanes_per_pass == 16384 and result.spp % 256 == 0 and result.spp > 512
    unbroken = dt.render(scene, until_noise=1.0, **{**common, "checkpoint": None})
    assert unbroken.settings.lanes_per_pass == 8192  # what it lowers to without a checkpoint
    # a checkpoint whose passes are larger than asked is still refused (memory bound kept)
    calls = iter(range(100))
    dt.render(scene, stop=lambda: next(calls) >= 1, **{**common, "checkpoint": str(tmp_path / "d.npz")})
    with pytest.raises(ValueError, match=r"lanes_per_pass: 16384 in the checkpoint, 4096 now"):
        dt.render(scene, **{**common, "checkpoint": str(tmp_path / "d.npz"), "lanes_per_pass": 4096})


def test_until_noise_needs_a_sensor_and_a_positive_ratio(cornell):
    with pytest.raises(ValueError, match="needs a sensor"):
        dt.render(cornell, spp=2, until_noise=0.5)
    with pytest.raises(ValueError, match=re.escape("until_noise=0.0: must be > 0")):
        dt.render(cornell, spp=2, sensor=Sensor(frames=[RawFrame(exposure=T)], noise=SILICON), until_noise=0.0)


def test_a_record_larger_than_the_memory_is_refused_before_rendering(cornell, monkeypatch):
    import sys

    monkeypatch.setattr(sys.modules["dopplertof.resources"], "available_memory_bytes", lambda: 10**5)  # 0.1 MB; the record and its Float64 sums need 0.42
    rendered = []
    monkeypatch.setattr(sys.modules["dopplertof.render"], "_traced_locally", lambda *a: rendered.append(a))
    with pytest.raises(ValueError, match=r"record: 30 frequencies x 2 beats x 1 window\(s\) on a 12x12 film need about 0.00039 GiB; 9.3e-05 GiB"):
        dt.render(cornell, spp=2, record=dict(band_hz=(10e6, 300e6), step_hz=10e6, beats=(0, 1), doppler=True), exposure=T)
    assert rendered == []
