"""Scenarios a user starts from, end to end (issue 16): each scene rendered with the four
cameras h ∈ {0, 1} × ψ ∈ {0°, 90°}, through the command line (a real subprocess:
``render`` then ``reconstruct``) and through the API (``dt.render`` then
``dt.reconstruct.velocity``).

The scenes: a Mitsuba 3 XML file written by hand from the README's "Scene format" section
(a sensor with a shutter, cubes with ``<animation>``, no ``<integrator>``), the original
authors' Mitsuba 3 file and a Mitsuba 0.6 file (``tests/data``), ``mi.cornell_box()`` as a
dict with its default (Gaussian) filter, a shutter and a moving box (API only: the command
line takes files and built-in names), and every built-in scene (its exposure in the middle
of its clip, where things move). 32² pixels, 8 spp.

Every output is finite (ground truth where a surface was hit), the files are those the
README lists, and the reconstruction runs. Where the light sits at the camera and a body
moves fast enough for 8 spp (:attr:`Scenario.check_sign`), the reconstructed velocity has
the ground truth's sign on the brightest quarter of the moving pixels; elsewhere (an area
light changes the optical length by the light's segment too, slow or small bodies are
noise at 8 spp) only that the reconstruction runs.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof import io, scenes

DATA = Path(__file__).parent / "data"
RESOLUTION = 32
SPP = 64  # the fewest (antithetic times: spp/4 degrees of freedom) with which a reconstructed pixel may be valid
CAMERA_SPECS = ("h=0,psi=0", "h=0,psi=90deg", "h=1,psi=0", "h=1,psi=90deg")
CAMERAS = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
MEASUREMENT_FILES = [f"measurement_{i}_h{h}_psi{deg}deg" for i, (h, deg) in enumerate([(0, 0), (0, 90), (1, 0), (1, 90)])]
RENDER_FILES = [
    "metadata.json", "intensity.exr", "stderr.exr", "depth.exr", "velocity.exr", "point_velocity.exr", "velocity_3d.exr",
    "flow.exr", "coverage.exr", "instance_id.exr", "measurement_covariance.npy",
    *(f"{m}.exr" for m in MEASUREMENT_FILES), *(f"{m}_stderr.exr" for m in MEASUREMENT_FILES),
]  # fmt: skip
RECONSTRUCT_FILES = ["velocity_reconstructed.exr", "velocity_reconstructed.png", "velocity_valid.png", "velocity_comparison.png", "velocity_error.json"]
MOVING_M_S = 0.5  # |ground-truth velocity| above which a pixel counts as moving
MIN_SIGN_PIXELS = 10  # the sign check needs at least this many bright moving pixels


@dataclass(frozen=True)
class Scenario:
    name: str
    scene: str | None  # the command line's SCENE (a file or built-in name); None: API only
    cli_options: tuple = ()
    exposure_start: float = 0.0  # s: the API's (the command line's is in cli_options)
    check_sign: bool = False

    def load(self):
        if self.scene in scenes.SCENES:
            return scenes.build(self.scene, resolution=RESOLUTION)
        if self.scene is None:
            return dt.load_scene(_mitsuba_cornell_box())
        return dt.load_scene(self.scene, film_resolution=RESOLUTION)


def _mid_clip(name: str) -> float:
    """Exposure start (s) that centres the default 1.5 ms exposure in the scene's clip."""
    return max(0.0, 0.5 * scenes.clip_duration(name) - 0.5 * CAMERAS[0].exposure)


def _mitsuba_cornell_box() -> dict:
    """``mi.cornell_box()`` as it comes (Gaussian filter, ceiling area light), small, with a
    shutter [0, 1.5 ms] and the small box approaching the camera at 10 m/s."""
    scene = mi.cornell_box()
    scene["sensor"] = {**scene["sensor"], "shutter_open": 0.0, "shutter_close": 0.0015}
    scene["sensor"]["film"] = {**scene["sensor"]["film"], "width": RESOLUTION, "height": RESOLUTION}
    scene["small-box"] = {**scene["small-box"], "motion": {"type": "parametric", "linear_velocity": [0.0, 0.0, 10.0]}}
    return scene


def _scenarios() -> list[Scenario]:
    files = [
        Scenario("readme-xml", str(DATA / "readme_scene.xml"), check_sign=True),
        Scenario("original-mitsuba3", str(DATA / "original_cornell.xml"), check_sign=True),
        Scenario("mitsuba-0.6", str(DATA / "legacy" / "cornell_0_6.xml"), check_sign=True),
        Scenario("mi.cornell_box-dict", None),
    ]
    builtins = [
        Scenario(name, name, ("--exposure-start", repr(_mid_clip(name))), _mid_clip(name), check_sign=name == "cornell-box")
        for name in scenes.SCENES
    ]  # fmt: skip
    return files + builtins


SCENARIOS = _scenarios()


def _check_sign(name, reconstructed, truth, intensity, valid):
    """The reconstructed velocity has the ground truth's sign on ≥ 90 % of the brightest
    quarter of the moving pixels where the reconstruction is valid."""
    moving = valid & np.isfinite(truth) & (np.abs(np.nan_to_num(truth)) > MOVING_M_S)
    count = int(moving.sum())
    assert count >= MIN_SIGN_PIXELS, f"{name}: only {count} valid moving pixels"
    brightest = np.argsort(np.where(moving, intensity, -np.inf), axis=None)[::-1][: max(MIN_SIGN_PIXELS, count // 4)]
    agree = np.mean(np.sign(reconstructed.flat[brightest]) == np.sign(truth.flat[brightest]))
    assert agree >= 0.9, f"{name}: the reconstructed sign agrees with the ground truth on {agree:.0%} of the brightest moving pixels"


def _check_finite(name, outputs: dict, coverage):
    hit = coverage > 0
    for key, value in outputs.items():
        if key in ("depth", "velocity", "point_velocity", "velocity_3d", "flow"):  # ground truth: none without a hit
            value = value[hit]
        assert np.isfinite(value).all(), f"{name}: {key} is not finite"


# ------------------------------------------------------------------------------ command line


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("scenario", [s for s in SCENARIOS if s.scene is not None], ids=lambda s: s.name)
def test_cli(scenario, tmp_path):
    out = tmp_path / "out"
    cameras = [a for spec in CAMERA_SPECS for a in ("--camera", spec)]
    render = _cli("render", scenario.scene, "--resolution", str(RESOLUTION), "--spp", str(SPP), *cameras, *scenario.cli_options, "-o", str(out), "--quiet")
    assert render.returncode == 0, render.stderr
    assert render.stderr == ""
    reconstruct = _cli("reconstruct", str(out))
    assert reconstruct.returncode == 0, reconstruct.stderr

    missing = [f for f in RENDER_FILES + RECONSTRUCT_FILES if not (out / f).is_file()]
    assert missing == []
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["spp"] == SPP and metadata["film"] == [RESOLUTION, RESOLUTION]
    assert metadata["versions"]["dopplertof"] == dt.__version__
    assert [(c["heterodyne"], c["phase"]) for c in metadata["cameras"]] == [(c.heterodyne, c.phase) for c in CAMERAS]
    assert all(c["exposure"] == CAMERAS[0].exposure for c in metadata["cameras"])  # the caller's T, whatever the scene's shutter

    read = {name: io.read_exr(out / f"{name}.exr") for name in ("intensity", "stderr", "depth", "velocity", "point_velocity", "velocity_3d", "flow", "coverage")}
    read["measurements"] = np.stack([io.read_exr(out / f"{m}.exr") for m in MEASUREMENT_FILES])
    read["measurement_stderr"] = np.stack([io.read_exr(out / f"{m}_stderr.exr") for m in MEASUREMENT_FILES])
    coverage = read["coverage"].squeeze()
    _check_finite(scenario.name, read, coverage)
    errors = json.loads((out / "velocity_error.json").read_text())
    assert 0.0 < errors["valid_fraction"] <= 1.0 and math.isfinite(errors["rmse_m_s"])
    if scenario.check_sign:
        reconstructed = io.read_exr(out / "velocity_reconstructed.exr").squeeze()
        valid = np.isfinite(reconstructed)
        _check_sign(scenario.name, reconstructed, read["velocity"].squeeze(), read["intensity"].mean(-1), valid)


# ------------------------------------------------------------------------------ API


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_api(scenario):
    scene = scenario.load()
    result = dt.render(scene, cameras=CAMERAS, spp=SPP, exposure_start=scenario.exposure_start)
    assert result.spp == SPP and result.measurements.shape == (4, RESOLUTION, RESOLUTION)
    assert result.settings.cameras == tuple(CAMERAS)
    outputs = {k: getattr(result, k) for k in ("measurements", "measurement_stderr", "measurement_covariance", "intensity", "stderr", "depth", "velocity", "point_velocity", "velocity_3d", "flow", "instance_id")}
    _check_finite(scenario.name, outputs, result.coverage)

    velocity = dt.reconstruct.velocity(result)
    assert velocity.velocity.shape == (RESOLUTION, RESOLUTION) and velocity.valid.any()
    assert np.isfinite(velocity.velocity[velocity.valid]).all()
    if scenario.scene is None:  # the dict's moving box: it is there, and it moves
        assert np.abs(np.nan_to_num(result.velocity)).max() > MOVING_M_S
    if scenario.check_sign:
        _check_sign(scenario.name, velocity.velocity, result.velocity, result.intensity.mean(-1), velocity.valid)


# ------------------------------------------------------------------------------ a sensor's shutter (issue 16.1)


@pytest.fixture(scope="module")
def one_ms_shutter(tmp_path_factory):
    """The README scene with its shutter open for 1 ms (not the cameras' default T)."""
    text = (DATA / "readme_scene.xml").read_text()
    shutter = '<float name="shutter_close" value="0.0015"/>'
    assert text.count(shutter) == 1
    path = tmp_path_factory.mktemp("shutter") / "one_ms.xml"
    path.write_text(text.replace(shutter, '<float name="shutter_close" value="0.001"/>'))
    # beside it, the shutter open from 1 to 2 ms
    opening = '<float name="shutter_open" value="0"/>'
    assert text.count(opening) == 1
    (path.parent / "late.xml").write_text(text.replace(shutter, '<float name="shutter_close" value="0.002"/>').replace(opening, '<float name="shutter_open" value="0.001"/>'))
    return path


@pytest.mark.parametrize(
    "command, exposure_s",
    [
        (["render", "--camera", "h=1,psi=0,T=0.0015"], 1.5e-3),  # the caller's T wins over the shutter's
        (["render", "--camera", "h=1,psi=0"], 1e-3),  # a camera without T: the shutter's T
        (["render", "--camera", "h=1,psi=0", "--exposure", "0.002"], 2e-3),
        (["render"], 1e-3),  # no camera: the shutter's T
        (["animate", "--frames", "1"], 1e-3),  # the default cameras take the shutter's T
        (["experiment", "time-sampling", "--quick"], 1e-3),
        (["experiment", "shifts", "--quick"], 1e-3),
        (["experiment", "velocity", "--quick"], 1e-3),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) else None,
)
def test_commands_take_a_scene_with_a_shutter(one_ms_shutter, tmp_path, command, exposure_s):
    out = tmp_path / "out"
    name, *options = command
    head = [name, options.pop(0)] if name == "experiment" else [name]
    extra = ["--cache", str(tmp_path / "cache")] if name == "experiment" else ["--spp", "4", "--quiet"]
    run = _cli(*head, str(one_ms_shutter), *options, *extra, "-o", str(out))
    assert run.returncode == 0, run.stderr
    metadata = json.loads((out / ("frame_0000" if name == "animate" else ".") / "metadata.json").read_text())
    if name == "render" and "--camera" not in options:
        assert metadata["cameras"] == [] and metadata["settings"]["exposure"] == exposure_s
    else:
        cameras = metadata["cameras"] if "cameras" in metadata else [metadata["base_camera"]]  # the sweeps record their grid's base
        assert cameras and {c["exposure"] for c in cameras} == {exposure_s}


def test_an_api_camera_exposing_past_the_files_shutter_warns(one_ms_shutter):
    """A dt.Camera's own T (default 1.5 ms) wins over a 1 ms shutter, where the command
    line's --camera without T takes the shutter's: it rendered past shutter_close silently."""
    scene = dt.load_scene(one_ms_shutter)
    with pytest.warns(UserWarning, match=r"the cameras expose 0 to 0\.0015 s: they close after the scene's shutter \(0 to 0\.001 s\); to expose for the shutter give exposure_start=0 and exposure=0\.001"):
        dt.render(scene, cameras=[dt.Camera()], spp=2, max_depth=2)
    with pytest.warns(UserWarning, match=r"they open before the scene's shutter"):  # the advice was about T, which was not the cause
        dt.render(dt.load_scene(one_ms_shutter.with_name("late.xml")), cameras=[dt.Camera(exposure=1e-3, exposure_start=0.0)], spp=2, max_depth=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dt.render(scene, cameras=[dt.Camera(exposure=1e-3)], spp=2, max_depth=2)
        dt.render(scene, spp=2, max_depth=2)  # the scene's own exposure


def test_the_command_line_warns_too_when_its_cameras_expose_outside_the_shutter(one_ms_shutter, tmp_path):
    """The API warned and the command line, given T=, was silent; without a camera it now
    says that the render holds no D-ToF measurement."""
    out = _cli("render", str(one_ms_shutter), "--camera", "h=1,T=1.5e-3", "--spp", "2", "--max-depth", "2", "--resolution", "4", "-o", str(tmp_path / "a"))
    assert out.returncode == 0 and "warning: the cameras expose 0 to 0.0015 s: they close after the scene's shutter" in out.stderr, out.stderr
    within = _cli("render", str(one_ms_shutter), "--camera", "h=1", "--spp", "2", "--max-depth", "2", "--resolution", "4", "-o", str(tmp_path / "b"))
    assert within.returncode == 0 and "shutter" not in within.stderr, within.stderr
    none = _cli("render", str(one_ms_shutter), "--spp", "2", "--max-depth", "2", "--resolution", "4", "-o", str(tmp_path / "c"))
    assert none.returncode == 0 and "(no D-ToF camera: intensity and ground truth only; give --camera)" in none.stdout, none.stdout
