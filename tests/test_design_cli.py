"""``dopplertof design``: sweeps and optimisation from the command line (a real subprocess)."""

import csv
import subprocess
from pathlib import Path
import sys

import numpy as np
import pytest

import dopplertof as dt
from test_faults import _render_until_progress

FAST = ["--resolution", "8", "--spp", "4", "--max-depth", "2"]
DOCS = Path(__file__).resolve().parents[1] / "docs"


def _run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_design_sweeps_optimises_and_writes_a_sensor_that_render_reads(tmp_path):
    out = tmp_path / "design"
    done = _run("design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=20e6:120e6:6", "--optimize", "phase", "--rmse-draws", "20", "-o", str(out), *FAST)
    assert done.returncode == 0, done.stderr
    assert "best of the sweep: modulation_frequency=" in done.stdout and "optimised (phase)" in done.stdout and "estimator RMSE" in done.stdout
    for name in ("velocity_crb", "depth_crb", "velocity_rmse"):
        assert dt.io.read_exr(out / f"{name}.exr").shape == (8, 8)
    with open(out / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["modulation_frequency"]) for r in rows] == [20e6, 40e6, 60e6, 80e6, 100e6, 120e6]
    assert all(r["status"] == "ok" and float(r["velocity_crb_mean"]) > 0 for r in rows[:5])
    assert rows[5]["status"].startswith("refused: D-ToF prototype") and "outside 1e+07 to 1e+08 Hz" in rows[5]["status"]  # the chip's 100 MHz
    assert (out / "sweep_modulation_frequency.png").stat().st_size > 0 and (out / "optimize.csv").exists()
    # the record is reused: the same sweep without a render gives the same numbers
    again = _run("design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=20e6:120e6:6", "--record", str(out / "record.npz"), "-o", str(tmp_path / "again"))
    assert again.returncode == 0, again.stderr
    assert (tmp_path / "again" / "sweep.csv").read_text() == (out / "sweep.csv").read_text()
    refused = _run("design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=20e6:120e6:6", "--record", str(out / "record.npz"), "-o", str(out))
    assert refused.returncode == 2 and refused.stderr.strip() == f"error: {str(out)!r} holds an earlier design run (record.npz, sweep.csv, optimize.csv, best_sensor.toml, velocity_crb.exr, depth_crb.exr, velocity_rmse.exr, sweep_modulation_frequency.png); choose another folder, --overwrite, or --resume to continue it"
    # a record is of its scene and its render: another scene, or render options beside it, are refused
    for args, says in [
        (["street"], "error: --record " + str(out / "record.npz") + ": rendered from the built-in scene 'cornell-box', not street (the built-in scene 'street')"),
        (["cornell-box", "--spp", "64", "--resolution", "32"], "error: --record: the record holds its render; --resolution, --spp would render another"),
    ]:  # fmt: skip
        other = _run("design", *args, "--sensor", "dtof-prototype", "--sweep", "f=20e6:120e6:6", "--record", str(out / "record.npz"), "-o", str(tmp_path / "other"))
        assert other.returncode == 2 and other.stderr.startswith(says), other.stderr
    rendered = _run("render", "cornell-box", "--sensor", str(out / "best_sensor.toml"), "-o", str(tmp_path / "render"), "--quiet", *FAST)
    assert rendered.returncode == 0, rendered.stderr
    assert (tmp_path / "render" / "raw_electrons.npy").exists()


def test_design_over_several_scenes_averages_their_objectives(tmp_path):
    sweep = ("--sweep", "f=20e6:60e6:3")
    both = _run("design", "cornell-box", "rotating", "--sensor", "dtof-prototype", *sweep, "--optimize", "phase", "-o", str(tmp_path / "both"), *FAST)
    assert both.returncode == 0, both.stderr
    assert "best sensor on cornell-box:" in both.stdout and "best sensor on rotating:" in both.stdout
    for name in ("record_0.npz", "record_1.npz", "velocity_crb_0.exr", "depth_crb_1.exr", "sweep.csv", "optimize.csv", "best_sensor.toml"):
        assert (tmp_path / "both" / name).exists(), name

    def objectives(folder):
        with open(folder / "sweep.csv", newline="") as f:
            return [float(r["objective"]) for r in csv.DictReader(f)]

    # each scene alone, from its own record: the two-scene objective is their mean
    alone = []
    for index, scene in enumerate(("cornell-box", "rotating")):
        done = _run("design", scene, "--sensor", "dtof-prototype", *sweep, "--record", str(tmp_path / "both" / f"record_{index}.npz"), "-o", str(tmp_path / scene))
        assert done.returncode == 0, done.stderr
        alone.append(objectives(tmp_path / scene))
    assert alone[0] != alone[1]
    assert objectives(tmp_path / "both") == pytest.approx([(a + b) / 2 for a, b in zip(*alone)], rel=1e-6)
    refused = _run("design", "cornell-box", "rotating", "--sensor", "dtof-prototype", *sweep, "--record", str(tmp_path / "both" / "record_0.npz"), "-o", str(tmp_path / "o"))
    assert refused.returncode == 2 and refused.stderr.strip() == "error: --record: give one per scene (2 scene(s), 1 record(s))"


def test_design_over_the_scenes_of_a_dataset_configuration(tmp_path):
    config = tmp_path / "my.toml"
    config.write_text("")  # the defaults
    out = tmp_path / "dataset"
    done = _run("design", "--dataset", str(config), "--samples", "2", "--dataset-seed", "3", "--sensor", "dtof-prototype", "--sweep", "f=20e6:60e6:3", "-o", str(out), *FAST)
    assert done.returncode == 0, done.stderr
    assert "best sensor on sample-00000000:" in done.stdout and "best sensor on sample-00000001:" in done.stdout
    assert (out / "record_0.npz").exists() and (out / "record_1.npz").exists() and (out / "sweep.csv").exists()
    # the scenes are the dataset's own: record 1 holds the depth of sample 1 of seed 3, not of sample 0
    from dopplertof.backend import ensure_variant
    from dopplertof.dataset.config import load_config
    from dopplertof.dataset.randomize import build_scene
    from dopplertof.dataset.sample import make_record

    depth = dt.io.read_record(out / "record_1.npz").maps["depth"]
    for index, same in ((1, True), (0, False)):
        scene = build_scene(make_record(load_config(config), 3, index, ensure_variant())["scene"], 8)
        direct = dt.render(scene, cameras=[dt.Camera(exposure=1.5e-3)], spp=4, max_depth=2).depth
        assert np.array_equal(direct, depth, equal_nan=True) == same
    missing = _run("design", "--dataset", str(config), "--sensor", "dtof-prototype", "--sweep", "f=20e6:60e6:3", "-o", str(tmp_path / "o"))
    assert missing.returncode == 2 and missing.stderr.strip() == "error: --dataset needs --samples N (how many of its scenes)"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--sensor", "dtof-prototype"], "give --sweep"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1:2"], "KEY=LO:HI:N"),
        (["--sensor", "dtof-prototype", "--sweep", "gain=1:2:2"], "unknown key 'gain'"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1e7:2e7:2", "--sweep", "f=3e7:4e7:2"], "each key once"),
        (["--sensor", "nosuchchip", "--sweep", "f=1e7:2e7:2"], "neither a preset"),
        (["--sensor", "dtof-prototype", "--optimize", "gain"], "'gain' is not one of"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1e7:2e7:2", "--record", "missing.npz"], "missing.npz"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1e7:2e7:2", "--dataset", "my.toml", "--samples", "2"], "give SCENE… or --dataset, not both"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1e7:2e7:2", "--samples", "2"], "--samples applies to --dataset"),
        # a sensor design trial's findings: each was a misleading answer or message, or came after the render
        (["--sensor", "dtof-prototype", "--sweep", "f=-10e6:100e6:10"], "modulation_frequency must be > 0 (Hz), LO is -1e+07"),
        (["--sensor", "dtof-prototype", "--sweep", "f=10e6:100e6:8"], "its points are 12857142.86 Hz apart"),
        (["--sensor", "dtof-prototype", "--sweep", "f=1e7:2e7:2", "--rmse-draws", "1"], "--rmse-draws: 0 (none) or at least 2"),
        (["--sensor", "mlx75027_square.toml", "--sweep", "h=0.5:1:2"], "every point of the sweep is refused, e.g. the sensor has no heterodyne frame"),
        (["--sensor", "custom.toml", "--optimize", "modulation_frequency"], "the sensor has no frequency range to search"),
        (["--sensor", "kinect-v2", "--sweep", "T=0.5e-3:1e-3:2", "--objective", "depth_crb"], "(the frame's modulation_frequency); give the sensor whole-Hz frequencies"),
    ],
)
def test_design_refuses_bad_input_with_one_error_line(tmp_path, args, message):
    (tmp_path / "custom.toml").write_text("taps = 2\n[[frames]]\nmodulation_frequency = 30e6\nheterodyne = 1.0\n[[frames]]\nmodulation_frequency = 30e6\n")
    (tmp_path / "mlx75027_square.toml").write_text((DOCS / "mlx75027_square.toml").read_text())
    done = _run("design", "cornell-box", *args, "-o", str(tmp_path / "o"), *FAST, cwd=tmp_path)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert lines[-1].startswith("error:") and message in lines[-1], done.stderr
    assert all(not line.startswith("error:") and "Traceback" not in line for line in lines[:-1]), done.stderr
    assert not (tmp_path / "o").exists()  # a refused run leaves no empty folder


def test_render_until_noise_reports_the_spp_it_took(tmp_path):
    sensor = tmp_path / "dim.toml"
    sensor.write_text('preset = "dtof-prototype"\n\n[silicon]\nradiance_unit = 1e-3\n')
    args = ["--sensor", str(sensor), "--resolution", "8", "--max-depth", "2", "--spp", "1024", "--lanes-per-pass", "1024", "--quiet"]
    done = _run("render", "cornell-box", "--until-noise", "0.5", "-o", str(tmp_path / "r"), *args)
    assert done.returncode == 0, done.stderr
    line = next(x for x in done.stdout.splitlines() if x.startswith("until-noise"))
    assert "until-noise 0.5 reached" in line
    spp = int(line.split(" at ")[1].split()[0])
    assert 0 < spp < 1024 and f"rendered cornell-box at {spp} spp" in done.stdout


def test_render_help_writes_the_until_noise_quantile_as_a_percentage():
    done = _run("render", "--help")
    assert done.returncode == 0 and "95% of the pixels" in " ".join(done.stdout.split()) and "%%" not in done.stdout


@pytest.mark.parametrize("args, message", [(["--until-noise", "0.5"], "give --sensor"), (["--sensor", "dtof-prototype", "--until-noise", "-1"], "error: until_noise=-1.0: must be > 0")])
def test_render_until_noise_refuses_bad_input(tmp_path, args, message):
    done = _run("render", "cornell-box", *args, "-o", str(tmp_path / "o"), *FAST)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0], done.stderr


STATIC_SCENE = """<scene version="3.0.0">
    <sensor type="perspective"> <float name="fov" value="40"/>
        <transform name="to_world"> <lookat origin="0 0 4" target="0 0 0" up="0 1 0"/> </transform>
        <film type="hdrfilm"> <integer name="width" value="8"/> <integer name="height" value="8"/> </film>
    </sensor>
    <emitter type="point"> <point name="position" value="0 0 4"/> <rgb name="intensity" value="10"/> </emitter>
    <shape type="rectangle"> <bsdf type="diffuse"/> </shape>
</scene>
"""


@pytest.mark.parametrize("objective", ["velocity_crb", "depth_crb"])
def test_design_of_a_scene_where_nothing_moves_says_so(tmp_path, objective):
    (tmp_path / "static.xml").write_text(STATIC_SCENE)
    done = _run("design", "static.xml", "--sensor", "dtof-prototype", "--sweep", "f=10e6:100e6:2", "--objective", objective, "-o", "d", *FAST, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == "error: static.xml: no moving pixel (the ground-truth velocity is zero everywhere in the exposure); the design's objective is the mean bound over the moving pixels"


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_design_interrupted_keeps_its_passes_and_resumes_to_the_same_record(tmp_path, signame):
    """A signal while the record renders kept nothing: every rendered pass was lost. Its
    sums are now in record.checkpoint.npz, and --resume finishes the same record (and so the
    same sweep) as an uninterrupted run."""
    import signal

    # a record long enough to be interrupted while it renders (8 M paths in 32 passes)
    design = ["design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=10e6:100e6:4", "--resolution", "32", "--spp", "8192", "--lanes-per-pass", "262144"]
    process, finish = _render_until_progress([*design, "-o", str(tmp_path / "o")], r"\|\s*([1-9]\d*)/32")  # a pass is done
    process.send_signal(getattr(signal, signame))
    stderr = finish()
    assert process.returncode == 128 + getattr(signal, signame), stderr
    assert stderr.strip().splitlines()[-1] == "error: interrupted before the record was finished; kept the rendered passes in record.checkpoint.npz: continue with the same command and --resume"
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["record.checkpoint.npz"]
    again = _run(*design, "-o", "o", cwd=tmp_path)
    assert again.returncode == 2 and again.stderr.strip() == "error: 'o' holds an earlier design run (record.checkpoint.npz); choose another folder, --overwrite, or --resume to continue it"
    if signame == "SIGINT":
        return
    resumed = _run(*design, "-o", "o", "--resume", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert "continuing record.checkpoint.npz" in resumed.stderr and not (tmp_path / "o" / "record.checkpoint.npz").exists()
    whole = _run(*design, "-o", "whole", cwd=tmp_path)
    assert whole.returncode == 0, whole.stderr
    assert (tmp_path / "o" / "sweep.csv").read_text() == (tmp_path / "whole" / "sweep.csv").read_text()
    records = [dt.io.read_record(tmp_path / folder / "record.npz") for folder in ("o", "whole")]
    np.testing.assert_array_equal(records[0].phasors, records[1].phasors)
    # a finished record is read, not rendered again; one of another render is refused
    reread = _run(*design, "-o", "o", "--resume", cwd=tmp_path)
    assert reread.returncode == 0 and "rendering the record" not in reread.stderr, reread.stderr
    other = _run(*[a if a != "8192" else "4096" for a in design], "-o", "o", "--resume", cwd=tmp_path)
    assert other.returncode == 2 and other.stderr.strip().startswith("error: --resume: o/record.npz was rendered by another command"), other.stderr


def test_design_interrupted_in_its_sweep_stops_at_once_and_names_what_is_kept(tmp_path):
    """SIGTERM while the sweep runs (the record read from a file): it was ignored until the
    end, or killed the process silently; now exit 143 and one line."""
    import signal
    import time

    sweeps = ["--sweep", "f=10e6:100e6:91", "--sweep", "T=0.5e-3:1.5e-3:101"]
    design = [sys.executable, "-m", "dopplertof.cli", "design", "cornell-box", "--sensor", "dtof-prototype", *sweeps]
    maker = subprocess.Popen([*design, "--resolution", "8", "--spp", "8", "-o", "r"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    deadline = time.monotonic() + 120
    while not (tmp_path / "r" / "record.npz").exists() and maker.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    maker.send_signal(signal.SIGTERM)  # its record is written (atomically): its own sweep is not needed
    _, made = maker.communicate(timeout=120)
    assert (tmp_path / "r" / "record.npz").exists(), made
    process = subprocess.Popen(
        [*design, "--record", "r/record.npz", "-o", "s"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
    )  # fmt: skip
    deadline = time.monotonic() + 120  # the sweep (9191 points) takes seconds: a signal once it starts lands in it
    while time.monotonic() < deadline and (line := process.stderr.readline()) and not line.startswith("sweeping 9191 point(s) of modulation_frequency x exposure over 1 record(s)"):
        pass
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 143, stderr
    assert stderr.strip().splitlines()[-1] == "error: interrupted after the records were read; nothing written"
    assert not (tmp_path / "s" / "sweep.csv").exists()
