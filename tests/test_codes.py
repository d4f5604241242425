"""Codes as data: sampled and Fourier codes, their exact correlation, and coded cameras."""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import codes
from dopplertof.modulation import Camera, full_weight, lowpass_weight, weight

TWO_PI = 2 * math.pi


def _midpoints(n):
    return TWO_PI * (np.arange(n) + 0.5) / n


def _square(n=16):
    return np.sign(np.cos(_midpoints(n)))


def _pulse(n=8):
    """4 over a quarter period centred on 0 (mean 1): the trapezoidal camera's light."""
    theta = _midpoints(n)
    return np.where(np.minimum(theta, TWO_PI - theta) < math.pi / 4, 4.0, 0.0)


# (named camera kwargs, coded camera kwargs) that must measure the same thing
EQUIVALENT = {
    "sampled sinusoid": ({}, dict(light_code=np.cos(_midpoints(1024)), sensor_code=np.cos(_midpoints(1024)))),
    "Fourier sinusoid": ({}, dict(light_code=codes.fourier([0, 1]), sensor_code=codes.fourier([0, 1]))),
    "sampled square": (dict(waveform="rectangular"), dict(light_code=_square(), sensor_code=_square())),
    "square and pulse": (dict(waveform="trapezoidal"), dict(light_code=_pulse(), sensor_code=_square(8))),
}


@pytest.mark.parametrize("low_pass", [True, False])
@pytest.mark.parametrize("case", sorted(EQUIVALENT))
def test_codes_reproduce_named_waveforms(case, low_pass):
    named_kw, coded_kw = EQUIVALENT[case]
    named = Camera(heterodyne=0.7, phase=-0.4, low_pass=low_pass, **named_kw)
    coded = Camera(heterodyne=0.7, phase=-0.4, low_pass=low_pass, **coded_kw)
    assert coded.waveform == "code"
    u = np.linspace(0, 1, 2001)
    length_m = np.linspace(0.0, 9.0, 2001)
    expected = weight(named, u, length_m)
    np.testing.assert_allclose(weight(coded, u, length_m), expected, atol=_tolerance(case, low_pass) * np.abs(expected).max())


def _tolerance(case, low_pass):
    """A sampled sinusoid is a staircase of N = 1024 steps: pointwise within π/N of the
    sinusoid (full product), its correlation's fundamental sinc²(1/N) of the sinusoid's."""
    if case == "sampled sinusoid":
        return 1e-4 if low_pass else math.pi / 1024
    return 1e-12


def test_codes_reproduce_named_waveforms_in_a_render():
    """Same paths (one render): the kernel's table and harmonic forms equal the named closed forms."""
    # Not the staircase's full product: its per-sample error, π/N of the carrier's
    # amplitude, is not small against a full-waveform pixel's cancelling sum.
    pairs = [(case, low_pass) for case in sorted(EQUIVALENT) for low_pass in (True, False) if low_pass or case != "sampled sinusoid"]
    cameras = []
    for h, (case, low_pass) in zip([1.0, 0.0, 0.5, 1.0, 0.25, 1.0, 0.0], pairs):
        cameras += [Camera(heterodyne=h, phase=0.3, low_pass=low_pass, **kw) for kw in EQUIVALENT[case]]
    result = dt.render(dt.scenes.cornell_box(resolution=12), cameras=cameras, spp=4, max_depth=2, seed=3)
    m = result.measurements.astype(np.float64)
    for k, (case, low_pass) in enumerate(pairs):
        named, coded = m[2 * k], m[2 * k + 1]
        scale = np.abs(named).max()
        assert scale > 0
        # float32 accumulation: 1e-6 relative at best
        assert np.abs(coded - named).max() <= max(_tolerance(case, low_pass), 1e-5) * scale, (case, low_pass)


def _direct_correlation(sensor, light, delta, n=240_000):
    phi = _midpoints(n)
    return np.array([np.mean(sensor(phi + d) * light(phi)) for d in delta])


@pytest.mark.parametrize(
    "make",
    [
        lambda rng: (codes.sampled(rng.normal(size=12)), codes.sampled(rng.normal(size=9))),
        lambda rng: (codes.sampled(rng.integers(0, 2, 10) * 2.0 - 1), codes.sampled(rng.integers(0, 2, 10) * 1.0)),
        lambda rng: (codes.fourier(rng.normal(size=4) + 1j * rng.normal(size=4)), codes.sampled(rng.normal(size=8))),
        lambda rng: (codes.sampled(rng.normal(size=8)), codes.fourier(rng.normal(size=6) + 1j * rng.normal(size=6))),
    ],
    ids=["chips 12x9", "binary chips", "fourier x chips", "chips x fourier"],
)
def test_correlation_equals_direct_integration_over_the_period(make):
    sensor, light = make(np.random.default_rng(7))
    delta = np.array([-7.3, -1.0, 0.0, 0.123, 1.9, 3.3, 12.0])
    expected = _direct_correlation(sensor, light, delta)
    got = codes.correlation(sensor, light)(delta)
    # The direct sum resolves the chips' edges to 1/240000 of a period.
    np.testing.assert_allclose(got, expected, atol=2e-4 * np.abs(expected).max())


def test_band_limited_light_correlates_exactly():
    rng = np.random.default_rng(2)
    camera = Camera(light_code=rng.integers(0, 2, 16) * 1.0, sensor_code=_square(), light_bandwidth=7.5 * 30e6)
    assert camera.light.order == 7  # harmonics above 7 × 30 MHz removed
    harmonics = np.fft.rfft(camera.light(_midpoints(4096)))
    assert np.abs(harmonics[8:]).max() < 1e-9 * np.abs(harmonics[1:8]).max()
    delta = np.array([0.0, 0.7, 4.0])
    np.testing.assert_allclose(camera.correlation(delta), _direct_correlation(camera.sensor_code, camera.light, delta), atol=2e-5)


@pytest.mark.parametrize("heterodyne,phase,length", [(0.0, 0.2, 1.3), (1.0, -2.0, 3.1)])
def test_lowpass_code_weight_is_the_dc_part_of_the_full_product(heterodyne, phase, length):
    """g1 C + g0 s̄ equals the average of s·(g1 g + g0) over many carrier periods (a sensor
    code with a non-zero mean keeps its g0 term)."""
    rng = np.random.default_rng(5)
    kw = dict(light_code=rng.uniform(0, 1, 10), sensor_code=rng.uniform(-0.5, 1, 8), heterodyne=heterodyne, phase=phase)
    full, low = Camera(low_pass=False, **kw), Camera(low_pass=True, **kw)
    periods, per_period = 500, 4000
    cycles_per_u = full.modulation_frequency * full.exposure
    u = 0.3 + (np.arange(periods * per_period) + 0.5) / per_period / cycles_per_u
    expected = weight(low, np.array([0.3 + periods / 2 / cycles_per_u]), length)[0]
    assert full_weight(full, u, length).mean() == pytest.approx(expected, abs=2e-3)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(light_code=_square()), "both light_code and sensor_code"),
        (dict(light_code=_square(), sensor_code=np.ones(4)), r"'sensor_code'.*N >= 8"),
        (dict(light_code=np.ones((2, 8)), sensor_code=_square()), r"'light_code' must be one period.*shape \(2, 8\)"),
        (dict(light_code=np.ones(8) * 1j, sensor_code=_square()), "fourier"),
        (dict(light_code=[1.0] * 7 + [np.nan], sensor_code=_square()), "finite"),
        (dict(light_code="abc", sensor_code=_square()), "'light_code' must be"),
        (dict(light_code=_square(), sensor_code=_square(), waveform="rectangular"), "exclude each other"),
        (dict(waveform="code"), "give light_code and sensor_code"),
        (dict(light_bandwidth=1e9), "light_bandwidth applies to cameras with light_code"),
        (dict(waveform="triangular", light_bandwidth=1e9), "not the triangular one"),
        (dict(waveform="rectangular", light_bandwidth=3e8, light_code=_pulse(), sensor_code=_square(8)), "exclude each other"),
        (dict(light_code=_square(), sensor_code=_square(), light_bandwidth=1e6), "below the modulation frequency"),
    ],
)
def test_coded_camera_refuses_bad_codes(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Camera(**kwargs)


def test_analytic_time_integration_refuses_coded_cameras():
    camera = Camera(light_code=codes.fourier([0, 1]), sensor_code=codes.fourier([0, 1]))
    with pytest.raises(ValueError, match="low-pass sinusoid only"):
        dt.RenderSettings.build({"cameras": [camera], "time_sampling": "analytic"})


def test_code_tables_load_from_npy_and_npz(tmp_path):
    table = np.random.default_rng(0).normal(size=(3, 16))
    np.save(tmp_path / "c.npy", table)
    np.savez(tmp_path / "c.npz", codes=table, other=np.zeros(3))
    np.savez(tmp_path / "one.npz", table)
    for name in ("c.npy", "c.npz", "one.npz"):
        np.testing.assert_array_equal(codes.load_codes(tmp_path / name), table)
    camera = Camera(light_code=codes.load_codes(tmp_path / "c.npy")[0], sensor_code=table[1])
    assert camera.light_code.samples == tuple(table[0])
    np.savez(tmp_path / "two.npz", a=table, b=table)
    with pytest.raises(ValueError, match="name the code table 'codes'"):
        codes.load_codes(tmp_path / "two.npz")
    np.save(tmp_path / "short.npy", np.ones((2, 4)))
    with pytest.raises(ValueError, match="N >= 8"):
        codes.load_codes(tmp_path / "short.npy")


def test_coded_cameras_round_trip_through_json():
    """metadata.json keeps a camera as Camera.as_dict(); reading it back gives the same camera."""
    import json

    for kw in (dict(light_code=_square(), sensor_code=_square(), light_bandwidth=3e8), dict(light_code=codes.fourier([0.1, 1 - 0.5j]), sensor_code=_pulse() / 4)):
        camera = Camera(heterodyne=0.5, phase=1.0, **kw)
        camera.correlation  # cached values must not leak into the record
        record = json.loads(json.dumps(camera.as_dict()))
        assert Camera(**record) == camera
    raw = dt.RawFrame(heterodyne_hz=400.0, exposure=1e-3)
    assert Camera(**raw.as_dict()) == Camera(heterodyne=0.4, exposure=1e-3)
    with pytest.raises(ValueError, match="one key, 'samples' or 'fourier'"):
        Camera(light_code={"chips": [1] * 8}, sensor_code=_square())


@pytest.mark.parametrize("waveform", codes.NAMED_CODES)
def test_a_named_waveform_through_a_finite_bandwidth_is_its_chips_band_limited(waveform):
    """The rectangular and trapezoidal waveforms with light_bandwidth keep their name (a
    chip's limits accept them) and weigh as their chip codes with the harmonics above the
    bandwidth removed: the named waveform's own Fourier series, truncated."""
    f = 30e6
    ph = np.linspace(-math.pi, math.pi, 181)
    named = Camera(modulation_frequency=f, waveform=waveform, heterodyne=0.0)
    third = Camera(modulation_frequency=f, waveform=waveform, heterodyne=0.0, light_bandwidth=3.5 * f)
    assert third.waveform == waveform and third.coded and third.light_mean == named.light_mean
    assert Camera(**third.as_dict()) == third  # written and read back
    # Λ/2 of the named waveform, numerically: its Fourier series up to the third harmonic
    dense = np.linspace(0, 2 * math.pi, 1 << 14, endpoint=False)
    lam = lowpass_weight(named, dense) / (0.5 * named.g1)
    series = np.fft.rfft(lam) / dense.size
    expected = 0.5 * named.g1 * (series[0].real + 2 * sum((series[m] * np.exp(1j * m * ph)).real for m in (1, 2, 3)))
    np.testing.assert_allclose(lowpass_weight(third, ph), expected, atol=1e-6)
    # a wide band approaches the named waveform: the tail Σ_{odd m > M} 8/(π² m²) ≈ 4/(π² M)
    wide = Camera(modulation_frequency=f, waveform=waveform, heterodyne=0.0, light_bandwidth=2001 * f)
    scale = 2.0 if waveform == "trapezoidal" else 1.0  # the trapezoid's Λ has the pulse's weight
    np.testing.assert_allclose(lowpass_weight(wide, ph), lowpass_weight(named, ph), atol=scale * named.g1 * 4 / (math.pi**2 * 2001))
    assert not np.allclose(lowpass_weight(third, ph), lowpass_weight(named, ph), atol=1e-3)
