"""`dopplertof animate`: frames at their own times, files, GIF, resuming, bad input."""

from __future__ import annotations

import csv
import dataclasses
import json
import shutil
import sys
import warnings

import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner

from dopplertof import animate, cli, io

FPS = 1000.0  # the Cornell box moves during [0, 1.5 ms]: frames 0 and 1 see motion, 2 does not
CLIP = ["cornell-box", "--frames", "3", "--fps", str(FPS), "--resolution", "16", "--spp", "4", "--quiet"]


def run_animate(*args):
    result = CliRunner().invoke(cli.main, ["animate", *map(str, args)])
    return result.exit_code, result.output


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clip") / "out"
    code, output = run_animate(*CLIP, "-o", folder)
    assert code == 0, output
    return folder, output


@pytest.fixture
def clip_copy(clip, tmp_path):
    folder = tmp_path / "out"
    shutil.copytree(clip[0], folder)
    return folder


def frame_lines(output):
    return [line for line in output.splitlines() if line.startswith("frame ")]


def test_every_frame_is_one_exposure_at_its_own_time(clip):
    folder, output = clip
    assert len(frame_lines(output)) == 3
    # 4 spp: why no pixel is valid is said with the frame
    assert "no valid pixel (its standard errors come from 1 degree of freedom, a valid pixel needs 15: more --spp)" in frame_lines(output)[0]
    for i in range(3):
        frame = folder / f"frame_{i:04d}"
        meta = json.loads((frame / "metadata.json").read_text())
        assert meta["settings"]["exposure_start"] == pytest.approx(i / FPS)
        assert meta["seed"] == i
        for name in ("intensity.exr", "velocity.exr", "measurement_2_h1_psi0deg.exr", "velocity_reconstructed.exr",
                     "velocity_reconstructed.png", "velocity_comparison.png", "done.json"):
            assert (frame / name).is_file(), f"frame {i}: {name}"
    # frames 0 and 1 overlap the boxes' motion, frame 2 ([2, 3.5] ms) sees them at rest
    gt = [io.read_exr(folder / f"frame_{i:04d}" / "velocity.exr") for i in range(3)]
    assert np.nanmax(np.abs(gt[0])) > 5 and np.nanmax(np.abs(gt[1])) > 1
    assert np.nanmax(np.abs(gt[2])) == 0


def test_clip_summary_and_gif(clip):
    folder, _ = clip
    with open(folder / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["frame"]) for r in rows] == [0, 1, 2]
    assert [float(r["time_s"]) for r in rows] == pytest.approx([0.0, 1e-3, 2e-3])
    assert all(0.0 <= float(r["valid_fraction"]) <= 1.0 for r in rows)
    gif = iio.imread(folder / "velocity.gif", index=None)
    assert gif.shape[0] == 3
    # ground truth | gap | reconstructed, each enlarged to >= 256 px
    assert gif.shape[1] >= animate.GIF_MIN_PANEL_PX and gif.shape[2] > 2 * gif.shape[1]
    record = json.loads((folder / "animation.json").read_text())
    assert record["fps"] == FPS and record["frames"] == 3 and len(record["cameras"]) == 4


def test_an_interrupted_clip_resumes_with_the_unfinished_frame(clip_copy, monkeypatch):
    folder = clip_copy
    (folder / "frame_0001" / "done.json").unlink()  # frame 1 never finished
    kept = {i: (folder / f"frame_{i:04d}" / "intensity.exr").stat().st_mtime_ns for i in (0, 2)}

    render_module = sys.modules["dopplertof.render"]
    real_render = render_module.render

    def interrupted(*args, **kwargs):  # what render() returns on Ctrl-C: the passes so far
        return dataclasses.replace(real_render(*args, **kwargs), interrupted=True)

    monkeypatch.setattr(render_module, "render", interrupted)
    code, output = run_animate(*CLIP, "-o", folder)
    assert code == 130
    assert "run the same command again to resume" in output
    assert not (folder / "frame_0001" / "done.json").exists()

    monkeypatch.setattr(render_module, "render", real_render)
    code, output = run_animate(*CLIP, "-o", folder)
    assert code == 0, output
    lines = frame_lines(output)
    assert "skipped" in lines[0] and "rendered" in lines[1] and "skipped" in lines[2], output
    assert (folder / "frame_0001" / "done.json").is_file()
    for i, mtime in kept.items():
        assert (folder / f"frame_{i:04d}" / "intensity.exr").stat().st_mtime_ns == mtime


def test_other_settings_are_refused_unless_overwritten(clip_copy):
    folder = clip_copy
    code, output = run_animate(*CLIP, "-o", folder, "--spp", 8)
    assert code == 2
    (line,) = output.strip().splitlines()
    assert line.startswith("error: ") and "spp: 4 there, 8 now" in line and "--overwrite" in line
    code, output = run_animate(*CLIP, "--frames", 1, "-o", folder, "--spp", 8, "--overwrite")  # last --frames wins
    assert code == 0, output
    assert sorted(p.name for p in folder.glob("frame_*")) == ["frame_0000"]
    assert json.loads((folder / "animation.json").read_text())["spp"] == 8


def test_a_shorter_clip_keeps_the_longer_ones_frames_and_says_so(clip_copy):
    folder = clip_copy
    code, output = run_animate(*CLIP, "--frames", 1, "-o", folder)
    assert code == 0, output
    assert "frame_0001 … frame_0002" in output and "--frames 3 takes them back in" in output
    assert (folder / "frame_0002" / "done.json").is_file()  # finished work is kept
    with open(folder / "summary.csv", newline="") as f:
        assert [int(r["frame"]) for r in csv.DictReader(f)] == [0]
    code, output = run_animate(*CLIP, "-o", folder)
    assert code == 0 and "note:" not in output and output.count("skipped") == 3, output


@pytest.mark.parametrize("args, message", [
    (["--frames", 0], "frames must be a positive integer, got 0"),
    (["--frames", -3], "frames must be a positive integer, got -3"),
    (["--fps", 0], "fps must be a finite number of frames per second > 0, got 0.0"),
    (["--fps", -24], "fps must be a finite number of frames per second > 0, got -24.0"),
    (["--fps", "nan"], "fps must be a finite number of frames per second > 0, got nan"),
    (["--camera", "h=1,psi=0", "--camera", "h=1,psi=90deg"], "same heterodyne ratio"),
    (["--camera", "h=0,psi=0", "--camera", "h=1,psi=0,f=20e6"], "modulation_frequency = 30 MHz (beside 20 MHz"),
])
def test_bad_input_is_one_line_and_nothing_is_rendered(tmp_path, args, message):
    code, output = run_animate("cornell-box", "--resolution", 16, "--spp", 4, "-o", tmp_path / "out", *args)
    assert code == 2
    (line,) = output.strip().splitlines()
    assert line.startswith("error: ") and message in line
    assert not list(tmp_path.glob("out/frame_*"))


def test_frame_count_covers_the_motion():
    assert animate.frame_count(1.5e-3, 30.0) == 1  # the Cornell box: one frame
    assert animate.frame_count(2.0, 30.0) == 60
    assert animate.frame_count(0.1, 30.0) == 3  # 0.1 * 30 is 3.0000000000000004 in floating point
    assert animate.frame_count(0.0, 30.0) == 1


def test_frames_and_fps_checks_accept_only_positive_numbers():
    assert animate.check_frames_and_fps(np.int64(4), 24) == (4, 24.0)
    for frames, fps in [(2.5, 30), (True, 30), (1, float("inf")), (1, "30")]:
        with pytest.raises(ValueError):
            animate.check_frames_and_fps(frames, fps)


def test_exposure_option_sets_the_default_cameras_and_is_checked(tmp_path):
    """``--exposure`` without ``--camera`` was accepted and dropped (even -1)."""
    code, output = run_animate("rotating", "--frames", "1", "--resolution", "8", "--spp", "4", "--quiet", "--exposure", "0.0005", "-o", tmp_path / "a")
    assert code == 0, output
    meta = json.loads((tmp_path / "a" / "frame_0000" / "metadata.json").read_text())
    assert [c["exposure"] for c in meta["settings"]["cameras"]] == [0.0005] * 4
    result = CliRunner().invoke(cli.main, ["animate", "rotating", "--frames", "1", "--resolution", "8", "--spp", "4", "--exposure", "-1", "-o", str(tmp_path / "b")])
    assert result.exit_code == 2 and result.output.strip() == "error: Camera: 'exposure' must be in (0, 60] s, got -1.0", result.output


@pytest.mark.parametrize("exposure", [None, 0.002])
def test_without_cameras_a_scene_that_declares_one_renders_the_default_set(data_dir, tmp_path, exposure):
    """Without ``--camera`` the clip renders the default four cameras with the scene's f and
    T (``--exposure``'s T where given); with ``--exposure`` it rendered the scene's one camera
    instead."""
    given = [] if exposure is None else ["--exposure", str(exposure)]
    code, output = run_animate(str(data_dir / "original_cornell.xml"), "-D", "res=8", "--frames", "1", "--spp", "4", "--quiet", *given, "-o", tmp_path / "a")
    assert code == 0, output
    cameras = json.loads((tmp_path / "a" / "frame_0000" / "metadata.json").read_text())["settings"]["cameras"]
    assert [(c["heterodyne"], c["exposure"], c["modulation_frequency"]) for c in cameras] == [(h, exposure or 0.0015, 30e6) for h in (0.0, 0.0, 1.0, 1.0)]


def test_a_rerun_with_another_scene_content_is_refused(data_dir, tmp_path):
    """Frames of one clip came from two scenes: a rerun with other -D values (or an edited
    file) skipped the finished frames and rendered the rest of the other scene."""
    path = tmp_path / "scene.xml"
    path.write_text((data_dir / "readme_scene.xml").read_text().replace('<rgb name="intensity" value="20"/>', '<rgb name="intensity" value="$power"/>'))
    common = (str(path), "--resolution", "8", "--spp", "4", "--fps", "1000", "--quiet", "-o", tmp_path / "clip")
    code, output = run_animate(*common, "--frames", "1", "-D", "power=20")
    assert code == 0, output
    code, output = run_animate(*common, "--frames", "2", "-D", "power=30")
    assert code == 2 and "holds an animation with other settings (scene_identity.content_sha256 (changed))" in output, output
    assert not (tmp_path / "clip" / "frame_0001").exists()


def test_frames_whose_exposures_overlap_warn(tmp_path):
    """--fps 1e9 queued frames 1 ns apart, each exposed for 1.5 ms, without a word."""
    import dopplertof as dt

    scene = dt.scenes.cornell_box(resolution=4)
    with pytest.warns(UserWarning, match=r"exposure \(0.0015 s\) is longer than the time between frames \(1/fps = 0.001 s\)"):
        animate.render_animation(scene, str(tmp_path / "a"), frames=2, fps=1000.0, settings={"spp": 4}, progress=False, log=lambda line: None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        animate.render_animation(scene, str(tmp_path / "b"), frames=2, fps=500.0, settings={"spp": 4}, progress=False, log=lambda line: None)
