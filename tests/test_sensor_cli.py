"""``dopplertof render --sensor PRESET|FILE.toml``: raw frames and their schedule on disk,
and one ``error:`` line (exit 2) for what a sensor cannot do."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from dopplertof.sensors import preset


def _run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_render_with_a_preset_writes_raw_frames_and_their_schedule(tmp_path):
    out = tmp_path / "mlx"
    proc = _run("render", "cornell-box", "--resolution", "8", "--spp", "2", "--max-depth", "2", "--quiet", "--sensor", "mlx75027", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    electrons = np.load(out / "raw_electrons.npy")
    dn = np.load(out / "raw_dn.npy")
    assert electrons.shape == dn.shape == (4, 2, 8, 8) and electrons.dtype == np.float32 and dn.dtype == np.int64
    meta = json.loads((out / "metadata.json").read_text())
    sensor = meta["sensor"]
    assert sensor["name"] == "mlx75027" and sensor["taps"] == 2 and sensor["limits"] == "MLX75027"
    assert [round(math.degrees(f["phase"])) for f in sensor["frames"]] == [0, 90, 180, 270]
    assert all(f["modulation_frequency"] == 100e6 and f["exposure"] == 300e-6 and f["exposure_start"] == 0.0 for f in sensor["frames"])
    assert {"raw_electrons.npy", "raw_dn.npy"} <= set(meta["files"])
    # the digital numbers are the preset's read-out of the electrons with the render's seed
    np.testing.assert_array_equal(dn, preset("mlx75027").read_out(electrons, seed=meta["seed"]))


def test_render_with_a_sensor_file(tmp_path):
    codes = np.sign(np.cos(2 * np.pi * (np.arange(3)[:, None] + 1) * (np.arange(16) + 0.5) / 16))
    np.savez(tmp_path / "codes.npz", codes=codes)
    (tmp_path / "sensor.toml").write_text(
        """
taps = 4
[silicon]
radiance_unit = 1e-3
read_noise_e = 5.0

[[frames]]
modulation_frequency = 20e6
exposure = 1e-3
heterodyne_hz = 500.0
light_code = { table = "codes.npz", row = 0 }
sensor_code = { table = "codes.npz", row = 0 }

[[frames]]
modulation_frequency = 20e6
exposure = 1e-3
exposure_start = 1e-3
phase = 0.5
"""
    )
    out = tmp_path / "out"
    proc = _run("render", "cornell-box", "--resolution", "8", "--spp", "2", "--max-depth", "2", "--quiet", "--sensor", "sensor.toml", "-o", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert np.load(out / "raw_electrons.npy").shape == (2, 4, 8, 8)
    frames = json.loads((out / "metadata.json").read_text())["sensor"]["frames"]
    assert frames[0]["light_code"] == {"samples": codes[0].tolist()} and frames[0]["heterodyne_hz"] == pytest.approx(500.0)
    assert frames[1]["exposure_start"] == 1e-3


@pytest.mark.parametrize(
    "toml,args,message",
    [
        (None, ["--sensor", "nosuch"], "error: --sensor 'nosuch': neither a preset (mlx75027, opt8241, imx556, kinect-v2, dtof-prototype) nor a .toml file"),
        (None, ["--sensor", "mlx75027", "--camera", "h=1"], "error: --camera and --sensor exclude each other"),
        ('preset = "mlx75027"\n[[frames]]\nmodulation_frequency = 30e6\nexposure = 1.5e-3\nheterodyne_hz = 667.0\nwaveform = "rectangular"\n',
         ["--sensor", "s.toml"], "error: s.toml: MLX75027 cannot capture this schedule: frame 0: heterodyne offset 667 Hz"),
        ('taps = 2\n[[frames]]\nfrequency = 30e6\n', ["--sensor", "s.toml"], "error: s.toml: unknown key frame 0 'frequency'"),
        # every unknown key at once (only the first was named)
        ('taps = 2\n[silicon]\nread_noise = 3\n[[frames]]\nmodulation_frequency = 30e6\nphse = 1\n', ["--sensor", "s.toml"],
         "error: s.toml: unknown keys [silicon] 'read_noise' (did you mean 'read_noise_e'?), frame 0 'phse' (did you mean 'phase'?)"),
        ('preset = "opt8241"\n[silicon]\nf_number = -1.0\n', ["--sensor", "s.toml"], "error: s.toml: Silicon: 'f_number' must be > 0, got -1.0"),
        ('taps = 2\n', ["--sensor", "s.toml"], "error: s.toml: a sensor without a preset needs [[frames]]"),
        ('taps = [', ["--sensor", "s.toml"], "error: s.toml: not valid TOML"),
        (None, ["--sensor", "missing.toml"], "error: sensor file 'missing.toml' not found"),
        ('taps = 2\n[[frames]]\nmodulation_frequency = 30e6\nlight_code = { table = "nosuch.npz", row = 0 }\nsensor_code = [1, 1, 1, 1, 0, 0, 0, 0]\n',
         ["--sensor", "s.toml"], "error: s.toml: frame 0: light_code: code table 'nosuch.npz' not found"),
        ('preset = "mlx75027"\nlight_bandwidth = -1.0\n', ["--sensor", "s.toml"], "error: s.toml: light_bandwidth: frame 0: "),
    ],
)
def test_bad_sensors_are_one_error_line(tmp_path, toml, args, message):
    if toml is not None:
        (tmp_path / "s.toml").write_text(toml)
    proc = _run("render", "cornell-box", "--resolution", "8", "--spp", "2", "-o", str(tmp_path / "out"), *args, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), proc.stderr
    assert not (tmp_path / "out").exists()


def test_reconstruct_reads_a_sensor_render(tmp_path):
    """`dopplertof reconstruct` of a --sensor folder uses the frames, not the mean-light cameras."""
    out = tmp_path / "proto"
    assert _run("render", "cornell-box", "--resolution", "8", "--spp", "4", "--max-depth", "2", "--quiet", "--sensor", "dtof-prototype", "-o", str(out)).returncode == 0
    proc = _run("reconstruct", str(out))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"reconstructed velocity (fit) of {out}")
    assert (out / "velocity_reconstructed.exr").exists()


def test_a_suspicious_frame_is_warned_about_once(tmp_path):
    (tmp_path / "s.toml").write_text('taps = 2\n[[frames]]\nmodulation_frequency = 30\n')
    proc = _run("render", "cornell-box", "--resolution", "8", "--spp", "4", "--max-depth", "2", "--quiet", "--sensor", "s.toml", "-o", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines() == ["warning: Camera: modulation_frequency=30 Hz, a wavelength of 9.99e+06 m; the unit is Hz (30 MHz is 30e6)"], proc.stderr


def test_a_sensor_file_gives_every_frame_the_light_bandwidth_and_design_reads_a_preset_out(tmp_path):
    """A preset's rectangular frames have unbounded harmonics, which a response record cannot
    read out: ``design --sensor mlx75027`` says how to band-limit them, and a file with the
    preset and a top-level ``light_bandwidth`` (for every frame that gives none) is read out."""
    from dopplertof.sensors.files import load_sensor

    refused = _run("design", "cornell-box", "--sensor", "mlx75027", "--sweep", "f=20e6:100e6:3", "--resolution", "8", "--spp", "4",
                   "-o", str(tmp_path / "refused"), cwd=tmp_path)
    assert refused.returncode == 2 and "`light_bandwidth = …` at the top of its file" in refused.stderr, refused.stderr
    (tmp_path / "s.toml").write_text('preset = "mlx75027"\nlight_bandwidth = 300e6\n')
    (tmp_path / "own.toml").write_text('taps = 2\nlight_bandwidth = 300e6\n[[frames]]\nwaveform = "rectangular"\nlight_bandwidth = 200e6\n'
                                       '[[frames]]\nwaveform = "rectangular"\nphase = 3.141592653589793\n')
    assert {f.light_bandwidth for f in load_sensor(str(tmp_path / "s.toml")).frames} == {300e6}
    assert [f.light_bandwidth for f in load_sensor(str(tmp_path / "own.toml")).frames] == [200e6, 300e6]  # a frame's own stays
    designed = _run("design", "cornell-box", "--sensor", "s.toml", "--sweep", "f=20e6:100e6:3", "--resolution", "8", "--spp", "4",
                    "--quiet", "-o", str(tmp_path / "design"), cwd=tmp_path)
    assert designed.returncode == 0, designed.stderr
    assert (tmp_path / "design" / "best_sensor.toml").is_file()
