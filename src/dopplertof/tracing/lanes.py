"""Lanes of a pass: which pixel, group, member and replicate each is, its random streams
and its exposure time.

A pass covers the pixels ``[pixel_start, pixel_start + n_pixels)`` of the film (a tile of
rows, so that a pass's memory does not grow with the film) and the samples
``[first_sample, first_sample + samples)`` of each. Lane ``l`` is sample
``first_sample + l mod samples`` of pixel ``pixel_start + l // samples`` (one lane per
*group* in paired tracing).

Random numbers are replayable (DESIGN §3.2): two PCG32 streams per lane, seeded from
(seed, pixel, group) and (seed, pixel, sample) and never from the lane or the pass, so
lanes of a group replay each other's paths and the result does not depend on how the
samples are split into passes or the pixels into tiles.

Windows of a capture schedule (:attr:`dopplertof.settings.RenderSettings.windows`) are
traced with seeds of their own (:func:`window_seed`), so their estimates are independent;
the first window keeps the render's seed.

Strata and replicates: where the times are stratified
(:func:`dopplertof.timesampling.stratifies`) the G = spp / N groups of a pixel form strata
of two contiguous groups (some of three; :class:`StrataLayout`), each group jittered
independently in its stratum, so the within-stratum differences give honest standard
errors. Otherwise the groups are independent and are split into R contiguous runs of
nearly equal size (:func:`replicate_layout`), whose means' spread is the standard error.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

STREAM_SHARED = 0x5EED0001
STREAM_OWN = 0x5EED0002
STREAM_ROTATION = 0x5EED0003
STREAM_SLICE = 0x5EED0004  # a slice's group number (traversal "slices": shared by all pixels)
STREAM_SLICE_OWN = 0x5EED0005  # a slice's member's own number


@dataclass(frozen=True)
class LaneSetup:
    """Host-side description of one pass.

    Parameters
    ----------
    width, height : int
        Film size in pixels.
    pixel_start : int
        First pixel (row-major index) of the pass's tile.
    n_pixels : int
        Pixels in the tile.
    first_sample : int
        Global index of the pass's first sample in each pixel.
    samples : int
        Samples of each pixel in this pass (a multiple of ``n_times``).
    spp_total : int
        Samples per pixel of the whole render.
    n_times : int
        Correlated times per group (N).
    exposure_start_s, exposure_s : float, s
        The exposure window.
    seed : int
        The window's seed, in [0, 2³²).
    grid : PhasorGrid or None
        A response record's frequencies (:class:`dopplertof.tracing.sink.PhasorGrid`) the pass
        accumulates; default None.
    slice_u : mi.Float64 or None
        With ``traversal="slices"`` (:mod:`dopplertof.slices`): the pass holds one group
        of each pixel, lanes member-major, and member ``m`` of every pixel takes the
        normalised time ``slice_u[m]`` (:func:`slice_times`); default None. Its
        ``first_sample`` may then be an ``mi.UInt32`` (a frozen pass's argument).
    """

    width: int
    height: int
    pixel_start: int  # first pixel (row-major index) of the pass's tile
    n_pixels: int  # pixels in the tile
    first_sample: int  # global index of the pass's first sample in each pixel
    samples: int  # samples of each pixel in this pass (a multiple of n_times)
    spp_total: int
    n_times: int  # correlated times per group (N)
    exposure_start_s: float
    exposure_s: float
    seed: int
    grid: object = None  # a response record's PhasorGrid (tracing.sink) the pass accumulates, or None
    slice_u: object = None  # traversal "slices": each member's normalised time (mi.Float64), shared by every pixel (slice_times)

    @property
    def n_groups(self) -> int:
        """Groups of correlated times per pixel: spp / n_times (at least 1)."""
        return max(self.spp_total // self.n_times, 1)


def replicate_layout(n_groups: int, replicates: int) -> tuple[int, int, int]:
    """(R, base, extra): R = min(replicates, G) runs; the first ``extra`` have ``base + 1``
    groups, the others ``base``.

    Parameters
    ----------
    n_groups : int
        Groups G of a pixel.
    replicates : int
        Requested replicates.

    Returns
    -------
    tuple of (int, int, int)
    """
    count = max(1, min(replicates, n_groups))
    return count, n_groups // count, n_groups % count


def replicate_bounds(n_groups: int, replicates: int) -> list[tuple[int, int]]:
    """[(first group, group count)] of each replicate (host side, same layout).

    Parameters
    ----------
    n_groups : int
        Groups of a pixel.
    replicates : int
        Requested replicates.

    Returns
    -------
    list of tuple of (int, int)
    """
    count, base, extra = replicate_layout(n_groups, replicates)
    return [(r * base + min(r, extra), base + (r < extra)) for r in range(count)]


def window_seed(seed: int, window: int) -> int:
    """The seed of window ``window`` of a capture schedule: ``seed`` itself for the first,
    else a 32-bit hash of (seed, window), far from ``seed + i`` (an animation's frames).

    Parameters
    ----------
    seed : int
        The render's seed, in [0, 2³²).
    window : int
        The window's index, from 0.

    Returns
    -------
    int
        In [0, 2³²).
    """
    if window == 0:
        return seed
    digest = hashlib.sha256(f"dopplertof window {seed} {window}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def opaque_u32(value):
    """A UInt32 scalar as kernel data rather than code: another value reuses the kernel.

    Parameters
    ----------
    value : int or mi.UInt32
        An ``mi.UInt32`` is data already (a frozen slice pass's argument): returned as is.

    Returns
    -------
    mi.UInt32
    """
    import drjit as dr
    import mitsuba as mi

    if isinstance(value, mi.UInt32):  # already data (a frozen slice pass's argument)
        return value
    a = mi.UInt32(int(value) & 0xFFFFFFFF)
    dr.make_opaque(a)
    return a


def seeded_pcg(seed_u32, stream, key_a, key_b):
    """A PCG32 seeded from (seed, stream, key_a, key_b) alone (DESIGN §3.2).

    Parameters
    ----------
    seed_u32 : mi.UInt32
        The window's seed.
    stream : int
        Which stream (``STREAM_*``).
    key_a, key_b : mi.UInt32
        The keys (pixel, sample or group).

    Returns
    -------
    mi.PCG32
    """
    import mitsuba as mi

    v0, v1 = mi.sample_tea_32(seed_u32 ^ stream, key_a, 4)
    rng = mi.PCG32()
    w0, w1 = mi.sample_tea_32(v0 ^ key_b, v1, 4)
    rng.seed(w0, w1)
    return rng


class Streams:
    """A lane's two streams: the group's (shared) and its own.

    ``next_1d(correlated)`` takes the group's number where ``correlated``: a Python bool
    when it is the same for every lane (only that stream advances) or a per-lane Bool
    (both advance, so each stays in step within its group). It is a Dr.Jit PyTree, so
    a symbolic loop carries its generators' state from one iteration to the next.

    Parameters
    ----------
    shared : mi.PCG32 or None, default None
        The group's stream.
    own : mi.PCG32 or None, default None
        The lane's own stream.
    """

    DRJIT_STRUCT = {"shared": object, "own": object}  # a PyTree: loop state for Dr.Jit

    def __init__(self, shared=None, own=None):
        self.shared, self.own = shared, own

    def next_1d(self, correlated):
        """The next uniform number in [0, 1) per lane: the group's stream where ``correlated``
        (a bool for every lane, or a per-lane Bool), else the lane's own (class docstring).

        Parameters
        ----------
        correlated : bool or mi.Bool

        Returns
        -------
        mi.Float
        """
        import drjit as dr

        if correlated is True:
            return self.shared.next_float32()
        if correlated is False:
            return self.own.next_float32()
        a = self.shared.next_float32()
        b = self.own.next_float32()
        return dr.select(correlated, a, b)

    def next_2d(self, correlated):
        """Two numbers of :meth:`next_1d` as a ``mi.Point2f``.

        Parameters
        ----------
        correlated : bool or mi.Bool

        Returns
        -------
        mi.Point2f
        """
        import mitsuba as mi

        return mi.Point2f(self.next_1d(correlated), self.next_1d(correlated))


def pixel_and_index(setup: LaneSetup, per_pixel: int):
    """(global pixel, index within the pixel's pass range) of every lane, ``per_pixel``
    lanes per pixel.

    Parameters
    ----------
    setup : LaneSetup
    per_pixel : int
        Lanes per pixel.

    Returns
    -------
    tuple of (mi.UInt32, mi.UInt32)
    """
    import drjit as dr
    import mitsuba as mi

    lane = dr.arange(mi.UInt32, setup.n_pixels * per_pixel)
    if setup.slice_u is not None:  # member-major: a SIMD packet's lanes trace one member's scene
        n_pixels = opaque_u32(setup.n_pixels)
        return lane % n_pixels + opaque_u32(setup.pixel_start), lane // n_pixels
    per = opaque_u32(per_pixel)  # data, not code: any spp or tile reuses the kernel
    return lane // per + opaque_u32(setup.pixel_start), lane % per


def slices_in_pass_order(parts, n_pixels: int, n_times: int):
    """The per-lane outputs of a pass's groups, traced one slice pass per group
    (``traversal="slices"``: member-major lanes, :func:`pixel_and_index`), in the lane order
    of a pass that traced them together (pixel-major, then group, then member), which the
    reduction expects.

    Parameters
    ----------
    parts : list of dict
        Per group of the pass, in order: its outputs (PyTrees of evaluated per-lane arrays).
    n_pixels : int
        Pixels of the pass's tile.
    n_times : int
        A pixel's lanes in a group's kernel: its members N (1 for the paired estimators,
        whose lane traces the whole group).

    Returns
    -------
    dict
    """
    import drjit as dr
    import mitsuba as mi

    lanes = n_pixels * n_times
    lane = dr.arange(mi.UInt32, lanes)
    member, pixel = lane // opaque_u32(n_pixels), lane % opaque_u32(n_pixels)
    per_pixel = opaque_u32(len(parts) * n_times)

    def placed(values):
        x = values[0]
        if isinstance(x, dict):
            return {k: placed([v[k] for v in values]) for k in x}
        if isinstance(x, (list, tuple)):
            return type(x)(placed([v[i] for v in values]) for i in range(len(x)))
        out = dr.zeros(type(x), lanes * len(values))
        for j, v in enumerate(values):
            dr.scatter(out, v, pixel * per_pixel + opaque_u32(j * n_times) + member)
        return out

    return placed(parts)


class StrataLayout:
    """The strata of a pixel's G groups (:mod:`dopplertof.timesampling`), in group order.

    The interval, in units of 1/G, is cut at the ``wraps`` that fall between groups (none
    where a piece would hold fewer than 2 groups); each piece is split into pairs, the last
    holding three where the piece has an odd number (one where G = 1). A stratum's
    *place* is its first unit in the interval; the pieces' strata take turns in group order
    (round i holds the i-th stratum of each piece), so every prefix of the groups spreads
    over the pieces. Per pixel the pairs of a piece (its first ``span`` units) are rotated
    by a whole number of pairs (:func:`stratum`), so each group's time is uniform over them
    on its own: a render stopped before its last pass is unbiased (but for a piece's
    three-group stratum). Computed, not listed: a render of 10⁹ spp has 10⁸ strata.

    Parameters
    ----------
    n_groups : int
        Groups G of a pixel, at least 1.
    wraps : sequence of float, default ()
        Cut points in (0, 1) (:func:`dopplertof.timesampling.wrap_points`).
    """

    def __init__(self, n_groups: int, wraps=()):
        from ..timesampling import group_cuts

        self.n_groups = n_groups
        edges = sorted({0, n_groups} | {c for c in group_cuts(n_groups, wraps)[0] if 0 < c < n_groups})
        if any(b - a < 2 for a, b in zip(edges, edges[1:])):
            edges = [0, n_groups]
        # per piece: (start, length, strata); its last stratum holds length - 2 (strata - 1) groups
        self.pieces = [(a, b - a, max((b - a) // 2, 1)) for a, b in zip(edges, edges[1:])]

    def _round_start(self, i: int) -> int:
        """The first group of round ``i``."""
        return sum(2 * min(i, n) + (length - 2 * n if i >= n else 0) for _, length, n in self.pieces)

    def units(self, g0: int, g1: int) -> list[tuple[int, int, int, int, int]]:
        """(first group, group count, place, piece start, piece span) of the strata that
        hold groups of [g0, g1), in group order.

        Parameters
        ----------
        g0, g1 : int
            A range of groups.

        Returns
        -------
        list of tuple of (int, int, int, int, int)
        """
        lo, hi = 0, max(n for *_, n in self.pieces)
        while lo < hi:  # the round that holds g0: the last whose start is <= g0
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if self._round_start(mid) <= g0 else (lo, mid - 1)
        out, first, i = [], self._round_start(lo), lo
        while first < g1:
            for start, length, n in self.pieces:
                if i < n:
                    size = 2 if i < n - 1 else length - 2 * (n - 1)
                    span = length if length % 2 == 0 else max(length - 3, 0)
                    if g0 < first + size and first < g1:
                        out.append((first, size, start + 2 * i, start, span))
                    first += size
            i += 1
        return out


def stratum(setup: LaneSetup, group, wraps, rotation):
    """(place, group count) of the stratum of per-lane ``group`` (UInt32, in the pass),
    its place rotated by ``rotation`` (:class:`StrataLayout`).

    Parameters
    ----------
    setup : LaneSetup
    group : mi.UInt32
        Each lane's group in its pixel.
    wraps : sequence of float
        Cut points in (0, 1).
    rotation : mi.Float
        A uniform per lane (per pixel, or per pixel and member): picks the rotation.

    Returns
    -------
    tuple of (mi.Float64, mi.UInt32)
    """
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    from ..jitdata import jit_array

    g0 = setup.first_sample // setup.n_times
    g1 = g0 + setup.samples // setup.n_times
    table = np.zeros((4, g1 - g0), np.uint32)  # per group of the pass: count, place, piece start, piece span
    for first, n, place, start, span in StrataLayout(setup.n_groups, wraps).units(g0, g1):
        a, b = max(first, g0) - g0, min(first + n, g1) - g0
        table[:, a:b] = np.array([n, place, start, span], np.uint32)[:, None]
    local = group - opaque_u32(g0)
    # data, not code; aligned, as a pass of one group reads each row as a scalar (jitdata)
    count, place, start, span = (dr.gather(mi.UInt32, jit_array(mi.UInt32, row), local) for row in table)
    F = mi.Float64
    offset = F(place - start)
    rotated = offset + 2.0 * dr.floor(F(rotation) * F(span) * 0.5)
    rotated = dr.select(rotated >= F(span), rotated - F(span), rotated)
    return F(start) + dr.select(offset < F(span), rotated, offset), count


def sample_time(setup: LaneSetup, settings, seed, pixel, group, member, r_shared, r_own):
    """Normalised time u (Float64) of each lane (:mod:`dopplertof.timesampling`).

    Parameters
    ----------
    setup : LaneSetup
    settings : RenderSettings
        Its time sampling, shift and stratification.
    seed : mi.UInt32
        The window's seed.
    pixel, group, member : mi.UInt32
        Each lane's pixel, group and member in the group.
    r_shared, r_own : mi.Float
        The group's and the lane's uniform numbers.

    Returns
    -------
    mi.Float64
        u in [0, 1).
    """
    import mitsuba as mi

    from ..timesampling import sample_times

    if setup.slice_u is not None:
        import drjit as dr

        return dr.gather(mi.Float64, setup.slice_u, mi.UInt32(member))
    # stratified decorrelates its members' strata; the antithetic members share r
    key = mi.UInt32(member) if settings.time_sampling == "stratified" else mi.UInt32(0)
    rotation = seeded_pcg(seed, STREAM_ROTATION, pixel, key).next_float32()
    place, count = stratum(setup, group, settings.wraps, rotation)
    return sample_times(
        settings.time_sampling, r_shared, r_own, place, count, setup.n_groups, mi.UInt32(member), setup.n_times,
        settings.shift, settings.stratify_intervals,
    )  # fmt: skip


def slice_times(setup: LaneSetup, settings):
    """Normalised times u of the members of every group of a pass with
    ``traversal="slices"`` (:mod:`dopplertof.slices`), shared by all pixels: drawn as
    :func:`sample_time` draws a pixel's, from streams keyed by the group (and member)
    alone, the strata rotated once for all pixels. Each pixel's times keep their
    distribution.

    Parameters
    ----------
    setup : LaneSetup
        The pass.
    settings : RenderSettings

    Returns
    -------
    numpy.ndarray
        u, shape (groups of the pass, members), float64, in [0, 1).
    """
    import dataclasses

    import drjit as dr
    import mitsuba as mi
    import numpy as np

    n = setup.n_times
    count = setup.samples  # the pass's groups x members
    sample = dr.arange(mi.UInt32, count) + opaque_u32(setup.first_sample)
    group, member = sample // opaque_u32(n), sample % opaque_u32(n)
    seed = opaque_u32(setup.seed)
    everywhere = dr.zeros(mi.UInt32, count)  # the pixel's place in the streams: one for all pixels
    r_shared = seeded_pcg(seed, STREAM_SLICE, everywhere, group).next_float32()
    r_own = seeded_pcg(seed, STREAM_SLICE_OWN, member, group).next_float32()
    u = sample_time(dataclasses.replace(setup, slice_u=None), settings, seed, everywhere, group, member, r_shared, r_own)
    return np.asarray(u, dtype=np.float64).reshape(-1, n)


def lane_times(setup: LaneSetup, u):
    """Scene times (s, Float64) of normalised times ``u``; the exposure is opaque data, so
    another exposure window (an animation's next frame) reuses the kernel.

    Parameters
    ----------
    setup : LaneSetup
    u : mi.Float64
        Normalised times.

    Returns
    -------
    mi.Float64
        Seconds.
    """
    import drjit as dr
    import mitsuba as mi

    start = mi.Float64(setup.exposure_start_s)
    length = mi.Float64(setup.exposure_s)
    dr.make_opaque(start, length)
    return start + u * length
