"""Velocity reconstructed from rendered Cornell-box measurements, and `dopplertof reconstruct`.

The reconstruction model assumes one path per pixel. With the Cornell box's full global
illumination (max_depth 4) the multipath makes the boxes read high by a few per cent
(measured at 32 px, 16k spp: +4.5 % on the short box, +2.8 % on the tall one): physics,
not an error, and too close to the 5 % bound to test the pipeline with. One indirect
bounce (max_depth 3) keeps indirect light on the static walls, so "zero within noise"
means something there, and leaves about +1 % on the boxes.

Both estimators are tested: the per-pixel fit (the default for sinusoids), which fits the
boxes' change of brightness during the exposure, and the homodyne/heterodyne ratio, blind
to it to first order with ψ = 0 and 90°; they agree closely here.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import cli, io, render_folder
from dopplertof.folder import write_result
from dopplertof.modulation import SPEED_OF_LIGHT_M_S

CAMERAS = [dt.Camera(heterodyne=h, phase=psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2)]
MOVING_M_S = 5.0  # the boxes move at 10 m/s; the top faces (motion in their plane) read 0


@pytest.fixture(scope="module")
def rendered():
    scene = dt.scenes.cornell_box(resolution=32)
    return dt.render(scene, cameras=CAMERAS, spp=4096, seed=7, max_depth=3,
                     time_sampling="antithetic", correlation="replay")


@pytest.fixture(scope="module", params=["ratio", "fit"])
def cornell(rendered, request):
    """The render and its reconstruction by each method."""
    reconstruction = render_folder.reconstruct(rendered.measurements, CAMERAS, request.param)
    assert reconstruction.method == request.param
    return rendered, reconstruction


def interior(mask):
    """Pixels whose 3x3 neighbourhood is inside ``mask``: no silhouette, no mixed pixel."""
    padded = np.pad(mask, 1, constant_values=False)
    h, w = mask.shape
    return np.logical_and.reduce([padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                                  for dy in (-1, 0, 1) for dx in (-1, 0, 1)])


def interior_of_each_object(instance_id):
    """Pixels whose 3x3 neighbourhood sees the same object (instance id): no silhouette."""
    return np.logical_or.reduce([interior(instance_id == i) for i in np.unique(instance_id)])


def velocity_stderr_bound(result):
    """Upper bound of the standard error of the reconstructed velocity (m/s), static pixels.

    Near zero velocity the estimate is linear in the heterodyne images E_i:
    v ≈ c/(2 f_g T) · Σ E_i H_i / Σ H_i² (the homodyne noise enters multiplied by v ≈ 0).
    E_0 and E_90 come from the same paths, so their errors are correlated in an unknown
    way; the triangle inequality bounds the combined error whatever the correlation.
    """
    h0, h90, _, _ = result.measurements.astype(np.float64)
    s_e0, s_e90 = result.measurement_stderr[2:].astype(np.float64)
    cam = CAMERAS[0]
    scale = SPEED_OF_LIGHT_M_S / (2 * cam.modulation_frequency * cam.exposure)
    return scale * (np.abs(h0) * s_e0 + np.abs(h90) * s_e90) / (h0**2 + h90**2)


@pytest.mark.parametrize("box, sign", [("short box, approaching", -1), ("tall box, receding", +1)])
def test_box_velocity_within_five_percent(cornell, box, sign):
    result, rec = cornell
    truth = result.velocity
    pixels = interior((np.sign(truth) == sign) & (np.abs(truth) > MOVING_M_S) & (result.coverage == 1))
    assert pixels.sum() >= 40, f"{box}: only {pixels.sum()} interior pixels"
    assert rec.valid[pixels].mean() > 0.95
    ratio = rec.velocity[pixels] / truth[pixels]
    assert np.nanmedian(ratio) == pytest.approx(1.0, abs=0.05), box


def test_static_surfaces_are_zero_within_noise(cornell):
    result, rec = cornell
    static = interior((result.velocity == 0) & (result.coverage == 1))
    assert static.sum() > 300
    assert rec.valid[static].mean() > 0.95
    # Where no path reaches a moving box, E is exactly 0: the ratio returns 0, the fit ~1e-14 m/s.
    sigma = np.maximum(velocity_stderr_bound(result)[static], 1e-9)
    z = rec.velocity[static] / sigma
    # Gaussian noise with a true (not over-) estimated sigma: median |z| = 0.67 and
    # P(|z| > 4) = 6e-5; a sample stderr from heavy-tailed path noise is sometimes low,
    # hence the margin.
    assert np.nanmedian(np.abs(z)) < 1.0
    assert np.nanmean(np.abs(z) > 4.0) < 0.01
    # and the walls carry no velocity in the mean: |mean v| within 4 standard errors
    assert abs(np.nanmean(rec.velocity[static])) < 4 * np.sqrt(np.nansum(sigma**2)) / static.sum()


# ------------------------------------------------------------------ dopplertof reconstruct


def run_reconstruct(*args):
    result = CliRunner().invoke(cli.main, ["reconstruct", *map(str, args)])
    return result.exit_code, result.output


def test_reconstruct_command_writes_the_maps(rendered, tmp_path):
    result = rendered
    rec = render_folder.reconstruct(result.measurements, CAMERAS)
    assert rec.method == "fit"  # the default for sinusoids
    write_result(result, tmp_path)
    code, output = run_reconstruct(tmp_path)
    assert code == 0, output
    for name in ("velocity_reconstructed.exr", "velocity_reconstructed.png", "velocity_valid.png",
                 "velocity_comparison.png", "depth_reconstructed.exr", "velocity_error.json"):
        assert (tmp_path / name).is_file(), name
    written = io.read_exr(tmp_path / "velocity_reconstructed.exr")
    # float32 EXR measurements in, the same estimate out where the folder's errors keep it valid
    shown = np.isfinite(written)
    assert rec.valid[shown].all()
    np.testing.assert_allclose(written[shown], rec.velocity[shown], rtol=1e-3, atol=1e-3)
    error = json.loads((tmp_path / "velocity_error.json").read_text())
    # with one indirect bounce the dim walls' velocity errors exceed the 1.4 m/s threshold
    assert error["valid_fraction"] > 0.5
    assert error["median_abs_error_m_s"] < 0.5


def write_folder(rendered, folder, cameras):
    """A render folder of the Cornell box whose metadata lists ``cameras``."""
    write_result(rendered, folder)
    meta = json.loads((folder / "metadata.json").read_text())
    meta["cameras"] = cameras
    (folder / "metadata.json").write_text(json.dumps(meta))


@pytest.mark.parametrize("change, message", [
    (lambda cams: [{**c, "modulation_frequency": 20e6 if i else 30e6} for i, c in enumerate(cams)],
     "modulation_frequency"),
    (lambda cams: [{**c, "heterodyne": 1.0} for c in cams[:1]], "same heterodyne ratio"),
    (lambda cams: [], "no D-ToF camera"),
    (lambda cams: [{**c, "phase": "ninety"} for c in cams], "'phase' must be a finite number"),
], ids=["two frequencies", "one heterodyne", "no camera", "bad phase"])
def test_reconstruct_command_refuses_a_bad_camera_set(rendered, tmp_path, change, message):
    cameras = [dict(vars(c)) for c in CAMERAS]
    write_folder(rendered, tmp_path, change(cameras))
    code, output = run_reconstruct(tmp_path)
    assert code == 2
    lines = output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], output
    assert not (tmp_path / "velocity_reconstructed.exr").exists()


def test_homodyne_cameras_give_the_depth_alone(rendered, tmp_path):
    """Homodyne cameras (an AMCW sensor's frames) were refused ("same heterodyne ratio"),
    though their depth is determined and the docs said it is written."""
    write_folder(rendered, tmp_path, [dict(vars(c)) for c in CAMERAS[:2]])
    code, output = run_reconstruct(tmp_path)
    assert code == 0 and output.startswith(f"reconstructed the depth of {tmp_path} (modulo 4.997 m) and no velocity: "), output
    assert "heterodyne" in output.splitlines()[0]
    depth = io.read_exr(tmp_path / "depth_reconstructed.exr")
    truth = dt.reconstruct.depth(rendered.measurements[:2], CAMERAS[:2])
    np.testing.assert_allclose(depth[np.isfinite(depth)], truth[np.isfinite(depth)], rtol=1e-4, atol=1e-4)
    assert json.loads((tmp_path / "reconstruction.json").read_text())["method"] == "depth only"
    assert not (tmp_path / "velocity_reconstructed.exr").exists()


def test_reconstruct_command_refuses_a_folder_that_is_not_a_render(rendered, tmp_path):
    code, output = run_reconstruct(tmp_path / "nothing")
    assert code == 2 and output.strip() == f"error: {tmp_path / 'nothing'}: no such folder"
    code, output = run_reconstruct(tmp_path)
    assert code == 2 and "not a 'dopplertof render' output folder" in output
    write_result(rendered, tmp_path)
    (image,) = [p for p in tmp_path.glob("measurement_3_*.exr") if not p.name.endswith("_stderr.exr")]
    image.unlink()
    code, output = run_reconstruct(tmp_path)
    assert code == 2 and output.strip().splitlines() == [
        f"error: {tmp_path}: no measurement file for camera 3 (measurement_3_h*.exr)"]


def test_reconstruct_command_refuses_a_folder_that_lost_part_of_its_errors(rendered, tmp_path):
    """With one camera's standard error (and the covariance) gone it judged validity from
    the signal alone: every pixel valid, RMSE 27 m/s."""
    write_result(rendered, tmp_path)
    (stderr,) = tmp_path.glob("measurement_2_*_stderr.exr")
    stderr.unlink()
    code, output = run_reconstruct(tmp_path)
    assert code == 2 and output.strip().splitlines() == [
        f"error: {tmp_path}: {stderr.name} missing (the render wrote it: the standard errors judge which pixels are valid); restore it or render again"]
    assert not (tmp_path / "velocity_reconstructed.exr").exists()


def test_reconstruct_refuses_a_measurement_changed_after_the_render(rendered, tmp_path):
    """Random bytes in a measurement's EXR (its size kept) were read as measurements: values
    up to 1.8e38 and velocities off by 0.22 m/s, exit 0."""
    write_result(rendered, tmp_path)
    (measurement,) = tmp_path.glob("measurement_0_*[0-9]deg.exr")
    data = bytearray(measurement.read_bytes())
    data[400:430] = bytes(range(30))
    measurement.write_bytes(bytes(data))
    code, output = run_reconstruct(tmp_path)
    assert code == 2 and output.strip().splitlines() == [
        f"error: {tmp_path}: {measurement.name} changed since the render wrote it (SHA-256 in metadata.json); render again, or restore it"]


# ------------------------------------------------------------------ calibrated validity


def off_by_three_sigma(rec, truth, region=True):
    """Fraction of the valid pixels (with ground truth, in ``region``) whose error exceeds 3
    stated errors, and the median |z| on the moving ones (z = error / stated error)."""
    valid = rec.valid & np.isfinite(truth) & region
    z = (rec.velocity[valid] - truth[valid]) / rec.velocity_stderr[valid]
    moving = np.abs(truth[valid]) > 1.0
    return float(np.mean(np.abs(z) > 3.0)), float(np.median(np.abs(z[moving])))


@pytest.mark.parametrize("method", ["ratio", "fit"])
def test_validity_is_calibrated_on_the_moving_plane(method):
    """Direct light on the receding plane, where the one-path model is exact (the oracle of
    dopplertof.oracles): among valid pixels, at most 2 % are off by more than three stated
    standard errors, and the stated errors are not inflated (median |z| near 0.67)."""
    from dopplertof.oracles import moving_plane_scene

    result = dt.render(moving_plane_scene(10.0, resolution=32), CAMERAS, spp=512, max_depth=2, seed=3)
    rec = dt.reconstruct.velocity(result, method=method)
    assert rec.valid.mean() > 0.9
    assert rec.max_velocity_stderr_m_s == pytest.approx(0.1 * np.percentile(np.abs(result.velocity), 90), rel=0.05)
    fraction, median_z = off_by_three_sigma(rec, result.velocity)
    assert fraction <= 0.02, fraction
    assert 0.4 < median_z < 1.0, median_z


@pytest.fixture(scope="module")
def direct():
    """The Cornell box with direct light only (max_depth 2): the model is exact away from
    silhouettes."""
    return dt.render(dt.scenes.cornell_box(resolution=64), cameras=CAMERAS, spp=256, seed=5, max_depth=2)


@pytest.mark.parametrize("method", ["ratio", "fit"])
def test_validity_is_calibrated_on_the_cornell_box_with_direct_light(direct, method):
    rec = dt.reconstruct.velocity(direct, method=method)
    truth = direct.velocity
    # the default threshold: a tenth of the boxes' 10 m/s (their faces read 10 to 15 m/s)
    assert rec.max_velocity_stderr_m_s == pytest.approx(1.35, rel=0.15)
    assert "speed scale" in rec.threshold_reason
    assert rec.valid[np.isfinite(truth)].mean() > 0.9
    fraction, median_z = off_by_three_sigma(rec, truth)
    assert fraction <= 0.02, fraction
    assert 0.3 < median_z < 1.0, median_z
    # a larger threshold admits noisier pixels, a smaller one fewer: it is honoured
    strict = dt.reconstruct.velocity(direct, method=method, max_velocity_stderr=0.05)
    assert strict.max_velocity_stderr_m_s == 0.05 and strict.threshold_reason == "given"
    assert np.nanmax(strict.velocity_stderr) <= 0.05 and strict.valid.sum() < rec.valid.sum()


@pytest.mark.parametrize("settings, dof", [
    ({"spp": 64}, 16),  # antithetic, stratified: one per stratum of two groups of two times
    ({"spp": 32}, 8),
    ({"spp": 64, "time_sampling": "uniform", "correlation": "none"}, 15),  # 16 replicates
    ({"spp": 64, "time_sampling": "uniform", "correlation": "none", "replicates": 4}, 3),
])
def test_a_render_says_how_many_degrees_of_freedom_its_errors_have(settings, dof):
    result = dt.render(dt.scenes.cornell_box(resolution=8), cameras=CAMERAS, max_depth=2, **settings)
    assert result.info["stderr_dof"] == dof


def test_errors_from_too_few_degrees_of_freedom_make_no_pixel_valid(tmp_path):
    """On the Cornell box's moving faces (direct light) a quarter of the pixels a threshold
    kept were off by more than three standard errors at 16 spp (4 degrees of freedom): the
    pixels whose error came out small by chance. Now none is valid there, with the reason;
    at 64 spp (16) they are, and calibrated."""
    scene = dt.scenes.cornell_box(resolution=32)
    few = dt.render(scene, cameras=CAMERAS, spp=16, seed=1, max_depth=2)
    assert few.info["stderr_dof"] == 4
    rec = dt.reconstruct.velocity(few)
    assert rec.stderr_dof == 4 and not rec.valid.any() and np.isnan(rec.velocity).all()
    arrays = dt.reconstruct.velocity(few.measurements, CAMERAS, measurement_covariance=few.measurement_covariance, stderr_dof=4)
    assert not arrays.valid.any()
    write_result(few, tmp_path)
    code, out, err = run_cli("reconstruct", tmp_path)
    assert code == 0, err
    assert "no pixel can be valid: its standard errors come from 4 degrees of freedom, and a valid pixel needs 15" in out.splitlines()[0]
    assert json.loads((tmp_path / "reconstruction.json").read_text())["stderr_dof"] == 4
    enough = dt.render(scene, cameras=CAMERAS, spp=64, seed=1, max_depth=2)
    rec = dt.reconstruct.velocity(enough)
    moving = rec.valid & (np.abs(np.nan_to_num(enough.velocity)) > MOVING_M_S)
    assert moving.sum() > 50
    z = (rec.velocity - enough.velocity)[moving] / rec.velocity_stderr[moving]
    assert np.mean(np.abs(z) > 3) < 0.08  # edges included


def test_a_stratified_render_stopped_early_says_its_errors_are_incomplete():
    """Stopped before its last stratum, a render's errors leave out the spread between the
    strata it did not draw: on the moving plane at 128 of 256 spp the h = 1 errors were
    100-145x too small, and a reconstruction marked 93 % of the pixels valid."""
    from dopplertof.oracles import moving_plane_scene

    scene = moving_plane_scene(10.0, resolution=16)
    calls = iter(range(100))
    partial = dt.render(scene, CAMERAS, spp=256, max_depth=2, seed=1, lanes_per_pass=16 * 256 * 4, stop=lambda: next(calls) >= 2)
    assert partial.interrupted and partial.spp == 128 and partial.info["stderr_dof"] == 0
    reference = dt.render(scene, CAMERAS, spp=4096, max_depth=2, seed=99)
    z = (partial.measurements - reference.measurements) / np.hypot(partial.measurement_stderr, reference.measurement_stderr)
    assert np.nanstd(z[2:]) > 20  # what the stated error leaves out
    assert not dt.reconstruct.velocity(partial).valid.any()
    whole = dt.render(scene, CAMERAS, spp=256, max_depth=2, seed=1, lanes_per_pass=16 * 256 * 4)
    assert whole.info["stderr_dof"] == 64 and dt.reconstruct.velocity(whole).valid.mean() > 0.9


def run_cli(*args):
    """``dopplertof`` in a real subprocess: (exit status, stdout, stderr)."""
    done = subprocess.run([sys.executable, "-m", "dopplertof.cli", *map(str, args)], capture_output=True, text=True)
    return done.returncode, done.stdout, done.stderr


def test_reconstruct_command_refuses_the_three_camera_set(rendered, tmp_path):
    """h=0 at 0°, h=1 at 0° and 90° cannot tell the boxes' brightening from a Doppler shift:
    refused, naming the camera to add."""
    three = [dict(vars(c)) for c in CAMERAS if not (c.heterodyne == 0 and c.phase)]
    write_folder(rendered, tmp_path, three)
    code, out, err = run_cli("reconstruct", tmp_path)
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: the cameras h=0,psi=0, h=1,psi=0, h=1,psi=90deg cannot determine velocity")
    assert lines[0].endswith("add h=0,psi=90deg"), lines[0]
    assert not (tmp_path / "velocity_reconstructed.exr").exists()


def test_reconstruct_command_states_threshold_error_model_and_depth_range(direct, tmp_path):
    write_result(direct, tmp_path)
    code, out, err = run_cli("reconstruct", tmp_path, "--max-velocity-stderr", "0.5m/s")
    assert code == 0, err
    head = out.splitlines()[0]
    assert "standard error ≤ 0.5 m/s (given)" in head and "multipath bias" in head
    assert "depth modulo 4.997 m" in head and "wrapped on 100.0%" in head  # the box is 5.8 to 7.8 m away
    info = json.loads((tmp_path / "reconstruction.json").read_text())
    assert info["max_velocity_stderr_m_s"] == 0.5
    assert info["depth_range_m"] == pytest.approx(SPEED_OF_LIGHT_M_S / (2 * CAMERAS[0].modulation_frequency))
    assert info["depth_wrapped_fraction"] == 1.0 and (tmp_path / "depth_wrapped.png").is_file()
    # the depth read is the true distance minus the range
    depth = io.read_exr(tmp_path / "depth_reconstructed.exr")
    seen = np.isfinite(depth) & (direct.coverage == 1)
    assert np.median(np.abs(direct.depth[seen] - depth[seen] - info["depth_range_m"])) < 0.01
    error = json.loads((tmp_path / "velocity_error.json").read_text())
    assert error["off_by_3_stderr_fraction"] <= 0.02
    # over the moving pixels alone (static walls read exactly 0 and dilute the first): the boxes' outlines count
    assert error["off_by_3_stderr_fraction"] < error["off_by_3_stderr_fraction_moving"] < 0.1
    assert f"({100 * error['off_by_3_stderr_fraction_moving']:.1f}% of those that move)" in head
    for bad in ("-1", "fast", "0m/s", "nan"):
        code, out, err = run_cli("reconstruct", tmp_path, "--max-velocity-stderr", bad)
        assert code == 2 and err.strip().splitlines() == [
            f"error: --max-velocity-stderr must be a speed > 0 in m/s (e.g. 0.5 or 0.5m/s), got '{bad}'"]


def test_depth_wrapped_marks_true_distances_beyond_the_range():
    truth = np.array([[np.nan, 0.5, 4.99], [5.0, 7.2, 12.0]])
    np.testing.assert_array_equal(render_folder.depth_wrapped(truth, 5.0), [[False, False, False], [True, True, True]])


def test_two_frequencies_unwrap_the_cornell_box_depth(tmp_path):
    """At 30 MHz alone the box (5.8 to 7.8 m away) reads 5 m short; with 20 MHz beside it the
    depth is known modulo c/(2 × 10 MHz) = 15 m: none wrapped, and the true distance."""
    cameras = CAMERAS + [dt.Camera(modulation_frequency=20e6, heterodyne=c.heterodyne, phase=c.phase) for c in CAMERAS]
    result = dt.render(dt.scenes.cornell_box(resolution=32), cameras=cameras, spp=256, seed=2, max_depth=2)
    write_result(result, tmp_path)
    code, out, err = run_cli("reconstruct", tmp_path)
    assert code == 0, err
    assert "depth modulo 14.99 m (c/(2 |f_1 − f_2|), two frequencies), wrapped on 0.0%" in out.splitlines()[0]
    depth = io.read_exr(tmp_path / "depth_reconstructed.exr")
    seen = np.isfinite(depth) & (result.coverage == 1)
    assert seen.mean() > 0.8
    assert np.median(np.abs(depth[seen] - result.depth[seen])) < 0.01
    rec = dt.reconstruct.velocity(result)
    assert rec.frequencies_hz == (30e6, 20e6)
    # away from silhouettes, where a pixel sees one surface and the one-path model holds
    # (on them the blend of a moving and a static surface is biased beyond the error: 2-3 %
    # of all valid pixels off by 3 errors at this size)
    fraction, _ = off_by_three_sigma(rec, result.velocity, region=interior_of_each_object(result.instance_id))
    assert fraction <= 0.02


def test_a_sensor_render_reconstructs_from_its_frames_cameras():
    """dt.reconstruct.velocity(result) of a render with sensor= raised "g1 must be > 0": the
    cameras that measure the windows' mean light (g1 = 0) went into the estimator. It now
    takes the frames' cameras, as `dopplertof reconstruct` of such a folder does."""
    sensor = dt.sensors.preset("dtof-prototype")
    result = dt.render(dt.scenes.cornell_box(resolution=12), sensor=sensor, spp=64, seed=2)
    assert len(result.cameras) > sensor.frame_cameras
    frames = slice(0, sensor.frame_cameras)
    direct = dt.reconstruct.velocity(result.measurements[frames], result.cameras[frames],
                                     measurement_covariance=result.maps["measurement_covariance"][frames, frames],
                                     stderr_dof=result.info["stderr_dof"])
    from_result = dt.reconstruct.velocity(result)
    np.testing.assert_array_equal(from_result.velocity, direct.velocity)
    np.testing.assert_array_equal(from_result.valid, direct.valid)


MOVING_LIGHT_SCENE = """<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  <emitter type="point" id="lamp"><rgb name="intensity" value="20"/>
    <animation name="to_world"><transform time="0"><translate z="4"/></transform><transform time="0.0015"><translate z="3.985"/></transform></animation>
  </emitter>
  <shape type="rectangle"><bsdf type="diffuse"/><transform name="to_world"><scale value="10"/></transform></shape>
</scene>"""


def test_a_comparison_with_the_ground_truth_where_lights_move_says_it_is_no_error(tmp_path):
    """A static camera and wall lit by a light approaching at 10 m/s: the reconstruction is
    right (dL/dt/2 = -5 cos θ m/s) and the ground truth 0 (the camera rays' hits do not
    move), and `reconstruct` reported a 5 m/s error with every valid pixel off by > 3
    standard errors."""
    (tmp_path / "lamp.xml").write_text(MOVING_LIGHT_SCENE)
    cameras = [a for c in ("h=0,psi=0", "h=0,psi=90deg", "h=1,psi=0", "h=1,psi=90deg") for a in ("--camera", c)]
    out = tmp_path / "r"
    run = CliRunner().invoke(cli.main, ["render", str(tmp_path / "lamp.xml"), "--spp", "64", "--quiet", *cameras, "-o", str(out)])
    assert run.exit_code == 0, run.output
    assert json.loads((out / "metadata.json").read_text())["render"]["light_sources_in_motion"] == [f"{tmp_path / 'lamp.xml'}: <emitter type=\"point\" id='lamp'> #1"]
    done = CliRunner().invoke(cli.main, ["reconstruct", str(out)])
    assert done.exit_code == 0, done.output
    assert "(not an error: the ground truth is the motion of the camera rays' hits, and light sources move here" in done.output
    error = json.loads((out / "velocity_error.json").read_text())
    assert "light sources move here" in error["note"]
    reconstructed = io.read_exr(out / "velocity_reconstructed.exr")
    assert np.nanmedian(reconstructed) == pytest.approx(-5.0, abs=0.5)  # -5 cos θ, θ small


def test_depth_takes_a_render_result_as_velocity_does(rendered):
    """``rc.depth(result)`` reads the result's measurements and cameras, as
    ``rc.velocity(result)`` does: the same depth as given them apart; bare measurements
    without cameras are refused naming the function."""
    np.testing.assert_array_equal(dt.reconstruct.depth(rendered), dt.reconstruct.depth(rendered.measurements, rendered.cameras))
    with pytest.raises(ValueError, match=r"depth\(\) needs the cameras \(or a RenderResult\)"):
        dt.reconstruct.depth(rendered.measurements)
    with pytest.raises(ValueError, match=r"velocity\(\) needs the cameras \(or a RenderResult\)"):
        dt.reconstruct.velocity(rendered.measurements)
