"""DynamicScene queries at per-lane times against stock Mitsuba scenes with the bodies baked
at those times, and re-timing against numpy matrix products."""

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt

T = mi.ScalarTransform4f
TIMES = (0.0, 0.4e-3, 1.1e-3, 2.0e-3)


def _cube_keys():
    """Three keys: rotation about different axes, translation, non-uniform scale."""
    k0 = T().translate([0.0, 0.0, 0.0]) @ T().rotate([0, 1, 0], 10) @ T().scale([0.5, 0.3, 0.4])
    k1 = T().translate([0.3, 0.1, -0.2]) @ T().rotate([0.7071067811865476, 0.7071067811865476, 0.0], 50) @ T().scale([0.6, 0.3, 0.5])
    k2 = T().translate([0.5, -0.2, 0.1]) @ T().rotate([0, 0, 1], 120) @ T().scale([0.4, 0.4, 0.4])
    return [(0.0, k0), (1.0e-3, k1), (2.0e-3, k2)]


def _scene_dict():
    return {
        "type": "scene",
        "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}},
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -3]).scale(5)},
        "cube": {"type": "cube", "motion": {"type": "keyframes", "keys": _cube_keys()}},
        "ball": {
            "type": "sphere",
            "to_world": T().translate([-1.5, 0.5, 0.0]) @ T().scale(0.4),
            "motion": {"type": "parametric", "linear_velocity": [100.0, 0, 0], "angular_velocity": [0, 0, 900.0], "pivot": [-1.5, 0, 0]},
        },
    }


@pytest.fixture(scope="module")
def dyn():
    scene = dt.load_scene(_scene_dict())
    scene.set_time_window(0.0, 2.0e-3)
    return scene


def _baked(scene, t):
    """Stock Mitsuba scene: the static wall plus each body as its own shape at M(t)."""
    d = {"type": "scene", "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -3]).scale(5)}}
    shapes = {"cube": "cube", "ball": "sphere"}
    for i, body in enumerate(scene.bodies):
        d[f"body{i}"] = {"type": shapes[body.name], "to_world": T(body.motion.matrix(t).tolist())}
    return mi.load_dict(d)


def _np3(v):
    return np.stack([np.asarray(v.x), np.asarray(v.y), np.asarray(v.z)], axis=-1).astype(np.float64)


def _m(m, p):
    return p @ m[:3, :3].T + m[:3, 3]


def test_bodies_are_grouped_by_motion(dyn):
    assert sorted(b.name for b in dyn.bodies) == ["ball", "cube"]
    assert len(dyn.static.shapes()) == 1  # the wall only


def _rays(n, seed):
    """Rays from a sphere of radius 4 towards random points near the bodies."""
    rng = np.random.default_rng(seed)
    origins = rng.normal(size=(n, 3))
    origins = 4.0 * origins / np.linalg.norm(origins, axis=1, keepdims=True)
    origins[:, 2] = np.abs(origins[:, 2])  # in front of the wall
    targets = rng.uniform([-2.0, -0.8, -0.8], [1.0, 0.8, 0.8], (n, 3))
    dirs = targets - origins
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return origins, dirs


def test_intersect_at_per_lane_times_matches_baked_scenes(dyn):
    n_per_time = 400
    origins, dirs = _rays(n_per_time * len(TIMES), seed=3)
    times = np.repeat(TIMES, n_per_time)
    ray = mi.Ray3f(mi.Point3f(*origins.T.astype(np.float32)), mi.Vector3f(*dirs.T.astype(np.float32)))
    hit = dyn.intersect(ray, mi.Float64(times))
    dr.eval(hit.si, hit.body, hit.p_local, hit.n_local)
    t_ours = np.asarray(hit.si.t, dtype=np.float64)
    p_ours = _np3(hit.si.p)
    n_ours = _np3(hit.si.n)
    body = np.asarray(hit.body)
    p_local = _np3(hit.p_local)
    names = [b.name for b in dyn.bodies]
    hits_per_body = np.zeros(3, int)
    for k, t in enumerate(TIMES):
        sl = slice(k * n_per_time, (k + 1) * n_per_time)
        ref_scene = _baked(dyn, t)
        ray_k = mi.Ray3f(mi.Point3f(*origins[sl].T.astype(np.float32)), mi.Vector3f(*dirs[sl].T.astype(np.float32)))
        si = ref_scene.ray_intersect(ray_k)
        dr.eval(si)
        t_ref = np.asarray(si.t, dtype=np.float64)
        valid = np.isfinite(t_ref)
        np.testing.assert_array_equal(np.isfinite(t_ours[sl]), valid)
        np.testing.assert_allclose(t_ours[sl][valid], t_ref[valid], rtol=1e-4, atol=1e-4)
        np.testing.assert_allclose(p_ours[sl][valid], _np3(si.p)[valid], atol=5e-4)
        # Same geometric normal up to float error (both sides face the same way).
        np.testing.assert_allclose(n_ours[sl][valid], _np3(si.n)[valid], atol=2e-3)
        # Which shape was hit: compare with each body alone at that time.
        for i, bname in enumerate(names):
            mask = body[sl] == i + 1
            hits_per_body[i + 1] += mask.sum()
            m = dyn.bodies[i].motion.matrix(t)
            np.testing.assert_allclose(_m(np.linalg.inv(m), p_ours[sl][mask]), p_local[sl][mask], atol=1e-3, err_msg=bname)
        hits_per_body[0] += (body[sl] == 0).sum()
    assert np.all(hits_per_body[1:] > 100), hits_per_body  # both bodies were hit often


def test_occluded_matches_baked_scenes(dyn):
    n_per_time = 300
    origins, dirs = _rays(n_per_time * len(TIMES), seed=4)
    times = np.repeat(TIMES, n_per_time)
    ray = mi.Ray3f(mi.Point3f(*origins.T.astype(np.float32)), mi.Vector3f(*dirs.T.astype(np.float32)))
    ray.maxt = mi.Float(np.full(len(times), 4.0, dtype=np.float32))  # segments ending before the wall
    blocked = np.asarray(dyn.occluded(ray, mi.Float64(times)))
    for k, t in enumerate(TIMES):
        sl = slice(k * n_per_time, (k + 1) * n_per_time)
        ray_k = mi.Ray3f(mi.Point3f(*origins[sl].T.astype(np.float32)), mi.Vector3f(*dirs[sl].T.astype(np.float32)))
        ray_k.maxt = 4.0
        baked = _baked(dyn, t)
        ref = baked.ray_test(ray_k)
        dr.eval(ref)  # before `baked` can be freed: the lazy result refers to it
        ref = np.asarray(ref)
        assert 0.1 < ref.mean() < 0.9
        np.testing.assert_array_equal(blocked[sl], ref, err_msg=f"t={t}")


def test_ray_missing_the_start_pose_hits_the_body_later(dyn):
    """The swept-bounds cull must not reject rays that meet the body only late."""
    cube = [b for b in dyn.bodies if b.name == "cube"][0]
    index = dyn.bodies.index(cube) + 1
    origin = [0.85, -0.2, 3.0]  # inside the cube's end pose, outside its start pose
    for t, expect_cube in [(0.0, False), (2.0e-3, True)]:
        alone = mi.load_dict({"type": "scene", "c": {"type": "cube", "to_world": T(cube.motion.matrix(t).tolist())}})
        ray = mi.Ray3f(mi.Point3f(*origin), mi.Vector3f(0, 0, -1))
        assert bool(np.asarray(alone.ray_test(ray))[0]) == expect_cube  # the geometry is as intended
        hit = dyn.intersect(ray, mi.Float64([t]))
        assert (int(np.asarray(hit.body)[0]) == index) == expect_cube, f"t={t}"


def _retime_ref(motion, p, t_from, t_to):
    return _m(motion.matrix(t_to) @ np.linalg.inv(motion.matrix(t_from)), p)


@pytest.mark.parametrize("name", ["cube", "ball"])
def test_retime_equals_matrix_products(dyn, name):
    b = [i for i, body in enumerate(dyn.bodies) if body.name == name][0]
    motion = dyn.bodies[b].motion
    rng = np.random.default_rng(5)
    n = 200
    p = rng.uniform(-1.5, 1.5, (n, 3))
    t_from = rng.uniform(-0.2e-3, 2.2e-3, n)
    t_to = rng.uniform(-0.2e-3, 2.2e-3, n)
    out = dyn.retime(mi.Point3f(*p.T.astype(np.float32)), mi.UInt32(np.full(n, b + 1, dtype=np.uint32)), mi.Float64(t_from), mi.Float64(t_to))
    out = _np3(out)
    ref = np.array([_retime_ref(motion, p[i : i + 1], t_from[i], t_to[i])[0] for i in range(n)])
    np.testing.assert_allclose(out, ref, rtol=1e-5, atol=2e-5)
    assert np.abs(ref - p).max() > 0.1  # the points really moved


def test_retime_mixed_bodies_per_lane(dyn):
    rng = np.random.default_rng(6)
    n = 90
    p = rng.uniform(-1, 1, (n, 3))
    body = np.arange(n, dtype=np.uint32) % 3  # 0 = static, 1, 2 = bodies
    t_from, t_to = np.full(n, 0.3e-3), np.full(n, 1.7e-3)
    out = _np3(dyn.retime(mi.Point3f(*p.T.astype(np.float32)), mi.UInt32(body), mi.Float64(t_from), mi.Float64(t_to)))
    for i in range(n):
        if body[i] == 0:
            np.testing.assert_allclose(out[i], p[i], atol=1e-7)  # static points stay put
        else:
            ref = _retime_ref(dyn.bodies[body[i] - 1].motion, p[i : i + 1], t_from[i], t_to[i])[0]
            np.testing.assert_allclose(out[i], ref, rtol=1e-5, atol=2e-5)


def test_surface_velocity_is_the_rigid_velocity(dyn):
    rng = np.random.default_rng(7)
    n = 60
    p = rng.uniform(-1, 1, (n, 3))
    body = (np.arange(n, dtype=np.uint32) % 3).astype(np.uint32)
    t = rng.uniform(0.05e-3, 1.95e-3, n)
    v = _np3(dyn.surface_velocity(mi.Point3f(*p.T.astype(np.float32)), mi.UInt32(body), mi.Float64(t)))
    h = 1e-7
    for i in range(n):
        if body[i] == 0:
            np.testing.assert_array_equal(v[i], 0.0)
            continue
        motion = dyn.bodies[body[i] - 1].motion
        ref = (_retime_ref(motion, p[i : i + 1], t[i], t[i] + h) - _retime_ref(motion, p[i : i + 1], t[i], t[i] - h))[0] / (2 * h)
        np.testing.assert_allclose(v[i], ref, rtol=1e-4, atol=0.05)


def test_poses_one_per_body(dyn):
    poses = dyn.poses(mi.Float64([0.0, 1e-3]), precise=True)
    assert len(poses) == len(dyn.bodies)
    for pose, body in zip(poses, dyn.bodies):
        x = _np3(pose.point_to_world(mi.Point3d(0.1, 0.2, 0.3)))
        for i, t in enumerate([0.0, 1e-3]):
            np.testing.assert_allclose(x[i], _m(body.motion.matrix(t), np.array([[0.1, 0.2, 0.3]]))[0], atol=1e-10)


# ----------------------------------------------------------------------------------------
# Swept bounds fitted to the exposure window


def _travelling_cube_scene(key_times):
    """A half-metre cube at the origin that creeps 1 cm over the first key interval, then
    travels to x = 10 m by the last key; a wall behind."""
    start, creep, far = (T().translate([x, 0, 0]) @ T().scale(0.5) for x in (0.0, 0.01, 10.0))
    keys = list(zip(key_times, (start, creep, far)))
    return dt.load_scene(
        {
            "type": "scene",
            "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}},
            "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -3]).scale(20)},
            "cube": {"type": "cube", "motion": {"type": "keyframes", "keys": keys}},
        }
    )


def _down_ray(x):
    """Rays from z = 5 straight down −z at each of the x positions (m)."""
    x = np.asarray(x, dtype=np.float32)
    return mi.Ray3f(mi.Point3f(x, np.zeros_like(x), np.full_like(x, 5.0)), mi.Vector3f(0, 0, -1))


def _box_hit(scene, ray):
    body = scene.bodies[0]
    return np.asarray(scene._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, mi.Float(np.inf)))


def test_a_body_far_from_the_ray_during_the_window_is_skipped():
    scene = _travelling_cube_scene((0.0, 1.0e-3, 1.0))
    far = _down_ray([5.0])  # where the cube passes half a second later
    # Without a window the bounds cover the whole key range: the far ray may meet the cube.
    assert _box_hit(scene, far)[0]
    assert np.asarray(scene.intersect(far, mi.Float64([0.5])).body)[0] == 1

    scene.set_time_window(0.0, 1.0e-3)
    assert not _box_hit(scene, far)[0], "the cube stays within 1 cm of the origin in the window"
    assert _box_hit(scene, _down_ray([0.0]))[0]
    # The far ray now skips the body: even at a time outside the window, when the cube is
    # there, it sees the wall (rays' times must lie in the window).
    assert np.asarray(scene.intersect(far, mi.Float64([0.5])).body)[0] == 0


def test_the_time_window_leaves_hits_inside_it_unchanged():
    scene = _travelling_cube_scene((0.0, 1.0e-3, 1.0))
    rng = np.random.default_rng(8)
    n = 2000
    ray = _down_ray(rng.uniform(-0.7, 0.7, n))
    ray.o.y = mi.Float(rng.uniform(-0.7, 0.7, n).astype(np.float32))
    times = mi.Float64(rng.uniform(0.0, 1.0e-3, n))

    def hits():
        hit = scene.intersect(ray, times)
        dr.eval(hit.si.t, hit.body)
        return np.asarray(hit.si.t), np.asarray(hit.body)

    whole_range = hits()
    scene.set_time_window(0.0, 1.0e-3)
    windowed = hits()
    assert 0.2 < (whole_range[1] == 1).mean() < 0.9  # both the cube and the wall are hit
    np.testing.assert_array_equal(windowed[0], whole_range[0])
    np.testing.assert_array_equal(windowed[1], whole_range[1])


@pytest.mark.parametrize("window, pose_x", [((0.0, 1.0e-3), 0.0), ((3.0, 3.001), 10.0)])
def test_a_window_outside_the_keys_bounds_the_held_pose(window, pose_x):
    """Before the first key the body holds its first pose, after the last its last: the
    bounds are that pose's box, and rays in the window still hit the body there."""
    scene = _travelling_cube_scene((1.0, 1.5, 2.0))
    scene.set_time_window(*window)
    body = scene.bodies[0]
    lo = np.array([body.swept_min.x[0], body.swept_min.y[0], body.swept_min.z[0]])
    hi = np.array([body.swept_max.x[0], body.swept_max.y[0], body.swept_max.z[0]])
    np.testing.assert_allclose(lo, [pose_x - 0.5, -0.5, -0.5], atol=1e-4)
    np.testing.assert_allclose(hi, [pose_x + 0.5, 0.5, 0.5], atol=1e-4)
    ray = _down_ray([pose_x + 0.3])
    hit = scene.intersect(ray, mi.Float64([window[1]]))
    assert np.asarray(hit.body)[0] == 1
    assert np.asarray(hit.si.t)[0] == pytest.approx(4.5, abs=1e-5)


@pytest.mark.parametrize("window", [(1.0, 0.5), (0.0, float("inf")), (float("nan"), 1.0)])
def test_bad_time_window(window):
    scene = _travelling_cube_scene((0.0, 1.0e-3, 1.0))
    with pytest.raises(ValueError, match="time window"):
        scene.set_time_window(*window)


def _room_with(shape: dict, res: int) -> dict:
    """A closed grey room (walls at ±1 m, floor at 0, ceiling at 2), the camera at z = 3.5
    looking in, a point light beside it, and ``shape``."""
    grey = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.6, 0.5, 0.4]}}
    walls = {
        "floor": T().translate([0, 0, 0]).rotate([1, 0, 0], -90),
        "ceiling": T().translate([0, 2, 0]).rotate([1, 0, 0], 90),
        "back": T().translate([0, 1, -1]),
        "left": T().translate([-1, 1, 0]).rotate([0, 1, 0], 90),
        "right": T().translate([1, 1, 0]).rotate([0, 1, 0], -90),
    }
    return {
        "type": "scene",
        "sensor": {
            "type": "perspective", "fov": 40.0, "to_world": T().look_at(origin=[0, 1, 3.5], target=[0, 1, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
        },
        **{name: {"type": "rectangle", "to_world": m, "bsdf": grey} for name, m in walls.items()},
        "light": {"type": "point", "position": [0.4, 1.6, 2.0], "intensity": {"type": "rgb", "value": [8.0] * 3}},
        "thing": shape,
    }  # fmt: skip


@pytest.mark.parametrize(
    "shape",
    [
        {"type": "cube", "bsdf": {"type": "conductor"}, "to_world": T().translate([0.1, 0.8, -0.2]) @ T().rotate([0, 1, 0], 35) @ T().scale([0.45, 0.25, 0.3])},
        {"type": "sphere", "bsdf": {"type": "dielectric"}, "to_world": T().translate([0.0, 0.9, 0.0]) @ T().scale(0.35)},
    ],
    ids=["mirror-cube-scaled-per-axis", "glass-sphere"],
)
def test_a_moving_body_with_a_scale_shades_like_the_same_shape_at_rest(shape):
    """A body's scale (its shape's ``to_world``, which its motion takes over) stretches the
    ray in the body's frame, and every BSDF but the diffuse one reads the hit's ``wi``: a
    mirror cube scaled differently per axis and a glass sphere, moving 0.1 mm over the
    exposure, must render what the same shapes at rest render (a static scene: no body code)
    within noise. Before the hit's ``wi`` and frame were rebuilt in the world, both were off
    (and glass bodies of a street dataset gave NaN, which its sensor model refused)."""
    res, spp = 24, 256
    start = shape["to_world"]
    moving = {**shape, "motion": {"type": "keyframes", "keys": [(0.0, start), (1.5e-3, T().translate([1e-4, 0, 0]) @ start)]}}
    moving.pop("to_world")
    kw = dict(spp=spp, max_depth=6, time_sampling="uniform")
    body = dt.render(dt.load_scene(_room_with(moving, res)), seed=1, **kw)
    rest = dt.render(dt.load_scene(_room_with(shape, res)), seed=2, **kw)
    assert np.all(np.isfinite(body.intensity)) and np.all(np.isfinite(body.stderr))
    se = np.hypot(body.stderr, rest.stderr)
    seen = se > 0
    z = (body.intensity - rest.intensity)[seen] / se[seen]
    assert seen.mean() > 0.9
    # Measured with the fix, 3 seed pairs each: |z| > 4 nowhere, mean z -0.09-0.04, spread
    # 1.01-1.06; without it 26 % of the cube's |z| exceeded 4 (mean z 3.0) and 4 % of the
    # sphere's (spread 3.7).
    assert np.mean(np.abs(z) > 4) < 0.005 and abs(np.mean(z)) < 0.25 and np.std(z) < 1.3, (np.mean(np.abs(z) > 4), np.mean(z), np.std(z))
