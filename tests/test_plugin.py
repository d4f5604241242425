"""The Mitsuba integrator plugin (`dopplertof`, `dopplertofpath`): registration, the original
code's parameter names (reference §8.2, §2.2, §3.6), the CLI reading them from a scene
file, and `mi.render` through the plugin against stock `path`."""

import json
import math
import os
import subprocess
import sys

import mitsuba as mi
import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import cli
from dopplertof.plugin import PLUGIN_NAMES, output_channels, render_image
from dopplertof.settings import RenderSettings, integrator_layer

from scene_dicts import T, grey, perspective


def render_settings(params: dict, where: str = "integrator") -> RenderSettings:
    """The settings an ``<integrator>`` block asks for (as the plugin and the CLI build them)."""
    return RenderSettings.build(integrator_layer(params, where), where=where)


# ----------------------------------------------------------------------------------------
# Registration


@pytest.mark.parametrize("name", PLUGIN_NAMES)
def test_plugin_loads_under_both_names(name):
    integrator = mi.load_dict({"type": name, "w_g": 30, "hetero_frequency": 1.0, "max_depth": 4})
    assert isinstance(integrator, mi.Integrator)
    camera = integrator.settings.cameras[0]
    assert camera.modulation_frequency == 30e6 and camera.heterodyne == 1.0
    assert integrator.settings.max_depth == 4
    assert integrator.aov_names() == output_channels()[3:]


def test_plugin_loads_from_a_scene_file(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(
        '<scene version="3.0.0"><integrator type="dopplertofpath">'
        '<float name="hetero_offset" value="0.25"/><integer name="path_correlation_depth" value="16"/>'
        "</integrator></scene>"
    )
    settings = mi.load_file(str(path)).integrator().settings
    assert settings.cameras[0].phase == pytest.approx(math.pi / 2)
    assert (settings.correlation, settings.correlation_depth) == ("replay", 16)


def test_unknown_or_mistyped_parameter_is_a_clear_error():
    with pytest.raises(RuntimeError, match=r"unknown setting 'w_gg'; did you mean 'w_g'\?"):
        mi.load_dict({"type": "dopplertof", "w_gg": 30})
    with pytest.raises(RuntimeError, match=r"'max_depth' must be an integer, got 2.5"):
        mi.load_dict({"type": "dopplertofpath", "max_depth": 2.5})
    with pytest.raises(ValueError, match=r"scene.xml: 'low_frequency_component_only' must be a boolean \(true/false\), got 'yes'"):
        render_settings({"low_frequency_component_only": "yes"}, "scene.xml")
    with pytest.raises(ValueError, match=r"^integrator: unknown time_sampling 'mirror'"):
        render_settings({"time_sampling_method": "mirror"})
    with pytest.raises(ValueError, match=r"give either 'exposure' or 'time', not both"):
        render_settings({"time": 1e-3, "exposure": 1e-3})


_REGISTRATION_SCRIPT = """
import os, sys
import mitsuba as mi
if sys.argv[1] == "variant-first":
    mi.set_variant(os.environ["DOPPLERTOF_VARIANT"])
import dopplertof as dt
if sys.argv[1] == "import-first":
    assert mi.variant() is None, mi.variant()   # importing sets no variant
    mi.set_variant(os.environ["DOPPLERTOF_VARIANT"])
    mi.load_dict({"type": "dopplertofpath"})
    dt.set_variant(os.environ["DOPPLERTOF_VARIANT"].replace("rgb", "mono"))  # and a later one
print(mi.variant(), mi.load_dict({"type": "dopplertof", "w_g": 20}).settings.cameras[0].modulation_frequency)
"""


@pytest.mark.parametrize("order", ["variant-first", "import-first"])
def test_registration_follows_the_variant(order):
    """Registered whether the variant is set before importing dopplertof or after it."""
    run = subprocess.run([sys.executable, "-c", _REGISTRATION_SCRIPT, order], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    variant, frequency = run.stdout.split()
    first = os.environ["DOPPLERTOF_VARIANT"]
    assert variant == (first.replace("rgb", "mono") if order == "import-first" else first)
    assert float(frequency) == 20e6


_SPECTRAL_SCRIPT = """
import warnings, mitsuba as mi
mi.set_variant("llvm_ad_spectral")
import dopplertof as dt
try:
    mi.load_dict({"type": "dopplertof"})
except RuntimeError as exc:
    print(str(exc).splitlines()[-1])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    dt.scenes.cornell_box(resolution=4)
print(mi.variant(), "|", "; ".join(str(w.message) for w in caught))
"""


def test_a_variant_dopplertof_does_not_render_in_is_named_not_switched_silently():
    """Under llvm_ad_spectral the plugin said 'Plugin "dopplertof" not found!', and
    dt.load_scene switched the variant to llvm_ad_rgb without a word."""
    run = subprocess.run([sys.executable, "-c", _SPECTRAL_SCRIPT], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    plugin, switched = run.stdout.strip().splitlines()
    assert plugin.startswith("ValueError: the dopplertof integrator renders in the Mitsuba variants llvm_ad_rgb") and "not in 'llvm_ad_spectral'" in plugin
    assert switched.startswith("llvm_ad_rgb | Mitsuba's active variant 'llvm_ad_spectral' is not one dopplertof renders in"), switched


def test_scene_dict_keeps_a_dopplertofpath_integrator():
    scene = dt.load_scene(
        {
            "type": "scene",
            "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}},
            "integrator": {"type": "dopplertofpath", "w_g": 20},
        }
    )
    assert scene.integrator_params == {"type": "dopplertofpath", "w_g": 20}


# ----------------------------------------------------------------------------------------
# The settings mapping, against the reference's table (§8.2; §2.2 shift default; §3.6)


def _camera(params):
    return render_settings(params).cameras[0]


def test_defaults_are_the_originals():
    """Camera defaults are the original's; every other setting is RenderSettings' one
    default (replay correlation, max_depth 5: see dopplertof.plugin)."""
    s = render_settings({})
    assert vars(s.cameras[0]) == dict(
        modulation_frequency=30e6, exposure=0.0015, heterodyne=0.0, phase=0.0,
        waveform="sinusoidal", g1=0.5, g0=0.5, low_pass=True, exposure_start=None,
        light_code=None, sensor_code=None, light_bandwidth=None,
    )
    resolved = dict(
        time_sampling=s.time_sampling, n_times=s.group_size, antithetic_shift=s.shift, stratify_intervals=s.stratify_intervals,
        correlation=s.correlation, correlation_depth=s.correlation_depth, reconnection_threshold=s.threshold,
        max_depth=s.max_depth, rr_depth=s.rr_depth, hide_emitters=s.hide_emitters, exposure_start=s.exposure_start,
    )
    assert resolved == dict(
        time_sampling="antithetic", n_times=2, antithetic_shift=0.5, stratify_intervals=True,
        correlation="replay", correlation_depth=None, reconnection_threshold=0.5, max_depth=5, rr_depth=5,
        hide_emitters=False, exposure_start=0.0,
    )
    assert s.replace(cameras=()) == RenderSettings()  # one default: the API's


@pytest.mark.parametrize(
    "params, field, expected",
    [
        ({"time": 0.002}, "exposure", 0.002),
        ({"w_g": 20}, "modulation_frequency", 20e6),  # MHz -> Hz
        ({"w_g": 20, "w_s": 20.002, "time": 0.001}, "heterodyne", 2.0),  # h = (w_s - w_g)·1e6·T
        ({"hetero_frequency": 0.5, "w_s": 99}, "heterodyne", 0.5),  # hetero_frequency wins
        ({"sensor_phase_offset": 1.0}, "phase", 1.0),  # rad
        ({"hetero_offset": 0.25, "sensor_phase_offset": 1.0}, "phase", math.pi / 2),  # 2π·value, wins
        ({"g_1": 0.8}, "g1", 0.8),
        ({"g_0": 0.3}, "g0", 0.3),
        ({"wave_function_type": "triangular"}, "waveform", "triangular"),
        ({"low_frequency_component_only": False}, "low_pass", False),
        ({"modulation_frequency": 15e6}, "modulation_frequency", 15e6),  # SI names
        ({"exposure": 1e-3}, "exposure", 1e-3),
        ({"heterodyne": -1.0}, "heterodyne", -1.0),
        ({"phase": 0.5}, "phase", 0.5),
    ],
)
def test_camera_parameters(params, field, expected):
    value = getattr(_camera(params), field)
    assert value == (pytest.approx(expected, rel=1e-12) if isinstance(expected, float) else expected)


@pytest.mark.parametrize(
    "params, expected",
    [
        ({"time_sampling_method": "stratified"}, dict(time_sampling="stratified", antithetic_shift=None, group_size=2)),
        ({"time_sampling_method": "antithetic_mirror"}, dict(time_sampling="antithetic_mirror", shift=0.0)),
        ({"time_sampling_method": "antithetic"}, dict(time_sampling="antithetic", shift=0.5)),
        ({"antithetic_shift": 0.25}, dict(antithetic_shift=0.25, shift=0.25)),
        ({"use_stratified_sampling_for_each_interval": False}, dict(stratify_intervals=False)),
        ({"path_correlation_depth": 0}, dict(correlation="none", correlation_depth=None)),
        ({"path_correlation_depth": 1}, dict(correlation="pixel", correlation_depth=None)),
        ({"path_correlation_depth": 2}, dict(correlation="replay", correlation_depth=2)),
        ({"path_correlation_depth": 16}, dict(correlation="replay", correlation_depth=16)),
        ({"correlation": "replay"}, dict(correlation="replay", correlation_depth=None)),
        ({"max_depth": 8, "rr_depth": 3, "hide_emitters": True}, dict(max_depth=8, rr_depth=3, hide_emitters=True)),
        ({"time_sampling": "uniform", "n_times": 1, "exposure_start": 0.5}, dict(time_sampling="uniform", n_times=1, exposure_start=0.5)),
        ({"m_reconnection_threshold": 0.2, "correlation": "adaptive"}, dict(reconnection_threshold=0.2, threshold=0.2)),  # M06's key (§8.1)
        ({"m_reconnection_threshold": 0.2}, dict(correlation="replay", reconnection_threshold=None)),  # travels with every mode; adaptive uses it
        ({"correlation": "adaptive", "reconnection_threshold": 1}, dict(correlation="adaptive", reconnection_threshold=1.0)),
        ({"is_doppler_integrator": True, "samples_per_pass": 4}, dict(time_sampling="antithetic")),  # accepted, no effect
    ],
)
def test_render_parameters(params, expected):
    """``expected`` names settings, or their resolved values (shift, group_size, threshold)."""
    s = render_settings(params)
    assert {k: getattr(s, k) for k in expected} == expected


@pytest.mark.parametrize(
    "params, message",
    [
        ({"m_reconnection_threshold": -0.1, "correlation": "adaptive"}, "'reconnection_threshold' must be >= 0.0, got -0.1"),
        ({"m_reconnection_threshold": 0.5, "reconnection_threshold": 0.5}, "give either 'reconnection_threshold' or 'm_reconnection_threshold'"),
        ({"reconnection_threshold": "rough"}, "'reconnection_threshold' must be a finite number"),
    ],
)
def test_bad_reconnection_threshold_is_a_clear_error(params, message):
    with pytest.raises(ValueError, match=f"^scene.xml: .*{message}"):
        render_settings(params, "scene.xml")


def test_another_integrators_block_gives_only_its_depths():
    assert integrator_layer({"type": "path", "max_depth": 3, "samples_per_pass": 2}) == {"max_depth": 3, "rr_depth": 5, "hide_emitters": False}
    with pytest.raises(ValueError, match="'max_depth' must be >= 1 or -1"):
        render_settings({"type": "path", "max_depth": 0})


def test_settings_are_accepted_by_render():
    """Every key the mapping returns is a keyword of dopplertof.render (checked cheaply:
    a bad spp fails after the keywords were bound)."""
    settings = integrator_layer({"path_correlation_depth": 3, "time_sampling_method": "stratified"})
    with pytest.raises(ValueError, match="spp"):
        dt.render(dt.DynamicScene(static=_grey_room(4)), spp=0, **settings)


# ----------------------------------------------------------------------------------------
# `dopplertof render` with an original-style scene file


def _small_original_cornell(data_dir, tmp_path, integrator_extra=""):
    text = (data_dir / "original_cornell.xml").read_text()
    text = text.replace('<default name="res" value="256"/>', '<default name="res" value="16"/>')
    text = text.replace('<integer name="max_depth" value="4"/>', '<integer name="max_depth" value="4"/>' + integrator_extra)
    path = tmp_path / "original.xml"
    path.write_text(text)
    return path


def _run_cli(args):
    result = CliRunner().invoke(cli.main, ["render", *map(str, args), "--quiet"])
    return result.exit_code, result.output


def test_cli_renders_an_original_scene_with_its_integrator_settings(data_dir, tmp_path):
    extra = (
        '<float name="hetero_offset" value="0.25"/><float name="antithetic_shift" value="0.25"/>'
        '<boolean name="use_stratified_sampling_for_each_interval" value="false"/>'
    )
    scene = _small_original_cornell(data_dir, tmp_path, extra)
    code, output = _run_cli([scene, "--spp", 4, "-o", tmp_path / "out"])
    assert code == 0, output
    meta = json.loads((tmp_path / "out" / "metadata.json").read_text())
    assert meta["spp"] == 4
    assert meta["settings"] == {
        **meta["settings"],
        **dict(max_depth=4, time_sampling="antithetic", antithetic_shift=0.25, stratify_intervals=False,
               correlation="replay", correlation_depth=4),
    }
    (camera,) = meta["cameras"]
    assert camera["exposure"] == 0.0015
    assert camera["modulation_frequency"] == 30e6 and camera["heterodyne"] == 1.0
    assert camera["phase"] == pytest.approx(math.pi / 2)
    assert os.path.exists(tmp_path / "out" / "measurement_0_h1_psi90deg.exr")


def test_cli_options_replace_the_files_settings(data_dir, tmp_path):
    scene = _small_original_cornell(data_dir, tmp_path)
    code, output = _run_cli([scene, "--spp", 2, "--max-depth", 2, "--correlation", "pixel",
                             "--time-sampling", "antithetic_mirror", "--exposure", 1e-3, "-o", tmp_path / "out"])
    assert code == 0, output
    meta = json.loads((tmp_path / "out" / "metadata.json").read_text())
    assert meta["settings"]["max_depth"] == 2
    assert meta["settings"]["correlation"] == "pixel"
    assert meta["settings"]["time_sampling"] == "antithetic_mirror"
    assert meta["cameras"][0]["exposure"] == 1e-3 and meta["cameras"][0]["heterodyne"] == 1.0


def test_cli_reports_a_bad_integrator_parameter_in_one_line(data_dir, tmp_path):
    scene = _small_original_cornell(data_dir, tmp_path, '<float name="w_gg" value="20"/>')
    code, output = _run_cli([scene, "--spp", 2, "-o", tmp_path / "out"])
    assert code == 2
    assert output.strip().splitlines() == [f"error: {scene}: <integrator>: unknown setting 'w_gg'; did you mean 'w_g'?"]


# ----------------------------------------------------------------------------------------
# mi.render through the plugin


def _grey_room(res, integrator=None, spp=64):
    """A static grey room lit by an area light behind the camera (box filter: a pixel is
    the average over its own area, as in dopplertof.render)."""
    scene = {
        "type": "scene",
        "sensor": perspective((0, 1, 4.0), (0, 1, 0), 30, res, sampler={"type": "independent", "sample_count": spp}),
        "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90), "bsdf": grey(0.7)},
        "back": {"type": "rectangle", "to_world": T().translate([0, 1, -1]), "bsdf": grey(0.8)},
        "left": {"type": "rectangle", "to_world": T().translate([-1, 1, 0]) @ T().rotate([0, 1, 0], 90), "bsdf": grey(0.4)},
        "box": {"type": "cube", "to_world": T().translate([0.2, 0.3, 0]) @ T().scale(0.3), "bsdf": grey(0.6)},
        "light": {
            "type": "rectangle",
            "to_world": T().translate([0.3, 1.3, 5.0]) @ T().rotate([0, 1, 0], 180),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [10.0] * 3}},
        },
    }
    if integrator is not None:
        scene["integrator"] = integrator
    return mi.load_dict(scene)


@pytest.mark.filterwarnings("ignore:Camera. modulation_frequency=1 Hz")  # f_g -> 0 on purpose: the DESIGN §3.7 limit
def test_mi_render_through_the_plugin_matches_stock_path():
    """h = 0, ψ = 0 and f_g → 0 (1 Hz): the measurement is (g1/2)× the intensity, path by
    path (DESIGN §3.7), and its mean is (g1/2)× stock `path`'s within noise."""
    g1, res, max_depth = 0.8, 16, 3
    integrator = {"type": "dopplertofpath", "w_g": 1e-6, "g_1": g1, "hetero_frequency": 0.0,
                  "time_sampling_method": "uniform", "max_depth": max_depth}
    img = np.array(mi.render(_grey_room(res, integrator, spp=64), seed=1), dtype=np.float64)  # spp from the sampler
    assert img.shape == (res, res, len(output_channels()))
    channels = output_channels()
    measurement, stderr = img[..., channels.index("measurement.R")], img[..., channels.index("measurement_stderr_0")]
    intensity = img[..., channels.index("intensity.R") : channels.index("intensity.B") + 1]
    np.testing.assert_array_equal(img[..., 1], measurement)
    np.testing.assert_allclose(measurement, 0.5 * g1 * intensity[..., 0], rtol=1e-5, atol=1e-9)

    stock = _grey_room(res, {"type": "moment", "nested": {"type": "path", "max_depth": max_depth}})
    spp_stock = 256
    ref = np.array(mi.render(stock, spp=spp_stock, seed=7), dtype=np.float64)
    ref_mean, ref_var = ref[..., 0], np.maximum(ref[..., 7] - ref[..., 4] ** 2, 0.0) / (spp_stock - 1)
    diff = measurement - 0.5 * g1 * ref_mean
    var = stderr**2 + (0.5 * g1) ** 2 * ref_var
    z = diff.sum() / math.sqrt(var.sum())
    ratio = (diff**2).sum() / var.sum()
    assert abs(z) < 3.5, z
    assert 0.5 < ratio < 1.5, ratio  # per-pixel differences are noise-sized
    assert 0.03 * measurement.sum() > 4 * math.sqrt(var.sum())  # power: a 3 % error would fail


def test_plugin_renders_only_the_first_sensor():
    scene = _grey_room(4)
    with pytest.raises(ValueError, match="first sensor only, got sensor 1"):
        render_image(render_settings({}), scene, sensor=1)


def test_output_channels_follow_the_active_variant(monkeypatch):
    """In a mono variant the film has one colour channel, and the names say so unasked."""
    import mitsuba as mi

    assert output_channels() == output_channels(mono=False)
    monkeypatch.setattr(mi, "is_rgb", False)
    assert output_channels() == output_channels(mono=True) and output_channels()[0] == "measurement.Y"
