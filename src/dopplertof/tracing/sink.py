"""Where a path's contributions go: the intensity and, weighted by W(u, L), every camera,
and, for a response record, the phasors of a frequency grid.

The per-lane accumulators are loop state, so they travel as a plain tuple
``(intensity, [measurement per camera])`` (plus the phasor sums with a :class:`PhasorGrid`)
that :meth:`Sink.add` returns anew (Dr.Jit tracks PyTrees, not attributes of Python
objects). :meth:`Sink.outputs` lays the per-lane results out under the names of
:data:`dopplertof.outputs.OUTPUTS` (and ``"record"``: :meth:`PhasorGrid.lane_values`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import modulation


@dataclass(frozen=True)
class PhasorGrid:
    """The part of a response record (:mod:`dopplertof.design.record`) one kernel accumulates.

    Per lane, every contribution (luminance ``lum``, Float64 optical length L) adds
    ``lum · e^{i2πF L/c}`` to one complex sum S(F) per frequency F = j·``step_hz``,
    j = ``first`` … ``first + count − 1``: e^{i2πF L/c} is evaluated once per contribution
    in Float64 at the first frequency and at the step, wrapped to one cycle, and the rest
    by the rotation recurrence z ← z·e^{i2π step L/c} in Float32 (``count`` steps lose at
    most ``count`` × 6e-8 of phase, far below a render's noise). After the bounce loop the
    lane's time u gives every beat ν: the lane's R(F, ν) = S(F) e^{i2πνu}
    (:meth:`lane_values`), which the pass reduces per pixel in Float64
    (:meth:`~dopplertof.passes.Reducer.reduce`). This holds for tracers that give every
    contribution of a lane the same u (:mod:`dopplertof.tracing.single`).

    Parameters
    ----------
    first : int. Index j of the grid's first frequency (F = j·step_hz), >= 1.
    count : int. Frequencies, >= 1.
    step_hz : float, Hz. The grid's step.
    beats : tuple of float. Beat cycles per exposure ν.
    moments : bool. Also the first moments u·R(F, ν) (the lane's u is exact). Default False.
    slopes : bool. Also ∂R/∂F = ⟨lum (i2πL/c) e^{…}⟩ (1/Hz), exact per contribution (and
        their moments with ``moments``). Default False.
    """

    first: int
    count: int
    step_hz: float
    beats: tuple
    moments: bool = False
    slopes: bool = False

    @property
    def quantities(self) -> tuple[str, ...]:
        """The complex quantities per (F, ν), in the order of :meth:`lane_values`:
        ``phasors``, then ``moments``, ``slopes`` and ``moment_slopes`` where held (the
        names of :class:`dopplertof.design.Record`'s arrays)."""
        names = ("phasors", "moments", "slopes", "moment_slopes")
        held = (True, self.moments, self.slopes, self.moments and self.slopes)
        return tuple(n for n, h in zip(names, held) if h)

    @property
    def channels(self) -> int:
        """Real values per lane: the luminance, then re and im of every quantity, F and ν."""
        return 1 + 2 * len(self.quantities) * self.count * len(self.beats)

    def empty(self):
        """Zero sums, the loop state :meth:`add` carries.

        Returns
        -------
        list of lists of (re, im) Float32 pairs: S(F) per frequency, and with ``slopes``
        ∂S/∂F per frequency.
        """
        import mitsuba as mi

        sums = [[(mi.Float(0), mi.Float(0)) for _ in range(self.count)]]
        if self.slopes:
            sums.append([(mi.Float(0), mi.Float(0)) for _ in range(self.count)])
        return sums

    def add(self, sums, lum, length_m, mask):
        """``sums`` plus one contribution, where ``mask``.

        Parameters
        ----------
        sums : the loop state of :meth:`empty`.
        lum : Float32. The contribution's luminance.
        length_m : Float64, m. Its optical path length.
        mask : Bool. Lanes where it counts.

        Returns
        -------
        The new sums (same layout).
        """
        import drjit as dr
        import mitsuba as mi

        lum = dr.select(mask, lum, 0.0)
        length_m = dr.select(mask, length_m, 0.0)  # an inactive lane's length may be anything, even inf
        cycles = length_m * mi.Float64(self.step_hz / modulation.SPEED_OF_LIGHT_M_S)  # of the step, per path
        sin_step, cos_step = (mi.Float(x) for x in dr.sincos(modulation.TWO_PI * (cycles - dr.floor(cycles))))
        start = cycles * float(self.first)  # exact: an integer multiple
        sin_0, cos_0 = (mi.Float(x) for x in dr.sincos(modulation.TWO_PI * (start - dr.floor(start))))
        re, im = lum * cos_0, lum * sin_0
        out = [list(s) for s in sums]
        if self.slopes:  # d/dF e^{i2πFL/c} = i (2πL/c) e^{i2πFL/c}
            scale = mi.Float(length_m * (modulation.TWO_PI / modulation.SPEED_OF_LIGHT_M_S))
        for j in range(self.count):
            out[0][j] = (out[0][j][0] + re, out[0][j][1] + im)
            if self.slopes:
                out[1][j] = (out[1][j][0] - scale * im, out[1][j][1] + scale * re)
            if j + 1 < self.count:
                re, im = re * cos_step - im * sin_step, re * sin_step + im * cos_step
        return out

    def lane_values(self, sums, lum_total, u):
        """The lane's real values, the per-lane record.

        Parameters
        ----------
        sums : the loop state after the bounce loop (:meth:`add`).
        lum_total : Float32. The lane's luminance (its Ī sample).
        u : Float64. The lane's normalised time in the exposure.

        Returns
        -------
        list of :attr:`channels` Float32: ``lum_total``, then R(F, ν) = S(F) e^{i2πνu}
        (re, im) for every quantity (:attr:`quantities`), F (outer) and ν (inner).
        """
        import drjit as dr
        import mitsuba as mi

        turns = []
        for beat in self.beats:
            if beat == 0.0:  # homodyne: e^{i0} = 1, no work
                turns.append(None)
                continue
            cycles = u * mi.Float64(beat)
            sin_b, cos_b = (mi.Float(x) for x in dr.sincos(modulation.TWO_PI * (cycles - dr.floor(cycles))))
            turns.append((cos_b, sin_b))
        u32 = mi.Float(u)
        values = [lum_total]
        for quantity in self.quantities:
            source = sums[1] if "slopes" in quantity else sums[0]
            weight = u32 if quantity.startswith("moment") else None
            for re, im in source:
                for turn in turns:
                    r, i = (re, im) if turn is None else (re * turn[0] - im * turn[1], re * turn[1] + im * turn[0])
                    values += [r, i] if weight is None else [r * weight, i * weight]
        return values


def scatter_pixels(values, lanes_per_pixel: int, n_pixels: int):
    """Per-pixel Float64 sums of per-lane values.

    The scatter joins the kernel that traces the lanes (it is evaluated with the pass's
    other outputs): the per-lane values never reach memory.

    Parameters
    ----------
    values : list of Float32 (lanes). Per-lane values (:meth:`PhasorGrid.lane_values`).
    lanes_per_pixel : int. Consecutive lanes per pixel.
    n_pixels : int. Pixels of the pass.

    Returns
    -------
    Float64 (n_pixels × len(values)), pixel-major: the sums over each pixel's lanes.
    """
    import drjit as dr
    import mitsuba as mi

    k = len(values)
    target = dr.zeros(mi.Float64, n_pixels * k)
    base = dr.arange(mi.UInt32, n_pixels * lanes_per_pixel) // lanes_per_pixel * k
    for c, value in enumerate(values):  # Local: a pixel's lanes are consecutive, so a SIMD packet adds up in registers first
        dr.scatter_reduce(dr.ReduceOp.Add, target, mi.Float64(value), base + c, mode=dr.ReduceMode.Local)
    return target


class Sink:
    """The cameras of a render and how contributions reach them; with a
    :class:`PhasorGrid` (``grid``) also the record's phasors.

    Parameters
    ----------
    cameras : sequence of Camera
        The render's D-ToF cameras.
    grid : PhasorGrid or None
        The record's frequencies this kernel accumulates; default None (no record).
    """

    def __init__(self, cameras, grid: PhasorGrid | None = None):
        self.cameras = list(cameras)
        self.grid = grid

    def empty(self):
        """Zero contributions: the intensity and one value per camera (and the grid's sums)."""
        import mitsuba as mi

        if self.grid is None:
            return mi.Spectrum(0), [mi.Float(0) for _ in self.cameras]
        return mi.Spectrum(0), [mi.Float(0) for _ in self.cameras], self.grid.empty()

    def bank(self, u):
        """The cameras' weights for lanes at normalised time ``u``.

        Parameters
        ----------
        u : mi.Float64
            Normalised times.

        Returns
        -------
        list
            Each camera's weight per lane.
        """
        return modulation.CameraBank(self.cameras, u)

    @property
    def needs_length(self) -> bool:
        """Float64 optical lengths are needed only where a camera or the grid weighs them."""
        return bool(self.cameras) or self.grid is not None

    def add(self, state, bank, contrib, length_m, mask):
        """``state`` plus an emitter contribution with optical length ``length_m`` (Float64).

        Parameters
        ----------
        state : tuple
            (intensity, [per-camera values]).
        bank : list
            :meth:`bank` of the lanes' times.
        contrib : mi.Spectrum
        length_m : mi.Float64
            m.
        mask : mi.Bool

        Returns
        -------
        tuple
            The new state.
        """
        import drjit as dr

        radiance, measurements, *phasors = state
        radiance = dr.select(mask, radiance + contrib, radiance)
        if not self.cameras and self.grid is None:
            return radiance, measurements
        lum = _luminance(contrib)
        measurements = [dr.select(mask, m + w * lum, m) for m, w in zip(measurements, bank.weights(length_m))]
        if self.grid is None:
            return radiance, measurements
        return radiance, measurements, self.grid.add(phasors[0], lum, length_m, mask)

    def add_analytic(self, state, cameras, first, second, continuous):
        """The analytic mode (:mod:`dopplertof.tracing.paired`): a contribution X with optical
        length L at the exposure's start (``first``) and end (``second``), each a
        (X, L, mask), integrated in closed form over the exposure under a model of X(t)
        and L(t) between them:

        * where both ends are present and the partner path lies on the primal's surfaces
          (``continuous``: one path moving), X and L are linear in time;
        * otherwise (the contribution is missing at one end: shadowed, the partner path
          gone; or the paths reach different surfaces: an occlusion change) the start's
          contribution fades linearly out and the end's in, each at its own L: the
          expectation over a switch at a uniformly distributed time.

        The original ramped a contribution missing at the end to zero (L held) and dropped
        one missing at the start; holding it constant was this package's earlier rule. Both
        are further from the unbiased estimate (docs/estimators.md, "Measured: the analytic mode's bias"; ``benchmarks/analytic_bias.py``).

        Parameters
        ----------
        state : tuple
            (intensity, [per-camera values]).
        cameras : sequence of Camera
        first, second : tuple
            (X, L, mask) at the exposure's start and end; L in m.
        continuous : mi.Bool
            Where the partner path lies on the primal's surfaces.

        Returns
        -------
        tuple
            The new state.
        """
        import drjit as dr
        import mitsuba as mi

        radiance, measurements = state
        (x1, l1, m1), (x2, l2, m2) = first, second
        x1, x2 = dr.select(m1, x1, 0.0), dr.select(m2, x2, 0.0)
        l1, l2 = dr.select(m1, l1, l2), dr.select(m2, l2, l1)  # a missing end's length is unused: keep it finite
        present = m1 | m2
        linear = m1 & m2 & continuous
        radiance = dr.select(present, radiance + 0.5 * (x1 + x2), radiance)
        lum1, lum2 = mi.Float64(_luminance(x1)), mi.Float64(_luminance(x2))
        out = []
        for m, cam in zip(measurements, cameras):
            moving = modulation.analytic_integral(cam, l1, l2, lum1, lum2)
            fading = modulation.analytic_integral(cam, l1, l1, lum1, 0.0) + modulation.analytic_integral(cam, l2, l2, 0.0, lum2)
            out.append(dr.select(present, m + mi.Float(dr.select(linear, moving, fading)), m))
        return radiance, out

    def outputs(self, state, truth: dict, hits, label, u=None):
        """Per-lane outputs, laid out under the names of :data:`dopplertof.outputs.OUTPUTS`.

        Parameters
        ----------
        state : the loop state (:meth:`empty`, :meth:`add`).
        truth : dict of per-lane ground truth (value × hit).
        hits : Float32. 1 where the camera ray hit.
        label : Float32. The hit's body id.
        u : Float64, optional. The lane's normalised time; needed with a grid.

        Returns
        -------
        dict: ``intensity``, ``measurements``, ``hits``, ``instance_id``, the truth, and
        with a grid ``record`` (:meth:`PhasorGrid.lane_values`).
        """
        radiance, measurements, *phasors = state
        out = {"intensity": radiance, "measurements": measurements, "hits": hits, "instance_id": label, **truth}
        if self.grid is not None:
            out["record"] = self.grid.lane_values(phasors[0], _luminance(radiance), u)
        return out


def _luminance(contrib):
    import mitsuba as mi

    return mi.luminance(contrib) if mi.is_rgb else contrib[0]
