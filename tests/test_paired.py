"""Paired tracing: correlation ``reconnection`` and ``adaptive`` (:mod:`dopplertof.tracing.paired`).

Issue 3's checks: a static scene at h = 1 renders zero (to float rounding with antithetic
pairs); every time sampling × correlation mode is unbiased against a high-spp reference on
the Cornell box and on the glossy scene (spinning rough-gold cube, rolling glass sphere,
mirror sphere); reconnections that fail (occluded, or one member's camera ray missing the
moving body) do not bias; bad settings are clear errors; on the Cornell box the paired modes
are not much noisier than replay.

Statistics. A *region sum* S (one camera's measurement summed over a set of pixels) has
the standard error sqrt(Σ stderr²): pixels draw independent random numbers. A render agrees
with the reference where z = (S − S_ref) / sqrt(se² + se_ref²) is small. A test checks many
z's at once (cameras × regions × estimators × seeds); it bounds max |z| by Bonferroni's
bound for a family false-alarm rate of 1e-4, which holds whatever the correlations between
the z's (they share the reference, and one render's cameras share its paths). Each such
test also checks that the same bound would flag a 10 % (glossy: 20 %) error of every
render, so that it can fail.
"""

import json
import math
from statistics import NormalDist

import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import cli
from dopplertof.correlation import MODES, PAIRED
from dopplertof.timesampling import METHODS

from scene_dicts import T, grey, perspective

MAX_DEPTH = 4
CAMERAS = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
HETERODYNE = [i for i, c in enumerate(CAMERAS) if c.heterodyne == 1.0]
FAMILY_FALSE_ALARM = 1e-4
SEEDS = (1, 2)
REFERENCE_SEED = 1000  # never one of the seeds of the renders it judges
MOVING_M_S = 1e-3  # |ground-truth velocity| above which a pixel is on a moving body


def bonferroni_bound(n_tests, family_false_alarm=FAMILY_FALSE_ALARM):
    """|z| that n two-sided normal tests all stay below with probability 1 − family_false_alarm."""
    return NormalDist().inv_cdf(1.0 - family_false_alarm / (2 * n_tests))


def time_sampling(method):
    """Pairs of times (n_times = 2) for every method; the antithetic shifts of the original
    (the defaults: ½ for antithetic, 0 for antithetic_mirror) and stratified intervals."""
    settings = dict(time_sampling=method, n_times=2, stratify_intervals=True)
    if method in ("antithetic", "antithetic_mirror"):
        settings["antithetic_shift"] = 0.0 if method == "antithetic_mirror" else 0.5
    return settings


def region_sums(result, masks):
    """(sums, standard errors), each (n_masks, n_cameras), of the measurements over ``masks``."""
    m = result.measurements.astype(np.float64)
    var = result.measurement_stderr.astype(np.float64) ** 2
    sums = np.array([m[:, mask].sum(axis=1) for mask in masks])
    errors = np.sqrt(np.array([var[:, mask].sum(axis=1) for mask in masks]))
    return sums, errors


def z_scores(result, reference, masks, relative_error=0.1):
    """z of every (region, camera), and the z a ``relative_error`` of the reference's sums
    would give (how large an error the comparison can see)."""
    sums, errors = region_sums(result, masks)
    ref_sums, ref_errors = region_sums(reference, masks)
    combined = np.sqrt(errors**2 + ref_errors**2)
    return ((sums - ref_sums) / combined).ravel(), (relative_error * np.abs(ref_sums) / combined).ravel()


def moving_and_whole(reference):
    """Region masks: the pixels on moving bodies (from the reference's velocity), the image."""
    moving = np.abs(np.nan_to_num(reference.velocity)) > MOVING_M_S
    return [moving, np.ones_like(moving)]


def render(scene, spp, seed, method="antithetic", correlation="replay", **kw):
    """A render with this module's cameras and depth, pairs of times of ``method``."""
    return dt.render(scene, cameras=CAMERAS, spp=spp, seed=seed, max_depth=MAX_DEPTH,
                     correlation=correlation, **time_sampling(method), **kw)


# ----------------------------------------------------------------------------------------
# Scenes and references (built once per module)


@pytest.fixture(scope="module")
def cornell():
    return dt.scenes.cornell_box(resolution=16)


@pytest.fixture(scope="module")
def cornell_reference(cornell):
    return render(cornell, 8192, REFERENCE_SEED)


@pytest.fixture(scope="module")
def static_cornell():
    return dt.scenes.cornell_box(resolution=16, displacement=0.0)


# ----------------------------------------------------------------------------------------
# Static scene at h = 1


@pytest.mark.parametrize("correlation", ["replay", *PAIRED])
def test_static_scene_heterodyne_is_zero_to_rounding_with_antithetic_pairs(static_cornell, correlation):
    """Antithetic pairs (shift ½) at h = 1 cancel exactly on a static scene: replay gives 0,
    the paired modes float rounding of the re-timed reconnection targets (measured at 16 px,
    32 spp, seeds 0–2: mean |m| ≤ 1.6e-7, max ≤ 3.4e-5 of the mean homodyne |m|)."""
    result = dt.render(static_cornell, cameras=CAMERAS, spp=32, seed=1, max_depth=MAX_DEPTH,
                       time_sampling="antithetic", correlation=correlation)
    homodyne = np.abs(result.measurements[0]).mean()
    heterodyne = np.abs(result.measurements[HETERODYNE])
    assert homodyne > 0
    assert heterodyne.mean() < 1e-5 * homodyne
    assert heterodyne.max() < 1e-3 * homodyne


def test_static_scene_heterodyne_is_zero_within_noise_for_other_time_samplings(static_cornell):
    """Paired modes at h = 1 on a static scene, with times that do not cancel pairwise
    (uniform, stratified, mirror): the whole image sums to zero within its noise."""
    zs = []
    for method in (m for m in METHODS if m != "antithetic"):  # antithetic: exact, above
        for correlation in PAIRED:
            result = render(static_cornell, 64, 3, method, correlation)
            sums, errors = region_sums(result, [np.ones(result.measurements.shape[1:], bool)])
            zs.extend((sums / errors)[0, HETERODYNE])
    assert np.abs(zs).max() < bonferroni_bound(len(zs)), np.round(zs, 2)


# ----------------------------------------------------------------------------------------
# Unbiasedness: every time sampling x correlation against a high-spp reference


def _agreement(scene, reference, spp, relative_error, exposure_start=0.0):
    """z's of every (method, correlation, seed) × (region, camera), and per render the
    largest z a ``relative_error`` would give."""
    masks = moving_and_whole(reference)
    assert masks[0].sum() >= 20, "too few pixels on moving bodies for a meaningful test"
    zs, sensitivity, labels = [], [], []
    for seed in SEEDS:
        for method in METHODS:
            for correlation in MODES:
                result = render(scene, spp, seed, method, correlation, exposure_start=exposure_start)
                z, error_z = z_scores(result, reference, masks, relative_error)
                zs.append(z)
                sensitivity.append(error_z.max())
                labels.append(f"seed {seed} {method}/{correlation}")
    return np.array(zs), np.array(sensitivity), labels


def _assert_agreement(zs, sensitivity, labels, relative_error):
    bound = bonferroni_bound(zs.size)
    worst = np.abs(zs).max(axis=1)
    failing = {label: round(float(w), 2) for label, w in zip(labels, worst) if w >= bound}
    assert not failing, f"|z| >= {bound:.2f}: {failing}"
    blind = [label for label, s in zip(labels, sensitivity) if s < bound]
    assert not blind, f"these renders would not reveal a {relative_error:.0%} error: {blind}"


@pytest.mark.slow
def test_every_mode_is_unbiased_on_the_cornell_box(cornell, cornell_reference):
    """4 time samplings × 5 correlations × 2 seeds at 256 spp, 4 cameras, regions = moving
    boxes and whole image. Measured: 8 other seed pairs and references, max |z| 2.0–2.8
    (bound 5.1); 10 seeds at 64 spp, mean z² 0.7–1.0 per mode and no mode's mean z of a
    statistic beyond ±0.65. Every render would reveal a 10 % error of the boxes' homodyne
    sum (z ≈ 50)."""
    _assert_agreement(*_agreement(cornell, cornell_reference, 256, 0.1), 0.1)


@pytest.mark.slow
def test_every_mode_is_unbiased_on_the_glossy_scene():
    """The glossy scene half-way through its clip: rough gold (α = 0.15, so ``adaptive``
    replays there and ``reconnection`` reconnects) spinning, glass (delta: replay in both)
    rolling, a mirror sphere. Same design as the Cornell box; 24 px, 512 spp. Noisier:
    every render would reveal a 20 % error of the moving pixels' homodyne sum. Since hits on
    scaled bodies shade right (their ``wi`` in the world), reconnection's and adaptive's
    moving pixels are noisier: at 256 spp a 20 % error gave z 4.8–5.8 there, some under the
    bound, so 512. Measured at 512 spp with 3 seed pairs and references: max |z| 2.7–3.2
    (bound 5.1), 20 % error z ≥ 7.3."""
    scene = dt.scenes.glossy(resolution=24)
    start = dt.scenes.clip_duration("glossy") / 2
    reference = render(scene, 8192, REFERENCE_SEED, exposure_start=start)
    _assert_agreement(*_agreement(scene, reference, 512, 0.2, exposure_start=start), 0.2)


# ----------------------------------------------------------------------------------------
# Shift failures


def slatted_wall(resolution, speed_m_s=40.0):
    """Thin slats (2 cm wide, 10 cm apart, 3 m tall) sliding sideways at ``speed_m_s`` in
    front of a 2.4 m wall that does not fill the view, a box in front of them, a point
    light at the camera.

    Between the two times of an antithetic pair (T/2 = 0.75 ms) the slats move 3 cm, more
    than their width, so a reconnection that crosses the slat plane (wall ↔ box, wall ↔
    light) is blocked at one time and free at the other about one time in five, and at
    every slat edge one member's camera ray hits the slat while the other's goes to the
    wall or, above and below the wall, out of the scene.
    """
    scene = {
        "type": "scene",
        "sensor": perspective((0, 0, 5), (0, 0, 0), 30, resolution),
        "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -1]) @ T().scale(1.2), "bsdf": grey(0.8)},
        "box": {"type": "cube", "to_world": T().translate([0.45, -0.3, 0.6]) @ T().rotate([0, 1, 0], 30) @ T().scale(0.25), "bsdf": grey(0.7)},
        "light": {"type": "point", "position": [0, 0, 5], "intensity": {"type": "rgb", "value": [30.0] * 3}},
    }
    for i in range(17):
        scene[f"slat-{i}"] = {
            "type": "cube",
            "to_world": T().translate([-0.8 + 0.1 * i, 0, 0]) @ T().scale([0.01, 1.5, 0.01]),
            "bsdf": grey(0.5),
            "motion": {"type": "parametric", "linear_velocity": [speed_m_s, 0, 0]},
        }
    return dt.load_scene(scene)


def quadrants(shape):
    """Four disjoint pixel masks, one per image quadrant."""
    rows, cols = np.indices(shape)
    top, left = rows < shape[0] // 2, cols < shape[1] // 2
    return [top & left, top & ~left, ~top & left, ~top & ~left]


def test_failed_shifts_do_not_bias():
    """Paired modes on :func:`slatted_wall` agree with antithetic + replay per image quadrant
    and camera; a shift failure must end the partner without biasing the pair."""
    scene = slatted_wall(16)
    reference = dt.render(scene, cameras=CAMERAS, spp=8192, seed=REFERENCE_SEED, max_depth=MAX_DEPTH)
    masks = quadrants(reference.measurements.shape[1:])
    zs, sensitivity = [], []
    for seed in SEEDS:
        for method in ("antithetic", "uniform"):
            for correlation in PAIRED:
                z, error_z = z_scores(render(scene, 256, seed, method, correlation), reference, masks)
                zs.append(z)
                sensitivity.append(error_z.max())
    zs = np.array(zs)
    bound = bonferroni_bound(zs.size)
    assert min(sensitivity) > bound
    assert np.abs(zs).max() < bound, np.round(zs, 1)


# ----------------------------------------------------------------------------------------
# Bad input


@pytest.mark.parametrize("correlation", PAIRED)
@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(n_times=3), r"pairs two times \(n_times=2\), got n_times=3"),
        (dict(time_sampling="stratified", n_times=4), "n_times=4"),
        (dict(correlation_depth=2), "'correlation_depth' applies to replay"),
        (dict(reconnection_threshold=-0.5), "'reconnection_threshold' must be >= 0.0, got -0.5"),
        (dict(reconnection_threshold=float("nan")), "threshold"),
    ],
)
def test_paired_modes_reject_bad_settings(static_cornell, correlation, kwargs, message):
    with pytest.raises(ValueError, match=message):
        dt.render(static_cornell, cameras=CAMERAS, spp=4, correlation=correlation, **kwargs)


def test_uniform_times_are_paired_for_the_paired_modes(static_cornell):
    result = dt.render(static_cornell, spp=4, max_depth=2, time_sampling="uniform", correlation="adaptive")
    assert result.settings.group_size == 2 and result.settings.correlation == "adaptive"


# ----------------------------------------------------------------------------------------
# Command line


def _run_render(*args):
    result = CliRunner().invoke(cli.main, ["render", *map(str, args), "--quiet"])
    return result.exit_code, result.output


def test_cli_renders_adaptive_with_its_threshold(tmp_path):
    code, output = _run_render("cornell-box", "--resolution", 4, "--spp", 2, "--max-depth", 2, "--camera", "h=1",
                               "--time-sampling", "stratified", "--correlation", "adaptive",
                               "--reconnection-threshold", 0.2, "-o", tmp_path)
    assert code == 0, output
    settings = json.loads((tmp_path / "metadata.json").read_text())["settings"]
    assert settings["correlation"] == "adaptive" and settings["time_sampling"] == "stratified"
    assert settings["reconnection_threshold"] == 0.2


@pytest.mark.parametrize(
    "args, message",
    [
        (["--correlation", "adaptive", "--reconnection-threshold", -1], "'reconnection_threshold' must be >= 0.0, got -1.0"),
        (["--correlation", "reconnection", "--correlation-depth", 2], "'correlation_depth' applies to replay"),
    ],
)
def test_cli_rejects_bad_paired_settings_in_one_line(tmp_path, args, message):
    code, output = _run_render("cornell-box", "--resolution", 4, "--spp", 2, *args, "-o", tmp_path)
    assert code == 2
    lines = output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], output


def test_cli_correlation_replaces_the_files_correlation_depth(data_dir, tmp_path):
    """A file's path_correlation_depth = 4 means replay to depth 4: --correlation picks
    another mode, and the depth goes with the file's mode instead of failing the paired one."""
    text = (data_dir / "original_cornell.xml").read_text()
    scene = tmp_path / "original.xml"
    scene.write_text(text.replace('<default name="res" value="256"/>', '<default name="res" value="4"/>'))
    code, output = _run_render(scene, "--spp", 2, "--max-depth", 2, "--correlation", "reconnection", "-o", tmp_path / "out")
    assert code == 0, output
    settings = json.loads((tmp_path / "out" / "metadata.json").read_text())["settings"]
    assert settings["correlation"] == "reconnection" and settings["correlation_depth"] is None


def test_cli_help_lists_every_correlation_mode():
    output = CliRunner().invoke(cli.main, ["render", "--help"]).output
    squeezed = " ".join(output.split())
    assert "--correlation [" + "|".join(MODES) + "]" in squeezed
    assert "--reconnection-threshold" in output


# ----------------------------------------------------------------------------------------
# Variance (not a timing)


@pytest.mark.slow
def test_paired_modes_are_not_much_noisier_than_replay_on_the_cornell_box(cornell, cornell_reference):
    """MSE of the h = 1 measurements (ψ = 0 and 90°) against the 8192-spp reference, the
    reference's own variance subtracted, over 8 seeds at 256 spp with antithetic pairs, on
    the moving boxes and on the whole image. Measured: reconnection = adaptive (all diffuse)
    have 1.7–2.5× replay's MSE on the boxes and 1.4–1.9× on the image (five seed sets);
    with 3 seeds the spread reaches 3.0 and 2.2."""
    masks = moving_and_whole(cornell_reference)
    reference = cornell_reference.measurements[HETERODYNE].astype(np.float64)
    reference_var = cornell_reference.measurement_stderr[HETERODYNE].astype(np.float64) ** 2
    mse = {}
    for correlation in ("replay", *PAIRED):
        squared = 0.0
        for seed in range(3, 11):
            result = render(cornell, 256, seed, "antithetic", correlation)
            squared = squared + (result.measurements[HETERODYNE] - reference) ** 2 - reference_var
        mse[correlation] = np.array([squared[:, mask].mean() for mask in masks])
    for correlation in PAIRED:
        ratio = mse[correlation] / mse["replay"]
        assert ratio[0] < 3.5 and ratio[1] < 3.0, f"{correlation}: MSE / replay's (boxes, image) = {np.round(ratio, 2)}"
