"""The core rewrite (issue 8): one settings object, every scene feature honoured or refused,
optical lengths with η on every segment, the film's filter, calibrated standard errors and
ground truth independent of the pass split."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof import reconstruct as rc
from dopplertof.oracles import moving_plane_measurement_pixels, moving_plane_scene
from dopplertof.settings import RenderSettings, integrator_layer, scene_layer

DATA = os.path.join(os.path.dirname(__file__), "data")
ORIGINAL_CORNELL = os.path.join(DATA, "original_cornell.xml")
C = 299_792_458.0


# ------------------------------------------------------------------------------ settings


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(hide_emitters="no"), r"'hide_emitters' must be a boolean"),
        (dict(max_depth=2.5), r"'max_depth' must be an integer"),
        (dict(seed=1.7), r"'seed' must be an integer"),
        (dict(seed=2**32), r"'seed' must be < 2\*\*32"),
        (dict(rr_depth=-5), r"'rr_depth' must be >= 1"),
        (dict(spp=0), r"'spp' must be >= 1"),
        (dict(time_sampling="mirror"), r"unknown time_sampling 'mirror'"),
        (dict(correlation="none", correlation_depth=3), r"'correlation_depth' applies to replay"),
        (dict(correlation="replay", reconnection_threshold=0.3), r"'reconnection_threshold' applies to adaptive"),
        (dict(time_sampling="uniform", antithetic_shift=0.3), r"'antithetic_shift' applies to antithetic"),
        (dict(cameras=["h=1"]), r"'cameras' must be a list of dopplertof.Camera"),
    ],
)
def test_wrong_settings_are_errors_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RenderSettings(**kwargs)


def test_unknown_setting_is_named_with_a_suggestion():
    with pytest.raises(ValueError, match=r"unknown setting 'max_detph'; did you mean 'max_depth'"):
        RenderSettings.build({"max_detph": 3})


@pytest.mark.parametrize(
    "params, match",
    [
        ({"type": "dopplertof_path"}, r"unknown integrator type"),
        ({"type": "aov"}, r"computes something other than path-traced radiance"),
        ({"type": "path", "w_g": 30.0, "max_depth": 3}, r"does not take 'w_g'"),
        ({"type": "dopplertof", "hide_emitters": "yes"}, r"'hide_emitters' must be a boolean"),
        ({"type": "dopplertof", "max_depth": 2.5}, r"'max_depth' must be an integer"),
        ({"type": "dopplertof", "w_gg": 3.0}, r"unknown setting 'w_gg'; did you mean 'w_g'"),
    ],
)
def test_integrator_parameters_are_checked(params, match):
    with pytest.raises(ValueError, match=match):
        integrator_layer(params, "scene.xml")


def test_an_override_takes_its_dependent_settings_along():
    """The file asks for replay to depth 3; --correlation reconnection is reconnection."""
    layer = integrator_layer({"type": "dopplertofpath", "path_correlation_depth": 3, "time_sampling_method": "antithetic_mirror"})
    s = RenderSettings.build(layer, {"correlation": "reconnection", "time_sampling": "stratified"})
    assert s.correlation == "reconnection" and s.correlation_depth is None
    assert s.time_sampling == "stratified" and s.antithetic_shift is None


def test_render_uses_the_scenes_integrator():
    scene = dt.load_scene(ORIGINAL_CORNELL, film_resolution=8)
    expected = RenderSettings.build(scene_layer(scene))
    result = dt.render(scene, spp=2)
    assert result.settings.cameras == expected.cameras and len(expected.cameras) == 1
    assert result.settings.replace(spp=expected.spp) == expected


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.slow
@pytest.mark.parametrize("correlation", ["none", "pixel", "replay", "reconnection", "adaptive"])
def test_render_animate_and_plugin_build_the_same_settings(tmp_path, correlation):
    """One file, one --correlation: the CLI render, animate and the plugin agree."""
    common = ["--resolution", "4", "--spp", "2", "--correlation", correlation, "--quiet"]
    r = _cli("render", ORIGINAL_CORNELL, "-o", str(tmp_path / "r"), *common)
    assert r.returncode == 0, r.stderr
    a = _cli("animate", ORIGINAL_CORNELL, "-o", str(tmp_path / "a"), "--frames", "1", *common, *[f"--camera=h={h},psi={p}" for h in (0, 1) for p in ("0", "90deg")])
    assert a.returncode == 0, a.stderr
    rendered = json.loads((tmp_path / "r" / "metadata.json").read_text())["settings"]
    animated = json.loads((tmp_path / "a" / "frame_0000" / "metadata.json").read_text())["settings"]
    for key in set(rendered) - {"cameras", "seed", "exposure_start"}:
        assert rendered[key] == animated[key], key
    scene = dt.load_scene(ORIGINAL_CORNELL)
    plugin = mi.load_dict({**scene.integrator_params}).settings.replace(correlation=correlation, spp=2)
    for key in set(rendered) - {"cameras"}:
        assert rendered[key] == plugin.as_dict()[key], key
    assert rendered["cameras"] == plugin.as_dict()["cameras"]


def test_mi_render_of_a_dynamic_scene_names_dopplertof_render():
    scene = dt.scenes.build("cornell-box", resolution=4)
    with pytest.raises(TypeError, match=r"use dopplertof.render\(scene\)"):
        mi.render(scene)
    assert np.array(mi.render(scene.static, integrator=mi.load_dict({"type": "path"}), spp=1)).shape == (4, 4, 3)


# ------------------------------------------------------------------------------ refusals


def _room(**extra):
    scene = {
        "type": "scene",
        "sensor": {"type": "perspective", "fov": 40, "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": "box"}}},
        "light": {"type": "point", "position": [0, 0, 4], "intensity": {"type": "rgb", "value": 10.0}},
        "floor": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(3)},
    }
    scene.update(extra)
    return scene


def test_participating_media_are_refused():
    medium = {"type": "homogeneous", "albedo": 0.5, "sigma_t": 1.0}
    with pytest.raises(dt.SceneError, match="participating medium"):
        dt.load_scene(_room(fog={"type": "cube", "interior": medium, "bsdf": {"type": "null"}}))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_keyframes_are_refused(bad):
    end = np.eye(4)
    end[0, 3] = bad
    shape = {"type": "cube", "motion": {"type": "keyframes", "keys": [(0.0, np.eye(4)), (1e-3, end)]}}
    with pytest.raises(dt.SceneError, match="non-finite"):
        dt.load_scene(_room(box=shape))


def test_the_sensor_shutter_is_the_exposure_window():
    scene_dict = _room()
    scene_dict["sensor"] = {**scene_dict["sensor"], "shutter_open": 0.25, "shutter_close": 0.2515}
    scene = dt.load_scene({**scene_dict, "integrator": {"type": "dopplertof", "hetero_frequency": 1.0}})
    s = RenderSettings.build(scene_layer(scene))
    assert s.exposure_start == 0.25 and s.cameras[0].exposure == pytest.approx(1.5e-3, rel=1e-5)  # float32 shutter
    contradicting = dt.load_scene({**scene_dict, "integrator": {"type": "dopplertof", "time": 1e-3}})
    with pytest.raises(ValueError, match="shutter is open for .* but the <integrator> exposure"):
        scene_layer(contradicting)


def test_shutter_times_read_as_written_and_callers_cameras_win():
    """Issue 16.1: Mitsuba keeps a shutter of 0.0015 s as float32 (0.001500000013); the
    scene's T is read as written, and a caller's cameras (any T) override the shutter's T
    as any caller setting overrides the scene's."""
    scene_dict = _room()
    scene_dict["sensor"] = {**scene_dict["sensor"], "shutter_open": 0.0, "shutter_close": 0.0015}
    scene = dt.load_scene(scene_dict)
    assert scene_layer(scene) == {"exposure": 0.0015, "exposure_start": 0.0}
    for exposure in (1.5e-3, 1e-3):
        camera = dt.Camera(heterodyne=1.0, exposure=exposure)
        s = RenderSettings.build(scene_layer(scene), {"cameras": [camera]})
        assert s.cameras == (camera,) and s.exposure is None and s.exposure_start == 0.0
    # Within one layer a contradiction is still the caller's mistake.
    with pytest.raises(ValueError, match="exposure=0.002 s differs from the cameras' exposure"):
        RenderSettings.build(scene_layer(scene), {"cameras": [dt.Camera()], "exposure": 2e-3})


# ------------------------------------------------------------------------------ optical length through glass

GLASS_F_HZ = 10e6  # ambiguity c/f = 30 m: one wrap covers the scenes below


def _homodyne_length(result):
    """Optical length (m) of the central pixels from homodyne measurements at ψ = 0, 90°."""
    m = result.measurements[:, 3:5, 3:5].mean(axis=(1, 2))
    k = 2 * math.pi * GLASS_F_HZ / C
    return (math.atan2(-m[1], m[0]) % (2 * math.pi)) / k


def _glass_scene(bsdf, light_inside_sphere=False):
    """Camera at the origin looking down +z. Either a 1 m slab (z 2..3) in front of an area
    light at z = 5 (optical length 2 + 1.5 + 2 = 5.5 m through smooth glass), or a point
    light at the centre of a glass sphere (r 0.5 m, centre z = 3) seen directly: 2.5 m of
    air to the surface and 0.5 m of glass to the light (2.5 + 0.75 = 3.25 m)."""
    scene = {
        "type": "scene",
        "sensor": {"type": "perspective", "fov": 2, "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": "box"}}},
        "integrator": {"type": "dopplertof", "max_depth": 3 if not light_inside_sphere else 2},
    }
    if light_inside_sphere:
        scene["ball"] = {"type": "sphere", "center": [0, 0, 3], "radius": 0.5, "bsdf": bsdf}
        scene["light"] = {"type": "point", "position": [0, 0, 3], "intensity": {"type": "rgb", "value": 10.0}}
    else:
        scene["slab"] = {"type": "cube", "to_world": mi.ScalarTransform4f().translate([0, 0, 2.5]).scale([3, 3, 0.5]), "bsdf": bsdf}
        scene["light"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, 5]).rotate([1, 0, 0], 180).scale(4),
                          "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}}}
    return dt.load_scene(scene)


ALL_MODES = [(t, c) for t in ("uniform", "stratified", "antithetic", "antithetic_mirror") for c in ("none", "pixel", "replay", "reconnection", "adaptive")]
ALL_MODES += [("analytic", c) for c in ("replay", "reconnection", "adaptive")]
HOMODYNE = [dt.Camera(modulation_frequency=GLASS_F_HZ, heterodyne=0.0, phase=p) for p in (0.0, math.pi / 2)]


@pytest.mark.slow
def test_every_mode_reads_the_optical_length_through_a_glass_slab():
    scene = _glass_scene({"type": "dielectric", "int_ior": 1.5})
    for time_sampling, correlation in ALL_MODES:
        result = dt.render(scene, HOMODYNE, spp=16, time_sampling=time_sampling, correlation=correlation)
        assert _homodyne_length(result) == pytest.approx(5.5, abs=2e-3), (time_sampling, correlation)


@pytest.mark.slow
def test_every_mode_agrees_through_rough_glass():
    scene = _glass_scene({"type": "roughdielectric", "int_ior": 1.5, "alpha": 0.2})
    reference = _homodyne_length(dt.render(scene, HOMODYNE, spp=1024, seed=99))
    assert 5.5 < reference < 5.6  # through the glass, a little longer off-axis
    for time_sampling, correlation in ALL_MODES:
        if time_sampling == "analytic":
            continue  # biased by design where paths are not linear in time; static here, but rough paths differ
        result = dt.render(scene, HOMODYNE, spp=256, time_sampling=time_sampling, correlation=correlation)
        assert _homodyne_length(result) == pytest.approx(reference, abs=0.01), (time_sampling, correlation)


def test_a_light_inside_glass_counts_the_glass_on_its_segment():
    scene = _glass_scene({"type": "roughdielectric", "int_ior": 1.5, "alpha": 0.1}, light_inside_sphere=True)
    for correlation in ("replay", "reconnection"):
        length = _homodyne_length(dt.render(scene, HOMODYNE, spp=64, correlation=correlation))
        assert length == pytest.approx(3.25, abs=2e-3), correlation


# ------------------------------------------------------------------------------ the film's filter


def _stock_mean_and_variance(scene_dict, spp, runs):
    """Per-pixel mean of ``runs`` stock renders and the variance of that mean."""
    images = np.stack([np.array(mi.render(mi.load_dict(scene_dict), spp=spp, seed=1000 + i), dtype=np.float64)[..., :3] for i in range(runs)])
    return images.mean(axis=0), images.var(axis=0, ddof=1) / runs


def _scene_with_filter(rfilter):
    scene = mi.cornell_box()
    scene["sensor"]["film"].update(width=48, height=48)
    if rfilter is not None:
        scene["sensor"]["film"]["rfilter"] = rfilter
    return scene


@pytest.mark.slow
@pytest.mark.parametrize("rfilter", [None, {"type": "tent"}, {"type": "box"}], ids=["default-gaussian", "tent", "box"])
def test_any_filter_matches_stock_path_per_pixel(rfilter):
    scene_dict = _scene_with_filter(rfilter)
    stock, stock_var = _stock_mean_and_variance(scene_dict, spp=64, runs=8)
    ours = dt.render(dt.load_scene(scene_dict), spp=512, seed=3, time_sampling="uniform", correlation="none")
    # Per pixel, the difference against stock is noise of the predicted size. (The image-wide
    # ratio MSE / predicted is dominated by a few heavy-tailed pixels next to the light: it
    # ranged 0.54 to 1.27 between runs of one configuration, so it cannot tell 10 % apart.)
    z = (ours.intensity - stock) / np.sqrt(ours.stderr.astype(np.float64) ** 2 + stock_var)
    assert 0.9 < np.std(z) < 1.12
    assert abs(np.mean(z)) < 0.05


@pytest.mark.parametrize("sample_border", [False, True])
def test_a_film_that_samples_its_border_matches_stock_path_per_pixel(sample_border):
    """``sample_border``: stock Mitsuba also draws samples past the film's edges, so an edge
    pixel averages the image beyond them (here a light just above the film: its top row is
    lit with the border, black without); it was ignored (the row came out black)."""
    T = mi.ScalarTransform4f
    scene_dict = {
        "type": "scene", "integrator": {"type": "path", "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 30, "to_world": T().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 12, "height": 12, "sample_border": sample_border, "rfilter": {"type": "gaussian"}}},
        "light": {"type": "rectangle", "to_world": T().translate([0.3, 1.6, 0]).scale(0.5), "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1, 1, 1]}}},
    }  # fmt: skip
    stock, stock_var = _stock_mean_and_variance(scene_dict, spp=1024, runs=8)
    ours = dt.render(dt.load_scene(scene_dict), spp=4096, seed=3, time_sampling="uniform", correlation="none", progress=False)
    variance = (ours.stderr.astype(np.float64) ** 2 + stock_var)[..., 0]
    noisy = variance > 0
    if not sample_border:
        assert not noisy.any() and stock.max() == 0 and ours.intensity.max() == 0
        return
    difference = ours.intensity[..., 0] - stock[..., 0]
    bright = stock[..., 0] > 0.01  # the top row under the light (the second row's light is rare paths: summed)
    z = np.concatenate([difference[bright] / np.sqrt(variance[bright]), difference[:2].sum(axis=1) / np.sqrt(variance[:2].sum(axis=1))])
    assert bright.sum() >= 6 and np.abs(z).max() < 4.5, np.round(z, 1)


def test_a_textured_area_light_matches_stock_path():
    """An area emitter with a texture for its radiance failed to load (the emitter check
    read the texture's ``to_uv`` transform as numbers)."""
    T = mi.ScalarTransform4f
    scene_dict = {
        "type": "scene", "integrator": {"type": "path", "max_depth": 3},
        "sensor": {"type": "perspective", "fov": 45, "to_world": T().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 12, "height": 12, "rfilter": {"type": "box"}}},
        "floor": {"type": "rectangle", "to_world": T().scale(2), "bsdf": {"type": "diffuse"}},
        "light": {"type": "rectangle", "to_world": T().translate([0.6, 0, 1]).rotate([1, 0, 0], 180).scale(0.5),
                  "emitter": {"type": "area", "radiance": {"type": "checkerboard", "color0": 0.2, "color1": 3.0}}},
    }  # fmt: skip
    stock, stock_var = _stock_mean_and_variance(scene_dict, spp=256, runs=8)
    ours = dt.render(dt.load_scene(scene_dict), spp=1024, seed=3, time_sampling="uniform", correlation="none", progress=False)
    variance = (ours.stderr.astype(np.float64) ** 2 + stock_var)[..., 0]
    assert (variance > 0).sum() > 100
    z = (ours.intensity[..., 0] - stock[..., 0]).sum() / np.sqrt(variance.sum())  # the image's sum
    assert abs(z) < 4, z


@pytest.mark.parametrize("name", ["mitchell", "catmullrom", "lanczos"])
def test_filters_with_negative_lobes_are_refused(name):
    with pytest.raises(dt.SceneError, match="has negative lobes"):
        dt.load_scene(_scene_with_filter({"type": name}))


# ------------------------------------------------------------------------------ calibrated standard errors


@pytest.mark.parametrize("n_groups, wraps", [(34, (0.5,)), (33, (0.5,)), (100, (0.3,)), (12, (1 / 3, 2 / 3)), (7, ()), (2, (0.5,)), (1, ())])
def test_strata_tile_the_interval_and_any_range_of_groups_finds_its_own(n_groups, wraps):
    from dopplertof.tracing.lanes import StrataLayout

    layout = StrataLayout(n_groups, wraps)
    units = layout.units(0, n_groups)
    assert [u[0] for u in units] == list(np.cumsum([0] + [u[1] for u in units[:-1]]))  # contiguous in group order
    places = sorted((place, n) for _, n, place, _, _ in units)
    assert [p for p, _ in places] == list(np.cumsum([0] + [n for _, n in places[:-1]])) and sum(n for _, n in places) == n_groups
    assert {n for _, n in places} <= ({1} if n_groups == 1 else {2, 3})
    cuts = [round(w * n_groups) for w in wraps if float(w * n_groups).is_integer() and n_groups > 2]
    assert all(any(p == c for p, _ in places) for c in cuts)  # a stratum starts at every cut
    for g0 in range(n_groups):
        for g1 in range(g0 + 1, n_groups + 1):
            assert layout.units(g0, g1) == [u for u in units if u[0] + u[1] > g0 and u[0] < g1], (g0, g1)


def test_each_pixels_times_fill_its_strata_and_the_rotation_varies():
    """Antithetic pairs, 68 spp: 34 groups in two pieces of 17 (7 pairs and a stratum of
    three each); per pixel, each stratum holds as many primal times as it has groups."""
    from dopplertof.tracing import lanes

    dt.scenes.build("cornell-box", resolution=4)  # sets the variant
    spp, pixels = 68, 500
    settings = RenderSettings(spp=spp)
    setup = lanes.LaneSetup(width=pixels, height=1, pixel_start=0, n_pixels=pixels, first_sample=0, samples=spp, spp_total=spp,
                            n_times=2, exposure_start_s=0.0, exposure_s=1.0, seed=0)  # fmt: skip
    pixel, index = lanes.pixel_and_index(setup, spp)
    group, member = index // 2, index % 2
    seed = mi.UInt32(0)
    r_shared = lanes.seeded_pcg(seed, lanes.STREAM_SHARED, pixel, group).next_float32()
    r_own = lanes.seeded_pcg(seed, lanes.STREAM_OWN, pixel, index).next_float32()
    u = np.array(lanes.sample_time(setup, settings, seed, pixel, group, member, r_shared, r_own)).reshape(pixels, 34, 2)
    assert np.allclose(u[:, :, 1], (u[:, :, 0] + 0.5) % 1.0, atol=1e-6)
    edges = np.array([0, 2, 4, 6, 8, 10, 12, 14, 17, 19, 21, 23, 25, 27, 29, 31, 34]) / 34
    counts = np.stack([np.histogram(row, bins=edges)[0] for row in u[:, :, 0]])
    np.testing.assert_array_equal(counts, np.broadcast_to(np.diff(edges * 34), counts.shape))
    first = np.floor(u[:, 0, 0] * 34)  # the place of group 0's stratum: rotated per pixel over the 7 pairs of its piece
    assert len(set(first // 2)) == 7


@pytest.mark.slow
@pytest.mark.parametrize(
    "time_sampling, spp, extra",
    [
        ("antithetic", 128, {}),
        ("uniform", 128, {}),
        ("stratified", 128, {}),
        ("antithetic_mirror", 128, {}),
        ("antithetic", 68, {}),  # 34 groups cut at ½ into two pieces of 17: strata of three, passes that close no pair
        ("stratified", 66, {}),  # 33 groups: a stratum of three
        ("stratified", 128, {"stratify_intervals": False}),  # independent groups: replicates
    ],
)  # fmt: skip
def test_measurement_stderr_is_calibrated(time_sampling, spp, extra):
    """z-scores of pixels against the exact moving-plane values have unit spread, at h = 1
    and h = 0. Stratified times take their errors from the differences within strata of two
    (or three) groups, about 32-64 degrees of freedom. Measured over seeds 11-18: spread
    0.94-1.17 in every case (576 pixels: the spread's own noise is about 0.03). Spreads
    these bounds reject: 5.3 (stratified) where one stratum straddled the heterodyne
    weight's jump at the exposure's end (a continuous rotation of the strata), 1.8
    (antithetic, 68 spp) where the antithetic wrap at ½ fell inside a stratum, 0.07 where
    replicates were interleaved over one stratification (the between-strata spread counted)."""
    speed = 10.0
    cameras = [dt.Camera(heterodyne=1.0), dt.Camera(heterodyne=0.0, phase=math.pi / 2)]
    result = dt.render(moving_plane_scene(speed, resolution=24), cameras, spp=spp, max_depth=2, seed=11, time_sampling=time_sampling, **extra)
    for i, camera in enumerate(cameras):
        exact = moving_plane_measurement_pixels(camera, speed, 24, nodes_per_pixel=4, time_panels=16)
        z = (result.measurements[i] - exact) / result.measurement_stderr[i]
        assert 0.88 <= np.std(z) <= 1.22, (time_sampling, spp, i, np.std(z))
        assert abs(np.mean(z)) < 4 / math.sqrt(z.size) * np.std(z) + 0.1


@pytest.mark.slow
def test_a_plain_render_keeps_the_papers_orderings_at_h_1():
    """``dt.render`` at 64 spp with nothing but the time sampling changed, RMSE of the
    measurements of 4 phases at h = 1 on the 16² Cornell box against a 4096-spp reference.
    Measured over seeds 0-5 (mean ± std of the ratio to uniform): stratified 0.254 ± 0.012,
    mirror 0.344 ± 0.019, antithetic 0.036 ± 0.003 (the paper: 0.38, 0.50, 0.038). Each
    bound is at least 5 standard deviations from its mean. With each interval stratified
    within 16 replicates per pixel (2 strata each) they were 0.48 ± 0.03 and 0.98 ± 0.07."""
    scene = dt.scenes.build("cornell-box", resolution=16)
    cameras = [dt.Camera(heterodyne=1.0, phase=k * math.pi / 2) for k in range(4)]
    reference = dt.render(scene, cameras, spp=4096, seed=1000).measurements
    rmse = {}
    for time_sampling in ("uniform", "stratified", "antithetic_mirror", "antithetic"):
        result = dt.render(scene, cameras, spp=64, seed=0, time_sampling=time_sampling)
        rmse[time_sampling] = float(np.sqrt(np.mean((result.measurements - reference) ** 2)))
    assert rmse["stratified"] < 0.32 * rmse["uniform"], rmse
    assert rmse["antithetic_mirror"] < 0.44 * rmse["uniform"], rmse
    assert rmse["antithetic"] < 0.3 * rmse["stratified"], rmse


def test_velocity_stderr_is_propagated_and_calibrated():
    """Direct light, a receding plane: reconstructed velocity against the truth, z spread ≈ 1."""
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    # 64 spp: 16 strata of two groups, 16 degrees of freedom (at 32 spp, 8, the z of a ratio of
    # measurements spreads 1.05-1.40 over seeds 5-10; at 64 spp 1.05-1.21)
    result = dt.render(moving_plane_scene(40.0, resolution=16), cameras, spp=64, max_depth=2, seed=5)
    # the z spread over every pixel: a threshold far above the errors
    v = rc.velocity(result, max_velocity_stderr=1e3)
    assert v.velocity_stderr is not None and v.valid.mean() > 0.9
    z = ((v.velocity - result.velocity) / v.velocity_stderr)[v.valid]
    assert 0.75 <= np.std(z) <= 1.3
    independent = rc.velocity(result.measurements, cameras, measurement_stderr=result.measurement_stderr, max_velocity_stderr=1e3)
    assert not np.allclose(independent.velocity_stderr[v.valid], v.velocity_stderr[v.valid])  # the covariance matters


def test_ground_truth_and_images_do_not_depend_on_the_pass_split():
    scene = dt.scenes.build("cornell-box", resolution=16)
    cams = [dt.Camera(heterodyne=1.0)]
    whole = dt.render(scene, cams, spp=8, seed=2)
    split = dt.render(scene, cams, spp=8, seed=2, lanes_per_pass=1024)  # tiles of 128 pixels x 8 spp
    thin = dt.render(scene, cams, spp=8, seed=2, lanes_per_pass=2048 + 512)  # 2 samples x all pixels... and tiles
    for other in (split, thin):
        for name in ("depth", "velocity", "point_velocity", "velocity_3d", "flow", "coverage", "instance_id", "intensity", "measurements"):
            np.testing.assert_array_equal(getattr(whole, name), getattr(other, name), err_msg=name)


@pytest.mark.parametrize("spp", [8, 12])  # pairs (device vs host); pieces of 3 groups (strata of three, carried across passes)
def test_standard_errors_do_not_depend_on_the_pass_split(spp):
    """Strata reduced on the device where a pass holds whole pairs, on the host where passes
    split them (one group per pass here): the same errors and covariance, to rounding."""
    scene = dt.scenes.build("cornell-box", resolution=32)
    cams = [dt.Camera(heterodyne=1.0), dt.Camera(heterodyne=0.0, phase=math.pi / 2)]
    whole = dt.render(scene, cams, spp=spp, seed=2)
    split = dt.render(scene, cams, spp=spp, seed=2, lanes_per_pass=2048)  # 1024 pixels x one group
    np.testing.assert_array_equal(whole.measurements, split.measurements)
    for name in ("stderr", "measurement_stderr", "measurement_covariance"):
        a, b = getattr(whole, name), getattr(split, name)
        assert np.isfinite(a).mean() > 0.5, name
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-12 * np.nanmax(np.abs(a)), err_msg=name)


@pytest.mark.parametrize("origin, target", [((0, 0, 0), (0, 0, -1)), ((0.3, 1.1, 5.0), (0.0, 0.2, 0.0)), ((-4.0, 2.0, 7.0), (1.0, -1.0, 3.0))])
def test_optical_flow_does_not_depend_on_where_the_camera_stands_or_looks(origin, target):
    """The receding plane placed in the camera's frame, wherever the camera is: the same
    flow (a camera away from the axes had NaN flow: float32 rounding of its film
    positions failed pinhole_scales' test of a separable projection)."""
    speed, n = 10.0, 16
    T = mi.ScalarTransform4f
    camera = T().look_at(origin=list(origin), target=list(target), up=[0, 1, 0])
    d = {
        "type": "scene",
        "sensor": {"type": "perspective", "fov": 40, "to_world": camera,
                   "film": {"type": "hdrfilm", "width": n, "height": n, "rfilter": {"type": "box"}}},
        "light": {"type": "point", "position": list(origin), "intensity": {"type": "rgb", "value": 10.0}},
        "plane": {"type": "rectangle", "to_world": camera @ T().translate([0, 0, 5]) @ T().rotate([0, 1, 0], 180) @ T().scale(20),
                  "motion": {"type": "parametric", "linear_velocity": list(camera @ mi.ScalarVector3f(0, 0, speed))}},
    }  # fmt: skip
    flow = dt.render(dt.load_scene(d), spp=128, max_depth=2, exposure=1.5e-3).flow
    centre = (np.arange(n) + 0.5) - n / 2
    z = 5.0 + speed * 0.75e-3
    tolerance = 0.02 * speed / z * n / 2
    np.testing.assert_allclose(flow[..., 0], np.broadcast_to(-centre[None, :] * speed / z, (n, n)), atol=tolerance)
    np.testing.assert_allclose(flow[..., 1], np.broadcast_to(-centre[:, None] * speed / z, (n, n)), atol=tolerance)


def test_optical_flow_of_a_receding_plane():
    """A plane receding along the optical axis at s shrinks the image towards its centre:
    d/dt (a x/z) = −(u − u_c) s / z pixels per second (u_c the film centre)."""
    speed, n = 10.0, 16
    result = dt.render(moving_plane_scene(speed, resolution=n), spp=128, max_depth=2)  # sample positions within a pixel: ±0.05 px/s
    centre = (np.arange(n) + 0.5) - n / 2
    z = 5.0 + speed * 0.75e-3  # mid-exposure distance along the axis, m
    expected_u = -centre[None, :] * speed / z
    expected_v = -centre[:, None] * speed / z
    np.testing.assert_allclose(result.flow[..., 0], np.broadcast_to(expected_u, (n, n)), atol=0.02 * speed / z * n / 2)
    np.testing.assert_allclose(result.flow[..., 1], np.broadcast_to(expected_v, (n, n)), atol=0.02 * speed / z * n / 2)
