"""``dopplertof experiment ...``: the quick forms run, write finite tables, and reuse references."""

import csv
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from dopplertof.cli import main
from dopplertof.experiments import common, sweeps, velocity
from dopplertof.experiments.common import Estimator, ReferenceCache, image_errors, open_scene
from dopplertof.timesampling import METHODS


def run_cli(*args):
    return CliRunner().invoke(main, ["experiment", *args], catch_exceptions=False)


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def finite(rows, columns):
    return all(math.isfinite(float(row[c])) for row in rows for c in columns)


def run_quick(experiment, tmp_path, cache_dir, columns):
    """Run ``experiment`` on the Cornell box in its quick form; (output folder, rows of its
    results.csv), after checking that it succeeded and wrote exactly ``columns``."""
    out = tmp_path / experiment
    result = run_cli(experiment, "cornell-box", "--quick", "--cache", str(cache_dir), "-o", str(out))
    assert result.exit_code == 0, result.output
    found, rows = read_csv(out / "results.csv")
    assert tuple(found) == columns
    return out, rows


def assert_written(out, *names):
    """Every named file is in ``out`` and not empty."""
    for name in names:
        assert (out / name).stat().st_size > 0, name


@pytest.fixture
def cache_dir(tmp_path):
    return tmp_path / "cache"


# ------------------------------------------------------------------------------- commands


@pytest.mark.slow
def test_time_sampling_quick(tmp_path, cache_dir):
    out, rows = run_quick("time-sampling", tmp_path, cache_dir, sweeps.RESULT_COLUMNS)
    configs = {(r["time_sampling"], r["correlation"]) for r in rows}
    assert configs == {(m, c) for m in METHODS for c in ("none", "replay")}
    assert len(rows) == len(configs) * 3 * 2  # quick: 3 h x 2 psi
    assert finite(rows, ("h", "psi_deg", "mae", "rmse", "relative_mae", "relative_rmse", "psnr_db", "stderr_rms", "reference_stderr_rms"))

    # the paper's headline: at h = 1, antithetic + replay beats uniform + independent paths
    def rmse_at_h1(method, mode):
        return np.mean([float(r["rmse"]) for r in rows if (r["time_sampling"], r["correlation"], r["h"]) == (method, mode, "1")])

    assert rmse_at_h1("antithetic", "replay") < 0.2 * rmse_at_h1("uniform", "none")

    columns, summary = read_csv(out / "summary.csv")
    assert tuple(columns) == sweeps.SUMMARY_COLUMNS
    assert len(summary) == len(configs) * 3
    assert finite(summary, ("rmse_mean", "rmse_std", "psnr_db_mean"))
    for mode in ("none", "replay"):
        assert_written(out, f"rmse_vs_h_{mode}.png", f"psnr_vs_h_{mode}.png")


@pytest.mark.slow
def test_shifts_quick(tmp_path, cache_dir):
    out, rows = run_quick("shifts", tmp_path, cache_dir, sweeps.RESULT_COLUMNS)
    assert {r["time_sampling"] for r in rows} == {"antithetic", "antithetic_mirror"}
    assert {float(r["shift"]) for r in rows} == {0.0, 0.5, 1.0}
    assert finite(rows, ("shift", "h", "mae", "rmse", "psnr_db"))

    # at h = 1 the antithetic shift a = T/2 cancels the static part (paper Fig. 15)
    def rmse(shift):
        return np.mean([float(r["rmse"]) for r in rows if r["time_sampling"] == "antithetic" and float(r["shift"]) == shift and r["h"] == "1"])

    assert rmse(0.5) < 0.2 * rmse(0.0)
    for method in ("antithetic", "antithetic_mirror"):
        assert_written(out, f"rmse_{method}_shift_h.png", f"rmse_vs_shift_{method}.png")


@pytest.mark.slow
def test_velocity_quick(tmp_path, cache_dir):
    out, rows = run_quick("velocity", tmp_path, cache_dir, velocity.COLUMNS)
    estimators = ["reference"] + [e.label.replace("/", "-") for e in velocity.DEFAULT_ESTIMATORS]
    assert [(r["estimator"], r["noise"]) for r in rows] == [(e, n) for e in estimators for n in ("none", "sensor")]
    assert finite(rows[:1], velocity.COLUMNS[6:])  # the reference has valid pixels; 16 spp may have none
    assert all(int(r["moving_pixels"]) > 10 for r in rows)  # the two boxes at +-10 m/s
    reference = rows[0]
    assert float(reference["median_abs_error_m_s"]) < 5.0
    # valid means the reconstruction's validity (its error within a threshold), not a finite estimate
    fractions = {(r["estimator"], r["noise"]): float(r["valid_fraction"]) for r in rows}
    assert fractions[("uniform-none", "none")] < 0.5  # every estimate is finite there
    for r in rows:
        if float(r["valid_fraction"]) > 0:
            assert float(r["max_velocity_stderr_m_s"]) > 0 and math.isfinite(float(r["rmse_m_s"]))
    for name in estimators:
        assert_written(out, f"velocity_{name}.png", f"velocity_error_{name}.png")


def test_rerun_loads_the_reference_from_the_cache(tmp_path, cache_dir, monkeypatch):
    calls = []
    real_render = common.render

    def counting_render(*args, **kwargs):
        calls.append(kwargs["seed"])
        return real_render(*args, **kwargs)

    monkeypatch.setattr(common, "render", counting_render)
    args = ["time-sampling", "cornell-box", "--quick", "--time-sampling", "antithetic", "--correlation", "replay", "--cache", str(cache_dir)]

    first = run_cli(*args, "-o", str(tmp_path / "a"))
    assert first.exit_code == 0, first.output
    assert "reference: rendering" in first.output
    assert sorted(calls) == [0, 1]  # the estimator at --seed 0, the reference at seed + 1

    calls.clear()
    second = run_cli(*args, "-o", str(tmp_path / "b"))
    assert second.exit_code == 0, second.output
    assert "reference: loaded from cache" in second.output
    assert calls == [0]

    def errors(folder):
        return [{k: v for k, v in row.items() if k != "render_seconds"} for row in read_csv(tmp_path / folder / "results.csv")[1]]

    assert errors("a") == errors("b")

    calls.clear()
    third = run_cli(*args, "--seed", "5", "-o", str(tmp_path / "c"))
    assert "reference: rendering" in third.output
    assert sorted(calls) == [5, 6]


def test_cache_key_covers_scene_and_parameters(tmp_path, data_dir):
    def key(scene, spp=16, seed=1, h=(0.0, 1.0), estimator=common.REFERENCE_ESTIMATOR):
        cameras = common.camera_grid(scene.base_camera, h, (0.0,))
        return ReferenceCache.key(scene, cameras, spp, seed, 3, estimator)

    small, large = open_scene("cornell-box", 8), open_scene("cornell-box", 10)
    base = key(small)
    assert key(open_scene("cornell-box", 8)) == base
    assert len({base, key(large), key(small, spp=32), key(small, seed=2), key(small, h=(0.0, 0.5)), key(small, estimator=Estimator("antithetic", "pixel"))}) == 6

    xml = tmp_path / "scene.xml"
    shutil.copy(data_dir / "original_cornell.xml", xml)
    before = key(open_scene(str(xml), None))
    xml.write_text(xml.read_text() + "\n<!-- edited -->\n")
    assert key(open_scene(str(xml), None)) != before


def test_cache_key_covers_the_rendering_source(monkeypatch):
    """A stale reference must not survive a change of the integrator without a version bump."""
    scene = open_scene("cornell-box", 8)
    cameras = common.camera_grid(scene.base_camera, (0.0, 1.0), (0.0,))

    def key():
        return ReferenceCache.key(scene, cameras, 16, 1, 3, common.REFERENCE_ESTIMATOR)

    before = key()
    monkeypatch.setattr(common, "rendering_source_digest", lambda: "0" * 64)
    assert key() != before


def test_rendering_source_digest_follows_the_renderer_only(tmp_path):
    package = tmp_path / "dopplertof"
    shutil.copytree(common.PACKAGE_DIR, package, ignore=shutil.ignore_patterns("__pycache__"))
    names = {p.relative_to(package).as_posix() for p in common.rendering_source_files(package)}
    tracing = {"tracing/single.py", "tracing/paired.py", "tracing/path.py", "tracing/lanes.py", "tracing/sink.py", "tracing/film.py", "tracing/materials.py"}
    assert tracing | {"render.py", "settings.py", "outputs.py", "timesampling.py", "scene.py", "motion.py", "loader.py", "scenes.py"} <= names
    assert not names & {"cli.py", "clitools.py", "folder.py", "viz.py", "io.py", "render_folder.py"}
    assert not any(name.startswith(("experiments/", "reconstruct/")) for name in names)

    before = common.rendering_source_digest(package)
    with open(package / "cli.py", "a") as f:
        f.write("\n# not rendering\n")
    assert common.rendering_source_digest(package) == before
    with open(package / "tracing" / "single.py", "a") as f:
        f.write("\n# rendering\n")
    changed = common.rendering_source_digest(package)
    assert changed != before
    (package / "tracing" / "bounce.py").write_text("# a new tracing module\n")
    assert common.rendering_source_digest(package) != changed


def test_cache_round_trip(tmp_path):
    scene = open_scene("cornell-box", 8)
    cameras = common.camera_grid(scene.base_camera, (0.0, 1.0), (0.0,))
    result, _ = common.timed_render(scene, cameras, common.REFERENCE_ESTIMATOR, 4, 3, 2)
    cache = ReferenceCache(tmp_path)
    assert cache.load("missing", cameras) is None
    cache.store("k", result)
    loaded = cache.load("k", cameras)
    for name in ("intensity", "measurements", "measurement_stderr", "velocity", "depth"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(result, name))
    assert (loaded.spp, loaded.seed, loaded.settings) == (result.spp, result.seed, result.settings)
    # a damaged file is rendered again (a truncated one raised BadZipFile from every experiment using it)
    whole = cache.path("k").read_bytes()
    for damaged in (whole[:1000], whole[:-40] + bytes(40)):
        cache.path("k").write_bytes(damaged)
        assert cache.load("k", cameras) is None


def test_default_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("DOPPLERTOF_CACHE", str(tmp_path / "mine"))
    assert common.default_cache_dir() == tmp_path / "mine"
    monkeypatch.delenv("DOPPLERTOF_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert common.default_cache_dir() == tmp_path / "xdg" / "dopplertof" / "references"


# --------------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "args, words",
    [
        (["no-such-experiment", "cornell-box"], "unknown experiment 'no-such-experiment'"),
        (["time-sampling", "no-such-scene", "--quick"], "no-such-scene"),
        (["velocity", "no-such-scene.xml", "--quick"], "no-such-scene.xml"),
        (["time-sampling", "cornell-box", "--quick", "--spp", "3"], "spp must be a positive multiple of 2"),
        (["velocity", "cornell-box", "--quick", "--reference-spp", "0"], "--reference-spp must be an integer >= 1, got 0"),
        (["shifts", "cornell-box", "--quick", "--h-steps", "-2"], "--h-steps must be an integer >= 2, got -2"),
        (["shifts", "cornell-box", "--quick", "--phases", "0"], "--phases must be an integer >= 1, got 0"),
        (["shifts", "cornell-box", "--quick", "--spp", "0"], "--spp must be an integer >= 1, got 0"),
        (["paper-fig12", "cornell-box", "--quick", "--max-depth", "0"], "--max-depth must be >= 1 or -1"),
        (["time-sampling", "cornell-box", "--quick", "--time-sampling", "bogus"], "unknown time_sampling 'bogus'"),
        (["time-sampling", "cornell-box", "--quick", "--correlation", "bogus"], "unknown correlation 'bogus'"),
        (["time-sampling", "cornell-box", "--quick", "--h-steps", "1"], "--h-steps"),
        (["shifts", "cornell-box", "--quick", "--time-sampling", "uniform"], "antithetic"),
        (["velocity", "cornell-box", "--quick", "--signal-electrons", "-1"], "signal electrons"),
        (["velocity", "cornell-box", "--quick", "--address", "auto"], "--address needs --ray"),
    ],
)
def test_bad_input_is_one_error_line(tmp_path, args, words):
    result = run_cli(*args, "--cache", str(tmp_path / "cache"), "-o", str(tmp_path / "out")) if args[0] != "no-such-experiment" else run_cli(*args)
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and words in lines[0], result.output
    assert "Traceback" not in result.output
    if "must be an" in words:  # checked before anything is announced or made
        assert result.output.strip() == lines[0] and not (tmp_path / "out").exists(), result.output


# ---------------------------------------------------------------------------------- metrics


def test_image_errors_of_a_known_offset():
    reference = np.array([[0.0, 1.0], [2.0, -1.0]])
    errors = image_errors(reference + 0.1, reference)
    assert errors["mae"] == pytest.approx(0.1)
    assert errors["rmse"] == pytest.approx(0.1)
    assert errors["relative_rmse"] == pytest.approx(0.1 / 1.0)
    assert errors["psnr_db"] == pytest.approx(20 * math.log10(3.0 / 0.1))
    assert image_errors(reference, reference)["psnr_db"] == math.inf
    assert math.isnan(image_errors(np.ones(3), np.zeros(3))["relative_mae"])


def test_velocity_errors_on_moving_and_static_pixels():
    truth = np.array([10.0, -10.0, 0.0, 0.0, np.nan])
    estimate = np.array([11.0, np.nan, 0.5, -0.5, 3.0])
    stats = velocity.velocity_errors(estimate, truth)
    assert stats["moving_pixels"] == 2 and stats["static_pixels"] == 2
    assert stats["valid_fraction"] == 0.5
    assert stats["mae_m_s"] == stats["rmse_m_s"] == stats["bias_m_s"] == 1.0
    assert stats["relative_mae"] == pytest.approx(0.1)
    assert stats["static_rmse_m_s"] == pytest.approx(0.5)


def test_phase_offsets_cover_half_a_period():
    assert sweeps.phase_offsets(4) == pytest.approx((0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4))
    with pytest.raises(ValueError, match="phases"):
        sweeps.phase_offsets(0)


# ------------------------------------------------------------------- the paper's orderings


def test_time_sampling_orderings_at_h_1_on_a_small_cornell_box(tmp_path, cache_dir):
    """The paper's orderings at h = 1 (Fig. 12: RMSE ratios to uniform 0.38 stratified,
    0.50 mirror, 0.038 antithetic, all with replayed paths), as the time-sampling sweep
    renders them: 16², 64 spp, 4 phases, reference 4096 spp.

    Measured over seeds 0-5 (mean ± std): stratified ÷ uniform 0.25 ± 0.02, mirror ÷
    uniform 0.32 ± 0.02, antithetic ÷ stratified 0.13 ± 0.03. Each bound below is at least
    5 standard deviations from its mean. With each interval stratified in only 2 strata
    (the render default of 16 replicates at 64 spp) the mirror was 0.97 × uniform (at 32²)."""
    scene = open_scene("cornell-box", 16)
    estimators = [Estimator(method, "replay") for method in METHODS]
    settings = sweeps.SweepSettings((1.0,), sweeps.phase_offsets(4), 64, 4096, 0, 4)
    sweeps.run_time_sampling(scene, tmp_path, estimators, settings, ReferenceCache(cache_dir), lambda line: None)
    _, rows = read_csv(tmp_path / "summary.csv")
    rmse = {row["time_sampling"]: float(row["rmse_mean"]) for row in rows}
    assert rmse["stratified"] < 0.4 * rmse["uniform"], rmse
    assert rmse["antithetic_mirror"] < 0.5 * rmse["uniform"], rmse
    assert rmse["antithetic"] < 0.3 * rmse["stratified"], rmse


# ------------------------------------------------------------------------ the paper's figures


def run_subprocess(*args, cache_dir):
    """``dopplertof experiment ARGS`` in a real process, the reference cache in ``cache_dir``."""
    env = {**os.environ, "DOPPLERTOF_CACHE": str(cache_dir)}
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", "experiment", *args], capture_output=True, text=True, env=env, timeout=600)


def test_paper_fig12_quick_writes_its_tables_and_plot(tmp_path, cache_dir):
    out = tmp_path / "fig12"
    done = run_subprocess("paper-fig12", "cornell-box", "--quick", "-o", str(out), cache_dir=cache_dir)
    assert done.returncode == 0, done.stderr
    found, rows = read_csv(out / "results.csv")
    assert tuple(found) == sweeps.RESULT_COLUMNS
    # the protocol's grid in its quick form: 3 ω_r x psi = 2π·linspace(0, 1, 5), every method with and without correlation
    assert {(r["time_sampling"], r["correlation"]) for r in rows} == {(m, c) for m in METHODS for c in ("none", "replay")}
    assert sorted({float(r["h"]) for r in rows}) == [0.0, 0.5, 1.0]
    assert sorted({round(float(r["psi_deg"])) for r in rows}) == [0, 90, 180, 270, 360]
    assert len(rows) == 8 * 3 * 5 and finite(rows, ("rmse", "rmse_x_exposure", "psnr_db"))
    _, summary = read_csv(out / "summary.csv")
    assert {int(r["count"]) for r in summary} == {5}
    assert_written(out, "fig12.png", "metadata.json")
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["max_depth"] == 4 and metadata["rendered_psi_deg"] == pytest.approx([0.0, 90.0])


@pytest.mark.slow
def test_paper_fig9_and_fig15_quick(tmp_path, cache_dir):
    out = tmp_path / "fig9"
    done = run_subprocess("paper-fig9", "cornell-box", "--quick", "--waveform", "sinusoidal", "--waveform", "rectangular", "-o", str(out), cache_dir=cache_dir)
    assert done.returncode == 0, done.stderr
    _, rows = read_csv(out / "results.csv")
    assert {r["waveform"] for r in rows} == {"sinusoidal", "rectangular"}
    assert {(r["time_sampling"], r["stratify_intervals"]) for r in rows} == {("uniform", "False")} | {  # uniform times have no strata
        (m, s) for m in ("stratified", "antithetic", "antithetic_mirror") for s in ("True", "False")
    }
    assert_written(out, "fig9.png")
    out = tmp_path / "fig15"
    done = run_subprocess("paper-fig15", "cornell-box", "--quick", "-o", str(out), cache_dir=cache_dir)
    assert done.returncode == 0, done.stderr
    _, rows = read_csv(out / "results.csv")
    assert {r["shift"] for r in rows} == {"0", "0.5", "1"}
    assert_written(out, "rmse_antithetic_shift_h.png", "rmse_vs_shift_antithetic_mirror.png")


@pytest.mark.parametrize(
    "args, words",
    [
        (("paper-fig9", "cornell-box", "--quick", "--waveform", "sawtooth"), "unknown --waveform 'sawtooth'"),
        (("paper-fig12", "cornell-box", "--quick", "--phase-steps", "1"), "--phase-steps must be an integer >= 2"),
        (("paper-fig12", "cornell-box", "--quick", "--time-sampling", "analytic"), "analytic"),
    ],
)
def test_paper_commands_refuse_bad_input_in_one_line(tmp_path, args, words):
    done = run_subprocess(*args, "-o", str(tmp_path / "out"), cache_dir=tmp_path / "cache")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and words in lines[0], done.stderr


def test_folded_phases_render_psi_beyond_pi_as_psi_minus_pi():
    rendered, index = sweeps.folded_phases([2 * math.pi * k / 10 for k in range(11)])
    assert rendered == pytest.approx([0.0, 0.2 * math.pi, 0.4 * math.pi, 0.6 * math.pi, 0.8 * math.pi])
    assert index == [0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 0]


def test_estimators_stratify_their_intervals_by_the_settings_default():
    """Further stratification has one default, the settings'; an estimator only overrides it when told."""
    from dopplertof.settings import FIELDS

    assert FIELDS["stratify_intervals"].default is True
    for method in METHODS:
        estimator = Estimator(method, "replay")
        # uniform times have no strata: their rows said stratify_intervals True
        assert "stratify_intervals" not in estimator.render_settings() and estimator.stratified == (method != "uniform")
        assert estimator.label == f"{method}/replay"
    off = Estimator("antithetic", "replay", stratify_intervals=False)
    assert off.render_settings()["stratify_intervals"] is False and off.label.endswith("no further stratification")


def _correlation_ratios(seed, cache):
    """RMSE of antithetic/replay ÷ antithetic/none at ω_r = 0 and 1 (mean over 4 ψ), 32²
    Cornell box, 64 spp, reference 4096 spp, as the time-sampling sweep renders them."""
    scene = open_scene("cornell-box", 32)
    estimators = [Estimator("antithetic", c) for c in ("none", "replay")]
    settings = sweeps.SweepSettings((0.0, 1.0), sweeps.phase_offsets(4), 64, 4096, seed, 4)
    rows, _ = sweeps._sweep(scene, estimators, settings, cache, lambda line: None)
    summary = common.mean_over(rows, sweeps.SUMMARY_GROUP, sweeps.METRICS)
    rmse = {(row["correlation"], row["h"]): row["rmse_mean"] for row in summary}
    return rmse[("replay", 0.0)] / rmse[("none", 0.0)], rmse[("replay", 1.0)] / rmse[("none", 1.0)]


@pytest.mark.slow
def test_full_correlation_costs_about_root_two_at_h_0(cache_dir):
    """Replayed paths make an antithetic pair one path at two times: at ω_r = 0 the pair
    counts as one sample (RMSE × √2 against independent paths at equal paths and time; the
    paper: 1.3-1.6×), at ω_r = 1 the static part cancels. This is the cost that no
    correlation policy measured in ``benchmarks/correlation_policy.py`` removes without
    losing more at ω_r = 1 (docs/estimators.md, "Measured: path correlation for homodyne cameras").

    Measured over seeds 0-5 (mean ± std of one seed): replay ÷ none 1.43 ± 0.092 at
    ω_r = 0 and 0.136 ± 0.013 at ω_r = 1. The test averages seeds 0 and 1 (± 0.065 at
    ω_r = 0): each bound is at least 4 standard deviations away."""
    ratios = np.mean([_correlation_ratios(seed, ReferenceCache(cache_dir)) for seed in (0, 1)], axis=0)
    assert 1.15 < ratios[0] < 1.75, ratios
    assert ratios[1] < 0.3, ratios


def test_an_experiment_stopped_by_sigterm_says_so_and_exits_143(tmp_path):
    """It was killed silently (exit -15) while every other command stops with a line."""
    import signal
    import time

    process = subprocess.Popen(
        [sys.executable, "-m", "dopplertof.cli", "experiment", "time-sampling", "cornell-box", "--resolution", "32", "--spp", "16",
         "--reference-spp", "65536", "--h-steps", "3", "--phases", "2", "-o", str(tmp_path / "e"), "--cache", str(tmp_path / "cache")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.time() + 120
    while time.time() < deadline and "reference: rendering" not in process.stdout.readline():
        pass
    time.sleep(1.0)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 143, stderr
    assert stderr.strip().splitlines()[-1].startswith("SIGTERM: stopped; no table was written")


def test_an_interrupted_reference_keeps_its_passes_and_the_next_run_continues_them(tmp_path, monkeypatch):
    """A 16384-spp reference stopped part way lost every pass (a fault trial): it now keeps
    them in the cache's checkpoint, and the next run continues to the same result."""
    import dopplertof as dt

    scene = open_scene("cornell-box", 8)
    cameras = [dt.Camera(heterodyne=1.0)]
    real = common.render
    stops = iter([False, False, True])
    monkeypatch.setattr(common, "render", lambda *a, **k: real(*a, stop=lambda: next(stops, True), **k))
    cache = ReferenceCache(tmp_path / "cache")
    args = (scene, cameras, 64, 0, 3, cache, lambda text: None)
    with pytest.raises(KeyboardInterrupt):
        common.reference_render(*args, lanes_per_pass=1024)
    key = cache.key(scene, cameras, 64, common.reference_seed(0), 3, common.REFERENCE_ESTIMATOR)
    assert cache.path(key, checkpoint=True).is_file() and not cache.path(key).exists()
    monkeypatch.setattr(common, "render", real)
    lines = []
    continued = common.reference_render(scene, cameras, 64, 0, 3, cache, lines.append, lanes_per_pass=1024)
    assert any("continuing its checkpoint" in line for line in lines)
    assert not cache.path(key, checkpoint=True).exists() and cache.path(key).is_file()
    whole = common.reference_render(scene, cameras, 64, 0, 3, ReferenceCache(tmp_path / "other"), lambda text: None, lanes_per_pass=1024)
    np.testing.assert_array_equal(continued.measurements, whole.measurements)
