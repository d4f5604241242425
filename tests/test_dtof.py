"""The D-ToF estimator against closed forms and exact identities."""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof.modulation import SPEED_OF_LIGHT_M_S, WAVEFORMS, lowpass_waveform

FOV_DEG = 30.0
DISTANCE_M = 5.0
RHO = 0.8
INTENSITY = 50.0


def _plane_scene(speed_m_s, exposure=1.5e-3, resolution=16):
    """A large diffuse plane facing a camera at the origin, receding along the axis at ``speed_m_s``;
    a point light at the camera."""
    import mitsuba as mi

    dt.set_variant("llvm_ad_rgb")
    # A flattened cube (a triangle mesh) whose front face is the plane z = -DISTANCE_M.
    # Keys in double precision: a float32 5.5 m translation is quantised to 0.5 µm, which
    # would misstate a 15 µm displacement by up to 1.6 %.
    start = mi.ScalarTransform4d().translate([0, 0, -DISTANCE_M - 0.5]) @ mi.ScalarTransform4d().scale([20, 20, 0.5])
    end = mi.ScalarTransform4d().translate([0, 0, -speed_m_s * exposure]) @ start
    return dt.load_scene(
        {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": FOV_DEG,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
            },
            "light": {"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": [INTENSITY] * 3}},
            "plane": {
                "type": "cube",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [RHO] * 3}},
                "motion": {"type": "keyframes", "keys": [(0.0, start), (exposure, end)]},
            },
        }
    )


def _reference_image_mean(camera, speed_m_s, nodes_xy=48, nodes_t=4096):
    """Exact image mean of the direct-light measurement, by quadrature over the film and time.

    A film point (fx, fy) sees along d ∝ ((2fx−1)τ, (2fy−1)τ, −1), τ = tan(fov/2); the plane
    at distance z(t) = z0 + v t is hit at s = z/|d_z|; the round trip is L = 2s and the
    radiance A = (ρ/π) I |d_z| / s².
    """
    tau = math.tan(math.radians(FOV_DEG) / 2)
    gx, gw = np.polynomial.legendre.leggauss(nodes_xy)
    f = 0.5 * (gx + 1)
    w = 0.5 * gw
    fx, fy = np.meshgrid(f, f, indexing="ij")
    wxy = np.outer(w, w)
    cos = 1.0 / np.sqrt(((2 * fx - 1) * tau) ** 2 + ((2 * fy - 1) * tau) ** 2 + 1.0)
    u = (np.arange(nodes_t) + 0.5) / nodes_t
    z = DISTANCE_M + speed_m_s * camera.exposure * u
    s = z[:, None, None] / cos[None]
    radiance = RHO / math.pi * INTENSITY * cos[None] / s**2
    phase = 2 * math.pi * camera.heterodyne * u[:, None, None] + camera.phase + camera.wavenumber * 2 * s
    integrand = 0.5 * camera.g1 * lowpass_waveform(phase, camera.waveform) * radiance
    return float((integrand.mean(axis=0) * wxy).sum())


CAMERA_GRID = [(h, psi) for h in (0.0, 0.5, 1.0) for psi in (0.0, math.pi / 2)]


@pytest.mark.slow
@pytest.mark.parametrize("waveform", WAVEFORMS)
@pytest.mark.parametrize("speed", [10.0, 1.0, 0.1, 0.01])
def test_moving_plane_matches_closed_form(waveform, speed):
    """Relative error < 0.5 % for every waveform, h ∈ {0, ½, 1}, ψ ∈ {0, π/2}, 10 m/s … 1 cm/s
    (15 µm of travel during the exposure at 1 cm/s)."""
    tolerance = 5e-3
    cameras = [dt.Camera(heterodyne=h, phase=psi, waveform=waveform) for h, psi in CAMERA_GRID]
    result = dt.render(_plane_scene(speed), cameras=cameras, spp=256, max_depth=2, seed=7)
    for cam, image in zip(cameras, result.measurements):
        ref = _reference_image_mean(cam, speed)
        got = float(image.astype(np.float64).mean())
        assert got == pytest.approx(ref, rel=tolerance), f"{waveform} {cam.label()} v={speed}: {got} vs {ref}"


def test_moving_plane_heterodyne_sinusoid_quick():
    """The fast-subset version: sinusoid, h = 1, 1 m/s."""
    cam = dt.Camera(heterodyne=1.0, phase=0.3)
    result = dt.render(_plane_scene(1.0, resolution=8), cameras=[cam], spp=64, max_depth=2, seed=3)
    assert float(result.measurements[0].mean()) == pytest.approx(_reference_image_mean(cam, 1.0), rel=5e-3)


def test_heterodyne_of_static_scene_is_exactly_zero_with_antithetic_replay():
    scene = dt.scenes.cornell_box(resolution=16, displacement=0.0)
    cams = [dt.Camera(heterodyne=1.0, phase=p) for p in (0.0, 1.0)]
    result = dt.render(scene, cameras=cams, spp=32, max_depth=4, time_sampling="antithetic", correlation="replay")
    homodyne_scale = float(np.abs(dt.render(scene, cameras=[dt.Camera(heterodyne=0.0)], spp=8, max_depth=4).measurements).mean())
    assert np.abs(result.measurements).max() < 1e-6 * homodyne_scale * 1e3  # float rounding only
    assert np.abs(result.measurements).max() < 1e-5


@pytest.mark.parametrize("time_sampling,correlation", [("uniform", "none"), ("stratified", "pixel"), ("antithetic", "none"), ("antithetic_mirror", "replay")])
def test_heterodyne_of_static_scene_is_zero_within_noise(time_sampling, correlation):
    scene = dt.scenes.cornell_box(resolution=16, displacement=0.0)
    result = dt.render(scene, cameras=[dt.Camera(heterodyne=1.0)], spp=64, max_depth=3, time_sampling=time_sampling, correlation=correlation, seed=11)
    total = result.measurements[0].astype(np.float64).sum()
    sigma = math.sqrt((result.measurement_stderr[0].astype(np.float64) ** 2).sum())
    assert sigma > 0
    assert abs(total) < 4 * sigma


def test_four_cameras_together_equal_each_alone():
    scene = dt.scenes.cornell_box(resolution=16)
    cams = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    together = dt.render(scene, cameras=cams, spp=16, max_depth=3, seed=5)
    for i, cam in enumerate(cams):
        alone = dt.render(scene, cameras=[cam], spp=16, max_depth=3, seed=5)
        np.testing.assert_allclose(alone.measurements[0], together.measurements[i], rtol=1e-5, atol=1e-9)
        np.testing.assert_allclose(alone.intensity, together.intensity, rtol=1e-6)


def test_analytic_mode_matches_closed_form_where_length_is_linear_in_time():
    """The biased closed-form mode is exact up to its linearisation: a plane receding at
    constant speed has L and (nearly) X linear in time; ψ is included (unlike the original)."""
    cams = [dt.Camera(heterodyne=h, phase=psi) for h, psi in CAMERA_GRID]
    for correlation in ("replay", "reconnection"):
        result = dt.render(_plane_scene(1.0), cameras=cams, spp=16, max_depth=2, seed=1, time_sampling="analytic", correlation=correlation)
        for cam, image in zip(cams, result.measurements):
            assert float(image.astype(np.float64).mean()) == pytest.approx(_reference_image_mean(cam, 1.0), rel=5e-3), cam.label()


def test_analytic_mode_rejects_what_it_cannot_integrate():
    scene = dt.scenes.cornell_box(resolution=8)
    with pytest.raises(ValueError, match="low-pass sinusoid only"):
        dt.render(scene, cameras=[dt.Camera(waveform="triangular")], spp=2, time_sampling="analytic")
    with pytest.raises(ValueError, match="fully correlated partner"):
        dt.render(scene, cameras=[dt.Camera()], spp=2, time_sampling="analytic", correlation="none")
