"""Sensors from the command line and files: a preset name or a TOML description, and the
record of a sensor that ``metadata.json`` keeps.

A sensor file (TOML)::

    preset = "mlx75027"        # optional: the chip's silicon, taps and limits
    taps = 2                   # without a preset: 1, 2 or 4 (default 2)
    light_bandwidth = 300e6    # optional (Hz): the light source's, for every frame that gives
                               # none (a rectangular waveform is then band-limited: what a
                               # response record reads out, dopplertof.design)

    [silicon]                  # Silicon parameters (changes to the preset's)
    radiance_unit = 1e-3
    wavelength_m = 940e-9

    [[frames]]                 # RawFrame parameters, SI units, phase in radians
    modulation_frequency = 100e6
    phase = 1.5707963267948966
    exposure = 300e-6
    waveform = "rectangular"

    [[frames]]
    modulation_frequency = 30e6
    heterodyne_hz = 666.67
    exposure = 1.5e-3
    light_code = [1, 1, 1, 1, 0, 0, 0, 0]                 # one period of samples, or
    sensor_code = { table = "codes.npz", row = 3 }       # a row of a code table (.npy/.npz,
                                                         # relative to this file)

Without ``[[frames]]`` a preset keeps its default schedule. Unknown keys are an error
naming them. :func:`sensor_toml` writes any sensor as such a file.
"""

from __future__ import annotations

import dataclasses
import difflib
import os

from ..codes import load_codes
from .frames import TAP_LAYOUTS, RawFrame, Sensor
from .noise import Silicon
from .presets import PRESETS, preset

_FILE_KEYS = ("preset", "taps", "light_bandwidth", "silicon", "frames")
_FRAME_KEYS = tuple(f.name for f in dataclasses.fields(RawFrame))
_SILICON_KEYS = tuple(f.name for f in dataclasses.fields(Silicon))


def load_sensor(spec: str) -> Sensor:
    """A sensor from a preset name (:data:`~dopplertof.sensors.PRESETS`) or a ``.toml`` file.

    Parameters
    ----------
    spec : str
        A preset name or the path of a ``.toml`` sensor file.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        Naming the file and key, for anything the file or name does not describe.
    FileNotFoundError
        If the file does not exist.
    """
    if spec in PRESETS:
        return preset(spec)
    if not spec.endswith(".toml"):
        raise ValueError(f"--sensor {spec!r}: neither a preset ({', '.join(PRESETS)}) nor a .toml file")
    try:
        with open(spec, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        raise FileNotFoundError(f"sensor file {spec!r} not found") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{spec}: not valid TOML (not UTF-8 text: {exc.reason} at byte {exc.start})") from None
    return loads_sensor(text, os.path.dirname(os.path.abspath(spec)), where=spec)


def loads_sensor(text: str, folder: str = ".", where: str = "sensor TOML") -> Sensor:
    """A sensor from the text of a sensor file (module docstring), such as
    :func:`sensor_toml` writes.

    Parameters
    ----------
    text : str. The TOML document.
    folder : str. Where code tables named in it are looked up; default the working folder.
    where : str. What the text is (a file name), the prefix of error messages.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        Naming ``where`` and the key, for anything the text does not describe.
    """
    import tomllib

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{where}: not valid TOML ({exc})") from None
    try:
        return _from_dict(data, folder)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _unknown(keys, known, where) -> list[str]:
    """What each key of ``keys`` not in ``known`` is called in an error, with a hint."""
    found = []
    for key in keys:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else f" (known: {', '.join(known)})"
            found.append(f"{where}{key!r}{hint}")
    return found


def _from_dict(data: dict, folder: str) -> Sensor:
    silicon = data.get("silicon", {})
    if not isinstance(silicon, dict):
        raise ValueError(f"[silicon] must be a table of Silicon parameters, got {silicon!r}")
    frames_data = data.get("frames")
    if frames_data is not None and (not isinstance(frames_data, list) or not all(isinstance(f, dict) for f in frames_data)):
        raise ValueError("frames must be [[frames]] tables")
    unknown = _unknown(data, _FILE_KEYS, "") + _unknown(silicon, _SILICON_KEYS, "[silicon] ")
    for index, frame in enumerate(frames_data or []):
        unknown += _unknown(frame, _FRAME_KEYS, f"frame {index} ")
    if unknown:  # every one at once
        raise ValueError(f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}")
    frames = None if frames_data is None else [_frame(f, k, folder) for k, f in enumerate(frames_data)]
    if "preset" in data:
        if "taps" in data:
            raise ValueError(f"'taps' is the preset's ({data['preset']!r}); remove it")
        if not isinstance(data["preset"], str) or data["preset"] not in PRESETS:
            raise ValueError(f"unknown sensor preset {data['preset']!r}; choose one of {', '.join(PRESETS)}")
        return _with_light_bandwidth(preset(data["preset"], frames, **silicon), data)
    if frames is None:
        raise ValueError("a sensor without a preset needs [[frames]]")
    taps = data.get("taps", 2)
    if taps not in TAP_LAYOUTS or isinstance(taps, bool):
        raise ValueError(f"'taps' must be one of {', '.join(map(str, TAP_LAYOUTS))}, got {taps!r}")
    return _with_light_bandwidth(Sensor(frames=frames, taps=taps, noise=Silicon(**silicon)), data)


def _with_light_bandwidth(sensor: Sensor, data: dict) -> Sensor:
    """``sensor`` with the file's top-level ``light_bandwidth`` given to every frame that
    gives none of its own (the frames check it: :class:`~dopplertof.Camera`)."""
    if "light_bandwidth" not in data:
        return sensor
    bandwidth = data["light_bandwidth"]
    frames = []
    for index, frame in enumerate(sensor.frames):
        try:
            frames.append(frame if frame.light_bandwidth is not None else dataclasses.replace(frame, light_bandwidth=bandwidth))
        except ValueError as exc:
            raise ValueError(f"light_bandwidth: frame {index}: {exc}") from None
    return dataclasses.replace(sensor, frames=frames)


def _frame(data: dict, index: int, folder: str) -> RawFrame:
    where = f"frame {index}: "
    kwargs = dict(data)
    for name in ("light_code", "sensor_code"):
        value = kwargs.get(name)
        if isinstance(value, dict) and set(value) == {"table", "row"}:
            path = os.path.join(folder, str(value["table"]))
            if not os.path.isfile(path):
                raise ValueError(f"{where}{name}: code table {value['table']!r} not found ({path})")
            table = load_codes(path)
            row = value["row"]
            if isinstance(row, bool) or not isinstance(row, int) or not 0 <= row < len(table):
                raise ValueError(f"{where}{name}: row {row!r} not in the {len(table)} rows of {value['table']!r}")
            kwargs[name] = table[row]
    try:
        return RawFrame(**kwargs)
    except ValueError as exc:
        raise ValueError(f"{where}{exc}") from None


def sensor_record(sensor: Sensor, scheduled=None) -> dict:
    """What ``metadata.json`` keeps of a sensor: its name, taps, silicon, limits and the
    schedule of its raw frames (each frame's parameters, heterodyne offset in Hz).

    ``scheduled``: the frames as rendered (a result's first ``len(sensor.frames)``
    cameras, whose ``exposure_start`` is filled in); default the sensor's own.

    Parameters
    ----------
    sensor : Sensor
    scheduled : list of Camera or None, default None
        As above.

    Returns
    -------
    dict
        JSON-able.
    """
    silicon = dataclasses.asdict(sensor.noise)
    frames = [{**f.as_dict(), "heterodyne_hz": f.heterodyne / f.exposure} for f in (scheduled or sensor.frames)]
    return {
        "name": sensor.name,
        "taps": sensor.taps,
        "silicon": silicon,
        "electrons_per_unit_s": sensor.noise.electrons_per_unit_s,
        "limits": None if sensor.limits is None else sensor.limits.name,
        "frames": frames,
        "cameras": "the render's cameras are the frames, then (4 taps) each frame advanced by 90, 180 and 270 deg, then one camera per exposure window measuring its mean luminance (weight 1)",
        "frame_cameras": sensor.frame_cameras,
        "raw_shape": "(frames, taps, H, W)",
    }


def sensor_toml(sensor: Sensor) -> str:
    """``sensor`` as a TOML sensor file (module docstring) that :func:`load_sensor` reads
    back to the same sensor: a preset's name and frames (its silicon written out whole), or
    the taps, silicon and frames of a custom one.

    Parameters
    ----------
    sensor : Sensor

    Returns
    -------
    str
        TOML text.

    Raises
    ------
    ValueError
        A setting with no TOML form.
    """
    silicon = {k: v for k, v in dataclasses.asdict(sensor.noise).items() if v is not None}
    lines = [f"preset = {_toml(sensor.name)}"] if sensor.name in PRESETS else [f"taps = {sensor.taps}"]
    lines += ["", "[silicon]"] + [f"{k} = {_toml(v)}" for k, v in silicon.items()]
    for frame in sensor.frames:
        values = {**frame.as_dict(), "heterodyne": frame.heterodyne, "heterodyne_hz": getattr(frame, "heterodyne_hz", None)}
        lines += ["", "[[frames]]"] + [f"{k} = {_toml(v)}" for k, v in values.items() if v is not None]
    return "\n".join(lines) + "\n"


def _toml(value) -> str:
    """A TOML value: numbers, booleans, strings, arrays and inline tables."""
    import json
    import math

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise ValueError(f"sensor_toml: cannot write {value!r} as TOML")
