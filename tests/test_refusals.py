"""Nonsense is refused, naming the input; legal but suspicious values warn (issue 16).

Each refusal is checked where it enters (scene file, scene dict, Mitsuba plugin, API
argument) and, for a representative few, through the command line in a subprocess: one
``error:`` line on stderr, exit status 2.
"""

import math
import subprocess
import sys
import warnings

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.modulation import SPEED_OF_LIGHT_M_S

FILM = '<film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>'


def xml_scene(tmp_path, body="", sensor_inner="", name="scene.xml"):
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0"><sensor type="perspective">{FILM}{sensor_inner}</sensor><shape type="sphere"/>{body}</scene>\n')
    return path


def dict_scene(sensor_extra=None, **entries):
    sensor = {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}, **(sensor_extra or {})}
    return {"type": "scene", "sensor": sensor, "ball": {"type": "sphere"}, **entries}


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=600)


def assert_cli_error(result, *fragments):
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


# ----------------------------------------------------------------------------------------
# Emitted radiance


@pytest.mark.parametrize("value", ["nan", "inf", "-1"])
def test_xml_emitter_intensity_must_be_finite_and_not_negative(tmp_path, value):
    path = xml_scene(tmp_path, f'<emitter type="point" id="lamp"><rgb name="intensity" value="{value}"/></emitter>')
    with pytest.raises(dt.SceneError, match=r"scene\.xml: emitter 'lamp' \(PointLight\): 'intensity.value' = .*must be finite and >= 0"):
        dt.load_scene(path)


def test_dict_area_emitter_radiance_names_its_shape():
    scene = dict_scene(panel={"type": "rectangle", "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0, math.nan, 1.0]}}})
    with pytest.raises(dt.SceneError, match=r"AreaLight on shape 'panel'\): 'radiance.value' = \[1.0, nan, 1.0\]"):
        dt.load_scene(scene)


def test_emitter_on_a_moving_body_and_a_moving_light_are_checked_too():
    moving = {"type": "parametric", "linear_velocity": [0, 0, 1]}
    panel = {"type": "rectangle", "motion": moving, "emitter": {"type": "area", "radiance": -2.0}}
    with pytest.raises(dt.SceneError, match=r"moving body 'panel'.*'radiance.value'"):
        dt.load_scene(dict_scene(panel=panel))
    lamp = {"type": "point", "intensity": math.inf, "motion": moving}
    with pytest.raises(dt.SceneError, match=r"entry 'lamp'.*'intensity.value' = \[inf"):
        dt.load_scene(dict_scene(lamp=lamp))


def test_envmap_pixels_are_checked():
    pixels = np.ones((8, 16, 3), np.float32)
    pixels[2, 3, 1] = np.nan
    scene = {"type": "scene", "sensor": dict_scene()["sensor"], "sky": {"type": "envmap", "bitmap": mi.Bitmap(pixels)}}
    with pytest.raises(dt.SceneError, match=r"emitter 'sky' \(EnvironmentMapEmitter\): 'data' has 1 bad values of \d+, the first nan"):
        dt.load_scene(scene)


def test_plugin_refuses_a_nan_emitter():
    scene = mi.load_dict({**dict_scene(lamp={"type": "point", "intensity": math.nan}), "integrator": {"type": "dopplertof"}})
    with pytest.raises(Exception) as info:
        mi.render(scene, spp=2)
    chain = [info.value]  # Dr.Jit wraps the integrator's error in its own
    while chain[-1].__cause__ or chain[-1].__context__:
        chain.append(chain[-1].__cause__ or chain[-1].__context__)
    assert any(isinstance(e, dt.SceneError) and "emitter 'lamp' (PointLight): 'intensity.value'" in str(e) for e in chain), chain


def test_cli_refuses_a_scene_file_with_nan_radiance(tmp_path):
    path = xml_scene(tmp_path, '<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="nan"/></emitter></shape>')
    assert_cli_error(cli("render", path, "-o", tmp_path / "out", "--spp", 2), "scene.xml", "'radiance.value'", "must be finite and >= 0")
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------------------
# Sensors and shutters


def test_a_second_sensor_is_refused(tmp_path):
    second = f'<sensor type="perspective">{FILM}</sensor>'
    with pytest.raises(dt.SceneError, match=r"scene has 2 sensors; dopplertof renders one"):
        dt.load_scene(xml_scene(tmp_path, second))
    with pytest.raises(dt.SceneError, match=r"<dict>: the scene has 2 sensors; dopplertof renders one"):
        dt.load_scene(dict_scene(other={"type": "perspective"}))
    assert_cli_error(cli("render", xml_scene(tmp_path, second), "-o", tmp_path / "out"), "scene has 2 sensors; dopplertof renders one")


@pytest.mark.parametrize("shutter,match", [
    ('<float name="shutter_close" value="nan"/>', r"shutter_open=0.0 and shutter_close=nan s must be finite"),
    ('<float name="shutter_close" value="inf"/>', r"shutter_close=inf s must be finite"),
    ('<float name="shutter_open" value="0.25"/><float name="shutter_close" value="0.25"/>', r"shutter_open and shutter_close are both 0.25 s, a shutter that never opens"),
    ('<float name="shutter_close" value="0"/>', r"are both 0.0 s"),
])  # fmt: skip
def test_xml_shutter_must_be_finite_and_open(tmp_path, shutter, match):
    with pytest.raises(dt.SceneError, match=match):
        dt.load_scene(xml_scene(tmp_path, sensor_inner=shutter))


def test_dict_zero_length_shutter_is_refused_and_no_shutter_is_fine():
    with pytest.raises(dt.SceneError, match=r"<dict>: the sensor's shutter_open and shutter_close are both 0.5 s"):
        dt.load_scene(dict_scene({"shutter_open": 0.5, "shutter_close": 0.5}))
    assert dt.load_scene(dict_scene()).sensor.shutter_open_time() == 0.0  # none given: the default exposure


# ----------------------------------------------------------------------------------------
# Motion


def test_absurd_keyframe_translation_names_the_key_and_the_body(tmp_path):
    keys = '<transform time="0"><translate z="0"/></transform><transform time="1e-3"><translate z="1e30"/></transform>'
    body = f'<shape type="cube" id="crate"><animation name="to_world">{keys}</animation></shape>'
    with pytest.raises(dt.SceneError, match=r"id='crate'.*key at t=0.001 s: translation \[0.0, 0.0, 1e\+30\] m is beyond the 1e\+06 m"):
        dt.load_scene(xml_scene(tmp_path, body))


def test_absurd_pivot_is_refused():
    with pytest.raises(ValueError, match=r"pivot \[0.0, 10000000.0, 0.0\] m is beyond the 1e\+06 m"):
        dt.motion.Parametric(angular_velocity=(0, 1, 0), pivot=(0, 1e7, 0))


@pytest.mark.parametrize("speed", [SPEED_OF_LIGHT_M_S, 3e8, 1e12])
def test_parametric_speed_of_light_or_more_is_refused_naming_the_motion(speed):
    motion = {"type": "parametric", "linear_velocity": [0, 0, speed]}
    with pytest.raises(dt.SceneError, match=r"entry 'crate': linear_velocity is .* m/s, at or above the speed of light"):
        dt.load_scene(dict_scene(crate={"type": "cube", "motion": motion}))


def test_keyframes_faster_than_light_are_refused():
    with pytest.raises(ValueError, match=r"crate: the translation between the keys at t=0 and 1e-09 s is 1e\+09 m/s, at or above"):
        dt.motion.Keyframed([0.0, 1e-9], [np.eye(4), _translation(z=1.0)], where="crate")


def test_fast_but_possible_motion_warns_and_slow_motion_does_not():
    with pytest.warns(UserWarning, match=r"linear_velocity is 1e\+06 m/s, above 299792 m/s \(1e-3 c\)"):
        dt.motion.Parametric(linear_velocity=(1e6, 0, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dt.motion.Parametric(linear_velocity=(100.0, 0, 0))
        dt.motion.Keyframed([0.0, 1e-3], [np.eye(4), _translation(z=0.015)])


def _translation(x=0.0, y=0.0, z=0.0):
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    return m


# ----------------------------------------------------------------------------------------
# Cameras and settings (ranges in Camera and RenderSettings; Camera's own in test_modulation)


def test_settings_exposure_shares_the_camera_bound():
    with pytest.raises(ValueError, match=r"'exposure' must be in \(0, 60\] s, got 1e\+300"):
        dt.RenderSettings(exposure=1e300)


@pytest.mark.parametrize("spec,fragment", [("g1=-1", "'g1' (light modulation amplitude) must be > 0, got -1.0"),
                                           ("h=1,T=1e300", "'exposure' must be in (0, 60] s, got 1e+300"),
                                           ("g0=-5", "'g0' (light DC offset) must be >= 0, got -5.0")])  # fmt: skip
def test_cli_refuses_absurd_camera_values(tmp_path, spec, fragment):
    assert_cli_error(cli("render", xml_scene(tmp_path), "--camera", spec, "-o", tmp_path / "out"), f"camera {spec!r}", fragment)


# ----------------------------------------------------------------------------------------
# $name parameters


def test_unknown_name_parameters_are_refused_with_the_known_ones(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(
        f'<scene version="3.0.0"><default name="radius" value="1"/><sensor type="perspective">{FILM}</sensor>'
        '<shape type="sphere"><float name="radius" value="$radius"/><transform name="to_world"><translate z="$depth"/></transform></shape></scene>'
    )  # fmt: skip
    assert dt.load_scene(path, radius="2", depth="1") is not None
    with pytest.raises(dt.SceneError, match=r"scene\.xml: unknown parameters \$radus, \$spp; the scene's parameters: \$depth, \$radius"):
        dt.load_scene(path, radus="2", depth="1", spp="4")
    assert_cli_error(cli("render", path, "-D", "radus=2", "-D", "depth=1", "-o", tmp_path / "out"), "unknown parameter $radus", "$depth, $radius")
    with pytest.raises(dt.SceneError, match=r"unknown parameter \$dep;"):  # a prefix of $depth is not $depth (it was taken for it)
        dt.load_scene(path, dep="1", depth="1")


def test_a_name_used_only_in_an_included_file_is_known(tmp_path):
    (tmp_path / "ball.xml").write_text('<scene version="3.0.0"><shape type="sphere"><float name="radius" value="$r"/></shape></scene>')
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0"><sensor type="perspective">{FILM}</sensor><include filename="ball.xml"/></scene>')
    assert dt.load_scene(path, r="0.5") is not None
    with pytest.raises(dt.SceneError, match=r"unknown parameter \$radius; the scene's parameters: \$r$"):
        dt.load_scene(path, r="0.5", radius="1")


# ----------------------------------------------------------------------------------------
# render() arguments


@pytest.fixture(scope="module")
def tiny():
    return dt.load_scene(dict_scene(lamp={"type": "point", "position": [0, 0, 3], "intensity": 10.0}))


@pytest.mark.parametrize("progress", ["no", "false", 0, None])
def test_progress_must_be_a_bool(tiny, progress):
    with pytest.raises(ValueError, match=rf"'progress' must be a boolean \(true/false\), got {progress!r}"):
        dt.render(tiny, spp=2, progress=progress)


def test_settings_may_be_a_dict_of_setting_names(tiny):
    result = dt.render(tiny, settings={"spp": 4, "seed": 3})
    assert result.spp == 4 and result.settings.seed == 3
    with pytest.raises(ValueError, match=r"unknown setting 'sp'; did you mean 'spp'"):
        dt.render(tiny, settings={"sp": 4})
    with pytest.raises(TypeError, match=r"settings must be a dopplertof.RenderSettings or a dict of setting names, got list"):
        dt.render(tiny, settings=[("spp", 4)])


def test_stop_before_the_first_pass_returns_an_empty_interrupted_result(tiny, tmp_path):
    checkpoint = tmp_path / "checkpoint.npz"
    result = dt.render(tiny, spp=4, stop=lambda: True, checkpoint=checkpoint)
    assert result.interrupted and result.spp == 0 and result.info["passes_done"] == 0
    assert np.isnan(result.intensity).all()
    assert not checkpoint.exists()  # nothing done, nothing to continue from
    with pytest.raises(TypeError, match=r"stop must be a callable"):
        dt.render(tiny, spp=4, stop=True)


# ----------------------------------------------------------------------------------------
# Warnings: legal but almost surely a mistake


def test_a_render_of_days_warns_with_its_estimated_time():
    scene = dt.load_scene(dict_scene(), film_resolution=64)
    with pytest.warns(UserWarning, match=r"spp=1000000000 on a 64x64 film is 4.1e\+12 paths: about 15.8 days at 3e\+06 paths/s"):
        result = dt.render(scene, spp=10**9, stop=lambda: True)  # stopped before its first pass
    assert result.spp == 0


def test_more_replicates_than_groups_warns_and_the_default_does_not():
    with pytest.warns(UserWarning, match=r"replicates=64 exceeds the 2 group\(s\) .* standard errors come from 2 replicate\(s\)"):
        dt.RenderSettings(spp=2, time_sampling="uniform", replicates=64)
    with pytest.warns(UserWarning, match=r"come from 1 replicate\(s\), so they are NaN"):
        dt.RenderSettings(spp=2, stratify_intervals=False, replicates=8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dt.RenderSettings(spp=4)  # the default 16 replicates, fewer groups: the user asked for neither
        dt.RenderSettings(spp=64, time_sampling="uniform", replicates=32)
        dt.RenderSettings(spp=64, stratify_intervals=False, replicates=32)


@pytest.mark.parametrize("time_sampling", ["stratified", "antithetic", "antithetic_mirror"])
def test_replicates_of_stratified_times_warn_that_they_do_nothing(time_sampling):
    with pytest.warns(UserWarning, match=rf"replicates=4 has no effect: time_sampling='{time_sampling}' with stratify_intervals .* come from the strata"):
        dt.RenderSettings(spp=64, time_sampling=time_sampling, replicates=4)


def test_a_wrap_inside_a_stratum_warns():
    # 33 antithetic pairs: the partner's wrap at ½ T falls in the middle of a group's share
    with pytest.warns(UserWarning, match=r"spp=66 gives 33 groups of 2 times: antithetic's times wrap .* at 0.5 T, inside a stratum"):
        dt.RenderSettings(spp=66)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dt.RenderSettings(spp=68)  # 34 pairs: cut into two pieces of 17
        dt.RenderSettings(spp=66, time_sampling="stratified")  # no wrap
        dt.RenderSettings(spp=66, time_sampling="antithetic_mirror")  # wraps at a = 0
        dt.RenderSettings(spp=66, stratify_intervals=False)


@pytest.mark.parametrize("args,warning", [
    (("--spp", 2, "--time-sampling", "uniform", "--replicates", 64), "warning: replicates=64 exceeds the 2 group(s)"),
    (("--replicates", 4), "warning: replicates=4 has no effect"),
    (("--camera", "h=1,f=30"), "warning: Camera: modulation_frequency=30 Hz"),
])  # fmt: skip
def test_cli_prints_a_warning_as_one_line(tmp_path, args, warning):
    blocker = tmp_path / "out"
    blocker.write_text("not a folder")  # the render stops at its output folder, after the settings
    result = cli("render", xml_scene(tmp_path), *args, "-o", blocker)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 2, result.stderr
    assert lines[0].startswith(warning) and lines[1].startswith("error: "), result.stderr


# ----------------------------------------------------------------------------------------
# render_animation() arguments


def test_render_animation_takes_settings_as_a_dict_and_refuses_the_rest(tiny, tmp_path):
    from dopplertof.animate import render_animation

    with pytest.raises(TypeError, match=r"settings must be a dopplertof.RenderSettings or a dict of setting names, got list"):
        render_animation(tiny, str(tmp_path / "clip"), frames=1, settings=[("spp", 4)])
    with pytest.raises(ValueError, match=r"unknown setting 'sp'"):
        render_animation(tiny, str(tmp_path / "clip"), frames=1, settings={"sp": 4})
    with pytest.raises(ValueError, match=r"'overwrite' must be a boolean \(true/false\), got 'no'"):
        render_animation(tiny, str(tmp_path / "clip"), frames=1, overwrite="no")


def test_render_animation_stopped_raises_its_own_exception(tiny, tmp_path):
    from dopplertof.animate import AnimationStopped, render_animation

    with pytest.raises(AnimationStopped, match=r"stopped in frame 0"):
        render_animation(tiny, str(tmp_path / "clip"), frames=1, settings={"spp": 4}, stop=lambda: True, log=lambda line: None)
    assert not (tmp_path / "clip" / "frame_0000" / "done.json").exists()


def test_an_spp_beyond_what_one_render_holds_is_refused_before_any_work(tmp_path):
    """2e10 paths per pixel overflowed the UInt32 strata table (a traceback), and 1e12 on a
    16x16 film grew to 20 GB before its first pass; one line now, up front."""
    with pytest.raises(ValueError, match=r"spp=20000000000 exceeds its maximum 2147483648: the most paths per pixel one render takes"):
        dt.RenderSettings.build({"spp": 20_000_000_000})
    dt.RenderSettings.build({"spp": 1 << 31})
    proc = cli("render", "cornell-box", "--resolution", "1", "--spp", "20000000000", "-o", tmp_path / "out", "--quiet")
    assert proc.returncode == 2 and proc.stderr.strip().startswith("error:") and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["render", "animate"])
def test_an_empty_output_folder_name_is_refused(tmp_path, command):
    """``-o "$UNSET"`` wrote to the default folder without a word."""
    proc = cli(command, "cornell-box", "--resolution", "8", "--spp", "4", "--quiet", "-o", "", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.strip().startswith("error: -o/--output is empty"), proc.stderr
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------------------
# What a scene file says of its integrator, sampler, sensor and BSDFs (a plugin audit)


@pytest.mark.parametrize("kind, depth", [("path", -1), ("volpath", -1), ("prb", 6)])
def test_a_stock_integrator_without_a_depth_takes_mitsubas_default(tmp_path, kind, depth):
    """``<integrator type="path"/>`` is unbounded in Mitsuba; it rendered at our default
    depth 5 (58 % of stock's brightness in a closed room)."""
    from dopplertof.settings import STOCK_PATH_DEFAULTS, scene_layer

    assert f"max_depth = {2**32 - 1 if depth == -1 else depth}" in str(mi.load_dict({"type": kind}))  # the table is Mitsuba's
    assert STOCK_PATH_DEFAULTS[kind]["max_depth"] == depth
    for scene in (dt.load_scene(xml_scene(tmp_path, f'<integrator type="{kind}"/>')), dt.load_scene(dict_scene(integrator={"type": kind}))):
        assert scene_layer(scene)["max_depth"] == depth
    assert scene_layer(dt.load_scene(dict_scene(integrator={"type": kind, "max_depth": 3})))["max_depth"] == 3


@pytest.mark.parametrize("integrator", [{"type": "direct"}, {"type": "depth"}, {"type": "aov", "aovs": "dd:depth"}, {"type": "moment", "nested": {"type": "path"}}])
def test_a_dict_with_an_integrator_that_is_not_a_path_tracer_is_refused(integrator):
    """In a dict, such an integrator was dropped and the scene path-traced (XML refused it)."""
    with pytest.raises(dt.SceneError, match=f"<integrator type='{integrator['type']}'> is a stock Mitsuba integrator that computes something other"):
        dt.load_scene(dict_scene(integrator=integrator))


def test_the_samplers_count_and_seed_are_the_renders_defaults(tmp_path):
    """A dict's ``sample_count`` was ignored (XML's was kept) and a seed in either was."""
    from dopplertof.settings import scene_layer

    sampler = '<sampler type="stratified"><integer name="sample_count" value="8"/><integer name="seed" value="5"/></sampler>'
    for scene in (dt.load_scene(xml_scene(tmp_path, sensor_inner=sampler)), dt.load_scene(dict_scene({"sampler": {"type": "independent", "sample_count": 8, "seed": 5}}))):
        assert (scene.spp_hint, scene.seed_hint) == (8, 5) and {"spp": 8, "seed": 5}.items() <= scene_layer(scene).items()
    scene = dt.load_scene(dict_scene({"sampler": {"type": "independent", "sample_count": 8, "seed": 5}}, ball={"type": "sphere", "center": [0, 0, 3]}, sky={"type": "constant"}))
    a, b, c = (dt.render(scene, progress=False, **seed) for seed in ({}, {"seed": 5}, {"seed": 0}))
    assert a.spp == 8 and np.array_equal(a.intensity, b.intensity) and not np.array_equal(a.intensity, c.intensity)


def test_an_irradiance_meter_is_refused():
    """It loaded, then the render failed with a traceback from Mitsuba (sample_ray not implemented)."""
    scene = {"type": "scene", "patch": {"type": "rectangle", "sensor": {"type": "irradiancemeter", "film": {"type": "hdrfilm", "width": 1, "height": 1, "rfilter": {"type": "box"}}}},
             "sky": {"type": "constant"}}  # fmt: skip
    with pytest.raises(dt.SceneError, match="the sensor is an irradiancemeter"):
        dt.load_scene(scene)


def test_a_batch_sensor_is_refused_when_the_scene_loads():
    """Its cameras' radial velocity and velocity_3d were taken in the batch's own frame: a body
    approaching the first camera read velocity_3d z = +8.75 m/s (through a perspective camera
    of the same pose, -10), and its flow was NaN."""
    sensor = {"type": "batch", "a": {"type": "perspective"}, "b": {"type": "perspective"},
              "film": {"type": "hdrfilm", "width": 8, "height": 4, "rfilter": {"type": "box"}}}
    scene = {"type": "scene", "sensor": sensor, "ball": {"type": "sphere"}}
    with pytest.raises(dt.SceneError, match=r"the sensor is a batch sensor \(its cameras' ground truth .*render each of its cameras as a scene of its own"):
        dt.load_scene(scene)


@pytest.mark.parametrize(
    "bsdf",
    [{"type": "principled", "spec_trans": 0.5}, {"type": "mask", "opacity": 0.5, "bsdf": {"type": "dielectric"}},
     {"type": "blendbsdf", "weight": 0.5, "bsdf_0": {"type": "diffuse"}, "bsdf_1": {"type": "roughdielectric"}}],
    ids=["principled", "mask-dielectric", "blend-dielectric"],
)  # fmt: skip
def test_a_bsdf_that_transmits_other_than_a_dielectric_of_its_own_is_refused_on_loading(bsdf):
    """A dielectric inside ``mask`` rendered with the index of air (wrong optical lengths);
    the others were refused only when the render began, with a message that said "not
    inside Principled" of a principled BSDF on its own."""
    with pytest.raises(dt.SceneError, match=r"shape 'ball': BSDF .* transmits light through the surface"):
        dt.load_scene(dict_scene(ball={"type": "sphere", "bsdf": bsdf}))


@pytest.mark.parametrize("bsdf", [{"type": "thindielectric"}, {"type": "null"}, {"type": "mask", "opacity": 0.5, "bsdf": {"type": "diffuse"}}, {"type": "dielectric"}])
def test_straight_through_and_dielectric_bsdfs_load(bsdf):
    from dopplertof.tracing.materials import relative_ior

    scene = dt.load_scene(dict_scene(ball={"type": "sphere", "bsdf": bsdf}))
    eta = relative_ior(scene.static.shapes()[0].bsdf())
    assert eta == pytest.approx(1.5046 / 1.000277, rel=1e-5) if bsdf["type"] == "dielectric" else eta == 1.0  # Mitsuba's bk7 in air


@pytest.mark.parametrize("pixel_format", ["xyz", "luminance", "rgba"])
def test_a_film_pixel_format_other_than_rgb_is_refused(pixel_format):
    """It was ignored: an xyz film's intensity.exr held RGB values under R, G, B."""
    film = {"type": "hdrfilm", "width": 4, "height": 4, "pixel_format": pixel_format, "rfilter": {"type": "box"}}
    scene = {"type": "scene", "sensor": {"type": "perspective", "film": film}, "ball": {"type": "sphere"}}
    with pytest.raises(dt.SceneError, match=f"the film's pixel_format is '{pixel_format}'"):
        dt.load_scene(scene)
    film["pixel_format"] = "rgb"
    dt.load_scene(scene)


def _spun_ball(angular_velocity_rad_s):
    look = mi.ScalarTransform4f().look_at(origin=[0, 0, 8], target=[0, 0, 0], up=[0, 1, 0])
    return {"type": "scene", "sensor": {"type": "perspective", "to_world": look, "film": {"type": "hdrfilm", "width": 4, "height": 4}},
            "ball": {"type": "sphere", "to_world": mi.ScalarTransform4f().translate([2, 0, 0]),
                     "motion": {"type": "parametric", "angular_velocity": [0, angular_velocity_rad_s, 0], "pivot": [0, 0, 0]}}}


def test_a_rotation_faster_than_light_is_refused_and_a_suspicious_one_warns():
    """Only the linear velocity was checked: a ball spun at 1e9 rad/s 2 m from its pivot
    rendered with a ground truth of 3e9 m/s."""
    with pytest.raises(dt.SceneError, match=r"entry 'ball': the fastest corner of its bounding box, rotation included is 3\.3\d+e\+09 m/s, at or above the speed of light"):
        dt.load_scene(_spun_ball(1e9))
    with pytest.warns(UserWarning, match=r"rotation included is 663325 m/s, above .* is the unit m/s\?"):
        dt.load_scene(_spun_ball(2e5))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dt.load_scene(_spun_ball(10.0))  # 33 m/s: nothing to say


# ----------------------------------------------------------------------------------------
# Elements Mitsuba ignores or cannot render here (a trial of scenes written by others)

BLACKBODY = '<spectrum type="blackbody" name="radiance"><float name="temperature" value="3000"/></spectrum>'


@pytest.mark.parametrize("body, fragment", [
    ('<integrator type="path"/><integrator type="path"><integer name="max_depth" value="6"/></integrator>', "a second <integrator>"),
    ('<sampler type="independent"><integer name="sample_count" value="12"/></sampler>', "a <sampler> outside the <sensor> is ignored"),
    ('<film type="hdrfilm"/>', "a <film> outside the <sensor> is ignored"),
    (f'<emitter type="constant">{BLACKBODY}</emitter>', "a blackbody spectrum needs a spectral Mitsuba variant"),
    (f'<shape type="rectangle"><emitter type="area">{BLACKBODY}</emitter></shape>', "blackbody"),
    ('<shape type="sphere" id="ball"><float name="radius" value="nan"/></shape>', "shape 'ball' has a position or size that is not finite"),
    ('<shape type="cube" id="box"><transform name="to_world"><translate y="nan"/></transform></shape>', "shape 'box' has a position or size that is not finite"),
])  # fmt: skip
def test_xml_elements_that_would_be_dropped_or_fail_mid_render_are_refused(tmp_path, body, fragment):
    with pytest.raises(dt.SceneError, match=fragment):
        dt.load_scene(str(xml_scene(tmp_path, body)))


def test_the_command_line_refuses_a_blackbody_in_one_line(tmp_path):
    path = xml_scene(tmp_path, f'<emitter type="constant">{BLACKBODY}</emitter>')
    assert_cli_error(cli("render", path, "-o", tmp_path / "out", "--spp", "4"), "blackbody spectrum")


@pytest.mark.parametrize("entries, fragment", [
    ({"a": {"type": "path"}, "b": {"type": "path", "max_depth": 6}}, "a second integrator"),
    ({"sky": {"type": "constant", "radiance": {"type": "blackbody", "temperature": 3000.0}}}, "blackbody"),
    ({"box": {"type": "cube", "to_world": mi.ScalarTransform4f().translate([0.0, math.nan, 0.0])}}, "shape 'box' has a position or size that is not finite"),
])  # fmt: skip
def test_dict_entries_that_would_be_dropped_or_fail_mid_render_are_refused(entries, fragment):
    with pytest.raises(dt.SceneError, match=fragment):
        dt.load_scene(dict_scene(**entries))


def test_an_odd_spp_from_the_files_sampler_says_where_it_came_from(tmp_path):
    path = xml_scene(tmp_path, sensor_inner='<sampler type="independent"><integer name="sample_count" value="7"/></sampler>')
    assert_cli_error(cli("render", path, "-o", tmp_path / "out"), "spp=7 must be a multiple of the 2", "the scene's <sampler> sample_count")


def test_what_is_not_a_dopplertof_scene_is_refused_saying_what_to_do():
    """``mi.cornell_box()`` or a file name handed to ``render`` is told to go through
    ``load_scene``; a scene Mitsuba already loaded (its motions, if any, gone) is told where
    it can go instead."""
    with pytest.raises(ValueError, match=r"got dict; give it to dopplertof.load_scene first"):
        dt.render(mi.cornell_box(), spp=4)
    with pytest.raises(ValueError, match=r"got str; give it to dopplertof.load_scene first"):
        dt.render("scene.xml", spp=4)
    loaded = mi.load_dict(dict_scene())
    for call in (lambda: dt.render(loaded, spp=4), lambda: dt.load_scene(loaded)):
        with pytest.raises(ValueError, match=r"got Scene; a loaded mi.Scene cannot be taken apart again: give its file or dict to dopplertof.load_scene, "
                                             r"or render it with mi.render and the 'dopplertof' integrator"):
            call()
