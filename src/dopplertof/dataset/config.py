"""The dataset configuration: every knob of the scene randomizer, the renders and the sensor.

The table :data:`PARAMETERS` is the one home of the defaults: :func:`default_toml` (what
``dopplertof dataset config --print`` prints) and :func:`markdown_table` (the table of docs/datasets.md)
are generated from it, and :func:`load_config` validates a user file against it.

A user file (TOML) sets any subset of the keys; an unknown key, a value of the wrong type,
a range whose minimum exceeds its maximum or an unknown choice is a ``ValueError`` naming
the key and the value. Kinds of value:

=============  ==============================================================================
kind           meaning
=============  ==============================================================================
``int``        an integer (``minimum`` applies)
``float``      a finite number (``minimum`` applies)
``str``        one of ``choices``
``range``      ``[min, max]``: a number drawn uniformly per sample (min = max fixes it)
``int_range``  ``[min, max]`` of integers, both included
``log_range``  ``[min, max]`` > 0, drawn log-uniformly
``floats``     a list of finite numbers
``weights``    a table ``{name = weight}`` over ``choices`` (weights ≥ 0, not all 0); the
               relative probabilities of the names
``sensors``    sensors to draw from per sample: ``""`` (none), a preset name or a sensor
               TOML file (:mod:`dopplertof.sensors.files`; a relative path is relative to
               the working folder), a list of them (equally likely) or a table
               ``{name = weight}``; normalised to the table (``{}``: none)
=============  ==============================================================================
"""

from __future__ import annotations

import copy
import math
import os
import tomllib
from dataclasses import dataclass

import numpy as np

SCENE_KINDS = ("indoor", "street")
BODY_SHAPES = ("box", "sphere", "cylinder", "vehicle", "person")
MATERIALS = ("diffuse", "plastic", "roughconductor", "conductor", "dielectric", "checkerboard")
CONDUCTORS = ("Al", "Au", "Cu", "Ag", "Cr")
WAVEFORMS = ("sinusoidal", "rectangular", "triangular", "trapezoidal")
TIME_SAMPLINGS = ("uniform", "stratified", "antithetic", "antithetic_mirror")
CORRELATIONS = ("none", "pixel", "replay", "reconnection", "adaptive")
MAX_RAW_ADC_BITS = 16  # raw taps are stored as uint16


@dataclass(frozen=True)
class Param:
    """One configuration key: dotted ``key`` (section.name), ``default``, ``unit``, ``doc``,
    ``kind`` (see the module docstring), ``choices`` and ``minimum`` where they apply.

    Parameters
    ----------
    key : str
        ``section.name``.
    default : object
        The default value.
    unit : str
        Its unit ("" where none).
    doc : str
        One line of meaning.
    kind : str
        How it is validated (module docstring).
    choices : tuple, default ()
        The allowed values, where there is a list.
    minimum : float or None, default None
        The smallest allowed value, where there is one.
    """

    key: str
    default: object
    unit: str
    doc: str
    kind: str
    choices: tuple = ()
    minimum: float | None = None


PARAMETERS: tuple[Param, ...] = (
    # -- render ------------------------------------------------------------------------------
    Param("render.resolution", 64, "px", "film width = height of every sample", "int", minimum=1),
    Param("render.spp", 64, "paths/px", "paths per pixel of each of the two renders (a multiple of 2 with antithetic sampling)", "int", minimum=1),
    Param("render.max_depth", 5, "-", "path depth of `measurements` (Mitsuba semantics; `measurements_direct` always uses 2: direct light)", "int", minimum=2),
    Param("render.time_sampling", "antithetic", "-", "time sampling of dopplertof.render", "str", TIME_SAMPLINGS),
    Param("render.correlation", "replay", "-", "path correlation of dopplertof.render", "str", CORRELATIONS),
    # -- camera ------------------------------------------------------------------------------
    Param("camera.modulation_frequency_hz", 30e6, "Hz", "light modulation frequency f_g", "float", minimum=0.0),
    Param("camera.exposure_s", 1.5e-3, "s", "exposure T (the scene moves during [0, T])", "float", minimum=0.0),
    Param("camera.waveform", "sinusoidal", "-", "modulation waveform", "str", WAVEFORMS),
    Param("camera.g1", 0.5, "-", "light modulation amplitude", "float", minimum=0.0),
    Param("camera.g0", 0.5, "-", "light modulation DC offset", "float", minimum=0.0),
    Param("camera.heterodyne", [0.0, 0.0, 1.0, 1.0], "cycles/exposure", "h of each captured measurement (the capture set)", "floats"),
    Param("camera.phase_deg", [0.0, 90.0, 0.0, 90.0], "deg", "sensor phase ψ of each captured measurement (as many as `heterodyne`)", "floats"),
    Param("camera.fov_deg", [40.0, 60.0], "deg", "field of view (Mitsuba `fov`, horizontal)", "range"),
    Param("camera.light_intensity_w_sr", [100.0, 300.0], "W/sr", "intensity of the modulated point light at the camera", "range"),
    # -- ego (the camera's own motion; its light moves with it) -------------------------------
    Param("ego.indoor_probability", 0.3, "-", "probability that an indoor sample's camera moves (hand-held or robot: horizontal translation in a random direction, and a yaw)", "float", minimum=0.0),
    Param("ego.indoor_speed_m_s", [0.5, 2.0], "m/s", "speed of a moving indoor camera", "range"),
    Param("ego.indoor_yaw_rate_rad_s", [0.0, 0.5], "rad/s", "yaw rate of a moving indoor camera about the vertical through its aperture (random sign)", "range"),
    Param("ego.street_probability", 0.5, "-", "probability that a street sample's camera moves (as on a vehicle: along the road, the way it looks, and a yaw)", "float", minimum=0.0),
    Param("ego.street_speed_m_s", [5.0, 20.0], "m/s", "speed of a moving street camera", "range"),
    Param("ego.street_yaw_rate_rad_s", [0.0, 0.1], "rad/s", "yaw rate of a moving street camera about the vertical through its aperture (random sign)", "range"),
    # -- scene -------------------------------------------------------------------------------
    Param("scene.kinds", {"indoor": 1.0, "street": 1.0}, "-", "relative probability of each scene kind", "weights", SCENE_KINDS),
    Param("scene.checker_floor_probability", 0.5, "-", "probability that the floor (or road) is a checkerboard", "float", minimum=0.0),
    Param("scene.indoor_width_m", [4.0, 8.0], "m", "room width (x)", "range"),
    Param("scene.indoor_depth_m", [5.0, 9.0], "m", "room depth (z, the camera looks along it)", "range"),
    Param("scene.indoor_height_m", [2.5, 3.5], "m", "room height", "range"),
    Param("scene.indoor_furniture", [1, 4], "-", "static boxes (tables, cabinets) in a room", "int_range"),
    Param("scene.street_road_width_m", [6.0, 10.0], "m", "road width", "range"),
    Param("scene.street_sidewalk_width_m", [2.0, 4.0], "m", "width of each sidewalk (raised 0.15 m)", "range"),
    Param("scene.street_buildings_per_side", [2, 5], "-", "buildings along each side of the street", "int_range"),
    Param("scene.street_poles", [0, 4], "-", "static poles on the sidewalks", "int_range"),
    # -- bodies ------------------------------------------------------------------------------
    Param("bodies.count", [2, 5], "-", "rigid bodies per scene", "int_range"),
    Param("bodies.moving_probability", 0.8, "-", "probability that a body moves (else it is static geometry, instance −1)", "float", minimum=0.0),
    Param("bodies.shapes", {"box": 1.0, "sphere": 1.0, "cylinder": 1.0, "vehicle": 1.0, "person": 1.0}, "-",
          "relative probability of each body shape (vehicles only in streets; a room draws a box instead)", "weights", BODY_SHAPES),
    Param("bodies.size_m", [0.3, 1.0], "m", "edge / diameter / height of a box, sphere or cylinder", "range"),
    Param("bodies.distance_m", [2.0, 9.0], "m", "distance from the camera to a body (clipped to the room)", "range"),
    Param("bodies.speed_m_s", [0.5, 10.0], "m/s", "translation speed of boxes, spheres, cylinders (random direction)", "range"),
    Param("bodies.vehicle_speed_m_s", [3.0, 20.0], "m/s", "vehicle speed along the road", "range"),
    Param("bodies.person_speed_m_s", [0.5, 3.0], "m/s", "walking speed (horizontal)", "range"),
    Param("bodies.spin_rad_s", [0.0, 6.0], "rad/s", "rotation rate about the body centre (random axis; vertical for vehicles and people)", "range"),
    # -- materials ---------------------------------------------------------------------------
    Param("materials.weights", {"diffuse": 3.0, "plastic": 1.0, "roughconductor": 1.0, "conductor": 0.5, "dielectric": 0.5, "checkerboard": 1.0}, "-",
          "relative probability of each body material", "weights", MATERIALS),
    Param("materials.roughness", [0.05, 0.4], "-", "GGX α of rough conductors and rough plastic", "range"),
    Param("materials.dielectric_ior", [1.3, 1.7], "-", "index of refraction of dielectrics", "range"),
    Param("materials.checker_scale", [2.0, 8.0], "checks/uv", "checkerboard frequency", "range"),
    Param("materials.albedo", [0.1, 0.8], "-", "each RGB channel of a diffuse or plastic reflectance", "range"),
    # -- sensor ------------------------------------------------------------------------------
    Param("sensor.signal_electrons", [2000.0, 20000.0], "e⁻", "both taps of the 99th-percentile intensity pixel collect this much per exposure (the photon level)", "log_range"),
    Param("sensor.ambient_electrons_per_s", [0.0, 2e6], "e⁻/s per tap", "ambient light and dark current", "range"),
    Param("sensor.read_noise_e", [1.0, 5.0], "e⁻ rms", "read noise per tap", "range"),
    Param("sensor.full_well_e", 100000.0, "e⁻", "tap capacity (the ADC spans it: gain = full_well / (2^adc_bits − 1))", "float", minimum=0.0),
    Param("sensor.adc_bits", 12, "bits", f"ADC resolution (≤ {MAX_RAW_ADC_BITS}: raw taps are uint16)", "int", minimum=1),
    Param("sensor.black_level_dn", 64.0, "DN", "ADC offset", "float", minimum=0.0),
    Param("sensor.model", "", "-",
          "a dopplertof.Sensor whose raw frames each sample also renders (fields `raw_electrons`, `raw_dn`; its schedule in the record's "
          "sensor.model): a preset (mlx75027, opt8241, imx556, kinect-v2, dtof-prototype) or a sensor TOML file, a list of them "
          "(equally likely) or a table {name = weight}, drawn per sample; empty: none. Its radiance scale is set per sample so that "
          "all taps of its first frame at the 99th-percentile pixel collect `signal_electrons`; the rest of its silicon "
          "(noise, ambient, ADC) is its own, not the keys above", "sensors"),
)

_BY_KEY = {p.key: p for p in PARAMETERS}

SECTION_DOCS = {
    "render": "the two renders of a sample (full global illumination and direct light)",
    "camera": "the D-ToF camera and its co-located modulated point light",
    "ego": "ego-motion: a moving camera, its light attached (constant velocity and yaw rate over the exposure)",
    "scene": "the procedural scene: an indoor room or a street",
    "bodies": "the rigid bodies: shape, placement and motion over the exposure",
    "materials": "materials of the bodies",
    "sensor": "the noise model of the `raw` taps (dopplertof.sensor), and the sensor whose raw frames a sample renders (dopplertof.sensors)",
}


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, float):
        text = repr(value)
        return text if ("e" in text or "." in text or "inf" in text or "nan" in text) else text + ".0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for {value!r}")


def default_toml() -> str:
    """The default configuration as a commented TOML document (``dataset config --print``).

    Returns
    -------
    str
    """
    lines = [
        "# dopplertof dataset configuration: the defaults. A file passed with --config may set",
        "# any subset of these keys; an unknown key is an error. [min, max] ranges are drawn",
        "# per sample (uniformly; log-uniformly for sensor.signal_electrons; integers included).",
    ]
    section = None
    for p in PARAMETERS:
        sec, name = p.key.split(".", 1)
        if sec != section:
            section = sec
            lines += ["", f"[{sec}]  # {SECTION_DOCS[sec]}"]
        lines.append(f"{name} = {_toml_value(p.default)}  # {p.unit}: {p.doc}" if p.unit != "-" else f"{name} = {_toml_value(p.default)}  # {p.doc}")
    return "\n".join(lines) + "\n"


def markdown_table() -> str:
    """The configuration keys as a Markdown table (key, default, unit, meaning).

    Returns
    -------
    str
    """
    rows = ["| key | default | unit | meaning |", "|---|---|---|---|"]
    for p in PARAMETERS:
        rows.append(f"| `{p.key}` | `{_toml_value(p.default)}` | {p.unit} | {p.doc.replace('|', '/')} |")
    return "\n".join(rows)


def defaults() -> dict:
    """The default configuration as a nested dict ``{section: {name: value}}``.

    Returns
    -------
    dict
    """
    out: dict = {}
    for p in PARAMETERS:
        sec, name = p.key.split(".", 1)
        out.setdefault(sec, {})[name] = copy.deepcopy(p.default)
    return out


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check(p: Param, value):
    """``value`` validated (and normalised: ints in float ranges become floats) for ``p``."""
    where = f"config key {p.key!r}"
    if p.kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where} must be an integer, got {value!r}")
        if p.minimum is not None and value < p.minimum:
            raise ValueError(f"{where} must be ≥ {p.minimum:g}, got {value!r}")
        return value
    if p.kind == "float":
        if not _is_number(value):
            raise ValueError(f"{where} must be a finite number, got {value!r}")
        if p.minimum is not None and value < p.minimum:
            raise ValueError(f"{where} must be ≥ {p.minimum:g}, got {value!r}")
        return float(value)
    if p.kind == "str":
        if value not in p.choices:
            raise ValueError(f"{where} must be one of {', '.join(p.choices)}; got {value!r}")
        return value
    if p.kind in ("range", "int_range", "log_range"):
        if not isinstance(value, list) or len(value) != 2:
            raise ValueError(f"{where} must be a range [min, max], got {value!r}")
        if p.kind == "int_range":
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
                raise ValueError(f"{where} must be a range of integers [min, max], got {value!r}")
            if value[0] < 0:
                raise ValueError(f"{where} must not be negative, got {value!r}")
        elif not all(_is_number(v) for v in value):
            raise ValueError(f"{where} must be a range of finite numbers [min, max], got {value!r}")
        lo, hi = value
        if lo > hi:
            raise ValueError(f"{where}: range min {lo!r} > max {hi!r}")
        if p.kind == "log_range" and lo <= 0:
            raise ValueError(f"{where}: a log-uniform range must be > 0, got {value!r}")
        return [int(lo), int(hi)] if p.kind == "int_range" else [float(lo), float(hi)]
    if p.kind == "floats":
        if not isinstance(value, list) or not value or not all(_is_number(v) for v in value):
            raise ValueError(f"{where} must be a non-empty list of finite numbers, got {value!r}")
        return [float(v) for v in value]
    if p.kind == "weights":
        if not isinstance(value, dict):
            raise ValueError(f"{where} must be a table {{name = weight}}, got {value!r}")
        unknown = sorted(set(value) - set(p.choices))
        if unknown:
            raise ValueError(f"{where}: unknown name(s) {unknown}; choose from {', '.join(p.choices)}")
        _check_weights(where, value)
        return {name: float(value.get(name, 0.0)) for name in p.choices}
    if p.kind == "sensors":
        return _check_sensors(where, value)
    raise AssertionError(p.kind)


def _check_weights(where: str, weights: dict) -> None:
    """ValueError unless every weight is a finite number ≥ 0 and one is > 0."""
    if not all(_is_number(v) and v >= 0 for v in weights.values()):
        raise ValueError(f"{where}: weights must be finite numbers ≥ 0, got {weights!r}")
    if sum(weights.values()) <= 0:
        raise ValueError(f"{where}: at least one weight must be > 0, got {weights!r}")


def _check_sensors(where: str, value) -> dict:
    """``{name: weight}`` of the sensors ``value`` names (kind ``sensors``), each loaded once
    to refuse what cannot be rendered or stored."""
    if value in ("", {}):  # {}: the validated form of "no sensor", as dataset.json keeps it
        return {}
    if value == []:  # an empty list is a mistake more likely than a way to say "no sensor"
        raise ValueError(f"{where} lists no sensor, got {value!r}; leave it out (or '') for a dataset without a sensor")
    if isinstance(value, str):
        table = {value: 1.0}
    elif isinstance(value, list) and all(isinstance(v, str) for v in value):
        table = {}
        for name in value:
            table[name] = table.get(name, 0.0) + 1.0
    elif isinstance(value, dict):
        _check_weights(where, value)
        table = {name: float(weight) for name, weight in value.items()}
    else:
        raise ValueError(f"{where} must be a sensor (preset name or .toml file), a list of them or a table {{name = weight}}, got {value!r}")
    from ..sensors.files import load_sensor

    for name in table:
        try:
            sensor = load_sensor(name)
        except (ValueError, OSError) as exc:
            raise ValueError(f"{where}: {exc}") from None
        if sensor.noise.adc_bits > MAX_RAW_ADC_BITS:
            raise ValueError(f"{where}: sensor {name!r} has a {sensor.noise.adc_bits}-bit ADC; `raw_dn` is uint16 (at most {MAX_RAW_ADC_BITS} bits)")
    # sorted: the draw must not depend on the order a file (or dataset.json) lists the names in
    return dict(sorted(table.items()))


def _flatten(user: dict, prefix: str = "") -> dict:
    flat = {}
    for name, value in user.items():
        key = f"{prefix}{name}"
        if key in _BY_KEY:
            flat[key] = value
        elif isinstance(value, dict) and not prefix:
            if name not in SECTION_DOCS:
                raise ValueError(f"unknown config section [{name}]; sections: {', '.join(SECTION_DOCS)}")
            flat.update(_flatten(value, key + "."))
        else:
            raise ValueError(f"unknown config key {key!r}")
    return flat


def validate(config: dict) -> dict:
    """A complete, validated configuration from a nested dict of overrides.

    Parameters
    ----------
    config : dict
        ``{section: {name: value}}``: any subset of :data:`PARAMETERS`; missing keys take
        their defaults.

    Returns
    -------
    dict
        Every key, normalised (``{section: {name: value}}``).

    Raises
    ------
    ValueError
        Naming the key and value: unknown key, wrong type, range min > max, and the
        cross-key rules (as many phases as heterodyne values, probabilities in [0, 1],
        ``sensor.adc_bits`` ≤ 16, ``render.spp`` a multiple of 2 with paired times).
    """
    out = defaults()
    for key, value in _flatten(config).items():
        sec, name = key.split(".", 1)
        out[sec][name] = value
    for p in PARAMETERS:  # user values and defaults, normalised the same way
        sec, name = p.key.split(".", 1)
        out[sec][name] = _check(p, out[sec][name])
    cam = out["camera"]
    if len(cam["heterodyne"]) != len(cam["phase_deg"]):
        raise ValueError(f"config keys 'camera.heterodyne' and 'camera.phase_deg' must have the same length, got {len(cam['heterodyne'])} and {len(cam['phase_deg'])}")
    if cam["modulation_frequency_hz"] <= 0 or cam["exposure_s"] <= 0:
        raise ValueError(f"camera.modulation_frequency_hz and camera.exposure_s must be > 0, got {cam['modulation_frequency_hz']!r}, {cam['exposure_s']!r}")
    lo, hi = cam["fov_deg"]
    if not (0 < lo and hi < 180):
        raise ValueError(f"config key 'camera.fov_deg' must lie in (0, 180) degrees, got {cam['fov_deg']!r}")
    for key in ("scene.checker_floor_probability", "bodies.moving_probability", "ego.indoor_probability", "ego.street_probability"):
        sec, name = key.split(".")
        if not 0 <= out[sec][name] <= 1:
            raise ValueError(f"config key {key!r} is a probability in [0, 1], got {out[sec][name]!r}")
    if out["sensor"]["adc_bits"] > MAX_RAW_ADC_BITS:
        raise ValueError(f"config key 'sensor.adc_bits' must be ≤ {MAX_RAW_ADC_BITS} (raw taps are uint16), got {out['sensor']['adc_bits']!r}")
    if cam["g0"] <= 0:
        raise ValueError(f"config key 'camera.g0' must be > 0 (the sensor model scales the signal by it), got {cam['g0']!r}")
    if out["sensor"]["black_level_dn"] >= (1 << out["sensor"]["adc_bits"]) - 1:
        raise ValueError(f"config key 'sensor.black_level_dn' must be below the ADC's maximum {(1 << out['sensor']['adc_bits']) - 1} DN, got {out['sensor']['black_level_dn']!r}")
    if out["sensor"]["full_well_e"] <= 0:
        raise ValueError(f"config key 'sensor.full_well_e' must be > 0, got {out['sensor']['full_well_e']!r}")
    for key in ("camera.light_intensity_w_sr", "bodies.size_m", "bodies.distance_m", "scene.indoor_width_m", "scene.indoor_depth_m",
                "scene.indoor_height_m", "scene.street_road_width_m", "scene.street_sidewalk_width_m", "materials.dielectric_ior"):
        sec, name = key.split(".")
        if out[sec][name][0] <= 0:
            raise ValueError(f"config key {key!r} must be > 0, got {out[sec][name]!r}")
    for key in ("bodies.speed_m_s", "bodies.vehicle_speed_m_s", "bodies.person_speed_m_s", "bodies.spin_rad_s", "materials.roughness",
                "sensor.ambient_electrons_per_s", "sensor.read_noise_e", "materials.checker_scale", "ego.indoor_speed_m_s", "ego.indoor_yaw_rate_rad_s",
                "ego.street_speed_m_s", "ego.street_yaw_rate_rad_s"):
        sec, name = key.split(".")
        if out[sec][name][0] < 0:
            raise ValueError(f"config key {key!r} must not be negative, got {out[sec][name]!r}")
    lo, hi = out["materials"]["albedo"]
    if not (0 <= lo and hi <= 1):
        raise ValueError(f"config key 'materials.albedo' must lie in [0, 1], got {[lo, hi]!r}")
    r = out["render"]
    paired = r["time_sampling"] != "uniform" or r["correlation"] in ("reconnection", "adaptive")
    if paired and r["spp"] % 2:
        raise ValueError(f"config key 'render.spp' must be a multiple of 2 with paired times ({r['time_sampling']}, {r['correlation']}), got {r['spp']!r}")
    group = 2 if paired else 1
    if r["spp"] < 2 * group:  # one group per pixel: no replicates, so no standard errors or camera covariance
        raise ValueError(
            f"config key 'render.spp' must be at least {2 * group} ({r['time_sampling']}, {r['correlation']}: two independent groups of "
            f"{group} correlated time(s) per pixel give the standard errors and the camera covariance), got {r['spp']!r}"
        )
    return out


def load_config(path: str | os.PathLike | None = None, overrides: dict | None = None) -> dict:
    """The validated configuration: the defaults, then the TOML file ``path``, then
    ``overrides`` (``{section: {name: value}}``, e.g. from command-line options).

    Parameters
    ----------
    path : str, path or None, default None
        A TOML file; None: the defaults only.
    overrides : dict or None, default None
        ``{section: {name: value}}``, applied last.

    Returns
    -------
    dict
        ``{section: {name: value}}``, every key present.

    Raises
    ------
    ValueError
        If the file cannot be read or parsed (naming it) or a value is invalid (see
        :func:`validate`).
    """
    user: dict = {}
    if path is not None:
        try:
            with open(path, "rb") as f:
                user = tomllib.load(f)
        except OSError as exc:
            raise ValueError(f"cannot read config file {os.fspath(path)!r}: {exc.strerror or exc}") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"config file {os.fspath(path)!r} is not valid TOML: {exc}") from None
    merged = copy.deepcopy(user)
    for sec, values in (overrides or {}).items():
        if not isinstance(merged.get(sec, {}), dict):
            raise ValueError(f"unknown config key {sec!r}")
        merged.setdefault(sec, {}).update(values)
    return validate(merged)


# ------------------------------------------------------------------------------------------
# Draws from the configured distributions


def draw(rng: np.random.Generator, config: dict, key: str):
    """One value of the range (or weights) ``key`` (``section.name``) drawn with ``rng``.

    Parameters
    ----------
    rng : numpy.random.Generator
    config : dict
        A validated configuration (:func:`load_config`).
    key : str
        ``section.name`` of a range or weights.

    Returns
    -------
    float, int or str
        A value of the range (an int for an integer range), or a name drawn by the weights.

    Raises
    ------
    ValueError
        ``key`` is not a distribution.
    """
    p = _BY_KEY[key]
    sec, name = key.split(".", 1)
    value = config[sec][name]
    if p.kind == "range":
        return float(rng.uniform(value[0], value[1])) if value[1] > value[0] else float(value[0])
    if p.kind == "int_range":
        return int(rng.integers(value[0], value[1] + 1))
    if p.kind == "log_range":
        return float(math.exp(rng.uniform(math.log(value[0]), math.log(value[1])))) if value[1] > value[0] else float(value[0])
    if p.kind == "weights":
        return choose(rng, value)
    raise ValueError(f"config key {key!r} is not a distribution")


def choose(rng: np.random.Generator, weights: dict) -> str:
    """A name drawn from ``{name: weight}`` (weights need not sum to 1).

    Parameters
    ----------
    rng : numpy.random.Generator
    weights : dict
        Name → weight ≥ 0, not all 0.

    Returns
    -------
    str
    """
    names = list(weights)
    w = np.array([weights[n] for n in names], dtype=np.float64)
    return names[int(rng.choice(len(names), p=w / w.sum()))]
