"""A pass's reduction (:mod:`dopplertof.passes`): the one-kernel per-pixel sums of a pass of
whole units are the block sums they replaced, bit for bit."""

from __future__ import annotations

import mitsuba as mi
import numpy as np
import pytest

from dopplertof.outputs import TRUTH
from dopplertof.passes import Pass, Reducer


def _outputs(rng, lanes, n_cameras):
    """Per-lane outputs of a pass as the tracer lays them out, random (signed, some exact
    zeros, wide range), and the same values on the host: (out, channels, truth rows)."""

    def values():  # magnitudes over 2^±40, so that Float64 sums round and their order shows
        x = (rng.standard_normal(lanes) * np.exp2(rng.integers(-40, 40, lanes))).astype(np.float32)
        x[rng.random(lanes) < 0.1] = 0.0
        return x

    channels = [values() for _ in range(3 + n_cameras)]
    out = {"intensity": mi.Color3f(*[mi.Float(c) for c in channels[:3]]), "measurements": [mi.Float(c) for c in channels[3:]]}
    truth = []
    for o in TRUTH:
        rows = [values() for _ in range(o.channels)]
        truth += rows
        out[o.name] = mi.Float(rows[0]) if o.channels == 1 else (mi.Vector3f if o.channels == 3 else mi.Vector2f)(*[mi.Float(r) for r in rows])
    hits = (rng.random(lanes) < 0.8).astype(np.float32)
    out["hits"], out["instance_id"] = mi.Float(hits), mi.Float(np.zeros(lanes, np.float32))
    return out, channels, truth + [hits]


def _sequential(x):
    """Sums over the last axis one after another, as Dr.Jit's block sums add (not numpy's pairwise sum)."""
    return np.cumsum(x, axis=-1)[..., -1]


@pytest.mark.parametrize("within, size", [(True, 2), (False, 1), (False, 4)])
def test_unit_sums_are_the_block_sums_bit_for_bit(within, size):
    rng = np.random.default_rng(size + 10 * within)
    n_pixels, spp, group, n_cameras = 48, 32, 2, 4  # antithetic pairs, one lane each (replay)
    groups = spp // group
    reducer = Reducer(3, n_cameras, spp, group, group, groups // size, () if within else None)
    lanes = n_pixels * spp
    out, channels, truth_rows = _outputs(rng, lanes, n_cameras)
    inc = reducer.reduce(Pass(0, spp, 0, n_pixels), out)

    x = np.stack(channels).astype(np.float64).reshape(-1, n_pixels, groups, group)
    means = (x[..., 0] + x[..., 1]) * (1.0 / group)  # (channels, pixels, groups), lanes in order
    cams = slice(3, None)
    pairs = [(i, j) for i in range(n_cameras) for j in range(i + 1, n_cameras)]
    if within:  # strata of two groups
        d = means[:, :, 0::2] - means[:, :, 1::2]
        expected = {"group_sum": _sequential(means), "within_sq": _sequential(d * d)}
        expected["within_cross"] = [_sequential(d[cams][i] * d[cams][j]) for i, j in pairs]
    else:
        reps = means if size == 1 else _sequential(means.reshape(-1, n_pixels, groups // size, size)) * (1.0 / size)
        expected = {"rep_sum": _sequential(reps), "rep_sq": _sequential(reps * reps)}
        expected["rep_cross"] = [_sequential(reps[cams][i] * reps[cams][j]) for i, j in pairs]
    truth = _sequential(np.stack(truth_rows).astype(np.float64).reshape(-1, n_pixels, spp))
    expected["truth_sum"] = truth[:-1]
    for name, value in expected.items():
        assert np.array_equal(np.asarray(inc[name]), np.asarray(value)), name
    assert np.array_equal(inc["hits"], np.rint(truth[-1]).astype(np.int32))


def test_spare_sums_hand_back_zeroed_arrays_and_keep_only_whole_ones_within_their_size():
    """:class:`SpareSums` gives a kept array back filled (its pages mapped already), keeps
    no view (a map may look at the memory) and nothing over its size."""
    from dopplertof.passes import SpareSums

    spares = SpareSums(max_bytes=2000)  # room for two arrays of 800 bytes
    a, b = np.arange(100.0), np.ones((2, 50))
    spares.keep(a, b, np.arange(200.0)[::2], np.ones(100))  # a strided view, then one over the size
    again = spares.full(100, np.float64)
    assert again is a and not again.any()
    assert spares.full((2, 50), np.float64, 7.0) is b and (b == 7.0).all()
    assert spares.full(100, np.float64) is not a  # no spare of that shape left: a new one
    assert spares.full(5, np.int32, -1).tolist() == [-1] * 5


def test_a_render_reuses_the_sums_of_the_last_without_touching_its_result():
    """The next render's sums are the arrays the last one's finished (no new pages to map:
    ``benchmarks/static_overhead.py``), its maps are its own (the first result is unchanged
    by the second render), and a render after another gives the same images as the first."""
    import dopplertof as dt
    from dopplertof import passes

    scene = dt.scenes.build("cornell-box", resolution=16)
    cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, np.pi / 2)]
    passes.SPARE_SUMS.clear()  # what earlier renders (other films) kept
    first = dt.render(scene, spp=8, seed=1, cameras=cameras)
    before = {name: np.array(value, copy=True) for name, value in first.maps.items()}
    kept = [id(a) for a in passes.SPARE_SUMS._kept]  # (a test may look inside)
    assert kept, "the finished render kept none of its sums"
    made = []
    init = passes.Accumulator.__init__

    def spy(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append({id(a) for a in self.state.values()})

    passes.Accumulator.__init__ = spy
    try:
        other = dt.render(scene, spp=8, seed=2, cameras=cameras)
    finally:
        passes.Accumulator.__init__ = init
    for name, value in before.items():
        np.testing.assert_array_equal(first.maps[name], value, err_msg=name)
    assert set(kept) <= made[0]
    again = dt.render(scene, spp=8, seed=1, cameras=cameras)
    assert not np.array_equal(other.measurements, first.measurements)
    for name, value in before.items():
        np.testing.assert_array_equal(again.maps[name], value, err_msg=name)
