"""Pictures of rendered images: tone mapping, signed colour maps, figures and animations.

Everything here makes 8-bit pictures for people to look at; data files (EXR, NPY, JSON)
are written by :mod:`dopplertof.io`.

=======================  ==================================================================
Function                 Meaning
=======================  ==================================================================
``linear_to_srgb``       IEC 61966-2-1 sRGB transfer curve, linear [0, 1] to encoded [0, 1]
``to_srgb8``             linear radiance to uint8 sRGB (exposure, clipping, NaN to black)
``auto_vmax``            default half-range of a signed colour map (99th pct. of abs value)
``signed_to_rgb8``       signed (H, W) map to uint8 RGB with a symmetric diverging map
``save_png``             write a uint8 picture as PNG
``save_intensity_png``   ``to_srgb8`` + ``save_png``
``save_signed_png``      signed map as PNG, optionally a figure with a labelled colourbar
``save_velocity_png``    ``save_signed_png`` for a velocity map in m/s
``comparison_figure``    side-by-side panels sharing one colour range and one colourbar
``plot_curves``          line plot with optional +-error shading
``write_gif``            animated GIF from uint8 frames
=======================  ==================================================================

Signed maps (velocities, Doppler phase differences) always use a symmetric range
[-vmax, vmax], so zero is the centre colour of the diverging colour map (white for
``"RdBu_r"``), positive values go to the upper end (red) and negative values to the lower
end (blue); values beyond the range are clipped to the end colours. NaN pixels (no
measurement) are drawn mid grey, ``NAN_RGB8``, which no diverging map's centre uses.

Figures are drawn with matplotlib's object-oriented API on an Agg canvas, never through
``pyplot``: this works without a display and leaves the caller's matplotlib backend and
open figures alone.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Mapping, Sequence, Union

import imageio.v3 as iio
import matplotlib
import matplotlib.colors
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .io import atomic_path

PathLike = Union[str, "os.PathLike[str]"]

#: Colour of NaN pixels in signed maps, uint8 RGB (mid grey).
NAN_RGB8 = (128, 128, 128)

#: Percentile of |finite values| used as the default half-range of signed maps.
AUTO_VMAX_PERCENTILE = 99.0

#: Resolution of figures with axes and colourbars, dots per inch.
FIGURE_DPI = 100
GIF_MAX_FRAME_S = 655.35  # a GIF frame's delay is a 16-bit count of hundredths of a second

# sRGB transfer curve constants (IEC 61966-2-1).
_SRGB_LINEAR_THRESHOLD = 0.0031308
_SRGB_LINEAR_SLOPE = 12.92
_SRGB_GAMMA = 2.4
_SRGB_SCALE = 1.055
_SRGB_OFFSET = 0.055


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------

def _prepare_output(path: PathLike, suffix: str) -> Path:
    """Check the suffix of ``path`` and create its parent directories."""
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise ValueError(f"expected a '{suffix}' file, got '{path}'")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _as_signed_map(image: np.ndarray) -> np.ndarray:
    """Return a (H, W) float64 array, or raise ``ValueError`` (luminance hint for RGB)."""
    array = np.asarray(image)
    if array.ndim == 3 and array.shape[2] in (3, 4):
        raise ValueError(
            f"signed maps must have shape (H, W), got shape {array.shape}; pass one channel "
            "or a luminance, e.g. image @ [0.2126, 0.7152, 0.0722]"
        )
    if array.ndim != 2:
        raise ValueError(f"signed maps must have shape (H, W), got shape {array.shape}")
    if array.size == 0:
        raise ValueError(f"image must not be empty, got shape {array.shape}")
    if np.iscomplexobj(array):
        raise ValueError(f"image must be real-valued, got dtype {array.dtype}")
    return array.astype(np.float64)


def _check_vmax(vmax: float) -> float:
    vmax = float(vmax)
    if not (math.isfinite(vmax) and vmax > 0):
        raise ValueError(f"vmax must be finite and > 0, got {vmax}")
    return vmax


def _get_cmap(cmap: str | matplotlib.colors.Colormap) -> matplotlib.colors.Colormap:
    if isinstance(cmap, matplotlib.colors.Colormap):
        return cmap
    try:
        return matplotlib.colormaps[cmap]
    except KeyError:
        raise ValueError(f"unknown matplotlib colour map {cmap!r}") from None


def _signed_cmap(cmap: str | matplotlib.colors.Colormap) -> matplotlib.colors.Colormap:
    """The colour map with NaN drawn as ``NAN_RGB8``, as in ``signed_to_rgb8``."""
    return _get_cmap(cmap).with_extremes(bad=np.asarray(NAN_RGB8) / 255.0)


def _panel_size_in(shape: tuple[int, int], height_in: float = 3.5) -> tuple[float, float]:
    """(width, height) in inches of an image panel of a given pixel shape."""
    height, width = shape
    aspect = min(max(width / height, 0.25), 4.0)
    return height_in * aspect, height_in


def _save_figure(figure: Figure, path: Path) -> None:
    FigureCanvasAgg(figure)  # attaches itself to the figure; no pyplot, no global backend
    with atomic_path(path) as tmp:
        figure.savefig(tmp, dpi=FIGURE_DPI, format="png")


def _add_colorbar(figure: Figure, mappable, axes, vmax: float, data: list[np.ndarray],
                  unit: str | None, signed: bool) -> None:
    # Arrow ends on the colourbar tell the reader that some values were clipped.
    clipped_high = any(np.any(d > vmax) for d in data)
    clipped_low = signed and any(np.any(d < -vmax) for d in data)
    extend = {(False, False): "neither", (True, False): "max",
              (False, True): "min", (True, True): "both"}[(clipped_high, clipped_low)]
    colorbar = figure.colorbar(mappable, ax=axes, extend=extend, shrink=0.9)
    if unit:
        colorbar.set_label(unit)


# ---------------------------------------------------------------------------------------------
# Tone mapping and colour maps
# ---------------------------------------------------------------------------------------------

def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Apply the sRGB transfer curve (IEC 61966-2-1) to linear values.

    Parameters
    ----------
    linear : array_like, any shape
        Linear intensities; clipped to [0, 1] first, NaN becomes 0.

    Returns
    -------
    numpy.ndarray of float64, same shape
        Encoded values in [0, 1]: ``12.92 x`` up to x = 0.0031308, then
        ``1.055 x**(1/2.4) - 0.055`` (continuous at the threshold).
    """
    x = np.clip(np.nan_to_num(np.asarray(linear, dtype=np.float64), nan=0.0), 0.0, 1.0)
    return np.where(
        x <= _SRGB_LINEAR_THRESHOLD,
        _SRGB_LINEAR_SLOPE * x,
        _SRGB_SCALE * np.power(x, 1.0 / _SRGB_GAMMA) - _SRGB_OFFSET,
    )


def to_srgb8(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Tone-map linear radiance to an 8-bit sRGB picture.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3)
        Linear radiance (any unit; 1.0 after exposure is white). Grey images are
        replicated to three channels.
    exposure : float, optional
        Linear scale applied before encoding, finite and > 0. Default 1.

    Returns
    -------
    numpy.ndarray of uint8, shape (H, W, 3)
        sRGB-encoded picture; values are clipped to [0, 1] before encoding, NaN and
        negative values become 0 (black), +inf becomes 255.

    Raises
    ------
    ValueError
        If the shape is not (H, W) or (H, W, 3), the image is empty or complex, or
        ``exposure`` is not finite and positive.
    """
    array = np.asarray(image)
    if not (array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 3)):
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got shape {array.shape}")
    if array.size == 0:
        raise ValueError(f"image must not be empty, got shape {array.shape}")
    if np.iscomplexobj(array):
        raise ValueError(f"image must be real-valued, got dtype {array.dtype}")
    exposure = float(exposure)
    if not (math.isfinite(exposure) and exposure > 0):
        raise ValueError(f"exposure must be finite and > 0, got {exposure}")

    linear = array.astype(np.float64) * exposure
    if linear.ndim == 2:
        linear = np.repeat(linear[:, :, None], 3, axis=2)
    return np.round(linear_to_srgb(linear) * 255.0).astype(np.uint8)


def auto_vmax(values: np.ndarray | Sequence[np.ndarray]) -> float:
    """Default half-range of a symmetric colour map for signed data.

    Parameters
    ----------
    values : array_like or sequence of array_like
        Signed data (several arrays are pooled, e.g. the panels of a comparison).

    Returns
    -------
    float
        The 99th percentile of |x| over finite x; if that is 0 (mostly zeros), the largest
        finite |x|; if that is 0 too, or there is no finite value, 1.0.
    """
    if isinstance(values, np.ndarray):
        pooled = values.ravel()
    else:
        pooled = np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in values])
    magnitudes = np.abs(pooled[np.isfinite(pooled)])
    if magnitudes.size == 0:
        return 1.0
    vmax = float(np.percentile(magnitudes, AUTO_VMAX_PERCENTILE))
    if vmax == 0.0:
        vmax = float(magnitudes.max())
    return vmax if vmax > 0.0 else 1.0


def signed_to_rgb8(image: np.ndarray, vmax: float | None = None,
                   cmap: str | matplotlib.colors.Colormap = "RdBu_r") -> np.ndarray:
    """Colour a signed map with a diverging colour map over the symmetric range [-vmax, vmax].

    Parameters
    ----------
    image : array_like, shape (H, W)
        Signed values in any unit (e.g. velocity in m/s). RGB images are refused: pass a
        single channel or a luminance.
    vmax : float, optional
        Half-range, same unit as ``image``, finite and > 0. Default :func:`auto_vmax`.
    cmap : str or matplotlib.colors.Colormap, optional
        Diverging colour map. Default ``"RdBu_r"`` (negative blue, zero white, positive red).

    Returns
    -------
    numpy.ndarray of uint8, shape (H, W, 3)
        0 maps to ``cmap(0.5)``, +vmax and above to ``cmap(1.0)``, -vmax and below to
        ``cmap(0.0)``; NaN pixels are ``NAN_RGB8`` (mid grey).

    Raises
    ------
    ValueError
        If the image is not (H, W) (for (H, W, 3): pass luminance), is empty or complex,
        ``vmax`` is not finite and positive, or ``cmap`` is unknown.
    """
    values = _as_signed_map(image)
    vmax = auto_vmax(values) if vmax is None else _check_vmax(vmax)
    colormap = _get_cmap(cmap)

    nan = np.isnan(values)
    # +-inf clip to the ends like any other out-of-range value.
    normalised = np.clip((np.where(nan, 0.0, values) + vmax) / (2.0 * vmax), 0.0, 1.0)
    rgb8 = colormap(normalised, bytes=True)[:, :, :3]
    rgb8[nan] = NAN_RGB8
    return np.ascontiguousarray(rgb8)


# ---------------------------------------------------------------------------------------------
# PNG pictures
# ---------------------------------------------------------------------------------------------

def save_png(path: PathLike, rgb8: np.ndarray) -> Path:
    """Write an 8-bit picture as a PNG file, one file pixel per array element.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``; missing parent directories are created.
    rgb8 : numpy.ndarray of uint8, shape (H, W), (H, W, 3) or (H, W, 4)
        Grey, RGB or RGBA picture (e.g. from :func:`to_srgb8`).

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If the suffix is not ``.png``, the dtype is not uint8 or the shape is unsupported.
    """
    picture = np.asarray(rgb8)
    if picture.dtype != np.uint8:
        raise ValueError(
            f"picture must be uint8, got dtype {picture.dtype}; use to_srgb8 or signed_to_rgb8"
        )
    if not (picture.ndim == 2 or (picture.ndim == 3 and picture.shape[2] in (3, 4))):
        raise ValueError(
            f"picture must have shape (H, W), (H, W, 3) or (H, W, 4), got shape {picture.shape}"
        )
    if picture.size == 0:
        raise ValueError(f"picture must not be empty, got shape {picture.shape}")
    path = _prepare_output(path, ".png")
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, picture, extension=".png")
    return path


def save_intensity_png(path: PathLike, image: np.ndarray, exposure: float = 1.0) -> Path:
    """Write linear radiance as an sRGB PNG of the same pixel size.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``.
    image : array_like, shape (H, W) or (H, W, 3)
        Linear radiance, see :func:`to_srgb8`.
    exposure : float, optional
        Linear scale before encoding, finite and > 0. Default 1.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    return save_png(path, to_srgb8(image, exposure=exposure))


def save_signed_png(path: PathLike, image: np.ndarray, vmax: float | None = None,
                    cmap: str | matplotlib.colors.Colormap = "RdBu_r", colorbar: bool = False,
                    title: str | None = None, unit: str | None = None) -> float:
    """Write a signed map as a PNG with a symmetric diverging colour map.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``.
    image : array_like, shape (H, W)
        Signed values, see :func:`signed_to_rgb8`.
    vmax : float, optional
        Half-range, same unit as ``image``. Default :func:`auto_vmax`.
    cmap : str or matplotlib.colors.Colormap, optional
        Diverging colour map. Default ``"RdBu_r"``.
    colorbar : bool, optional
        False (default): the PNG is the coloured map itself, (H, W) pixels. True: a figure
        with the map, a colourbar labelled ``unit`` and ``title``; its size in pixels is
        chosen for legibility, not equal to (H, W).
    title : str, optional
        Figure title (only with ``colorbar=True``).
    unit : str, optional
        Colourbar label, e.g. ``"m/s"`` (only with ``colorbar=True``).

    Returns
    -------
    float
        The vmax used, same unit as ``image``.

    Raises
    ------
    ValueError
        As :func:`signed_to_rgb8`, or if the suffix is not ``.png``.
    """
    values = _as_signed_map(image)
    vmax = auto_vmax(values) if vmax is None else _check_vmax(vmax)
    if not colorbar:
        save_png(path, signed_to_rgb8(values, vmax=vmax, cmap=cmap))
        return vmax

    path = _prepare_output(path, ".png")
    panel_w, panel_h = _panel_size_in(values.shape)
    figure = Figure(figsize=(panel_w + 1.4, panel_h + (0.5 if title else 0.2)),
                    layout="constrained")
    axes = figure.add_subplot()
    mappable = axes.imshow(values, cmap=_signed_cmap(cmap), vmin=-vmax, vmax=vmax,
                           interpolation="nearest")
    axes.set_axis_off()
    _add_colorbar(figure, mappable, axes, vmax, [values], unit, signed=True)
    if title:
        figure.suptitle(title)
    _save_figure(figure, path)
    return vmax


def save_velocity_png(path: PathLike, velocity_m_s: np.ndarray, vmax: float | None = None,
                      title: str | None = None) -> float:
    """Write a radial-velocity map as a figure with an "m/s" colourbar.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``.
    velocity_m_s : array_like, shape (H, W)
        Velocity in m/s; NaN (no estimate) is drawn grey.
    vmax : float, optional
        Half-range in m/s. Default :func:`auto_vmax`.
    title : str, optional
        Figure title.

    Returns
    -------
    float
        The vmax used, m/s.
    """
    return save_signed_png(path, velocity_m_s, vmax=vmax, colorbar=True, title=title,
                           unit="m/s")


# ---------------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------------

def comparison_figure(path: PathLike, images: Mapping[str, np.ndarray], signed: bool = True,
                      vmax: float | None = None, title: str | None = None,
                      unit: str | None = None,
                      cmap: str | matplotlib.colors.Colormap | None = None) -> float:
    """Side-by-side panels with one shared colour range and one colourbar.

    Typical use: ``{"reconstructed": v_est, "ground truth": v_true}`` velocity maps.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``.
    images : mapping of str to array_like, each of shape (H, W)
        Panel title to data, drawn left to right in mapping order; all in the same unit.
        Shapes may differ.
    signed : bool, optional
        True (default): range [-vmax, vmax] with a diverging map (default ``"RdBu_r"``).
        False: range [0, vmax] with a sequential map (default ``"gray"``).
    vmax : float, optional
        Upper end of the shared range, finite and > 0. Default: :func:`auto_vmax` of all
        panels pooled (for ``signed=False`` the 99th percentile of the finite values).
    title : str, optional
        Figure title.
    unit : str, optional
        Colourbar label, e.g. ``"m/s"``.
    cmap : str or matplotlib.colors.Colormap, optional
        Overrides the default colour map. NaN is drawn mid grey.

    Returns
    -------
    float
        The vmax used.

    Raises
    ------
    ValueError
        If ``images`` is empty, a panel is not (H, W), ``vmax`` is not finite and positive,
        or the suffix is not ``.png``.
    """
    if not images:
        raise ValueError(f"images must contain at least one panel, got {dict(images)!r}")
    panels = {}
    for name, image in images.items():
        try:
            panels[str(name)] = _as_signed_map(image)
        except ValueError as error:
            raise ValueError(f"panel {name!r}: {error}") from None

    if vmax is not None:
        vmax = _check_vmax(vmax)
    elif signed:
        vmax = auto_vmax(list(panels.values()))
    else:
        # Non-negative data: the same pooled 99th percentile, with the same fallbacks.
        vmax = auto_vmax([np.clip(p, 0.0, None) for p in panels.values()])
    vmin = -vmax if signed else 0.0
    colormap = _signed_cmap(cmap if cmap is not None else ("RdBu_r" if signed else "gray"))

    path = _prepare_output(path, ".png")
    sizes = [_panel_size_in(p.shape, height_in=3.0) for p in panels.values()]
    figure = Figure(figsize=(sum(w for w, _ in sizes) + 1.5, 3.0 + (0.9 if title else 0.6)),
                    layout="constrained")
    axes = figure.subplots(1, len(panels), squeeze=False)[0]
    for ax, (name, values) in zip(axes, panels.items()):
        mappable = ax.imshow(values, cmap=colormap, vmin=vmin, vmax=vmax,
                             interpolation="nearest")
        ax.set_title(name)
        ax.set_axis_off()
    _add_colorbar(figure, mappable, list(axes), vmax, list(panels.values()), unit, signed)
    if title:
        figure.suptitle(title)
    _save_figure(figure, path)
    return vmax


def plot_curves(path: PathLike, x: np.ndarray,
                curves: Mapping[str, tuple[np.ndarray, np.ndarray | None] | np.ndarray],
                xlabel: str, ylabel: str, logy: bool = False,
                title: str | None = None) -> Path:
    """Line plot of several curves over a shared x axis, with optional +-error bands.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.png``.
    x : array_like, shape (N,)
        Abscissa shared by all curves.
    curves : mapping of str to (y, yerr) or y
        Legend label to ``y`` of shape (N,) and ``yerr`` of shape (N,) (>= 0, drawn as a
        shaded band y - yerr .. y + yerr) or None. A bare ``y`` means no band.
    xlabel, ylabel : str
        Axis labels; include the unit, e.g. ``"spp"``, ``"RMSE (m/s)"``.
    logy : bool, optional
        Logarithmic y axis (non-positive values and band edges are clipped). Default False.
    title : str, optional
        Figure title.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If ``x`` is not 1-D and non-empty, ``curves`` is empty, a ``y``/``yerr`` does not
        match ``x`` in shape, a ``yerr`` is negative, or the suffix is not ``.png``.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"x must be a non-empty 1-D array, got shape {x.shape}")
    if not curves:
        raise ValueError(f"curves must contain at least one curve, got {dict(curves)!r}")
    parsed = {}
    for label, curve in curves.items():
        if isinstance(curve, tuple):
            if len(curve) != 2:
                raise ValueError(f"curve {label!r} must be (y, yerr), got {len(curve)} items")
            y, yerr = curve
        else:
            y, yerr = curve, None
        y = np.asarray(y, dtype=np.float64)
        if y.shape != x.shape:
            raise ValueError(f"curve {label!r}: y has shape {y.shape}, x has shape {x.shape}")
        if yerr is not None:
            yerr = np.asarray(yerr, dtype=np.float64)
            if yerr.shape != x.shape:
                raise ValueError(
                    f"curve {label!r}: yerr has shape {yerr.shape}, x has shape {x.shape}"
                )
            if np.any(yerr < 0):
                raise ValueError(
                    f"curve {label!r}: yerr must be >= 0, got minimum {np.nanmin(yerr)}"
                )
        parsed[str(label)] = (y, yerr)

    path = _prepare_output(path, ".png")
    figure = Figure(figsize=(6.4, 4.4), layout="constrained")
    axes = figure.add_subplot()
    for label, (y, yerr) in parsed.items():
        (line,) = axes.plot(x, y, marker="o", markersize=3, label=label)
        if yerr is not None:
            axes.fill_between(x, y - yerr, y + yerr, color=line.get_color(), alpha=0.25,
                              linewidth=0)
    if logy:
        axes.set_yscale("log", nonpositive="clip")
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    if title:
        axes.set_title(title)
    _save_figure(figure, path)
    return path


# ---------------------------------------------------------------------------------------------
# Animation
# ---------------------------------------------------------------------------------------------

def write_gif(path: PathLike, frames: Sequence[np.ndarray], fps: float) -> Path:
    """Write frames as a looping animated GIF.

    GIF stores frame durations in hundredths of a second, so the playback rate is
    approximately ``fps`` (exact for divisors of 100, e.g. 10, 20, 25, 50). The GIF
    encoder (Pillow) merges consecutive identical frames into one longer frame, so the
    file can hold fewer frames than given while the total duration is kept.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.gif``; missing parent directories are created.
    frames : sequence of numpy.ndarray of uint8, each of shape (H, W, 3)
        The frames, all the same shape (e.g. from :func:`to_srgb8`).
    fps : float
        Frames per second, finite and >= 1 / :data:`GIF_MAX_FRAME_S` (a frame lasts at
        most 655.35 s).

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If ``fps`` is not finite or below 1 / 655.35 s, ``frames`` is empty, a frame is not uint8
        (H, W, 3), the frames differ in shape, or the suffix is not ``.gif``.
    """
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be finite and > 0, got {fps}")
    if 1.0 / fps > GIF_MAX_FRAME_S:
        raise ValueError(f"fps must be >= {1.0 / GIF_MAX_FRAME_S:.4g}: a GIF frame lasts at most {GIF_MAX_FRAME_S} s, got fps={fps!r}")
    frames = [np.asarray(frame) for frame in frames]
    if not frames:
        raise ValueError("frames must contain at least one frame, got 0")
    first_shape = frames[0].shape
    for index, frame in enumerate(frames):
        if frame.dtype != np.uint8:
            raise ValueError(f"frame {index} must be uint8, got dtype {frame.dtype}")
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.size == 0:
            raise ValueError(f"frame {index} must have shape (H, W, 3), got {frame.shape}")
        if frame.shape != first_shape:
            raise ValueError(
                f"frame {index} has shape {frame.shape}, frame 0 has shape {first_shape}"
            )
    path = _prepare_output(path, ".gif")
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, np.stack(frames), extension=".gif", duration=1000.0 / fps, loop=0)
    return path
