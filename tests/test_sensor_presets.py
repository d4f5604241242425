"""Sensor presets: sourced silicon, legal schedules accepted, illegal ones refused, each renders."""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof.sensors import PRESETS, RawFrame, preset

NAMES = ["mlx75027", "opt8241", "imx556", "kinect-v2", "dtof-prototype"]


def test_the_presets_are_the_named_five():
    assert sorted(PRESETS) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_each_preset_renders_the_cornell_box(name):
    sensor = preset(name, radiance_unit=1e-4)
    scene = dt.scenes.cornell_box(resolution=8)
    result = dt.render(scene, sensor=sensor, spp=2, max_depth=2, seed=1)
    assert result.raw.shape == (len(sensor.frames), sensor.taps, 8, 8)
    assert np.isfinite(result.raw).all() and result.raw.max() > 0
    dn = sensor.read_out(result, seed=2)
    assert dn.shape == result.raw.shape and 0 <= dn.min() and dn.max() <= sensor.noise.max_dn


def test_mlx75027_numbers_and_schedule():
    sensor = preset("mlx75027")
    assert sensor.taps == 2 and sensor.noise.pixel_pitch_m == 10e-6 and sensor.noise.adc_bits == 12
    assert sensor.noise.contrast(100e6) == pytest.approx(0.78) and sensor.noise.contrast(40e6) == pytest.approx(0.85)
    assert sensor.noise.qe == pytest.approx(0.51)
    assert preset("mlx75027", wavelength_m=940e-9).noise.qe == pytest.approx(0.28)
    assert [round(math.degrees(f.phase)) for f in sensor.frames] == [0, 90, 180, 270]
    # legal: 8 raw phases in 45° steps at 20 MHz, 999 µs each
    legal = [RawFrame(modulation_frequency=20e6, phase=k * math.pi / 4, exposure=999e-6, waveform="rectangular") for k in range(8)]
    assert len(preset("mlx75027", frames=legal).frames) == 8


@pytest.mark.parametrize(
    "name,frame,match",
    [
        ("mlx75027", dict(modulation_frequency=30e6, heterodyne_hz=667.0, exposure=0.5e-3, waveform="rectangular"), r"^MLX75027 cannot capture this schedule: frame 0: heterodyne offset 667 Hz .*use the 'dtof-prototype' preset$"),
        ("mlx75027", dict(modulation_frequency=30e6, exposure=1.5e-3, waveform="rectangular"), "integration time 0.0015 s not below its 0.001 s"),
        ("mlx75027", dict(modulation_frequency=30.5e6, exposure=0.5e-3, waveform="rectangular"), "not a multiple of its 1e[+]06 Hz step"),
        ("mlx75027", dict(modulation_frequency=30e6, exposure=0.5e-3, phase=0.3, waveform="rectangular"), "phase 17.1887 deg not a multiple of its 45 deg step"),
        ("mlx75027", dict(modulation_frequency=120e6, exposure=0.5e-3, waveform="rectangular"), "outside 4e[+]06 to 1e[+]08 Hz"),
        ("mlx75027", dict(modulation_frequency=30e6, exposure=0.5e-3, waveform="triangular"), "waveform 'triangular'"),
        ("opt8241", dict(modulation_frequency=30e6, heterodyne=1.0), "OPT8241 cannot capture .*heterodyne offset 666.667 Hz"),
        ("imx556", dict(modulation_frequency=30e6, heterodyne=1.0, waveform="rectangular"), "IMX556 cannot capture"),
        ("kinect-v2", dict(modulation_frequency=50e6, phase=math.pi / 2), "phase 90 deg not a multiple of its 120 deg step"),
        ("dtof-prototype", dict(modulation_frequency=5e6, heterodyne=1.0), "outside 1e[+]07 to 1e[+]08 Hz"),
    ],
)
def test_presets_refuse_what_their_hardware_cannot_do(name, frame, match):
    with pytest.raises(ValueError, match=match):
        preset(name, frames=[RawFrame(**frame)])


def test_mlx75027_refuses_more_than_eight_raw_frames():
    frames = [RawFrame(modulation_frequency=20e6, phase=(k % 8) * math.pi / 4, exposure=1e-4, waveform="rectangular") for k in range(9)]
    with pytest.raises(ValueError, match=r"9 raw frames \(at most 8\)"):
        preset("mlx75027", frames=frames)


def test_dtof_prototype_takes_sub_hz_offsets_and_any_phase():
    frames = [RawFrame(modulation_frequency=30e6, exposure=1.5e-3, heterodyne_hz=0.37, phase=0.123)]
    assert preset("dtof-prototype", frames=frames).frames[0].heterodyne == pytest.approx(0.37 * 1.5e-3)
    default = preset("dtof-prototype").frames
    assert [(f.modulation_frequency, f.exposure, f.heterodyne, f.phase) for f in default] == [(30e6, 1.5e-3, 0.0, 0.0), (30e6, 1.5e-3, 0.0, math.pi / 2), (30e6, 1.5e-3, 1.0, 0.0), (30e6, 1.5e-3, 1.0, math.pi / 2)]


def test_kinect_v2_is_nine_frames_one_after_another():
    frames = preset("kinect-v2").frames
    assert len(frames) == 9 and len({f.modulation_frequency for f in frames}) == 3
    assert [f.exposure_start for f in frames] == [k * 1e-3 for k in range(9)]


def test_preset_refuses_unknown_names_and_parameters():
    with pytest.raises(ValueError, match="unknown sensor preset 'mlx'; choose one of mlx75027"):
        preset("mlx")
    with pytest.raises(ValueError, match="unknown silicon parameter"):
        preset("mlx75027", pixel_size=1.0)
    with pytest.raises(ValueError, match="'f_number' must be > 0"):
        preset("opt8241", f_number=0.0)
