"""``traversal="slices"`` (:mod:`dopplertof.slices`): one Mitsuba scene per correlated member,
placed at its instant. Its hits are the per-lane traversals' at that instant, its renders
estimate the same images, and what it cannot trace yet it refuses."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from test_many_bodies import EXPOSURE, _extra_bodies, _grey, _rays, _scene_dict

T = mi.ScalarTransform4f


@pytest.fixture(scope="module")
def scene():
    s = dt.load_scene(_extra_bodies(_scene_dict()))
    s.set_time_window(0.0, EXPOSURE)
    return s


def _hits(scene, traversal, ray, time_s):
    scene.traversal = traversal
    try:
        hit = scene.intersect(ray, time_s)
        blocked = scene.occluded(mi.Ray3f(ray.o, ray.d, 2.5), time_s)
        values = [hit.body, hit.si.t, hit.n_local, hit.plane_local, blocked]
        dr.eval(values)
        return [np.array(v) for v in values]
    finally:
        scene.traversal = "auto"


def test_member_scenes_hit_what_the_bodies_hit_at_their_instants(scene):
    """Rays at the two members' times meet in the member scenes the bodies, distances,
    rest-frame normals and planes the per-body loop finds at those times (to float32
    rounding: the member scenes hold the bodies placed in the world)."""
    ray, _ = _rays(3000, seed=5)
    times = (0.3e-3, 1.1e-3)
    slices = scene.slice_scenes(2)
    slices.place(times)
    time_s = mi.Float64(np.where(np.arange(dr.width(ray.o)) % 2, *times[::-1]))
    a, b = _hits(scene, "per-body", ray, time_s), _hits(scene, "slices", ray, time_s)
    same = a[0] == b[0]
    assert same.mean() > 0.99 and (a[0] > 0).mean() > 0.2
    hit = same & np.isfinite(a[1])
    sphere = a[0] == [x.name for x in scene.bodies].index("ball") + 1  # Mitsuba's float32 sphere test: see test_many_bodies
    np.testing.assert_allclose(a[1][hit & ~sphere], b[1][hit & ~sphere], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(a[1][hit & sphere], b[1][hit & sphere], rtol=2e-3)
    moving_mesh = hit & (a[0] > 0) & ~sphere
    np.testing.assert_allclose(a[2][:, moving_mesh], b[2][:, moving_mesh], atol=1e-6)  # the rest triangle's normal
    np.testing.assert_array_equal(a[3][:, moving_mesh], b[3][:, moving_mesh])  # and its first vertex
    assert (a[4] == b[4]).mean() > 0.99


def test_member_scenes_give_the_per_lane_tracers_float64_distances(scene):
    """The Float64 distances a path's optical length is made of (``hit_distance64``), from
    Float64 origins at the two members' times: on triangles, moving or static, the member
    scenes' world planes at those instants (a table of Float64 planes placed by the bodies'
    Float64 poses) give the per-body loop's distances (its rest planes, the ray taken into
    the body's frame) to 1e-9 m, where the float32 distances of the same hits are off by up
    to 1e-7 relative: so the distances of two instants differ by the motion alone."""
    from dopplertof.tracing.path import hit_distance64

    ray, _ = _rays(3000, seed=7)
    times = (0.2e-3, 1.3e-3)
    scene.slice_scenes(2).place(times)
    time_s = mi.Float64(np.where(np.arange(dr.width(ray.o)) % 2, *times[::-1]))
    origin = mi.Vector3d(ray.o) + mi.Vector3d(1e-9, -2e-9, 3e-9)  # not float32 numbers

    def distances(traversal):
        scene.traversal = traversal
        try:
            hit = scene.intersect(ray, time_s)
            t64, _ = hit_distance64(scene, scene.poses(time_s, precise=True), hit, origin, ray.d)
            values = [hit.body, t64, hit.si.t, hit.si.shape.is_mesh()]
            dr.eval(values)
            return [np.array(v) for v in values]
        finally:
            scene.traversal = "auto"

    a, b = distances("per-body"), distances("slices")
    on_triangle = (a[0] == b[0]) & np.isfinite(a[1]) & a[3] & b[3]
    assert on_triangle.mean() > 0.5 and (on_triangle & (a[0] > 0)).mean() > 0.2
    np.testing.assert_allclose(b[1][on_triangle], a[1][on_triangle], rtol=0, atol=1e-9)
    assert np.abs(b[2][on_triangle] - a[1][on_triangle]).max() > 1e-8  # float32 is seen: the check can fail


def test_a_render_in_pixel_tiles_is_the_render_in_one():
    """Films larger than a pass (``lanes_per_pass``) are traced in tiles of pixels: each
    tile's groups replay a recording with the tile's first pixel as data, and the last,
    smaller tile has a recording of its own. Split into four tiles (three of 512 pixels,
    one of 64), the render is the one-pass render bit for bit, its errors to rounding (a
    recording that kept its first tile's pixels rendered other pixels than the tile's, and
    the smaller tile failed)."""
    scene = dt.load_scene(_extra_bodies(_scene_dict(res=40)))
    scene.traversal = "slices"
    options = dict(spp=8, seed=3, cameras=[dt.Camera(heterodyne=1.0)])
    tiled, whole = dt.render(scene, lanes_per_pass=1024, **options), dt.render(scene, **options)
    for name in ("intensity", "measurements"):
        np.testing.assert_array_equal(np.asarray(getattr(tiled, name)), np.asarray(getattr(whole, name)), err_msg=name)
    # (the errors' sums are grouped by pass: equal to rounding, as with the per-lane tracer)
    np.testing.assert_allclose(np.asarray(tiled.measurement_stderr), np.asarray(whole.measurement_stderr), rtol=1e-6)


def test_moving_meshes_of_one_material_are_one_mesh():
    """A member scene merges the moving meshes whose BSDFs are of one definition (the 32
    grey cubes: one update and one Embree geometry, not 32); a BSDF that differs in a value
    below its printed precision, and an area light, keep meshes of their own (merged, they
    would render another material or lose the emitter). Hits on the merged mesh find their
    bodies: see the test above, on the same cubes."""
    from dopplertof.slices import _same_bsdf

    d, almost = _scene_dict(), float(np.nextafter(np.float32(0.7), np.float32(1)))  # one float32 step above
    for name, extra, dx in (("almost", {"bsdf": _grey(almost)}, 0.01), ("lamp", {"bsdf": _grey(0.7), "emitter": {"type": "area"}}, 0.02)):
        m0 = T().translate([0.5, 0.4, -2.0]) @ T().scale(0.05)
        d[name] = {"type": "cube", **extra, "motion": {"type": "keyframes", "keys": [(0.0, m0), (EXPOSURE, T().translate([dx, 0, 0]) @ m0)]}}
    scene = dt.load_scene(d)
    placement = scene.slice_scenes(2).placements[0]
    names = [b.name for b in scene.bodies]
    groups = sorted(sorted(names[i] for i in set(placement.vertex_body[a:b].tolist())) for _, a, b in placement.spans)
    lattice = sorted(n for n in names if n not in ("almost", "lamp"))
    assert groups == sorted([lattice, ["almost"], ["lamp"]])
    grey, almost = (mi.load_dict(_grey(v)) for v in (0.7, almost))
    assert str(grey) == str(almost) and not _same_bsdf(grey, almost) and _same_bsdf(grey, mi.load_dict(_grey(0.7)))


def _cameras():
    return [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]


def test_slices_render_what_the_per_lane_tracer_renders():
    """The moving Cornell box: the slices' measurements and intensity estimate the
    per-lane tracer's (independent seeds; z of their differences has unit spread), and so
    does the ground-truth depth."""
    results = {}
    for traversal, seed in (("auto", 1), ("slices", 2)):
        scene = dt.scenes.build("cornell-box", resolution=24)
        scene.traversal = traversal
        results[traversal] = dt.render(scene, spp=64, seed=seed, cameras=_cameras())
    a, b = results["auto"], results["slices"]
    e = np.sqrt(np.asarray(a.measurement_stderr, np.float64) ** 2 + np.asarray(b.measurement_stderr, np.float64) ** 2)
    keep = e > 0
    z = (np.asarray(a.measurements, np.float64) - np.asarray(b.measurements, np.float64))[keep] / e[keep]
    assert keep.sum() > 1000 and abs(z.mean()) < 0.15 and 0.7 < z.std() < 1.6
    ia, ib = np.asarray(a.intensity, np.float64), np.asarray(b.intensity, np.float64)
    assert abs(ia.mean() / ib.mean() - 1) < 0.02
    np.testing.assert_allclose(np.nanmean(np.asarray(a.depth)), np.nanmean(np.asarray(b.depth)), rtol=5e-3)


def test_a_moving_glass_body_is_traced_through():
    """A moving dielectric sphere in front of a wall: its copies in the member scenes have
    BSDFs of their own, which the material tables hold (finite optical lengths), and the
    image matches the per-lane tracer's."""
    d = {
        "type": "scene",
        "sensor": {"type": "perspective", "fov": 40, "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 16, "height": 16}},
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -4]).scale(3), "bsdf": {"type": "diffuse"}},
        "light": {"type": "point", "position": [0.0, 0.5, 0.0], "intensity": {"type": "rgb", "value": [10.0] * 3}},
        "ball": {"type": "sphere", "to_world": T().translate([0, 0, -2]).scale(0.5), "bsdf": {"type": "dielectric"},
                 "motion": {"type": "parametric", "linear_velocity": [0, 0, 10.0]}},
    }  # fmt: skip
    scene = dt.load_scene(d)
    scene.traversal = "slices"
    result = dt.render(scene, spp=32, seed=3, cameras=_cameras())
    assert np.isfinite(np.asarray(result.measurements)).all() and np.isfinite(np.asarray(result.intensity)).all()
    scene.traversal = "auto"
    reference = dt.render(scene, spp=32, seed=4, cameras=_cameras())
    assert abs(np.asarray(result.intensity).mean() / np.asarray(reference.intensity).mean() - 1) < 0.05


def _z(a, b):
    """Per measurement, the difference of two independent estimates in their standard errors."""
    m1, m2 = np.asarray(a.measurements, np.float64), np.asarray(b.measurements, np.float64)
    e1, e2 = np.asarray(a.measurement_stderr, np.float64), np.asarray(b.measurement_stderr, np.float64)
    keep = (e1 > 0) & (e2 > 0)
    return (m1 - m2)[keep] / np.sqrt(e1**2 + e2**2)[keep]


@pytest.mark.parametrize("options", [dict(correlation="reconnection"), dict(correlation="adaptive"), dict(time_sampling="analytic")])
def test_paired_estimators_trace_both_instants_in_their_member_scenes(options):
    """A paired lane traces its primal in one member's scene and its partner in the
    other's (analytic: the exposure's ends): the measurements are the per-lane tracer's
    within their standard errors (other paths: independent errors). Placing the analytic
    members at sampled times instead gave a z spread of 3.2."""
    scene = dt.scenes.build("cornell-box", resolution=12)
    out = {}
    for seed, traversal in enumerate(("auto", "slices")):
        scene.traversal = traversal
        out[traversal] = dt.render(scene, spp=32, seed=seed, cameras=_cameras(), **options)
    z = _z(out["slices"], out["auto"])
    assert len(z) > 100 and np.std(z) < 1.3 and np.mean(np.abs(z) > 4) < 0.01, (np.std(z), np.mean(np.abs(z) > 4))
    assert abs(np.asarray(out["slices"].intensity).mean() / np.asarray(out["auto"].intensity).mean() - 1) < 0.05


@pytest.mark.parametrize("options", [dict(time_sampling="uniform"), dict(time_sampling="stratified"), dict(time_sampling="antithetic", n_times=4), dict(correlation="none")])
def test_every_unpaired_time_sampling_renders(options):
    """Each member of a kernel at its own instant, whatever the group's size and the
    correlation: the intensity is the per-lane tracer's within noise."""
    scene = dt.scenes.build("cornell-box", resolution=12)
    out = {}
    for traversal in ("auto", "slices"):
        scene.traversal = traversal
        out[traversal] = dt.render(scene, spp=32, seed=5, cameras=_cameras()[:2], **options)
    assert np.isfinite(np.asarray(out["slices"].measurements)).all()
    assert abs(np.asarray(out["slices"].intensity).mean() / np.asarray(out["auto"].intensity).mean() - 1) < 0.05


def test_garbage_collected_while_a_pass_is_recorded_breaks_nothing():
    """Python's collector does not free Mitsuba objects while ``dr.freeze`` records a
    pass: Dr.Jit 1.5 then fails the recording (every group traced anew, with a warning) or
    aborts the process. Here the collector is asked to run inside the recording, with the
    garbage of an earlier scene waiting (in a child process: an abort would end pytest)."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(
        """
        import gc, warnings
        import dopplertof as dt
        import mitsuba as mi
        from dopplertof.slices import SliceScenes

        gc.disable()  # the garbage below stays until a collection is asked for
        mi.set_variant("llvm_ad_rgb")
        garbage = [mi.load_dict(mi.cornell_box())]
        garbage.append(garbage)  # a reference cycle: freed by the collector alone
        del garbage
        set_state = SliceScenes.set_state

        def collect_and_set_state(self, state):  # runs while the pass is recorded
            gc.collect()
            return set_state(self, state)

        SliceScenes.set_state = collect_and_set_state
        scene = dt.scenes.build("cornell-box", resolution=8)
        scene.traversal = "slices"
        warnings.simplefilter("error")
        dt.render(scene, spp=8, cameras=[dt.Camera()])
        print("rendered")
        """
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "rendered" in run.stdout, run.stderr[-2000:]


@pytest.mark.parametrize("name", ["lamp", "street"])
def test_a_slice_pass_is_given_the_motions_it_reads_and_no_other(name):
    """A recorded pass's replays walk its inputs, so the bodies' motions its kernel reads
    only through the pose table's concatenation are left out of them (with 128 cubes,
    2816 of 3526 inputs); what reads a motion itself keeps it: a body's area emitter, the
    camera, a moving light (street). Dr.Jit refuses to record a pass that reads an array
    it was not given, so the render also shows that nothing it reads was left out: it
    records and replays without falling back (a warning). A first version left the
    camera's and the light's motions out with the bodies', and the street's recording
    failed."""
    import warnings

    from dopplertof.slices import kernel_inputs, table_only_motions
    from dopplertof.tracing.materials import MaterialTables

    if name == "lamp":
        d = _extra_bodies(_scene_dict())
        m0 = T().translate([0.5, 0.4, -2.0]) @ T().scale(0.05)
        d["lamp"] = {"type": "cube", "bsdf": _grey(0.7), "emitter": {"type": "area"}, "motion": {"type": "keyframes", "keys": [(0.0, m0), (EXPOSURE, T().translate([0.02, 0, 0]) @ m0)]}}
        scene = dt.load_scene(d)
    else:
        scene = dt.scenes.build(name, resolution=16)
    left = table_only_motions(scene)
    read_directly = [b.motion for b in scene.bodies if b.scene.emitters()] + scene.motions()[len(scene.bodies) :]
    assert read_directly and left and not {id(m) for m in read_directly} & {id(m) for m in left}
    inputs = {id(x) for x in kernel_inputs(scene, MaterialTables.of(scene), leave_out=left)}
    assert not inputs & {id(a) for m in left for a in m._data.values()}
    assert {id(a) for m in read_directly for a in m._data.values()} <= inputs
    scene.traversal = "slices"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = dt.render(scene, spp=8, seed=1, cameras=_cameras()[:1])  # four groups in one pass: three replays
    assert np.isfinite(np.asarray(result.measurements)).all()


@pytest.mark.parametrize("name", ["cornell-box", "street"])
def test_a_slice_pass_is_recorded_once(name, monkeypatch):
    """A render's groups replay one recording of the pass: none records again (a trace
    and a kernel compile more). Before, the first replay's write-back made the third
    group record again (two recordings). (A moving disk still records twice: Mitsuba
    derives literals from its placed transform, its du and dv, that change with every
    placement.)"""
    made = []
    freeze = dr.freeze

    def spy(f=None, **kwargs):
        made.append(freeze(f, **kwargs))
        return made[-1]

    monkeypatch.setattr(dr, "freeze", spy)
    scene = dt.scenes.build(name, resolution=16)
    scene.traversal = "slices"
    dt.render(scene, spp=8, seed=1, cameras=_cameras()[:1])  # four groups in one pass
    assert made and [f.n_recordings for f in made] == [1] * len(made)


@pytest.mark.parametrize("name", [*sorted(dt.scenes.SCENES), "original_cornell.xml", "readme_scene.xml"])
def test_every_built_in_scene_renders_with_slices_as_with_the_per_lane_tracer(name):
    """Every built-in scene (moving camera, moving lights, area lights, glass, 24 bodies)
    and the scene files of others (the original authors', the README's with its shutter
    and ``<animation>``): with the same seed the paths differ only by their times (a
    pixel's times are drawn once for all pixels), so the same surfaces are seen and the
    images are nearly equal; the pass is recorded and replayed (no fallback warning: the
    original authors' file once fell back, its kernel calling shapes the recording did not
    hold)."""
    import warnings
    from pathlib import Path

    if name.endswith(".xml"):
        scene = dt.load_scene(str(Path(__file__).parent / "data" / name), film_resolution=16)
    else:
        scene = dt.scenes.build(name, resolution=16)
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for traversal in ("auto", "slices"):
            scene.traversal = traversal
            out[traversal] = dt.render(scene, spp=8, seed=3)
    seen = {t: np.asarray(r.maps["instance_id"]) for t, r in out.items()}
    assert np.mean(seen["slices"] == seen["auto"]) > 0.99
    assert np.isfinite(np.asarray(out["slices"].measurements)).all()
    assert abs(np.asarray(out["slices"].intensity).mean() / np.asarray(out["auto"].intensity).mean() - 1) < 0.01


_CHILD_ENV = "DOPPLERTOF_TEST_SLICES_CHILD"  # set in the child process that runs the test below


# Measured with this test's settings (two sets of 64 seeds each, before it was written): the
# slices' per-pixel MSE ÷ the per-lane tracer's was 0.98-1.00 at h = 0, 0.98-1.01 at h = ½
# and 0.99-1.07 at h = 1, their z spreads within 0.01 of each other (the per-lane tracer's
# own: 1.2-1.5, from heavy-tailed errors at moving outlines, docs/estimators.md).
@pytest.mark.slow
@pytest.mark.parametrize("name", ["cornell-box", "rotating"])
def test_slices_keep_each_pixels_error(name):
    """Issue 17's variance test: a pixel's estimator keeps its distribution when its times
    are shared by every pixel of a kernel. Against a 16384-spp reference of the per-lane
    tracer, 96 renders of 64 spp with each traversal (the same seeds: the paths differ only
    by their times) have per-pixel mean squared errors within 10 % of each other at every
    heterodyne frequency h, and the z-scores of their stated standard errors the same
    spread. The errors of one slices render are correlated across its pixels, so its MSE
    is noisier than the per-lane tracer's: many renders, few pixels.

    Run in a child process of its own: a slices render runs Python's full garbage
    collection before it records its pass (``passes.PassTracer._sliced``), which in the
    suite's process, with millions of objects, cost more than the renders (measured ad hoc:
    the Cornell box's half took 24 s with two million objects added to the process, 9.5 s
    without; docs/troubleshooting.md)."""
    if os.environ.get(_CHILD_ENV) != name:
        child = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"{__file__}::test_slices_keep_each_pixels_error[{name}]"],
                               env={**os.environ, _CHILD_ENV: name}, capture_output=True, text=True, timeout=1200)  # fmt: skip
        assert child.returncode == 0 and "1 passed" in child.stdout, child.stdout[-3000:] + child.stderr[-2000:]
        return
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 0.5, 1.0) for p in (0.0, math.pi / 2)]
    scene = dt.scenes.build(name, resolution=16)
    reference = dt.render(scene, spp=16384, seed=1000003, cameras=cameras, max_depth=4)
    ref = np.asarray(reference.measurements, np.float64)
    ref_var = np.asarray(reference.measurement_stderr, np.float64) ** 2
    squares, spreads = {}, {}
    for traversal in ("auto", "slices"):
        scene.traversal = traversal
        sq, z = [], []
        for seed in range(96):
            r = dt.render(scene, spp=64, seed=seed, cameras=cameras, max_depth=4)
            x, var = np.asarray(r.measurements, np.float64), np.asarray(r.measurement_stderr, np.float64) ** 2
            sq.append((x - ref) ** 2 - ref_var)
            both = var + ref_var
            z.append(np.where(both > 0, (x - ref) / np.sqrt(np.where(both > 0, both, 1.0)), np.nan))
        squares[traversal], spreads[traversal] = np.stack(sq), np.stack(z)
    for k, h in enumerate((0.0, 0.5, 1.0)):
        cams = [2 * k, 2 * k + 1]
        ratio = squares["slices"][:, cams].mean() / squares["auto"][:, cams].mean()
        z_ratio = np.nanstd(spreads["slices"][:, cams]) / np.nanstd(spreads["auto"][:, cams])
        assert 0.9 < ratio < 1.1 and abs(z_ratio - 1) < 0.05, (h, ratio, z_ratio)
