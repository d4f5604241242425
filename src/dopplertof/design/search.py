"""Sweeps and optimisation of a sensor's parameters on a recorded scene.

A *variant* of a sensor sets one parameter on its frames (:data:`KEYS`):

=========================  =========================================================
key (alias)                what it sets
=========================  =========================================================
``modulation_frequency``   every frame's modulation frequency (Hz)
(``f``)
``heterodyne`` (``h``)     every heterodyne frame's offset h (beat cycles per
                           exposure; homodyne frames stay homodyne)
``exposure`` (``T``)       every frame's exposure (s; h kept, so the offset in Hz
                           follows 1/T)
=========================  =========================================================

Each variant is rebuilt as a :class:`~dopplertof.Sensor` with the original's limits, so a
preset refuses what its chip cannot capture; a sweep lists such variants as refused.
:func:`record_spec` chooses a record that holds every variant of a sweep (its frequencies,
their harmonics, its beats and, for exposures, one window per exposure).

:func:`sweep` evaluates the objective (:data:`OBJECTIVES`, m/s or m: the mean bound over the
moving pixels, :func:`~dopplertof.design.crb`) on the grid of every combination.
:func:`optimize` minimises it from the sensor's own values: the phases of the frames by
gradient descent (:func:`~dopplertof.design.gradient`; a step the chip refuses is no step), the modulation frequency
by a pattern search on the record's frequency grid within the chip's range (the record
gives the objective exactly there and only there: a gradient step would leave the grid).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from .precision import crb

KEYS = {"modulation_frequency": "modulation_frequency", "f": "modulation_frequency", "heterodyne": "heterodyne", "h": "heterodyne", "exposure": "exposure", "T": "exposure"}
OBJECTIVES = ("velocity_crb", "depth_crb")
OPTIMIZE_KEYS = ("modulation_frequency", "phase")
MAX_SWEEP_POINTS = 10_000


def parse_sweep(text: str) -> tuple[str, np.ndarray]:
    """``KEY=LO:HI:N`` → (key, N values from LO to HI); ValueError naming the text.

    Parameters
    ----------
    text : str
        ``KEY=LO:HI:N`` with a key of :data:`KEYS`.

    Returns
    -------
    tuple of (str, ndarray)

    Raises
    ------
    ValueError
        Not ``KEY=LO:HI:N``, or an unknown key.
    """
    if "=" not in text:
        raise ValueError(f"--sweep {text!r}: expected KEY=LO:HI:N, e.g. modulation_frequency=10e6:100e6:10")
    key, _, grid = text.partition("=")
    key = key.strip()
    if key not in KEYS:
        raise ValueError(f"--sweep {text!r}: unknown key {key!r}; choose one of {', '.join(KEYS)}")
    parts = grid.split(":")
    try:
        low, high, count = float(parts[0]), float(parts[1]), int(parts[2])
        if len(parts) != 3:
            raise IndexError
    except (ValueError, IndexError):
        raise ValueError(f"--sweep {text!r}: expected KEY=LO:HI:N with numbers LO, HI and a whole N") from None
    if not (math.isfinite(low) and math.isfinite(high)) or count < 1 or (count == 1 and low != high) or high < low:
        raise ValueError(f"--sweep {text!r}: needs finite LO <= HI and N >= 1 (N = 1 only with LO = HI)")
    key = KEYS[key]
    if key in ("modulation_frequency", "exposure") and not low > 0:
        raise ValueError(f"--sweep {text!r}: {key} must be > 0 ({'Hz' if key == 'modulation_frequency' else 's'}), LO is {low:g}")
    values = np.linspace(low, high, count)
    if key == "modulation_frequency" and any(v != round(v) for v in values):
        raise ValueError(f"--sweep {text!r}: its points are {(high - low) / (count - 1):.10g} Hz apart, and a record's frequencies "
                         f"are whole Hz: choose LO, HI and N so that (HI - LO)/(N - 1) is whole Hz")
    return key, values


def variant(sensor, changes: dict):
    """``sensor`` with ``changes`` ({key: value}, keys of :data:`KEYS`) set on its frames,
    checked against its limits (ValueError where its chip cannot capture them).

    Parameters
    ----------
    sensor : Sensor
    changes : dict
        Key of :data:`KEYS` → value (Hz, beat cycles per exposure or s).

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        The chip cannot capture the changed frames.
    """
    if "heterodyne" in {KEYS[key] for key in changes} and all(frame.heterodyne == 0 for frame in sensor.frames):
        raise ValueError("the sensor has no heterodyne frame (every h = 0): a heterodyne sweep changes nothing")
    frames = []
    for frame in sensor.frames:
        update = {}
        for key, value in changes.items():
            key = KEYS[key]
            if key == "heterodyne" and frame.heterodyne == 0:
                continue
            update[key] = float(value)
        if update and getattr(frame, "heterodyne_hz", None) is not None:
            update["heterodyne_hz"] = None  # h is the parameter kept (module docstring)
        frames.append(dataclasses.replace(frame, **update))
    return dataclasses.replace(sensor, frames=frames)


def record_spec(sensor, sweeps, beats_extra=(), optimize=(), doppler=True):
    """(RecordSpec, cameras) for a record holding every variant of ``sweeps`` (list of
    (key, values)) and of ``optimize`` (the modulation frequency: the chip's whole range at
    its frequency step, else 1 MHz): the cameras give its windows to ``render``.

    Parameters
    ----------
    sensor : Sensor
    sweeps : list of tuple of (str, ndarray)
        As :func:`parse_sweep` gives them.
    beats_extra : sequence of float, default ()
        More beats to record (cycles per exposure).
    optimize : sequence of str, default ()
        Keys of :data:`OPTIMIZE_KEYS`.
    doppler : bool, default True
        Record the first moments (velocity bounds need them).

    Returns
    -------
    tuple of (RecordSpec, list of Camera)

    Raises
    ------
    ValueError
        A frequency that is not whole Hz, or too many sweep points.
    """
    from .record import RecordSpec, harmonics

    _check_size(sweeps)
    variants, refused = [], []
    for values in itertools.product(*[v for _, v in sweeps]):
        try:
            variants.append(variant(sensor, dict(zip([k for k, _ in sweeps], values))))
        except ValueError as exc:
            refused.append(str(exc))  # the chip refuses it: the sweep lists it as refused
    if refused and not variants:  # before a render that nothing could use
        raise ValueError(f"every point of the sweep is refused, e.g. {refused[0]}")
    variants = variants or [sensor]
    frequencies, beats, cameras = set(), {0.0, *beats_extra}, []
    for v in variants:
        for index, camera in enumerate(v.cameras()):
            _, terms = harmonics(camera, f"sensor {sensor.name!r}, frame {index}")
            for m, _ in terms:
                frequency = m * camera.modulation_frequency
                if frequency != round(frequency):
                    source = (f"{m} x the frame's modulation_frequency {camera.modulation_frequency!r} Hz" if m != 1 else "the frame's modulation_frequency")
                    raise ValueError(f"frame {index}: a record's frequencies are whole Hz, got {frequency!r} Hz ({source}); "
                                     f"give the sensor whole-Hz frequencies (a sensor file's [[frames]] modulation_frequency)")
                frequencies.add(round(frequency))
                beats.add(m * camera.heterodyne)
        cameras += [c for c in v.cameras() if (c.exposure_start, c.exposure) not in {(x.exposure_start, x.exposure) for x in cameras}]
    if "modulation_frequency" in optimize:
        limits = sensor.limits
        low, high = limits.frequency_hz if limits is not None else (min(frequencies), max(frequencies))
        if low == high:
            raise ValueError("--optimize modulation_frequency: the sensor has no frequency range to search (no preset's chip limits, "
                             "one frequency): give --sweep f=LO:HI:N to span one, or a sensor file with a preset")
        step = (limits.frequency_step_hz if limits is not None and limits.frequency_step_hz else 1e6)
        frequencies |= {round(f) for f in np.arange(math.ceil(low / step), math.floor(high / step) + 1) * step}
    step = math.gcd(*sorted(frequencies))
    return RecordSpec(band_hz=(float(min(frequencies)), float(max(frequencies))), step_hz=float(step), beats=tuple(sorted(beats)), doppler=doppler, cameras_per_render=128), cameras


def _check_size(sweeps):
    total = math.prod(len(v) for _, v in sweeps)
    if total > MAX_SWEEP_POINTS:
        raise ValueError(f"the sweep has {total} points, more than {MAX_SWEEP_POINTS}; use fewer values")


def as_records(records) -> list:
    """The records of a design as a list.

    Parameters
    ----------
    records : :class:`~dopplertof.design.Record`, or a list or tuple of them (the scenes).

    Returns
    -------
    list of Record, not empty.

    Raises
    ------
    ValueError
        For an empty list.
    """
    records = list(records) if isinstance(records, (list, tuple)) else [records]
    if not records:
        raise ValueError("design: no record (give at least one scene)")
    return records


def check_moving(records, names=None) -> None:
    """Refuse records with no moving pixel: the objectives are means over the moving pixels
    (:func:`summary`), which such a scene does not have (a static scene, or bodies whose
    motion ends before the exposure).

    Parameters
    ----------
    records : Record or list of Record (:func:`as_records`).
    names : list of str or None, default None
        What each record is (a scene's name or file) for the message; default ``record``
        (one) or ``record i``.

    Raises
    ------
    ValueError
        Naming the first record without a moving pixel.
    """
    from .precision import moving_pixels

    records = as_records(records)
    names = names or (["record"] if len(records) == 1 else [f"record {i}" for i in range(len(records))])
    for name, record in zip(names, records):
        if not moving_pixels(record).any():
            raise ValueError(f"{name}: no moving pixel (the ground-truth velocity is zero everywhere in the exposure); the design's objective is the mean bound over the moving pixels")


def summary(records, sensor) -> dict:
    """The bounds' summary averaged over the scenes of a design.

    Parameters
    ----------
    records : Record or list of Record (:func:`as_records`).
    sensor : :class:`dopplertof.Sensor`.

    Returns
    -------
    dict: ``velocity_crb_mean``, ``velocity_crb_median`` (m/s), ``depth_crb_mean``,
    ``depth_crb_median`` (m): each scene's (over its moving pixels,
    :meth:`~dopplertof.design.precision.Precision.summary`) averaged, every scene weighing
    the same; ``moving_pixels``: their sum.
    """
    summaries = [crb(r, sensor).summary() for r in as_records(records)]
    out = {k: float(np.mean([x[k] for x in summaries])) for k in summaries[0] if k != "moving_pixels"}
    out["moving_pixels"] = int(sum(x["moving_pixels"] for x in summaries))
    return out


def objective_value(records, sensor, objective: str) -> float:
    """The design's objective for ``sensor``.

    Parameters
    ----------
    records : Record or list of Record (:func:`as_records`).
    sensor : :class:`dopplertof.Sensor`.
    objective : str. One of :data:`OBJECTIVES`.

    Returns
    -------
    float (m/s or m): the mean bound over the moving pixels where it is finite, averaged
    over the scenes (:func:`summary`).

    Raises
    ------
    ValueError
        For an unknown objective, or what the records cannot read out.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}")
    return summary(records, sensor)[f"{objective}_mean"]


def sweep(records, sensor, sweeps, objective: str = "velocity_crb") -> list[dict]:
    """The objective on every combination of the sweeps' values.

    Parameters
    ----------
    records : Record or list of Record (:func:`as_records`): the scenes.
    sensor : :class:`dopplertof.Sensor`. The sensor the variants are made of (:func:`variant`).
    sweeps : list of (key, values) (:func:`parse_sweep`).
    objective : str. One of :data:`OBJECTIVES`. Default ``"velocity_crb"``.

    Returns
    -------
    list of dict, one per combination: the values, ``objective`` (NaN and ``status`` = the
    reason where the chip refuses the variant or no moving pixel's bound is finite, else
    ``"ok"``) and the mean and median
    bounds, averaged over the scenes (:func:`summary`).

    Raises
    ------
    ValueError
        For a grid of more than :data:`MAX_SWEEP_POINTS` points, or records without a
        moving pixel (:func:`check_moving`).
    """
    _check_size(sweeps)
    check_moving(records)
    keys = [k for k, _ in sweeps]
    rows = []
    for values in itertools.product(*[v for _, v in sweeps]):
        row = dict(zip(keys, map(float, values)))
        try:
            candidate = variant(sensor, row)
        except ValueError as exc:
            rows.append({**row, "objective": float("nan"), "status": f"refused: {exc}"})
            continue
        values = summary(records, candidate)
        finite = values[f"{objective}_mean"] == values[f"{objective}_mean"]  # NaN: no moving pixel has a finite bound
        status = "ok" if finite else f"no bound: {objective} is infinite at every moving pixel (the frames carry no information on it)"
        rows.append({**row, "objective": values[f"{objective}_mean"], **values, "status": status})
    return rows


def optimize(records, sensor, keys, objective: str = "velocity_crb", *, iterations: int = 50):
    """Minimise the objective over ``keys`` from ``sensor``'s values.

    Parameters
    ----------
    records : Record or list of Record (:func:`as_records`): the scenes; the objective is
        averaged over them (:func:`summary`), the phase gradient too.
    sensor : :class:`dopplertof.Sensor`. The start.
    keys : list of str. Of :data:`OPTIMIZE_KEYS`.
    objective : str. One of :data:`OBJECTIVES`. Default ``"velocity_crb"``.
    iterations : int. At most this many steps. Default 50.

    Returns
    -------
    (best sensor, history): history holds one dict per step with the values and the
    objective.

    Raises
    ------
    ValueError
        For unknown keys, or records without a moving pixel (:func:`check_moving`).
    """
    from .gradient import gradient

    unknown = [k for k in keys if k not in OPTIMIZE_KEYS]
    if unknown or not keys:
        raise ValueError(f"--optimize: choose keys among {', '.join(OPTIMIZE_KEYS)}, got {list(keys)!r}")
    check_moving(records)
    best, best_value = sensor, objective_value(records, sensor, objective)
    history = [_state(best, best_value)]
    for _ in range(iterations):
        improved = False
        if "modulation_frequency" in keys:
            candidate, value = _frequency_step(records, best, best_value, objective)
            if value < best_value:
                best, best_value, improved = candidate, value, True
        if "phase" in keys:
            candidate, value = _phase_step(records, best, best_value, objective, gradient)
            if value < best_value * (1 - 1e-9):
                best, best_value, improved = candidate, value, True
        history.append(_state(best, best_value))
        if not improved:
            break
    return best, history


def _state(sensor, value):
    return {"objective": value, "modulation_frequency": sensor.frames[0].modulation_frequency, "phases": [f.phase for f in sensor.frames]}


def _frequency_step(records, sensor, value, objective):
    """The best of the grid frequencies at ±1, ±2, ±4, … grid steps from the current one
    (within the records, which share one grid, and the chip's range), or the current one."""
    grid = as_records(records)[0].spec.frequencies_hz
    f0 = sensor.frames[0].modulation_frequency
    here = int(np.argmin(np.abs(grid - f0)))
    best, best_value = sensor, value
    jump = 1
    while jump < grid.size:
        for index in (here - jump, here + jump):
            if 0 <= index < grid.size:
                try:
                    candidate = variant(sensor, {"modulation_frequency": grid[index]})
                    v = objective_value(records, candidate, objective)
                except ValueError:
                    continue  # outside the chip's range, or a harmonic beyond the record
                if v < best_value:
                    best, best_value = candidate, v
        jump *= 2
    return best, best_value


def _phase_step(records, sensor, value, objective, gradient):
    """One gradient step on the frames' phases (the gradient averaged over the scenes) with
    a backtracking line search."""
    phases = [("phase", i) for i in range(len(sensor.frames))]
    by_scene = [gradient(r, sensor, objective, phases).by_parameter for r in as_records(records)]
    direction = np.array([np.mean([g[p] for g in by_scene]) for p in phases])
    norm = np.linalg.norm(direction)
    if norm == 0:
        return sensor, value
    step = 0.5 / norm  # at most half a radian first
    for _ in range(20):
        frames = [dataclasses.replace(f, phase=f.phase - step * d) for f, d in zip(sensor.frames, direction)]
        try:
            candidate = dataclasses.replace(sensor, frames=frames)
            v = objective_value(records, candidate, objective)
        except ValueError:
            v = math.inf
        if v < value:
            return candidate, v
        step *= 0.5
    return sensor, value
