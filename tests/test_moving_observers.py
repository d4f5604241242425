"""Moving cameras and moving lights (issue 10): relativity, closed forms, stock Mitsuba.

* Relativity: a camera (with its light attached) moving towards or across a static scene
  measures what the static camera measures of the scene moving the other way, in every
  time sampling × correlation mode, with the same ground truth.
* The moving-plane closed form holds with the camera moving instead of the plane.
* A moving point light, and an area light on a moving body, give the intensity of stock
  ``path`` renders with the light baked at stratified times (emitter sampling and the
  density of emitter hits across static and moving emitters).
* Scene files: ``<animation>`` and ``<emitter>`` inside ``<sensor>``, moving point lights;
  what cannot move is refused with an error naming it.
"""

import math

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.oracles import moving_plane_measurement_pixels, moving_plane_scene
from scene_dicts import T, grey

CAMERAS = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
ALL_MODES = [(t, c) for t in ("uniform", "stratified", "antithetic", "antithetic_mirror") for c in ("none", "pixel", "replay", "reconnection", "adaptive")]
ALL_MODES += [("analytic", c) for c in ("replay", "reconnection", "adaptive")]
TRUTH = ("depth", "velocity", "point_velocity", "velocity_3d", "flow")


def _assert_same_within_noise(a, b, bound=5.0):
    """Every measurement of renders ``a`` and ``b`` agrees within ``bound`` standard errors."""
    se = np.sqrt(a.measurement_stderr.astype(np.float64) ** 2 + b.measurement_stderr.astype(np.float64) ** 2)
    diff = np.abs(a.measurements.astype(np.float64) - b.measurements)
    scale = np.abs(a.measurements).max()
    assert np.all(diff <= bound * se + 1e-5 * scale), float(np.max(diff / np.maximum(se, 1e-30)))


def _assert_same_truth(a, b):
    for name in TRUTH:
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-3, atol=1e-3, err_msg=name)


# ----------------------------------------------------------------------------------------
# Relativity


@pytest.mark.parametrize("time_sampling,correlation", ALL_MODES)
def test_camera_receding_from_a_plane_measures_the_plane_receding(time_sampling, correlation):
    speed = 10.0
    kw = dict(spp=32, max_depth=2, seed=4, time_sampling=time_sampling, correlation=correlation)
    plane = dt.render(moving_plane_scene(speed, resolution=8), CAMERAS, **kw)
    camera = dt.render(moving_plane_scene(speed, resolution=8, mover="camera"), CAMERAS, **kw)
    _assert_same_within_noise(plane, camera)
    _assert_same_truth(plane, camera)
    assert np.nanmin(camera.velocity) > 9.99  # relative radial velocity, positive receding (analytic: at t = 0 and T)


def test_the_moving_plane_closed_form_holds_with_the_camera_moving():
    speed = 10.0
    result = dt.render(moving_plane_scene(speed, resolution=8, mover="camera"), CAMERAS, spp=256, max_depth=2, seed=9)
    for k, camera in enumerate(CAMERAS):
        z = (result.measurements[k] - moving_plane_measurement_pixels(camera, speed, 8)) / result.measurement_stderr[k]
        assert abs(float(z.mean())) < 0.5 and 0.6 < float(z.std()) < 1.5 and float(np.abs(z).max()) < 5, camera


def _lateral_scene(mover, speed_m_s, exposure_s=1.5e-3, sensor_type="perspective"):
    """A wall and a box before it, a camera with its point light attached; ``mover``
    ``"scene"`` slides the wall and box along −x, ``"camera"`` the camera along +x."""
    look = T().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0])
    shift = mi.ScalarTransform4d().translate([speed_m_s * exposure_s, 0, 0])
    lens = {"aperture_radius": 0.05, "focus_distance": 3.5} if sensor_type == "thinlens" else {}
    sensor = {"type": sensor_type, "fov": 40, "film": {"type": "hdrfilm", "width": 12, "height": 12, "rfilter": {"type": "box"}},
              "light": {"type": "point", "intensity": {"type": "rgb", "value": 20.0}}, **lens}
    wall = {"type": "rectangle", "to_world": mi.ScalarTransform4d().scale(3), "bsdf": grey(0.6)}
    box = {"type": "cube", "to_world": mi.ScalarTransform4d().translate([0.4, 0, 1]) @ mi.ScalarTransform4d().scale(0.4), "bsdf": grey(0.3)}
    if mover == "scene":
        sensor["to_world"] = look
        for shape in (wall, box):
            start = shape.pop("to_world")
            shape["motion"] = {"type": "keyframes", "keys": [(0.0, start), (exposure_s, shift.inverse() @ start)]}
    else:
        start = mi.ScalarTransform4d().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0])
        sensor["motion"] = {"type": "keyframes", "keys": [(0.0, start), (exposure_s, shift @ start)]}
    return dt.load_scene({"type": "scene", "sensor": sensor, "wall": wall, "box": box})


@pytest.mark.parametrize("correlation,sensor_type", [("replay", "perspective"), ("reconnection", "perspective"), ("adaptive", "thinlens")])
def test_a_camera_moving_sideways_measures_the_scene_moving_the_other_way(correlation, sensor_type):
    kw = dict(spp=64, max_depth=3, seed=2, correlation=correlation)
    scene = dt.render(_lateral_scene("scene", 200.0, sensor_type=sensor_type), CAMERAS, **kw)
    camera = dt.render(_lateral_scene("camera", 200.0, sensor_type=sensor_type), CAMERAS, **kw)
    _assert_same_within_noise(scene, camera)
    _assert_same_truth(scene, camera)
    assert np.abs(camera.flow[..., 0]).max() > 1.0  # the scene slides across the film


# ----------------------------------------------------------------------------------------
# Moving lights against stock Mitsuba


def _stock_average(scene_at, times_s, spp):
    """Mean of stock ``path`` renders of ``scene_at(t)`` at ``times_s``, and its variance."""
    images = np.stack([np.array(mi.render(mi.load_dict(scene_at(t)), spp=spp, seed=100 + k), dtype=np.float64)[..., :3] for k, t in enumerate(times_s)])
    return images.mean(axis=0), images.var(axis=0, ddof=1) / len(times_s)


def _room(extra):
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 50, "to_world": T().look_at(origin=[0, 1, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}}},
        "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(3), "bsdf": grey(0.7)},
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -1.5]).scale(3), "bsdf": grey(0.5)},
        "lamp": {"type": "point", "position": [-1.5, 2, 1], "intensity": {"type": "rgb", "value": 4.0}},
    }
    scene.update(extra)
    return scene


EXPOSURE_S = 1.5e-3
SLIDE_M_S = 600.0  # 0.9 m during the exposure
TIMES_S = (np.arange(16) + 0.5) / 16 * EXPOSURE_S


def _assert_matches_stock(result, stock_mean, stock_var):
    ours = result.intensity.astype(np.float64).sum(axis=(0, 1))
    ours_var = (result.stderr.astype(np.float64) ** 2).sum(axis=(0, 1))
    theirs = stock_mean.sum(axis=(0, 1))
    z = (ours - theirs) / np.sqrt(ours_var + stock_var.sum(axis=(0, 1)))
    assert np.all(np.abs(z) < 4.5), z
    assert np.all(np.abs(ours - theirs) < 0.03 * theirs), (ours, theirs)  # and a stratification error well below


def test_a_moving_point_light_matches_stock_renders_baked_at_stratified_times():
    def light_at(t):
        return {"type": "point", "position": [0.6 + SLIDE_M_S * t, 0.8, 0.5], "intensity": {"type": "rgb", "value": 3.0}}

    moving = {**light_at(0.0), "motion": {"type": "parametric", "linear_velocity": [SLIDE_M_S, 0, 0]}}
    result = dt.render(dt.load_scene(_room({"spot": moving})), spp=512, exposure=EXPOSURE_S, max_depth=4, seed=1)
    _assert_matches_stock(result, *_stock_average(lambda t: _room({"spot": light_at(t)}), TIMES_S, 256))


def test_an_area_light_on_a_moving_body_matches_stock_renders_baked_at_stratified_times():
    def panel_at(t):
        to_world = T().translate([-0.8 + SLIDE_M_S * t, 1.2, 0.3]).rotate([1, 0, 0], 70).scale(0.3)
        return {"type": "rectangle", "to_world": to_world, "bsdf": grey(0.2), "glow": {"type": "area", "radiance": {"type": "rgb", "value": 6.0}}}

    moving = {**panel_at(0.0), "motion": {"type": "parametric", "linear_velocity": [SLIDE_M_S, 0, 0]}}
    result = dt.render(dt.load_scene(_room({"panel": moving})), spp=512, exposure=EXPOSURE_S, max_depth=4, seed=1)
    _assert_matches_stock(result, *_stock_average(lambda t: _room({"panel": panel_at(t)}), TIMES_S, 256))


# ----------------------------------------------------------------------------------------
# Scene files


SENSOR_XML = """<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="30"/>
        {animation}
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
        {light}
    </sensor>
    <shape type="rectangle"><transform name="to_world"><scale value="20"/><translate z="-5"/></transform></shape>
    {extra}
</scene>"""
CAMERA_KEYS = """<animation name="to_world">
            <transform time="0"><lookat origin="0 0 0" target="0 0 -1" up="0 1 0"/></transform>
            <transform time="0.0015"><lookat origin="0 0 0.015" target="0 0 -0.985" up="0 1 0"/></transform>
        </animation>"""
ATTACHED = '<emitter type="point"><rgb name="intensity" value="50"/></emitter>'


def _xml(tmp_path, **parts):
    path = tmp_path / "scene.xml"
    still = '<transform name="to_world"><lookat origin="0 0 0" target="0 0 -1" up="0 1 0"/></transform>'
    path.write_text(SENSOR_XML.format(**{"animation": still, "light": "", "extra": "", **parts}))
    return str(path)


def test_xml_camera_animation_and_attached_light(tmp_path):
    scene = dt.load_scene(_xml(tmp_path, animation=CAMERA_KEYS, light=ATTACHED))
    assert scene.camera_motion is not None and len(scene.lights) == 1
    result = dt.render(scene, [dt.Camera(heterodyne=0.0)], spp=16, max_depth=2)
    assert 9.99 < np.nanmin(result.velocity) and np.nanmax(result.velocity) < 10.7  # 10 m/s receding, / cos of the pixel's ray
    assert np.nanmean(result.depth) > 5.0 and result.intensity.mean() > 0


def test_xml_moving_point_light(tmp_path):
    lamp = f'<emitter type="point"><rgb name="intensity" value="5"/>{CAMERA_KEYS}</emitter>'
    scene = dt.load_scene(_xml(tmp_path, extra=lamp))
    assert len(scene.lights) == 1 and scene.camera_motion is None
    assert dt.render(scene, spp=4, max_depth=2).intensity.mean() > 0


@pytest.mark.parametrize("extra,match", [
    ('<emitter type="constant"><animation name="to_world"><transform time="0"/></animation></emitter>', "emitter of type 'constant' cannot move"),
    ('<emitter type="point"><point name="position" value="0 0 0"/><animation name="to_world"><transform time="0"/></animation></emitter>', "position and an <animation>"),
])
def test_xml_lights_that_cannot_move_are_refused(tmp_path, extra, match):
    with pytest.raises(dt.SceneError, match=match):
        dt.load_scene(_xml(tmp_path, extra=extra))


def test_a_scaling_camera_motion_is_refused():
    keys = [(0.0, np.eye(4)), (1e-3, np.diag([2.0, 2.0, 2.0, 1.0]))]
    scene = _room({})
    scene["sensor"] = {**scene["sensor"], "motion": {"type": "keyframes", "keys": keys}}
    del scene["sensor"]["to_world"]
    with pytest.raises(dt.SceneError, match="the sensor has a motion that scales"):
        dt.load_scene(scene)


def test_an_attached_area_emitter_is_refused():
    scene = _room({})
    scene["sensor"] = {**scene["sensor"], "glow": {"type": "constant"}}
    with pytest.raises(dt.SceneError, match="emitter of type 'constant' cannot move"):
        dt.load_scene(scene)


# ----------------------------------------------------------------------------------------
# Every estimator with a moving camera, a moving light and rotating bodies


def _everything_moves(resolution=16):
    """A camera driving forward and turning, with its light; a point light sliding
    overhead; a spinning rough-gold cube and a tumbling box before static walls."""
    look = mi.ScalarTransform4d().look_at(origin=[0, 1.2, 4.5], target=[0, 0.6, 0], up=[0, 1, 0])
    sensor = {"type": "perspective", "fov": 45, "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
              "to_world": look, "motion": {"type": "parametric", "linear_velocity": [1.0, 0, -8.0], "angular_velocity": [0, 2.0, 0], "pivot": [0, 1.2, 4.5]},
              "light": {"type": "point", "position": [0.05, 0, 0], "intensity": {"type": "rgb", "value": 30.0}}}
    cube_centre, box_centre = [0.5, 0.45, 0.2], [-0.7, 0.35, 0.6]
    return dt.load_scene({
        "type": "scene",
        "sensor": sensor,
        "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(4), "bsdf": grey(0.6)},
        "wall": {"type": "rectangle", "to_world": T().translate([0, 2, -1.5]).scale([4, 2, 1]), "bsdf": grey(0.5)},
        "overhead": {"type": "point", "position": [-1.0, 2.5, 1.5], "intensity": {"type": "rgb", "value": 8.0},
                     "motion": {"type": "parametric", "linear_velocity": [6.0, 0, 0]}},
        "gold": {"type": "cube", "to_world": T().translate(cube_centre).scale(0.35), "motion": {"type": "parametric", "angular_velocity": [0, 40.0, 0], "pivot": cube_centre},
                 "bsdf": {"type": "roughconductor", "material": "Au", "distribution": "ggx", "alpha": 0.2}},
        "box": {"type": "cube", "to_world": T().translate(box_centre).scale(0.3), "bsdf": grey(0.7),
                "motion": {"type": "parametric", "linear_velocity": [0, 0, 5.0], "angular_velocity": [20.0, 0, 10.0], "pivot": box_centre}},
    })


@pytest.mark.slow
def test_every_mode_is_unbiased_with_a_moving_camera_a_moving_light_and_rotating_bodies():
    """4 time samplings × 5 correlations × 2 seeds at 256 spp against 8192 spp, regions
    and bound as in tests/test_paired.py (Bonferroni, family false alarm 1e-4); every render
    would reveal a 10 % error."""
    from test_paired import _agreement, _assert_agreement, REFERENCE_SEED, render

    scene = _everything_moves()
    reference = render(scene, 8192, REFERENCE_SEED)
    _assert_agreement(*_agreement(scene, reference, 256, 0.1), 0.1)
