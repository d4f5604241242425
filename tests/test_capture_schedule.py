"""Capture schedules: cameras with exposure windows of their own (``Camera.exposure_start``)."""

import dataclasses
import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import reconstruct as rc
from dopplertof.modulation import parse_camera
from dopplertof.oracles import PLANE_EXPOSURE_S, moving_plane_measurement_mean, moving_plane_scene
from dopplertof.tracing.lanes import window_seed

T = PLANE_EXPOSURE_S


def _sequential(cameras, exposure=T):
    """The cameras one after another: camera i's window opens at i·T."""
    return [dataclasses.replace(c, exposure_start=i * exposure) for i, c in enumerate(cameras)]


def _image_mean_and_error(result, i):
    """Image mean of camera i's measurement and its standard error (pixels independent)."""
    image = result.measurements[i].astype(np.float64)
    error = math.sqrt(float((result.measurement_stderr[i].astype(np.float64) ** 2).sum())) / image.size
    return float(image.mean()), error


# ------------------------------------------------------------------------------ closed form


def test_four_sequential_phase_windows_match_the_closed_form_per_window():
    """Four homodyne phase images captured one after another (AMCW) of a plane receding at
    50 m/s: each matches the closed form of the plane during its own window. The plane
    moves 7.5 cm between windows (0.09 rad of phase, ≈ 9 % of the signal), so the closed
    form of the first window misses windows 2-4 by far more than the tolerance."""
    speed = 50.0
    cameras = _sequential([dt.Camera(heterodyne=0.0, phase=psi) for psi in np.arange(4) * math.pi / 2])
    scene = moving_plane_scene(speed, resolution=8, duration=4 * T)
    result = dt.render(scene, cameras=cameras, spp=512, max_depth=2, seed=4)
    assert result.info["windows"] == [[i * T, T] for i in range(4)]
    assert [c.exposure_start for c in result.cameras] == [i * T for i in range(4)]
    scale = moving_plane_measurement_mean(dt.Camera(heterodyne=0.0), speed)  # the signal's size
    for i, cam in enumerate(cameras):
        got, error = _image_mean_and_error(result, i)
        expected = moving_plane_measurement_mean(cam, speed)
        tolerance = 4.0 * error + 1e-3 * abs(scale)
        assert abs(got - expected) < tolerance, f"window {i}: {got} vs {expected} (± {tolerance})"
        if i > 0:  # the test tells the windows apart
            first_window = moving_plane_measurement_mean(dataclasses.replace(cam, exposure_start=0.0), speed)
            assert abs(first_window - expected) > 10 * tolerance, f"window {i}"


def test_velocity_is_reconstructed_from_a_sequential_schedule():
    """h ∈ {0, 1} × ψ ∈ {0, 90°} in four windows one after another: the reconstruction
    models the plane's motion between the windows and finds its velocity; taking the
    windows as one (the same cameras without their starts) does not."""
    speed = 50.0
    cameras = _sequential([dt.Camera(heterodyne=h, phase=psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2)])
    result = dt.render(moving_plane_scene(speed, resolution=8, duration=4 * T), cameras=cameras, spp=256, max_depth=2, seed=2)
    truth = float(np.nanmean(result.velocity))
    scheduled = rc.velocity(result)
    assert scheduled.method == "fit" and scheduled.valid.all()
    assert float(np.mean(scheduled.velocity)) == pytest.approx(truth, rel=0.02)
    unaware = [dataclasses.replace(c, exposure_start=None) for c in cameras]
    ignored = rc.velocity(result.measurements, unaware)
    assert abs(float(np.nanmean(ignored.velocity)) - truth) > 0.05 * truth


def test_schedule_model_inverts_exactly():
    """model_measurements and velocity agree for schedules (no rendering): every speed of
    the fit's range, homodyne/heterodyne pairs and the Hu et al. scheme, in any order."""
    speeds = np.linspace(-1600.0, 1600.0, 81)
    depths = np.linspace(1.0, 4.5, 81)  # inside the ambiguity range c/(2 f_g) = 5.0 m
    pairs = [dt.Camera(heterodyne=h, phase=psi) for psi in (0.0, math.pi / 2) for h in (0.0, 1.0)]
    hu = [dt.Camera(heterodyne=h, phase=psi) for h, psi in zip((0.5, 0.5, -0.5, -0.5), np.array([3, 0, 1, 2]) * math.pi / 2)]
    for cameras in (_sequential(pairs), _sequential(pairs[::-1]), _sequential(hu)):
        m = rc.model_measurements(1.0, depths, speeds, cameras)
        got = rc.velocity(m, cameras)
        np.testing.assert_allclose(got.velocity, speeds, atol=1e-6)
        np.testing.assert_allclose(got.depth, depths, atol=1e-9)
    # cameras of one window: the ratio on request; a pair split over two windows cannot be
    shared = [dataclasses.replace(c, exposure_start=0.0) for c in pairs]
    assert rc.velocity(rc.model_measurements(1.0, 2.0, 30.0, shared)[:, None], shared, method="ratio").method == "ratio"
    with pytest.raises(ValueError, match="same phase and exposure window"):
        rc.velocity(rc.model_measurements(1.0, 2.0, 30.0, _sequential(pairs))[:, None], _sequential(pairs), method="ratio")


# ------------------------------------------------------------------------------ plumbing


@pytest.fixture(scope="module")
def cornell():
    return dt.scenes.cornell_box(resolution=8)


def test_a_single_window_renders_as_without_a_schedule(cornell):
    """Cameras that give the render's own window explicitly are one window: bit-identical."""
    cameras = [dt.Camera(heterodyne=h, phase=psi) for h in (0.0, 1.0) for psi in (0.0, 1.0)]
    plain = dt.render(cornell, cameras=cameras, spp=16, max_depth=3, seed=5, exposure_start=2e-4)
    explicit = dt.render(cornell, cameras=[dataclasses.replace(c, exposure_start=2e-4) for c in cameras], spp=16, max_depth=3, seed=5, exposure_start=2e-4)
    assert plain.maps.keys() == explicit.maps.keys()
    for name in plain.maps:
        np.testing.assert_array_equal(plain.maps[name], explicit.maps[name], err_msg=name)
    assert plain.info["windows"] == [[2e-4, T]] and all(c.exposure_start == 2e-4 for c in plain.cameras)


def test_windows_share_paths_within_and_are_independent_between(cornell):
    """Window 0 (cameras 0 and 2) is the render of its cameras alone, intensity and ground
    truth included; window 1 (camera 1) is a render of its window with its own seed; the
    covariance is that of each window, 0 between them."""
    cameras = [dt.Camera(heterodyne=0.0), dt.Camera(heterodyne=1.0, exposure_start=T), dt.Camera(heterodyne=1.0, phase=1.0)]
    common = dict(spp=16, max_depth=3)
    both = dt.render(cornell, cameras=cameras, seed=3, **common)
    first = dt.render(cornell, cameras=[cameras[0], cameras[2]], seed=3, **common)
    second = dt.render(cornell, cameras=[dt.Camera(heterodyne=1.0)], exposure_start=T, seed=window_seed(3, 1), **common)
    np.testing.assert_array_equal(both.measurements[[0, 2]], first.measurements)
    np.testing.assert_array_equal(both.measurement_stderr[[0, 2]], first.measurement_stderr)
    np.testing.assert_array_equal(both.measurements[1], second.measurements[0])
    for name in ("intensity", "stderr", "depth", "velocity", "coverage", "instance_id"):
        np.testing.assert_array_equal(both.maps[name], first.maps[name], err_msg=name)
    cov = both.measurement_covariance
    np.testing.assert_array_equal(cov[np.ix_([0, 2], [0, 2])], first.measurement_covariance)
    assert np.abs(cov[0, 2]).max() > 0  # same paths: correlated
    assert not cov[0, 1].any() and not cov[1, 2].any()  # other windows: independent
    np.testing.assert_allclose(cov[1, 1], second.measurement_stderr[0].astype(np.float64) ** 2, rtol=1e-6)


def test_cameras_of_different_exposures_are_windows_of_their_own(cornell):
    cameras = [dt.Camera(exposure=1e-3), dt.Camera(exposure=2e-3)]
    result = dt.render(cornell, cameras=cameras, spp=4, max_depth=2)
    assert result.info["windows"] == [[0.0, 1e-3], [0.0, 2e-3]]


def test_a_schedule_resumes_from_its_checkpoint(cornell, tmp_path):
    """Stopped in the second window (two passes per window), continued: bit-identical."""
    cameras = _sequential([dt.Camera(heterodyne=0.0), dt.Camera(heterodyne=1.0)]) + [dt.Camera(heterodyne=1.0, phase=1.0)]
    common = dict(cameras=cameras, spp=32, max_depth=2, lanes_per_pass=1024, seed=1)
    checkpoint = str(tmp_path / "schedule.npz")
    calls = iter(range(100))
    partial = dt.render(cornell, checkpoint=checkpoint, stop=lambda: next(calls) >= 3, **common)
    assert partial.interrupted and partial.info["passes_done"] == 3 and partial.info["passes"] == 4
    assert partial.info["window_spp"] == [32, 16] and partial.spp == 16  # per window (the command said 0 of a schedule's spp)
    resumed = dt.render(cornell, checkpoint=checkpoint, **common)
    whole = dt.render(cornell, **common)
    for name in whole.maps:
        np.testing.assert_array_equal(resumed.maps[name], whole.maps[name], err_msg=name)


# ------------------------------------------------------------------------------ input


def test_camera_text_takes_a_start():
    assert parse_camera("h=0,psi=90deg,start=1.5e-3").exposure_start == 1.5e-3
    assert parse_camera("h=0,exposure_start=0").exposure_start == 0.0
    assert parse_camera("h=0").exposure_start is None
    assert "start=0.003" in dt.Camera(exposure_start=3e-3).label()


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: parse_camera("h=0,start=soon"), r"start='soon' is not a number"),
        (lambda: parse_camera("h=0,start=1,exposure_start=2"), r"'exposure_start' given twice"),
        (lambda: parse_camera("h=0,start=inf"), r"'exposure_start' must be a finite number"),
        (lambda: dt.Camera(exposure_start="0"), r"'exposure_start' must be a finite number, got '0'"),
        (lambda: dt.RenderSettings(cameras=[dt.Camera(exposure=1e-3), dt.Camera(exposure=2e-3)], exposure=1e-3), r"differs from the cameras' exposure"),
        (lambda: rc.velocity(np.zeros((4, 1)), [dt.Camera(heterodyne=h, exposure_start=s) for h, s in ((0, None), (1, None), (0, T), (1, T))]), r"some cameras give an exposure_start"),
    ],
)
def test_bad_schedules_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_animations_refuse_a_schedule(cornell, tmp_path):
    from dopplertof.animate import render_animation

    settings = dt.RenderSettings(cameras=_sequential([dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, 1.0)]), spp=2)
    with pytest.raises(ValueError, match="animate does not take"):
        render_animation(cornell, str(tmp_path / "clip"), frames=1, settings=settings)
