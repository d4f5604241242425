"""One render on Ray workers (dopplertof.render_ray): bit-identical to the local render,
through the command line and the API, stopped and resumed; bad input.

The Ray tests share one local Ray of 2 CPUs (2 workers), started once for the module.
"""

import json
import shutil
import signal
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import io
from dopplertof.cli import main

SRC = str(Path(dt.__file__).resolve().parents[1])
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def local_ray():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": {"PYTHONPATH": SRC}})
    yield ray
    ray.shutdown()


def _assert_same_maps(one, other):
    assert one.maps.keys() == other.maps.keys()
    for name in one.maps:
        np.testing.assert_array_equal(one.maps[name], other.maps[name], err_msg=name, strict=True)


# ------------------------------------------------------------------------------ command line


def test_cli_render_cornell_box_on_ray_equals_the_local_render_bit_for_bit(local_ray, tmp_path):
    # 32² pixels x 32 spp in passes of 4096 lanes: 8 passes over 2 workers
    args = ["render", "cornell-box", "--resolution", "32", "--spp", "32", "--lanes-per-pass", "4096",
            "--camera", "h=1", "--camera", "h=0,psi=90deg", "--seed", "7", "--quiet"]  # fmt: skip
    runner = CliRunner()
    local = runner.invoke(main, [*args, "-o", str(tmp_path / "local")])
    assert local.exit_code == 0, local.output
    on_ray = runner.invoke(main, [*args, "-o", str(tmp_path / "ray"), "--ray", "--workers", "2"])
    assert on_ray.exit_code == 0, on_ray.output
    names = sorted(p.name for p in (tmp_path / "local").iterdir() if p.suffix in (".exr", ".npy"))
    assert "stderr.exr" in names and "measurement_covariance.npy" in names
    assert names == sorted(p.name for p in (tmp_path / "ray").iterdir() if p.suffix in (".exr", ".npy"))
    for name in names:
        read = io.read_exr if name.endswith(".exr") else io.read_npy
        a, b = read(tmp_path / "local" / name), read(tmp_path / "ray" / name)
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True), name
    meta = json.loads((tmp_path / "ray" / "metadata.json").read_text())
    assert meta["render"]["executor"] == "ray" and meta["render"]["passes"] == 8


def test_a_ray_render_of_its_own_local_ray_prints_only_its_result(tmp_path):
    from test_faults import _cli

    pytest.importorskip("ray")
    # a new local Ray (no address): Ray's notes ("Started a local Ray instance", token
    # authentication) are not printed; the render's own lines are
    done = _cli("render", "cornell-box", "--resolution", "8", "--spp", "2", "--quiet", "--ray", "--workers", "1",
                "-o", str(tmp_path / "out"), timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stderr == "" and done.stdout.startswith("rendered cornell-box at 2 spp"), (done.stdout, done.stderr)


@pytest.mark.slow
def test_sigterm_stops_a_ray_render_and_a_local_resume_is_bit_identical(local_ray, tmp_path):
    from test_faults import _cli, _interrupt

    # ray.init replaces the SIGTERM handler: the render's own must still stop after a pass
    address = local_ray.get_runtime_context().gcs_address
    status, stderr, out, args = _interrupt(tmp_path, signal.SIGTERM, "interrupted", ["--ray", "--address", address, "--workers", "2"])
    assert status == 128 + signal.SIGTERM and "--resume" in stderr, stderr
    assert json.loads((out / "metadata.json").read_text())["interrupted"] and (out / "checkpoint.npz").exists()
    local_args = args[: args.index("--ray")] + args[args.index("--workers") + 2 :]
    assert _cli(*local_args, "--resume").returncode == 0
    whole = tmp_path / "whole"
    assert _cli(*[a if a != str(out) else str(whole) for a in local_args]).returncode == 0
    for name in ("intensity.exr", "stderr.exr", "measurement_0_h1_psi0deg.exr", "measurement_0_h1_psi0deg_stderr.exr"):
        np.testing.assert_array_equal(io.read_exr(out / name), io.read_exr(whole / name), err_msg=name)


@pytest.mark.parametrize(
    "args, match",
    [(["--address", "auto"], "--address needs --ray"), (["--workers", "2"], "--workers needs --ray"), (["--ray", "--workers", "0"], "0 is not in the range")],
)
def test_cli_ray_options_without_ray_or_bad(tmp_path, args, match):
    res = CliRunner().invoke(main, ["render", "cornell-box", "--resolution", "4", "--spp", "2", "-o", str(tmp_path / "o"), *args])
    assert res.exit_code == 2 and match in res.output, res.output


def test_cli_ray_without_the_package_is_one_error_line(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    res = CliRunner().invoke(main, ["render", "cornell-box", "--resolution", "4", "--spp", "2", "-o", str(tmp_path / "o"), "--ray"])
    assert res.exit_code == 2
    assert res.output.strip() == "error: --ray needs the 'ray' package: pip install 'dopplertof[ray]'"
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------ API


def test_api_ray_render_stopped_and_resumed_equals_the_local_render(local_ray, tmp_path):
    # 32² pixels x 16 spp in passes of 1024 lanes: tiles of 512 pixels, one group each, and
    # strata of 2 groups that span passes (the sums carried from pass to pass)
    scene = dt.scenes.build("cornell-box", resolution=32)
    cameras = [dt.Camera(heterodyne=1.0), dt.Camera(heterodyne=0.0, phase=np.pi / 2), dt.Camera(heterodyne=0.5)]
    settings = dict(cameras=cameras, spp=16, lanes_per_pass=1024, seed=3)
    whole = dt.render(scene, **settings)
    assert whole.info["passes"] == 16
    on_ray = dt.render(scene, executor="ray", workers=2, **settings)
    _assert_same_maps(on_ray, whole)

    checkpoint = str(tmp_path / "c.npz")
    calls = iter(range(100))
    partial = dt.render(scene, executor="ray", checkpoint=checkpoint, stop=lambda: next(calls) >= 5, **settings)
    assert partial.interrupted and partial.info["passes_done"] == 5
    resumed = dt.render(scene, executor="ray", workers=2, checkpoint=checkpoint, **settings)
    assert not resumed.interrupted and resumed.spp == 16
    _assert_same_maps(resumed, whole)


def test_a_capture_schedule_and_a_moving_camera_on_ray_equal_the_local_render(local_ray):
    scene = dt.scenes.build("street", resolution=16)
    cameras = [dt.Camera(modulation_frequency=150e6, exposure=1e-3, heterodyne=1.0, phase=p, exposure_start=k * 1e-3) for k, p in enumerate((0.0, np.pi / 2))]
    settings = dict(cameras=cameras, spp=8, lanes_per_pass=1024, seed=5)
    local = dt.render(scene, **settings)
    assert len(local.info["windows"]) == 2
    _assert_same_maps(dt.render(scene, executor="ray", workers=2, **settings), local)


def test_api_ray_render_of_a_scene_file_with_values_and_a_film_size(local_ray, tmp_path):
    # the workers load the file again: its $values, film size, a mesh beside it, the traversal
    text = (DATA / "moving_mesh.xml").read_text()
    text = text.replace('<scene version="3.0.0">', '<scene version="3.0.0">\n<default name="fov" value="30"/>')
    text = text.replace('<float name="fov" value="30"/>', '<float name="fov" value="$fov"/>')
    (tmp_path / "scene.xml").write_text(text)
    shutil.copy(DATA / "quad.obj", tmp_path / "quad.obj")
    scene = dt.load_scene(str(tmp_path / "scene.xml"), film_resolution=(12, 8), fov="20")
    assert scene.recipe == ("file", str(tmp_path / "scene.xml"), {"fov": "20"}, (12, 8))
    scene.traversal = "tree"
    settings = dict(cameras=[dt.Camera(heterodyne=1.0)], spp=32, lanes_per_pass=1024)
    _assert_same_maps(dt.render(scene, executor="ray", **settings), dt.render(scene, **settings))


def test_experiment_references_render_on_ray_with_the_same_pixels(local_ray, tmp_path):
    from dopplertof.experiments import common

    scene = common.open_scene("cornell-box", 16)
    cameras = common.camera_grid(scene.base_camera, (0.0, 1.0), (0.0,))
    local = common.reference_render(scene, cameras, 16, 0, 3, common.ReferenceCache(tmp_path / "local"), lambda text: None)
    on_ray = common.reference_render(scene, cameras, 16, 0, 3, common.ReferenceCache(tmp_path / "ray", {"executor": "ray"}), lambda text: None)
    assert on_ray.info["executor"] == "ray"
    _assert_same_maps(on_ray, local)


def test_a_worker_that_cannot_build_the_scene_is_one_clear_error(local_ray, tmp_path):
    scene = dt.scenes.build("cornell-box", resolution=4)
    scene.recipe = ("file", str(tmp_path / "gone.xml"), {}, None)  # as if the file were not on the worker's node
    with pytest.raises(ValueError, match=r"a Ray worker on .* cannot build the scene: .*gone.xml: scene file not found"):
        dt.render(scene, spp=2, executor="ray")


def test_ray_render_of_a_dict_scene_is_refused():
    scene = dt.oracles.moving_plane_scene(1.0, resolution=4)
    assert scene.recipe is None
    with pytest.raises(ValueError, match="loaded from a dict"):
        dt.render(scene, spp=2, executor="ray")


@pytest.mark.parametrize(
    "kwargs, match",
    [({"executor": "dask"}, "executor must be one of local, ray"), ({"address": "auto"}, "apply to executor='ray'"),
     ({"executor": "ray", "workers": 0}, "workers must be a positive integer")],
)  # fmt: skip
def test_bad_executor_arguments(kwargs, match):
    scene = dt.scenes.build("cornell-box", resolution=4)
    with pytest.raises(ValueError, match=match):
        dt.render(scene, spp=2, **kwargs)


def test_a_worker_refuses_a_scene_file_changed_since_it_was_loaded(local_ray, tmp_path):
    """The workers load the file again: edited in between (a light 10x brighter), they
    rendered the edited scene and the driver took it for the loaded one."""
    path = tmp_path / "scene.xml"
    path.write_text((DATA / "readme_scene.xml").read_text())
    scene = dt.load_scene(str(path), film_resolution=8)
    text = path.read_text()
    assert text.count('<rgb name="intensity" value="') == 1
    path.write_text(text.replace('<rgb name="intensity" value="', '<rgb name="intensity" value="1'))  # "5" -> "15": brighter
    with pytest.raises(ValueError, match=r"a Ray worker on .* built another scene than the one loaded: .*scene.xml changed since"):
        dt.render(scene, spp=2, executor="ray")


def test_a_builtin_scene_from_its_function_knows_its_recipe():
    """The README's own dt.scenes.cornell_box(...) was refused by Ray as "loaded from a dict"."""
    direct, built = dt.scenes.cornell_box(16), dt.scenes.build("cornell-box", resolution=16)
    assert direct.recipe == built.recipe and direct.recipe[:2] == ("builtin", "cornell-box")
    assert direct.identity() == built.identity() != dt.scenes.cornell_box(16, displacement=0.02).identity()
