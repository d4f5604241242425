"""Rigid motion models against an independent numpy reference.

The reference builds every key from known parameters (translation, axis-angle rotation,
per-axis scale) and interpolates them with Rodrigues' formula, never with quaternions, so
it shares no code with :mod:`dopplertof.motion`.
"""

import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from dopplertof.motion import Keyframed, Parametric

# ----------------------------------------------------------------------------------------
# Independent reference


def rodrigues(axis, angle):
    """3x3 rotation by ``angle`` (rad) about ``axis``."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def rotation_log(r):
    """(axis, angle) of a rotation matrix with angle in (0, π)."""
    angle = math.acos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    if angle < 1e-12:
        return np.array([0.0, 0.0, 1.0]), 0.0
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (2 * math.sin(angle))
    return axis, angle


def trs(translation, rotation, scale):
    m = np.eye(4)
    m[:3, :3] = rotation @ np.diag(scale)
    m[:3, 3] = translation
    return m


class RefKeys:
    """Keys (t, b, R, s) and their interpolation: linear b and s, geodesic R."""

    def __init__(self, times, translations, rotations, scales):
        self.times = np.asarray(times, dtype=np.float64)
        self.b = [np.asarray(x, dtype=np.float64) for x in translations]
        self.r = rotations
        self.s = [np.asarray(x, dtype=np.float64) for x in scales]

    def matrices(self):
        return [trs(b, r, s) for b, r, s in zip(self.b, self.r, self.s)]

    def matrix(self, t):
        if t <= self.times[0]:
            return trs(self.b[0], self.r[0], self.s[0])
        if t >= self.times[-1]:
            return trs(self.b[-1], self.r[-1], self.s[-1])
        i = int(np.searchsorted(self.times, t, side="right") - 1)
        a = (t - self.times[i]) / (self.times[i + 1] - self.times[i])
        axis, angle = rotation_log(self.r[i + 1] @ self.r[i].T)
        rot = rodrigues(axis, a * angle) @ self.r[i]
        return trs((1 - a) * self.b[i] + a * self.b[i + 1], rot, (1 - a) * self.s[i] + a * self.s[i + 1])


def parametric_reference(v, w, pivot, base, t):
    """Translate(pivot + v t) · Rotate(ω t) · Translate(−pivot) · base."""
    w = np.asarray(w, dtype=np.float64)
    rate = np.linalg.norm(w)
    rot = np.eye(4)
    if rate > 0:
        rot[:3, :3] = rodrigues(w / rate, rate * t)
    to_pivot = np.eye(4)
    to_pivot[:3, 3] = np.asarray(pivot) + np.asarray(v) * t
    from_pivot = np.eye(4)
    from_pivot[:3, 3] = -np.asarray(pivot, dtype=np.float64)
    return to_pivot @ rot @ from_pivot @ base


def apply(m, p):
    return (m[:3, :3] @ p.T).T + m[:3, 3]


def fd_velocity(matrix_fn, t, p_world, h):
    """d/dt of the body point at ``p_world`` at time t, by central differences."""
    local = apply(np.linalg.inv(matrix_fn(t)), p_world)
    return (apply(matrix_fn(t + h), local) - apply(matrix_fn(t - h), local)) / (2 * h)


def vec_np(v):
    return np.array([np.asarray(v.x), np.asarray(v.y), np.asarray(v.z)], dtype=np.float64).T


def pose_arrays(pose, x_local, p_world, precise):
    """Evaluate a Pose per lane: world point, local point, velocity at p_world."""
    V = mi.Point3d if precise else mi.Point3f
    xw = pose.point_to_world(V(*[x_local[:, k] for k in range(3)]))
    xl = pose.point_to_local(V(*[p_world[:, k] for k in range(3)]))
    vel = pose.velocity(V(*[p_world[:, k] for k in range(3)]))
    dr.eval(xw, xl, vel)
    return vec_np(xw), vec_np(xl), vec_np(vel)


# ----------------------------------------------------------------------------------------
# Fixtures


@pytest.fixture(scope="module")
def three_keys():
    """Three keys with rotation about changing axes, translation and non-uniform scale."""
    return RefKeys(
        times=[0.0, 1.0e-3, 2.5e-3],
        translations=[[0.1, -0.2, 0.3], [0.6, 0.1, -0.4], [1.0, 0.8, 0.2]],
        rotations=[rodrigues([0, 0, 1], 0.3), rodrigues([1, 1, 0], 1.1) @ rodrigues([0, 0, 1], 0.3), rodrigues([0.2, 1, 0.3], 2.0)],
        scales=[[1.0, 2.0, 0.5], [1.5, 1.0, 0.7], [0.8, 1.2, 1.1]],
    )


@pytest.fixture(scope="module")
def keyframed(three_keys):
    return Keyframed(three_keys.times, three_keys.matrices())


# ----------------------------------------------------------------------------------------
# Keyframed


def test_keyframed_matrix_at_keys_equals_the_keys(three_keys, keyframed):
    for t, m in zip(three_keys.times, three_keys.matrices()):
        np.testing.assert_allclose(keyframed.matrix(t), m, rtol=0, atol=1e-12)


def test_keyframed_matrix_interpolates_like_the_reference(three_keys, keyframed):
    for t in np.linspace(0.0, 2.5e-3, 23):
        np.testing.assert_allclose(keyframed.matrix(t), three_keys.matrix(t), rtol=0, atol=1e-10, err_msg=f"t={t}")


def test_keyframed_matrices_of_many_times_at_once_match_the_reference(three_keys, keyframed):
    """Times before, between, on and after the keys, unsorted, in one call (swept bounds
    evaluate their sample times so)."""
    times = np.array([2.0e-3, -1.0, 0.0, 1.0e-3, 0.3e-3, 2.5e-3, 7.0, 1.7e-3, 2.5e-3 - 1e-12])
    stacked = keyframed.matrices(times)
    assert stacked.shape == (len(times), 4, 4)
    for t, m in zip(times, stacked):
        np.testing.assert_allclose(m, three_keys.matrix(t), rtol=0, atol=1e-10, err_msg=f"t={t}")
    assert Keyframed([0.5], three_keys.matrices()[:1]).matrices(times).shape == (len(times), 4, 4)


def test_slerp_of_a_quarter_turn_at_half_time_is_an_eighth_turn():
    start = np.eye(4)
    end = trs([0, 0, 0], rodrigues([0, 0, 1], math.pi / 2), [1, 1, 1])
    motion = Keyframed([0.0, 2.0], [start, end])
    np.testing.assert_allclose(motion.matrix(1.0)[:3, :3], rodrigues([0, 0, 1], math.pi / 4), atol=1e-12)
    pose = motion.pose(mi.Float64([1.0, 0.5]), precise=True)
    x = vec_np(pose.point_to_world(mi.Point3d(1, 0, 0)))
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    np.testing.assert_allclose(x[0], [c, s, 0], atol=1e-12)
    np.testing.assert_allclose(x[1], [math.cos(math.pi / 8), math.sin(math.pi / 8), 0], atol=1e-12)
    # Constant angular velocity (π/2)/(2 s) about +z.
    np.testing.assert_allclose(vec_np(pose.omega)[0], [0, 0, math.pi / 4], atol=1e-12)


@pytest.mark.parametrize("precise, rtol, atol", [(True, 1e-10, 1e-12), (False, 2e-6, 2e-6)])
def test_keyframed_pose_matches_the_reference_per_lane(three_keys, keyframed, precise, rtol, atol):
    rng = np.random.default_rng(0)
    times = np.concatenate([three_keys.times, rng.uniform(-1e-3, 3.5e-3, 61)])
    x_local = rng.uniform(-1, 1, (len(times), 3))
    p_world = rng.uniform(-2, 2, (len(times), 3))
    xw, xl, _ = pose_arrays(keyframed.pose(mi.Float64(times), precise), x_local, p_world, precise)
    for i, t in enumerate(times):
        m = three_keys.matrix(t)
        np.testing.assert_allclose(xw[i], apply(m, x_local[i]), rtol=rtol, atol=atol, err_msg=f"t={t}")
        np.testing.assert_allclose(xl[i], apply(np.linalg.inv(m), p_world[i]), rtol=rtol, atol=10 * atol, err_msg=f"t={t}")


def test_keyframed_pose_with_many_unevenly_spaced_keys_matches_the_reference():
    """The key interval is found per lane among 50 keys: every interval, the keys
    themselves and times outside the key range."""
    rng = np.random.default_rng(11)
    n = 50
    times = np.cumsum(rng.uniform(0.01e-3, 1.0e-3, n)) + 0.5e-3  # gaps vary 100-fold
    rotations = [rodrigues([0, 0, 1], 0.2)]
    for _ in range(n - 1):  # < π per interval: slerp and the reference take the same arc
        rotations.append(rodrigues(rng.normal(size=3), rng.uniform(0.1, 2.5)) @ rotations[-1])
    ref = RefKeys(times, rng.uniform(-1, 1, (n, 3)), rotations, rng.uniform(0.5, 2.0, (n, 3)))
    motion = Keyframed(ref.times, ref.matrices())
    lane_times = np.concatenate(
        [times, 0.5 * (times[1:] + times[:-1]), rng.uniform(times[0] - 1e-3, times[-1] + 1e-3, 200), [times[0] - 1.0, times[-1] + 1.0]]
    )
    x_local = rng.uniform(-1, 1, (len(lane_times), 3))
    for precise, tol in [(True, 1e-9), (False, 2e-5)]:
        xw, _, _ = pose_arrays(motion.pose(mi.Float64(lane_times), precise), x_local, x_local, precise)
        expected = np.array([apply(ref.matrix(t), x) for t, x in zip(lane_times, x_local)])
        np.testing.assert_allclose(xw, expected, rtol=tol, atol=tol, err_msg=f"precise={precise}")
    # Velocity: the rate of the interval holding each lane's time, zero outside the keys.
    mid = 0.5 * (times[1:] + times[:-1])
    p_world = rng.uniform(-2, 2, (len(mid), 3))
    _, _, vel = pose_arrays(motion.pose(mi.Float64(mid), True), p_world, p_world, True)
    h = 1e-3 * np.diff(times).min()
    expected = np.array([fd_velocity(ref.matrix, t, p, h) for t, p in zip(mid, p_world)])
    np.testing.assert_allclose(vel, expected, rtol=1e-5, atol=1e-3 * np.abs(expected).max())


def test_key_values_of_many_keys_do_not_change_the_kernel():
    """Only the number of keys is part of the kernel: the search over other key times and
    transforms launches the same kernel."""
    rng = np.random.default_rng(12)
    lane_times = mi.Float64(rng.uniform(-0.1, 1.1, 64))

    def kernel_of(times):
        mats = [trs(rng.uniform(-1, 1, 3), rodrigues(rng.normal(size=3), rng.uniform(0, 1)), rng.uniform(0.5, 2, 3)) for _ in times]
        x = Keyframed(times, mats).pose(lane_times, True).point_to_world(mi.Point3d(0.1, 0.2, 0.3))
        dr.kernel_history()  # clear
        dr.eval(x)
        return [k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]

    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        first = kernel_of(np.linspace(0.0, 1.0, 20))
        assert first
        assert kernel_of(np.sort(rng.uniform(0.0, 1.0, 20))) == first
        assert kernel_of(np.linspace(0.0, 1.0, 21)) != first  # the check can tell kernels apart
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was)


def test_keyframed_velocity_equals_finite_differences_inside_segments(three_keys, keyframed):
    times = np.array([0.1e-3, 0.5e-3, 0.93e-3, 1.2e-3, 1.9e-3, 2.4e-3])
    rng = np.random.default_rng(1)
    p_world = rng.uniform(-2, 2, (len(times), 3))
    _, _, vel = pose_arrays(keyframed.pose(mi.Float64(times), True), np.zeros_like(p_world), p_world, True)
    for i, t in enumerate(times):
        expected = fd_velocity(three_keys.matrix, t, p_world[i], h=1e-8)
        np.testing.assert_allclose(vel[i], expected, rtol=1e-5, atol=1e-3, err_msg=f"t={t}")
        assert np.linalg.norm(expected) > 10.0  # the motion is fast: the check is not vacuous


def test_keyframed_clamps_outside_the_key_range_with_zero_velocity(three_keys, keyframed):
    before, after = -1.0, 1.0
    np.testing.assert_allclose(keyframed.matrix(before), three_keys.matrices()[0], atol=1e-12)
    np.testing.assert_allclose(keyframed.matrix(after), three_keys.matrices()[-1], atol=1e-12)
    p_world = np.array([[0.3, 0.2, 0.1], [1.0, -1.0, 0.5]])
    x_local = np.array([[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]])
    xw, _, vel = pose_arrays(keyframed.pose(mi.Float64([before, after]), True), x_local, p_world, True)
    np.testing.assert_allclose(xw[0], apply(three_keys.matrices()[0], x_local[0]), atol=1e-12)
    np.testing.assert_allclose(xw[1], apply(three_keys.matrices()[-1], x_local[1]), atol=1e-12)
    np.testing.assert_array_equal(vel, 0.0)


def test_keyframed_normals_and_vectors_follow_the_linear_part(three_keys, keyframed):
    t = 1.7e-3
    m = three_keys.matrix(t)[:3, :3]
    n_local = np.array([0.3, -0.5, 0.8])
    v_local = np.array([1.0, 0.2, -0.4])
    pose = keyframed.pose(mi.Float64([t]), True)
    n = vec_np(pose.normal_to_world(mi.Vector3d(*[float(x) for x in n_local])))[0]
    v = vec_np(pose.vector_to_world(mi.Vector3d(*[float(x) for x in v_local])))[0]
    n_ref = np.linalg.inv(m).T @ n_local
    np.testing.assert_allclose(n, n_ref / np.linalg.norm(n_ref), atol=1e-12)
    np.testing.assert_allclose(v, m @ v_local, atol=1e-12)


def test_two_keyframed_motions_with_the_same_key_count_give_their_own_results():
    """Motion parameters are data, not kernel constants: two motions evaluated one after
    the other (the second reusing the first's kernel) must each give their own poses."""
    a = RefKeys([0.0, 1.0], [[0, 0, 0], [1, 0, 0]], [np.eye(3), rodrigues([0, 1, 0], 0.5)], [[1, 1, 1], [2, 1, 1]])
    b = RefKeys([0.5, 3.0], [[0, 2, 0], [0, 0, 5]], [rodrigues([1, 0, 0], 1.0), np.eye(3)], [[1, 1, 3], [1, 1, 1]])
    x = np.array([[0.2, 0.3, 0.4]] * 3)
    times = np.array([0.25, 0.6, 0.9])
    for ref in (a, b, a):
        motion = Keyframed(ref.times, ref.matrices())
        xw, _, _ = pose_arrays(motion.pose(mi.Float64(times), True), x, x, True)
        for i, t in enumerate(times):
            np.testing.assert_allclose(xw[i], apply(ref.matrix(t), x[i]), atol=1e-12)


def test_single_key_is_static():
    m = trs([1, 2, 3], rodrigues([0, 1, 0], 0.4), [2, 2, 2])
    motion = Keyframed([0.0], [m])
    assert motion.is_static()
    xw, _, vel = pose_arrays(motion.pose(mi.Float64([-1.0, 0.0, 5.0]), True), np.ones((3, 3)), np.ones((3, 3)), True)
    np.testing.assert_allclose(xw, np.tile(apply(m, np.ones(3)), (3, 1)), atol=1e-12)
    np.testing.assert_array_equal(vel, 0.0)
    assert not Keyframed([0.0, 1.0], [m, trs([1, 2, 3.1], rodrigues([0, 1, 0], 0.4), [2, 2, 2])]).is_static()


@pytest.mark.parametrize(
    "times, matrices, match",
    [
        ([0.0, 0.0], [np.eye(4), np.eye(4)], "strictly increasing"),
        ([1.0, 0.5], [np.eye(4), np.eye(4)], "strictly increasing"),
        ([0.0, float("nan")], [np.eye(4), np.eye(4)], "finite"),
        ([0.0, 1.0], [np.eye(4)], "matrices"),
        ([0.0], [np.diag([1.0, -1.0, 1.0, 1.0])], "reflection"),
        ([0.0], [np.array([[1, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])], "shear"),
        ([0.0], [np.eye(3)], "4x4"),
    ],
)
def test_keyframed_rejects_bad_keys(times, matrices, match):
    with pytest.raises(ValueError, match=match) as info:
        Keyframed(times, matrices)
    assert "\n" not in str(info.value)


def test_swept_bounds_contain_the_box_at_every_time(three_keys, keyframed):
    lo, hi = np.array([-1.0, -1, -1]), np.array([1.0, 1, 1])
    bmin, bmax = keyframed.swept_bounds(lo, hi, 0.0, 2.5e-3)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    for t in np.linspace(0, 2.5e-3, 401):
        pts = apply(three_keys.matrix(t), corners)
        assert np.all(pts >= bmin - 1e-9) and np.all(pts <= bmax + 1e-9), f"t={t}"


# ----------------------------------------------------------------------------------------
# Parametric

PARAMETRIC_CASES = [
    dict(v=[3.0, -1.0, 2.0], w=[0.0, 0.0, 0.0], pivot=[0, 0, 0], base=np.eye(4)),
    dict(v=[0.0, 0.0, 0.0], w=[0.0, 200.0, 0.0], pivot=[0.5, 0, -1], base=np.eye(4)),
    dict(v=[1.0, 2.0, -3.0], w=[100.0, -50.0, 300.0], pivot=[0.2, 1.0, -0.5], base=trs([1, 2, 3], rodrigues([1, 2, 3], 0.7), [0.5, 2, 1])),
]


@pytest.mark.parametrize("case", PARAMETRIC_CASES)
def test_parametric_matrix_matches_the_reference(case):
    motion = Parametric(case["v"], case["w"], case["pivot"], base=case["base"])
    for t in [-2e-3, 0.0, 1e-3, 7.5e-3]:
        ref = parametric_reference(case["v"], case["w"], case["pivot"], case["base"], t)
        np.testing.assert_allclose(motion.matrix(t), ref, atol=1e-12, err_msg=f"t={t}")
    times = np.array([7.5e-3, -2e-3, 0.0, 1e-3])
    for t, m in zip(times, motion.matrices(times)):
        np.testing.assert_allclose(m, parametric_reference(case["v"], case["w"], case["pivot"], case["base"], t), atol=1e-12, err_msg=f"t={t}")


@pytest.mark.parametrize("case", PARAMETRIC_CASES)
@pytest.mark.parametrize("precise, tol", [(True, 1e-10), (False, 3e-6)])
def test_parametric_pose_and_velocity(case, precise, tol):
    motion = Parametric(case["v"], case["w"], case["pivot"], base=case["base"])
    times = np.array([-1e-3, 0.0, 0.4e-3, 1.5e-3, 4e-3])
    rng = np.random.default_rng(2)
    x_local = rng.uniform(-1, 1, (len(times), 3))
    p_world = rng.uniform(-2, 2, (len(times), 3))
    xw, xl, vel = pose_arrays(motion.pose(mi.Float64(times), precise), x_local, p_world, precise)

    def ref(t):
        return parametric_reference(case["v"], case["w"], case["pivot"], case["base"], t)

    for i, t in enumerate(times):
        np.testing.assert_allclose(xw[i], apply(ref(t), x_local[i]), rtol=tol, atol=tol, err_msg=f"t={t}")
        np.testing.assert_allclose(xl[i], apply(np.linalg.inv(ref(t)), p_world[i]), rtol=tol, atol=10 * tol, err_msg=f"t={t}")
        # Rigid motion: v(p) = v_lin + ω × (p − pivot(t)), pivot(t) = pivot + v_lin t.
        expected = np.asarray(case["v"]) + np.cross(case["w"], p_world[i] - (np.asarray(case["pivot"]) + np.asarray(case["v"]) * t))
        np.testing.assert_allclose(vel[i], expected, rtol=max(tol, 1e-6), atol=1e-3 if not precise else 1e-9, err_msg=f"t={t}")
        np.testing.assert_allclose(vel[i], fd_velocity(ref, t, p_world[i], 1e-7), rtol=1e-5, atol=1e-3)


def test_parametric_rejects_bad_vectors():
    with pytest.raises(ValueError, match="linear_velocity"):
        Parametric([1.0, 2.0])
    with pytest.raises(ValueError, match="angular_velocity"):
        Parametric([0, 0, 0], [0, float("inf"), 0])
    assert Parametric().is_static()
    assert not Parametric([0, 0, 1e-3]).is_static()


def test_swept_bounds_reach_the_extremes_at_keys_between_samples():
    """A box that goes out and comes back turns at a key time that no uniform sample
    hits: the bounds must still reach it there."""
    turn = 0.37  # not a multiple of 1/64
    at_x = [trs([x, 0, 0], np.eye(3), [1, 1, 1]) for x in (0.0, 1.0, 0.0)]
    out_and_back = Keyframed([0.0, turn, 1.0], at_x)
    bmin, bmax = out_and_back.swept_bounds([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], 0.0, 1.0, samples=65)
    assert bmax[0] >= 1.5 and bmin[0] <= -0.5
    assert bmax[0] < 1.5 + 1e-4 and np.all(np.abs(bmax[1:] - 0.5) < 1e-4), "and stay tight"


@pytest.mark.parametrize("t0, t1", [(0.2e-3, 0.9e-3), (0.9e-3, 2.1e-3), (-0.5e-3, 0.1e-3)])
def test_swept_bounds_over_part_of_the_key_range(three_keys, keyframed, t0, t1):
    """Bounds over a window (crossing a key or not) contain the box at every time in it,
    and are smaller than over the whole key range."""
    lo, hi = np.array([-1.0, -1, -1]), np.array([1.0, 1, 1])
    bmin, bmax = keyframed.swept_bounds(lo, hi, t0, t1)
    full_min, full_max = keyframed.swept_bounds(lo, hi, 0.0, 2.5e-3)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    for t in np.linspace(t0, t1, 401):
        pts = apply(three_keys.matrix(t), corners)
        assert np.all(pts >= bmin) and np.all(pts <= bmax), f"t={t}"
    assert np.prod(bmax - bmin) < 0.9 * np.prod(full_max - full_min)
