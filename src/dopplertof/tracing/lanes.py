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

Replicates: the G = spp / N groups of a pixel are split into R contiguous runs of nearly
equal size (:func:`replicate_layout`); each run is stratified over its own groups
(:mod:`dopplertof.timesampling`), so the R run means are independent and their spread
is an honest standard error even where stratification makes groups dependent.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

STREAM_SHARED = 0x5EED0001
STREAM_OWN = 0x5EED0002
STREAM_ROTATION = 0x5EED0003


@dataclass(frozen=True)
class LaneSetup:
    """Host-side description of one pass."""

    width: int
    height: int
    pixel_start: int  # first pixel (row-major index) of the pass's tile
    n_pixels: int  # pixels in the tile
    first_sample: int  # global index of the pass's first sample in each pixel
    samples: int  # samples of each pixel in this pass (a multiple of n_times)
    spp_total: int
    n_times: int  # correlated times per group (N)
    replicates: int  # requested R (fewer where the pixel has fewer groups)
    exposure_start_s: float
    exposure_s: float
    seed: int

    @property
    def n_groups(self) -> int:
        """Groups of correlated times per pixel: spp / n_times (at least 1)."""
        return max(self.spp_total // self.n_times, 1)

    @property
    def layout(self) -> tuple[int, int, int]:
        """(R, base, extra) of a pixel's groups: :func:`replicate_layout` of
        :attr:`n_groups` and ``replicates``."""
        return replicate_layout(self.n_groups, self.replicates)


def replicate_layout(n_groups: int, replicates: int) -> tuple[int, int, int]:
    """(R, base, extra): R = min(replicates, G) runs; the first ``extra`` have ``base + 1``
    groups, the others ``base``."""
    count = max(1, min(replicates, n_groups))
    return count, n_groups // count, n_groups % count


def replicate_bounds(n_groups: int, replicates: int) -> list[tuple[int, int]]:
    """[(first group, group count)] of each replicate (host side, same layout)."""
    count, base, extra = replicate_layout(n_groups, replicates)
    return [(r * base + min(r, extra), base + (r < extra)) for r in range(count)]


def window_seed(seed: int, window: int) -> int:
    """The seed of window ``window`` of a capture schedule: ``seed`` itself for the first,
    else a 32-bit hash of (seed, window), far from ``seed + i`` (an animation's frames)."""
    if window == 0:
        return seed
    digest = hashlib.sha256(f"dopplertof window {seed} {window}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def opaque_u32(value):
    """A UInt32 scalar as kernel data rather than code: another value reuses the kernel."""
    import drjit as dr
    import mitsuba as mi

    a = mi.UInt32(int(value) & 0xFFFFFFFF)
    dr.make_opaque(a)
    return a


def seeded_pcg(seed_u32, stream, key_a, key_b):
    """A PCG32 seeded from (seed, stream, key_a, key_b) alone (DESIGN §3.2)."""
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
    """

    DRJIT_STRUCT = {"shared": object, "own": object}  # a PyTree: loop state for Dr.Jit

    def __init__(self, shared=None, own=None):
        self.shared, self.own = shared, own

    def next_1d(self, correlated):
        """The next uniform number in [0, 1) per lane: the group's stream where ``correlated``
        (a bool for every lane, or a per-lane Bool), else the lane's own (class docstring)."""
        import drjit as dr

        if correlated is True:
            return self.shared.next_float32()
        if correlated is False:
            return self.own.next_float32()
        a = self.shared.next_float32()
        b = self.own.next_float32()
        return dr.select(correlated, a, b)

    def next_2d(self, correlated):
        """Two numbers of :meth:`next_1d` as a ``mi.Point2f``."""
        import mitsuba as mi

        return mi.Point2f(self.next_1d(correlated), self.next_1d(correlated))


def pixel_and_index(setup: LaneSetup, per_pixel: int):
    """(global pixel, index within the pixel's pass range) of every lane, ``per_pixel``
    lanes per pixel."""
    import drjit as dr
    import mitsuba as mi

    lane = dr.arange(mi.UInt32, setup.n_pixels * per_pixel)
    per = opaque_u32(per_pixel)  # data, not code: any spp or tile reuses the kernel
    return lane // per + opaque_u32(setup.pixel_start), lane % per


def stratum(setup: LaneSetup, group):
    """(replicate, index in it, its group count) of per-lane ``group`` (UInt32)."""
    import drjit as dr

    _, base, extra = setup.layout
    base_u, extra_n = opaque_u32(base), opaque_u32(extra)  # base >= 1: R <= G
    cut = extra_n * (base_u + 1)
    big = group < cut
    g_rest = group - cut
    replicate = dr.select(big, group // (base_u + 1), extra_n + g_rest // base_u)
    index = dr.select(big, group % (base_u + 1), g_rest % base_u)
    return replicate, index, dr.select(big, base_u + 1, base_u)


def sample_time(setup: LaneSetup, settings, seed, pixel, group, member, r_shared, r_own):
    """Normalised time u (Float64) of each lane (:mod:`dopplertof.timesampling`)."""
    import mitsuba as mi

    from ..timesampling import sample_times

    replicate, index, n_strata = stratum(setup, group)
    rotation = seeded_pcg(seed, STREAM_ROTATION, pixel, replicate * setup.n_times + member).next_float32()
    return sample_times(
        settings.time_sampling, r_shared, r_own, index, n_strata, mi.UInt32(member), setup.n_times,
        settings.shift, settings.stratify_intervals, rotation,
    )  # fmt: skip


def lane_times(setup: LaneSetup, u):
    """Scene times (s, Float64) of normalised times ``u``; the exposure is opaque data, so
    another exposure window (an animation's next frame) reuses the kernel."""
    import drjit as dr
    import mitsuba as mi

    start = mi.Float64(setup.exposure_start_s)
    length = mi.Float64(setup.exposure_s)
    dr.make_opaque(start, length)
    return start + u * length
