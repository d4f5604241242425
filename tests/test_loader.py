"""Loading dynamic scenes from XML (original Mitsuba 3 D-ToF syntax) and dicts, and the
messages for bad input."""

import os
import re

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.motion import Keyframed, Parametric

T = mi.ScalarTransform4f

SHORT_BOX = np.array([0.286891427, 0, -0.0877115114, 0.33, 0, 0.3, 0, 0.3, 0.0877115114, 0, 0.286891427, 0.37, 0, 0, 0, 1]).reshape(4, 4)
TALL_BOX = np.array([0.286891427, 0, 0.0877115114, -0.33, 0, 0.6, 0, 0.6, -0.0877115114, 0, 0.286891427, -0.29, 0, 0, 0, 1]).reshape(4, 4)


def translate(x=0.0, y=0.0, z=0.0):
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    return m


def assert_one_line(exc_info, max_len=600):
    text = str(exc_info.value)
    assert "\n" not in text, text
    assert len(text) < max_len, text


SENSOR_XML = """
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>"""


def write_scene(tmp_path, body, name="scene.xml", with_sensor=True):
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">{SENSOR_XML if with_sensor else ""}\n{body}\n</scene>\n')
    return path


def animated(shape_inner="", keys=((0.0, '<translate x="0"/>'), (1e-3, '<translate x="1"/>')), shape="sphere"):
    frames = "".join(f'<transform time="{t}">{ops}</transform>' for t, ops in keys)
    return f'<shape type="{shape}">{shape_inner}<animation name="to_world">{frames}</animation></shape>'


# ----------------------------------------------------------------------------------------
# The original Mitsuba 3 D-ToF Cornell box


@pytest.fixture(scope="module")
def original(data_dir):
    return dt.load_scene(data_dir / "original_cornell.xml")


def test_original_scene_loads_with_two_bodies(original):
    assert sorted(b.name for b in original.bodies) == ["short-box", "tall-box"]
    assert original.resolution == (256, 256)
    assert original.spp_hint == 1024
    assert len(original.static.emitters()) == 1
    for body in original.bodies:
        assert len(body.scene.shapes()) == 1 and body.scene.shapes()[0].class_name() == "Cube"


def test_original_scene_keeps_the_integrator_parameters(original):
    p = original.integrator_params
    assert p["type"] == "dopplertofpath"
    assert p["time"] == pytest.approx(0.0015)
    assert p["w_g"] == pytest.approx(30.0)
    assert p["hetero_frequency"] == pytest.approx(1.0)
    assert p["time_sampling_method"] == "antithetic"
    assert p["path_correlation_depth"] == 4 and isinstance(p["path_correlation_depth"], int)
    assert p["max_depth"] == 4


def test_original_sampler_becomes_a_stock_sampler(original):
    sampler = original.sensor.sampler()
    assert sampler.sample_count() == 1024
    assert "Independent" in sampler.class_name()


def test_original_keyframes_compose_like_mitsuba(original):
    """Later operations left-multiply: the second key is Translate(z) · matrix."""
    bodies = {b.name: b for b in original.bodies}
    for name, matrix, dz in [("short-box", SHORT_BOX, 0.015), ("tall-box", TALL_BOX, -0.015)]:
        motion = bodies[name].motion
        assert isinstance(motion, Keyframed)
        np.testing.assert_allclose(motion.times, [0.0, 0.0015])
        np.testing.assert_allclose(motion.matrix(0.0), matrix, atol=1e-7)
        np.testing.assert_allclose(motion.matrix(0.0015), translate(z=dz) @ matrix, atol=1e-7)
        np.testing.assert_allclose(motion.matrix(0.00075), translate(z=dz / 2) @ matrix, atol=1e-7)


def test_original_scene_intersections(original):
    """A ray along the camera axis through the short box's front face hits it, and its
    hit point moves 15 mm towards the camera over the exposure."""
    bodies = [b.name for b in original.bodies]
    short_index = bodies.index("short-box") + 1
    centre = SHORT_BOX[:3, 3]
    origin = [float(centre[0]), float(centre[1]), 6.8]
    ray = mi.Ray3f(mi.Point3f(*[np.full(2, v, dtype=np.float32) for v in origin]), mi.Vector3f(0, 0, -1))
    hit = original.intersect(ray, mi.Float64([0.0, 0.0015]))
    np.testing.assert_array_equal(np.asarray(hit.body), [short_index, short_index])
    t = np.asarray(hit.si.t, dtype=np.float64)
    assert t[0] - t[1] == pytest.approx(0.015, abs=2e-6)


def test_original_scene_renders_like_the_builtin_cornell_box(original, monkeypatch):
    """Same geometry, same seed: the XML scene and the built-in one render the same paths.

    The camera rays sample the film's reconstruction filter: the file has a tent filter,
    so the built-in box (box filter) is given the same one here.
    The transforms differ in their last float bits, so a ray grazing an edge may go another
    way: allow a handful of differing pixels out of 65536."""
    load = dt.scenes._load

    def with_tent_filter(scene):
        scene["sensor"]["film"]["rfilter"] = {"type": "tent"}
        return load(scene)

    monkeypatch.setattr(dt.scenes, "_load", with_tent_filter)
    builtin = dt.scenes.cornell_box(resolution=256)
    monkeypatch.undo()
    a = dt.render(original, spp=2, seed=3, max_depth=4)
    b = dt.render(builtin, spp=2, seed=3, max_depth=4)
    for name in ("depth", "velocity", "point_velocity", "intensity"):
        x, y = getattr(a, name), getattr(b, name)
        same = np.isclose(x, y, rtol=1e-4, atol=1e-4, equal_nan=True)
        assert same.mean() > 0.999, (name, np.argwhere(~same)[:5])
    assert np.nanmin(a.velocity) < -9 and np.nanmax(a.velocity) > 9  # the boxes do move


def test_xml_defaults_can_be_overridden(data_dir):
    scene = dt.load_scene(data_dir / "original_cornell.xml", res=24, spp=8)
    assert scene.resolution == (24, 24)
    assert scene.spp_hint == 8


# ----------------------------------------------------------------------------------------
# Other XML features


def test_animation_ops_compose_like_a_static_transform(tmp_path):
    """The ops of a keyframe give the same matrix as Mitsuba's own <transform> parser."""
    ops = (
        '<scale x="0.5" y="2" z="1"/><rotate x="0.6" y="0" z="0.8" angle="40"/>'
        '<translate x="1" y="-2" z="3"/><rotate y="1" angle="-25"/>'
    )
    body = (
        f'<shape type="rectangle" id="still"><transform name="to_world">{ops}</transform></shape>'
        + animated(keys=((0.0, ops), (1.0, ops + '<translate z="1"/>')), shape="rectangle")
    )
    scene = dt.load_scene(write_scene(tmp_path, body))
    stock = np.array(mi.traverse(scene.static)["still.to_world"].matrix, dtype=np.float64).reshape(4, 4)
    motion = scene.bodies[0].motion
    np.testing.assert_allclose(motion.matrix(0.0), stock, atol=1e-6)
    np.testing.assert_allclose(motion.matrix(1.0), translate(z=1) @ stock, atol=1e-6)


def test_moving_mesh_file_is_found_next_to_the_scene(data_dir, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # relative file names resolve against the scene's folder
    scene = dt.load_scene(data_dir / "moving_mesh.xml")
    assert len(scene.bodies) == 1
    result = dt.render(scene, spp=2, seed=0, max_depth=2, exposure=1e-3)  # keys span 1 ms
    centre = result.velocity[6:10, 6:10]
    # Receding at 4 m/s: d/dt of the distance along a ray at angle θ to the axis is 4/cos θ.
    assert np.all(centre >= 4.0 * (1 - 1e-5)) and np.all(centre < 4.0 / np.cos(np.radians(6)))
    assert result.intensity[8, 8].min() > 0


def test_loading_xml_keeps_the_file_resolver(data_dir):
    """Mitsuba finds its plugins through the file resolver: loading an XML scene must leave
    the resolver's search paths as they were (it may add and remove its own folder)."""
    resolver = mi.file_resolver()
    before = [str(resolver[i]) for i in range(len(resolver))]
    dt.load_scene(data_dir / "moving_mesh.xml")
    after = [str(resolver[i]) for i in range(len(resolver))]
    assert after == before
    # A plugin type not used elsewhere in the tests still loads afterwards.
    mi.load_dict({"type": "scene", "s": {"type": "sphere", "bsdf": {"type": "roughplastic"}}})


def test_shapes_sharing_a_motion_form_one_body(tmp_path):
    keys = ((0.0, '<translate x="0"/>'), (1e-3, '<translate x="1"/>'))
    body = animated(keys=keys) + animated(keys=keys, shape="cube") + animated(keys=((0.0, "<translate y='0'/>"), (1e-3, "<translate y='1'/>")))
    scene = dt.load_scene(write_scene(tmp_path, body))
    assert len(scene.bodies) == 2
    assert sorted(len(b.scene.shapes()) for b in scene.bodies) == [1, 2]


def test_a_moving_instance_of_a_shapegroup_renders_like_the_shape_itself(tmp_path):
    """In XML it failed with a parser message about '_arg_0' (the body's scene lacked the
    shapegroup); a dict worked."""
    keys = ((0.0, '<translate x="0"/>'), (1.5e-3, '<translate z="0.015"/>'))
    view = ('<sensor type="perspective"><transform name="to_world"><lookat origin="0 0 4" target="0 0 0" up="0 1 0"/></transform>'
            '<film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film></sensor>'
            '<emitter type="point"><point name="position" value="0 0 4"/></emitter>')
    group = '<shape type="shapegroup" id="grp"><shape type="sphere"><float name="radius" value="0.3"/></shape></shape>'
    instanced = dt.load_scene(write_scene(tmp_path, view + group + animated('<ref id="grp"/>', keys=keys, shape="instance"), "instanced.xml", with_sensor=False))
    plain = dt.load_scene(write_scene(tmp_path, view + animated('<float name="radius" value="0.3"/>', keys=keys), "plain.xml", with_sensor=False))
    camera = [dt.Camera(heterodyne=0.0)]
    a, b = (dt.render(s, cameras=camera, spp=16, max_depth=2) for s in (instanced, plain))
    assert (a.instance_id >= 0).sum() > 0 and len(instanced.bodies) == 1
    for name in ("velocity", "velocity_3d", "depth"):  # an instance's intersection rounds its own way
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-6, err_msg=name)


# ----------------------------------------------------------------------------------------
# Bad XML


@pytest.mark.parametrize(
    "body, match",
    [
        ('<shape type="sphere">', r"malformed XML"),
        ('<shape type="sphere"><bsdf type="diffuse"><float name="bogus" value="1"/></bsdf></shape>', r"bogus"),
        (animated(keys=((1e-3, '<translate x="0"/>'), (1e-3, '<translate x="1"/>'))), r"strictly increasing"),
        (animated(keys=((2e-3, '<translate x="0"/>'), (1e-3, '<translate x="1"/>'))), r"strictly increasing"),
        (animated(keys=(("abc", '<translate x="0"/>'),)), r"keyframe time 'abc' is not a number"),
        ('<shape type="obj"><string name="filename" value="nope.obj"/></shape>', r"nope\.obj"),
        (animated(keys=((0.0, '<shear x="1"/>'),)), r"unknown transform operation"),
        ('<shape type="sphere"><animation name="to_world"></animation></shape>', r"no keyframes"),
        ('<shape type="sphere"><animation name="radius"><transform time="0"/></animation></shape>', r'only <animation name="to_world">'),
        ('<shape type="sphere"><animation name="to_world"><translate x="1"/></animation></shape>', r"may only contain <transform"),
        ('<shape type="sphere"><animation name="to_world"><transform><translate x="1"/></transform></animation></shape>', r"time"),
        (animated('<transform name="to_world"><translate x="1"/></transform>'), r"both"),
        (animated('<emitter type="area"/>', keys=((0.0, '<scale x="1" y="2" z="1"/>'), (1e-3, '<translate x="1"/>')), shape="rectangle"), r"keys scale the axes differently"),
        (animated(keys=((0.0, '<matrix value="1 0 0"/>'),)), r"matrix needs 9 or 16 numbers"),
        (animated(keys=((0.0, '<translate x="one"/>'),)), r"expected numbers"),
        ('<shape type="sphere"><float name="radius" value="$r"/></shape>', r"unresolved parameter"),
    ],
)
def test_bad_xml_raises_a_one_line_scene_error(tmp_path, body, match):
    with pytest.raises(dt.SceneError, match=match) as info:
        dt.load_scene(write_scene(tmp_path, body))
    assert_one_line(info)
    assert "scene.xml" in str(info.value)  # says which file


def test_missing_scene_file(tmp_path):
    with pytest.raises(dt.SceneError, match="not found") as info:
        dt.load_scene(tmp_path / "absent.xml")
    assert_one_line(info)


def test_wrong_root_element(tmp_path):
    path = tmp_path / "x.xml"
    path.write_text("<shape type='sphere'/>")
    with pytest.raises(dt.SceneError, match="root element must be <scene>") as info:
        dt.load_scene(path)
    assert_one_line(info)


def test_scene_without_sensor(tmp_path):
    with pytest.raises(dt.SceneError, match="no <sensor>") as info:
        dt.load_scene(write_scene(tmp_path, '<shape type="sphere"/>', with_sensor=False))
    assert_one_line(info)


def test_scene_error_is_a_value_error():
    assert issubclass(dt.SceneError, ValueError)
    with pytest.raises(dt.SceneError, match="file path or a dict"):
        dt.load_scene(42)


# ----------------------------------------------------------------------------------------
# Dicts


def dict_scene(**shapes):
    return {
        "type": "scene",
        "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}},
        **shapes,
    }


def test_dict_motion_forms():
    keys = [(0.0, T().translate([0, 0, 0])), (1e-3, np.array(T().translate([0, 0, 1]).matrix))]
    custom = Parametric([1, 0, 0])
    scene = dt.load_scene(
        dict_scene(
            a={"type": "sphere", "motion": {"type": "keyframes", "keys": keys}},
            b={"type": "sphere", "to_world": T().translate([2, 0, 0]), "motion": {"type": "parametric", "angular_velocity": [0, 0, 10], "pivot": [0, 0, 0]}},
            c={"type": "sphere", "motion": custom},
            d={"type": "sphere"},
        )
    )
    bodies = {b.name: b for b in scene.bodies}
    assert sorted(bodies) == ["a", "b", "c"]
    assert bodies["c"].motion is custom
    np.testing.assert_allclose(bodies["a"].motion.matrix(0.5e-3), translate(z=0.5), atol=1e-12)
    # Parametric motion acts on top of to_world: rotating about the origin moves the centre.
    c, s = np.cos(0.1), np.sin(0.1)
    np.testing.assert_allclose(bodies["b"].motion.matrix(0.01)[:3, 3], [2 * c, 2 * s, 0], atol=1e-12)
    assert len(scene.static.shapes()) == 1


@pytest.mark.parametrize(
    "motion, match",
    [
        ({"type": "wobble"}, r"'keyframes' or 'parametric'"),
        ("fast", r"'keyframes' or 'parametric'"),
        ({"type": "keyframes", "keys": [(0.0, np.eye(4))], "speed": 3}, r"unknown motion parameter\(s\) \['speed'\]"),
        ({"type": "parametric", "spin": 1.0}, r"unknown motion parameter\(s\) \['spin'\]"),
        ({"type": "keyframes", "keys": [(2e-3, np.eye(4)), (1e-3, np.eye(4))]}, r"strictly increasing"),
        ({"type": "keyframes", "keys": [("soon", np.eye(4))]}, r"keyframe time 'soon' is not a number"),
        ({"type": "keyframes", "keys": [("0", np.eye(4))]}, r"keyframe time '0' is not a number"),
        ({"type": "keyframes", "keys": [(0.0, np.eye(4), 5), (1.0, np.eye(4))]}, r"a keyframe is a pair \(time_s, transform\), got 3 entries"),
        ({"type": "keyframes", "keys": []}, r"at least one keyframe"),
        ({"type": "keyframes", "keys": [(0.0, np.eye(3))]}, r"4x4"),
        ({"type": "parametric", "linear_velocity": [1, 0]}, r"linear_velocity must be 3 finite numbers"),
        ({"type": "parametric", "linear_velocity": "fast"}, r"entry 'ball': linear_velocity must be 3 finite numbers, got 'fast'"),
    ],
)
def test_bad_dict_motion(motion, match):
    with pytest.raises(dt.SceneError, match=match) as info:
        dt.load_scene(dict_scene(ball={"type": "sphere", "motion": motion}))
    assert_one_line(info)
    assert "'ball'" in str(info.value)  # says which entry


def test_an_integrator_value_no_render_could_take_is_refused_when_the_scene_loads(tmp_path):
    """max_depth 0 loaded and was refused only when the render began, without the file's name."""
    path = write_scene(tmp_path, '<integrator type="path"><integer name="max_depth" value="0"/></integrator><shape type="sphere"/>')
    with pytest.raises(dt.SceneError, match=r"scene\.xml: <integrator>: 'max_depth' must be >= 1 or -1 \(unbounded\), got 0") as info:
        dt.load_scene(path)
    assert_one_line(info)


def test_a_motion_where_nothing_moves_says_so():
    """It was only Mitsuba's 'Plugin "parametric" not found!'."""
    ball = {"type": "sphere", "bsdf": {"type": "diffuse", "motion": {"type": "parametric", "linear_velocity": [0, 0, 1]}}}
    with pytest.raises(dt.SceneError, match=r"ball\.bsdf\.motion.*a 'motion' was given where nothing moves: only a top-level shape, emitter or the sensor") as info:
        dt.load_scene(dict_scene(ball=ball))
    assert_one_line(info)


def test_keyframes_and_to_world_conflict():
    motion = {"type": "keyframes", "keys": [(0.0, np.eye(4))]}
    with pytest.raises(dt.SceneError, match="replaces 'to_world'") as info:
        dt.load_scene(dict_scene(ball={"type": "sphere", "to_world": T(), "motion": motion}))
    assert_one_line(info)


def test_dict_emitter_on_a_body_scaled_unequally_is_rejected():
    keys = [(0.0, np.diag([1.0, 2.0, 1.0, 1.0])), (1e-3, np.eye(4))]
    shape = {"type": "rectangle", "emitter": {"type": "area"}, "motion": {"type": "keyframes", "keys": keys}}
    with pytest.raises(dt.SceneError, match="keys scale the axes differently") as info:
        dt.load_scene(dict_scene(lamp=shape))
    assert_one_line(info)


def test_dict_unknown_plugin_parameter():
    with pytest.raises(dt.SceneError, match="bogus") as info:
        dt.load_scene(dict_scene(ball={"type": "sphere", "bsdf": {"type": "diffuse", "bogus": 1.0}}))
    assert_one_line(info)


def test_dict_without_scene_type_or_sensor():
    with pytest.raises(dt.SceneError, match="'type': 'scene'"):
        dt.load_scene({"ball": {"type": "sphere"}})
    with pytest.raises(dt.SceneError, match="no sensor") as info:
        dt.load_scene({"type": "scene", "ball": {"type": "sphere"}})
    assert_one_line(info)


def test_relative_paths_do_not_depend_on_the_working_directory(data_dir, monkeypatch):
    monkeypatch.chdir(os.path.dirname(data_dir))
    scene = dt.load_scene(os.path.join("data", "original_cornell.xml"), res=8)
    assert scene.resolution == (8, 8)


def test_dict_shapes_sharing_a_motion_form_one_body():
    keys = [(0.0, T().translate([0, 0, 0])), (1e-3, T().translate([0, 0, 1]))]
    same_keys = [(0.0, np.eye(4)), (1e-3, translate(z=1))]  # the same keys in another form
    spin = {"type": "parametric", "angular_velocity": [0, 50, 0], "pivot": [0, 0, 0]}
    scene = dt.load_scene(
        dict_scene(
            a={"type": "sphere", "motion": {"type": "keyframes", "keys": keys}},
            b={"type": "cube", "motion": {"type": "keyframes", "keys": same_keys}},
            c={"type": "sphere", "motion": {"type": "keyframes", "keys": keys[:1]}},
            d={"type": "sphere", "to_world": T().translate([1, 0, 0]), "motion": dict(spin)},
            e={"type": "cube", "to_world": T().translate([-1, 0, 0]).scale(0.2), "motion": dict(spin)},
            f={"type": "sphere", "center": [0, 1, 0], "motion": dict(spin)},
            g={"type": "sphere", "motion": {**spin, "pivot": [0, 0, 1]}},
        )
    )
    assert [b.name for b in scene.bodies] == ["a, b", "c", "d, e, f", "g"]
    assert [len(b.scene.shapes()) for b in scene.bodies] == [2, 1, 3, 1]


def test_dict_moving_shapes_and_lights_keep_their_references():
    """A moving shape (or light) refers to a top-level object by ``"ref"``, as
    ``mi.cornell_box()``'s boxes refer to its ``"white"`` BSDF; a reference may refer on."""
    move = {"type": "parametric", "linear_velocity": [0, 0, 1]}
    scene = dt.load_scene(
        dict_scene(
            grey={"type": "srgb", "color": [0.3, 0.4, 0.5]},
            white={"type": "diffuse", "reflectance": {"type": "ref", "id": "grey"}},
            box={"type": "cube", "bsdf": {"type": "ref", "id": "white"}, "motion": dict(move)},
            lamp={"type": "spot", "intensity": {"type": "ref", "id": "grey"}, "motion": dict(move)},
        )
    )
    (body,) = scene.bodies
    assert body.scene.shapes()[0].bsdf().id() == "white" and len(scene.lights) == 1


def test_rotating_scene_is_one_body():
    """The merry-go-round's platform and riders share one spin: one body."""
    scene = dt.scenes.rotating(resolution=8)
    assert len(scene.bodies) == 1
    assert len(scene.bodies[0].scene.shapes()) == 6


def test_shapes_placed_differently_move_together_as_placed():
    """Shapes sharing a parametric motion but not their to_world keep it in the body's
    frame: each is where its own to_world and the motion put it, as if loaded alone."""
    spin = {"type": "parametric", "linear_velocity": [0.0, 0.0, 300.0], "angular_velocity": [0, 900.0, 0], "pivot": [0.2, 0, 0]}
    placements = {
        "left": T().translate([-0.8, 0, 0]) @ T().rotate([1, 1, 0], 30) @ T().scale([0.3, 0.5, 0.3]),
        "right": T().translate([0.8, 0.1, 0]) @ T().scale(0.4),
    }
    as_given = {"left": placements["left"], "right": np.array(placements["right"].matrix)}  # both forms of to_world
    grouped = dt.load_scene(dict_scene(**{k: {"type": "cube", "to_world": m, "motion": dict(spin)} for k, m in as_given.items()}))
    assert len(grouped.bodies) == 1
    grouped.set_time_window(0.0, 2e-3)
    motion = dt.load_scene(dict_scene(x={"type": "cube", "motion": dict(spin)})).bodies[0].motion
    rng = np.random.default_rng(9)
    n = 3000
    origins = np.stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-0.8, 0.8, n), np.full(n, 4.0)], axis=1).astype(np.float32)
    times = rng.choice([0.0, 0.7e-3, 1.3e-3, 2e-3], n)
    hit = grouped.intersect(mi.Ray3f(mi.Point3f(*origins.T), mi.Vector3f(0, 0, -1)), mi.Float64(times))
    t_ours = np.asarray(hit.si.t, dtype=np.float64)
    t_ref = np.empty(n)
    for t in np.unique(times):  # the shapes alone in stock scenes, baked at M(t) · to_world
        at = times == t
        baked = mi.load_dict({"type": "scene", **{k: {"type": "cube", "to_world": T(motion.matrix(t).tolist()) @ m} for k, m in placements.items()}})
        ref = baked.ray_intersect(mi.Ray3f(mi.Point3f(*origins[at].T), mi.Vector3f(0, 0, -1)))
        t_ref[at] = np.asarray(ref.t)
    assert 0.2 < np.isfinite(t_ref).mean() < 0.8
    np.testing.assert_array_equal(np.isfinite(t_ours), np.isfinite(t_ref))
    hit_both = np.isfinite(t_ref)
    np.testing.assert_allclose(t_ours[hit_both], t_ref[hit_both], atol=1e-4)


def test_a_sheared_to_world_stays_with_the_shape():
    """A parametric motion's base must be rigid·scale; a sheared to_world (fine for a
    Mitsuba shape) stays on the shape, the motion acting on top of it."""
    shear = np.eye(4)
    shear[0, 1] = 0.5
    scene = dt.load_scene(dict_scene(box={"type": "cube", "to_world": shear, "motion": {"type": "parametric", "linear_velocity": [0, 0, 1]}}))
    (body,) = scene.bodies
    np.testing.assert_array_equal(body.motion.base, np.eye(4))
    np.testing.assert_allclose(body.bounds_local[1], [1.5, 1.0, 1.0], atol=1e-6)  # x + 0.5 y at the corner


def test_rotate_axis_is_normalised_like_mitsuba(tmp_path):
    """<rotate y="2" angle="90"/> is a rotation about y in Mitsuba's XML, not a shear."""
    xml = tmp_path / "s.xml"
    xml.write_text(
        '<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/>'
        '<integer name="height" value="4"/></film></sensor><shape type="sphere"><animation name="to_world">'
        '<transform time="0"><rotate y="2" angle="0"/></transform><transform time="1"><rotate y="2" angle="90"/></transform>'
        "</animation></shape></scene>"
    )
    motion = dt.load_scene(str(xml)).bodies[0].motion
    np.testing.assert_allclose(motion.matrix(1.0)[:3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)


def test_unknown_plugin_type_is_named_as_such():
    with pytest.raises(dt.SceneError, match=r"spherez.*\(unknown plugin type\)$"):
        dt.load_scene({"type": "scene", "a": {"type": "spherez"}})


# ----------------------------------------------------------------------------------------
# One OptiX pipeline and SBT per scene (loader.pipeline_host, gpu-notes §1)


def _pipeline_types(dyn):
    return {shape.class_name() for shape in dyn.pipeline_host.shapes()}


def _used_types(dyn):
    scenes = [dyn.static] + [b.scene for b in dyn.bodies]
    return {shape.class_name() for s in scenes for shape in s.shapes()}


@pytest.mark.parametrize("name", ["rotating", "cornell_box"])
def test_a_scene_with_bodies_has_a_host_covering_every_shape_type(name):
    """The static scene and every body are guests of one never-traced host whose pipeline
    has every analytic type they use (a mesh of any kind needs only the host's rectangle)."""
    dyn = getattr(dt.scenes, name)(resolution=8)
    analytic = {"Sphere", "Disk", "Cylinder"}
    assert dyn.pipeline_host is not None
    assert _used_types(dyn) & analytic <= _pipeline_types(dyn)
    assert "Rectangle" in _pipeline_types(dyn)
    assert not ({"Sphere", "Disk", "Cylinder"} - _used_types(dyn)) & _pipeline_types(dyn)  # no more than needed


def test_an_xml_scene_with_a_moving_sphere_has_a_host_with_spheres(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(
        """<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
  <shape type="rectangle"><transform name="to_world"><scale value="10"/><translate z="5"/></transform></shape>
  <shape type="sphere"><point name="center" x="0" y="0" z="3"/><float name="radius" value="0.5"/>
    <animation name="to_world"><transform time="0"><translate x="0"/></transform><transform time="1"><translate x="1"/></transform></animation>
  </shape>
  <emitter type="point"><point name="position" x="0" y="0" z="0"/></emitter>
</scene>"""
    )
    dyn = dt.load_scene(str(path))
    assert _pipeline_types(dyn) == {"Rectangle", "Sphere"}
    result = dt.render(dyn, spp=4, max_depth=2, seed=0)
    assert result.coverage.min() == 1.0 and (result.instance_id == 0).any()  # the sphere is hit


def test_a_static_scene_needs_no_host():
    dyn = dt.load_scene({"type": "scene", "sensor": {"type": "perspective"}, "plane": {"type": "rectangle"}})
    assert dyn.pipeline_host is None and not dyn.bodies


def test_shapes_no_host_covers_are_refused_on_cuda(monkeypatch):
    """On CUDA a guest whose shape type the host's pipeline lacks fails to load (OptiX:
    "shape type not mapped"); the loader says so first, naming the type."""
    from dopplertof import loader

    monkeypatch.setattr(mi, "variant", lambda: "cuda_ad_rgb")
    with pytest.raises(dt.SceneError, match=r"<dict>: .*shape type 'sdfgrid' on cuda_ad_rgb"):
        loader.pipeline_host({"sdfgrid", "sphere", "diffuse"}, "<dict>")


def test_a_moving_area_light_scaled_per_axis_by_its_own_to_world_renders_like_it_at_rest():
    """``mi.cornell_box()``'s ceiling light (to_world scales x and y differently) given a
    translation: it was refused (its scale went into the motion, which then looked
    non-conformal); the scale now stays in the shape. 1.5 mm of travel: the image is the
    static one's within noise."""
    import mitsuba as mi

    def box(moving):
        d = mi.cornell_box()
        d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = 16
        if moving:
            d["light"]["motion"] = {"type": "parametric", "linear_velocity": [1, 0, 0]}
        return dt.load_scene(d)

    scene = box(True)
    assert len(scene.bodies) == 1 and scene.bodies[0].scene.emitters() and scene.bodies[0].motion.is_conformal()
    a = dt.render(scene, spp=256, seed=1, max_depth=3)
    b = dt.render(box(False), spp=256, seed=2, max_depth=3)
    z = (a.intensity - b.intensity) / np.hypot(a.stderr, b.stderr)
    assert abs(np.nanmean(z)) < 0.2 and 0.8 < np.nanstd(z) < 1.25, (np.nanmean(z), np.nanstd(z))


# ----------------------------------------------------------------------------------------
# Errors that name the user's file and line (a trial of scenes written by others)


def test_mitsubas_errors_name_the_users_file_and_line_through_defaults_and_includes(tmp_path):
    """Mitsuba parses the rewritten text ($name substituted, includes expanded): its errors
    said "At string (line 5, col 60)", a line of that text, not of the file (line 7)."""
    body = ('  <default name="r" value="0.5"/>\n  <default name="q" value="0.5"/>\n'
            '  <shape type="sphere"><float name="radius" value="$r"/><bsdf type="nosuchbsdf"/></shape>')
    path = write_scene(tmp_path, body)  # the sphere's <bsdf> is on line 7 of the file
    with pytest.raises(dt.SceneError, match=r"At .*scene\.xml \(line 7\): failed to instantiate bsdf plugin") as exc:
        dt.load_scene(path)
    assert "string" not in str(exc.value)
    (tmp_path / "sub dir ü").mkdir()
    (tmp_path / "sub dir ü" / "inc.xml").write_text(
        '<scene version="3.0.0">\n  <shape type="sphere"><bsdf type="diffuse"><float name="bogus" value="1"/></bsdf></shape>\n</scene>\n')
    path = write_scene(tmp_path, '  <default name="r" value="0.5"/>\n  <include filename="sub dir ü/inc.xml"/>', name="main.xml")
    with pytest.raises(dt.SceneError, match=r"inc\.xml \(line 2\): Found 1 unreferenced property"):
        dt.load_scene(path)


@pytest.mark.parametrize("where, body", [
    ("bsdf", '<shape type="sphere"><bsdf type="diffuse">{anim}</bsdf></shape>'),
    ("shape", '<shape type="shapegroup" id="g"><shape type="sphere">{anim}</shape></shape><shape type="instance"><ref id="g"/></shape>'),
    ("emitter", '<shape type="sphere"><emitter type="area">{anim}<rgb name="radiance" value="1"/></emitter></shape>'),
])  # fmt: skip
def test_an_animation_where_nothing_moves_is_refused_naming_its_line(tmp_path, where, body):
    """It was Mitsuba's "unsupported XML element: <animation>" at a line of the rewritten text."""
    anim = '<animation name="to_world"><transform time="0"><translate z="0"/></transform><transform time="0.001"><translate z="0.01"/></transform></animation>'
    path = write_scene(tmp_path, body.format(anim=anim))
    with pytest.raises(dt.SceneError, match=rf'an <animation> inside <{where} type="\w+"> \(.*scene\.xml \(line 5\)\): only a top-level shape') as exc:
        dt.load_scene(path)
    assert_one_line(exc)


def test_a_new_film_size_is_refused_beside_a_crop_window_in_files_and_dicts(tmp_path):
    film = '<integer name="crop_width" value="4"/><integer name="crop_height" value="4"/>'
    path = tmp_path / "crop.xml"
    path.write_text(f'<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>'
                    f'<integer name="height" value="8"/>{film}</film></sensor></scene>')
    says = r"crop_width, crop_height, a crop window of its own size; a new film size \(--resolution, film_resolution=\) would crop something else"
    with pytest.raises(dt.SceneError, match=says):
        dt.load_scene(path, film_resolution=16)
    scene = {"type": "scene", "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8, "crop_width": 4, "crop_height": 4}}}
    with pytest.raises(dt.SceneError, match=says):  # the dict's crop was kept with the new size
        dt.load_scene(scene, film_resolution=16)
    assert dt.load_scene(scene).resolution == (4, 4)


def test_emitters_inside_the_sensor_are_refused_in_their_own_words(tmp_path):
    """An area light in the <sensor> was "a 'area' emitter cannot move", and an <animation>
    on a light in the sensor named every place but that one."""
    film = '<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>'
    anim = '<animation name="to_world"><transform time="0"><translate z="0"/></transform><transform time="0.001"><translate z="0.01"/></transform></animation>'
    for emitter, says in [
        ('<emitter type="area"><rgb name="radiance" value="1"/></emitter>', "an emitter of type 'area' inside the <sensor> would move with the camera"),
        (f'<emitter type="point">{anim}</emitter>', "or an emitter inside the sensor (it moves with the camera)"),
    ]:  # fmt: skip
        path = tmp_path / "s.xml"
        path.write_text(f'<scene version="3.0.0"><sensor type="perspective">{film}{emitter}</sensor><shape type="rectangle"/></scene>')
        with pytest.raises(dt.SceneError, match=re.escape(says)):
            dt.load_scene(path)
