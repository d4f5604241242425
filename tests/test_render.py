"""dopplertof.render against stock Mitsuba and against exact ground truth.

Statistical comparisons use the per-pixel variances of both estimates: ours from the
result's ``stderr``, stock Mitsuba's from the ``moment`` integrator (second moment of the
same samples). Two unbiased estimates differ per pixel by noise alone, so

* the image means differ by less than 3 combined standard errors, and
* the mean squared difference over the pixels is the sum of both variances, within the
  ratio's own noise (√(2/N_eff), N_eff ≈ the number of pixels that carry the variance).

The scenes are grey so that all three channels carry the same samples: the moment
integrator reports the second moment of the luminance only, which then equals each channel's.
"""

import math
import os

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt

T = mi.ScalarTransform4f
EXPOSURE = 1.5e-3


# ----------------------------------------------------------------------------------------
# Scenes


def _grey(value):
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [value] * 3}}


BOX_TO_WORLD = T().translate([0.3, 0.35, 0.1]) @ T().rotate([0, 1, 0], 25) @ T().scale(0.35)


def grey_box(res, light):
    """A small grey Cornell-like room (open at the front) with a cube; ``light`` is
    ``"point"`` (inside the room) or ``"area"`` (a square behind the camera, facing the
    room, so that no pixel sees an emitter edge)."""
    scene = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": 35,
            "to_world": T().look_at(origin=[0, 1, 4.5], target=[0, 1, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
        },
        "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90), "bsdf": _grey(0.7)},
        "ceiling": {"type": "rectangle", "to_world": T().translate([0, 2, 0]) @ T().rotate([1, 0, 0], 90), "bsdf": _grey(0.6)},
        "back": {"type": "rectangle", "to_world": T().translate([0, 1, -1]), "bsdf": _grey(0.8)},
        "left": {"type": "rectangle", "to_world": T().translate([-1, 1, 0]) @ T().rotate([0, 1, 0], 90), "bsdf": _grey(0.3)},
        "right": {"type": "rectangle", "to_world": T().translate([1, 1, 0]) @ T().rotate([0, 1, 0], -90), "bsdf": _grey(0.5)},
        "box": {"type": "cube", "to_world": BOX_TO_WORLD, "bsdf": _grey(0.7)},
    }
    if light == "area":
        scene["light"] = {
            "type": "rectangle",
            "to_world": T().translate([0.3, 1.3, 5.5]) @ T().rotate([0, 1, 0], 180),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [3.0] * 3}},
        }
    else:
        scene["light"] = {"type": "point", "position": [0.2, 1.5, 2.5], "intensity": {"type": "rgb", "value": [5.0] * 3}}
    return scene


def stock_moments(scene_dict, max_depth, spp, seed):
    """Stock `path` through the `moment` integrator: (mean, variance of the mean) of
    channel 0, both (H, W)."""
    d = dict(scene_dict)
    d["integrator"] = {"type": "moment", "nested": {"type": "path", "max_depth": max_depth}}
    img = np.array(mi.render(mi.load_dict(d), spp=spp, seed=seed), dtype=np.float64)
    assert img.shape[-1] == 9  # R G B, nested X Y Z, second moments X Y Z
    mean, m2 = img[..., 0], img[..., 7]
    np.testing.assert_allclose(img[..., 4], mean, rtol=1e-5, atol=1e-7)  # grey: Y == R
    return mean, np.maximum(m2 - mean**2, 0.0) / (spp - 1)


def noise_statistics(ours_mean, ours_var, ref_mean, ref_var):
    """(MSE / predicted MSE, z of the image-mean difference, N_eff)."""
    d = ours_mean - ref_mean
    v = ours_var + ref_var
    ratio = float((d**2).sum() / v.sum())
    z = float(d.sum() / np.sqrt(v.sum()))
    n_eff = float(v.sum() ** 2 / (v**2).sum())
    return ratio, z, n_eff


def assert_agree_within_noise(ours_mean, ours_var, ref_mean, ref_var, min_n_eff=1000):
    ratio, z, n_eff = noise_statistics(ours_mean, ours_var, ref_mean, ref_var)
    assert n_eff > min_n_eff, f"too few pixels carry the variance for a tight test (N_eff={n_eff:.0f})"
    assert abs(z) < 3.0, f"image means differ by {z:.2f} standard errors"
    assert abs(ratio - 1.0) < 0.10, f"MSE is {ratio:.3f}× what noise alone predicts (N_eff={n_eff:.0f})"


def ours_channel0(result):
    np.testing.assert_array_equal(result.intensity[..., 0], result.intensity[..., 1])  # grey scene
    return result.intensity[..., 0].astype(np.float64), result.stderr[..., 0].astype(np.float64) ** 2


# ----------------------------------------------------------------------------------------
# 1. Static scenes equal stock Mitsuba `path`


@pytest.mark.slow
@pytest.mark.parametrize("light", ["point", "area"])
@pytest.mark.parametrize("max_depth", [3, 5])
def test_static_scene_equals_stock_path(light, max_depth):
    res = 64
    scene = grey_box(res, light)
    ours = dt.render(dt.load_scene(scene), spp=512, seed=11, max_depth=max_depth, time_sampling="uniform")
    ref_mean, ref_var = stock_moments(scene, max_depth, spp=1024, seed=5)
    assert_agree_within_noise(*ours_channel0(ours), ref_mean, ref_var)


def test_static_scene_equals_stock_path_quick():
    """A cheap version of the test above (means only, looser)."""
    res = 24
    scene = grey_box(res, "area")
    ours = dt.render(dt.load_scene(scene), spp=64, seed=2, max_depth=3, time_sampling="uniform")
    ref_mean, ref_var = stock_moments(scene, 3, spp=256, seed=9)
    mean, var = ours_channel0(ours)
    ratio, z, _ = noise_statistics(mean, var, ref_mean, ref_var)
    assert abs(z) < 3.5 and 0.7 < ratio < 1.3, (z, ratio)


def test_the_comparison_detects_a_one_percent_error():
    """The statistic has power: a 1 % brighter copy of our image fails it."""
    res = 64
    scene = grey_box(res, "point")
    ours = dt.render(dt.load_scene(scene), spp=256, seed=4, max_depth=3, time_sampling="uniform")
    ref_mean, ref_var = stock_moments(scene, 3, spp=512, seed=6)
    mean, var = ours_channel0(ours)
    ratio, z, _ = noise_statistics(1.01 * mean, var, ref_mean, ref_var)
    assert abs(z) > 3 or abs(ratio - 1) > 0.1


def test_directly_visible_area_light_equals_stock():
    """max_depth=1: emitters only. A sample is either the radiance L or 0, so pixels whose
    samples all hit show L exactly, and the per-sample variance is known in closed form,
    m (L − m) for a pixel mean m: stock Mitsuba's variance needs no estimate."""
    res, spp_ours, spp_stock = 32, 64, 1024
    radiance = np.array([4.0, 2.0, 1.0])
    scene = {
        "type": "scene",
        "sensor": grey_box(res, "point")["sensor"],
        "light": {
            "type": "rectangle",
            "to_world": T().translate([0.1, 1.0, 0.0]) @ T().scale([0.7, 0.5, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance.tolist()}},
        },
    }
    ours = dt.render(dt.load_scene(scene), spp=spp_ours, seed=1, max_depth=1, time_sampling="uniform")
    d = dict(scene, integrator={"type": "path", "max_depth": 1})
    stock = np.array(mi.render(mi.load_dict(d), spp=spp_stock, seed=1), dtype=np.float64)
    inside = ours.coverage == 1.0
    assert inside.sum() > 50 and (ours.coverage == 0).sum() > 50
    np.testing.assert_allclose(ours.intensity[inside], np.tile(radiance, (inside.sum(), 1)), rtol=1e-6)
    np.testing.assert_array_equal(ours.intensity[ours.coverage == 0], 0.0)
    for c in range(3):
        var_stock = np.maximum(stock[..., c] * (radiance[c] - stock[..., c]), 0) / spp_stock
        var_ours = ours.stderr[..., c].astype(np.float64) ** 2
        diff = ours.intensity[..., c].astype(np.float64).sum() - stock[..., c].sum()
        assert abs(diff) < 3 * np.sqrt((var_ours + var_stock).sum()), c


# ----------------------------------------------------------------------------------------
# 2. Bodies that do not move render like static shapes


def _box_as_body(scene, motion):
    scene = dict(scene)
    box = dict(scene["box"])
    if motion["type"] == "keyframes":
        box.pop("to_world")
    box["motion"] = motion
    scene["box"] = box
    return scene


@pytest.mark.parametrize("light", ["point", "area"])
@pytest.mark.parametrize(
    "motion",
    [
        {"type": "keyframes", "keys": [(0.0, BOX_TO_WORLD), (0.7e-3, BOX_TO_WORLD), (1.5e-3, BOX_TO_WORLD)]},
        {"type": "parametric", "linear_velocity": [0, 0, 0], "angular_velocity": [0, 0, 0], "pivot": [0.3, 0.3, 0.3]},
    ],
    ids=["keyframes", "parametric"],
)
def test_zero_velocity_bodies_render_like_static_shapes(light, motion):
    """Same seed, same random numbers (they depend on seed, pixel and sample only), and the
    same geometry: the only difference is that the box is intersected in its own frame and
    mapped back, which changes the hit points by float rounding (~1e-7 relative). So the
    images agree to float precision, not just within noise, and the ground truth is 0."""
    base = grey_box(24, light)
    static = dt.render(dt.load_scene(base), spp=32, seed=7, max_depth=4)
    scene = dt.load_scene(_box_as_body(base, motion))
    assert len(scene.bodies) == 1
    moving = dt.render(scene, spp=32, seed=7, max_depth=4)
    scale = float(static.intensity.max())
    np.testing.assert_allclose(moving.intensity, static.intensity, rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(moving.depth, static.depth, rtol=1e-5, equal_nan=True)
    assert np.nanmax(np.abs(moving.velocity)) == 0.0
    assert np.nanmax(np.abs(moving.point_velocity)) == 0.0


# ----------------------------------------------------------------------------------------
# 3. Moving bodies: the average over time of stock renders of the baked scene


def _box_matrix_at(t):
    """The box translates 0.6 m along +x over the exposure (independent of dopplertof)."""
    m = np.array(BOX_TO_WORLD.matrix, dtype=np.float64).copy()
    m[:3, 3] += np.array([-0.6, 0.0, 0.0]) + np.array([0.6, 0.0, 0.0]) * (t / EXPOSURE)
    return m


@pytest.mark.slow
@pytest.mark.parametrize("light", ["point", "area"])
def test_moving_body_equals_time_average_of_baked_stock_renders(light):
    """Midpoint rule over K = 32 strata: its bias (where an edge crosses a pixel, ~1e-3 of
    the edge contrast) is far below the per-pixel noise at these sample counts."""
    res, K, spp_per_time = 64, 32, 32
    base = grey_box(res, light)
    keys = [(0.0, T(_box_matrix_at(0.0).tolist())), (EXPOSURE, T(_box_matrix_at(EXPOSURE).tolist()))]
    scene = _box_as_body(base, {"type": "keyframes", "keys": keys})
    ours = dt.render(dt.load_scene(scene), spp=512, seed=3, max_depth=4, time_sampling="uniform", exposure=EXPOSURE)
    ref_mean = np.zeros((res, res))
    ref_var = np.zeros((res, res))
    for k in range(K):
        baked = dict(base)
        baked["box"] = dict(base["box"], to_world=T(_box_matrix_at((k + 0.5) / K * EXPOSURE).tolist()))
        mean, var = stock_moments(baked, 4, spp=spp_per_time, seed=100 + k)
        ref_mean += mean / K
        ref_var += var / K**2
        if k == 0:
            first = mean
    mean, var = ours_channel0(ours)
    assert_agree_within_noise(mean, var, ref_mean, ref_var)
    # The blur is real: the first stratum alone is far from the time average.
    assert noise_statistics(first, ref_var, ref_mean, ref_var)[0] > 20


# ----------------------------------------------------------------------------------------
# 4. Ground-truth velocity


def _camera(kind, res, **extra):
    return {
        "type": kind,
        "near_clip": 1e-6,  # rays start at the centre of projection (see the depth test)
        "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
        **extra,
    }


def _light():
    return {"type": "point", "position": [0.0, 0.0, 0.0], "intensity": {"type": "rgb", "value": [10.0] * 3}}


def _instant(scene, **kw):
    """One sample per pixel at (practically) one instant: every quantity is that of a
    single camera ray, so per-pixel relations hold exactly."""
    kw.setdefault("exposure", 1e-9)
    return dt.render(scene, spp=1, time_sampling="uniform", max_depth=2, **kw)


FOV = 40.0


def _pixel_dz_range(res):
    """Range of −d_z over each pixel's footprint for the FOV-40 pinhole (x and y fov equal)."""
    tan = math.tan(math.radians(FOV / 2))
    edges = (2 * np.arange(res + 1) / res - 1) * tan
    lo_x = np.minimum(np.abs(edges[:-1]), np.abs(edges[1:]))
    lo_x[(edges[:-1] < 0) & (edges[1:] > 0)] = 0.0
    hi_x = np.maximum(np.abs(edges[:-1]), np.abs(edges[1:]))
    dz_max = 1 / np.sqrt(1 + lo_x[:, None] ** 2 + lo_x[None, :] ** 2)
    dz_min = 1 / np.sqrt(1 + hi_x[:, None] ** 2 + hi_x[None, :] ** 2)
    return dz_min, dz_max


@pytest.mark.parametrize("vz", [-7.0, 3.0])
def test_plane_translating_along_the_axis(vz):
    """Plane z = −5 facing a pinhole at the origin, moving with v = (0, 0, vz). Per ray:
    point velocity v·d̂ = vz·d_z, ray-fixed velocity (n·v)/(n·d̂) = vz/d_z, and the hit is
    at depth·d̂, so d_z = −5/depth."""
    res = 16
    scene = dt.load_scene(
        {
            "type": "scene",
            "sensor": _camera("perspective", res, fov=FOV),
            "plane": {"type": "rectangle", "to_world": T().translate([0, 0, -5]) @ T().scale(20), "bsdf": _grey(0.5), "motion": {"type": "parametric", "linear_velocity": [0, 0, vz]}},
            "light": _light(),
        }
    )
    r = _instant(scene, seed=1)
    assert np.all(r.coverage == 1)
    dz = -5.0 / r.depth.astype(np.float64)
    dz_min, dz_max = _pixel_dz_range(res)
    assert np.all(-dz >= dz_min - 1e-6) and np.all(-dz <= dz_max + 1e-6)  # d̂ lies in its pixel
    np.testing.assert_allclose(r.point_velocity, vz * dz, rtol=1e-5)
    np.testing.assert_allclose(r.velocity, vz / dz, rtol=1e-5)
    # More samples per pixel: the ray-fixed velocity is linear in 1/d_z, as is the depth,
    # so the relation survives pixel averaging.
    r8 = dt.render(scene, spp=8, time_sampling="uniform", max_depth=2, exposure=1e-9)
    np.testing.assert_allclose(r8.velocity, vz * r8.depth / -5.0, rtol=1e-5)


def test_velocity_is_the_time_derivative_of_depth_along_fixed_rays():
    """A tilted disc rotating about an off-centre axis: velocity = d(depth)/dt, checked by
    central differences of two instants rendered with the same seed (same rays)."""
    res = 24
    to_world = T().translate([0.2, -0.1, -4.0]) @ T().rotate([1, 0, 0], 35) @ T().scale(1.2)
    scene = dt.load_scene(
        {
            "type": "scene",
            "sensor": _camera("perspective", res, fov=FOV),
            "disc": {"type": "disk", "to_world": to_world, "bsdf": _grey(0.5), "motion": {"type": "parametric", "angular_velocity": [30.0, 20.0, 0.0], "pivot": [0.5, 0.0, -4.2], "linear_velocity": [0, 0, -2.0]}},
            "light": _light(),
        }
    )
    t, h = 2e-3, 5e-5
    # A camera turns on the Float64 path lengths: the finite difference of depths 0.1 mm
    # apart needs more than float32 hit distances (intensity-only renders use those).
    cam = [dt.Camera(exposure=1e-9)]
    mid = _instant(scene, seed=5, exposure_start=t, cameras=cam)
    before = _instant(scene, seed=5, exposure_start=t - h, cameras=cam)
    after = _instant(scene, seed=5, exposure_start=t + h, cameras=cam)
    ok = (mid.coverage == 1) & (before.coverage == 1) & (after.coverage == 1)
    assert ok.sum() > 100
    fd = (after.depth.astype(np.float64) - before.depth) / (2 * h)
    np.testing.assert_allclose(mid.velocity[ok], fd[ok], rtol=2e-3, atol=5e-3)
    assert np.abs(fd[ok]).max() > 5  # the motion is not trivial


TILT = math.radians(40)


def _tilted_disc(angular_velocity, camera="orthographic", res=24):
    """Unit-ish disc at c = (0, 0, −3), tilted about x: in-plane axes e1 = x and
    e2 = (0, cos a, sin a), normal n = (0, −sin a, cos a); spinning about an axis through c."""
    return dt.load_scene(
        {
            "type": "scene",
            "sensor": _camera(camera, res, **({"fov": FOV} if camera == "perspective" else {})),
            "disc": {
                "type": "disk",
                "to_world": T().translate([0, 0, -3]) @ T().rotate([1, 0, 0], math.degrees(TILT)) @ T().scale(0.8),
                "bsdf": _grey(0.5),
                "motion": {"type": "parametric", "angular_velocity": list(angular_velocity), "pivot": [0, 0, -3]},
            },
            "light": _light(),
        }
    )


def test_disc_spinning_about_a_diameter():
    """ω = w·e1 through c, orthographic camera (d̂ = −z). A point r = s e1 + u e2 from c moves
    at w u n, so v·d̂ = −w u cos a and (n·v)/(n·d̂) = −w u / cos a, with u = r_z / sin a read
    from the depth. Both are affine in the depth, so they hold for pixel averages too."""
    w = 50.0
    r = dt.render(_tilted_disc([w, 0, 0]), spp=4, time_sampling="uniform", max_depth=2, exposure=1e-9)
    hit = r.coverage > 0
    assert hit.sum() > 150
    rz = -r.depth[hit].astype(np.float64) + 3.0  # hit z = −depth (rays start at z ≈ 0)
    u = rz / math.sin(TILT)
    np.testing.assert_allclose(r.point_velocity[hit], -w * u * math.cos(TILT), rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(r.velocity[hit], -w * u / math.cos(TILT), rtol=1e-4, atol=1e-4)
    assert np.abs(r.point_velocity[hit]).max() > 10


@pytest.mark.parametrize("camera", ["orthographic", "perspective"])
def test_disc_spinning_in_its_own_plane(camera):
    """ω = w·n: every point moves within the disc's plane, so the distance along a fixed
    ray does not change (velocity 0), while the points themselves move along the rays."""
    w = 50.0
    n = np.array([0.0, -math.sin(TILT), math.cos(TILT)])
    res = 24
    r = dt.render(_tilted_disc(w * n, camera, res), spp=16, time_sampling="uniform", max_depth=2, exposure=1e-9, seed=2)
    hit = r.coverage > 0
    assert hit.sum() > 100
    assert np.abs(r.velocity[hit]).max() < 1e-4 * w
    assert np.abs(r.point_velocity[hit]).max() > 0.2 * w * 0.8 * math.sin(TILT)
    if camera == "orthographic":
        # v·d̂ = −w s sin a with s = x of the hit; x is the pixel's film coordinate.
        x_centre = 2 * (np.arange(res) + 0.5) / res - 1
        expected = -w * math.sin(TILT) * np.broadcast_to(x_centre, (res, res))
        full = r.coverage == 1
        pixel = 2.0 / res
        np.testing.assert_allclose(r.point_velocity[full], expected[full], atol=0.3 * w * math.sin(TILT) * pixel)


def test_sideways_motion_of_a_tilted_plane_changes_distance_not_point_velocity():
    """Orthographic camera, plane with normal (sin a, 0, cos a) moving along +x at vx:
    (n·v)/(n·d̂) = −vx tan a exactly, and v·d̂ = 0."""
    a, vx = math.radians(30), 6.0
    scene = dt.load_scene(
        {
            "type": "scene",
            "sensor": _camera("orthographic", 8),
            "plane": {"type": "rectangle", "to_world": T().translate([0, 0, -3]) @ T().rotate([0, 1, 0], 30) @ T().scale(5), "bsdf": _grey(0.5), "motion": {"type": "parametric", "linear_velocity": [vx, 0, 0]}},
            "light": _light(),
        }
    )
    r = dt.render(scene, spp=4, time_sampling="uniform", max_depth=2, exposure=1e-9)
    assert np.all(r.coverage == 1)
    np.testing.assert_allclose(r.velocity, -vx * math.tan(a), rtol=1e-5)
    np.testing.assert_allclose(r.point_velocity, 0.0, atol=1e-5)


def test_depth_is_measured_from_the_centre_of_projection():
    """The D-ToF path starts at the camera, not at the near-clip plane: for the same rays
    (same seed) a facing plane at 5 m gives exactly twice the depth of one at 2.5 m.
    (Mitsuba's perspective camera starts its rays at near_clip/d_z; default 1 cm.)"""
    depths = []
    for z in (5.0, 2.5):
        scene = dt.load_scene(
            {
                "type": "scene",
                "sensor": {"type": "perspective", "fov": FOV, "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]), "film": {"type": "hdrfilm", "width": 8, "height": 8}},
                "plane": {"type": "rectangle", "to_world": T().translate([0, 0, -z]) @ T().scale(20), "bsdf": _grey(0.5)},
                "light": _light(),
            }
        )
        depths.append(_instant(scene, seed=3).depth.astype(np.float64))
    np.testing.assert_allclose(depths[0] / depths[1], 2.0, rtol=1e-5)


@pytest.fixture(scope="session")
def cornell64():
    scene = dt.scenes.cornell_box(resolution=64)
    return scene, dt.render(scene, spp=8, seed=0, max_depth=3)


def _cornell_reference(scene, res, grid=5):
    """Per-pixel labels and normals from stock Mitsuba ray casts: a grid×grid pattern of
    film positions covering each pixel (edges included), at times 0, T/2 and T, against the
    static scene and each box baked at that time."""
    f = np.linspace(0.0, 1.0, grid)
    fx = (np.arange(res)[None, :, None, None] + f[None, None, None, :]) / res
    fy = (np.arange(res)[:, None, None, None] + f[None, None, :, None]) / res
    fx = np.broadcast_to(fx, (res, res, grid, grid)).ravel()
    fy = np.broadcast_to(fy, (res, res, grid, grid)).ravel()
    ray, _ = scene.sensor.sample_ray(0.0, 0.5, mi.Point2f(fx.astype(np.float32), fy.astype(np.float32)), mi.Point2f(0.5, 0.5))
    d = np.stack([np.asarray(ray.d.x), np.asarray(ray.d.y), np.asarray(ray.d.z)], -1).astype(np.float64)
    labels, normals = [], []
    for t in (0.0, EXPOSURE / 2, EXPOSURE):
        si = scene.static.ray_intersect(ray)
        dr.eval(si)
        best = np.asarray(si.t, dtype=np.float64)
        label = np.zeros(best.shape, int)
        normal = np.stack([np.asarray(si.n.x), np.asarray(si.n.y), np.asarray(si.n.z)], -1).astype(np.float64)
        for i, body in enumerate(scene.bodies):
            alone = mi.load_dict({"type": "scene", "b": {"type": "cube", "to_world": T(body.motion.matrix(t).tolist())}})
            sb = alone.ray_intersect(ray)
            dr.eval(sb)
            tb = np.asarray(sb.t, dtype=np.float64)
            closer = tb < best
            label[closer] = i + 1
            best = np.minimum(best, tb)
            nb = np.stack([np.asarray(sb.n.x), np.asarray(sb.n.y), np.asarray(sb.n.z)], -1).astype(np.float64)
            normal[closer] = nb[closer]
        labels.append(label.reshape(res, res, -1))
        normals.append(normal.reshape(res, res, -1, 3))
    return np.stack(labels), np.stack(normals), d.reshape(res, res, -1, 3)


def test_cornell_box_ground_truth_velocity(cornell64):
    scene, r = cornell64
    res = 64
    names = [b.name for b in scene.bodies]
    labels, normals, d = _cornell_reference(scene, res)
    velocities = {"short-box": np.array([0, 0, 10.0]), "tall-box": np.array([0, 0, -10.0])}  # 15 mm / 1.5 ms
    static = (labels == 0).all(axis=(0, 3))
    # Static pixels (not even a neighbour touches a box): exactly zero.
    near_box = ~static
    near_box = near_box | np.roll(near_box, 1, 0) | np.roll(near_box, -1, 0) | np.roll(near_box, 1, 1) | np.roll(near_box, -1, 1)
    far = ~near_box
    assert far.sum() > 2000
    assert np.all(r.velocity[far] == 0.0) and np.all(r.point_velocity[far] == 0.0)
    for name, expected_sign in [("short-box", -1), ("tall-box", 1)]:
        index = names.index(name) + 1
        on = (labels == index).all(axis=(0, 3))
        assert on.sum() > 150
        v = velocities[name]
        # The mean over the box: the faces seen nearly head-on move at ∓10 m/s along the ray.
        assert np.mean(r.velocity[on]) == pytest.approx(expected_sign * 10.0, rel=0.06)
        assert np.median(r.velocity[on]) == pytest.approx(expected_sign * 10.0, rel=0.02)
        # Per pixel, where the whole pixel sees one face: (n·v)/(n·d̂) and v·d̂ averaged over
        # the pixel's footprint, from stock geometry.
        n = normals[:, :, :, :, :]
        one_face = on & (np.abs(n - n[0, :, :, :1, :]).max(axis=(0, 3, 4)) < 1e-4)
        assert one_face.sum() > 100
        # Our pixels average 8 random samples, the reference a 5x5 grid: allow for the
        # variation of the function over the pixel (large on faces seen at grazing angles).
        n0 = normals[0]
        per_ray = np.einsum("hwgk,k->hwg", n0, v) / np.einsum("hwgk,hwgk->hwg", n0, d)
        ref_velocity = per_ray.mean(-1)
        tol = 2e-3 * np.abs(ref_velocity) + 0.5 * (per_ray.max(-1) - per_ray.min(-1))
        err = np.abs(r.velocity - ref_velocity)
        assert np.all(err[one_face] <= tol[one_face]), np.argwhere(one_face & (err > tol))[:5]
        ref_point_velocity = (d @ v).mean(-1)
        np.testing.assert_allclose(r.point_velocity[on], ref_point_velocity[on], rtol=2e-3)
        assert np.all(np.sign(r.point_velocity[on]) == expected_sign)


# ----------------------------------------------------------------------------------------
# 7. Seeds and passes


def test_same_seed_same_image_whatever_the_pass_split():
    scene = dt.scenes.cornell_box(resolution=16)
    cams = [dt.Camera(heterodyne=0.0), dt.Camera(heterodyne=1.0, phase=0.5)]
    one = dt.render(scene, cams, spp=24, seed=5, max_depth=3)
    many = dt.render(scene, cams, spp=24, seed=5, max_depth=3, lanes_per_pass=16 * 16 * 4)  # 6 passes
    odd = dt.render(scene, cams, spp=24, seed=5, max_depth=3, lanes_per_pass=16 * 16 * 10)  # 10 + 10 + 4
    for other in (many, odd):
        for name in ("intensity", "measurements", "depth", "velocity", "point_velocity", "coverage"):
            np.testing.assert_allclose(getattr(other, name), getattr(one, name), rtol=1e-5, atol=1e-7, equal_nan=True, err_msg=name)
        assert other.spp == one.spp == 24
    different = dt.render(scene, cams, spp=24, seed=6, max_depth=3)
    assert np.abs(different.intensity - one.intensity).max() > 1e-3
    assert np.abs(different.measurements - one.measurements).max() > 1e-4


def _flat_plane(intensity=1000.0):
    """A facing plane lit head-on: within a pixel the radiance varies by ~1e-4, so the
    per-sample variance is ~1e-6 of the squared mean (a hard case for Σx² − (Σx)²/n)."""
    return dt.load_scene(
        {
            "type": "scene",
            "sensor": {"type": "perspective", "fov": 20, "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]), "film": {"type": "hdrfilm", "width": 8, "height": 8}},
            "plane": {"type": "rectangle", "to_world": T().translate([0, 0, -5]) @ T().scale(20), "bsdf": _grey(0.5)},
            "light": {"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": [intensity] * 3}},
        }
    )


def test_stderr_does_not_depend_on_the_pass_split():
    """The per-pixel Σx and Σx² are the same numbers whatever the split, up to Float64
    rounding (DESIGN §3.2, §3.3)."""
    scene = _flat_plane()
    kw = dict(spp=1024, time_sampling="uniform", max_depth=2, seed=1)
    one = dt.render(scene, **kw)
    split = dt.render(scene, lanes_per_pass=64 * 16, **kw)  # 64 passes of 16 spp
    np.testing.assert_allclose(split.intensity, one.intensity, rtol=1e-6)
    np.testing.assert_allclose(split.stderr, one.stderr, rtol=1e-3)


def test_stderr_matches_the_spread_over_seeds():
    """Independent check of ``stderr``: the standard deviation of the pixel means over
    independent seeds. With 32 seeds the ratio of the two is 1 within ~13 % per pixel; over
    256 pixels and 3 channels the mean ratio is far tighter."""
    scene = dt.scenes.cornell_box(resolution=16, light="area")
    runs = [dt.render(scene, spp=16, seed=100 + k, max_depth=3, time_sampling="uniform") for k in range(32)]
    means = np.stack([r.intensity for r in runs]).astype(np.float64)
    reported = np.mean([r.stderr.astype(np.float64) ** 2 for r in runs], axis=0)
    empirical = means.var(axis=0, ddof=1)
    ok = reported > 0
    assert ok.mean() > 0.9
    assert np.mean(empirical[ok]) / np.mean(reported[ok]) == pytest.approx(1.0, abs=0.1)


def _kernels_launched(warm_up, *renders):
    """The hashes of the JIT kernels each of ``renders`` (callables) launches, after
    ``warm_up`` (whose kernels are not listed: a first render also uploads scene data)."""
    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        warm_up()
        dr.kernel_history()  # clear
        launched = []
        for render in renders:
            render()
            launched.append([k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT])
        return launched
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was)


def test_changing_parameters_does_not_recompile():
    """Motion values, camera parameters and the seed are data: after a first render, scenes
    with other motion values and other cameras launch exactly the same kernels."""
    a = dt.scenes.cornell_box(resolution=16)
    b = dt.scenes.cornell_box(resolution=16, displacement=0.05)
    c = dt.scenes.cornell_box(resolution=16, displacement=0.0)
    cams = [dt.Camera(heterodyne=0.0), dt.Camera(phase=1.0)]
    # Cameras sharing a modulation frequency share its sincos: that grouping is part of
    # the kernel, the values are not.
    other_cams = [dt.Camera(heterodyne=1.0, phase=0.3, modulation_frequency=20e6), dt.Camera(phase=1.5, modulation_frequency=20e6)]
    reference, *others = _kernels_launched(
        lambda: dt.render(a, cams, spp=8, seed=0),
        lambda: dt.render(a, cams, spp=8, seed=1),
        *(lambda s=scene, c=cameras, k=seed: dt.render(s, c, spp=8, seed=k) for scene, cameras, seed in [(b, cams, 0), (c, other_cams, 3), (a, other_cams, 2)]),
    )
    assert reference
    for kernels in others:
        assert kernels == reference


@pytest.mark.parametrize("correlation", ["replay", "reconnection"])
def test_another_path_depth_does_not_recompile(correlation):
    """``max_depth`` and ``rr_depth`` are data: a dataset's direct-light render (another
    depth, the same scene) launches the kernels of its full render, so a new scene is
    compiled once, not twice (``benchmarks/dataset.py``)."""
    scene = dt.scenes.cornell_box(resolution=16)
    cams = [dt.Camera(heterodyne=1.0)]
    depths = [dict(max_depth=2), dict(max_depth=3, rr_depth=1), dict(max_depth=-1)]
    reference, *others = _kernels_launched(
        lambda: dt.render(scene, cams, spp=8, seed=0, correlation=correlation),
        lambda: dt.render(scene, cams, spp=8, seed=1, correlation=correlation),
        *(lambda d=d: dt.render(scene, cams, spp=8, seed=2, correlation=correlation, **d) for d in depths),
    )
    assert reference
    for d, kernels in zip(depths, others):
        assert kernels == reference, d


# ----------------------------------------------------------------------------------------
# Result shape and simple invariants


def test_result_shapes_and_coverage(cornell64):
    scene, r = cornell64
    assert r.intensity.shape == (64, 64, 3) and r.stderr.shape == (64, 64, 3)
    assert r.measurements.shape == (0, 64, 64)
    for name in ("depth", "velocity", "point_velocity", "coverage"):
        assert getattr(r, name).shape == (64, 64)
    assert r.intensity.dtype == np.float32
    assert r.spp == 8
    # The closed room fills the view: every sample hits.
    np.testing.assert_array_equal(r.coverage, 1.0)
    assert np.all((r.depth > 5.5) & (r.depth < 8.0))


def test_missed_pixels_have_nan_ground_truth():
    scene = dt.load_scene(
        {
            "type": "scene",
            "sensor": _camera("perspective", 16, fov=FOV),
            "ball": {"type": "sphere", "to_world": T().translate([0, 0, -5]) @ T().scale(0.8), "bsdf": _grey(0.5)},
            "light": _light(),
        }
    )
    r = dt.render(scene, spp=4, time_sampling="uniform", max_depth=2)
    assert r.coverage[0, 0] == 0 and r.coverage[8, 8] == 1
    assert np.isnan(r.depth[0, 0]) and np.isnan(r.velocity[0, 0]) and np.isnan(r.point_velocity[0, 0])
    np.testing.assert_array_equal(r.intensity[0, 0], 0.0)
    assert 5 - 0.8 <= r.depth[8, 8] < 5 - 0.8 + 0.05  # the front of the ball, near the axis


# ----------------------------------------------------------------------------------------
# 8. Bad input


def _one_line(info):
    text = str(info.value)
    assert "\n" not in text and len(text) < 600, text


@pytest.fixture(scope="module")
def tiny():
    return dt.scenes.cornell_box(resolution=4)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(spp=0), r"'spp' must be >= 1, got 0"),
        (dict(spp=-4), r"'spp' must be >= 1, got -4"),
        (dict(spp=2.5), r"'spp' must be an integer, got 2.5"),
        (dict(spp=3), r"multiple of the 2"),
        (dict(exposure=0.0), r"'exposure' must be in \(0, 60\] s"),
        (dict(exposure=-1e-3), r"'exposure' must be in \(0, 60\] s"),
        (dict(exposure=float("nan")), r"'exposure' must be a finite number"),
        (dict(max_depth=0), r"'max_depth' must be >= 1 or -1"),
        (dict(time_sampling="sometimes"), r"unknown time_sampling 'sometimes'"),
        (dict(correlation="telepathy"), r"unknown correlation 'telepathy'"),
        (dict(cameras=["camera"]), r"'cameras' must be a list of dopplertof.Camera"),
        (dict(cameras=[dt.Camera(exposure=1e-3), dt.Camera(exposure=2e-3)], exposure=1e-3), r"differs from the cameras' exposure"),
    ],
)
def test_bad_render_arguments(tiny, kwargs, match):
    kwargs = dict(kwargs)
    cameras = kwargs.pop("cameras", None)
    with pytest.raises(ValueError, match=match) as info:
        dt.render(tiny, cameras, **kwargs)
    _one_line(info)


@pytest.mark.parametrize("resolution", [0, -16, 2.5, True])
def test_bad_resolution(resolution):
    with pytest.raises(ValueError, match="resolution must be a positive integer") as info:
        dt.scenes.cornell_box(resolution=resolution)
    _one_line(info)


def test_bad_light_kind():
    with pytest.raises(ValueError, match="light must be 'point' or 'area'") as info:
        dt.scenes.cornell_box(resolution=4, light="laser")
    _one_line(info)


def test_another_exposure_window_reuses_the_kernels():
    """Animation frames differ only in exposure_start: no recompilation per frame."""
    scene = dt.scenes.cornell_box(resolution=8)
    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        for correlation in ("replay", "adaptive"):
            hashes = []
            for start in (0.0, 1e-3, 2.5e-3):
                dr.kernel_history()
                dt.render(scene, [dt.Camera()], spp=4, correlation=correlation, exposure_start=start)
                hashes.append([k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT])
            assert hashes[1] and hashes[1] == hashes[2]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was)


@pytest.mark.parametrize("correlation", ["replay", "adaptive"])
def test_hidden_emitters_are_passed_through_as_in_stock_path(correlation):
    """With hide_emitters, a camera ray passes through a visible area light (stock `path`):
    the pixel shows what lies behind it, not the light's own reflection."""
    scene_dict = {
        "type": "scene",
        "sensor": _camera("perspective", 8, fov=40.0),
        "light": {"type": "rectangle", "to_world": T().translate([0, 0, -3]), "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [5.0] * 3}}, "bsdf": _grey(0.5)},
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -4]).scale(3), "bsdf": _grey(0.5)},
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [0.5] * 3}},
    }
    stock = np.array(mi.render(mi.load_dict(scene_dict), integrator=mi.load_dict({"type": "path", "max_depth": 3, "hide_emitters": True}), spp=512, seed=1))[..., :3]
    ours = dt.render(dt.load_scene(scene_dict), cameras=[dt.Camera()], spp=512, max_depth=3, correlation=correlation, hide_emitters=True, seed=2)
    centre = (slice(3, 5), slice(3, 5))
    diff = ours.intensity[centre].astype(np.float64).mean() - stock[centre].mean()
    assert abs(diff) < 4 * ours.stderr[centre].astype(np.float64).mean() + 0.02 * stock[centre].mean()
    assert stock[centre].mean() < 1.0  # the light itself (radiance 5) is not what is seen


@pytest.mark.parametrize("correlation", ["replay", "adaptive"])
def test_another_spp_or_shift_reuses_the_kernels(correlation):
    """spp and the antithetic shift are data: sweeping them launches the same kernels."""
    scene = dt.scenes.cornell_box(resolution=8)
    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        hashes = []
        for spp, shift in ((8, 0.5), (16, 0.5), (32, 0.25)):  # at least two strata of two (one reduces without a block sum, three on the host)
            dr.kernel_history()
            dt.render(scene, [dt.Camera()], spp=spp, correlation=correlation, antithetic_shift=shift)
            hashes.append([k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT])
        assert hashes[1] and hashes[0] == hashes[1] == hashes[2]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was)


def test_a_result_saved_from_python_is_a_render_folder_the_commands_read(tmp_path):
    """``dt.folder.save(result, folder)`` writes what ``dopplertof render`` writes: the reconstruction
    reads back the very measurements, errors and cameras; a second save there is refused
    unless ``overwrite``."""
    from dopplertof.render_folder import read_render_folder

    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    result = dt.render(dt.scenes.cornell_box(resolution=8), cameras=cameras, spp=8, max_depth=3)
    folder = tmp_path / "saved"
    written = dt.folder.save(result, folder)
    assert "metadata.json" in written[-1] and all(os.path.isfile(p) for p in written)
    read_cameras, measurements, truth, stderr, covariance = read_render_folder(str(folder))
    assert [c.label() for c in read_cameras] == [c.label() for c in result.cameras]
    np.testing.assert_array_equal(measurements, result.measurements)
    np.testing.assert_array_equal(stderr, result.measurement_stderr)
    np.testing.assert_array_equal(truth, result.velocity)
    with pytest.raises(ValueError, match=r"holds .*; use --overwrite \(overwrite=True\) to replace them"):
        dt.folder.save(result, folder)
    assert dt.folder.save(result, folder, overwrite=True) == written
