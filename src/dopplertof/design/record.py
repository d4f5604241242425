"""A scene's response record: render once, read out any sensor in a declared band.

Every sensor-side parameter enters a render only through the low-pass weight of each path
contribution (:mod:`dopplertof.modulation`). A low-pass weight is a sum of harmonics,

    W(u, L) = c₀ + Re Σ_{m≥1} a_m e^{i m (2π h u + ψ + k L)},     k = 2π f / c,

(the sinusoid: a₁ = g₁/2; a coded camera: a_m = g₁ K_m, c₀ = g₁ K₀ + g₀ s̄, K_m the harmonics
of its correlation, :mod:`dopplertof.codes`), so a pixel's measurement is

    M = c₀ Ī + Re Σ_m a_m e^{imψ} R(m f, m h),     R(F, ν) = ⟨lum · e^{i 2π ν u} e^{i 2π F L / c}⟩,

with ⟨·⟩ the estimator's average over the pixel's samples and Ī = ⟨lum⟩ the window's mean
luminance. The record holds, per exposure window and pixel, Ī and R(F, ν) on a declared grid:
every multiple F of ``step_hz`` in ``band_hz`` crossed with the declared ``beats`` ν (beat
cycles per exposure: the heterodyne ratios h, their multiples m h for codes, integer or
not). The tracing kernel accumulates them while it traces the render's own paths
(:class:`~dopplertof.tracing.sink.PhasorGrid`: per lane, every contribution's phasors over
the frequency grid, the beats from the lane's time, summed per pixel in Float64), so a
sensor read out of the record equals the same sensor rendered directly (same seed, same
windows in the same order) to rounding: the record is *exact* wherever it applies, and
refuses everything else (:func:`evaluate`):

* a frequency m f (every harmonic m of the camera's correlation with a non-zero
  coefficient) outside ``band_hz`` or not a multiple of ``step_hz``;
* a beat m h not among ``beats``;
* an exposure window that was not recorded;
* weights with unbounded harmonics: the full-waveform model, the named rectangular,
  triangular and trapezoidal waveforms and sampled codes without ``light_bandwidth`` (give
  the rectangular and trapezoidal waveforms and codes the source's bandwidth, at most the
  band's top, and they are band-limited and exact).

Size: 8 bytes per (F, ν) pair and pixel plus 4 for Ī, per window
(:meth:`RecordSpec.bytes_per_pixel`): a 256² record of 10–300 MHz at 1 MHz with beats
(0, 1) is 0.3 GB. Cost: a kernel holds :data:`FREQUENCIES_PER_KERNEL` frequencies; the first
run of them rides on the render's own passes (1.4× a plain render for 30 frequencies and 2
beats, docs/design.md), each further run traces the paths again. The paired tracers
(:func:`by_probes`) record through probe cameras instead: each R(F, ν) the measurement of
a sinusoidal camera (frequency F, heterodyne ν, ψ = 0 and −π/2), ``cameras_per_render`` of
them per kernel, each chunk re-tracing the paths.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..codes import NAMED_CODES
from ..modulation import MAX_HETERODYNE, MAX_MODULATION_FREQUENCY_HZ, SUSPICIOUS_MODULATION_FREQUENCY_HZ, Camera
from ..validation import checked

# A grid longer than this is a unit mistake (MHz given as Hz): 4096 frequencies per beat
# and pixel are already 32 kB per pixel.
MAX_FREQUENCIES = 4096
MAX_BEATS = 64
# Harmonics of a correlation smaller than this fraction of its largest are zero (rounding
# of the chips' transform), not a term the record must hold.
NEGLIGIBLE_HARMONIC = 1e-9
# How close (relative) a frequency or beat must be to the grid to be on it.
GRID_TOLERANCE = 1e-9
# Beat step δ (cycles per exposure) of the central difference that gives the first moments:
# its truncation error, (2πδ)²/6 ≈ 7e-6 relative, and the Float32 rounding of the lanes'
# sums divided by 4πδ, about 1e-5 relative, are both far below a render's noise.
MOMENT_BEAT_STEP = 1e-3
# Frequency step δF (Hz) of the central difference that gives the slopes ∂R/∂F: a phase step
# 2π δF L / c of 1e-2 rad at 5 m (truncation 2e-5 relative), large enough that the Float32
# rounding of the mixed difference ∂R₁/∂F stays near 1e-3 relative.
SLOPE_FREQUENCY_STEP_HZ = 1e5
# Frequencies one tracing kernel accumulates (:class:`~dopplertof.tracing.sink.PhasorGrid`):
# their sums are per-lane loop state (8 bytes each, twice with ``slopes``), and a record of
# more frequencies traces the paths again for every further run of them.
FREQUENCIES_PER_KERNEL = 32
# What a record may hold beside R: the first moments R₁ (``doppler``), the slopes ∂R/∂F
# (``slopes``) and ∂R₁/∂F (both), and the derivatives of R and R₁ with respect to the
# window's exposure T and start (``window_slopes``).
DERIVED = ("moments", "slopes", "moment_slopes", "exposure_slopes", "start_slopes", "exposure_moment_slopes", "start_moment_slopes")
# Step of the central differences that give the window slopes, as a fraction of the
# window's exposure: at 10 m/s and 1 ms it moves a path by 0.1 mm (a phase step of 4e-4 rad
# at 100 MHz, against the lanes' float32 rounding of 1e-7), with a truncation error of
# (δ/T)² ≈ 1e-4 of the second derivative's share.
WINDOW_STEP = 1e-2


@dataclass(frozen=True)
class RecordSpec:
    """What a record holds (module docstring).

    Parameters
    ----------
    band_hz : (float, float), Hz. Lowest and highest frequency F recorded (every harmonic of
        an evaluated camera must lie in it). Default (10 MHz, 300 MHz). A band below
        100 kHz is honoured with a warning (Hz written for MHz, as the Camera warns).
    step_hz : float, Hz. The grid: every multiple of it in ``band_hz``. Default 10 MHz.
    beats : sequence of float. The beat cycles per exposure ν recorded (a camera with
        heterodyne h needs m h for each of its harmonics m). Default (0, 1): homodyne and
        the one-beat heterodyne.
    cameras_per_render : int. Probe cameras traced per kernel where the record is rendered
        by probe cameras (the paired tracers, :func:`by_probes`; bounds the kernel's state:
        4 bytes per camera and lane). Default 32.
    doppler : bool. Also record the first moments R₁(F, ν) = ⟨lum · u e^{i2πνu} e^{i2πFL/c}⟩,
        the derivative of every measurement with respect to the paths' rate L̇ that
        precision maps need (:func:`dopplertof.design.crb`): exact in the kernel (the
        lane's u times its R; probe cameras: a central difference in ν, tripling the
        probes). They double the size. Default False.
    slopes : bool. Also record the slopes ∂R/∂F (and, with ``doppler``, ∂R₁/∂F): the
        derivative of every measurement with respect to the modulation frequency, which
        frequency gradients need (:func:`dopplertof.design.gradient`): exact in the kernel
        (i2πL/c per contribution; probe cameras: a central difference in F). They double
        the size again. Default False.
    window_slopes : bool. Also record the derivatives of Ī, R (and, with ``doppler``, R₁)
        with respect to each window's exposure T and start (1/s): central differences of
        the window traced again at T ± δ and start ± δ with its own seed (same random
        numbers, δ = :data:`WINDOW_STEP` × T), which exposure and start gradients need.
        Four more traces of every window; not with the paired tracers (probe cameras).
        Default False.
    """

    band_hz: tuple = (10e6, 300e6)
    step_hz: float = 10e6
    beats: tuple = (0.0, 1.0)
    cameras_per_render: int = 32
    doppler: bool = False
    slopes: bool = False
    window_slopes: bool = False

    def __post_init__(self):
        band = self.band_hz
        if not isinstance(band, (tuple, list)) or len(band) != 2:
            raise ValueError(f"record: 'band_hz' must be (lowest, highest) in Hz, got {band!r}")
        low, high = (checked("band_hz", b, "float", "record") for b in band)
        if not 0 < low <= high <= MAX_MODULATION_FREQUENCY_HZ:
            raise ValueError(f"record: 'band_hz' must satisfy 0 < lowest <= highest <= {MAX_MODULATION_FREQUENCY_HZ:g} Hz, got {band!r}")
        step = checked("step_hz", self.step_hz, "float", "record")
        if not step > 0:
            raise ValueError(f"record: 'step_hz' must be > 0 Hz, got {self.step_hz!r}")
        object.__setattr__(self, "band_hz", (low, high))
        object.__setattr__(self, "step_hz", step)
        if high < SUSPICIOUS_MODULATION_FREQUENCY_HZ:  # the Camera's warning, for the same unit mistake
            warnings.warn(f"record: band_hz={self.band_hz!r} Hz is below {SUSPICIOUS_MODULATION_FREQUENCY_HZ / 1e3:g} kHz; the unit is Hz (10 MHz is 10e6)", stacklevel=3)
        first, last = self._multiples()
        n = max(last - first + 1, 0)  # counted, not made: a unit mistake may ask for 10⁹
        if n == 0:
            raise ValueError(f"record: no multiple of step_hz={step:g} Hz lies in band_hz={band!r}")
        if n > MAX_FREQUENCIES:
            raise ValueError(f"record: band_hz={band!r} at step_hz={step:g} Hz is {n} frequencies, more than {MAX_FREQUENCIES}; use a coarser step or a narrower band")
        if isinstance(self.beats, (str, bytes)) or not hasattr(self.beats, "__iter__"):
            raise ValueError(f"record: 'beats' must be a sequence of beat cycles per exposure, got {self.beats!r}")
        beats = tuple(checked("beats", b, "float", "record") for b in self.beats)
        if not 1 <= len(beats) <= MAX_BEATS:
            raise ValueError(f"record: 'beats' must hold 1 to {MAX_BEATS} values, got {len(beats)}")
        if len(set(beats)) != len(beats):
            raise ValueError(f"record: 'beats' lists a value twice: {self.beats!r}")
        if any(abs(b) > MAX_HETERODYNE for b in beats):
            raise ValueError(f"record: 'beats' must be within +-{MAX_HETERODYNE:g}, got {self.beats!r}")
        object.__setattr__(self, "beats", beats)
        per = checked("cameras_per_render", self.cameras_per_render, "int", "record")
        if per < 1:
            raise ValueError(f"record: 'cameras_per_render' must be >= 1, got {per!r}")
        object.__setattr__(self, "cameras_per_render", per)
        object.__setattr__(self, "doppler", checked("doppler", self.doppler, "bool", "record"))
        object.__setattr__(self, "slopes", checked("slopes", self.slopes, "bool", "record"))
        object.__setattr__(self, "window_slopes", checked("window_slopes", self.window_slopes, "bool", "record"))

    @property
    def frequencies_hz(self) -> np.ndarray:
        """The recorded frequencies F (Hz): multiples j·step_hz within band_hz."""
        first, last = self._multiples()
        return np.arange(first, last + 1, dtype=np.float64) * self.step_hz

    def _multiples(self) -> tuple:
        """(first, last) j of the multiples j·step_hz within band_hz (none: last < first)."""
        low, high = self.band_hz
        return math.ceil(low / self.step_hz * (1 - GRID_TOLERANCE)), math.floor(high / self.step_hz * (1 + GRID_TOLERANCE))

    def bytes_per_pixel(self, n_windows: int = 1) -> int:
        """Record size per pixel (bytes): complex64 R(F, ν) (and R₁ with ``doppler``, their
        slopes with ``slopes``) and float32 Ī per window.

        Parameters
        ----------
        n_windows : int
            Exposure windows recorded; default 1.

        Returns
        -------
        int
            Bytes per pixel.
        """
        arrays = len(_derived_of(self)) + 1
        return n_windows * (8 * arrays * self.frequencies_hz.size * len(self.beats) + 4 * (3 if self.window_slopes else 1))

    def as_dict(self) -> dict:
        """The spec as a JSON-friendly dict (``RecordSpec(**spec.as_dict())`` is the same spec).

        Returns
        -------
        dict
        """
        return {"band_hz": list(self.band_hz), "step_hz": self.step_hz, "beats": list(self.beats), "cameras_per_render": self.cameras_per_render, "doppler": self.doppler, "slopes": self.slopes, "window_slopes": self.window_slopes}


def as_spec(value) -> RecordSpec:
    """``record=`` of :func:`dopplertof.render` as a :class:`RecordSpec`: True (defaults),
    a RecordSpec, or a dict of its fields.

    Parameters
    ----------
    value : bool, dict or RecordSpec

    Returns
    -------
    RecordSpec

    Raises
    ------
    ValueError
        Anything else, or a dict with unknown keys.
    """
    if value is True:
        return RecordSpec()
    if isinstance(value, RecordSpec):
        return value
    if isinstance(value, dict):
        unknown = sorted(set(value) - {f.name for f in dataclasses.fields(RecordSpec)})
        if unknown:
            raise ValueError(f"record: unknown key(s) {unknown}; use {', '.join(f.name for f in dataclasses.fields(RecordSpec))}")
        return RecordSpec(**value)
    raise ValueError(f"record must be True, a dict of RecordSpec fields or a dopplertof.design.RecordSpec, got {value!r}")


@dataclass
class Record:
    """A scene's response record (module docstring).

    Attributes
    ----------
    phasors : complex64 (windows, frequencies, beats, H, W). R(F, ν) per window and pixel.
    luminance : float32 (windows, H, W). Ī, the window's mean luminance.
    moments : complex64 like ``phasors``, or None. R₁(F, ν) (``spec.doppler``).
    slopes, moment_slopes : complex64 like ``phasors``, or None. ∂R/∂F and ∂R₁/∂F (1/Hz;
        ``spec.slopes``, the second also ``spec.doppler``).
    exposure_slopes, start_slopes, exposure_moment_slopes, start_moment_slopes : complex64
        like ``phasors``, or None. ∂R/∂T, ∂R/∂start, ∂R₁/∂T, ∂R₁/∂start of each window
        (1/s; ``spec.window_slopes``, the moments' also ``spec.doppler``).
    luminance_slopes : float32 (2, windows, H, W) or None. ∂Ī/∂T and ∂Ī/∂start (1/s;
        ``spec.window_slopes``).
    spec : :class:`RecordSpec`.
    windows : tuple of (start_s, exposure_s). The recorded exposure windows, in render order.
    settings : RenderSettings of the render (its cameras dropped; the windows are above).
    maps : dict. The render's intensity and ground truth (reference window).
    spp : int. Paths per pixel.
    info : dict, default {}. ``kernels`` and ``frequencies_per_kernel`` (recorded in the kernel), or
        ``render_seconds`` (s), ``renders`` and ``probe_cameras`` (recorded through probe cameras).
    """

    phasors: np.ndarray
    luminance: np.ndarray
    spec: RecordSpec
    windows: tuple
    settings: object
    maps: dict
    spp: int
    info: dict = field(default_factory=dict)
    moments: np.ndarray | None = None
    slopes: np.ndarray | None = None
    moment_slopes: np.ndarray | None = None
    exposure_slopes: np.ndarray | None = None
    start_slopes: np.ndarray | None = None
    exposure_moment_slopes: np.ndarray | None = None
    start_moment_slopes: np.ndarray | None = None
    luminance_slopes: np.ndarray | None = None

    RECORD_FORMAT = "dopplertof-record-1"

    def to_arrays(self) -> dict:
        """Every array of the record, and its metadata as a JSON string (``metadata``), for
        :func:`dopplertof.io.write_record`.

        Returns
        -------
        dict
        """
        import json

        settings = self.settings.as_dict()
        settings.pop("cameras")
        meta = {"format": self.RECORD_FORMAT, "spec": self.spec.as_dict(), "windows": [list(w) for w in self.windows], "settings": settings, "spp": self.spp, "info": self.info}
        arrays = {"phasors": self.phasors, "luminance": self.luminance, "metadata": np.array(json.dumps(meta, default=float))}
        for name in (*DERIVED, "luminance_slopes"):
            if getattr(self, name) is not None:
                arrays[name] = getattr(self, name)
        arrays.update({f"map.{name}": value for name, value in self.maps.items()})
        return arrays

    @classmethod
    def from_arrays(cls, arrays: dict, where: str = "record") -> "Record":
        """The record :meth:`to_arrays` wrote; ValueError naming ``where`` if it is not one.

        Parameters
        ----------
        arrays : dict
            Name → array, as :meth:`to_arrays` gives them.
        where : str, default ``"record"``
            Named in errors (a file).

        Returns
        -------
        Record

        Raises
        ------
        ValueError
            Another format, or arrays that do not match the record's grid.
        """
        import json

        from ..settings import RenderSettings

        try:
            meta = json.loads(str(arrays["metadata"]))
            if meta.get("format") != cls.RECORD_FORMAT:
                raise ValueError(f"format {meta.get('format')!r}, expected {cls.RECORD_FORMAT!r}")
            spec = RecordSpec(**meta["spec"])
            windows = tuple(tuple(float(x) for x in w) for w in meta["windows"])
            phasors, luminance = np.asarray(arrays["phasors"]), np.asarray(arrays["luminance"])
            expected = (len(windows), spec.frequencies_hz.size, len(spec.beats))
            if phasors.dtype != np.complex64 or phasors.shape[:3] != expected or luminance.shape != (len(windows), *phasors.shape[3:]):
                raise ValueError(f"arrays of shape {phasors.shape} and {luminance.shape} do not match the record's grid {expected}")
            derived = {name: np.asarray(arrays[name]) if name in _derived_of(spec) else None for name in DERIVED}
            for name, value in derived.items():
                if value is not None and (value.dtype != np.complex64 or value.shape != phasors.shape):
                    raise ValueError(f"{name} of shape {value.shape} do not match the phasors {phasors.shape}")
            if spec.window_slopes:
                derived["luminance_slopes"] = np.asarray(arrays["luminance_slopes"])
                if derived["luminance_slopes"].shape != (2, *luminance.shape):
                    raise ValueError(f"luminance_slopes of shape {derived['luminance_slopes'].shape} do not match the luminance {luminance.shape}")
            settings = RenderSettings.build(meta["settings"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: not a dopplertof response record ({exc})") from None
        maps = {name[4:]: np.asarray(value) for name, value in arrays.items() if name.startswith("map.")}
        return cls(phasors, luminance, spec, windows, settings, maps, int(meta["spp"]), dict(meta["info"]), **derived)

    @property
    def nbytes(self) -> int:
        """Memory the record's arrays take, in bytes."""
        return int(self.phasors.nbytes + self.luminance.nbytes + sum(getattr(self, n).nbytes for n in (*DERIVED, "luminance_slopes") if getattr(self, n) is not None))

    def window_index(self, camera: Camera, where: str) -> int:
        """Index of ``camera``'s exposure window in :attr:`windows`; a ValueError starting with
        ``where`` if the window was not recorded.

        Parameters
        ----------
        camera : Camera
        where : str
            Named in the error.

        Returns
        -------
        int

        Raises
        ------
        ValueError
            The window was not recorded.
        """
        window = camera.window(self.settings.exposure_start)
        for index, recorded in enumerate(self.windows):
            if math.isclose(window[0], recorded[0], rel_tol=1e-12, abs_tol=1e-15) and math.isclose(window[1], recorded[1], rel_tol=1e-12):
                return index
        raise ValueError(f"{where}: its exposure window (start {window[0]:g} s, {window[1]:g} s) was not recorded; the record holds {list(self.windows)}")

    def frequency_index(self, frequency_hz: float, where: str) -> int:
        """Index of ``frequency_hz`` (Hz) on the record's frequency grid; a ValueError starting
        with ``where`` if it is off the grid or outside the band.

        Parameters
        ----------
        frequency_hz : float, Hz
        where : str
            Named in the error.

        Returns
        -------
        int

        Raises
        ------
        ValueError
            Off the grid or outside the band.
        """
        low, high = self.spec.band_hz
        grid = self.spec.frequencies_hz
        j = round(frequency_hz / self.spec.step_hz)
        index = j - round(grid[0] / self.spec.step_hz)
        if not 0 <= index < grid.size or abs(frequency_hz - j * self.spec.step_hz) > GRID_TOLERANCE * frequency_hz:
            raise ValueError(
                f"{where}: needs the frequency {frequency_hz:.9g} Hz, which the record does not hold "
                f"(multiples of {self.spec.step_hz:g} Hz in [{low:g}, {high:g}] Hz)"
            )  # fmt: skip
        return index

    def beat_index(self, beat: float, where: str) -> int:
        """Index of ``beat`` (cycles per exposure) among the record's beats; a ValueError
        starting with ``where`` if it was not declared.

        Parameters
        ----------
        beat : float, cycles per exposure
        where : str
            Named in the error.

        Returns
        -------
        int

        Raises
        ------
        ValueError
            A beat that was not declared.
        """
        for index, recorded in enumerate(self.spec.beats):
            if abs(beat - recorded) <= GRID_TOLERANCE * max(1.0, abs(recorded)):
                return index
        raise ValueError(f"{where}: needs the beat {beat:.9g} cycles per exposure, which the record does not hold (beats {list(self.spec.beats)}); declare it in the record's beats")


# ----------------------------------------------------------------------------------------
# Recording


def _sides(spec: RecordSpec) -> list[tuple[int, int]]:
    """(beat side, frequency side) of the probes: (0, 0) is R(F, ν); ±1 are the steps ±δ in
    ν (``doppler``) and ±δF in F (``slopes``) whose central differences give R₁ and ∂R/∂F."""
    beat = (0, 1, -1) if spec.doppler else (0,)
    frequency = (0, 1, -1) if spec.slopes else (0,)
    return [(b, f) for b in beat for f in frequency]


def _derived_of(spec: RecordSpec) -> tuple[str, ...]:
    """The names of :data:`DERIVED` a record of ``spec`` holds."""
    window, both = spec.window_slopes, spec.window_slopes and spec.doppler
    held = (spec.doppler, spec.slopes, spec.doppler and spec.slopes, window, window, both, both)
    return tuple(n for n, h in zip(DERIVED, held) if h)


def _probes(spec: RecordSpec, start_s: float, exposure_s: float) -> list[tuple]:
    """(camera, frequency index, beat index, part, side) of one window: Ī first (part None),
    then the real (ψ = 0) and imaginary (ψ = −π/2: cos(Δ − π/2) = sin Δ) part of R at every
    (F + side[1] δF, ν + side[0] δ) (:func:`_sides`)."""
    from ..sensors.frames import mean_light_camera

    out = [(mean_light_camera(start_s, exposure_s), None, None, None, (0, 0))]
    for j, frequency in enumerate(spec.frequencies_hz):
        for b, beat in enumerate(spec.beats):
            for side in _sides(spec):
                for part, phase in ((0, 0.0), (1, -0.5 * math.pi)):
                    camera = Camera(
                        modulation_frequency=float(frequency) + side[1] * SLOPE_FREQUENCY_STEP_HZ, exposure=exposure_s, exposure_start=start_s,
                        heterodyne=beat + side[0] * MOMENT_BEAT_STEP, phase=phase, g1=2.0, g0=0.0,
                    )  # fmt: skip
                    out.append((camera, j, b, part, side))
    return out


def by_probes(settings) -> bool:
    """Whether a render records through probe cameras rather than in its kernel.

    The paired tracers give a lane's contributions two times (or integrate them over the
    exposure), which the kernel's phasor sums (:class:`~dopplertof.tracing.sink.PhasorGrid`)
    do not model.

    Parameters
    ----------
    settings : RenderSettings of the render.

    Returns
    -------
    bool: True for the paired tracers (``settings.paired``).
    """
    return settings.paired


def kernel_grids(spec: RecordSpec) -> list:
    """The grids of the kernels that record ``spec``.

    Parameters
    ----------
    spec : :class:`RecordSpec`.

    Returns
    -------
    list of :class:`~dopplertof.tracing.sink.PhasorGrid`: the spec's frequencies in runs of
    at most :data:`FREQUENCIES_PER_KERNEL`, each with every beat.
    """
    from ..tracing.sink import PhasorGrid

    first = round(spec.frequencies_hz[0] / spec.step_hz)
    n = spec.frequencies_hz.size
    return [
        PhasorGrid(first + j, min(FREQUENCIES_PER_KERNEL, n - j), spec.step_hz, spec.beats, spec.doppler, spec.slopes)
        for j in range(0, n, FREQUENCIES_PER_KERNEL)
    ]  # fmt: skip


def check_memory(spec: RecordSpec, width: int, height: int, n_windows: int, probes: bool = False) -> None:
    """Refuse a record that needs more than the available memory.

    Parameters
    ----------
    spec : :class:`RecordSpec`.
    width, height : int, pixels. The film.
    n_windows : int. Exposure windows recorded.
    probes : bool. Recorded through probe cameras (:func:`by_probes`). Default False.

    Raises
    ------
    ValueError
        Where the record's complex64 arrays and, while it is rendered, the Float64
        per-pixel sums of one kernel's grid per window (with ``probes``: every probe side
        until their differences are taken) exceed the available memory.
    """
    from ..resources import available_memory_bytes

    grid = spec.frequencies_hz.size * len(spec.beats)
    if probes:
        need = width * height * n_windows * (8 * (len(_sides(spec)) + len(_derived_of(spec))) * grid + 4)
    else:
        need = width * height * n_windows * (spec.bytes_per_pixel() + 8 * kernel_grids(spec)[0].channels)
    available = available_memory_bytes()
    if available is not None and need > available:
        raise ValueError(
            f"record: {spec.frequencies_hz.size} frequencies x {len(spec.beats)} beats x {n_windows} window(s) on a {width}x{height} film need about "
            f"{need / 2**30:.2g} GiB; {available / 2**30:.2g} GiB are available: use a coarser step_hz, a narrower band or fewer beats"
        )  # fmt: skip


def first_grid(spec: RecordSpec, settings):
    """The grid a render accumulates in its own passes.

    Parameters
    ----------
    spec : :class:`RecordSpec`.
    settings : RenderSettings of the render.

    Returns
    -------
    :class:`~dopplertof.tracing.sink.PhasorGrid` (the first of :func:`kernel_grids`), or
    None where the render records through probe cameras (:func:`by_probes`).

    Raises
    ------
    ValueError
        For ``window_slopes`` with probe cameras.
    """
    if not by_probes(settings):
        return kernel_grids(spec)[0]
    if spec.window_slopes:
        raise ValueError("record: window_slopes needs the single-path tracer; the paired tracers (correlation reconnection or adaptive, analytic time sampling) record through probe cameras")
    return None


def record_scene(scene, settings, spec: RecordSpec, rendered) -> Record:
    """The record of ``scene`` for the windows of ``settings`` (same seed, same paths).

    Each further grid of :func:`kernel_grids` traces the windows' finished passes again,
    and ``window_slopes`` four variants of each window. Renders that :func:`by_probes`
    record through probe cameras instead (:func:`_record_by_probes`).

    Parameters
    ----------
    scene : DynamicScene, the render's.
    settings : RenderSettings, the render's.
    spec : :class:`RecordSpec`.
    rendered : what :func:`dopplertof.render` traced: (settings of each window, per window
        (the Float64 sums of the first grid, an :class:`~dopplertof.passes.Accumulator`'s ``state["record_sum"]``;
        the samples per pixel; the passes done), the passes, the result's maps).

    Returns
    -------
    :class:`Record`.

    Raises
    ------
    KeyboardInterrupt
        A Ctrl-C: there is no partial record.
    """
    if by_probes(settings):
        return _record_by_probes(scene, settings, spec)
    window_settings, recorded, passes, maps = rendered
    width, height = scene.resolution
    grids = kernel_grids(spec)
    shape = (len(window_settings), spec.frequencies_hz.size, len(spec.beats), height, width)
    arrays = {name: np.zeros(shape, np.complex64) for name in ("phasors", *_derived_of(spec))}
    luminance = np.zeros(shape[:1] + shape[3:], np.float32)
    luminance_slopes = np.zeros((2, *luminance.shape), np.float32) if spec.window_slopes else None
    for w, (window, (first_sums, samples, done)) in enumerate(zip(window_settings, recorded)):
        j0 = 0
        for g, grid in enumerate(grids):
            luminance[w], parts = _unpack(grid, first_sums if g == 0 else _traced_sums(scene, window, grid, passes[:done]), samples, (height, width))
            for name, part in parts.items():
                arrays[name][w, j0 : j0 + grid.count] = part
            if spec.window_slopes:
                step = WINDOW_STEP * window.exposure_s
                start, exposure = window.exposure_start, window.exposure_s
                values = dataclasses.replace(grid, slopes=False)  # R and R₁ only
                for k, kind in enumerate(("exposure", "start")):
                    moved = [_moved(window, exposure + d, start) if kind == "exposure" else _moved(window, exposure, start + d) for d in (step, -step)]
                    ends = [_unpack(values, _traced_sums(scene, m, values, passes[:done]), samples, (height, width)) for m in moved]
                    luminance_slopes[k, w] = (ends[0][0] - ends[1][0]) / (2 * step)
                    for name in values.quantities:
                        target = f"{kind}_slopes" if name == "phasors" else f"{kind}_moment_slopes"
                        arrays[target][w, j0 : j0 + grid.count] = (ends[0][1][name] - ends[1][1][name]) / (2 * step)
            j0 += grid.count
    maps = {k: v for k, v in maps.items() if not k.startswith("measurement") and k != "raw"}
    windows = tuple((w.start_s, w.exposure_s) for w in settings.windows)
    info = {"kernels": len(grids), "frequencies_per_kernel": FREQUENCIES_PER_KERNEL}
    spp = int(min(samples.min() for _, samples, _ in recorded))
    return Record(arrays.pop("phasors"), luminance, spec, windows, settings.replace(cameras=()), maps, spp, info, luminance_slopes=luminance_slopes, **arrays)


def _traced_sums(scene, window, grid, passes) -> np.ndarray:
    """(channels, pixels) sums of ``grid``'s per-lane values over ``passes`` of ``window``
    (its settings: cameras, start, seed) traced again."""
    from ..passes import PassTracer

    width, height = scene.resolution
    tracer, sums = PassTracer(scene, window, grid), np.zeros((grid.channels, width * height))
    for p in passes:
        sums[:, p.pixel_start : p.pixel_start + p.n_pixels] += tracer(p)["record"]
    return sums


def _unpack(grid, sums, samples, shape):
    """(Ī (H, W), {quantity: (count, beats, H, W) complex}) of ``grid``'s sums over
    ``samples`` lanes per pixel (:meth:`~dopplertof.tracing.sink.PhasorGrid.lane_values`),
    in Float64: the window slopes difference them before the record rounds them."""
    means = sums / samples
    parts = means[1:].reshape(len(grid.quantities), grid.count, len(grid.beats), 2, *shape)
    return means[0].reshape(shape), {name: parts[q, :, :, 0] + 1j * parts[q, :, :, 1] for q, name in enumerate(grid.quantities)}


def _moved(window, exposure_s, start_s):
    """``window``'s settings (same seed: same random numbers) with its exposure window moved
    to [``start_s``, ``start_s`` + ``exposure_s``] (s)."""
    cameras = tuple(dataclasses.replace(c, exposure=exposure_s, exposure_start=start_s) for c in window.cameras)
    return dataclasses.replace(window, cameras=cameras, exposure_start=start_s)


def _record_by_probes(scene, settings, spec: RecordSpec) -> Record:
    """The record rendered as probe cameras (for the paired tracers, :func:`by_probes`).

    The probe cameras of every window are traced in chunks of ``spec.cameras_per_render``;
    each chunk holds the same number of every window's probes, in the windows' order, so
    each window keeps its seed (:func:`dopplertof.tracing.lanes.window_seed`).
    """
    from ..render import render

    windows = [(w.start_s, w.exposure_s) for w in settings.windows]
    width, height = scene.resolution
    n_freq, n_beats = spec.frequencies_hz.size, len(spec.beats)
    phasors = np.zeros((len(windows), n_freq, n_beats, height, width), np.complex64)
    # complex64 holds the float32 maps exactly; their difference is exact (Sterbenz) where they are close
    sides = {side: np.zeros((len(windows), n_freq, n_beats, height, width), np.complex64) for side in _sides(spec) if side != (0, 0)}
    luminance = np.zeros((len(windows), height, width), np.float32)
    probes = [_probes(spec, *w) for w in windows]
    per_window = max(1, spec.cameras_per_render // len(windows))
    maps, seconds, spp = None, 0.0, settings.spp
    for first in range(0, len(probes[0]), per_window):
        chunk = [p for window in probes for p in window[first : first + per_window]]
        result = render(scene, cameras=[p[0] for p in chunk], settings=settings)
        if result.interrupted:  # a Ctrl-C: a record of partial chunks would silently mix sample counts
            raise KeyboardInterrupt
        seconds += result.info["render_seconds"]
        spp = min(spp, result.spp)
        if maps is None:
            maps = {k: v for k, v in result.maps.items() if not k.startswith("measurement")}
        for (camera, j, b, part, side), value in zip(chunk, result.measurements):
            w = windows.index(camera.window(settings.exposure_start))
            if part is None:
                luminance[w] = value
                continue
            target = phasors if side == (0, 0) else sides[side]
            if part == 0:
                target[w, j, b].real = value
            else:
                target[w, j, b].imag = value
    info = {"render_seconds": seconds, "renders": math.ceil(len(probes[0]) / per_window), "probe_cameras": len(probes[0]) * len(windows)}
    sides[(0, 0)] = phasors
    beat_step, frequency_step = 4j * math.pi * MOMENT_BEAT_STEP, 2.0 * SLOPE_FREQUENCY_STEP_HZ  # e^{±i2πδu}: ±i2πδ u; F ± δF
    derived = {}
    if spec.doppler:
        derived["moments"] = (sides[(1, 0)] - sides[(-1, 0)]) / beat_step
    if spec.slopes:
        derived["slopes"] = (sides[(0, 1)] - sides[(0, -1)]) / frequency_step
    if spec.doppler and spec.slopes:
        derived["moment_slopes"] = ((sides[(1, 1)] - sides[(-1, 1)]) - (sides[(1, -1)] - sides[(-1, -1)])) / (beat_step * frequency_step)
    derived = {name: value.astype(np.complex64) for name, value in derived.items()}
    return Record(phasors, luminance, spec, tuple(windows), settings.replace(cameras=()), maps, spp, info, **derived)


# ----------------------------------------------------------------------------------------
# Reading out


def harmonics(camera: Camera, where: str) -> tuple[float, list[tuple[int, complex]]]:
    """(c₀, [(m, a_m)]) of ``camera``'s low-pass weight W = c₀ + Re Σ a_m e^{imΔ}
    (module docstring); ValueError naming ``where`` for weights the record cannot hold.

    Parameters
    ----------
    camera : Camera
    where : str
        Named in the error.

    Returns
    -------
    tuple of (float, list of tuple of (int, complex))

    Raises
    ------
    ValueError
        A full-waveform model or a waveform with unbounded harmonics.
    """
    if not camera.low_pass:
        raise ValueError(f"{where}: the full-waveform model (low_pass=False) has unbounded harmonics; a record reads out low-pass cameras only")
    if camera.coded:
        corr = camera.correlation
        if corr.harmonics is None:
            raise ValueError(f"{where}: two sampled codes correlate to unbounded harmonics; give the camera a light_bandwidth within the record's band")
        k = np.asarray(corr.harmonics)
        scale = np.abs(k).max()
        terms = [(m, complex(camera.g1 * k[m])) for m in range(1, k.size) if abs(k[m]) > NEGLIGIBLE_HARMONIC * scale]
        return float(camera.g1 * k[0].real + camera.g0 * camera.sensor_mean), terms
    if camera.waveform != "sinusoidal":
        hint = ("give it the source's light_bandwidth (Hz, within the record's band: Camera(light_bandwidth=…), or for a sensor "
                "`light_bandwidth = …` at the top of its file, beside `preset = \"NAME\"` for a preset)") if camera.waveform in NAMED_CODES else "use the sinusoid or a band-limited code (light_bandwidth)"
        raise ValueError(f"{where}: the {camera.waveform} waveform has unbounded harmonics; {hint}")
    return 0.0, [(1, complex(0.5 * camera.g1))]


def readout_terms(record: Record, camera: Camera, where: str = "camera") -> tuple[int, float, list[tuple]]:
    """(window, c₀, [(m, a_m e^{imψ}, frequency index, beat index)]) of ``camera``: where
    in ``record`` its harmonics are read (module docstring); ValueError naming ``where``
    for what the record does not hold.

    Parameters
    ----------
    record : Record
    camera : Camera
    where : str, default ``"camera"``
        Named in errors.

    Returns
    -------
    tuple of (int, float, list of tuple)

    Raises
    ------
    ValueError
        The record does not hold the camera's window, frequency or beat.
    """
    constant, terms = harmonics(camera, where)
    w = record.window_index(camera, where)
    located = [
        (m, a * np.exp(1j * m * camera.phase), record.frequency_index(m * camera.modulation_frequency, where), record.beat_index(m * camera.heterodyne, where))
        for m, a in terms
    ]  # fmt: skip
    return w, constant, located


def measure(record: Record, camera: Camera, where: str = "camera", dtype=np.float64) -> np.ndarray:
    """The measurement of ``camera`` read out of ``record`` (module docstring).

    Parameters
    ----------
    record : :class:`Record`.
    camera : :class:`~dopplertof.Camera`.
    where : str. What error messages name. Default ``"camera"``.
    dtype : numpy dtype. float64 (default), or float32 as a render gives it.

    Returns
    -------
    ndarray (H, W) of ``dtype``.

    Raises
    ------
    ValueError
        Naming ``where``, for what the record does not hold.
    """
    w, constant, terms = readout_terms(record, camera, where)
    out = np.multiply(record.luminance[w], constant, dtype=dtype)
    for _, coefficient, j, b in terms:
        # Re(a R) = (Re R, Im R) · (Re a, −Im a): one matrix-vector product over the pixels
        pairs = record.phasors[w, j, b].view(np.float32).reshape(-1, 2)
        out += (pairs @ np.array([coefficient.real, -coefficient.imag], dtype)).reshape(out.shape)
    return out


def evaluate(record: Record, sensor):
    """The result a direct render of ``sensor`` gives, read out of ``record``.

    Parameters
    ----------
    record : :class:`Record` (``dopplertof.render(..., record=True).record`` or
        :func:`dopplertof.io.read_record`).
    sensor : :class:`dopplertof.Sensor`, or a list of :class:`dopplertof.Camera`.

    Returns
    -------
    RenderResult with ``measurements`` (cameras, H, W), with a sensor its ``raw``
    (frames, taps, H, W) electrons, and the record's intensity and ground truth. It has no
    ``measurement_stderr`` (the record keeps no per-replicate values).

    Raises
    ------
    ValueError
        Naming the camera, for what the record cannot give (module docstring).
    """
    from ..render import RenderResult
    from ..sensors import Sensor

    if not isinstance(record, Record):
        raise ValueError(f"evaluate: 'record' must be a dopplertof.design.Record, got {type(record).__name__}")
    if isinstance(sensor, Sensor):
        cameras = sensor.cameras()
    elif isinstance(sensor, (list, tuple)) and sensor and all(isinstance(c, Camera) for c in sensor):
        cameras, sensor = list(sensor), None
    else:
        raise ValueError(f"evaluate: 'sensor' must be a dopplertof.Sensor or a list of dopplertof.Camera, got {sensor!r}")
    measurements = np.stack([measure(record, c, f"camera {i} ({c.label()})", np.float32) for i, c in enumerate(cameras)])
    maps = dict(record.maps, measurements=measurements)
    if sensor is not None:
        maps["raw"] = sensor.raw(measurements)
    settings = record.settings.replace(cameras=tuple(cameras))
    return RenderResult(maps=maps, settings=settings, spp=record.spp, info={"from_record": True}, sensor=sensor)
