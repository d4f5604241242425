"""A render's passes: the schedule, tracing and reducing a pass, and adding it up.

:func:`schedule` splits the film × spp into passes of at most ``lanes_per_pass`` lanes.
:class:`PassTracer` traces a pass where its scene is (this process, or a Ray worker:
:mod:`dopplertof.render_ray`) and reduces it there (:meth:`Reducer.reduce`) to per-pixel
Float64 increments, which :meth:`Accumulator.apply` adds, pass by pass in order, to the sums
:mod:`dopplertof.render` turns into the result (see there for what the sums are).
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import warnings
from dataclasses import dataclass

import numpy as np

from .outputs import ESTIMATES, TRUTH
from .settings import RenderSettings

MAX_COVARIANCE_CAMERAS = 8  # beyond, the per-pixel camera covariance is not kept (memory)


@dataclass(frozen=True)
class Pass:
    first_sample: int
    samples: int
    pixel_start: int
    n_pixels: int


def schedule(n_pixels: int, spp: int, group: int, lanes_per_pass: int) -> list[Pass]:
    """Passes covering ``n_pixels`` × ``spp``: sample ranges (whole groups) outermost,
    tiles of pixels innermost, each pass at most ``lanes_per_pass`` lanes (at least one
    group of one pixel)."""
    samples = min(spp, max(group, (lanes_per_pass // n_pixels) // group * group))
    pixels = min(n_pixels, max(1, lanes_per_pass // samples))
    return [
        Pass(s0, min(samples, spp - s0), p0, min(pixels, n_pixels - p0)) for s0 in range(0, spp, samples) for p0 in range(0, n_pixels, pixels)
    ]


# ----------------------------------------------------------------------------------------
# Accumulation


class Reducer:
    """How a render's passes reduce to per-pixel increments of the sums (module docstring).

    The half of the accumulation that runs where the pass was traced (this process, or a
    Ray worker: :mod:`dopplertof.render_ray`); :class:`Accumulator` adds the increments.

    ===============  =====  ==========================================================
    color_channels   int    3 (RGB) or 1 (mono)
    n_cameras        int    D-ToF cameras
    spp              int    paths per pixel
    group            int    correlated samples per group (``settings.group_size``)
    lanes_per_group  int    lanes a group takes (1 where primal and partner share a lane)
    replicates       int    independent replicates per pixel (``settings.replicates``)
    wraps            tuple  where the strata are cut (``settings.wraps``) where the times
                     |None  are stratified over the pixel's groups (``settings.stratified``):
                            errors from the strata; None where they are not
    ===============  =====  ==========================================================

    The standard errors come from *units* of a pixel's groups: with ``stratified`` its
    strata (:class:`~dopplertof.tracing.lanes.StrataLayout`), whose within-stratum spread
    Q_s = n_s/(n_s − 1) Σ (x_g − x̄_s)² (d_s² for a pair) sums to G² Var(μ̂)
    (:mod:`dopplertof.timesampling`); else its independent replicates
    (:func:`~dopplertof.tracing.lanes.replicate_bounds`), whose means' spread gives it.
    """

    def __init__(self, color_channels, n_cameras, spp, group, lanes_per_group, replicates, wraps):
        from .tracing.lanes import StrataLayout, replicate_bounds

        self.color_channels, self.n_cameras = color_channels, n_cameras
        self.group, self.lanes_per_group = group, lanes_per_group
        n_groups = max(spp // group, 1)
        self.within = wraps is not None
        if self.within:
            self.strata = StrataLayout(n_groups, wraps)
            self.replicated = n_groups > 1  # standard errors can be estimated
        else:
            self.bounds = replicate_bounds(n_groups, replicates)
            self.replicated = len(self.bounds) > 1
        self.pairs = []
        if self.replicated and 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS:  # cameras share paths: their errors correlate
            self.pairs = [(i, j) for i in range(n_cameras) for j in range(i + 1, n_cameras)]

    @staticmethod
    def layout(settings: RenderSettings) -> tuple:
        """The arguments above of a render with ``settings`` (in the active variant)."""
        import mitsuba as mi

        group = settings.group_size
        lanes_per_group = 1 if settings.paired else group
        return 3 if mi.is_rgb else 1, len(settings.cameras), settings.spp, group, lanes_per_group, settings.replicates, settings.wraps if settings.stratified else None

    def groups(self, p: Pass) -> tuple[int, int]:
        """The pass's groups of every pixel: [g0, g1)."""
        return p.first_sample // self.group, (p.first_sample + p.samples) // self.group

    def segments(self, p: Pass) -> list[tuple[int, int, int, int]]:
        """The pass's groups split at unit ends: (first group, end group, unit end, unit size)."""
        g0, g1 = self.groups(p)
        units = [(a, n) for a, n, *_ in self.strata.units(g0, g1)] if self.within else self.bounds
        return [(max(a, g0), min(a + n, g1), a + n, n) for a, n in units if max(a, g0) < min(a + n, g1)]

    def reduce(self, p: Pass, out: dict) -> dict:
        """One pass's per-lane outputs (Dr.Jit arrays), reduced in Float64 on the device to
        per-pixel host increments (numpy), which :meth:`Accumulator.apply` adds.

        A pass of whole units (the usual one) is reduced to per-pixel sums in one kernel
        (:meth:`_unit_sums`: replicates: of their means, squares and camera products; strata
        of two groups: of the groups and of their differences' squares and camera products;
        the truth), so only per-pixel arrays reach the host. Otherwise the group means
        (gathers: Dr.Jit's block reductions over blocks of 2 lanes cost several times the
        reduction itself) reach the host, which splits them at the units' ends.

        Parameters
        ----------
        p : Pass
            The pass.
        out : dict
            Its per-lane outputs (:meth:`~dopplertof.tracing.sink.Sink.outputs`), not yet
            evaluated.

        Returns
        -------
        dict
            Name → numpy increments of :attr:`Accumulator.state` (arrays, or lists of
            per-pixel rows).
        """
        import drjit as dr
        import mitsuba as mi

        group, lanes_per_group = self.group, self.lanes_per_group
        lanes_per_pixel = p.samples // group * lanes_per_group
        intensity = out["intensity"]
        channels = [intensity[c] for c in range(self.color_channels)] + list(out["measurements"])
        truth = [x for o in TRUTH for x in _components(out[o.name], o.channels)] + [out["hits"]]
        record = None
        if "record" in out:  # a response record's phasors, summed per pixel in the tracing kernel
            from .tracing.sink import scatter_pixels

            record = scatter_pixels(out["record"], lanes_per_pixel, p.n_pixels)
        dr.eval(channels, truth, out["instance_id"], record)  # one kernel traces every output (DESIGN §3.3)

        g0, g1 = self.groups(p)
        segments = self.segments(p)
        inc = {}
        if self.whole(segments):  # the usual pass: complete units (pairs of groups, or replicates of one size)
            size, count = segments[0][1] - segments[0][0], len(segments)
            sums, squares, cross, truth_sums = self._unit_sums(channels, truth, p.n_pixels, lanes_per_pixel, count, size)
            prefix = "within" if self.within else "rep"
            inc["group_sum" if self.within else "rep_sum"] = [np.asarray(x.numpy()) for x in sums]
            inc[f"{prefix}_sq"] = [np.asarray(x.numpy()) for x in squares]
            inc[f"{prefix}_cross"] = [np.asarray(x.numpy()) for x in cross]
        else:
            n_groups = p.n_pixels * (g1 - g0)
            first = dr.arange(mi.UInt32, n_groups) * lanes_per_group
            means = [self._group_mean(x, first) for x in channels]
            truth_sums = [dr.block_sum(mi.Float64(x), lanes_per_pixel) for x in truth]
            dr.eval(means, truth_sums)  # one kernel for every channel, not one per reduction
            host = np.stack([np.asarray(m.numpy()).reshape(p.n_pixels, g1 - g0) for m in means])  # (channels, pixels, groups)
            inc["parts"] = np.stack([host[:, :, a - g0 : b - g0].sum(axis=2) for a, b, *_ in segments], axis=2)
            if self.within and self.replicated:  # (channels, pixels, segments) sums of squares and of camera products
                pieces = [host[:, :, a - g0 : b - g0] for a, b, *_ in segments]
                inc["parts_sq"] = np.stack([(x * x).sum(axis=2) for x in pieces], axis=2)
                cc = self.color_channels
                inc["parts_cross"] = [np.stack([(x[cc + i] * x[cc + j]).sum(axis=1) for x in pieces], axis=1) for i, j in self.pairs]
        truth_sums = [np.asarray(x.numpy()) for x in truth_sums]
        inc["truth_sum"] = truth_sums[:-1]
        inc["hits"] = np.rint(truth_sums[-1]).astype(np.int32)  # counts of hits: whole numbers
        if p.first_sample == 0:  # the label of the pixel's first sample
            inc["instance_id"] = np.asarray(out["instance_id"].numpy()).reshape(p.n_pixels, lanes_per_pixel)[:, 0].astype(np.int32)
        if record is not None:  # (channels, pixels) sums over the pass's lanes
            inc["record"] = np.asarray(record.numpy()).reshape(p.n_pixels, -1).T
        return inc

    def _group_mean(self, x, first):
        """Float64 mean of per-lane ``x`` (mi.Float) over the groups whose first lanes are
        ``first`` (mi.UInt32), summed in lane order (mi.Float64, one value per group)."""
        import drjit as dr
        import mitsuba as mi

        total = mi.Float64(dr.gather(mi.Float, x, first))
        for k in range(1, self.lanes_per_group):
            total += mi.Float64(dr.gather(mi.Float, x, first + k))
        return total * (1.0 / self.lanes_per_group)

    def _unit_sums(self, channels, truth, n_pixels, lanes_per_pixel, count, size):
        """Per-pixel Float64 sums of a pass made of ``count`` complete units of ``size``
        groups per pixel (:meth:`reduce`): (sums, squares, camera products, truth sums),
        lists of Float64 arrays (one value per pixel), computed in one kernel.

        Strata (pairs of groups): the sums of the group means, and of the squares and camera
        products of the pairs' differences. Replicates: of the replicates' means, their
        squares and camera products. Truth: of every lane's value.

        A symbolic loop per pixel walks its units in group order and adds in the order of
        Dr.Jit's block sums (one after another from 0), so the sums are bit-identical to
        those of block sums over per-group arrays, without the Float64 per-lane and
        per-group arrays or one reduction kernel per channel. The unit count and size
        are kernel data: any spp reuses the kernel.

        Parameters
        ----------
        channels, truth : list of mi.Float
            Per-lane estimates (colour channels, then cameras) and truth values (the last
            the hit count), evaluated.
        n_pixels, lanes_per_pixel : int
            The pass's pixels and each one's consecutive lanes.
        count, size : int
            Units per pixel and groups per unit (2 for strata).

        Returns
        -------
        tuple of lists of mi.Float64
            (sums, squares, camera products, truth sums), each one value per pixel.
        """
        import drjit as dr
        import mitsuba as mi

        F = mi.Float64
        lanes_per_group, cc = self.lanes_per_group, self.color_channels
        groups = mi.UInt32(count * size)
        per_pixel = mi.UInt32(lanes_per_pixel)
        inv_size = F(1.0 / size)
        unit_size = mi.UInt32(size)
        dr.make_opaque(groups, per_pixel, inv_size, unit_size)
        base = dr.arange(mi.UInt32, n_pixels) * per_pixel
        n_channels, n_truth, n_pairs = len(channels), len(truth), len(self.pairs)

        def zeros(n):
            return [dr.zeros(F, n_pixels) for _ in range(n)]

        def add_truth(truth_sums, first_lane):
            for k in range(lanes_per_group):
                truth_sums = [t + F(dr.gather(mi.Float, x, first_lane + k)) for t, x in zip(truth_sums, truth)]
            return truth_sums

        if self.within:  # units are pairs of groups: one iteration per pair

            def body(g, sums, squares, cross, truth_sums):
                first_a = base + g * lanes_per_group
                first_b = first_a + lanes_per_group
                a = [self._group_mean(x, first_a) for x in channels]
                b = [self._group_mean(x, first_b) for x in channels]
                sums = [s + ma + mb for s, ma, mb in zip(sums, a, b)]
                d = [ma - mb for ma, mb in zip(a, b)]
                squares = [q + x * x for q, x in zip(squares, d)]
                cross = [c + d[cc + i] * d[cc + j] for c, (i, j) in zip(cross, self.pairs)]
                truth_sums = add_truth(add_truth(truth_sums, first_a), first_b)
                return g + 2, sums, squares, cross, truth_sums

            state = (mi.UInt32(0), zeros(n_channels), zeros(n_channels), zeros(n_pairs), zeros(n_truth))
            _, sums, squares, cross, truth_sums = dr.while_loop(state, lambda g, *_: g < groups, body, label="dopplertof strata sums")
        else:  # units are replicates of `size` groups: one iteration per group, a replicate closed every `size`

            def body(g, open_sums, sums, squares, cross, truth_sums):
                first = base + g * lanes_per_group
                open_sums = [o + self._group_mean(x, first) for o, x in zip(open_sums, channels)]
                closing = (g % unit_size) == unit_size - 1
                r = [o * inv_size for o in open_sums]
                sums = [dr.select(closing, s + x, s) for s, x in zip(sums, r)]
                squares = [dr.select(closing, q + x * x, q) for q, x in zip(squares, r)]
                cross = [dr.select(closing, c + r[cc + i] * r[cc + j], c) for c, (i, j) in zip(cross, self.pairs)]
                open_sums = [dr.select(closing, 0.0, o) for o in open_sums]
                return g + 1, open_sums, sums, squares, cross, add_truth(truth_sums, first)

            state = (mi.UInt32(0), zeros(n_channels), zeros(n_channels), zeros(n_channels), zeros(n_pairs), zeros(n_truth))
            _, _, sums, squares, cross, truth_sums = dr.while_loop(state, lambda g, *_: g < groups, body, label="dopplertof replicate sums")
        dr.eval(sums, squares, cross, truth_sums)
        return sums, squares, cross, truth_sums

    def whole(self, segments) -> bool:
        """Whether a pass's segments are complete units of one size (pairs, where stratified)."""
        sizes = {b - a for a, b, *_ in segments}
        equal = len(sizes) == 1 and (not self.within or sizes == {2})
        return self.replicated and equal and all(b - a == size for a, b, _, size in segments)


class SpareSums:
    """The sums of finished renders, kept for the next render's :class:`Accumulator` (at
    most ``max_bytes`` of them): their pages are mapped already. A new array's pages are
    mapped when first written, which on a virtual machine costs microseconds a page: at
    256² new sums were half of a render's 7355 page faults and 19 ms of its host work
    (``benchmarks/static_overhead.py``, its ``page faults`` column), where stock Mitsuba's
    memory comes from Dr.Jit's cache. The result's maps are new arrays all the same.

    ==========  =====  ==================================================
    max_bytes   int    the most kept at once, bytes (default 64 MiB)
    ==========  =====  ==================================================
    """

    def __init__(self, max_bytes: int = 64 << 20):
        import threading

        self.max_bytes = max_bytes
        self._kept = []
        self._lock = threading.Lock()

    def full(self, shape, dtype, value=0) -> np.ndarray:
        """An array of ``shape`` and ``dtype`` holding ``value``: a kept one if one fits."""
        shape, dtype = tuple(np.atleast_1d(shape)), np.dtype(dtype)
        with self._lock:
            for i in range(len(self._kept) - 1, -1, -1):  # the last kept first
                kept = self._kept[i]
                if kept.shape == shape and kept.dtype == dtype:
                    del self._kept[i]
                    kept.fill(value)
                    return kept
        return np.zeros(shape, dtype) if value == 0 else np.full(shape, value, dtype)

    def clear(self):
        """Free every kept array."""
        with self._lock:
            self._kept.clear()

    def keep(self, *arrays):
        """Keep ``arrays`` for a later :meth:`full`: the caller holds no reference to them
        (nor to a view of them) any more. Views, read-only or non-contiguous arrays and what
        would exceed ``max_bytes`` are left to be freed."""
        with self._lock:
            held = sum(kept.nbytes for kept in self._kept)
            for array in arrays:
                if array.flags.owndata and array.flags.writeable and array.flags.c_contiguous and held + array.nbytes <= self.max_bytes:
                    self._kept.append(array)
                    held += array.nbytes


SPARE_SUMS = SpareSums()  # one per process: the Accumulators' arrays


class Accumulator(Reducer):
    """Float64 per-pixel sums (module docstring) of ``n_pixels`` pixels; ``state`` is what a
    checkpoint holds. A pass is added by ``apply(p, reduce(p, out))``, wherever ``reduce``
    ran: the same numpy operations in pass order, so the sums are bit-identical.
    ``applying`` is True while :meth:`apply` runs: an exception that leaves it True (a
    KeyboardInterrupt, say) left the sums holding part of a pass.
    """

    applying = False

    def __init__(self, n_pixels, color_channels, n_cameras, spp, group, lanes_per_group, replicates, wraps, record_channels=0):
        super().__init__(color_channels, n_cameras, spp, group, lanes_per_group, replicates, wraps)
        # The sums every pass writes come from the spares (their pages mapped already); the
        # open unit's sums stay np.zeros, whose pages are mapped only where a pass that cuts
        # a unit writes them (rarely), and are not handed back by finish.
        c, n, pairs, zeros = color_channels + n_cameras, n_pixels, len(self.pairs), SPARE_SUMS.full
        self.state = {"passes_done": np.zeros(1, np.int64), "group_sum": zeros((c, n), np.float64), "groups_done": zeros(n, np.int32)}
        if self.replicated and self.within:  # the open stratum's sums, and the closed strata's Q_s
            self.state.update(open_sum=np.zeros((c, n)), open_sq=np.zeros((c, n)), within_sq=zeros((c, n), np.float64), strata_closed=zeros(n, np.int32))
            if self.pairs:
                self.state.update(open_cross=np.zeros((pairs, n)), within_cross=zeros((pairs, n), np.float64))
        elif self.replicated:
            self.state.update(open_sum=np.zeros((c, n)), rep_sum=zeros((c, n), np.float64), rep_sq=zeros((c, n), np.float64), reps_closed=zeros(n, np.int32))
            if self.pairs:
                self.state["rep_cross"] = zeros((pairs, n), np.float64)
        truth_channels = sum(o.channels for o in TRUTH)
        self.state.update(truth_sum=zeros((truth_channels, n), np.float64), hits=zeros(n, np.int32), samples=zeros(n, np.int32))
        self.state["instance_id"] = np.full(n, -1, np.int32)  # the result's map is a view of it: never kept
        if record_channels:  # (channels, pixels) Float64 sums over lanes of a response record's phasors (PhasorGrid)
            self.state["record_sum"] = np.zeros((record_channels, n))

    def apply(self, p: Pass, inc: dict):
        """Add one pass's increments (from :meth:`Reducer.reduce`) to the sums."""
        self.applying = True
        s = self.state
        pix = slice(p.pixel_start, p.pixel_start + p.n_pixels)
        if "within_sq" in inc:
            _add_rows(s["group_sum"], pix, inc["group_sum"])
            _add_rows(s["within_sq"], pix, inc["within_sq"])
            for k, x in enumerate(inc["within_cross"]):
                s["within_cross"][k, pix] += x
            s["strata_closed"][pix] += len(self.segments(p))
        elif "rep_sum" in inc:
            segments = self.segments(p)
            size, count = segments[0][1] - segments[0][0], len(segments)
            _add_rows(s["group_sum"], pix, [x * size for x in inc["rep_sum"]])
            _add_rows(s["rep_sum"], pix, inc["rep_sum"])
            _add_rows(s["rep_sq"], pix, inc["rep_sq"])
            for k, x in enumerate(inc["rep_cross"]):
                s["rep_cross"][k, pix] += x
            s["reps_closed"][pix] += count
        else:
            parts = inc["parts"]
            s["group_sum"][:, pix] += parts.sum(axis=2)
            if self.replicated:
                for k, (a, b, end, size) in enumerate(self.segments(p)):
                    s["open_sum"][:, pix] += parts[:, :, k]
                    if self.within:
                        s["open_sq"][:, pix] += inc["parts_sq"][:, :, k]
                        for j, x in enumerate(inc["parts_cross"]):
                            s["open_cross"][j, pix] += x[:, k]
                        if b == end:
                            self._close_stratum(pix, size)
                    elif b == end:  # the replicate is complete: its mean is one independent unit
                        self._close(pix, (s["open_sum"][:, pix] / size)[:, :, None])
                        s["open_sum"][:, pix] = 0.0
        g0, g1 = self.groups(p)
        s["groups_done"][pix] += g1 - g0
        _add_rows(s["truth_sum"], pix, inc["truth_sum"])
        s["hits"][pix] += inc["hits"]
        s["samples"][pix] += p.samples
        if "record" in inc:
            s["record_sum"][:, pix] += inc["record"]
        if "instance_id" in inc:
            s["instance_id"][pix] = inc["instance_id"]
        s["passes_done"][0] += 1
        self.applying = False

    def _close(self, pix, rep_means):
        """Add complete replicates: their means, (channels, pixels, replicates)."""
        s = self.state
        s["rep_sum"][:, pix] += rep_means.sum(axis=2)
        s["rep_sq"][:, pix] += np.einsum("cpr,cpr->cp", rep_means, rep_means)
        cams = rep_means[self.color_channels :]
        for j, (i1, i2) in enumerate(self.pairs):
            s["rep_cross"][j, pix] += np.einsum("pr,pr->p", cams[i1], cams[i2])
        s["reps_closed"][pix] += rep_means.shape[2]

    def _close_stratum(self, pix, n):
        """Add the open stratum of ``n`` groups, complete: its Q_s (class docstring), from
        the sums of its groups, squares and camera products, which restart at zero."""
        s = self.state
        total = s["open_sum"][:, pix]
        if n >= 2:  # a lone group (G = 1) says nothing about the variance
            scale = n / (n - 1)
            s["within_sq"][:, pix] += scale * (s["open_sq"][:, pix] - total * total / n)
            cams = total[self.color_channels :]
            for j, (i1, i2) in enumerate(self.pairs):
                s["within_cross"][j, pix] += scale * (s["open_cross"][j, pix] - cams[i1] * cams[i2] / n)
            s["strata_closed"][pix] += 1
        for name in ("open_sum", "open_sq", "open_cross"):
            if name in s:
                s[name][:, pix] = 0.0

    def finish(self, height, width, n_cameras) -> dict:
        """The result's maps (float32). Consumes the state: each sum goes as soon as its maps
        are made (to :data:`SPARE_SUMS`, up to its size, else freed), so the peak is the sums
        or the maps, not both, beyond the spares."""
        s = self.state
        cc = self.color_channels
        n_pix = height * width

        def image(rows):  # float32 rows (k, pixels) -> (H, W) or (H, W, k)
            return rows[0].reshape(height, width) if len(rows) == 1 else np.stack(rows, axis=-1).reshape(height, width, len(rows))

        keep = SPARE_SUMS.keep  # each sum once read (the maps are new arrays)
        with np.errstate(invalid="ignore", divide="ignore"):
            groups = s["groups_done"].astype(np.float64)
            keep(s.pop("groups_done"))
            mean = [(row / groups).astype(np.float32) for row in s["group_sum"]]
            keep(s.pop("group_sum"))
            self.stderr_dof = stderr_dof(s)
            if "within_sq" in s:  # Var(μ̂) = Σ_s Q_s / G² (class docstring)
                closed = s["strata_closed"] >= 1
                err = np.where(closed, np.sqrt(np.maximum(s["within_sq"], 0.0)) / groups, np.nan).astype(np.float32)
                keep(s.pop("strata_closed"), s.pop("within_sq"))
            elif "rep_sum" in s:
                n = s["reps_closed"].astype(np.float64)
                rep_mean = s["rep_sum"] / n
                var = np.maximum(s["rep_sq"] / n - rep_mean * rep_mean, 0.0) * n / (n - 1)
                err = np.where(n >= 2, np.sqrt(var / n), np.nan).astype(np.float32)
                keep(s.pop("reps_closed"), s.pop("rep_sum"), s.pop("rep_sq"))
                del var
            else:
                err = np.full((len(mean), n_pix), np.nan, np.float32)
            covariance = None
            if self.pairs:  # covariance of the cameras' means, from the same strata or replicates
                covariance = np.zeros((n_cameras, n_cameras, n_pix), np.float32)
                for i in range(n_cameras):
                    covariance[i, i] = err[cc + i].astype(np.float64) ** 2
                for k, (i, j) in enumerate(self.pairs):
                    if self.within:
                        cross = np.where(closed, s["within_cross"][k] / (groups * groups), np.nan)
                    else:
                        cross = np.where(n >= 2, (s["rep_cross"][k] / n - rep_mean[cc + i] * rep_mean[cc + j]) * n / (n - 1) / n, np.nan)
                    covariance[i, j] = covariance[j, i] = cross
                keep(s.pop("within_cross" if self.within else "rep_cross"))
            del groups
            hits = s["hits"]
            truth_rows = [(row / hits).astype(np.float32) for row in s["truth_sum"]]
            coverage = (hits / s["samples"]).astype(np.float32)
            del hits
            keep(s.pop("hits"), s.pop("truth_sum"), s.pop("samples"))
        maps = {}
        for o in ESTIMATES:
            if o.channels == "color":
                maps[o.name], maps[o.stderr_name] = image(mean[:cc]), image(list(err[:cc]))
            else:
                maps[o.name] = np.stack(mean[cc:]).reshape(n_cameras, height, width) if n_cameras else np.zeros((0, height, width), np.float32)
                maps[o.stderr_name] = err[cc:].reshape(n_cameras, height, width)
        k = 0
        for o in TRUTH:
            maps[o.name] = image(truth_rows[k : k + o.channels])
            k += o.channels
        maps["coverage"] = coverage.reshape(height, width)
        maps["instance_id"] = s["instance_id"].reshape(height, width)
        if covariance is not None:
            maps["measurement_covariance"] = covariance.reshape(n_cameras, n_cameras, height, width)
        return maps


def stderr_dof(state: dict) -> int:
    """The degrees of freedom of the standard errors' variance estimate, of the pixel with
    the fewest: one per closed stratum (two groups each), replicates − 1; 0 where there is
    no error estimate.

    Parameters
    ----------
    state : dict
        An :class:`Accumulator`'s sums (before :meth:`Accumulator.finish` consumes them).

    Returns
    -------
    int
    """
    if "strata_closed" in state and state["strata_closed"].size:
        return int(state["strata_closed"].min())
    if "reps_closed" in state and state["reps_closed"].size:
        return max(int(state["reps_closed"].min()) - 1, 0)
    return 0


def _settled_inputs(settle, *args):
    """Record and replay ``settle`` (a frozen function that does nothing, over a slice
    pass's inputs) once each, before the pass is recorded. Dr.Jit 1.5's first replay of a
    frozen function writes its inputs back and changes how many distinct variables they
    hold (390 to 380 on the moving Cornell box), so the pass's third group no longer
    matched its recording and recorded again: a second trace and a second kernel compile
    in the first render of every scene. Settled first, the pass records once
    (``tests/test_slices.py``)."""
    for _ in range(2):
        settle(*args)


def _add_rows(total, pix, rows):
    """``total[k, pix] += rows[k]`` for every row: per-pixel rows (numpy views of the device's
    sums) are added where they are, not first stacked into a new array."""
    for k, row in enumerate(rows):
        total[k, pix] += row


def _components(value, channels):
    return [value] if channels == 1 else [value[i] for i in range(channels)]


@contextlib.contextmanager
def _collector_paused():
    """Python's garbage collector does not run until the block ends: objects of Dr.Jit's
    registry (Mitsuba's shapes, BSDFs, emitters) freed while ``dr.freeze`` records make the
    recording fail ("the number of registry entries did not match") or abort the process
    (Dr.Jit 1.5)."""
    paused = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if paused:
            gc.enable()


class PassTracer:
    """Traces the passes of one render where its scene is (this process, or a Ray worker:
    :mod:`dopplertof.render_ray`); ``tracer(p)`` is pass ``p``'s increments
    (:meth:`Reducer.reduce`). Fits the scene's time window to the exposure.

    ========  ================  ============================================
    scene     DynamicScene      the scene, its film the render's
    settings  RenderSettings    the render's settings (built, not overrides)
    grid      PhasorGrid|None   a response record's phasors to accumulate too
                                (:class:`~dopplertof.tracing.sink.PhasorGrid`)
    ========  ================  ============================================
    """

    def __init__(self, scene, settings: RenderSettings, grid=None):
        from .tracing.materials import MaterialTables

        scene.set_time_window(settings.exposure_start, settings.exposure_start + settings.exposure_s)
        self.scene, self.settings, self.grid = scene, settings, grid
        self.slices = None
        self._frozen_groups = {}  # traversal "slices": tile size -> its recorded group pass (_sliced)
        if scene.bodies and scene.traversal_in_use() == "slices":
            self.slices = scene.slice_scenes(settings.group_size)
        self.tables = MaterialTables.of(scene)
        self.reducer = Reducer(*Reducer.layout(settings))

    def __call__(self, p: Pass) -> dict:
        from .tracing import interrupts_unwrapped, trace_pass
        from .tracing.lanes import LaneSetup

        s = self.settings
        width, height = self.scene.resolution
        setup = LaneSetup(
            width=width, height=height, pixel_start=p.pixel_start, n_pixels=p.n_pixels, first_sample=p.first_sample,
            samples=p.samples, spp_total=s.spp, n_times=s.group_size,
            exposure_start_s=float(s.exposure_start), exposure_s=float(s.exposure_s), seed=s.seed, grid=self.grid,
        )  # fmt: skip
        with interrupts_unwrapped():  # the path loop and the reduction loop are traced here
            out = trace_pass(self.scene, s, setup, self.tables) if self.slices is None else self._sliced(setup)
            return self.reducer.reduce(p, out)

    def _sliced(self, setup):
        """A pass's per-lane outputs with ``traversal="slices"``: one kernel per group of the
        pass, every pixel's member m at one instant, its scene placed there first
        (:mod:`dopplertof.slices`). The group's pass is traced once and replayed
        (``dr.freeze``) for the others: what changes from group to group (the first sample,
        the members' times, the bodies' poses and vertices) is its arguments' data."""
        import drjit as dr
        import mitsuba as mi

        from .slices import kernel_inputs, table_only_motions
        from .tracing import _interrupt_in, trace_pass
        from .tracing.lanes import slice_times, slices_in_pass_order

        s, n = self.settings, self.settings.group_size
        slices, scene, tables = self.slices, self.scene, self.tables
        # What the recording fixes: everything of the pass but its data (the tile's first
        # pixel, the group's first sample, the members' times, the placed scenes), so one
        # recording per tile size (a render's last tile may be smaller).
        template = dataclasses.replace(setup, samples=n, first_sample=0, pixel_start=0)

        def group(pixel_start, first_sample, slice_u, state):
            slices.set_state(state)
            return trace_pass(scene, s, dataclasses.replace(template, pixel_start=pixel_start, first_sample=first_sample, slice_u=slice_u), tables)

        settle = None
        if setup.n_pixels not in self._frozen_groups:
            gc.collect()  # garbage of earlier renders goes now, not while the pass is recorded (_collector_paused)
            scene.emitters.far_reference()  # built now, not while the pass is recorded
            inputs = kernel_inputs(scene, tables, leave_out=table_only_motions(scene))  # what the kernel reads that no argument holds
            self._frozen_groups[setup.n_pixels] = dr.freeze(group, state_fn=lambda *_: inputs)
            settle = dr.freeze(lambda *_: None, state_fn=lambda *_: inputs)  # _settled_inputs
        traced = self._frozen_groups[setup.n_pixels]
        pixel_start = dr.opaque(mi.UInt32, setup.pixel_start)
        parts = []
        for j, u in enumerate(slice_times(setup, s)):
            slices.place(float(s.exposure_start) + u * float(s.exposure_s))
            first = dr.opaque(mi.UInt32, setup.first_sample + j * n)
            times = mi.Float64([float(x) for x in u])
            dr.make_opaque(times)
            try:
                with _collector_paused():
                    if settle is not None:
                        _settled_inputs(settle, pixel_start, first, times, slices.state())
                        settle = None
                    out = traced(pixel_start, first, times, slices.state())
            except RuntimeError as exc:  # the recording or its replay failed: trace every group instead
                if _interrupt_in(exc) is not None:
                    raise
                cause = str(exc.__cause__ or exc).splitlines()[0]
                warnings.warn(f"traversal='slices' traces every group of this render anew (slower): dr.freeze could not record its pass ({cause})", stacklevel=2)
                self._frozen_groups[setup.n_pixels] = traced = group
                out = group(pixel_start, first, times, slices.state())
            dr.eval(out)  # before the next group moves the scenes
            parts.append(out)
        return slices_in_pass_order(parts, setup.n_pixels, 1 if s.paired else n)
