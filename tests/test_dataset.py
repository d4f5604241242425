"""Datasets (dopplertof.dataset): determinism across executors, faults, resume, verify,
readers, bad input, and the ground truth against the reconstruction.

One tiny reference dataset (8 samples, 4 shards of 2, 16², 4 spp) is generated once per
module in this process; every other generation must reproduce its bytes.
"""

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import dopplertof as dt
from dopplertof import resources
from dopplertof.cli import main
from dopplertof.dataset import config as config_mod
from dopplertof.dataset import execute, schema, shards
from dopplertof.dataset.generate import parse_shard_range
from dopplertof.dataset.sample import make_record, render_record

SMALL = dict(samples=8, seed=5, resolution=16, spp=4, shard_size=2)
SRC = str(Path(dt.__file__).resolve().parents[1])


def _run_env():
    """Environment for a subprocess that imports this checkout's dopplertof."""
    env = dict(os.environ)
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("DOPPLERTOF_VARIANT", "llvm_ad_rgb")
    return env


def _cli_args(folder):
    return ["dataset", "generate", "-o", str(folder), "--samples", "8", "--seed", "5", "--resolution", "16", "--spp", "4",
            "--shard-size", "2", "--quiet"]


def digests(folder) -> dict:
    """sha256 of every shard and of dataset.json."""
    folder = Path(folder)
    names = sorted(p.name for p in folder.glob("shard-*.tar")) + ["dataset.json"]
    return {n: hashlib.sha256((folder / n).read_bytes()).hexdigest() for n in names}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("reference")
    result = dt.dataset.generate(folder, **SMALL)
    assert result["manifest"]["complete"] and len(result["generated"]) == 4
    return folder


def test_reference_layout_and_manifest(reference):
    m = json.loads((reference / "dataset.json").read_text())
    assert [s["name"] for s in m["shards"]] == [f"shard-{k:06d}.tar" for k in range(4)]
    assert m["complete"] and m["samples_done"] == 8 and m["seed"] == 5
    assert set(m["versions"]) >= {"dopplertof", "mitsuba", "drjit", "numpy"}
    assert m["config"]["render"] == {**config_mod.defaults()["render"], "resolution": 16, "spp": 4}
    for s in m["shards"]:
        assert s["sha256"] == hashlib.sha256((reference / s["name"]).read_bytes()).hexdigest()
    sensor_fields = {f.name for f in schema.FIELDS if f.needs == schema.SENSOR_MODEL}
    assert set(m["fields"]) | set(m["missing_fields"]) == set(schema.FIELD_NAMES) - sensor_fields  # no sensor.model: no sensor fields
    assert {"measurements", "measurement_stderr", "measurements_direct", "raw", "intensity", "depth", "velocity"} <= set(m["fields"])
    assert not list(reference.glob(".*.tmp"))
    # a rerun skips every (checked) shard and rewrites nothing
    before = digests(reference)
    again = dt.dataset.generate(reference, **SMALL)
    assert again["generated"] == [] and len(again["skipped"]) == 4
    assert digests(reference) == before


def test_two_workers_and_a_killed_worker_give_the_same_bytes(reference, tmp_path, monkeypatch):
    marker = tmp_path / "killed"
    monkeypatch.setenv(execute.FAULT_ENV, f"2:{marker}")
    folder = tmp_path / "w2"
    dt.dataset.generate(folder, **SMALL, workers=2)
    assert marker.exists(), "the fault hook did not fire"
    assert digests(folder) == digests(reference)


def test_auto_workers_are_one_per_cpu_within_the_shards_and_the_memory(monkeypatch):
    gib = 1 << 30
    monkeypatch.setattr(resources, "usable_cpus", lambda: 8)
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 3 * gib + 1)
    assert execute.auto_workers(10, "llvm_ad_rgb", 128) == 2  # memory: 1 GiB + 32 MiB each
    assert execute.auto_workers(10, "llvm_ad_rgb", 1024) == 1  # 1 GiB + 2 GiB each
    assert execute.auto_workers(1, "llvm_ad_rgb", 16) == 1  # no more than the shards
    assert execute.auto_workers(10, "cuda_ad_rgb", 16) == 1  # one GPU: this process
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 100 * gib)
    assert execute.auto_workers(10, "llvm_ad_rgb", 16) == 8  # one per CPU
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: gib // 2)
    assert execute.auto_workers(10, "llvm_ad_rgb", 16) == 1
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: None)  # not Linux: no memory bound
    assert execute.auto_workers(3, "llvm_ad_rgb", 16) == 3


def test_the_command_takes_auto_workers_and_the_api_one(reference, tmp_path, monkeypatch):
    """``dataset generate`` renders on one worker per CPU unless told (Dr.Jit compiles each
    new scene's kernel on one thread, so one process leaves the other cores waiting); the
    API's default stays this process (more would import the calling script again). The
    bytes are the reference's either way."""
    taken = []
    run_local = execute.run_local

    def spy(jobs, workers, on_done, **kwargs):
        taken.append(workers)
        return run_local(jobs, 1, on_done, **kwargs)  # in this process: the spy sees what it was asked

    monkeypatch.setattr(resources, "usable_cpus", lambda: 3)
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 100 << 30)
    monkeypatch.setattr(execute, "run_local", spy)
    res = CliRunner().invoke(main, _cli_args(tmp_path / "cli"))
    assert res.exit_code == 0 and res.output.rstrip().endswith("s on 3 worker processes"), res.output  # it says what rendered
    assert dt.dataset.generate(tmp_path / "api", **SMALL)["executor"] == "this process"
    dt.dataset.generate(tmp_path / "api-auto", **SMALL, workers="auto", shards_range="0:1")
    assert taken == [3, 1, 1]  # 4 shards on 3 CPUs; the API's default; "auto" for one shard
    assert dt.dataset.generate(tmp_path / "api", **SMALL)["executor"] is None  # nothing left to render
    assert digests(tmp_path / "cli") == digests(reference) == digests(tmp_path / "api")


@pytest.mark.slow
def test_ray_with_a_killed_worker_gives_the_same_bytes(reference, tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")
    marker = tmp_path / "killed"
    monkeypatch.setenv(execute.FAULT_ENV, f"1:{marker}")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": {"PYTHONPATH": SRC}})
    try:
        folder = tmp_path / "ray"
        result = dt.dataset.generate(folder, **SMALL, ray=True)
    finally:
        ray.shutdown()
    assert marker.exists(), "the fault hook did not fire: no Ray worker was killed"
    assert len(result["generated"]) == 4
    assert digests(folder) == digests(reference)


def test_shard_range_then_the_rest(reference, tmp_path):
    folder = tmp_path / "ranges"
    first = dt.dataset.generate(folder, **SMALL, shards_range="3:4")
    assert first["generated"] == ["shard-000003.tar"] and not first["manifest"]["complete"]
    assert digests(folder)["shard-000003.tar"] == digests(reference)["shard-000003.tar"]
    rest = dt.dataset.generate(folder, **SMALL)
    assert rest["skipped"] == ["shard-000003.tar"] and len(rest["generated"]) == 3
    assert digests(folder) == digests(reference)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_sigterm_keeps_finished_shards_and_a_rerun_resumes_byte_identically(reference, tmp_path, sig):
    folder = tmp_path / "interrupted"
    cmd = [sys.executable, "-m", "dopplertof.cli", *_cli_args(folder)]
    proc = subprocess.Popen(cmd, env=_run_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not (folder / shards.RECORDS / "shard-000000.json").exists():
        assert proc.poll() is None and time.time() < deadline, proc.communicate()
        time.sleep(0.05)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal arrived")  # the machine outran the poll
    assert proc.returncode == 128 + sig, err  # as every command: 143 for SIGTERM, 129 for SIGHUP
    assert "interrupted" in err and "resume" in err
    assert not list(folder.glob(".*.tmp")), "a killed shard left its temporary file"
    manifest = json.loads((folder / "dataset.json").read_text())
    assert 1 <= manifest["shards_done"] < 4 and not manifest["complete"]
    done = [s["name"] for s in manifest["shards"] if s["sha256"]]
    assert all(digests(folder)[n] == digests(reference)[n] for n in done)
    # verify says the dataset is incomplete (exit 1), the shards not written yet not being damage
    res = CliRunner().invoke(main, ["dataset", "verify", str(folder)])
    assert res.exit_code == 1 and "0 bad shard(s)" in res.output and "not written yet (the dataset is incomplete)" in res.output
    subprocess.run(cmd, env=_run_env(), check=True, capture_output=True, timeout=300)
    assert digests(folder) == digests(reference)


def test_corrupt_shard_is_found_by_verify_and_regenerated(reference, tmp_path):
    folder = tmp_path / "corrupt"
    shutil.copytree(reference, folder)
    shard = folder / "shard-000001.tar"
    data = bytearray(shard.read_bytes())
    data[700] ^= 0xFF
    shard.write_bytes(bytes(data))
    (folder / "shard-000002.tar").write_bytes(bytes(data[:1000]))  # truncated
    runner = CliRunner()
    res = runner.invoke(main, ["dataset", "verify", str(folder)])
    assert res.exit_code == 1
    assert "shard-000001.tar: corrupt" in res.output and "shard-000002.tar: corrupt" in res.output
    assert "shard-000000.tar" not in res.output
    result = dt.dataset.generate(folder, **SMALL)
    assert result["generated"] == ["shard-000001.tar", "shard-000002.tar"]
    assert digests(folder) == digests(reference)
    assert runner.invoke(main, ["dataset", "verify", str(folder)]).exit_code == 0


def test_reader_without_dopplertof_matches_the_schema(reference):
    """The README's reader: tarfile + numpy only, in a process that never imports dopplertof."""
    script = textwrap.dedent(
        """
        import io, json, sys, tarfile, glob
        import numpy as np
        samples = {}
        for path in sorted(glob.glob(sys.argv[1] + "/shard-*.tar")):
            with tarfile.open(path) as tar:
                for member in tar:
                    key, field = member.name.split(".", 1)
                    data = tar.extractfile(member).read()
                    value = json.loads(data) if field == "json" else np.load(io.BytesIO(data))
                    samples.setdefault(key, {})[field.removesuffix(".npy")] = value
        assert "dopplertof" not in sys.modules
        out = {k: {f: ([str(v.dtype), list(v.shape)] if hasattr(v, "dtype") else v["key"]) for f, v in s.items()} for k, s in samples.items()}
        print(json.dumps(out))
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([sys.executable, "-c", script, str(reference)], env=env, capture_output=True, text=True, timeout=60, cwd="/")
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout)
    manifest = json.loads((reference / "dataset.json").read_text())
    assert sorted(got) == [f"sample-{i:08d}" for i in range(8)]
    for key, fields in got.items():
        assert fields.pop("json") == key
        assert fields == {f: [manifest["schema"][f]["dtype"], manifest["schema"][f]["shape"]] for f in manifest["fields"]}


def test_open_indexing_iteration_and_webdataset(reference):
    ds = dt.dataset.open(reference)
    assert len(ds) == 8 and ds.complete
    items = list(ds)
    assert [s["__key__"] for s in items] == [f"sample-{i:08d}" for i in range(8)]
    for i in (0, 3, 5, -1):
        one = ds[i]
        ref = items[i]
        assert one["__key__"] == ref["__key__"] and one["json"] == ref["json"]
        for f in ds.fields:
            assert one[f].dtype == np.dtype(ds.schema[f]["dtype"]) and list(one[f].shape) == ds.schema[f]["shape"]
            np.testing.assert_array_equal(one[f], ref[f])
    with pytest.raises(IndexError):
        ds[8]
    assert items[2]["json"]["index"] == 2 and items[2]["json"]["dataset_seed"] == 5

    wds = pytest.importorskip("webdataset")
    urls = [str(reference / f"shard-{k:06d}.tar") for k in range(4)]
    loaded = list(wds.WebDataset(urls, shardshuffle=False, empty_check=False).decode())
    assert [s["__key__"] for s in loaded] == [f"sample-{i:08d}" for i in range(8)]
    np.testing.assert_array_equal(loaded[5]["measurements.npy"], items[5]["measurements"])
    assert loaded[5]["json"]["key"] == "sample-00000005"


def test_torch_adapter(reference):
    torch = pytest.importorskip("torch")
    ds = dt.dataset.open(reference).torch()
    assert len(ds) == 8
    item = ds[1]
    assert isinstance(item["measurements"], torch.Tensor) and item["raw"].dtype == torch.int32


def test_torch_adapter_without_torch_installed(reference, monkeypatch):
    """The adapter's own logic through a stand-in for the two torch entry points it uses
    (``torch.utils.data.Dataset`` and ``torch.from_numpy``), where torch is not installed;
    and the clear ImportError where nothing provides torch."""
    import sys
    import types

    if "torch" not in sys.modules:
        monkeypatch.setitem(sys.modules, "torch", None)  # an import of torch fails
        with pytest.raises(ImportError, match="does not depend on it"):
            dt.dataset.open(reference).torch()
    fake = types.ModuleType("torch")
    fake.from_numpy = lambda a: ("tensor", a)
    fake.utils = types.SimpleNamespace(data=types.SimpleNamespace(Dataset=object))
    data = types.ModuleType("torch.utils.data")
    data.Dataset = object
    for name, module in (("torch", fake), ("torch.utils", fake.utils), ("torch.utils.data", data)):
        monkeypatch.setitem(sys.modules, name, module)
    ds = dt.dataset.open(reference).torch()
    assert len(ds) == 8
    item, plain = ds[1], dt.dataset.open(reference)[1]
    assert item["measurements"][0] == "tensor" and np.array_equal(item["measurements"][1], plain["measurements"])
    assert plain["raw"].dtype == np.uint16 and item["raw"][1].dtype == np.int32  # torch has no uint16
    assert item["json"] == plain["json"]


def test_record_rerenders_its_sample(reference):
    ds = dt.dataset.open(reference)
    stored = ds[3]
    record = {k: v for k, v in stored["json"].items() if k != "sensor_derived"}
    assert record == make_record(config_mod.validate(ds.manifest["config"]), 5, 3, ds.manifest["variant"])  # a function of (S, i)
    arrays, derived, _ = render_record(record, ds.fields)
    assert derived == stored["json"]["sensor_derived"]
    for f in ds.fields:
        assert arrays[f].tobytes() == stored[f].tobytes(), f


def test_new_ground_truth_fields(reference):
    ds = dt.dataset.open(reference)
    assert {"velocity_3d", "flow", "instance_id", "moving_mask"} <= set(ds.fields)
    assert ds.manifest["missing_fields"] == []
    for sample in ds:
        h = w = 16
        assert sample["velocity_3d"].shape == (h, w, 3) and sample["flow"].shape == (h, w, 2)
        ids = sample["instance_id"]
        assert ids.dtype == np.int32 and ids.min() >= -1 and ids.max() < len(sample["json"]["bodies"])
        bodies = sample["json"]["bodies"]
        moving = np.array([b["speed_m_s"] > 0 or b["spin_rad_s"] > 0 for b in bodies] + [False])
        np.testing.assert_array_equal(sample["moving_mask"], ((ids >= 0) & moving[np.where(ids >= 0, ids, len(bodies))]).astype(np.uint8))


# ------------------------------------------------------------------------------------------
# Ground truth against the reconstruction

GT_CONFIG = {
    "scene": {"kinds": {"indoor": 1.0, "street": 0.0}, "indoor_furniture": [0, 0]},
    "bodies": {"count": [2, 2], "moving_probability": 1.0, "shapes": {"box": 1.0}, "spin_rad_s": [0.0, 0.0], "size_m": [0.8, 1.0],
               "distance_m": [2.5, 4.0], "speed_m_s": [5.0, 10.0]},
    "materials": {"weights": {"diffuse": 1.0}},
}


def test_direct_light_measurements_reconstruct_the_ground_truth_velocity(tmp_path):
    """On a direct-light-only sample (translating diffuse boxes), the ratio reconstruction
    from the clean ``measurements_direct`` matches the ground-truth radial ``velocity`` on
    the moving pixels away from silhouettes, within the error propagated from
    ``measurements_direct_covariance`` by :func:`dopplertof.reconstruct.velocity` (z-test)."""
    from numpy.lib.stride_tricks import sliding_window_view

    from dopplertof import reconstruct

    dt.dataset.generate(tmp_path, 1, seed=7, config=GT_CONFIG, resolution=32, spp=32)
    s = dt.dataset.open(tmp_path)[0]
    cams = [dt.Camera(**c) for c in s["json"]["cameras"]]
    assert [(c.heterodyne, round(np.degrees(c.phase))) for c in cams] == [(0, 0), (0, 90), (1, 0), (1, 90)]
    m = s["measurements_direct"].astype(np.float64)
    # every pixel, as before the default threshold became a tenth of the scene's speeds
    rec = reconstruct.velocity(m, cams, method="ratio", measurement_covariance=s["measurements_direct_covariance"], max_velocity_stderr=83.0)
    sigma_v = rec.velocity_stderr
    truth = s["velocity"].astype(np.float64)
    # moving pixels whose 3x3 neighbourhood sees the same velocity (no silhouettes / mixed pixels)
    padded = np.pad(np.nan_to_num(truth, nan=1e9), 1, constant_values=1e9)
    window = sliding_window_view(padded, (3, 3))
    spread = window.max(axis=(-1, -2)) - window.min(axis=(-1, -2))
    interior = np.isfinite(truth) & (np.abs(truth) > 0.1) & rec.valid & (spread < 0.05 * np.abs(truth) + 0.05)
    assert interior.sum() >= 30, interior.sum()
    z = (rec.velocity[interior] - truth[interior]) / sigma_v[interior]
    assert 0.5 < np.mean(z**2) < 1.6, np.mean(z**2)  # calibrated: the cameras' covariance is propagated
    assert np.all(np.abs(z) < 5), np.sort(np.abs(z))[-5:]  # no pixel off: |z| < 5 over ~100 pixels (Bonferroni, α ≈ 1e-4)
    # and no gross error (a sign or camera mix-up is off by ~100 %): 32 spp leaves ~10 % noise
    assert np.median(np.abs(rec.velocity[interior] - truth[interior])) < 0.25 * np.median(np.abs(truth[interior]))
    # and the full-GI measurements are a different image (indirect light is there)
    assert not np.array_equal(s["measurements"], s["measurements_direct"])


# ------------------------------------------------------------------------------------------
# Configuration and bad input


def test_default_config_is_printed_and_round_trips():
    import tomllib

    res = CliRunner().invoke(main, ["dataset", "config", "--print"])
    assert res.exit_code == 0
    assert res.output == config_mod.default_toml()
    assert config_mod.validate(tomllib.loads(res.output)) == config_mod.validate({})
    assert config_mod.validate({}) == config_mod.load_config()


@pytest.mark.parametrize(
    "toml, message",
    [
        ("[bodies]\nsped_m_s = [1.0, 2.0]\n", "unknown config key 'bodies.sped_m_s'"),
        ("[bodies]\nspeed_m_s = [5.0, 1.0]\n", "range min 5.0 > max 1.0"),
        ("[render]\nresolution = 'big'\n", "'render.resolution' must be an integer"),
        ("[nope]\nx = 1\n", "unknown config section [nope]"),
        ("[camera]\nheterodyne = [0.0, 1.0]\n", "same length"),
        ("[scene]\nkinds = { forest = 1.0 }\n", "unknown name(s) ['forest']"),
        ("[ego]\nstreet_probability = 1.5\n", "'ego.street_probability' is a probability in [0, 1]"),
        ("render = [\n", "not valid TOML"),
        ("[sensor]\nmodel = 'mlx9'\n", "'sensor.model': --sensor 'mlx9': neither a preset"),
        ("[sensor]\nmodel = 3\n", "'sensor.model' must be a sensor (preset name or .toml file)"),
        ("[sensor]\nmodel = []\n", "'sensor.model' lists no sensor, got []"),
        ("[sensor]\nmodel = { mlx75027 = -1.0 }\n", "'sensor.model': weights must be finite numbers ≥ 0"),
        ("[sensor]\nmodel = ['missing.toml']\n", "config key 'sensor.model': sensor file 'missing.toml' not found"),
    ],
)
def test_bad_config_is_one_error_line_and_exit_2(tmp_path, toml, message):
    path = tmp_path / "bad.toml"
    path.write_text(toml)
    res = CliRunner().invoke(main, ["dataset", "generate", "-o", str(tmp_path / "out"), "--samples", "2", "--config", str(path)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], res.output
    with pytest.raises(ValueError, match="config"):
        config_mod.load_config(path)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--samples", "0"], "samples must be an integer ≥ 1, got 0"),
        (["--samples", "4", "--shard-size", "0"], "shard_size must be"),
        (["--samples", "4", "--shards", "3:9"], "shard range '3:9'"),
        (["--samples", "4", "--spp", "3"], "'render.spp' must be a multiple of 2"),
        (["--samples", "4", "--address", "ray://x:1"], "--address needs --ray"),
        (["--samples", "4", "--spp", "2"], "'render.spp' must be at least 4 (antithetic, replay: two independent groups"),
        (["--samples", "4", "--workers", "0"], "workers must be an integer ≥ 1 or 'auto', got 0"),
        (["--samples", "4", "--workers", "many"], "Invalid value for '--workers': 'many' is neither an integer nor 'auto'"),
        (["--samples", "4", "--workers", "3", "--ray"], "workers=3 counts local processes; with Ray each shard is a task of its own"),
    ],
)
def test_bad_arguments_are_one_error_line_and_exit_2(tmp_path, args, message):
    res = CliRunner().invoke(main, ["dataset", "generate", "-o", str(tmp_path / "out"), *args])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], res.output


def test_unwritable_or_foreign_folder_is_an_error(tmp_path, reference):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    res = CliRunner().invoke(main, ["dataset", "generate", "-o", str(blocker / "sub"), "--samples", "2"])
    assert res.exit_code == 2 and res.output.startswith("error: output ") and "which is a file" in res.output, res.output  # as render says it
    with pytest.raises(ValueError, match="samples must be an integer ≥ 1, got 0"):
        dt.dataset.generate(tmp_path / "x", 0)
    # a folder holding another dataset is refused, naming what differs
    with pytest.raises(ValueError, match="differs in seed: 5 there, 6 now"):
        dt.dataset.generate(reference, **{**SMALL, "seed": 6})
    res = CliRunner().invoke(main, ["dataset", "verify", str(tmp_path)])
    assert res.exit_code == 2 and res.output.startswith("error: ") and "dataset.json" in res.output
    # a folder holding another command's output is refused, naming it
    (tmp_path / "render").mkdir()
    (tmp_path / "render" / "metadata.json").write_text('{"spp": 4}')
    with pytest.raises(ValueError, match="holds a render; a dataset would mix with it"):
        dt.dataset.generate(tmp_path / "render", **SMALL)


def test_info_prints_statistics_and_a_contact_sheet(reference, tmp_path):
    sheet = tmp_path / "sheet.png"
    res = CliRunner().invoke(main, ["dataset", "info", str(reference), "--sheet", str(sheet), "--sheet-samples", "2"])
    assert res.exit_code == 0, res.output
    assert "8 samples read of 8 planned" in res.output and "depth (m)" in res.output and "body speed (m/s)" in res.output
    assert "moving fraction" in res.output
    assert "moving cameras:" in res.output and "camera speed (m/s)" in res.output
    import imageio.v3 as iio

    picture = iio.imread(sheet)
    assert picture.ndim == 3 and picture.shape[0] >= 2 * 128


def test_info_that_cannot_write_its_contact_sheet_prints_the_report_then_one_error(reference, tmp_path):
    """A dataset on read-only storage (here a sheet path under a file, which no user can
    create): the report is printed, then one ``error:`` line, exit 2 (was a traceback)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    res = CliRunner().invoke(main, ["dataset", "info", str(reference), "--sheet", str(blocker / "sheet.png"), "--sheet-samples", "1"])
    assert res.exit_code == 2, res.output
    assert "depth (m)" in res.output and "Traceback" not in res.output
    assert res.output.strip().splitlines()[-1].startswith("error: the contact sheet")


@pytest.mark.parametrize("option", ["--sheet-samples", "--max-samples"])
def test_info_refuses_a_count_below_one(reference, option):
    res = CliRunner().invoke(main, ["dataset", "info", str(reference), option, "-1", "--sheet", "none"])
    assert res.exit_code == 2 and res.output.strip().startswith("error:") and "got -1" in res.output, res.output


def test_sample_streams_are_counter_based():
    cfg = config_mod.validate({})
    forward = [make_record(cfg, 11, i, "llvm_ad_rgb") for i in range(4)]
    backward = [make_record(cfg, 11, i, "llvm_ad_rgb") for i in reversed(range(4))][::-1]
    assert forward == backward
    assert forward[0]["scene"] != forward[1]["scene"]
    assert make_record(cfg, 12, 0, "llvm_ad_rgb")["render"]["seed"] != forward[0]["render"]["seed"]
    assert parse_shard_range("2:", 5) == range(2, 5)


def test_docs_tables_come_from_the_one_home():
    """The datasets page's configuration and field tables are the generated ones (no drift)."""
    page = (Path(__file__).parents[1] / "docs" / "datasets.md").read_text()
    assert config_mod.markdown_table() in page
    assert schema.markdown_table() in page


def test_the_subpackage_is_reached_from_the_package_alone():
    """The README's ``dt.dataset.generate``/``dt.dataset.open`` after a bare ``import dopplertof``,
    without loading the renderer for it."""
    code = "import sys, dopplertof as dt; print(callable(dt.dataset.generate), callable(dt.dataset.open), 'drjit' in sys.modules)"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.stdout.split() == ["True", "True", "False"], run.stderr


# ------------------------------------------------------------------ datasets that take a sensor

CUSTOM_SENSOR = """
taps = 1
[silicon]
read_noise_e = 5.0
adc_bits = 14
[[frames]]
modulation_frequency = 30e6
exposure = 1.5e-3
[[frames]]
modulation_frequency = 30e6
exposure = 1.5e-3
heterodyne_hz = 666.6666666666666
"""


@pytest.fixture(scope="module")
def sensor_dataset(tmp_path_factory):
    """3 samples (16², 4 spp) drawing from a preset and a sensor file of one tap."""
    folder = tmp_path_factory.mktemp("sensors")
    (folder / "one_tap.toml").write_text(CUSTOM_SENSOR)
    config = folder / "config.toml"
    config.write_text(f'[sensor]\nmodel = {{ mlx75027 = 1.0, "{folder / "one_tap.toml"}" = 1.0 }}\n')
    out = folder / "ds"
    dt.dataset.generate(out, samples=3, seed=2, resolution=16, spp=4, shard_size=3, config=str(config))
    return out


def test_sensor_dataset_stores_raw_frames_and_schedule_readable_with_tarfile_and_numpy(sensor_dataset):
    import io
    import tarfile

    manifest = json.loads((sensor_dataset / "dataset.json").read_text())
    assert {"raw_electrons", "raw_dn"} <= set(manifest["fields"])
    assert manifest["schema"]["raw_dn"]["shape"] == ["F", "K", 16, 16]  # the two sensors differ
    samples = {}
    with tarfile.open(sensor_dataset / "shard-000000.tar") as tar:
        for member in tar:
            key, field = member.name.split(".", 1)
            data = tar.extractfile(member).read()
            samples.setdefault(key, {})[field] = json.loads(data) if field == "json" else np.load(io.BytesIO(data))
    names = set()
    for sample in samples.values():
        model = sample["json"]["sensor"]["model"]
        names.add(Path(model["name"]).name)
        schedule = model["schedule"]
        shape = (len(schedule["frames"]), schedule["taps"], 16, 16)
        electrons, dn = sample["raw_electrons.npy"], sample["raw_dn.npy"]
        assert electrons.shape == dn.shape == shape and electrons.dtype == np.float32 and dn.dtype == np.uint16
        # the radiance scale puts the 99th-percentile pixel of frame 0 at signal_electrons (all its taps)
        bright = np.percentile(electrons[0].astype(np.float64).sum(axis=0), 99)
        assert bright == pytest.approx(sample["json"]["sensor"]["signal_electrons"], rel=1e-5)
        assert schedule["frames"][0]["modulation_frequency"] in (100e6, 30e6) and schedule["silicon"]["adc_bits"] in (12, 14)
    assert names == {"mlx75027", "one_tap.toml"}


def test_sensor_dataset_raw_dn_is_the_read_out_of_raw_electrons_and_rerenders(sensor_dataset):
    import dataclasses

    from dopplertof.sensors.files import loads_sensor

    ds = dt.dataset.open(sensor_dataset)
    for stored in ds:
        model = stored["json"]["sensor"]["model"]
        sensor = loads_sensor(model["toml"])
        assert [f.as_dict() for f in sensor.frames] == [{k: v for k, v in f.items() if k != "heterodyne_hz"} for f in model["schedule"]["frames"]]
        scaled = dataclasses.replace(sensor, noise=dataclasses.replace(sensor.noise, radiance_unit=stored["json"]["sensor_derived"]["model"]["radiance_unit"]))
        np.testing.assert_array_equal(scaled.read_out(stored["raw_electrons"], seed=model["noise_seed"]), stored["raw_dn"])
    stored = ds[1]
    record = {k: v for k, v in stored["json"].items() if k != "sensor_derived"}
    assert record == make_record(config_mod.validate(ds.manifest["config"]), 2, 1, ds.manifest["variant"])  # a function of (S, i)
    arrays, derived, _ = render_record(record)
    assert derived == stored["json"]["sensor_derived"]
    for f in ds.fields:
        assert arrays[f].tobytes() == stored[f].tobytes(), f


def test_info_counts_the_sensors_drawn(sensor_dataset):
    res = CliRunner().invoke(main, ["dataset", "info", str(sensor_dataset)])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith("sensors (raw_electrons, raw_dn): "))
    names = [s["json"]["sensor"]["model"]["name"] for s in dt.dataset.open(sensor_dataset)]
    assert line == "sensors (raw_electrons, raw_dn): " + ", ".join(f"{k} {names.count(k)}" for k in sorted(set(names)))


def test_sensor_draws_follow_the_weights_and_leave_other_draws_alone():
    plain = config_mod.validate({})
    weighted = config_mod.validate({"sensor": {"model": {"mlx75027": 3.0, "opt8241": 1.0}}})
    assert config_mod.validate({"sensor": {"model": ["mlx75027", "mlx75027", "opt8241"]}})["sensor"]["model"] == {"mlx75027": 2.0, "opt8241": 1.0}
    assert config_mod.validate({"sensor": {"model": "imx556"}})["sensor"]["model"] == {"imx556": 1.0}
    n = 300
    drawn = [make_record(weighted, 7, i, "llvm_ad_rgb") for i in range(n)]
    share = np.mean([r["sensor"]["model"]["name"] == "mlx75027" for r in drawn])
    assert abs(share - 0.75) < 5 * np.sqrt(0.75 * 0.25 / n)
    for i in (0, 5):  # the scene, render seeds and the `raw` sensor are those of the same sample without a model
        without = make_record(plain, 7, i, "llvm_ad_rgb")
        assert "model" not in without["sensor"]
        assert {k: v for k, v in drawn[i]["sensor"].items() if k != "model"} == without["sensor"]
        assert drawn[i]["scene"] == without["scene"] and drawn[i]["render"] == without["render"]


def test_sensor_with_too_many_adc_bits_is_refused_in_a_subprocess(tmp_path):
    (tmp_path / "deep.toml").write_text(CUSTOM_SENSOR.replace("adc_bits = 14", "adc_bits = 20"))
    (tmp_path / "config.toml").write_text('[sensor]\nmodel = "deep.toml"\n')
    res = subprocess.run([sys.executable, "-m", "dopplertof.cli", "dataset", "generate", "-o", str(tmp_path / "out"), "--samples", "1",
                          "--config", str(tmp_path / "config.toml")], capture_output=True, text=True, cwd=tmp_path, env=_run_env(), timeout=120)
    assert res.returncode == 2, res.stderr
    assert res.stderr.strip().splitlines() == ["error: config key 'sensor.model': sensor 'deep.toml' has a 20-bit ADC; `raw_dn` is uint16 (at most 16 bits)"]


def test_a_sensor_file_edited_between_runs_is_not_mixed_in(tmp_path):
    sensor_file = tmp_path / "one_tap.toml"
    sensor_file.write_text(CUSTOM_SENSOR)
    config = tmp_path / "config.toml"
    config.write_text(f'[sensor]\nmodel = "{sensor_file}"\n')
    small = dict(samples=1, seed=0, resolution=8, spp=4, config=str(config))
    dt.dataset.generate(tmp_path / "ds", **small)
    manifest = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert "read_noise_e = 5.0" in manifest["sensor_models"][str(sensor_file)]
    assert dt.dataset.generate(tmp_path / "ds", **small)["generated"] == []  # unchanged: resumes
    sensor_file.write_text(CUSTOM_SENSOR.replace("read_noise_e = 5.0", "read_noise_e = 6.0"))
    with pytest.raises(ValueError, match="holds another dataset \\(it differs in sensor_models\\..*sensor.* \\(changed\\)\\)"):
        dt.dataset.generate(tmp_path / "ds", **small)


def test_dataset_info_stays_a_function_after_its_module_is_imported():
    """``dt.dataset.info`` is a function; its implementation's module must not replace it
    as an attribute of the package when first imported (a second call would fail)."""
    import importlib

    import dopplertof.dataset as dataset

    importlib.import_module("dopplertof.dataset.summary")
    assert callable(dataset.info) and dataset.info.__module__ == "dopplertof.dataset"


def _children(pid):
    """PIDs of the processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry))
    return found


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_workers_end_when_their_driver_is_killed(tmp_path):
    """SIGKILL of ``dataset generate --workers 2`` left its two workers (and multiprocessing's
    resource tracker) rendering, re-parented, for minutes."""
    import signal
    import subprocess
    import sys
    import time

    args = [sys.executable, "-m", "dopplertof.cli", "dataset", "generate", "-o", str(tmp_path / "d"), "--samples", "40", "--resolution", "16", "--spp", "8", "--shard-size", "2", "--workers", "2", "--quiet"]
    driver = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120
    while len(workers := [p for p in _children(driver.pid) if "spawn_main" in open(f"/proc/{p}/cmdline").read()]) < 2:
        assert driver.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    everyone = _children(driver.pid)
    os.kill(driver.pid, signal.SIGKILL)
    driver.wait()
    deadline = time.monotonic() + 30
    while (alive := [p for p in everyone if os.path.exists(f"/proc/{p}") and open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"]):
        if time.monotonic() > deadline:
            for p in alive:
                os.kill(p, signal.SIGKILL)
            pytest.fail(f"{len(alive)} of the driver's processes outlived it by 30 s")
        time.sleep(0.2)
    assert len(workers) == 2


def test_the_reader_takes_integers_and_slices_and_says_what_else_it_refuses(reference):
    ds = dt.dataset.open(reference)
    assert [s["__key__"] for s in ds[1:3]] == [ds[1]["__key__"], ds[2]["__key__"]] and ds[-1]["__key__"] == ds[len(ds) - 1]["__key__"]
    assert ds[np.int64(2)]["__key__"] == ds[2]["__key__"]
    for bad in (1.0, "a", True):
        with pytest.raises(TypeError, match="dataset indices must be integers or slices"):
            ds[bad]


def test_verify_tells_shards_not_written_yet_from_damaged_ones(tmp_path, reference):
    """A generation under way (or stopped) has shards it has not written: not 'bad'."""
    folder = tmp_path / "part"
    dt.dataset.generate(folder, **SMALL, shards_range="0:1")
    res = CliRunner().invoke(main, ["dataset", "verify", str(folder)])
    assert res.exit_code == 1 and "0 bad shard(s), 1 ok; 3 not written yet (the dataset is incomplete)" in res.output and "finish it" in res.output, res.output
    with open(folder / "shard-000000.tar", "r+b") as f:
        f.truncate(1000)
    res = CliRunner().invoke(main, ["dataset", "verify", str(folder)])
    assert res.exit_code == 1 and "shard-000000.tar: corrupt" in res.output and "3 not written yet" in res.output
    with pytest.warns(UserWarning, match="shard-000000.tar are missing or differ from their records and are left out"):
        assert len(dt.dataset.open(folder)) == 0


def test_a_shard_whose_bytes_changed_is_refused_when_read(tmp_path, reference):
    """Random bytes in a shard of the right size were read as data (a field off by 5.6e37)
    while only `dataset verify` noticed; the reader checks each shard's SHA-256 the first
    time it reads it."""
    import shutil

    folder = tmp_path / "copy"
    shutil.copytree(reference, folder)
    ds = dt.dataset.open(folder)
    shard = ds._shards[0]["name"]
    with open(folder / shard, "r+b") as f:
        f.seek(2000)
        f.write(b"\x7f" * 64)  # inside the first sample's arrays: the tar still reads
    for read in (lambda d: d[0], lambda d: next(iter(d))):
        with pytest.raises(ValueError, match=rf"{shard}: its contents differ from its record \(SHA-256\)"):
            read(dt.dataset.open(folder))
    assert len(dt.dataset.open(folder)[len(ds) - 1]) > 1  # the other shards read as before
