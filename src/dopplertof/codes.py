"""Modulation and demodulation codes as data: sampled chips or Fourier coefficients.

A code is one period of a periodic function x(θ), θ the modulation phase (rad). It is
given either as

* **samples** (:func:`sampled`, or any 1-D real array passed as ``light_code`` /
  ``sensor_code`` of a :class:`~dopplertof.Camera`): N ≥ 8 values, sample n held over the
  phase interval [2πn/N, 2π(n+1)/N) (the chips a pattern generator clocks out: binary or
  not);
* **Fourier coefficients** (:func:`fourier`): complex c_0 … c_M with
  x(θ) = Re Σ_m c_m e^{imθ} (``[0, 1]`` is cos θ, ``[0, -1j]`` is sin θ): band-limited.

A camera measures the cross-correlation of its sensor code s and light code g,

    C(Δ) = (1/2π) ∫ s(φ + Δ) g(φ) dφ,

at the slow phase Δ = 2π h u + ψ + k L (:mod:`dopplertof.modulation`). It is computed
exactly in both representations (:func:`correlation`):

* two sampled codes (resampled to the least common multiple of their lengths, an exact
  operation for chips) correlate to a function that is exactly piecewise linear between the
  lags 2πj/N: a table of N values, interpolated linearly;
* where either code is band-limited (Fourier coefficients, or a light code passed through
  the source's bandwidth, :func:`band_limited`), C has finitely many harmonics,
  C(Δ) = Re Σ_m K_m e^{imΔ} with K_0 = s_0 g_0 and K_m = 2 s_m conj(g_m), where s_m, g_m are
  the codes' exact complex Fourier coefficients (those of chips in closed form).

The kernel evaluates either form per path at a Float64 phase: a table lookup with two
gathers, or a complex Horner sum of M terms (:class:`PeriodicFunction`).

Code tables (K codes of N samples each) load from ``.npy``/``.npz`` (:func:`load_codes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .jitdata import jit_array

TWO_PI = 2.0 * math.pi
MIN_SAMPLES = 8
# Largest common grid two sampled codes are resampled to (the lcm of their lengths): its
# table is gathered per path; beyond, resample the codes yourself to a common length.
MAX_TABLE_SAMPLES = 1 << 16
# Largest Fourier order (harmonics) of a band-limited code or correlation: the kernel pays
# one complex multiply-add per harmonic and path.
MAX_HARMONICS = 4096


@dataclass(frozen=True)
class Code:
    """One period of a modulation code: ``samples`` (chips) or ``fourier`` coefficients.

    Exactly one of the two is given. Build with :func:`sampled`, :func:`fourier` or
    :func:`as_code`.

    Parameters
    ----------
    samples : tuple of float, optional
        N ≥ 8 finite values; sample n holds over [2πn/N, 2π(n+1)/N) of the period.
    fourier : tuple of complex, optional
        c_0 … c_M (finite, M ≥ 1, at most :data:`MAX_HARMONICS`) of
        ``x(θ) = Re Σ_m c_m e^{imθ}``.
    """

    samples: tuple | None = None
    fourier: tuple | None = None

    def __post_init__(self):
        if (self.samples is None) == (self.fourier is None):
            raise ValueError("Code: give exactly one of 'samples' or 'fourier'")
        if self.samples is not None:
            values = np.asarray(self.samples, dtype=np.float64)
            if values.ndim != 1 or values.size < MIN_SAMPLES:
                raise ValueError(f"Code: 'samples' must be one period of N >= {MIN_SAMPLES} values, got shape {values.shape}")
            if not np.all(np.isfinite(values)):
                raise ValueError("Code: 'samples' must be finite numbers")
            object.__setattr__(self, "samples", tuple(float(v) for v in values))
        else:
            values = np.asarray(self.fourier, dtype=np.complex128)
            if values.ndim != 1 or not 2 <= values.size <= MAX_HARMONICS + 1:
                raise ValueError(f"Code: 'fourier' must hold c_0 ... c_M with 1 <= M <= {MAX_HARMONICS}, got shape {values.shape}")
            if not np.all(np.isfinite(values)):
                raise ValueError("Code: 'fourier' coefficients must be finite")
            object.__setattr__(self, "fourier", tuple(complex(v) for v in values))

    def as_dict(self) -> dict:
        """JSON-friendly: ``{"samples": [...]}`` or ``{"fourier": [[re, im], ...]}``
        (:func:`as_code` reads it back).

        Returns
        -------
        dict
        """
        if self.samples is not None:
            return {"samples": list(self.samples)}
        return {"fourier": [[c.real, c.imag] for c in self.fourier]}

    @property
    def order(self) -> int | None:
        """Highest harmonic M of a band-limited code; None for chips (unbounded)."""
        return len(self.fourier) - 1 if self.fourier is not None else None

    def coefficients(self, order: int) -> np.ndarray:
        """Exact complex Fourier coefficients x_m, m = 0 … ``order``, of
        x(θ) = Σ_{m=−∞}^{∞} x_m e^{imθ} (x_{−m} = conj x_m).

        Parameters
        ----------
        order : int
            The highest harmonic m returned, ≥ 0.

        Returns
        -------
        ndarray
            (order + 1,) complex128.
        """
        m = np.arange(order + 1)
        if self.fourier is not None:
            c = np.zeros(order + 1, np.complex128)
            given = np.asarray(self.fourier)[: order + 1]
            c[: given.size] = given
            out = 0.5 * c
            out[0] = c[0].real
            return out
        x = np.asarray(self.samples)
        n = x.size
        # Chip n contributes x[n] (1/2π)∫ e^{−imθ} over its interval: the DFT times the
        # chip's own transform (1 − e^{−2πim/N}) / (2πim).
        dft = np.fft.fft(x)[m % n]  # the DFT is N-periodic in m
        out = np.empty(order + 1, np.complex128)
        out[0] = x.mean()
        mm = m[1:]
        out[1:] = dft[1:] * (1.0 - np.exp(-2j * np.pi * mm / n)) / (2j * np.pi * mm)
        return out

    def periodic(self) -> "PeriodicFunction":
        """x(θ) itself, for evaluation (chips: a step table; Fourier: its harmonics).

        Returns
        -------
        PeriodicFunction
        """
        if self.samples is not None:
            return PeriodicFunction(table=np.asarray(self.samples), linear=False)
        return PeriodicFunction(harmonics=np.asarray(self.fourier))

    def __call__(self, theta):
        """x(θ) for phases θ (rad, any real; numpy or Dr.Jit Float64)."""
        return self.periodic()(theta)

    @property
    def mean(self) -> float:
        """The code's mean over one period (its DC coefficient), e.g. 0.5 for a 0/1 square."""
        return float(self.coefficients(0)[0].real)

    def _grid(self, parts: int) -> np.ndarray:
        """x at θ_j = 2π(j + ½)/n on a grid fine enough to see every chip or harmonic,
        n a multiple of ``parts``; a Fourier code by one inverse FFT."""
        if self.samples is not None:
            n = 4 * parts * len(self.samples)
            return self((np.arange(n) + 0.5) * (TWO_PI / n))
        n = 64 * parts * (self.order + 1)
        c = np.zeros(n, np.complex128)
        c[: self.order + 1] = self.fourier
        # e^{imθ_j} = e^{iπm/n} e^{2πimj/n}: the half-step shift, then the inverse DFT
        return (np.fft.ifft(c * np.exp(1j * np.pi * np.arange(n) / n)) * n).real

    def extremes(self) -> tuple[float, float]:
        """(min, max) of x(θ): exact for chips, on a fine grid for a Fourier code.

        Returns
        -------
        tuple of (float, float)
        """
        if self.samples is not None:
            return min(self.samples), max(self.samples)
        values = self._grid(1)
        return float(values.min()), float(values.max())

    def shifted_sum(self, parts: int) -> float:
        """max_θ |Σ_j x(θ + 2πj/parts)|: zero where the code has no harmonic (nor mean)
        at multiples of ``parts`` (a tap layout that splits the charge ``parts`` ways).

        Parameters
        ----------
        parts : int
            Taps that split the charge, ≥ 1.

        Returns
        -------
        float
        """
        values = self._grid(parts)
        step = values.size // parts
        return float(np.abs(sum(np.roll(values, -j * step) for j in range(parts))).max())


def sampled(samples) -> Code:
    """A sampled code: one period of N ≥ 8 chips (see :class:`Code`).

    Parameters
    ----------
    samples : array_like
        One period of real chips, 1-D, N ≥ 8, finite.

    Returns
    -------
    Code

    Raises
    ------
    ValueError
        Fewer than 8 samples, not 1-D, or not finite.
    """
    return Code(samples=samples)


def fourier(coefficients) -> Code:
    """A band-limited code x(θ) = Re Σ_m c_m e^{imθ} from c_0 … c_M (see :class:`Code`).

    Parameters
    ----------
    coefficients : array_like of complex
        c_0 … c_M.

    Returns
    -------
    Code

    Raises
    ------
    ValueError
        Coefficients that are not a finite 1-D array.
    """
    return Code(fourier=coefficients)


# The named waveforms of :mod:`dopplertof.modulation` whose light and sensor modulations are
# chips with edges on the 8-chip grid (exact codes): sign(cos θ), and the trapezoid's light
# pulse 4·[θ within π/4 of 0]. (light, sensor) samples.
_NAMED_CHIPS = {
    "rectangular": ((1, 1, -1, -1, -1, -1, 1, 1), (1, 1, -1, -1, -1, -1, 1, 1)),
    "trapezoidal": ((4, 0, 0, 0, 0, 0, 0, 4), (1, 1, -1, -1, -1, -1, 1, 1)),
}
NAMED_CODES = tuple(_NAMED_CHIPS)


def named(waveform: str) -> tuple[Code, Code]:
    """The exact chip codes of a named waveform's light and sensor modulations.

    Parameters
    ----------
    waveform : str. One of :data:`NAMED_CODES` (``"rectangular"``, ``"trapezoidal"``).

    Returns
    -------
    (light, sensor) : two sampled :class:`Code` of 8 chips; their correlation is the
    waveform's Λ/2.

    Raises
    ------
    ValueError
        For a waveform that is not one of :data:`NAMED_CODES` (the sinusoid is a single
        harmonic; the triangle is not a chip sequence).
    """
    if waveform not in _NAMED_CHIPS:
        raise ValueError(f"named: the {waveform!r} waveform has no exact chip code; choose one of {', '.join(NAMED_CODES)}")
    light, sensor = _NAMED_CHIPS[waveform]
    return sampled(tuple(map(float, light))), sampled(tuple(map(float, sensor)))


def as_code(value, name: str) -> Code:
    """``value`` as a :class:`Code`.

    Parameters
    ----------
    value : Code, array_like or dict
        A Code, a 1-D array of real samples (one period), or :meth:`Code.as_dict`'s dict.
    name : str
        The parameter named in errors.

    Returns
    -------
    Code

    Raises
    ------
    ValueError
        Naming ``name``, for anything else (2-D tables: pick a row; complex arrays: use
        :func:`fourier`; fewer than 8 samples; non-finite values).
    """
    if isinstance(value, Code):
        return value
    if isinstance(value, dict):  # Code.as_dict's form (metadata.json)
        if set(value) == {"samples"}:
            return as_code(value["samples"], name)
        if set(value) == {"fourier"}:
            pairs = np.asarray(value["fourier"], dtype=np.float64)
            if pairs.ndim != 2 or pairs.shape[1] != 2:
                raise ValueError(f"{name!r}: 'fourier' must list [re, im] pairs, got {value['fourier']!r}")
            try:
                return Code(fourier=tuple(pairs[:, 0] + 1j * pairs[:, 1]))
            except ValueError as exc:
                raise ValueError(f"{name!r}: {exc}") from None
        raise ValueError(f"{name!r}: a code written as a dict has one key, 'samples' or 'fourier', got {sorted(value)}")
    try:
        array = np.asarray(value)
    except Exception:  # noqa: BLE001 (any object numpy cannot read is refused by name)
        array = None
    if array is None or array.dtype == object or not (np.issubdtype(array.dtype, np.number) or array.dtype == bool):
        raise ValueError(f"{name!r} must be one period of sampled values (1-D array) or a dopplertof.codes.Code, got {value!r}")
    if np.iscomplexobj(array):
        raise ValueError(f"{name!r}: complex values are Fourier coefficients; pass dopplertof.codes.fourier(...)")
    if array.ndim != 1:
        raise ValueError(f"{name!r} must be one period of samples (1-D), got shape {array.shape}; pick one row of a code table")
    try:
        return Code(samples=tuple(array.astype(np.float64)))
    except ValueError as exc:
        raise ValueError(f"{name!r}: {exc}") from None


def load_codes(path) -> np.ndarray:
    """A code table (K rows × N samples, float64) from a ``.npy`` file, or a ``.npz`` file
    holding exactly one array (or one named ``codes``).

    Parameters
    ----------
    path : str or path
        A ``.npy`` or ``.npz`` file.

    Returns
    -------
    ndarray
        (K, N) float64.

    Raises
    ------
    ValueError
        If the file holds no K × N real table with N ≥ 8 (or several arrays, none named
        ``codes``); OSError if it cannot be read.
    """
    path = str(path)
    if path.endswith(".npz"):
        with np.load(path, allow_pickle=False) as data:
            names = list(data.files)
            if "codes" in names:
                table = data["codes"]
            elif len(names) == 1:
                table = data[names[0]]
            else:
                raise ValueError(f"{path}: holds arrays {names}; name the code table 'codes'")
    elif path.endswith(".npy"):
        table = np.load(path, allow_pickle=False)
    else:
        raise ValueError(f"{path}: a code table is a .npy or .npz file")
    table = np.asarray(table)
    if table.ndim == 1:
        table = table[None]
    if table.ndim != 2 or np.iscomplexobj(table) or not np.issubdtype(table.dtype, np.number):
        raise ValueError(f"{path}: a code table is K rows x N real samples, got {table.dtype} of shape {table.shape}")
    if table.shape[1] < MIN_SAMPLES or not np.all(np.isfinite(table)):
        raise ValueError(f"{path}: codes need N >= {MIN_SAMPLES} finite samples per row, got shape {table.shape}")
    return table.astype(np.float64)


def band_limited(code: Code, order: int) -> Code:
    """``code`` with every harmonic above ``order`` removed (an ideal low-pass source:
    its modulation bandwidth is ``order`` × the modulation frequency).

    Parameters
    ----------
    code : Code
    order : int
        The highest harmonic kept, ≥ 1.

    Returns
    -------
    Code
        A Fourier code.

    Raises
    ------
    ValueError
        ``order`` passes no harmonic of the modulation.
    """
    if order < 1:
        raise ValueError(f"band_limited: the bandwidth passes no harmonic of the modulation (order {order})")
    x = code.coefficients(order)
    c = 2.0 * x
    c[0] = x[0]
    return Code(fourier=tuple(c))


def correlation(sensor: Code, light: Code) -> "PeriodicFunction":
    """C(Δ) = (1/2π)∫ s(φ + Δ) g(φ) dφ of a sensor and a light code, exactly (module docstring).

    Parameters
    ----------
    sensor, light : Code
        The sensor's demodulation code and the light's modulation code.

    Returns
    -------
    PeriodicFunction

    Raises
    ------
    ValueError
        If two sampled codes need a common grid longer than :data:`MAX_TABLE_SAMPLES`.
    """
    orders = [c.order for c in (sensor, light) if c.order is not None]
    if orders:
        order = min(orders)
        s, g = sensor.coefficients(order), light.coefficients(order)
        k = 2.0 * s * np.conj(g)
        k[0] = (s[0] * g[0]).real
        return PeriodicFunction(harmonics=k)
    n_s, n_g = len(sensor.samples), len(light.samples)
    n = n_s * n_g // math.gcd(n_s, n_g)
    if n > MAX_TABLE_SAMPLES:
        raise ValueError(f"codes of {n_s} and {n_g} samples need a common grid of {n} > {MAX_TABLE_SAMPLES}; resample them to a common length")
    s = np.repeat(np.asarray(sensor.samples), n // n_s)
    g = np.repeat(np.asarray(light.samples), n // n_g)
    # Σ_n s[n + j] g[n] for every lag j, by the correlation theorem.
    table = np.fft.ifft(np.fft.fft(s) * np.conj(np.fft.fft(g))).real / n
    return PeriodicFunction(table=table, linear=True)


@dataclass(frozen=True, eq=False)
class PeriodicFunction:
    """A 2π-periodic function: a table over one period (``linear``: knots at 2πj/N,
    interpolated linearly; else steps held over [2πj/N, 2π(j+1)/N)) or harmonics K_m,
    f(θ) = Re Σ_m K_m e^{imθ}.

    Parameters
    ----------
    table : ndarray or None, default None
        (N,) values over one period.
    harmonics : ndarray or None, default None
        (M + 1,) complex K_0 … K_M.
    linear : bool, default True
        With ``table``: interpolate linearly, else hold steps.
    """

    table: np.ndarray | None = None
    harmonics: np.ndarray | None = None
    linear: bool = True

    def __call__(self, theta):
        """f(θ) for numpy or Dr.Jit Float64 phases (rad, any real)."""
        if isinstance(theta, np.ndarray) or np.isscalar(theta):
            return self._numpy(np.asarray(theta, dtype=np.float64))
        return self.drjit(theta, self.opaque())

    def _numpy(self, theta):
        if self.harmonics is not None:
            z = np.exp(1j * theta)
            acc = np.zeros_like(z) + self.harmonics[-1]
            for k in self.harmonics[-2::-1]:
                acc = acc * z + k
            return acc.real
        n = self.table.size
        x = (theta - TWO_PI * np.floor(theta / TWO_PI)) * (n / TWO_PI)
        j = np.minimum(np.floor(x).astype(np.int64), n - 1)
        if not self.linear:
            return self.table[j]
        frac = x - j
        return self.table[j] * (1.0 - frac) + self.table[(j + 1) % n] * frac

    def opaque(self):
        """The Dr.Jit constants of :meth:`drjit`: the table (Float64, one extra knot for the
        wrap) or the harmonics as opaque Float64 scalars (changing values recompiles nothing)."""
        import drjit as dr
        import mitsuba as mi

        if self.harmonics is None:
            t = self.table
            return jit_array(mi.Float64, np.append(t, t[0]) if self.linear else t, np.float64)

        def opaque(v):
            a = mi.Float64(float(v))
            dr.make_opaque(a)
            return a

        return [(opaque(k.real), opaque(k.imag)) for k in self.harmonics]

    def drjit(self, theta, constants, z=None):
        """f(θ) for Dr.Jit Float64 ``theta`` with :meth:`opaque`'s ``constants``.

        ``z`` = (cos θ, sin θ) where the caller has them already (harmonics only).

        Parameters
        ----------
        theta : mi.Float64
            Phase, rad.
        constants : tuple
            :meth:`opaque`'s.
        z : tuple of mi.Float64 or None, default None
            (cos θ, sin θ), used by harmonics only.

        Returns
        -------
        mi.Float64
        """
        import drjit as dr
        import mitsuba as mi

        if self.harmonics is not None:
            if z is None:
                sin_t, cos_t = dr.sincos(theta - TWO_PI * dr.floor(theta * (1.0 / TWO_PI)))
                z = (cos_t, sin_t)
            zr, zi = z
            ar, ai = constants[-1]
            ar, ai = ar + 0.0 * zr, ai + 0.0 * zr
            for kr, ki in constants[-2::-1]:  # Horner: acc = acc·z + K_m
                ar, ai = ar * zr - ai * zi + kr, ar * zi + ai * zr + ki
            return ar
        n = self.table.size
        x = (theta - TWO_PI * dr.floor(theta * (1.0 / TWO_PI))) * (n / TWO_PI)
        j = dr.minimum(mi.UInt32(dr.floor(x)), n - 1)
        lower = dr.gather(mi.Float64, constants, j)
        if not self.linear:
            return lower
        frac = x - mi.Float64(j)
        return dr.fma(dr.gather(mi.Float64, constants, j + 1) - lower, frac, lower)
