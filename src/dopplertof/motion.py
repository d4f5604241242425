"""Rigid motion of bodies during the exposure, evaluated per lane (per ray time).

A motion maps a point ``x_local`` of a body to the world at time ``t`` (seconds)::

    p_world = b(t) + R(t) · (s(t) ∘ x_local)

with ``R`` a rotation (unit quaternion ``q``), ``s`` a per-axis scale and ``b`` a
translation. Both motion models produce a :class:`Pose` that also carries the time
derivatives ``ω`` (angular velocity, rad/s, world frame), ``ḃ`` (m/s) and ``ṡ`` (1/s), so
the velocity of any world point on the body is available in closed form
(:meth:`Pose.velocity`).

=====================  =========================================================
model                  meaning
=====================  =========================================================
:class:`Keyframed`     any number of keys ``(time_s, 4x4 matrix)``; translation
                       and scale interpolated linearly, rotation by slerp (constant
                       angular velocity between keys); clamped outside the key
                       range (zero velocity there; at the last key, the last
                       segment's)
:class:`Parametric`    ``M(t) = Translate(pivot + v t) · Rotate(ω t) ·
                       Translate(−pivot) · M0``: linear velocity ``v`` (m/s) and
                       angular velocity ``ω`` (rad/s, axis·rate) about ``pivot``
                       (m), applied to a base transform ``M0``
=====================  =========================================================

Motion parameters live in Dr.Jit arrays made opaque, so changing them does not
recompile the rendering kernel; only the number of keys is baked in.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .jitdata import jit_array
from .modulation import SPEED_OF_LIGHT_M_S

# Positions (translations, pivots) beyond this are refused: scenes are metres to kilometres
# across, and a body 1e30 m away is a typo that makes it vanish (Float32 hit points there
# are ~1e23 m apart).
MAX_COORDINATE_M = 1e6
# A body faster than this is almost surely a unit mistake (mm/s given as m/s, say): it
# warns. The speed of light is refused: no such motion is physical.
SUSPICIOUS_SPEED_M_S = 1e-3 * SPEED_OF_LIGHT_M_S


def check_speed(speed_m_s: float, what: str, where: str) -> None:
    """ValueError for a speed at or above the speed of light, a warning above
    :data:`SUSPICIOUS_SPEED_M_S`; ``what`` names the velocity (``linear_velocity``,
    ``the keys at t=0 and 1e-9 s``), ``where`` the motion."""
    if speed_m_s >= SPEED_OF_LIGHT_M_S:
        raise ValueError(f"{where}: {what} is {speed_m_s:g} m/s, at or above the speed of light ({SPEED_OF_LIGHT_M_S:g} m/s)")
    if speed_m_s > SUSPICIOUS_SPEED_M_S:
        warnings.warn(f"{where}: {what} is {speed_m_s:g} m/s, above {SUSPICIOUS_SPEED_M_S:g} m/s (1e-3 c); is the unit m/s?", stacklevel=3)

# ----------------------------------------------------------------------------------------
# Host-side (numpy) decomposition of 4x4 matrices


def _quat_from_matrix(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a 3x3 rotation matrix."""
    m = r
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 0.5 / np.sqrt(trace + 1.0)
        q = [0.25 / s, (m[2, 1] - m[1, 2]) * s, (m[0, 2] - m[2, 0]) * s, (m[1, 0] - m[0, 1]) * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (w, x, y, z) along the last axis (broadcast)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def _quat_to_axis_angle(q: np.ndarray) -> tuple[np.ndarray, float]:
    """Axis (unit) and angle (rad, in [0, π]) of a unit quaternion."""
    q = q if q[0] >= 0 else -q
    sin_half = np.linalg.norm(q[1:])
    angle = 2.0 * np.arctan2(sin_half, q[0])
    axis = q[1:] / sin_half if sin_half > 1e-300 else np.array([0.0, 0.0, 1.0])
    return axis, float(angle)


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) as (w, x, y, z)."""
    w, x, y, z = np.moveaxis(np.asarray(q), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def decompose(matrix, where: str = "transform") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split an affine 4x4 matrix into (translation, quaternion (w,x,y,z), scale).

    The matrix must be ``Translate · Rotate · Scale`` with a per-axis scale (no shear,
    no reflection) and a translation within :data:`MAX_COORDINATE_M` on every axis.
    Raises ValueError naming ``where`` otherwise.
    """
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4):
        raise ValueError(f"{where}: expected a 4x4 matrix, got shape {m.shape}")
    if not np.isfinite(m).all():
        raise ValueError(f"{where}: transform has non-finite entries (NaN or inf): {m.tolist()}")
    if np.abs(m[:3, 3]).max() > MAX_COORDINATE_M:
        raise ValueError(f"{where}: translation {m[:3, 3].tolist()} m is beyond the {MAX_COORDINATE_M:g} m any coordinate may reach")
    if not np.allclose(m[3], [0, 0, 0, 1], atol=1e-9):
        raise ValueError(f"{where}: projective matrices cannot be rigid motion keys (last row {m[3]})")
    linear = m[:3, :3]
    scale = np.linalg.norm(linear, axis=0)
    if np.any(scale <= 0):
        raise ValueError(f"{where}: degenerate (zero-scale) transform")
    rotation = linear / scale
    if np.linalg.det(rotation) < 0:
        raise ValueError(f"{where}: reflections cannot be interpolated as rigid motion")
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-5):
        raise ValueError(
            f"{where}: transform has shear; motion keys must be Translate·Rotate·Scale "
            "with a per-axis scale"
        )
    return m[:3, 3].copy(), _quat_from_matrix(rotation), scale


def compose(translation, quaternion, scale) -> np.ndarray:
    """Inverse of :func:`decompose`: the 4x4 matrix ``T · R · S`` (or a stack of them,
    (..., 4, 4), from stacked translations (..., 3), quaternions (..., 4), scales (..., 3))."""
    rotation = _quat_to_matrix(np.asarray(quaternion, dtype=np.float64))
    m = np.zeros((*rotation.shape[:-2], 4, 4))
    m[..., :3, :3] = rotation * np.asarray(scale)[..., None, :]
    m[..., :3, 3] = translation
    m[..., 3, 3] = 1.0
    return m


# ----------------------------------------------------------------------------------------
# Per-lane pose (Dr.Jit)


def _cross(a, b):
    import drjit as dr

    return dr.cross(a, b)


def _rotate(q, v):
    """Rotate vector ``v`` by unit quaternion ``q = (w, x, y, z)`` (tuple of scalars or arrays)."""
    import drjit as dr

    w, qv = q[0], type(v)(q[1], q[2], q[3])
    t = 2.0 * dr.cross(qv, v)
    return v + w * t + dr.cross(qv, t)


def _conj(q):
    return (q[0], -q[1], -q[2], -q[3])


@dataclass
class Pose:
    """Per-lane rigid pose and its time derivatives (see module docstring).

    ``q`` is a tuple (w, x, y, z) of arrays; ``scale``, ``translation``, ``omega``,
    ``translation_rate`` and ``scale_rate`` are 3-vectors of the same float type
    (``mi.Vector3f`` or ``mi.Vector3d``).
    """

    q: tuple
    scale: object
    translation: object
    omega: object
    translation_rate: object
    scale_rate: object

    def point_to_world(self, x_local):
        return self.translation + _rotate(self.q, self.scale * x_local)

    def point_to_local(self, p_world):
        return _rotate(_conj(self.q), p_world - self.translation) / self.scale

    def vector_to_world(self, v_local):
        return _rotate(self.q, self.scale * v_local)

    def vector_to_local(self, v_world):
        return _rotate(_conj(self.q), v_world) / self.scale

    def normal_to_world(self, n_local):
        import drjit as dr

        return dr.normalize(_rotate(self.q, n_local / self.scale))

    def velocity(self, p_world):
        """Velocity (m/s) of the body point currently at ``p_world``."""
        r = p_world - self.translation
        stretch = _rotate(self.q, (self.scale_rate / self.scale) * _rotate(_conj(self.q), r))
        return self.translation_rate + _cross(self.omega, r) + stretch


def box_corners(bbox_min, bbox_max) -> np.ndarray:
    """The 8 corners of an axis-aligned box as homogeneous points, shape (8, 4).

    Parameters
    ----------
    bbox_min, bbox_max : (3,) array_like
        The box's opposite corners.

    Returns
    -------
    ndarray of float64
    """
    lo, hi = np.asarray(bbox_min, dtype=np.float64), np.asarray(bbox_max, dtype=np.float64)
    return np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


class Motion:
    """Base class: a rigid motion evaluated per lane. Subclasses implement :meth:`pose`."""

    def pose(self, time_s, precise: bool = False) -> Pose:  # pragma: no cover - interface
        """Pose at per-lane times ``time_s`` (``mi.Float64``, seconds).

        ``precise=True`` returns Float64 components (``mi.Vector3d``), else Float32.
        """
        raise NotImplementedError

    def matrix(self, time_s: float) -> np.ndarray:
        """The 4x4 world transform at one time (host-side, numpy float64)."""
        return self.matrices(np.array([time_s], dtype=np.float64))[0]

    def matrices(self, times_s) -> np.ndarray:
        """The world transforms (len(times_s), 4, 4) at each of ``times_s`` (host-side,
        numpy float64)."""
        raise NotImplementedError

    def time_range(self) -> tuple[float, float]:
        """Times (s) outside which the pose is constant (±inf for unbounded motion)."""
        raise NotImplementedError

    checked_speed_m_s = 0.0  # the speed (m/s) the motion checked itself (check_speed): its translation's

    def is_static(self) -> bool:
        return False

    def is_rigid(self) -> bool:
        """Whether the motion keeps distances (no scale other than 1): cameras and point
        or spot lights need it (their path lengths and intensities fall off with distance)."""
        return True

    def is_conformal(self) -> bool:
        """Whether the motion keeps angles (a scale equal on every axis): area emitters on a
        moving body need it, since solid-angle densities in its frame are then those in
        the world."""
        return True

    def breakpoints(self, t0: float, t1: float) -> np.ndarray:
        """Times (s) strictly inside (t0, t1) where the motion's velocity may jump."""
        return np.empty(0)

    def max_point_speed(self, bbox_min, bbox_max, steps_per_segment: int = 64) -> float:
        """The largest speed (m/s) of a corner of a local box, over the keys' range: finite
        differences at ``steps_per_segment`` steps between breakpoints (a rotation's arc to
        within 0.01 %). Rotation counts: a body spun about a far pivot moves fast.

        Parameters
        ----------
        bbox_min, bbox_max : (3,) array_like
            The body's local bounding box (m).
        steps_per_segment : int
            Steps between two breakpoints (keys).

        Returns
        -------
        float
        """
        t0, t1 = self.time_range()
        edges = np.union1d([t0, t1], self.breakpoints(t0, t1))
        if len(edges) < 2 or not t1 > t0:
            return 0.0
        times = np.unique(np.concatenate([np.linspace(a, b, steps_per_segment + 1) for a, b in zip(edges, edges[1:])]))
        at = (self.matrices(times) @ box_corners(bbox_min, bbox_max).T)[:, :3, :]  # (times, 3, 8)
        return float((np.linalg.norm(np.diff(at, axis=0), axis=1) / np.diff(times)[:, None]).max())

    def swept_bounds(self, bbox_min, bbox_max, t0: float, t1: float, samples: int = 65):
        """World-space AABB covering a local box at every time in [t0, t1] s.

        The box's corners are taken at ``samples`` times and at the breakpoints between
        (where a keyframed path has corners, and its extremes). Between two of those times
        a corner's path is smooth; its largest gap from the chord of the half interval,
        measured at every midpoint, pads the box: about four times the gap left after
        adding those midpoints (exactly so for the arc of a rotation).
        """
        corners = box_corners(bbox_min, bbox_max)
        times = np.union1d(np.linspace(t0, t1, samples), self.breakpoints(t0, t1))
        mids = 0.5 * (times[1:] + times[:-1])
        at_times = (self.matrices(times) @ corners.T).transpose(0, 2, 1)[..., :3]  # (times, 8, 3)
        at_mids = (self.matrices(mids) @ corners.T).transpose(0, 2, 1)[..., :3]
        chord_gap = np.abs(at_mids - 0.5 * (at_times[1:] + at_times[:-1])).max(initial=0.0)
        pts = np.concatenate([at_times, at_mids]).reshape(-1, 3)
        # Float32 poses and ray tests round within a few ulps of the coordinates.
        pad = chord_gap + 1e-6 * (1 + np.abs(pts).max())
        return pts.min(axis=0) - pad, pts.max(axis=0) + pad


def _opaque_f64(values):
    import drjit as dr
    import mitsuba as mi

    arr = jit_array(mi.Float64, values, np.float64)
    dr.make_opaque(arr)
    return arr


class Keyframed(Motion):
    """Keyframed rigid motion: keys ``(time_s, 4x4 matrix)``, strictly increasing times.

    Parameters
    ----------
    times : sequence of float
        Key times in seconds, strictly increasing.
    matrices : sequence of 4x4 array_like
        World transforms ``T · R · S`` at each key (no shear; translations within
        :data:`MAX_COORDINATE_M` m).

    Translations between keys faster than light are refused, faster than
    :data:`SUSPICIOUS_SPEED_M_S` warn (:func:`check_speed`).
    """

    def __init__(self, times, matrices, where: str = "motion"):
        times = np.asarray(times, dtype=np.float64)
        if times.ndim != 1 or len(times) < 1:
            raise ValueError(f"{where}: at least one keyframe is needed")
        if len(matrices) != len(times):
            raise ValueError(f"{where}: {len(times)} key times but {len(matrices)} matrices")
        if not np.all(np.isfinite(times)):
            raise ValueError(f"{where}: keyframe times must be finite numbers, got {times.tolist()}")
        if np.any(np.diff(times) <= 0):
            raise ValueError(f"{where}: keyframe times must be strictly increasing, got {times.tolist()}")
        parts = [decompose(m, f"{where}, key at t={t:g} s") for t, m in zip(times, matrices)]
        self.times = times
        self.translations = np.array([p[0] for p in parts])
        quats = [parts[0][1]]
        for p in parts[1:]:  # shortest-arc slerp: keep consecutive quaternions in one hemisphere
            quats.append(p[1] if np.dot(p[1], quats[-1]) >= 0 else -p[1])
        self.quaternions = np.array(quats)
        self.scales = np.array([p[2] for p in parts])
        self.checked_speed_m_s = 0.0  # the fastest translation between keys, checked here
        for i in range(len(times) - 1):
            speed = np.linalg.norm(self.translations[i + 1] - self.translations[i]) / (times[i + 1] - times[i])
            check_speed(float(speed), f"the translation between the keys at t={times[i]:g} and {times[i + 1]:g} s", where)
            self.checked_speed_m_s = max(self.checked_speed_m_s, float(speed))
        self._axes, self._angles, self._durations = self._segments()
        self._upload()

    def _segments(self):
        """Per-segment axis, angle and duration (host arrays; one dummy for a single key)."""
        n = len(self.times)
        axes, angles, durations = [], [], []
        for i in range(max(n - 1, 1)):
            j = min(i + 1, n - 1)
            rel = _quat_mul(self.quaternions[j], self.quaternions[i] * np.array([1, -1, -1, -1]))
            axis, angle = _quat_to_axis_angle(rel)
            axes.append(axis)
            angles.append(angle)
            durations.append(self.times[j] - self.times[i] if j != i else 1.0)
        return np.array(axes), np.array(angles), np.array(durations)

    def _upload(self):
        axes, angles, durations = self._axes, self._angles, self._durations
        n = len(self.times)
        nxt = np.minimum(np.arange(n) + 1, n - 1)
        self._key_times = _opaque_f64(self.times)
        self._data = {
            "t": self._key_times,
            **{f"b{k}": _opaque_f64(self.translations[:, k]) for k in range(3)},
            **{f"db{k}": _opaque_f64(self.translations[nxt, k] - self.translations[:, k]) for k in range(3)},
            **{f"s{k}": _opaque_f64(self.scales[:, k]) for k in range(3)},
            **{f"ds{k}": _opaque_f64(self.scales[nxt, k] - self.scales[:, k]) for k in range(3)},
            **{f"q{k}": _opaque_f64(self.quaternions[:, k]) for k in range(4)},
            **{f"axis{k}": _opaque_f64(np.append(axes[:, k], 0.0)) for k in range(3)},
            "angle": _opaque_f64(np.append(angles, 0.0)),
            "duration": _opaque_f64(np.append(durations, 1.0)),
        }

    def time_range(self):
        return float(self.times[0]), float(self.times[-1])

    def breakpoints(self, t0, t1):
        return self.times[(self.times > t0) & (self.times < t1)]

    def is_rigid(self):
        return bool(np.allclose(self.scales, 1.0, rtol=0, atol=1e-6))

    def is_conformal(self):
        return bool(np.allclose(self.scales, self.scales[:, :1], rtol=1e-6, atol=0))

    def is_static(self):
        return len(self.times) == 1 or (
            np.allclose(self.translations, self.translations[0], atol=0)
            and np.allclose(self.quaternions, self.quaternions[0], atol=0)
            and np.allclose(self.scales, self.scales[0], atol=0)
        )

    def matrices(self, times_s) -> np.ndarray:
        times_s = np.asarray(times_s, dtype=np.float64)
        n = len(self.times)
        if n == 1:
            return np.broadcast_to(compose(self.translations[0], self.quaternions[0], self.scales[0]), (len(times_s), 4, 4)).copy()
        # Before the first key and after the last the pose is that key's, exactly.
        i = np.clip(np.searchsorted(self.times, times_s, side="right") - 1, 0, n - 2)
        alpha = np.clip((times_s - self.times[i]) / (self.times[i + 1] - self.times[i]), 0.0, 1.0)
        last = times_s >= self.times[-1]
        i, alpha = np.where(last, n - 1, i), np.where(last, 0.0, alpha)
        nxt = np.minimum(i + 1, n - 1)
        half = 0.5 * alpha * np.append(self._angles, 0.0)[i]
        axes = np.vstack([self._axes, [0.0, 0.0, 1.0]])[i]
        q = _quat_mul(np.column_stack([np.cos(half), np.sin(half)[:, None] * axes]), self.quaternions[i])
        a = alpha[:, None]
        b = (1 - a) * self.translations[i] + a * self.translations[nxt]
        s = (1 - a) * self.scales[i] + a * self.scales[nxt]
        return compose(b, q, s)

    def pose(self, time_s, precise: bool = False) -> Pose:
        import drjit as dr
        import mitsuba as mi

        d = self._data
        n = len(self.times)
        t = mi.Float64(time_s)
        # Segment holding t, clamped to [0, n − 2]: the first key after t, found by a
        # branch-free binary search over the opaque key times (⌈log2 n⌉ gathers per lane;
        # only n is baked into the kernel), minus one.
        if n > 1:
            after = dr.binary_search(1, n - 1, lambda k: dr.gather(mi.Float64, d["t"], k) <= t)
            idx = mi.UInt32(after) - 1
        else:
            idx = mi.UInt32(0)
        t0 = dr.gather(mi.Float64, d["t"], idx)
        duration = dr.gather(mi.Float64, d["duration"], idx)
        # Moving from the first key to the last, both included: at the last key the velocity
        # is the last segment's (what an exposure ending there saw), zero only beyond it.
        inside = (t >= dr.gather(mi.Float64, d["t"], 0)) & (t <= dr.gather(mi.Float64, d["t"], n - 1))
        alpha64 = dr.clip((t - t0) / duration, 0.0, 1.0)
        if n == 1:
            alpha64 = mi.Float64(0.0)
        F = mi.Float64 if precise else mi.Float
        V = mi.Vector3d if precise else mi.Vector3f
        alpha = F(alpha64)
        rate = F(dr.select(inside, 1.0 / duration, 0.0))

        return segment_pose(lambda name: F(dr.gather(mi.Float64, d[name], idx)), alpha, rate, V)


def segment_pose(g, alpha, rate, V) -> Pose:
    """The pose at fraction ``alpha`` of a keyframe segment, and its rates (``rate`` =
    1/duration inside the keys, 0 outside); ``g(name)`` gathers the segment's key data
    (base b, deltas db and ds, rotation axis and angle, start quaternion q)."""
    import drjit as dr

    db = V(g("db0"), g("db1"), g("db2"))
    ds = V(g("ds0"), g("ds1"), g("ds2"))
    translation = V(g("b0"), g("b1"), g("b2")) + alpha * db
    scale = V(g("s0"), g("s1"), g("s2")) + alpha * ds
    axis = V(g("axis0"), g("axis1"), g("axis2"))
    angle = g("angle")
    sh, ch = dr.sincos(0.5 * alpha * angle)
    q = _quat_mul_lanes((ch, sh * axis.x, sh * axis.y, sh * axis.z), (g("q0"), g("q1"), g("q2"), g("q3")))
    return Pose(q=q, scale=scale, translation=translation, omega=axis * (angle * rate), translation_rate=db * rate, scale_rate=ds * rate)


def _quat_mul_lanes(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


class Parametric(Motion):
    """Constant linear and angular velocity about a pivot (see module docstring).

    Parameters
    ----------
    linear_velocity : (3,) array_like, m/s
    angular_velocity : (3,) array_like, rad/s (axis times rate, right-handed)
    pivot : (3,) array_like, m. Default: the origin. Within :data:`MAX_COORDINATE_M`.
    base : 4x4 array_like. Pose at t = 0 (``M0``). Default: identity.

    A linear speed at or above the speed of light is refused, above
    :data:`SUSPICIOUS_SPEED_M_S` it warns (:func:`check_speed`); so is a body's fastest point
    (:meth:`max_point_speed`), the rotation included, when the loader knows its box.
    """

    def __init__(self, linear_velocity=(0, 0, 0), angular_velocity=(0, 0, 0), pivot=(0, 0, 0), base=None, where="motion"):
        def vec3(name, value):
            try:
                arr = np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                arr = None
            if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"{where}: {name} must be 3 finite numbers, got {value!r}")
            return arr

        self.linear_velocity = vec3("linear_velocity", linear_velocity)
        self.angular_velocity = vec3("angular_velocity", angular_velocity)
        self.pivot = vec3("pivot", pivot)
        if np.abs(self.pivot).max() > MAX_COORDINATE_M:
            raise ValueError(f"{where}: pivot {self.pivot.tolist()} m is beyond the {MAX_COORDINATE_M:g} m any coordinate may reach")
        self.checked_speed_m_s = float(np.linalg.norm(self.linear_velocity))  # checked here
        check_speed(self.checked_speed_m_s, "linear_velocity", where)
        self.base = np.eye(4) if base is None else np.asarray(base, dtype=np.float64)
        self.b0, self.q0, self.s0 = decompose(self.base, f"{where}: base transform")
        rate = np.linalg.norm(self.angular_velocity)
        self.axis = self.angular_velocity / rate if rate > 0 else np.array([0.0, 0.0, 1.0])
        self.rate = rate
        self._data = {
            k: _opaque_f64(v)
            for k, v in {
                "v": self.linear_velocity,
                "axis": self.axis,
                "rate": [self.rate],
                "pivot": self.pivot,
                "b0": self.b0,
                "q0": self.q0,
                "s0": self.s0,
            }.items()
        }

    def time_range(self):
        return -np.inf, np.inf

    def max_point_speed(self, bbox_min, bbox_max, steps_per_segment: int = 64) -> float:
        """|v| + |ω| × the farthest corner of the local box from the pivot (at t = 0, a
        distance the rotation keeps): a bound on the speed of every point (m/s)."""
        reach = np.linalg.norm((self.base @ box_corners(bbox_min, bbox_max).T)[:3].T - self.pivot, axis=1).max()
        return float(np.linalg.norm(self.linear_velocity) + self.rate * reach)

    def is_static(self):
        return not np.any(self.linear_velocity) and not np.any(self.angular_velocity)

    def is_rigid(self):
        return bool(np.allclose(self.s0, 1.0, rtol=0, atol=1e-6))

    def is_conformal(self):
        return bool(np.allclose(self.s0, self.s0[0], rtol=1e-6, atol=0))

    def matrices(self, times_s) -> np.ndarray:
        times_s = np.asarray(times_s, dtype=np.float64)
        half = 0.5 * self.rate * times_s
        q_rot = np.column_stack([np.cos(half), np.sin(half)[:, None] * self.axis])
        rot = _quat_to_matrix(q_rot)
        b = self.pivot + self.linear_velocity * times_s[:, None] + rot @ (self.b0 - self.pivot)
        return compose(b, _quat_mul(q_rot, self.q0), np.broadcast_to(self.s0, b.shape))

    def pose(self, time_s, precise: bool = False) -> Pose:
        import drjit as dr
        import mitsuba as mi

        F = mi.Float64 if precise else mi.Float
        V = mi.Vector3d if precise else mi.Vector3f
        d = self._data

        return parametric_pose(lambda name, k: dr.gather(mi.Float64, d[name], k), time_s, F, V)


def parametric_pose(at, time_s, F, V) -> Pose:
    """The pose of a parametric motion at ``time_s``; ``at(name, k)`` gathers component
    ``k`` of its parameters (Float64 rate, axis, pivot, v, b0, s0, q0)."""
    import drjit as dr
    import mitsuba as mi

    def vec(name):
        return V(F(at(name, 0)), F(at(name, 1)), F(at(name, 2)))

    t64 = mi.Float64(time_s)
    rate = F(at("rate", 0))
    axis = vec("axis")
    pivot = vec("pivot")
    v = vec("v")
    sh, ch = dr.sincos(F(0.5 * t64 * at("rate", 0)))
    q_rot = (ch, sh * axis.x, sh * axis.y, sh * axis.z)
    q0 = tuple(F(at("q0", k)) for k in range(4))
    t = F(t64)
    translation = pivot + v * t + _rotate(q_rot, vec("b0") - pivot)
    omega = axis * rate
    return Pose(
        q=_quat_mul_lanes(q_rot, q0),
        scale=vec("s0"),
        translation=translation,
        omega=omega,
        translation_rate=v + dr.cross(omega, translation - pivot - v * t),
        scale_rate=V(0, 0, 0),
    )
