"""The body atlas (:mod:`dopplertof.atlas`), the traversal CUDA takes: every built-in scene
renders as through the per-body loop, an emitter on a moving body is seen through it (a
hit on a copy is handed back as a hit on the body's own shape), its cells keep the bodies
apart, it shares the pipeline host, and what it cannot hold is refused or left to the
per-body loop. (The many-bodies suite compares its hits with the other traversals'.)"""

import dataclasses

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.atlas import BodyAtlas
from dopplertof.loader import HOST_KEY
from scene_dicts import T, grey

CAMERAS = [dt.Camera(heterodyne=0.0), dt.Camera(heterodyne=1.0, phase=0.5)]


def _render_both(scene, **kw):
    out = {}
    for traversal in ("per-body", "atlas"):
        scene.traversal = traversal
        out[traversal] = dt.render(scene, CAMERAS, max_depth=3, seed=1, **kw)
    scene.traversal = "auto"
    return out["per-body"], out["atlas"]


@pytest.mark.parametrize("name", list(dt.scenes.SCENES))
def test_every_built_in_scene_renders_through_the_atlas_as_through_the_per_body_loop(name):
    """The same seed: the same paths, so the same images up to float32 rounding (a ray
    through the atlas starts where it enters the body's cell), which may turn a sample at
    an edge between two faces (the street's cars) onto the other face: a few pixels'
    ground truth then differs by that sample's share."""
    scene = dt.scenes.build(name, resolution=12)
    start = 0.5 * dt.scenes.clip_duration(name)
    for correlation in ("replay", "reconnection"):
        a, b = _render_both(scene, spp=8, correlation=correlation, exposure_start=start)
        np.testing.assert_array_equal(a.instance_id, b.instance_id)
        for field in ("intensity", "measurements", "depth", "velocity"):
            x, y = getattr(a, field), getattr(b, field)
            close = np.isclose(x, y, rtol=1e-4, atol=1e-5 * np.nanmax(np.abs(x))) | (np.isnan(x) & np.isnan(y))
            assert close.mean() > 0.97, f"{correlation} {field}: {close.mean():.3f} of the pixels agree"
            if field in ("intensity", "measurements"):
                np.testing.assert_allclose(x, y, rtol=1e-2, atol=1e-3 * np.nanmax(np.abs(x)), err_msg=f"{correlation} {field}")


def _glowing_panel_scene():
    """A camera facing a moving emissive panel (seen directly and lighting a wall) and a
    moving grey cube in front of the wall."""
    return {
        "type": "scene",
        "sensor": {
            "type": "perspective", "fov": 50, "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
        },
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -4]).scale(3), "bsdf": grey(0.5)},
        "panel": {
            "type": "rectangle", "to_world": T().translate([-0.5, 0.3, -2.5]).rotate([0, 1, 0], 20).scale(0.4), "bsdf": grey(0.2),
            "glow": {"type": "area", "radiance": {"type": "rgb", "value": 5.0}},
            "motion": {"type": "parametric", "linear_velocity": [10.0, 0, 0]},
        },
        "box": {"type": "cube", "to_world": T().translate([0.5, -0.3, -3]).scale(0.3), "bsdf": grey(0.7),
                "motion": {"type": "parametric", "linear_velocity": [0, 0, 20.0]}},
    }  # fmt: skip


def test_an_emitter_on_a_moving_body_is_seen_and_lights_through_the_atlas():
    scene = dt.load_scene(_glowing_panel_scene())
    assert len(scene.bodies) == 2
    a, b = _render_both(scene, spp=16)
    panel = a.instance_id == [body.name for body in scene.bodies].index("panel")
    assert panel.sum() > 10 and np.median(a.intensity[panel]) == 5.0  # seen: its radiance
    np.testing.assert_allclose(b.intensity, a.intensity, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(b.measurements, a.measurements, rtol=1e-4, atol=1e-6)


def test_each_body_lies_in_a_cell_of_its_own():
    scene = dt.scenes.build("dominoes", resolution=4)
    atlas = scene._body_atlas()
    boxes = []
    for b, body in enumerate(scene.bodies):
        lo, hi = (np.asarray(v) + atlas.offsets_m[b] for v in body.bounds_local)
        boxes.append((lo, hi))
    for shape in atlas.scene.shapes():
        box = shape.bbox()
        lo, hi = np.array([box.min.x, box.min.y, box.min.z]), np.array([box.max.x, box.max.y, box.max.z])
        assert sum(np.all(lo >= blo - 1e-5) and np.all(hi <= bhi + 1e-5) for blo, bhi in boxes) == 1  # in exactly one body's box
    for i, (lo_i, hi_i) in enumerate(boxes):
        for lo_j, hi_j in boxes[i + 1 :]:
            assert np.any(hi_i < lo_j) or np.any(hi_j < lo_i)  # no two bodies' boxes overlap


def test_the_atlas_is_a_guest_of_the_scenes_pipeline_host(monkeypatch):
    """On CUDA a kernel may trace only scenes that share one OptiX shader binding table."""
    scene = dt.scenes.build("cornell-box", resolution=4)
    seen = []
    load_dict = mi.load_dict
    monkeypatch.setattr(mi, "load_dict", lambda d, *a, **k: seen.append(d) or load_dict(d, *a, **k))
    scene._body_atlas()
    atlas_dicts = [d for d in seen if any(str(key).startswith("atlas-") for key in d)]
    assert len(atlas_dicts) == 1 and atlas_dicts[0][HOST_KEY] is scene.pipeline_host is not None


def test_a_body_the_atlas_cannot_hold_is_refused_by_name_or_left_to_the_per_body_loop(monkeypatch):
    scene = dt.scenes.build("cornell-box", resolution=4)
    held = mi.load_dict({
        "type": "scene",
        "group": {"type": "shapegroup", "cube": {"type": "cube"}},
        "copy": {"type": "instance", "shapegroup": {"type": "ref", "id": "group"}},
    })  # fmt: skip
    scene.bodies = [dataclasses.replace(scene.bodies[0], scene=held), *scene.bodies[1:]]
    assert BodyAtlas.unsupported(scene.bodies) == f"body {scene.bodies[0].name!r}: shape Instance"
    scene.traversal = "atlas"
    with pytest.raises(ValueError, match=f"traversal='atlas' cannot hold body {scene.bodies[0].name!r}: shape Instance"):
        scene.traversal_in_use()
    scene.traversal = "auto"
    monkeypatch.setattr(mi, "variant", lambda: "cuda_ad_rgb")
    assert scene.traversal_in_use() == "per-body"


def test_a_scenes_atlas_is_built_before_its_first_kernel_so_the_second_render_reuses_it():
    """Built while the first render's kernel was traced, the atlas's new shapes changed the
    layout of that kernel's calls over shapes: every new scene compiled twice (0.5 s each
    for 16 cubes on the CPU; minutes on CUDA)."""
    import drjit as dr

    scene = dt.load_scene(_glowing_panel_scene())
    scene.traversal = "atlas"
    kernels = []
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        for seed in (1, 2):
            dt.render(scene, CAMERAS, spp=4, max_depth=3, seed=seed)
            kernels.append({k["hash"] for k in dr.kernel_history() if "hash" in k and k["operation_count"] > 1000})
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert kernels[0] and kernels[0] == kernels[1]
