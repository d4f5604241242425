"""A new user's first hour (issue 9): bad input, output folders, signals, resume, memory."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import dopplertof as dt
from dopplertof import io

DATA = os.path.join(os.path.dirname(__file__), "data")
ORIGINAL_CORNELL = os.path.join(DATA, "original_cornell.xml")


def _cli(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True, text=True, **kwargs)


def _one_error_line(run, match):
    assert run.returncode == 2, (run.returncode, run.stdout, run.stderr)
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), run.stderr
    assert match in lines[0], lines[0]


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


SCENE_XML = """<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="4"/></film>
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler></sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="0"/><rgb name="intensity" value="1"/></emitter>
  <shape type="rectangle"><transform name="to_world"><translate z="-3"/></transform>{extra}</shape>
</scene>"""


@pytest.mark.parametrize(
    "args, match",
    [
        (["--camera", "low_pass=flase"], "low_pass' must be true or false, got 'flase'"),
        (["--camera", "f=1e300"], "modulation_frequency must be in (0, 1e+12] Hz"),
        (["--camera", ""], "camera '': empty"),
        (["--camera", "h=1,h=0"], "'h' given twice"),
        (["--correlation", "none", "--correlation-depth", "3"], "'correlation_depth' applies to replay"),
        (["--reconnection-threshold", "0.3"], "'reconnection_threshold' applies to adaptive"),
        (["--seed", str(2**32)], "'seed' must be < 2**32"),
        (["--max-depth", "2.5"], "'2.5' is not a valid integer"),
        (["--spp", "0"], "'spp' must be >= 1"),
        (["--resolution", "0"], "expected N or WxH"),
        (["--resolution", "50000"], "needs about"),
        (["--time-sampling", "mirror"], "'mirror' is not one of"),
        (["--bogus"], "No such option '--bogus'"),
        (["-D", "nonsense"], "expected name=value"),
    ],
)
def test_bad_command_line_input_is_one_error_line(tmp_path, args, match):
    _one_error_line(_cli("render", "cornell-box", "--resolution", "8", "-o", str(tmp_path / "out"), *args), match)
    assert not (tmp_path / "out" / "metadata.json").exists()


@pytest.mark.parametrize(
    "w, spp, extra, match",
    [
        (4, 0, "", "'spp' must be >= 1"),
        (0, 4, "", "at least 1x1"),
        (4, 4, '<bsdf type="diffuse"><boolean name="x" value="maybe"/></bsdf>', "maybe"),
    ],
)
def test_bad_scene_files_are_one_error_line(tmp_path, w, spp, extra, match):
    path = _write(tmp_path, "s.xml", SCENE_XML.format(w=w, spp=spp, extra=extra))
    _one_error_line(_cli("render", path, "-o", str(tmp_path / "out"), "--quiet"), match)


def test_the_api_names_bad_values():
    with pytest.raises(ValueError, match="'low_pass' must be a boolean"):
        dt.Camera(low_pass="false")
    with pytest.raises(ValueError, match="modulation_frequency must be in"):
        dt.Camera(modulation_frequency=1e300)


# ------------------------------------------------------------------------------ output folders


def test_output_folder_problems_are_found_before_rendering(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    _one_error_line(_cli("render", "cornell-box", "-o", str(a_file)), "exists and is not a folder")
    _one_error_line(_cli("render", "cornell-box", "-o", str(a_file / "sub")), "which is a file")
    if os.geteuid() != 0:  # root writes anywhere; the read-only case is covered by the next test
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        _one_error_line(_cli("render", "cornell-box", "-o", str(locked / "o")), "not writable")


def test_a_read_only_file_system_is_one_error_line(tmp_path):
    if not os.path.exists("/proc/self/mountinfo"):
        pytest.skip("needs Linux")
    readonly = next((line.split()[4] for line in open("/proc/self/mountinfo") if " ro," in f" {line.split()[5]},"), None)
    if readonly is None:
        readonly = "/proc/sys"  # read-only for writes of files even as root
    _one_error_line(_cli("render", "cornell-box", "--resolution", "8", "-o", os.path.join(readonly, "dopplertof-out")), "not writable")


def test_a_used_folder_is_refused_unless_overwrite(tmp_path):
    out = str(tmp_path / "o")
    common = ["--resolution", "8", "--spp", "2", "-o", out, "--quiet"]
    assert _cli("render", "cornell-box", *common, "--camera", "h=1").returncode == 0
    (tmp_path / "o" / "mine.txt").write_text("keep me")
    _one_error_line(_cli("render", "cornell-box", *common), "holds another render's files")
    assert _cli("render", "cornell-box", *common, "--overwrite").returncode == 0
    names = set(os.listdir(out))
    assert "mine.txt" in names and not any(n.startswith("measurement_") for n in names)


# ------------------------------------------------------------------------------ signals, faults and resume

# 64² × 256 spp in 256 passes of 4096 lanes (two tiles of 2048 pixels × 2 spp), with a progress bar.
_LONG_RENDER = ["render", "cornell-box", "--resolution", "64", "--spp", "256", "--lanes-per-pass", "4096", "--camera", "h=1", "--seed", "3"]
_KILLABLE = [*_LONG_RENDER, "--quiet"]
_EXRS = ("intensity.exr", "stderr.exr", "depth.exr", "velocity.exr", "measurement_0_h1_psi0deg.exr", "measurement_0_h1_psi0deg_stderr.exr")


def _render_until_progress(args, pattern):
    """Start the CLI with ``args``; return once its stderr (the progress bar) matches the
    regular expression ``pattern``: (process, a function that waits for it to end and returns
    its whole stderr)."""
    import re
    import threading

    proc = subprocess.Popen([sys.executable, "-m", "dopplertof.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen, matched = [], threading.Event()

    def read():
        while (char := proc.stderr.read(1)):
            seen.append(char)
            if not matched.is_set() and re.search(pattern, "".join(seen[-40:])):
                matched.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    assert matched.wait(timeout=300), "".join(seen)

    def finish():
        proc.wait(timeout=300)
        reader.join(timeout=10)
        return "".join(seen)

    return proc, finish


def _interrupt(tmp_path, sig, name, extra=()):
    """Start a render (``extra``: more arguments), send ``sig`` once its progress bar shows
    a finished pass; the finished process's status, its stderr, the output folder and the
    arguments."""
    out = tmp_path / name
    args = [*_LONG_RENDER, "-o", str(out), *extra]
    proc, finish = _render_until_progress(args, r"\|\s*([1-9]\d*)/\d+")
    proc.send_signal(sig)
    stderr = finish()
    return proc.returncode, stderr, out, [*args, "--quiet"]


@pytest.mark.parametrize("after_s", [0.05, 0.15])
def test_ctrl_c_while_the_command_loads_is_one_line(tmp_path, after_s):
    """Ctrl-C while a render command loads (its imports, Mitsuba's among them, take most of
    a second; 0.05 s is inside the package's own import): one line and exit status 130, as
    later on, not a traceback (a KeyboardInterrupt raised inside an import). (The ``scenes``
    command, once used here, ends in 0.15 s on a fast machine: Ctrl-C then lands while
    Python exits.)"""
    command = Path(sys.executable).with_name("dopplertof")
    args = [str(command), "render", "cornell-box", "--resolution", "8", "--spp", "2", "-o", str(tmp_path / "out"), "--quiet"]
    run = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(after_s)
    run.send_signal(signal.SIGINT)
    out, err = run.communicate(timeout=60)
    assert run.returncode == 130 and err.strip().startswith("error:") and len(err.strip().splitlines()) == 1, (run.returncode, err)
    assert not (tmp_path / "out" / "metadata.json").exists()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP], ids=["SIGTERM", "SIGINT", "SIGHUP"])
def test_a_signal_keeps_the_work_and_resume_is_bit_identical(tmp_path, uninterrupted, sig):
    status, stderr, out, args = _interrupt(tmp_path, sig, "interrupted")
    assert status == 128 + sig, stderr
    assert "--resume" in stderr
    assert re.search(r": stopped after \d+ of \d+ passes, at \d+ of 256 spp; partial result and checkpoint in", stderr), stderr  # (a pass of part of the film said "at 0 of 256 spp")
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["interrupted"] and 0 < meta["spp"] < 256
    assert (out / "checkpoint.npz").exists()
    partial = io.read_exr(out / "intensity.exr")
    assert np.isfinite(partial).all()
    resumed = _cli(*args, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "checkpoint.npz").exists()
    _assert_same_as_an_uninterrupted_render(uninterrupted, out)




def _passes_in_checkpoint(path):
    with np.load(path) as data:
        return int(data["passes_done"][0])


def _start_and_wait_for_a_checkpoint(out):
    """A render into ``out`` saving a checkpoint after every pass; returns the process once
    the first checkpoint is there."""
    proc = subprocess.Popen([sys.executable, "-m", "dopplertof.cli", *_KILLABLE, "-o", str(out), "--checkpoint-interval", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 300
    while not (out / "checkpoint.npz").exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no checkpoint after 300 s"
        time.sleep(0.01)
    return proc


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The output folder of ``_KILLABLE`` rendered without a fault, once for the tests that
    resume it."""
    whole = tmp_path_factory.mktemp("uninterrupted") / "out"
    run = _cli(*_KILLABLE, "-o", str(whole))
    assert run.returncode == 0, run.stderr
    return whole


def _assert_same_as_an_uninterrupted_render(whole, out):
    for name in _EXRS:
        np.testing.assert_array_equal(io.read_exr(out / name), io.read_exr(whole / name), err_msg=name)


@pytest.mark.slow
def test_sigkill_loses_at_most_the_checkpoint_interval_and_resume_is_bit_identical(tmp_path, uninterrupted):
    out = tmp_path / "killed"
    proc = _start_and_wait_for_a_checkpoint(out)
    proc.kill()
    proc.wait(timeout=60)
    assert not (out / "metadata.json").exists()
    kept = _passes_in_checkpoint(out / "checkpoint.npz")
    assert 0 < kept < 256
    (out / f".checkpoint.{2**22 + 1}.partial.npz").write_bytes(b"half")  # what a kill mid-save leaves (no such process id)
    _one_error_line(_cli(*_KILLABLE, "-o", str(out)), "continue it with --resume")
    resumed = _cli(*_KILLABLE, "-o", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "checkpoint.npz").exists() and not [p for p in os.listdir(out) if ".partial" in p]
    _assert_same_as_an_uninterrupted_render(uninterrupted, out)


@pytest.fixture
def small_disk(tmp_path):
    """A 16 MiB tmpfs (needs root); unmounted after the test."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    mount = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs", str(disk)], capture_output=True, text=True)
    if mount.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {mount.stderr.strip()}")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


@pytest.mark.slow
def test_a_disk_that_fills_mid_render_keeps_the_checkpoint_and_resume_is_bit_identical(tmp_path, uninterrupted, small_disk):
    import errno

    out = small_disk / "out"
    # Another program fills the disk, and keeps it full, until the render gives up. Its file
    # is opened before the render starts: opened after, it could find the disk full for a
    # moment (a checkpoint being saved holds two copies) and fail before the render does.
    with open(small_disk / "filler", "wb") as filler:
        proc = _start_and_wait_for_a_checkpoint(out)
        while proc.poll() is None:
            try:
                filler.write(b"\0" * 65536)
                filler.flush()
            except OSError as exc:
                assert exc.errno == errno.ENOSPC
                time.sleep(0.005)
    stdout, stderr = proc.communicate()
    _one_error_line(subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), "No space left on device")
    assert "passes is kept" in stderr and "--resume" in stderr
    kept = _passes_in_checkpoint(out / "checkpoint.npz")
    assert 0 < kept < 256, stderr
    os.remove(small_disk / "filler")
    resumed = _cli(*_KILLABLE, "-o", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "checkpoint.npz").exists()
    _assert_same_as_an_uninterrupted_render(uninterrupted, out)


def test_a_dataset_on_a_full_disk_is_one_error_line_and_leaves_no_partial_shard(small_disk):
    free = os.statvfs(small_disk).f_bavail * os.statvfs(small_disk).f_frsize
    with open(small_disk / "filler", "wb") as filler:  # room for the manifest, not for a shard
        filler.write(b"\0" * (free - 256 * 1024))
    out = small_disk / "ds"
    run = _cli("dataset", "generate", "-o", str(out), "--samples", "2", "--shard-size", "1", "--resolution", "64", "--spp", "4", "--quiet")
    _one_error_line(run, f"cannot write {str(out)!r}: No space left on device")
    assert "run the same command again" in run.stderr
    assert not [p for p in os.listdir(out) if ".partial" in p or p.endswith(".tar")]  # no half-written shard left behind


@pytest.mark.slow
def test_a_disk_that_fills_while_the_images_are_written_keeps_the_rendered_sums(tmp_path, uninterrupted, small_disk):
    """The render finishes, its checkpoint is saved, then the disk is too full for the images:
    one error line, and --resume writes them without rendering again."""
    from dopplertof.render import checkpoint_disk_bytes

    out = small_disk / "out"
    # The bar shows once the folder is checked and the render runs.
    proc, finish = _render_until_progress([*_LONG_RENDER, "-o", str(out), "--checkpoint-interval", "3600"], r"/256")
    checkpoint_bytes = checkpoint_disk_bytes(64, 64, dt.RenderSettings(cameras=(dt.Camera(heterodyne=1),))) // 2  # one copy, + npz headers (< 64 KiB)
    free = os.statvfs(small_disk).f_bavail * os.statvfs(small_disk).f_frsize
    with open(small_disk / "filler", "wb") as filler:  # room for the checkpoint and 64 KiB more
        filler.write(b"\0" * (free - checkpoint_bytes - 65536))
    stderr = finish()
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if line.startswith("error:")]
    assert proc.returncode == 2 and len(lines) == 1 and "No space left on device" in lines[0] and "--resume" in lines[0], stderr
    assert "Traceback" not in stderr
    assert _passes_in_checkpoint(out / "checkpoint.npz") == 256 and not (out / "metadata.json").exists()
    os.remove(small_disk / "filler")
    resumed = _cli(*_KILLABLE, "-o", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "checkpoint.npz").exists()
    _assert_same_as_an_uninterrupted_render(uninterrupted, out)


def test_a_checkpoint_is_continued_only_by_the_scene_it_was_made_of(tmp_path, monkeypatch):
    """The checkpoint knew a scene by its source: every built-in is "<dict>" (a render of
    cornell-box resumed as cornell-box-area mixed the two), a file by its path as typed (an
    edited file or other -D values were mixed in, the same file by another path refused)."""
    checkpoint = tmp_path / "c.npz"
    settings = dict(spp=4, checkpoint=checkpoint, keep_checkpoint=True)
    dt.render(dt.scenes.build("cornell-box", resolution=8), **settings)
    with pytest.raises(ValueError, match=r'another scene \(scene.builtin: "cornell-box" in the checkpoint, "cornell-box-area" now; scene.content_sha256 \(changed\)\)'):
        dt.render(dt.scenes.build("cornell-box-area", resolution=8), **settings)
    checkpoint.unlink()
    path = tmp_path / "scene.xml"
    path.write_text(Path(DATA, "readme_scene.xml").read_text().replace('<rgb name="intensity" value="20"/>', '<rgb name="intensity" value="$power"/>'))
    dt.render(dt.load_scene(str(path), film_resolution=8, power="20"), **settings)
    monkeypatch.chdir(tmp_path)  # the same file by another path: continued
    dt.render(dt.load_scene("scene.xml", film_resolution=8, power="20"), **settings)
    with pytest.raises(ValueError, match="scene.content_sha256"):  # another $power
        dt.render(dt.load_scene(str(path), film_resolution=8, power="30"), **settings)
    path.write_text(path.read_text().replace('value="0.8 0.3 0.2"', 'value="0.8 0.3 0.3"'))
    with pytest.raises(ValueError, match="scene.content_sha256"):  # the file edited
        dt.render(dt.load_scene(str(path), film_resolution=8, power="20"), **settings)


def test_a_checkpoint_interval_is_honoured_or_refused(tmp_path):
    scene = dt.scenes.build("cornell-box", resolution=16)  # 256 pixels x 8 spp: two passes of 1024 lanes
    checkpoint = tmp_path / "c.npz"
    seen = []

    def stop():  # called before each pass: what the checkpoint holds then
        seen.append(_passes_in_checkpoint(checkpoint) if checkpoint.exists() else 0)
        return False

    whole = dt.render(scene, spp=8, lanes_per_pass=1024, checkpoint=checkpoint, checkpoint_interval_s=0, keep_checkpoint=True, stop=stop)
    assert seen == [0, 1] and _passes_in_checkpoint(checkpoint) == 2
    resumed = dt.render(scene, spp=8, lanes_per_pass=1024, checkpoint=checkpoint)  # complete: nothing left to render
    np.testing.assert_array_equal(resumed.intensity, whole.intensity)
    assert not checkpoint.exists()
    seen.clear()
    dt.render(scene, spp=8, lanes_per_pass=1024, checkpoint=checkpoint, checkpoint_interval_s=3600, stop=stop)
    assert seen == [0, 0] and not checkpoint.exists()
    for bad in (-1.0, float("nan"), "60"):
        with pytest.raises(ValueError, match="'checkpoint_interval_s' must be"):
            dt.render(scene, spp=8, checkpoint=checkpoint, checkpoint_interval_s=bad)
    _one_error_line(_cli("render", "cornell-box", "--resolution", "8", "-o", str(tmp_path / "o"), "--checkpoint-interval", "-5"), "'checkpoint_interval_s' must be >= 0 seconds, got -5.0")


def test_stopping_at_once_inside_an_update_keeps_the_last_checkpoint_not_a_torn_pass(tmp_path, monkeypatch):
    """A second Ctrl-C raises KeyboardInterrupt wherever the code is, also half-way through
    adding a pass to the sums: the render falls back to the last checkpoint."""
    from dopplertof.passes import Accumulator

    scene = dt.scenes.build("cornell-box", resolution=16)  # 256 pixels x 16 spp: four passes of 1024 lanes
    checkpoint = tmp_path / "c.npz"
    apply = Accumulator.apply
    calls = iter(range(100))

    def torn_third_pass(self, p, inc):
        if next(calls) == 2:
            self.applying = True
            self.state["group_sum"][:, p.pixel_start : p.pixel_start + p.n_pixels] += 1.0  # half the update
            raise KeyboardInterrupt
        apply(self, p, inc)

    monkeypatch.setattr(Accumulator, "apply", torn_third_pass)
    with pytest.raises(KeyboardInterrupt):  # no checkpoint yet: nothing is kept, nothing torn is saved
        dt.render(scene, spp=16, lanes_per_pass=1024, checkpoint=checkpoint, checkpoint_interval_s=3600)
    assert not checkpoint.exists()
    calls = iter(range(100))
    partial = dt.render(scene, spp=16, lanes_per_pass=1024, checkpoint=checkpoint, checkpoint_interval_s=0)
    assert partial.interrupted and partial.info["passes_done"] == 2 and _passes_in_checkpoint(checkpoint) == 2
    monkeypatch.setattr(Accumulator, "apply", apply)
    stops = iter(range(100))
    two_passes = dt.render(scene, spp=16, lanes_per_pass=1024, stop=lambda: next(stops) >= 2)
    np.testing.assert_array_equal(partial.intensity, two_passes.intensity)
    resumed = dt.render(scene, spp=16, lanes_per_pass=1024, checkpoint=checkpoint)
    whole = dt.render(scene, spp=16, lanes_per_pass=1024)
    np.testing.assert_array_equal(resumed.intensity, whole.intensity)
    np.testing.assert_array_equal(resumed.stderr, whole.stderr)


@pytest.mark.parametrize("loop", ["path", "reduction"])
def test_an_interrupt_while_drjit_traces_a_pass_stops_the_render_like_any_other(monkeypatch, loop):
    """Ctrl-C (or a dataset's SIGTERM) handled while Dr.Jit traces a loop of the pass (the
    path loop, the reduction's loop) raises inside the traced body, and Dr.Jit wraps it in a
    RuntimeError: the render must still see the interrupt and keep its finished passes (CI
    once saw a traceback and exit 1 here)."""
    from dopplertof.passes import Accumulator, Reducer

    scene = dt.scenes.build("cornell-box", resolution=16)
    applied, calls = [], []
    apply = Accumulator.apply
    # the first intersection of a pass is traced before the path loop, the second inside it;
    # a group's mean is first taken inside the reduction's loop (whole strata)
    owner, name, nth = (type(scene), "intersect", 2) if loop == "path" else (Reducer, "_group_mean", 1)
    original = getattr(owner, name)

    def counting(self, p, inc):
        apply(self, p, inc)
        applied.append(p)

    def interrupted_in_the_third_pass(self, *args, **kwargs):
        calls.append(len(applied))
        if calls.count(2) == nth:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Accumulator, "apply", counting)
    monkeypatch.setattr(owner, name, interrupted_in_the_third_pass)
    partial = dt.render(scene, spp=16, lanes_per_pass=1024)
    assert partial.interrupted and partial.info["passes_done"] == 2
    monkeypatch.setattr(owner, name, original)
    stops = iter(range(100))
    np.testing.assert_array_equal(partial.intensity, dt.render(scene, spp=16, lanes_per_pass=1024, stop=lambda: next(stops) >= 2).intensity)


def test_a_stopped_animation_frame_continues_from_its_checkpoint(tmp_path):
    from dopplertof import animate

    scene = dt.scenes.build("cornell-box", resolution=16)  # 256 pixels x 8 spp: two passes of 1024 lanes per frame
    settings = dt.RenderSettings(cameras=tuple(animate.default_cameras()), spp=8, lanes_per_pass=1024)
    common = dict(frames=2, fps=30.0, settings=settings, progress=False, log=lambda line: None)
    calls = iter(range(100))
    with pytest.raises(animate.AnimationStopped):  # frame 0 whole, frame 1 stopped after its first pass
        animate.render_animation(scene, str(tmp_path / "a"), stop=lambda: next(calls) == 3, **common)
    assert animate.is_done(str(tmp_path / "a"), 0) and not animate.is_done(str(tmp_path / "a"), 1)
    frame_1 = tmp_path / "a" / "frame_0001"
    assert _passes_in_checkpoint(frame_1 / "checkpoint.npz") == 1
    passes = []
    animate.render_animation(scene, str(tmp_path / "a"), stop=lambda: passes.append(1) and False, **common)
    assert len(passes) == 1  # frame 0 done, frame 1 continued with its second pass
    animate.render_animation(scene, str(tmp_path / "b"), **common)
    assert not [p for p in os.listdir(frame_1) if p.startswith("checkpoint")]
    for name in ("measurement_3_h1_psi90deg.exr", "intensity.exr", "velocity_reconstructed.exr"):
        np.testing.assert_array_equal(io.read_exr(frame_1 / name), io.read_exr(tmp_path / "b" / "frame_0001" / name), err_msg=name)


def test_a_resume_with_other_settings_is_refused(tmp_path):
    scene = dt.scenes.build("cornell-box", resolution=16)  # 256 pixels x 8 spp: two passes of 1024 lanes
    checkpoint = str(tmp_path / "c.npz")
    calls = iter(range(100))
    partial = dt.render(scene, spp=8, lanes_per_pass=1024, checkpoint=checkpoint, stop=lambda: next(calls) >= 1)
    assert partial.interrupted and os.path.exists(checkpoint)
    with pytest.raises(ValueError, match=r"other settings or another scene \(seed: 0 in the checkpoint, 1 now\)"):
        dt.render(scene, spp=8, seed=1, lanes_per_pass=1024, checkpoint=checkpoint)
    with pytest.raises(ValueError, match=r"\(spp: 8 in the checkpoint, 16 now\)"):
        dt.render(scene, spp=16, lanes_per_pass=1024, checkpoint=checkpoint)
    resumed = dt.render(scene, spp=8, lanes_per_pass=1024, checkpoint=checkpoint)
    whole = dt.render(scene, spp=8, lanes_per_pass=1024)
    np.testing.assert_array_equal(resumed.intensity, whole.intensity)
    np.testing.assert_array_equal(resumed.stderr, whole.stderr)
    assert not os.path.exists(checkpoint)


# ------------------------------------------------------------------------------ memory


@pytest.mark.slow
def test_a_large_film_renders_in_bounded_memory(tmp_path):
    """2048² at 2 spp with small passes: the peak is the film's buffers, not the lanes.

    The peak is the child's own VmHWM: getrusage's ru_maxrss survives exec, so a child
    started from a large pytest process would report the parent's peak."""
    code = (
        "import dopplertof as dt\n"
        "s = dt.scenes.build('cornell-box', resolution=2048)\n"
        "r = dt.render(s, spp=2, lanes_per_pass=1 << 18)\n"
        "hwm_kib = next(line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:'))\n"
        "print(int(hwm_kib) * 1024)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr
    peak = int(run.stdout.split()[-1])
    assert peak < 2.5 * 2**30, f"peak {peak / 2**30:.2f} GiB"


# ------------------------------------------------------------------------------ help and metadata


def test_help_lists_every_setting():
    text = _cli("render", "--help").stdout
    from dopplertof.settings import FIELDS

    for name in FIELDS:
        if name != "cameras":
            assert "--" + name.replace("_", "-") in text, name


def test_the_command_line_starts_without_the_heavy_libraries():
    code = "import sys, dopplertof.cli; print(sorted(m for m in ('mitsuba', 'drjit', 'matplotlib') if m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "[]"


def test_metadata_records_the_render(tmp_path):
    out = tmp_path / "o"
    assert _cli("render", "cornell-box", "--resolution", "8", "--spp", "4", "--camera", "h=1", "-o", str(out), "--quiet").returncode == 0
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["scene"] == {"builtin": "cornell-box", "resolution": "8"}
    assert meta["film"] == [8, 8] and meta["spp"] == meta["spp_requested"] == 4
    assert set(meta["versions"]) >= {"dopplertof", "mitsuba", "drjit", "variant", "device"}
    assert meta["render"]["render_seconds"] > 0 and meta["command"][0]
    assert meta["settings"]["seed"] == 0 and len(meta["cameras"]) == 1
    assert set(meta["files"]) <= set(os.listdir(out))


# ------------------------------------------------------------------------------ other commands (issue 16)


def test_reconstruct_into_a_file_or_an_unwritable_folder_is_one_error_line(tmp_path):
    rendered = tmp_path / "r"
    cameras = [a for c in ("h=0", "h=1", "h=0,psi=90deg", "h=1,psi=90deg") for a in ("--camera", c)]
    assert _cli("render", "cornell-box", "--resolution", "8", "--spp", "4", *cameras, "-o", str(rendered), "--quiet").returncode == 0
    a_file = tmp_path / "file"
    a_file.write_text("x")
    _one_error_line(_cli("reconstruct", str(rendered), "-o", str(a_file)), "exists and is not a folder")
    _one_error_line(_cli("reconstruct", str(rendered), "-o", str(a_file / "sub")), "which is a file")
    _one_error_line(_cli("reconstruct", str(rendered), "-o", "/proc/sys/dopplertof-out"), "not writable")
    assert a_file.read_text() == "x"
    done = _cli("reconstruct", str(rendered), "-o", str(tmp_path / "v"))
    assert done.returncode == 0 and (tmp_path / "v" / "velocity_reconstructed.exr").exists(), done.stderr


@pytest.mark.parametrize("fps, match", [("1e-9", "fps must be >= 0.001526 frames per second"), ("0", "fps must be a finite number of frames per second > 0")])
def test_animate_refuses_an_fps_its_clip_cannot_hold(tmp_path, fps, match):
    out = tmp_path / "clip"
    _one_error_line(_cli("animate", "cornell-box", "--fps", fps, "--resolution", "8", "--spp", "2", "-o", str(out), "--quiet"), match)
    assert not out.exists()


@pytest.mark.parametrize("address, why", [("nonsense:1234", "cannot reach the Ray cluster at 'nonsense:1234' within 5 s"),
                                          ("127.0.0.1:1", "Connection refused")])
def test_an_unreachable_ray_address_fails_fast(tmp_path, address, why):
    pytest.importorskip("ray")
    started = time.monotonic()
    run = _cli("render", "cornell-box", "--resolution", "8", "--spp", "2", "-o", str(tmp_path / "o"), "--quiet", "--ray", "--address", address, timeout=120)
    _one_error_line(run, why)
    assert time.monotonic() - started < 60


def test_experiment_output_and_cache_are_checked_before_rendering(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    common = ["experiment", "velocity", "cornell-box", "--quick", "--cache", str(tmp_path / "cache")]
    _one_error_line(_cli(*common, "-o", str(a_file)), "exists and is not a folder")
    _one_error_line(_cli(*common, "-o", "/proc/sys/dopplertof-out"), "not writable")
    _one_error_line(_cli(*common[:-1], str(a_file), "-o", str(tmp_path / "o")), "reference cache: output")
    assert not (tmp_path / "cache").exists() or not os.listdir(tmp_path / "cache")


def _sigint_while_dr_jit_loads(args):
    """Run the CLI with ``args``, send SIGINT while Dr.Jit's library is being loaded (the
    command's own code runs, no pass has started); (exit status, stderr)."""
    # A shell without job control starts background commands with SIGINT ignored, and Python
    # then installs no handler of its own: the child gets SIGINT's default back here.
    proc = subprocess.Popen([sys.executable, "-m", "dopplertof.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip
    maps = f"/proc/{proc.pid}/maps"
    if not os.path.exists(maps):
        proc.kill()
        pytest.skip("needs /proc")
    deadline = time.monotonic() + 120
    while "libdrjit" not in open(maps).read():
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.001)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=300)
    return proc.returncode, stderr


def test_sigint_during_start_up_is_one_error_line(tmp_path):
    out = tmp_path / "o"
    status, stderr = _sigint_while_dr_jit_loads([*_KILLABLE, "-o", str(out)])
    assert status == 130, stderr
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert lines == ["error: interrupted before the first pass finished; nothing written"], stderr
    assert not (out / "metadata.json").exists() and not (out / "checkpoint.npz").exists()


@pytest.mark.parametrize("args, says", [
    (["animate", "cornell-box", "--resolution", "16", "--spp", "4", "--frames", "2", "--quiet"], "interrupted: the finished frames are in"),
    (["experiment", "velocity", "cornell-box", "--quick"], "SIGINT: stopped; no table was written"),
    (["dataset", "generate", "--samples", "2", "--resolution", "8", "--spp", "4"], "interrupted: 0 of"),
], ids=["animate", "experiment", "dataset"])
def test_sigint_during_start_up_of_other_commands_neither_crashes_nor_prints_a_traceback(tmp_path, args, says):
    """Dr.Jit's extension crashed (SIGSEGV) when the KeyboardInterrupt came during its start-up."""
    extra = ["--cache", str(tmp_path / "cache")] if args[0] == "experiment" else []
    status, stderr = _sigint_while_dr_jit_loads([*args, "-o", str(tmp_path / "o"), *extra])
    assert status == 130 and says in stderr and "Traceback" not in stderr, (status, stderr)


def _no_space(*args, **kwargs):
    import errno

    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_render_whose_last_checkpoint_cannot_be_written_is_returned_all_the_same(tmp_path, monkeypatch):
    """A full disk at the final save of the sums (kept until the images are written) lost the
    whole finished render: the images would have fit."""
    monkeypatch.setattr(sys.modules["dopplertof.render"], "save_checkpoint", _no_space)  # (dt.render is the function)
    scene = dt.scenes.build("cornell-box", resolution=8)
    with pytest.warns(UserWarning, match="cannot write the checkpoint .*No space left on device.*returned without it"):
        result = dt.render(scene, spp=8, checkpoint=str(tmp_path / "ck.npz"), keep_checkpoint=True)
    assert result.spp == 8 and not result.interrupted and "No space left" in result.info["checkpoint_error"]


def test_the_command_line_writes_the_images_when_only_the_checkpoint_does_not_fit(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from dopplertof.cli import main

    monkeypatch.setattr(sys.modules["dopplertof.render"], "save_checkpoint", _no_space)  # (dt.render is the function)
    out = tmp_path / "out"
    run = CliRunner().invoke(main, ["render", "cornell-box", "--resolution", "8", "--spp", "8", "-o", str(out)])
    assert run.exit_code == 0, run.output
    assert (out / "intensity.exr").is_file() and (out / "metadata.json").is_file() and not (out / "checkpoint.npz").exists()


@pytest.mark.parametrize("markers, kind", [
    ({"metadata.json": {"spp": 8, "files": []}}, "render"),
    ({"checkpoint.npz": None}, "render"),
    ({"metadata.json": {"experiment": "shifts"}}, "experiment"),
    ({"dataset.json": {}}, "dataset"),
    ({"animation.json": {}}, "animation"),
    ({"sweep.csv": None}, "design"),
    ({"record_1.npz": None}, "design"),
    ({"record.checkpoint.npz": None}, "design"),  # an interrupted design run
    ({"record_2.checkpoint.npz": None}, "design"),
    ({}, None),
])  # fmt: skip
def test_each_commands_output_is_known_and_another_command_refuses_it(tmp_path, markers, kind):
    from dopplertof.folder import OUTPUT_KINDS, output_kind, refuse_other_output

    for name, content in markers.items():
        (tmp_path / name).write_text(json.dumps(content) if content is not None else "")
    assert output_kind(str(tmp_path)) == kind
    for own in OUTPUT_KINDS:
        if kind is None or own == kind:
            refuse_other_output(str(tmp_path), own)  # its own kind (or nothing) is the command's to decide
        else:
            with pytest.raises(ValueError, match=f"holds {OUTPUT_KINDS[kind]}; {OUTPUT_KINDS[own]} would mix with it"):
                refuse_other_output(str(tmp_path), own)


def test_an_experiment_into_a_render_folder_is_refused_before_it_renders(tmp_path):
    """It replaced the render's metadata.json, after which neither reconstruct nor render
    knew the folder."""
    out = tmp_path / "render"
    assert _cli("render", "cornell-box", "--resolution", "4", "--spp", "4", "-o", str(out)).returncode == 0
    before = (out / "metadata.json").read_bytes()
    _one_error_line(_cli("experiment", "shifts", "cornell-box", "--quick", "-o", str(out), "--cache", str(tmp_path / "cache")), "holds a render")
    assert (out / "metadata.json").read_bytes() == before and not (tmp_path / "cache").exists()


@pytest.mark.parametrize("how", ["resume", "overwrite"])
def test_a_reconstruction_of_a_render_goes_when_the_render_is_continued_or_replaced(tmp_path, how):
    from dopplertof import folder

    (tmp_path / "metadata.json").write_text(json.dumps({"files": ["intensity.exr"], "interrupted": True}))
    (tmp_path / "checkpoint.npz").write_bytes(b"")
    for name in ("intensity.exr", "velocity_reconstructed.exr", "notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "reconstruction.json").write_text(json.dumps({"files": ["velocity_reconstructed.exr"]}))
    folder.prepare(str(tmp_path), **{how: True})
    assert not (tmp_path / "velocity_reconstructed.exr").exists() and not (tmp_path / "reconstruction.json").exists()
    assert (tmp_path / "notes.txt").exists()  # not the render's
    assert (tmp_path / "intensity.exr").exists() == (how == "resume")


def test_a_resume_in_the_checkpoints_own_passes_says_so(tmp_path):
    """Its passes decide the result bit for bit, so the checkpoint's are kept; a smaller
    pass size asked for (the troubleshooting page: nothing is silently altered) is named."""
    scene = dt.scenes.build("cornell-box", resolution=8)
    checkpoint = str(tmp_path / "ck.npz")
    calls = iter([False, True])
    dt.render(scene, spp=64, lanes_per_pass=1024, checkpoint=checkpoint, checkpoint_interval_s=0, stop=lambda: next(calls, True))
    with pytest.warns(UserWarning, match="in its own passes of 1024 lanes, not 2048"):
        assert dt.render(scene, spp=64, lanes_per_pass=2048, checkpoint=checkpoint).spp == 64


@pytest.mark.parametrize("name, match", [
    ("", "must name a file"),
    (".", "must name a file"),
    ("afile/ck.npz", "does not exist \\(or is a file\\)"),
    ("nowhere/ck.npz", "does not exist"),
])  # fmt: skip
def test_an_api_checkpoint_that_cannot_be_written_is_refused_before_rendering(tmp_path, monkeypatch, name, match):
    """It was found at the first save, a checkpoint interval (a minute) into the render."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    with pytest.raises(ValueError, match=match):
        dt.render(dt.scenes.build("cornell-box", resolution=4), spp=4, checkpoint=name)


def test_a_checkpoint_that_is_not_one_says_so_without_numpys_advice(tmp_path):
    garbage = tmp_path / "ck.npz"
    garbage.write_bytes(b"not a checkpoint at all")  # numpy takes it for a pickle
    with pytest.raises(ValueError, match="cannot be read") as caught:
        dt.render(dt.scenes.build("cornell-box", resolution=4), spp=4, checkpoint=str(garbage))
    assert "pickle" not in str(caught.value)


def test_a_folder_without_the_space_a_render_needs_is_refused_and_not_left_behind(tmp_path):
    from dopplertof import folder

    out = tmp_path / "new" / "out"
    with pytest.raises(ValueError, match="MB free; this render writes about"):
        folder.check_writable(str(out), bytes_needed=1 << 62)
    assert not out.exists()
    out.mkdir(parents=True)  # one that was there stays
    with pytest.raises(ValueError, match="MB free"):
        folder.check_writable(str(out), bytes_needed=1 << 62)
    assert out.is_dir()


def test_a_second_signal_while_the_first_checkpoint_is_written_keeps_it(tmp_path, monkeypatch):
    """A second Ctrl-C 0.3 s after the first, while the render wrote its first checkpoint,
    left none: every finished pass was lost, and the command said none had finished. The
    signal now comes once the checkpoint is whole."""
    from dopplertof.clitools import StopOnSignal

    render_module = sys.modules["dopplertof.render"]  # (dopplertof.render is the function)

    write = render_module.save_checkpoint

    def write_under_a_second_signal(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # the second signal, as the checkpoint is written
        write(*args, **kwargs)

    monkeypatch.setattr(render_module, "save_checkpoint", write_under_a_second_signal)
    signals, calls = StopOnSignal(), []

    def stop():
        calls.append(1)
        if len(calls) == 2:  # the first signal, after the first pass
            os.kill(os.getpid(), signal.SIGINT)
        return signals()

    checkpoint = tmp_path / "c.npz"
    with signals, pytest.raises(KeyboardInterrupt):
        dt.render(dt.scenes.cornell_box(resolution=16), spp=64, lanes_per_pass=4096, checkpoint=checkpoint, stop=stop)
    assert _passes_in_checkpoint(checkpoint) == 1


@pytest.mark.parametrize("command", [
    ["render", "cornell-box", "--resolution", "4", "--spp", "2"],
    ["design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=10e6:40e6:4", "--resolution", "4", "--spp", "4"],
    ["experiment", "velocity", "cornell-box", "--quick"],
])  # fmt: skip
def test_a_folder_another_process_is_writing_is_refused(tmp_path, command):
    """Two renders into one folder both reported success and left files of each (and two
    design runs replaced each other's record). The second is refused while the first holds
    the folder, and the folder is free again afterwards."""
    from dopplertof.folder import LOCK, held

    out = tmp_path / "out"
    out.mkdir()
    with held(str(out)):  # another process's hold, as far as the command can tell
        run = _cli(*command, "-o", str(out))
    assert run.returncode == 2 and run.stderr.strip().splitlines()[-1] == (
        f"error: output folder {str(out)!r} is being written by another dopplertof process; wait for it to finish, or choose another folder"), run.stderr
    again = _cli(*command, "-o", str(out))
    assert again.returncode == 0, again.stderr
    assert not (out / LOCK).exists()


def test_an_overwrite_into_a_folder_being_rendered_removes_nothing(tmp_path):
    """--overwrite removed the running render's checkpoint before the hold refused it."""
    from dopplertof.folder import held

    out = tmp_path / "out"
    out.mkdir()
    (out / "checkpoint.npz").write_bytes(b"the running render's sums")
    with held(str(out)):
        run = _cli("render", "cornell-box", "--resolution", "4", "--spp", "2", "--overwrite", "-o", str(out))
    assert run.returncode == 2 and "is being written by another dopplertof process" in run.stderr, run.stderr
    assert (out / "checkpoint.npz").read_bytes() == b"the running render's sums"


def test_an_experiment_into_another_experiments_folder_is_refused(tmp_path):
    """`experiment shifts` replaced a velocity experiment's results.csv and metadata.json and
    left its plots; the same experiment still replaces its own tables."""
    out = tmp_path / "e"
    assert _cli("experiment", "velocity", "cornell-box", "--quick", "-o", str(out)).returncode == 0
    other = _cli("experiment", "shifts", "cornell-box", "--quick", "-o", str(out))
    assert other.returncode == 2 and "holds the 'velocity' experiment's tables; this one ('shifts') would replace them" in other.stderr
    assert _cli("experiment", "velocity", "cornell-box", "--quick", "-o", str(out)).returncode == 0


def test_a_resume_whose_checkpoint_was_removed_says_so(tmp_path):
    """--resume on an interrupted render whose checkpoint was deleted said the folder held
    "a finished render"."""
    out = tmp_path / "r"
    args = ("render", "cornell-box", "--resolution", "4", "--spp", "4", "-o", str(out))
    assert _cli(*args).returncode == 0
    metadata = json.loads((out / "metadata.json").read_text())
    (out / "metadata.json").write_text(json.dumps({**metadata, "interrupted": True}))  # as a stopped render leaves it, its checkpoint gone
    run = _cli(*args, "--resume")
    assert run.returncode == 2 and "holds an interrupted render whose checkpoint is gone (nothing to resume from)" in run.stderr, run.stderr


def test_a_design_record_that_does_not_fit_the_disk_is_refused_before_it_renders(small_disk):
    """A design rendered its record for 10 s into a nearly full disk, then lost it: the
    space is now checked before the render, as a render's is."""
    free = os.statvfs(small_disk).f_bavail * os.statvfs(small_disk).f_frsize
    with open(small_disk / "filler", "wb") as filler:
        filler.write(b"\0" * (free - 200_000))  # 0.2 MB left: a 32² record with its checkpoint needs more
    run = _cli("design", "cornell-box", "--sensor", "dtof-prototype", "--sweep", "f=10e6:100e6:4", "--resolution", "32", "--spp", "64", "-o", str(small_disk / "g"))
    assert run.returncode == 2 and "has 0.2 MB free; this render writes about" in run.stderr and "rendering the record" not in run.stderr, run.stderr
    assert not (small_disk / "g").exists()
