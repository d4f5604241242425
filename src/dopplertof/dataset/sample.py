"""One dataset sample: its record (a pure function of the dataset seed and the index) and
its arrays (rendered from the record alone).

:func:`make_record` draws everything random about sample ``i`` of a dataset with seed ``S``
from counter-based streams, ``numpy.random.SeedSequence(S, spawn_key=(i,))`` spawned into
five independent children (scene, render seeds, sensor settings, sensor noise, and the
sensor model of ``sensor.model``, which only datasets with one draw from): the sample
depends on (S, i) and the configuration only, never on which worker renders it, in which
order, or how many samples came before. :func:`render_record` renders a record; the JSON
record stored next to a sample's arrays is that record, so it re-renders the sample.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from . import randomize, schema
from .config import choose, draw

DIRECT_MAX_DEPTH = 2  # Mitsuba semantics: emitter hits + one bounce, i.e. direct light only
# a stream is appended, never inserted: SeedSequence children keep their keys, so older datasets keep their bytes
_STREAMS = ("scene", "render", "sensor_settings", "sensor_noise", "sensor_model")
_SEED_MASK = 0x7FFFFFFF  # render seeds are 31-bit non-negative integers


def streams(seed: int, index: int) -> dict:
    """The independent ``SeedSequence`` streams of sample ``index`` of dataset ``seed``
    (module docstring), by name.

    Parameters
    ----------
    seed : int
        The dataset's seed.
    index : int
        The sample, from 0.

    Returns
    -------
    dict
        Name → ``numpy.random.SeedSequence``.
    """
    root = np.random.SeedSequence(int(seed), spawn_key=(int(index),))
    return dict(zip(_STREAMS, root.spawn(len(_STREAMS))))


def versions(variant: str) -> dict:
    """The versions a sample's bytes depend on: dopplertof, Mitsuba, Dr.Jit, numpy and the
    Mitsuba ``variant`` (str) the sample is rendered with.

    Parameters
    ----------
    variant : str
        The Mitsuba variant.

    Returns
    -------
    dict
    """
    import drjit
    import mitsuba

    import dopplertof

    return {"dopplertof": dopplertof.__version__, "mitsuba": mitsuba.__version__, "drjit": drjit.__version__, "numpy": np.__version__,
            "variant": variant}


def cameras_of(config: dict) -> list[dict]:
    """The capture set of ``config`` as :class:`dopplertof.Camera` keyword dicts.

    Parameters
    ----------
    config : dict
        The validated configuration.

    Returns
    -------
    list of dict
    """
    from ..modulation import Camera

    cam = config["camera"]
    out = []
    for h, psi_deg in zip(cam["heterodyne"], cam["phase_deg"]):
        camera = Camera(modulation_frequency=cam["modulation_frequency_hz"], exposure=cam["exposure_s"], heterodyne=h,
                        phase=math.radians(psi_deg), waveform=cam["waveform"], g1=cam["g1"], g0=cam["g0"])
        out.append(dataclasses.asdict(camera))
    return out


def make_record(config: dict, seed: int, index: int, variant: str) -> dict:
    """The JSON record of sample ``index``: everything needed to render it (no Mitsuba call).

    Parameters
    ----------
    config : dict
        Validated configuration (:func:`dopplertof.dataset.config.load_config`).
    seed : int
        Dataset seed S (≥ 0).
    index : int
        Sample index i (≥ 0).
    variant : str
        Mitsuba variant the sample is rendered with (part of its identity: CPU and GPU
        backends round differently).

    Returns
    -------
    dict
        JSON-able.
    """
    s = streams(seed, index)
    scene = randomize.sample_scene(np.random.default_rng(s["scene"]), config)
    render_seed, direct_seed = (int(x) & _SEED_MASK for x in s["render"].generate_state(2, np.uint32))
    settings = np.random.default_rng(s["sensor_settings"])
    sen = config["sensor"]
    sensor = {
        "signal_electrons": draw(settings, config, "sensor.signal_electrons"),
        "ambient_electrons_per_s": draw(settings, config, "sensor.ambient_electrons_per_s"),
        "read_noise_e": draw(settings, config, "sensor.read_noise_e"),
        "full_well_e": sen["full_well_e"],
        "adc_bits": sen["adc_bits"],
        "gain_e_per_dn": sen["full_well_e"] / ((1 << sen["adc_bits"]) - 1),
        "black_level_dn": sen["black_level_dn"],
        "noise_seed": int(s["sensor_noise"].generate_state(1, np.uint64)[0]),
    }
    if sen["model"]:
        sensor["model"] = sensor_model_record(np.random.default_rng(s["sensor_model"]), sen["model"])
    r = config["render"]
    bodies = [
        {"instance_id": k, "name": b["name"], "shape": b["shape"], "speed_m_s": float(np.linalg.norm(b["linear_velocity_m_s"])),
         "spin_rad_s": float(np.linalg.norm(b["angular_velocity_rad_s"])), "moving": True}
        for k, b in enumerate(scene["bodies"])
    ]
    cam = scene["camera"]
    ego = {"moving": randomize.camera_motion(cam) is not None, "speed_m_s": float(np.linalg.norm(cam["linear_velocity_m_s"])),
           "yaw_rate_rad_s": float(cam["angular_velocity_rad_s"][1])}
    return {
        "key": f"sample-{index:08d}",
        "index": int(index),
        "dataset_seed": int(seed),
        "scene": scene,
        "cameras": cameras_of(config),
        "render": {"resolution": r["resolution"], "spp": r["spp"], "max_depth": r["max_depth"], "direct_max_depth": DIRECT_MAX_DEPTH,
                   "time_sampling": r["time_sampling"], "correlation": r["correlation"], "seed": render_seed, "direct_seed": direct_seed},
        "sensor": sensor,
        "bodies": bodies,
        "camera_motion": ego,
        "versions": versions(variant),
    }


def sensor_model_record(rng: np.random.Generator, models: dict) -> dict:
    """The record of a sample's sensor (config key ``sensor.model``), JSON-friendly.

    Parameters
    ----------
    rng : numpy.random.Generator. The sample's ``sensor_model`` stream: draws the sensor,
        then its render seed and its noise seed.
    models : dict. ``{name: weight}``: preset names or sensor TOML files.

    Returns
    -------
    dict
        ``name`` (as configured), ``toml`` (the sensor, :func:`dopplertof.sensors.files.sensor_toml`:
        rebuilt from it alone), ``schedule`` (its frames, taps and silicon,
        :func:`~dopplertof.sensors.files.sensor_record`), ``render_seed``, ``noise_seed``.
    """
    import json

    from ..sensors.files import load_sensor, sensor_record, sensor_toml

    name = choose(rng, models)
    sensor = load_sensor(name)
    render_seed, noise_seed = rng.integers(0, _SEED_MASK + 1, size=2)
    return {"name": name, "toml": sensor_toml(sensor), "schedule": json.loads(json.dumps(sensor_record(sensor))),
            "render_seed": int(render_seed), "noise_seed": int(noise_seed)}


def render_sensor_model(scene, record: dict) -> tuple[np.ndarray, np.ndarray, dict]:
    """Render a record's sensor (``record["sensor"]["model"]``) and read it out.

    The sensor's radiance scale (``Silicon.radiance_unit``) is set so that all taps of its
    first frame at the 99th-percentile pixel collect the record's ``signal_electrons``; the
    rest of its silicon is its own.

    Parameters
    ----------
    scene : DynamicScene. The sample's scene.
    record : dict. The sample's record (:func:`make_record`).

    Returns
    -------
    raw_electrons : ndarray of float32, (frames, taps, H, W). Signal electrons before noise
        (:meth:`dopplertof.Sensor.raw`).
    raw_dn : ndarray of uint16, (frames, taps, H, W). :meth:`dopplertof.Sensor.read_out`
        of them with the record's noise seed, mode ``"raw"``.
    derived : dict. ``radiance_unit`` and ``electrons_per_unit_s`` of the scaled silicon.

    Raises
    ------
    KeyboardInterrupt
        If the render was interrupted.
    """
    from ..render import render
    from ..sensors.files import loads_sensor

    model, r = record["sensor"]["model"], record["render"]
    sensor = loads_sensor(model["toml"], where=f"sensor {model['name']!r} of {record['key']}")
    result = render(scene, sensor=sensor, seed=model["render_seed"], spp=r["spp"], max_depth=r["max_depth"],
                    time_sampling=r["time_sampling"], correlation=r["correlation"])  # fmt: skip
    if result.interrupted:
        raise KeyboardInterrupt("render interrupted")
    scaled = sensor.with_signal(result.measurements, record["sensor"]["signal_electrons"])
    raw = scaled.raw(result.measurements)
    dn = scaled.read_out(raw, seed=model["noise_seed"], mode="raw").astype(np.uint16)
    return raw, dn, {"radiance_unit": scaled.noise.radiance_unit, "electrons_per_unit_s": scaled.noise.electrons_per_unit_s}


def sensor_model(record: dict, intensity_luminance: np.ndarray):
    """The :class:`dopplertof.sensor.SensorModel` of a record, given the clean luminance:
    both taps of the 99th-percentile pixel collect ``signal_electrons`` per exposure.

    Parameters
    ----------
    record : dict
        A sample's record (its ``sensor`` settings).
    intensity_luminance : ndarray
        (H, W) luminance of the noiseless intensity.

    Returns
    -------
    SensorModel
    """
    from ..sensor import SensorModel

    sen = record["sensor"]
    cam = record["cameras"][0]
    finite = intensity_luminance[np.isfinite(intensity_luminance)]
    bright = float(np.percentile(finite, 99)) if finite.size else 0.0
    if not bright > 0:  # a black image: no light, any scale gives zero signal
        bright = 1.0
    return SensorModel(
        electrons_per_unit=sen["signal_electrons"] / (cam["exposure"] * cam["g0"] * bright),
        ambient_electrons_per_s=sen["ambient_electrons_per_s"],
        read_noise_e=sen["read_noise_e"],
        full_well_e=sen["full_well_e"],
        adc_bits=sen["adc_bits"],
        gain_e_per_dn=sen["gain_e_per_dn"],
        black_level_dn=sen["black_level_dn"],
    )


def render_record(record: dict, fields=None) -> tuple[dict, dict, dict]:
    """Render a sample from its record.

    Parameters
    ----------
    record : dict
        From :func:`make_record` (or a sample's ``<key>.json``).
    fields : sequence of str or None
        The fields to return; a field the renderer cannot provide, or ``raw_electrons`` /
        ``raw_dn`` of a record without a sensor model, is a ValueError. Default: every
        field the record gives (:func:`dopplertof.dataset.schema.available_fields`).

    Returns
    -------
    arrays : dict
        ``{field: numpy array}`` in the order of :data:`dopplertof.dataset.schema.FIELDS`.
    derived : dict
        Values computed while rendering (the sensor's ``electrons_per_unit``), added to
        the stored record under ``sensor_derived``.
    seconds : dict
        Wall time of ``scene`` (building), ``render`` (both renders, and the sensor
        model's render and read-out) and ``sensor`` (the `raw` taps).
    """
    from ..backend import set_variant
    from ..modulation import Camera
    from ..render import render
    from ..sensor import luminance

    set_variant(record["versions"]["variant"])
    modelled = "model" in record["sensor"]
    if fields is None:
        fields = schema.available_fields(len(record["cameras"]), sensor_model=modelled)[0]
    r = record["render"]
    t0 = time.perf_counter()
    scene = randomize.build_scene(record["scene"], r["resolution"])
    cameras = [Camera(**c) for c in record["cameras"]]
    t1 = time.perf_counter()
    common = dict(cameras=cameras, spp=r["spp"], time_sampling=r["time_sampling"], correlation=r["correlation"])
    full = render(scene, seed=r["seed"], max_depth=r["max_depth"], **common)
    direct = render(scene, seed=r["direct_seed"], max_depth=r["direct_max_depth"], **common)
    if full.interrupted or direct.interrupted:
        raise KeyboardInterrupt("render interrupted")
    if modelled:
        raw_electrons, raw_dn, model_derived = render_sensor_model(scene, record)
    t2 = time.perf_counter()

    lum = luminance(full.intensity)
    model = sensor_model(record, lum)
    rng = np.random.default_rng(record["sensor"]["noise_seed"])
    raw = np.stack([np.stack(model.sample_taps(lum, m, cam, rng)) for m, cam in zip(full.measurements, cameras)]).astype(np.uint16)
    t3 = time.perf_counter()

    out = {
        "measurements": full.measurements,
        "measurement_stderr": full.measurement_stderr,
        "measurements_direct": direct.measurements,
        "measurements_direct_stderr": direct.measurement_stderr,
        "raw": raw,
        "intensity": full.intensity,
        "depth": full.depth,
        "velocity": full.velocity,
    }
    if modelled:
        out.update(raw_electrons=raw_electrons, raw_dn=raw_dn)
    covariance = {"measurement_covariance": full, "measurements_direct_covariance": direct}
    for name in ("velocity_3d", "flow", "instance_id", *covariance):
        if name in fields:
            value = covariance[name].maps.get("measurement_covariance") if name in covariance else getattr(full, name, None)
            if value is None:
                raise ValueError(f"field {name!r} is not rendered for this capture set (a camera covariance needs 2 to 8 cameras); remove it from the config's fields")
            out[name] = value
    if "moving_mask" in fields:  # bodies that move in the world; the camera's own motion is in the velocities
        moving = np.array([not b.motion.is_static() for b in scene.bodies] + [False], dtype=bool)
        ids = np.asarray(out["instance_id"])
        out["moving_mask"] = ((ids >= 0) & moving[np.where(ids >= 0, ids, len(scene.bodies))]).astype(np.uint8)
    arrays = {}
    for name in fields:
        if name not in out:
            raise ValueError(f"field {name!r} needs a sensor: set the config key 'sensor.model'")
        spec = schema.BY_NAME[name]
        arrays[name] = np.ascontiguousarray(np.asarray(out[name]).astype(spec.dtype, copy=False))
    derived = {"electrons_per_unit": model.electrons_per_unit}
    if modelled:
        derived["model"] = model_derived
    return arrays, derived, {"scene": t1 - t0, "render": t2 - t1, "sensor": t3 - t2}
