"""The fields of a dataset sample: name, dtype, shape, unit and meaning (one table).

Every sample of a shard has one ``<key>.<field>.npy`` member per field below (``key`` is
``sample-%08d`` of the sample index) and one ``<key>.json`` record (:data:`RECORD`).
Shapes use ``C`` for the number of cameras of the capture set, ``H`` × ``W`` for the film,
``F`` × ``K`` for the raw frames and taps of the sample's sensor (config key ``sensor.model``).
``dataset.json`` carries this table under ``schema`` (with ``C``, ``H``, ``W`` filled in, and
``F``, ``K`` where every sensor the dataset draws from has the same).

Fields whose ``needs`` names a render output (:data:`dopplertof.outputs.OUTPUTS`) are written
only when the renderer provides it; ``dataset.json`` lists the others under ``missing_fields``.
"""

from __future__ import annotations

from dataclasses import dataclass

FORMAT_NAME = "dopplertof-dataset"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class Field:
    """One array of a sample.

    Parameters
    ----------
    name : str
        The field (``<key>.<name>.npy``).
    dtype : str
        numpy dtype name.
    shape : tuple
        Shape template of ints and ``C``, ``H``, ``W`` (cameras, height, width).
    unit : str
    meaning : str
    needs : str or None, default None
        The :class:`~dopplertof.RenderResult` attribute it needs, if not always present.
    """

    name: str
    dtype: str
    shape: tuple
    unit: str
    meaning: str
    needs: str | None = None  # RenderResult attribute (or SENSOR_MODEL) the field needs, if not always present


SENSOR_MODEL = "sensor.model"  # the `needs` of the fields a dataset has only with that config key

FIELDS: tuple[Field, ...] = (
    Field("measurements", "float32", ("C", "H", "W"), "radiance × g1/2",
          "clean D-ToF measurement per camera of the capture set, (1/T)∫W f dt, full global illumination (render.max_depth)"),
    Field("measurement_stderr", "float32", ("C", "H", "W"), "radiance × g1/2", "Monte Carlo standard error of `measurements` (exactly 0 where every path of the pixel cancelled, static paths at h ≠ 0: not an exact value, never a weight 1/σ²)"),
    Field("measurements_direct", "float32", ("C", "H", "W"), "radiance × g1/2",
          "the same cameras, single-bounce (direct) light only: max_depth = 2"),
    Field("measurements_direct_stderr", "float32", ("C", "H", "W"), "radiance × g1/2", "Monte Carlo standard error of `measurements_direct`"),
    Field("measurement_covariance", "float32", ("C", "C", "H", "W"), "(radiance × g1/2)²",
          "covariance of the Monte Carlo errors of `measurements` between cameras (they share paths; 2 to 8 cameras)", needs="measurement_covariance"),
    Field("measurements_direct_covariance", "float32", ("C", "C", "H", "W"), "(radiance × g1/2)²",
          "the same for `measurements_direct`", needs="measurement_covariance"),
    Field("raw", "uint16", ("C", 2, "H", "W"), "DN",
          "noisy raw taps A, B of a 2-tap pixel per camera (dopplertof.sensor: shot, read noise, ambient, full well, ADC); "
          "(A − B) · gain_e_per_dn / (electrons_per_unit · T) is the measurement (record: sensor)"),
    Field("raw_electrons", "float32", ("F", "K", "H", "W"), "e⁻",
          "signal electrons of each raw frame and tap of the sample's sensor (record: sensor.model; dopplertof.Sensor.raw), before "
          "ambient light, dark current, tap mismatch, shot and read noise, full well and ADC", needs=SENSOR_MODEL),
    Field("raw_dn", "uint16", ("F", "K", "H", "W"), "DN",
          "`raw_electrons` read out: dopplertof.Sensor.read_out(raw_electrons, seed=sensor.model.noise_seed, mode='raw') "
          "(ambient, dark current, fixed pattern, shot and read noise, full well, ADC)", needs=SENSOR_MODEL),
    Field("intensity", "float32", ("H", "W", 3), "radiance", "standard (intensity) image, linear RGB"),
    Field("depth", "float32", ("H", "W"), "m", "camera-ray hit distance from the aperture (NaN: no hit)"),
    Field("velocity", "float32", ("H", "W"), "m/s",
          "radial velocity seen by the pixel, relative to the (possibly moving) camera: d/dt of the hit distance along the camera ray "
          "fixed in the camera's frame, positive receding (NaN: no hit)"),
    Field("velocity_3d", "float32", ("H", "W", 3), "m/s", "velocity of the hit point relative to the camera, camera frame (x left, y up, z forward)", needs="velocity_3d"),
    Field("flow", "float32", ("H", "W", 2), "px/s", "image-plane motion of the hit point (x right, y down)", needs="flow"),
    Field("instance_id", "int32", ("H", "W"), "-", "moving body hit (index into the record's scene.bodies), −1 static or background", needs="instance_id"),
    Field("moving_mask", "uint8", ("H", "W"), "-", "1 where instance_id ≥ 0 and that body moves in the world during the exposure (the camera's own motion does not count: "
          "static geometry seen by a moving camera has a velocity but 0 here)", needs="instance_id"),
)

FIELD_NAMES = tuple(f.name for f in FIELDS)
BY_NAME = {f.name: f for f in FIELDS}

RECORD = {
    "key": "sample key, sample-%08d of the index",
    "index": "sample index in the dataset",
    "dataset_seed": "the dataset seed S; the sample depends only on (S, index)",
    "scene": "scene description (dopplertof.dataset.randomize): camera (pose and velocities), light (attached to the camera), static primitives, "
             "moving bodies in instance order",
    "cameras": "the capture set: dopplertof.Camera parameters per measurement",
    "render": "resolution, spp, max_depth, time sampling, correlation, and the seeds of the full and direct renders",
    "sensor": "sensor parameters of `raw` (dopplertof.sensor.SensorModel arguments) and its noise seed; with the config key sensor.model, "
              "`model`: the sensor drawn (name, toml: the sensor file that rebuilds it, schedule: its frames, taps and silicon, "
              "render_seed, noise_seed)",
    "bodies": "per moving body: instance id, shape, speed (m/s), spin rate (rad/s), moving",
    "camera_motion": "the camera's own motion (ego-motion): moving, speed (m/s), yaw rate (rad/s, about the vertical, right-handed)",
    "versions": "dopplertof, mitsuba, drjit, numpy and the Mitsuba variant",
}


def resolve(shape: tuple, cameras: int, height: int, width: int, frames: int | None = None, taps: int | None = None) -> list:
    """A shape template with ``C``, ``H``, ``W`` (and ``F``, ``K`` where given) replaced by numbers.

    Parameters
    ----------
    shape : tuple. A :class:`Field` shape.
    cameras, height, width : int. C, H, W.
    frames, taps : int or None. F and K; None leaves the letter (sensors that differ).

    Returns
    -------
    list
    """
    sizes = {"C": cameras, "H": height, "W": width, "F": frames, "K": taps}
    return [s if sizes.get(s) is None else sizes[s] for s in shape]


def available_fields(n_cameras: int, sensor_model: bool = False) -> tuple[list[str], list[str]]:
    """(fields written, fields missing).

    Parameters
    ----------
    n_cameras : int. Cameras of the capture set.
    sensor_model : bool. Whether the dataset has a sensor (config key ``sensor.model``);
        without one its fields are neither written nor missing. Default False.

    Returns
    -------
    written, missing : list of str
        Missing: those whose ``needs`` the renderer does not output
        (:data:`dopplertof.outputs.OUTPUTS`, and the camera covariance for 2 to
        ``MAX_COVARIANCE_CAMERAS`` cameras).
    """
    from ..outputs import OUTPUTS
    from ..passes import MAX_COVARIANCE_CAMERAS

    outputs = {o.name for o in OUTPUTS}
    if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS:
        outputs.add("measurement_covariance")
    candidates = [f for f in FIELDS if sensor_model or f.needs != SENSOR_MODEL]
    present = [f.name for f in candidates if f.needs in (None, SENSOR_MODEL) or f.needs in outputs]
    return present, [f.name for f in candidates if f.name not in present]


def schema_table(fields, cameras: int, height: int, width: int, frames: int | None = None, taps: int | None = None) -> dict:
    """``{field: {dtype, shape, unit, meaning}}`` of the written ``fields`` (shapes as
    :func:`resolve` fills them).

    Parameters
    ----------
    fields : iterable of str
        Field names.
    cameras, height, width : int
        C, H and W.
    frames, taps : int or None
        F and K; None leaves the letter (samples whose sensors differ). Default None.

    Returns
    -------
    dict
    """
    return {
        name: {"dtype": BY_NAME[name].dtype, "shape": resolve(BY_NAME[name].shape, cameras, height, width, frames, taps),
               "unit": BY_NAME[name].unit, "meaning": BY_NAME[name].meaning}
        for name in fields
    }


def markdown_table() -> str:
    """The fields as a Markdown table (docs/datasets.md's).

    Returns
    -------
    str
    """
    rows = ["| field | dtype | shape | unit | meaning |", "|---|---|---|---|---|"]
    for f in FIELDS:
        shape = "(" + ", ".join(str(s) for s in f.shape) + ")"
        note = " (needs the renderer's `" + f.needs + "`)" if f.needs else ""
        rows.append(f"| `{f.name}` | {f.dtype} | {shape} | {f.unit} | {f.meaning}{note} |")
    return "\n".join(rows)
