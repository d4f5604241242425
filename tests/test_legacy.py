"""Scene files of the original Mitsuba 0.6 D-ToF code (dopplertof.mitsuba06), the loader's
<include>, $name and film_resolution, and the render command's -D and --resolution."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import cli, mitsuba06, scenes
from dopplertof.motion import Keyframed
from dopplertof.settings import RenderSettings, integrator_layer


def render_settings(params):
    return RenderSettings.build(integrator_layer(params), {"spp": 840})  # a multiple of any group size used here

SENSOR_0_6 = """
    <sensor type="perspective">
        <float name="shutterOpen" value="0"/><float name="shutterClose" value="0.0015"/>
        <film type="mfilm"><integer name="width" value="4"/><integer name="height" value="4"/>{film}</film>
    </sensor>"""


def write(tmp_path, body, name="scene.xml", version="0.6.0", film=""):
    path = tmp_path / name
    path.write_text(f'<scene version="{version}">{SENSOR_0_6.format(film=film)}\n{body}\n</scene>\n')
    return path


@pytest.fixture(scope="module")
def pair(data_dir):
    return dt.load_scene(data_dir / "legacy" / "cornell_0_6.xml"), dt.load_scene(data_dir / "legacy" / "cornell_3.xml")


# ----------------------------------------------------------------------------------------
# The 0.6 Cornell box equals its Mitsuba 3 form


def test_0_6_scene_loads_like_its_mitsuba3_form(pair):
    old, new = pair
    assert render_settings(old.integrator_params) == render_settings(new.integrator_params)
    assert old.resolution == new.resolution == (256, 256)
    assert old.spp_hint == new.spp_hint == 1024  # 512 camera samples x 2 times
    np.testing.assert_array_equal(np.array(old.sensor.world_transform().matrix), np.array(new.sensor.world_transform().matrix))
    assert str(old.sensor.film()) == str(new.sensor.film())

    def boxes(scene):  # Mitsuba merges the white rectangles into one mesh
        shapes = [(s.class_name(), s.id(), tuple(s.bbox().min), tuple(s.bbox().max)) for s in scene.static.shapes()]
        return sorted(shapes), (tuple(scene.static.bbox().min), tuple(scene.static.bbox().max))

    assert boxes(old) == boxes(new) and len(boxes(old)[0]) == 3
    assert [b.name for b in old.bodies] == [b.name for b in new.bodies] == ["short-box", "tall-box"]
    for a, b in zip(old.bodies, new.bodies):
        assert isinstance(a.motion, Keyframed)
        for t in (0.0, 0.0004, 0.0015):
            np.testing.assert_array_equal(a.motion.matrix(t), b.motion.matrix(t))


def test_0_6_scene_renders_like_its_mitsuba3_form(data_dir):
    images = []
    for name in ("cornell_0_6.xml", "cornell_3.xml"):
        scene = dt.load_scene(data_dir / "legacy" / name, film_resolution=16)
        images.append(dt.render(scene, spp=8, seed=5))
    old, new = images
    assert np.isfinite(old.measurements[0]).all() and np.abs(old.measurements[0]).max() > 0
    for field in ("measurements", "intensity", "depth", "velocity"):
        np.testing.assert_array_equal(np.asarray(getattr(old, field)), np.asarray(getattr(new, field)))


# ----------------------------------------------------------------------------------------
# The integrator keys


@pytest.mark.parametrize(
    "props, expected",
    [
        ({}, {"time_sampling": "uniform", "n_times": 2, "correlation": "none", "stratify_intervals": False}),
        ({"maxDepth": 3, "rrDepth": 7, "hideEmitters": True}, {"max_depth": 3, "rr_depth": 7, "hide_emitters": True}),
        ({"time": 0.002, "w_g": 20, "w_s": 20.0005, "g_1": 0.4, "g_0": 0.6}, {"time": 0.002, "w_g": 20.0, "w_s": 20.0005, "g_1": 0.4, "g_0": 0.6}),
        ({"sensor_phase_offset": 1.0, "hetero_offset": 0.25, "hetero_frequency": 1.0}, {"sensor_phase_offset": 1.0, "hetero_offset": 0.25, "hetero_frequency": 1.0}),
        ({"wave_function_type": "triangular"}, {"wave_function_type": "triangular"}),
        ({"low_srequency_component_only": False}, {"low_frequency_component_only": False}),
        ({"low_frequency_component_only": True}, {}),
        ({"time_sampling_mode": "antithetic"}, {"time_sampling": "antithetic", "n_times": 2, "antithetic_shift": 0.5}),
        ({"time_sampling_mode": "antithetic", "antithetic_shifts": "0.25"}, {"antithetic_shift": 0.25, "n_times": 2}),
        ({"time_sampling_mode": "antithetic", "antithetic_shifts": " 0.75\t0.25  0.5 "}, {"n_times": 4}),
        ({"time_sampling_mode": "antithetic", "antithetic_shifts_number": 3}, {"n_times": 3}),
        ({"time_sampling_mode": "antithetic_mirror"}, {"time_sampling": "antithetic_mirror", "antithetic_shift": 0.0}),
        ({"time_sampling_mode": "antithetic_mirror", "antithetic_shifts": "0.50"}, {"antithetic_shift": 0.5}),
        ({"time_sampling_mode": "stratified", "antithetic_shifts": "0.1 0.7"}, {"time_sampling": "stratified", "n_times": 3}),
        ({"use_full_time_stratification": True}, {"stratify_intervals": True}),
        ({"spatial_correlation_mode": "pixel"}, {"correlation": "pixel"}),
        ({"spatial_correlation_mode": "sampler"}, {"correlation": "replay"}),
        ({"spatial_correlation_mode": "ray_position"}, {"correlation": "reconnection"}),
        ({"spatial_correlation_mode": "ray_sampler"}, {"correlation": "replay"}),
        ({"spatial_correlation_mode": "ray_adaptive", "m_reconnection_threshold": 0.3}, {"correlation": "adaptive", "m_reconnection_threshold": 0.3}),
        ({"time_sampling_mode": "analytic", "spatial_correlation_mode": "ray_sampler"}, {"time_sampling": "analytic", "correlation": "replay"}),
        ({"primal_antithetic_mis_power": 1.0, "force_constant_attenuation": False, "image_offset": 1.0}, {}),
        ({"image_offset": 0.0}, {}),
    ],
)
def test_integrator_keys(props, expected):
    params, strict = mitsuba06.integrator_params(dict(props))
    assert not strict
    assert {k: params[k] for k in expected} == expected
    assert "antithetic_shift" not in params or params["time_sampling"] in ("antithetic", "antithetic_mirror")
    settings = render_settings(params)  # every translation is a valid render setting
    assert settings.time_sampling == params["time_sampling"] and settings.group_size == params["n_times"]


def test_strict_normals_is_reported():
    assert mitsuba06.integrator_params({"strictNormals": True})[1] is True
    assert mitsuba06.integrator_params({"strictNormals": False})[1] is False


@pytest.mark.parametrize(
    "props, match",
    [
        ({"maxdepth": 3}, r"unknown Mitsuba 0.6 dopplertofpath parameter 'maxdepth'"),
        ({"maxDepth": 3.5}, r"'maxDepth' must be a <integer>"),
        ({"hideEmitters": "yes"}, r"'hideEmitters' must be a <boolean>"),
        ({"spatial_correlation_mode": "mis"}, r"'mis'.*no equivalent"),
        ({"spatial_correlation_mode": "ray"}, r"unknown spatial_correlation_mode 'ray'"),
        ({"time_sampling_mode": "periodic"}, r"unknown time_sampling_mode 'periodic'"),
        ({"primal_antithetic_mis_power": 2.0}, r"'primal_antithetic_mis_power'=2.0 is not supported: only the balance heuristic"),
        ({"force_constant_attenuation": True}, r"'force_constant_attenuation'=True is not supported"),
        ({"image_offset": 100.0}, r"'image_offset'=100.0 is not supported"),
        ({"low_frequency_component_only": False}, r"ignored by the original.*low_srequency_component_only"),
        ({"time_sampling_mode": "antithetic", "antithetic_shifts": "0.2 0.5"}, r"evenly spaced set i/3"),
        ({"time_sampling_mode": "antithetic", "antithetic_shifts": "0.12_0.35"}, r"whitespace-separated numbers"),
        ({"antithetic_shifts": ""}, r"'antithetic_shifts' is empty"),
        ({"antithetic_shifts_number": -1}, r"'antithetic_shifts_number' must be >= 0"),
        ({"antithetic_shifts_number": 4, "antithetic_shifts": "0.5"}, r"contradicts 'antithetic_shifts_number'=4"),
        ({"time_sampling_mode": "antithetic_mirror", "antithetic_shifts": "0.5 0.25"}, r"antithetic_mirror takes one shift"),
        ({"time_sampling_mode": "antithetic_mirror", "antithetic_shifts_number": 3}, r"antithetic_mirror pairs 2 times"),
        ({"spatial_correlation_mode": "ray_position", "antithetic_shifts_number": 3}, r"ray_position pairs 2 times"),
        ({"time_sampling_mode": "analytic", "spatial_correlation_mode": "sampler"}, r"analytic time sampling needs a paired"),
    ],
)
def test_integrator_refusals(props, match):
    with pytest.raises(dt.SceneError, match=match):
        mitsuba06.integrator_params(dict(props), "here")


# ----------------------------------------------------------------------------------------
# Scene elements


def translated(xml):
    root = ET.fromstring(xml)
    mitsuba06.translate(root, "test")
    return root


@pytest.mark.parametrize(
    "name, snake",
    [("toWorld", "to_world"), ("intIOR", "int_ior"), ("cropOffsetX", "crop_offset_x"), ("sampleCount", "sample_count"),
     ("fovAxis", "fov_axis"), ("specularReflectance", "specular_reflectance"), ("max_depth", "max_depth"), ("B", "B")],
)
def test_names_follow_mitsuba3s_upgrade_rule(name, snake):
    assert mitsuba06.snake_case(name) == snake


def test_detection(data_dir):
    assert mitsuba06.is_legacy(ET.fromstring('<scene version="0.5.0"/>'))
    assert mitsuba06.is_legacy(ET.fromstring('<scene version="3.0.0"><shape type="cube"><transform name="toWorld"/></shape></scene>'))
    assert mitsuba06.is_legacy(ET.fromstring('<scene version="3.0.0"><integrator type="dopplertofpath"><string name="time_sampling_mode" value="uniform"/></integrator></scene>'))
    assert not mitsuba06.is_legacy(ET.parse(data_dir / "original_cornell.xml").getroot())
    assert not mitsuba06.is_legacy(ET.parse(data_dir / "legacy" / "cornell_3.xml").getroot())


def test_element_translations():
    root = translated(
        '<scene version="0.6.0">'
        '<sensor type="thinlens"><float name="apertureRadius" value="0.1"/><float name="focusDistance" value="2"/>'
        '<sampler type="ldsampler"><integer name="sampleCount" value="16"/><integer name="dimension" value="4"/></sampler>'
        '<film type="mfilm"/></sensor>'
        '<bsdf type="conductor" id="c"/><bsdf type="roughconductor" id="m"><string name="material" value="Au"/></bsdf>'
        '<bsdf type="roughdiffuse" id="r"><float name="alpha" value="0"/><srgb name="reflectance" value="#808080" intent="reflectance"/></bsdf>'
        '<shape type="sphere"><transform name="toWorld"><lookAt origin="0 0 1" target="0 0 0" up="0 1 0"/></transform></shape>'
        "</scene>"
    )
    assert root.attrib["version"] == "3.0.0"
    sensor = root.find("sensor")
    assert [p.attrib["name"] for p in sensor.findall("float")] == ["aperture_radius", "focus_distance"]
    sampler = sensor.find("sampler")
    assert sampler.attrib["type"] == "independent" and [(p.attrib["name"], p.attrib["value"]) for p in sampler] == [("sample_count", "16")]
    film = sensor.find("film")
    assert film.attrib["type"] == "hdrfilm" and film.find("rfilter").attrib["type"] == "box"
    # mfilm's default luminance is not made explicit: the intensity is written as RGB (a luminance film is refused)
    assert {p.attrib["name"]: p.attrib["value"] for p in film if "name" in p.attrib} == {"width": "1", "height": "1"}
    bsdfs = {b.attrib["id"]: b for b in root.findall("bsdf")}
    assert bsdfs["c"].find("string").attrib == {"name": "material", "value": "Cu"}
    assert [p.attrib["value"] for p in bsdfs["m"]] == ["Au"]
    assert bsdfs["r"].attrib["type"] == "diffuse" and bsdfs["r"].find("float") is None
    rgb = bsdfs["r"].find("rgb")
    assert rgb.attrib["name"] == "reflectance" and "intent" not in rgb.attrib
    np.testing.assert_allclose([float(v) for v in rgb.attrib["value"].split()], [0.2158605] * 3, rtol=1e-6)
    assert root.find("shape/transform").attrib["name"] == "to_world" and root.find("shape/transform/lookat") is not None


def test_sample_count_counts_paths():
    """0.6's sampleCount counts camera samples of n times each; our spp counts paths."""
    root = translated(
        '<scene version="0.6.0"><integrator type="dopplertofpath"><string name="time_sampling_mode" value="antithetic"/>'
        '<integer name="antithetic_shifts_number" value="4"/></integrator>'
        '<sensor type="perspective"><float name="shutterClose" value="0.0015"/>'
        '<sampler type="independent"><integer name="sampleCount" value="8"/></sampler></sensor></scene>'
    )
    assert root.find("sensor/sampler/integer").attrib["value"] == "32"


@pytest.mark.parametrize(
    "body, film, match",
    [
        ('<integrator type="dopplertofpath"><float name="time" value="0.002"/></integrator>', "", r"shutterClose=time=0.002"),
        ("", '<string name="pixelFormat" value="spectrum"/>', r"pixelFormat 'spectrum' has no Mitsuba 3 equivalent"),
        ('<bsdf type="roughdiffuse"><float name="alpha" value="0.2"/></bsdf>', "", r"roughdiffuse \(Oren-Nayar\)"),
        ('<shape type="sphere"><float name="maxSmoothAngle" value="30"/></shape>', "", r"max_smooth_angle.*unknown parameter"),
        ('<integrator type="dopplertofpath"><boolean name="hideEmitters" value="maybe"/></integrator>', "", r"<boolean name='hideEmitters' value='maybe'>: expected true or false"),
        ('<integrator type="dopplertofpath"><integer name="maxDepth" value="3.5"/></integrator>', "", r"<integer name='maxDepth' value='3.5'>: expected an integer"),
        ('<integrator type="path"><float name="maxDepth" value="x"/></integrator>', "", r"<float name='max_depth' value='x'>: expected a number"),
        ('<integrator type="dopplertofpath"><boolean name="strictNormals" value="true"/></integrator>'
         '<bsdf type="bumpmap"/>', "", r"strictNormals=true differs from Mitsuba 3 where a bump"),
    ],
)
def test_scene_refusals(tmp_path, body, film, match):
    with pytest.raises(dt.SceneError, match=match) as info:
        dt.load_scene(write(tmp_path, body, film=film))
    assert "\n" not in str(info.value) and "scene.xml" in str(info.value)


def test_strict_normals_on_flat_and_smooth_meshes(tmp_path):
    quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
    (tmp_path / "flat.obj").write_text(quad + "vn 0 0 1\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n")
    (tmp_path / "smooth.obj").write_text(quad + "vn 0 0 1\nvn 0.6 0 0.8\nf 1//1 2//2 3//1\nf 1//1 3//1 4//1\n")
    strict = '<integrator type="dopplertofpath"><boolean name="strictNormals" value="true"/></integrator>'
    for name, fails in (("flat", False), ("smooth", True)):
        path = write(tmp_path, f'{strict}<shape type="obj" id="{name}"><string name="filename" value="{name}.obj"/></shape><shape type="cube"/>')
        if fails:
            with pytest.raises(dt.SceneError, match="smooth-shaded mesh 'smooth'"):
                dt.load_scene(path)
        else:
            dt.load_scene(path)


# ----------------------------------------------------------------------------------------
# <include>, $name, film_resolution


def test_includes_are_relative_to_the_including_file(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "a.xml").write_text('<scene version="0.6.0"><include filename="b.xml"/></scene>')
    (tmp_path / "parts" / "b.xml").write_text('<scene version="0.6.0"><shape type="sphere" id="ball"><float name="radius" value="$r"/></shape></scene>')
    scene = dt.load_scene(write(tmp_path, '<default name="r" value="0.5"/><include filename="parts/a.xml"/>'))
    (ball,) = [s for s in scene.static.shapes() if s.id() == "ball"]
    assert float(ball.bbox().extents()[0]) == pytest.approx(1.0)


@pytest.mark.parametrize(
    "files, match",
    [
        ({"a.xml": '<scene version="0.6.0"><include filename="scene.xml"/></scene>'}, r"include cycle \(scene.xml -> a.xml -> scene.xml\)"),
        ({"a.xml": '<scene version="3.0.0"><shape type="sphere"/></scene>'}, r"version '3.0.0' mixes the Mitsuba 0.6 and 3 formats"),
        ({}, r"<include filename='a.xml'>.*not found"),
    ],
)
def test_bad_includes(tmp_path, files, match):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(dt.SceneError, match=match):
        dt.load_scene(write(tmp_path, '<include filename="a.xml"/>'))


@pytest.mark.parametrize("params, size", [({}, (24, 16)), ({"resx": 8}, (8, 16)), ({"res": 4}, (24, 4))])
def test_longest_parameter_name_is_substituted_first(tmp_path, params, size):
    body = '<default name="res" value="16"/><default name="resx" value="24"/>'
    film = '<integer name="width" value="$resx"/><integer name="height" value="$res"/>'
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{body}<sensor type="perspective"><film type="hdrfilm">{film}</film></sensor></scene>')
    assert dt.load_scene(path, **params).resolution == size


def test_film_resolution(data_dir, tmp_path):
    assert dt.load_scene(data_dir / "original_cornell.xml", film_resolution=(20, 12)).resolution == (20, 12)
    assert dt.load_scene(data_dir / "legacy" / "cornell_0_6.xml", film_resolution=10, res=99).resolution == (10, 10)
    scene = {"type": "scene", "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}}}
    assert dt.load_scene(scene, film_resolution=(6, 3)).resolution == (6, 3)
    with pytest.raises(dt.SceneError, match="film_resolution must be"):
        dt.load_scene(scene, film_resolution=(6, 0))
    with pytest.raises(dt.SceneError, match="crop_width"):
        dt.load_scene(write(tmp_path, "", film='<integer name="cropWidth" value="2"/>'), film_resolution=8)


# ----------------------------------------------------------------------------------------
# dopplertof render -D / --resolution


def test_cli_load_takes_defines_and_resolution(data_dir):
    path = str(data_dir / "legacy" / "cornell_0_6.xml")
    assert scenes.open_scene(path, None, ["res=8"]).resolution == (8, 8)
    assert scenes.open_scene(path, None, ["res=8", "resx=6"]).resolution == (6, 8)
    assert scenes.open_scene(path, "12x10", ["res=8"]).resolution == (12, 10)
    assert scenes.open_scene("cornell-box", "12").resolution == (12, 12)


@pytest.mark.parametrize(
    "args, message",
    [
        (["-D", "res"], "error: -D 'res': expected name=value"),
        (["-D", "=3"], "error: -D '=3': expected name=value"),
        (["--resolution", "0"], "error: --resolution '0': expected N or WxH"),
        (["--resolution", "8y8"], "error: --resolution '8y8': expected N or WxH"),
        (["-D", "spp=x"], "expected an integer"),
    ],
)
def test_cli_bad_defines_and_resolution(data_dir, tmp_path, args, message):
    result = CliRunner().invoke(cli.main, ["render", str(data_dir / "legacy" / "cornell_0_6.xml"), *args, "-o", str(tmp_path), "--quiet"])
    assert result.exit_code == 2 and message in result.output, result.output


def test_cli_built_in_scenes_refuse_defines_and_rectangles(tmp_path):
    for args, message in ((["-D", "a=1"], "-D applies to scene files"), (["--resolution", "8x4"], "built-in scenes are square")):
        result = CliRunner().invoke(cli.main, ["render", "cornell-box", *args, "-o", str(tmp_path), "--quiet"])
        assert result.exit_code == 2 and message in result.output, result.output


def test_cli_renders_a_0_6_file(data_dir, tmp_path):
    result = CliRunner().invoke(cli.main, ["render", str(data_dir / "legacy" / "cornell_0_6.xml"), "-D", "spp=2", "--resolution", "6x4",
                                           "-o", str(tmp_path), "--quiet"])
    assert result.exit_code == 0, result.output
    assert "at 4 spp" in result.output  # 2 camera samples x 2 times
    assert dt.io.read_exr(str(tmp_path / "intensity.exr")).shape[:2] == (4, 6)
