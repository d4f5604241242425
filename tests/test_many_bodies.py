"""Many moving bodies: the tree traversal of :class:`dopplertof.scene.DynamicScene` against
the per-body loop (bit-identical hits, occlusion, poses and renders, with the bodies' poses
listed or from the table), the atlas traversal against it too (the same hits, values to
float32 rounding: its rays start where they enter a body's cell), and each against exact
ground truth for translating cubes.

The scene has 32 translating cubes on a lattice, two of them crossing (overlapping swept
boxes), a keyframed cube with three keys (rotation and scale: the pose table's key search)
and a sphere spinning about an off-centre pivot (a parametric motion, an analytic shape).
"""

import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.scene import LISTED_POSES_MAX_BODIES, PER_BODY_MAX_BODIES, PoseTable

T = mi.ScalarTransform4f
EXPOSURE = 1.5e-3
HALF = 0.08  # half side of the lattice cubes, m


def _grey(value):
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [value] * 3}}


def _lattice():
    """{key: (centre at t=0, velocity m/s)} of 32 cubes on an 8 x 4 lattice at z ≈ −3 m,
    facing the camera; odd ones move along z, even ones sideways; cubes 0 and 1 cross."""
    cubes = {}
    for i in range(32):
        x, y = -0.84 + 0.24 * (i % 8), -0.36 + 0.24 * (i // 8)
        z = -3.0 - 0.05 * (i % 5)
        velocity = (0.0, 0.0, 40.0 + 5 * (i % 3)) if i % 2 else (30.0, -20.0 * (i % 3), 0.0)
        cubes[f"cube-{i:02d}"] = ((x, y, z), velocity)
    # Cubes 0 and 1 swap places during the exposure: their swept boxes overlap.
    (x0, y0, z0), (x1, _, _) = cubes["cube-00"][0], cubes["cube-01"][0]
    cubes["cube-00"] = ((x0, y0, z0), ((x1 - x0) / EXPOSURE, 0.0, 0.0))
    cubes["cube-01"] = ((x1, y0, z0 - 0.02), ((x0 - x1) / EXPOSURE, 0.0, 0.0))
    return cubes


def _scene_dict(res=16, camera="perspective"):
    d = {
        "type": "scene",
        "sensor": {
            "type": camera,
            "near_clip": 1e-6,
            "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
            **({"fov": 40.0} if camera == "perspective" else {}),
        },
        "back": {"type": "rectangle", "to_world": T().translate([0, 0, -4]).scale(3), "bsdf": _grey(0.5)},
        "light": {"type": "point", "position": [0.0, 0.0, 0.0], "intensity": {"type": "rgb", "value": [10.0] * 3}},
    }
    for key, ((x, y, z), v) in _lattice().items():
        m0 = T().translate([x, y, z]) @ T().scale(HALF)
        m1 = T().translate([vi * EXPOSURE for vi in v]) @ m0
        d[key] = {"type": "cube", "bsdf": _grey(0.7), "motion": {"type": "keyframes", "keys": [(0.0, m0), (EXPOSURE, m1)]}}
    return d


def _extra_bodies(d):
    """Add the three-key cube and the spinning sphere (not axis-aligned translations)."""
    k0 = T().translate([0.3, 0.1, -2.2]) @ T().rotate([0, 1, 0], 10) @ T().scale([0.1, 0.06, 0.08])
    k1 = T().translate([0.35, 0.12, -2.3]) @ T().rotate([0.6, 0.8, 0.0], 50) @ T().scale([0.12, 0.06, 0.1])
    k2 = T().translate([0.4, 0.05, -2.25]) @ T().rotate([0, 0, 1], 120) @ T().scale(0.09)
    d["tumbler"] = {"type": "cube", "bsdf": _grey(0.6), "motion": {"type": "keyframes", "keys": [(0.0, k0), (0.7e-3, k1), (EXPOSURE, k2)]}}
    d["ball"] = {
        "type": "sphere",
        "to_world": T().translate([-0.4, -0.2, -2.4]) @ T().scale(0.12),
        "bsdf": _grey(0.4),
        "motion": {"type": "parametric", "linear_velocity": [20.0, 0, 0], "angular_velocity": [0, 0, 900.0], "pivot": [-0.45, -0.2, -2.4]},
    }
    return d


@pytest.fixture(scope="module")
def scene():
    s = dt.load_scene(_extra_bodies(_scene_dict()))
    assert len(s.bodies) == 34 > PER_BODY_MAX_BODIES
    s.set_time_window(0.0, EXPOSURE)
    return s


def _traversals(scene, query):
    """``query()`` with each traversal, as numpy arrays: {traversal: [arrays]}."""
    out = {}
    for traversal in ("per-body", "tree", "atlas"):
        scene.traversal = traversal
        try:
            values = query()
            dr.eval(values)
            out[traversal] = [np.array(v) for v in values]
        finally:
            scene.traversal = "auto"
    return out


def _assert_identical(a, b):
    for x, y in zip(a, b):
        assert x.shape == y.shape
        np.testing.assert_array_equal(x, y)


def _assert_same_hits(a, b, sphere_body):
    """``a``, ``b``: [body, t, ...]. The same bodies, primitives and occlusion, and the same
    values to float32 rounding. The atlas's rays start where they enter a body's cell,
    shifted by metres: a hit 30 µm from its origin moves by a rounding of the offset
    (0.4 µm, 1 % of t, so t is compared in absolute terms). On the spinning sphere
    (``sphere_body``) Mitsuba's sphere test (float32 on Embree) loses digits for an origin
    20 radii away, which the per-body loop has and the atlas, starting at the cell, has
    not: t differs by up to 0.15 % there, and the values computed from it (points,
    normals) are compared on the other bodies only.
    Where two overlapping bodies' coplanar faces tie (the crossing cubes 0 and 1) the atlas
    may break the tie the other way, at the same distance."""
    same = a[0] == b[0]
    assert same.mean() > 0.99
    np.testing.assert_allclose(a[1][~same], b[1][~same], rtol=1e-5)
    sphere = a[0][same] == sphere_body
    for k, (x, y) in enumerate(zip(a, b)):
        assert x.shape == y.shape
        x, y = x[..., same], y[..., same]
        if x.dtype.kind != "f":
            np.testing.assert_array_equal(x, y)
            continue
        np.testing.assert_array_equal(np.isfinite(x), np.isfinite(y))
        x, y = np.nan_to_num(x, posinf=0.0), np.nan_to_num(y, posinf=0.0)
        np.testing.assert_allclose(x[..., ~sphere], y[..., ~sphere], rtol=0 if k == 1 else 1e-5, atol=2e-6 if k == 1 else 1e-5)
        if k == 1:
            np.testing.assert_allclose(x[sphere], y[sphere], rtol=2e-3)


def _assert_traversals_agree(out, scene):
    _assert_identical(out["per-body"], out["tree"])
    _assert_same_hits(out["per-body"], out["atlas"], sphere_body=[b.name for b in scene.bodies].index("ball") + 1)


def _rays(n, seed):
    """Rays from the camera region into the scene, from inside the bodies' swept boxes (the
    lattice cubes' centres, so also inside the bodies) and from the overlap of cubes 0 and 1."""
    rng = np.random.default_rng(seed)
    cubes = list(_lattice().values())
    centres = np.array([c for c, _ in cubes])
    third = n // 3
    o = np.concatenate(
        [
            rng.uniform([-0.3, -0.3, -0.2], [0.3, 0.3, 0.0], (third, 3)),
            centres[rng.integers(0, len(centres), third)] + rng.uniform(-0.5, 0.5, (third, 3)) * HALF,
            np.array(cubes[0][0]) + rng.uniform([0.0, -HALF, -HALF], [0.24, HALF, HALF], (n - 2 * third, 3)),
        ]
    )
    target = rng.uniform([-1.0, -0.6, -3.3], [1.0, 0.6, -2.0], (n, 3))
    d = target - o
    d[third:] = rng.normal(size=(n - third, 3))  # any direction from inside
    d /= np.linalg.norm(d, axis=1)[:, None]
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(v) for v in o.T.astype(np.float32)]), mi.Vector3f(*[mi.Float(v) for v in d.T.astype(np.float32)]))
    return ray, mi.Float64(rng.uniform(0.0, EXPOSURE, n))


def test_closest_hits_are_bit_identical(scene):
    ray, time_s = _rays(6000, seed=1)

    def query():
        hit = scene.intersect(ray, time_s)
        si = hit.si
        return [hit.body, si.t, si.p, si.n, si.sh_frame.s, si.uv, si.prim_index, hit.p_local, hit.n_local, hit.plane_local]

    out = _traversals(scene, query)
    _assert_traversals_agree(out, scene)
    body = out["per-body"][0]
    assert len(np.unique(body)) > 30, "the rays reach most bodies"
    assert np.sum(body == 0) > 100, "and the static wall"


def test_secondary_hits_and_occlusion_are_bit_identical(scene):
    """Rays spawned from first hits (on the bodies: inside their swept boxes) towards random
    points, and shadow rays between hits and points."""
    ray, time_s = _rays(6000, seed=2)
    scene.traversal = "per-body"
    hit = scene.intersect(ray, time_s)
    rng = np.random.default_rng(3)
    target = mi.Point3f(*[mi.Float(v) for v in rng.uniform([-1.0, -0.6, -3.5], [1.0, 0.6, -1.0], (6000, 3)).T.astype(np.float32)])
    valid = hit.si.is_valid()
    spawned = hit.si.spawn_ray(dr.normalize(target - hit.si.p))
    shadow = hit.si.spawn_ray_to(target)
    dr.eval(spawned, shadow, valid)
    scene.traversal = "auto"

    def query():
        h = scene.intersect(spawned, time_s, valid)
        return [h.body, h.si.t, h.si.p, h.p_local, h.plane_local, scene.occluded(shadow, time_s, valid)]

    out = _traversals(scene, query)
    _assert_traversals_agree(out, scene)
    assert 0.2 < out["per-body"][-1][np.array(valid)].mean() < 0.9, "some shadow rays blocked, some not"


def test_poses_and_velocities_are_bit_identical(scene):
    rng = np.random.default_rng(4)
    n = 2000
    body = mi.UInt32(rng.integers(0, len(scene.bodies) + 1, n).astype(np.uint32))
    # times before, inside and after the key ranges
    time_s = mi.Float64(rng.uniform(-0.5e-3, 2.0e-3, n))
    p = mi.Point3f(*[mi.Float(v) for v in rng.uniform(-1, 1, (3, n)).astype(np.float32)])

    def query():
        out = []
        for precise in (False, True):
            pose = scene.select_pose(scene.poses(time_s, precise), body)
            out += [*pose.q, pose.scale, pose.translation, pose.omega, pose.translation_rate, pose.scale_rate]
        out.append(scene.surface_velocity(p, body, time_s))
        out.append(scene.retime(p, body, time_s, time_s + 1e-4))
        return out

    out = _traversals(scene, query)
    _assert_identical(out["per-body"], out["tree"])
    _assert_identical(out["per-body"], out["atlas"])  # no ray traced: poses alone


def test_pose_table_equals_each_motions_pose():
    """Keyframed motions with 1 to 4 keys and parametric motions, any time."""
    from dopplertof.motion import Keyframed, Parametric, compose

    rng = np.random.default_rng(5)

    def key(i):
        q = rng.normal(size=4)
        return compose(rng.normal(size=3), q / np.linalg.norm(q), rng.uniform(0.5, 2, 3))

    motions = [Keyframed(np.cumsum(rng.uniform(1e-4, 1e-3, k)), [key(i) for i in range(k)]) for k in (1, 2, 3, 4, 2)]
    motions += [Parametric(rng.normal(size=3), rng.normal(size=3) * 100, rng.normal(size=3), base=key(0)), Parametric((1, 2, 3))]
    table = PoseTable(motions)
    n = 3000
    body = rng.integers(0, len(motions), n).astype(np.uint32)
    time_s = mi.Float64(rng.uniform(-1e-3, 4e-3, n))
    for precise in (False, True):
        got = table.pose(mi.UInt32(body), time_s, precise)
        for b, motion in enumerate(motions):
            want = motion.pose(time_s, precise)
            lanes = body == b
            for x, y in zip(_flat(got), _flat(want)):
                np.testing.assert_array_equal(np.array(x)[lanes], np.broadcast_to(np.array(y), n)[lanes])


def _flat(pose):
    return [*pose.q, *pose.scale, *pose.translation, *pose.omega, *pose.translation_rate, *pose.scale_rate]


def test_window_change_refits_the_tree_as_data(scene):
    """A new window moves the swept boxes (and the tree); the old one restores them."""
    box = scene.bodies[0].swept_box
    scene.set_time_window(0.0, 0.1e-3)
    assert not np.allclose(scene.bodies[0].swept_box[1], box[1])
    tree_lo = np.array(scene._tree.lo)
    scene.set_time_window(0.0, EXPOSURE)
    np.testing.assert_array_equal(scene.bodies[0].swept_box[1], box[1])
    assert not np.array_equal(tree_lo, np.array(scene._tree.lo))


def _assert_renders_agree(results):
    """The tree's render bit-identical to the per-body loop's; the atlas's the same on
    nearly every pixel and within 0.5 % (or 0.2 % of the image's largest value, for the
    heterodyne measurements' cancellations) on the rest: the rounding of _assert_same_hits,
    the spinning sphere's float32 digits among it."""
    a = results["per-body"]
    for name in ("intensity", "measurements", "depth", "velocity", "instance_id"):
        x, y = getattr(a, name), getattr(results["atlas"], name)
        np.testing.assert_array_equal(x, getattr(results["tree"], name), err_msg=name)
        np.testing.assert_allclose(x, y, rtol=5e-3, atol=2e-3 * np.nanmax(np.abs(x)), err_msg=name)
        close = np.isclose(x, y, rtol=1e-5, atol=1e-7) | (np.isnan(x) & np.isnan(y))
        assert close.mean() > 0.97, (name, close.mean())


def test_render_is_identical_through_every_traversal(scene):
    """Intensity, a D-ToF camera (Float64 path lengths, shadow rays) and the ground truth."""
    results = {}
    for traversal in ("per-body", "tree", "atlas"):
        scene.traversal = traversal
        try:
            results[traversal] = dt.render(scene, cameras=[dt.Camera(heterodyne=1.0, phase=0.5)], spp=4, max_depth=3, seed=7)
        finally:
            scene.traversal = "auto"
    _assert_renders_agree(results)
    assert len(np.unique(results["per-body"].instance_id)) > 20


def test_few_bodies_render_identically_through_every_traversal():
    """Up to LISTED_POSES_MAX_BODIES bodies the poses are a list, which either traversal
    takes: a few cubes (two crossing), the keyframed cube and the spinning sphere."""
    d = _scene_dict(res=12)
    for key in [k for k in d if k.startswith("cube-")][6:]:
        del d[key]
    scene = dt.load_scene(_extra_bodies(d))
    assert 2 < len(scene.bodies) <= LISTED_POSES_MAX_BODIES and isinstance(scene.poses(mi.Float64(0.0)), list)
    results = {}
    for traversal in ("per-body", "tree", "atlas"):
        scene.traversal = traversal
        results[traversal] = dt.render(scene, cameras=[dt.Camera(heterodyne=1.0, phase=0.5)], spp=4, max_depth=3, seed=7)
    _assert_renders_agree(results)
    assert len(np.unique(results["per-body"].instance_id)) > 4


def _pixel_dz_range(res, fov_deg=40.0):
    """Per pixel (rows top-down), the range of −d_z of the pinhole's rays through it."""
    tan = math.tan(math.radians(fov_deg / 2))
    edges = (2 * np.arange(res + 1) / res - 1) * tan
    lo, hi = edges[:-1], edges[1:]
    near = np.where((lo < 0) & (hi > 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    far = np.maximum(np.abs(lo), np.abs(hi))
    r2_near = near[:, None] ** 2 + near[None, :] ** 2
    r2_far = far[:, None] ** 2 + far[None, :] ** 2
    return 1 / np.sqrt(1 + r2_far), 1 / np.sqrt(1 + r2_near)


def _sees_front_face(res, centre, z_face, fov_deg=40.0):
    """Pixels (rows top-down) whose every ray enters the cube at ``centre`` through its
    front face (the square of half side ``HALF`` at ``z_face``), not a side face."""
    tan = math.tan(math.radians(fov_deg / 2))
    edges = (2 * np.arange(res + 1) / res - 1) * tan * -z_face  # on the face's plane, m
    x_in = (edges[:-1] >= centre[0] - HALF) & (edges[1:] <= centre[0] + HALF)
    y_in = (-edges[1:] >= centre[1] - HALF) & (-edges[:-1] <= centre[1] + HALF)
    return y_in[:, None] & x_in[None, :]


@pytest.mark.parametrize("traversal", ["per-body", "tree", "atlas"])
def test_translating_cubes_ground_truth_is_exact(traversal):
    """One ray per pixel at one instant, camera at the origin: on a cube's front face
    (normal +z, at z_f) the hit is depth·d̂ with d_z = z_f / depth inside the pixel, and the
    ray-fixed velocity (n·v)/(n·d̂) = v_z / d_z = v_z · depth / z_f."""
    res = 64
    scene = dt.load_scene(_scene_dict(res=res))
    scene.traversal = traversal
    assert len(scene.bodies) == 32 and scene.traversal_in_use() == traversal
    r = dt.render(scene, spp=1, time_sampling="uniform", max_depth=2, exposure=1e-9, seed=3)
    dz_min, dz_max = _pixel_dz_range(res)
    cubes = _lattice()
    checked = 0
    for b, body in enumerate(scene.bodies):
        (_, _, z), v = cubes[body.name]
        z_face = z + HALF
        on = (r.instance_id == b) & (r.coverage == 1) & _sees_front_face(res, cubes[body.name][0], z_face)
        depth = r.depth[on].astype(np.float64)
        minus_dz = -z_face / depth
        assert np.all((minus_dz >= dz_min[on] - 1e-6) & (minus_dz <= dz_max[on] + 1e-6)), body.name
        np.testing.assert_allclose(r.velocity[on], v[2] * depth / z_face, rtol=1e-5, atol=1e-6, err_msg=body.name)
        checked += on.sum()
    assert checked > 150  # about 9 pixels a cube


def test_cuda_walks_the_atlas_never_dr_switch(monkeypatch):
    """On CUDA the tree's dr.switch traces would run inside OptiX direct callables:
    ``"auto"`` takes the atlas there, whatever the number of bodies, and ``"tree"`` is
    refused, naming itself and the atlas."""
    scene = dt.load_scene(_extra_bodies(_scene_dict(res=4)))
    few = dt.load_scene({k: v for k, v in _scene_dict(res=4).items() if not k.startswith("cube-") or k < "cube-02"})
    assert len(scene.bodies) > PER_BODY_MAX_BODIES and len(few.bodies) == 2
    assert (scene.traversal_in_use(), few.traversal_in_use()) == ("tree", "per-body")  # LLVM: the tree above PER_BODY_MAX_BODIES
    monkeypatch.setattr(mi, "variant", lambda: "cuda_ad_rgb")
    assert scene.traversal_in_use() == few.traversal_in_use() == "atlas" and scene.uses_tree()
    scene.traversal = "tree"
    with pytest.raises(ValueError, match="traversal='tree'.*cuda_ad_rgb; use 'atlas'"):
        scene.uses_tree()
