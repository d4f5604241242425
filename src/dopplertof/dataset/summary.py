"""What a dataset holds: counts, value ranges and histograms of the ground truth, and a
contact sheet of a few samples (``dopplertof dataset info DIR``)."""

from __future__ import annotations

import math
import os
from collections import Counter

import numpy as np

from ..outputs import MOVING_PIXEL_M_S
from ..validation import checked_in_range
from .reader import open_dataset

_BINS = 10
_BAR_WIDTH = 30


def _histogram_lines(values: np.ndarray, unit: str, bins: int = _BINS) -> list[str]:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return ["    (no values)"]
    lo, hi = float(values.min()), float(values.max())
    if hi == lo:
        return [f"    all {values.size} values = {lo:.4g} {unit}"]
    counts, edges = np.histogram(values, bins=bins, range=(lo, hi))
    peak = counts.max()
    return [f"    {edges[k]:10.4g} … {edges[k + 1]:<10.4g} {unit:4s} {'█' * int(round(_BAR_WIDTH * c / peak)):<{_BAR_WIDTH}s} {c}"
            for k, c in enumerate(counts)]


def summarize(folder, sheet: str | None = None, sheet_samples: int = 4, max_samples: int | None = None) -> dict:
    """Statistics of the dataset in ``folder`` and (with ``sheet``) a contact-sheet PNG.

    Parameters
    ----------
    folder : str or path
        Dataset folder.
    sheet : str, optional
        PNG path of the contact sheet: one row per sample (intensity, every measurement,
        ground-truth velocity; signed images on a symmetric diverging scale per row).
    sheet_samples : int
        Rows of the contact sheet (the first samples).
    max_samples : int, optional
        Summarise only the first ``max_samples`` samples (default: all finished ones).

    Returns
    -------
    dict
        ``lines`` (the printable report) and ``stats`` (numbers: samples, shards, scene
        kinds, sensors drawn, depth and velocity ranges, moving fractions, body speeds, moving
        cameras), ``sheet_error``: why the contact sheet could not be written (a read-only
        or full folder), else None.
    """
    sheet_samples = checked_in_range("sheet_samples", sheet_samples, at_least=1, kind="int")
    if max_samples is not None:
        max_samples = checked_in_range("max_samples", max_samples, at_least=1, kind="int")
    ds = open_dataset(folder)
    m = ds.manifest
    depths, speeds, body_speeds, spins, ego_speeds = [], [], [], [], []
    kinds: Counter = Counter()
    sensors: Counter = Counter()  # the sensor model of each sample (config key sensor.model), if any
    moving_px = total_px = sees_motion_px = 0
    rows = []
    sheet_error = None
    n = 0
    for sample in ds:
        if max_samples is not None and n >= max_samples:
            break
        rec = sample["json"]
        kinds[rec["scene"]["kind"]] += 1
        if "model" in rec["sensor"]:
            sensors[rec["sensor"]["model"]["name"]] += 1
        depths.append(sample["depth"].ravel())
        v = sample["velocity"].ravel()
        speeds.append(np.abs(v))
        sees_motion_px += int(np.sum(np.abs(v[np.isfinite(v)]) > MOVING_PIXEL_M_S))
        total_px += v.size
        if "moving_mask" in sample:
            moving_px += int(sample["moving_mask"].sum())
        body_speeds += [b["speed_m_s"] for b in rec["bodies"]]
        spins += [b["spin_rad_s"] for b in rec["bodies"]]
        ego = rec.get("camera_motion", {"moving": False})  # records before ego-motion: a static camera
        if ego["moving"]:
            ego_speeds.append(ego["speed_m_s"])
        if sheet and len(rows) < sheet_samples:
            rows.append(_sheet_row(sample))
        n += 1
    depth = np.concatenate(depths) if depths else np.empty(0)
    speed = np.concatenate(speeds) if speeds else np.empty(0)
    has_mask = "moving_mask" in ds.fields
    stats = {
        "samples": n,
        "samples_planned": m["samples"],
        "shards_done": m["shards_done"],
        "shards": len(m["shards"]),
        "complete": m["complete"],
        "scene_kinds": dict(kinds),
        "sensors": dict(sensors),
        "depth_m": [float(np.nanmin(depth)), float(np.nanmax(depth))] if np.isfinite(depth).any() else None,
        "speed_m_s": [float(np.nanmin(speed)), float(np.nanmax(speed))] if np.isfinite(speed).any() else None,
        "no_hit_fraction": float(np.mean(~np.isfinite(depth))) if depth.size else None,
        "pixels_seeing_motion_fraction": sees_motion_px / total_px if total_px else None,
        "moving_mask_fraction": moving_px / total_px if (has_mask and total_px) else None,
        "moving_bodies": len(body_speeds),
        "moving_cameras": len(ego_speeds),
    }
    lines = [
        f"dataset {os.fspath(folder)}: {n} samples read of {m['samples']} planned; {m['shards_done']}/{len(m['shards'])} shards done"
        f"{'' if m['complete'] else ' (incomplete)'}; seed {m['seed']}, {m['config']['render']['resolution']}², {m['config']['render']['spp']} spp, "
        f"variant {m['variant']}",
        f"fields: {', '.join(ds.fields)}" + (f"; missing (renderer lacks them): {', '.join(m['missing_fields'])}" if m["missing_fields"] else ""),
        f"scene kinds: {', '.join(f'{k} {c}' for k, c in sorted(kinds.items()))}; moving bodies: {len(body_speeds)}; moving cameras: {len(ego_speeds)}",
        *([f"sensors (raw_electrons, raw_dn): {', '.join(f'{k} {c}' for k, c in sorted(sensors.items()))}"] if sensors else []),
        f"moving fraction: {stats['moving_mask_fraction']:.4f} of pixels (moving_mask)" if stats["moving_mask_fraction"] is not None
        else "moving fraction (moving_mask): n/a, the dataset has no instance_id",
        f"pixels whose radial velocity exceeds {MOVING_PIXEL_M_S * 1e3:g} mm/s: {stats['pixels_seeing_motion_fraction']:.4f}"
        if total_px else "no pixels",
        f"pixels without a hit (background): {stats['no_hit_fraction']:.4f}" if depth.size else "",
        "depth (m), hit pixels:",
        *_histogram_lines(depth, "m"),
        "|radial velocity| (m/s) on pixels seeing motion:",
        *_histogram_lines(speed[speed > MOVING_PIXEL_M_S], "m/s"),
        "body speed (m/s):",
        *_histogram_lines(np.asarray(body_speeds, dtype=np.float64), "m/s"),
        "body spin rate (rad/s):",
        *_histogram_lines(np.asarray(spins, dtype=np.float64), "r/s"),
        "camera speed (m/s), moving cameras:",
        *_histogram_lines(np.asarray(ego_speeds, dtype=np.float64), "m/s"),
    ]
    if sheet and rows:
        from .. import viz

        width = max(r.shape[1] for r in rows)
        padded = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
        try:
            viz.save_png(sheet, np.concatenate(padded, axis=0))
            lines.append(f"contact sheet: {sheet} (per row: intensity, measurements {_camera_labels(m)}, ground-truth velocity)")
        except OSError as exc:
            sheet_error = f"the contact sheet {sheet} cannot be written ({exc.strerror or exc}); the report above is complete: pass --sheet PATH elsewhere or --sheet none"
    return {"lines": [line for line in lines if line], "stats": stats, "sheet_error": sheet_error}


def _camera_labels(manifest) -> str:
    cam = manifest["config"]["camera"]
    return ", ".join(f"h={h:g} ψ={p:g}°" for h, p in zip(cam["heterodyne"], cam["phase_deg"]))


def _upscale(tile: np.ndarray, min_size: int = 128) -> np.ndarray:
    k = max(1, math.ceil(min_size / tile.shape[0]))
    return np.repeat(np.repeat(tile, k, axis=0), k, axis=1)


def _sheet_row(sample: dict) -> np.ndarray:
    from .. import viz
    from ..sensor import luminance

    intensity = sample["intensity"]
    lum = luminance(intensity)
    finite = lum[np.isfinite(lum)]
    bright = float(np.percentile(finite, 99)) if finite.size else 0.0
    tiles = [viz.to_srgb8(np.nan_to_num(intensity), 0.8 / bright if bright > 0 else 1.0)]
    meas = sample["measurements"]
    tiles += [viz.signed_to_rgb8(m) for m in meas]  # each on its own scale: heterodyne images are ~1 % of homodyne ones
    tiles.append(viz.signed_to_rgb8(sample["velocity"]))
    gap = np.full((tiles[0].shape[0], 2, 3), 255, dtype=np.uint8)
    row = []
    for t in tiles:
        row += [t, gap]
    out = _upscale(np.concatenate(row[:-1], axis=1))
    return np.pad(out, ((0, 4), (0, 0), (0, 0)), constant_values=255)
