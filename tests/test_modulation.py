"""Modulation weights: normalisation, wrapping, camera validation."""

import math
import warnings

import numpy as np
import pytest

from dopplertof.modulation import WAVEFORMS, Camera, full_weight, lowpass_waveform, weight, wrap_phase


@pytest.mark.parametrize("waveform", WAVEFORMS)
@pytest.mark.parametrize("heterodyne,phase,length", [(0.0, 0.0, 1.3), (1.0, -2.0, 3.1), (-0.5, 0.7, 0.2), (0.25, -7.0, 5.0)])
def test_lowpass_equals_exposure_average_of_full_waveform(waveform, heterodyne, phase, length):
    """(g1/2)Λ equals the numerical average of s·(g1 g + g0) over many carrier periods."""
    full = Camera(heterodyne=heterodyne, phase=phase, waveform=waveform, low_pass=False)
    low = Camera(heterodyne=heterodyne, phase=phase, waveform=waveform, low_pass=True)
    # 1000 carrier periods around u0, sampled 4000 times per period (midpoints): the slow
    # beat changes by < 1e-4 rad over the window, so the window average is the low-pass value.
    periods = 1000
    u0 = 0.3
    cycles_per_u = full.modulation_frequency * full.exposure
    u = u0 + (np.arange(periods * 4000) + 0.5) / 4000 / cycles_per_u
    average = full_weight(full, u, length).mean()
    expected = weight(low, np.array([u0 + periods / 2 / cycles_per_u]), length)[0]
    assert average == pytest.approx(expected, abs=2e-3 * low.g1)


@pytest.mark.parametrize("waveform", WAVEFORMS)
def test_negative_phases_wrap_like_positive_ones(waveform):
    theta = np.linspace(-30, 30, 1001)
    np.testing.assert_allclose(lowpass_waveform(theta, waveform), lowpass_waveform(theta + 2 * math.pi * 7, waveform), atol=1e-9)
    w = wrap_phase(theta)
    assert np.all((w >= 0) & (w < 2 * math.pi))


def test_lowpass_shapes_at_known_points():
    assert lowpass_waveform(np.array([0.0]), "rectangular")[0] == pytest.approx(2.0)
    assert lowpass_waveform(np.array([math.pi]), "rectangular")[0] == pytest.approx(-2.0)
    assert lowpass_waveform(np.array([0.0]), "triangular")[0] == pytest.approx(2 / 3)
    assert lowpass_waveform(np.array([math.pi / 4]), "trapezoidal")[0] == pytest.approx(2.0)
    assert lowpass_waveform(np.array([math.pi / 2]), "trapezoidal")[0] == pytest.approx(0.0)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"waveform": "square"}, "unknown waveform"),
        ({"exposure": 0.0}, r"'exposure' must be in \(0, 60\] s, got 0.0"),
        ({"exposure": -1e-3}, r"'exposure' must be in \(0, 60\] s, got -0.001"),
        ({"exposure": 1e300}, r"'exposure' must be in \(0, 60\] s, got 1e\+300"),
        ({"g1": -1}, r"'g1' .* must be > 0, got -1.0"),
        ({"g1": 0}, r"'g1' .* must be > 0, got 0.0"),
        ({"g0": -5}, r"'g0' .* must be >= 0, got -5.0"),
        ({"low_pass": "no"}, r"'low_pass' must be a boolean"),
        ({"modulation_frequency": 0}, r"modulation_frequency must be in \(0, "),
        ({"heterodyne": float("nan")}, "'heterodyne' must be a finite number"),
    ],
)
def test_camera_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Camera(**kwargs)


def test_a_modulation_frequency_in_the_wrong_unit_warns():
    with pytest.warns(UserWarning, match=r"modulation_frequency=30 Hz, a wavelength of 9.99e\+06 m; the unit is Hz"):
        Camera(modulation_frequency=30)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Camera(modulation_frequency=10e6)


@pytest.mark.parametrize("text,expected", [("false", False), ("False", False), ("0", False), ("no", False), ("true", True), ("1", True), (False, False), (True, True)])
def test_camera_from_original_parses_boolean_text_strictly(text, expected):
    assert Camera.from_original({"low_frequency_component_only": text}).low_pass is expected


@pytest.mark.parametrize("params,match", [
    ({"low_frequency_component_only": "maybe"}, r"'low_frequency_component_only' must be true or false, got 'maybe'"),
    ({"low_frequency_component_only": 2}, r"'low_frequency_component_only' must be a boolean"),
    ({"time": "soon"}, r"'time' must be a finite number, got 'soon'"),
    ({"g_1": "-1"}, r"'g1' .* must be > 0, got -1.0"),
    # a misspelt key gave the default (a homodyne camera for a misspelt hetero_frequency)
    ({"w_g": 30, "hetero_frequnecy": 1.0}, r"unknown camera key 'hetero_frequnecy' \(did you mean 'hetero_frequency'\?\); the keys are time, "),
    ({"w_g": 30e6}, r"modulation_frequency must be in .*, got 30000000000000.0 \(w_g and w_s are in MHz: w_g=30 is 30 MHz\)"),
])  # fmt: skip
def test_camera_from_original_refuses_bad_values(params, match):
    with pytest.raises(ValueError, match=match):
        Camera.from_original(params)


def test_camera_from_original_reads_numbers_given_as_text():
    cam = Camera.from_original({"time": "0.002", "w_g": "20", "hetero_frequency": "1"})
    assert (cam.exposure, cam.modulation_frequency, cam.heterodyne) == (0.002, 20e6, 1.0)
    assert Camera.from_original({"w_g": "30"}).heterodyne == 0.0  # w_s defaults to w_g exactly: homodyne


def test_camera_from_original_parameter_names():
    cam = Camera.from_original({"time": 0.002, "w_g": 150, "hetero_frequency": 0.5, "hetero_offset": 0.25, "sensor_phase_offset": 9.0})
    assert cam.modulation_frequency == pytest.approx(150e6)
    assert cam.exposure == pytest.approx(0.002)
    assert cam.heterodyne == pytest.approx(0.5)
    assert cam.phase == pytest.approx(math.pi / 2)  # hetero_offset overrides sensor_phase_offset
    # w_s is converted without float32 cancellation: h = (f_s - f_g) T
    cam = Camera.from_original({"time": 0.0015, "w_g": 30, "w_s": 30.000666666666667})
    assert cam.heterodyne == pytest.approx(1.0, rel=1e-6)
