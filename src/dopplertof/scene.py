"""A dynamic scene: static geometry plus rigid bodies, with ray queries at per-lane times.

Stock Mitsuba 3.9 has no motion blur (DESIGN §3.1), so a :class:`DynamicScene` holds

* ``static``: one ``mi.Scene`` with the sensor, every emitter and the static shapes;
* ``bodies``: one small ``mi.Scene`` per rigid body, its shapes in the body's local frame,
  and the body's :class:`~dopplertof.motion.Motion`. Shapes that share a motion are
  grouped into one body.

A ray with its own time is intersected with the static scene and, mapped into each body's
frame by ``M_b(t)⁻¹``, with each body's scene (skipped where it misses the body's swept
bounding box); the closest hit wins and is mapped back to the world. ``wi``, ``t`` and
``uv`` are invariant under rigid motion, so BSDFs work unchanged.

Emitters must be static (they live in ``static``); a moving shape carrying an area
emitter is rejected when the scene is built.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .motion import Motion


class SceneError(ValueError):
    """A scene description that cannot be loaded; the message says what and where."""


@dataclass
class Body:
    """A rigid body: its shapes (local frame) in ``scene`` and its ``motion``."""

    name: str
    scene: object  # mi.Scene
    motion: Motion
    bounds_local: tuple  # (min xyz, max xyz) numpy arrays
    swept_min: object = None  # mi.Point3f (opaque), world-space AABB over the motion
    swept_max: object = None


@dataclass
class Hit:
    """World-space result of :meth:`DynamicScene.intersect`.

    ``si`` is a ``mi.SurfaceInteraction3f`` in world space; ``body`` is 0 for static
    geometry and ``b + 1`` for ``bodies[b]``; ``p_local`` is the hit in the frame of the
    body (world frame for static geometry); ``n_local`` the geometric normal there;
    ``plane_local`` a point of the hit primitive's plane in that frame that is the same
    for every hit of the primitive (a triangle's first vertex; ``p_local`` for analytic
    shapes), so distances recomputed against it cancel exactly between correlated paths.
    """

    si: object
    body: object
    p_local: object
    n_local: object
    plane_local: object


@dataclass
class DynamicScene:
    """Static scene + moving bodies. Build with :func:`dopplertof.load_scene`."""

    static: object  # mi.Scene
    bodies: list = field(default_factory=list)
    integrator_params: dict = field(default_factory=dict)
    spp_hint: int | None = None
    source: str = "<dict>"

    def __post_init__(self):
        for body in self.bodies:
            self._prepare_body(body)

    # ------------------------------------------------------------------------------------
    def _prepare_body(self, body: Body, t0: float | None = None, t1: float | None = None):
        """Swept bounds of ``body`` over the times [t0, t1] s; without a window, over its
        whole key range ([0, 1] s for an unbounded motion)."""
        import drjit as dr
        import mitsuba as mi

        lo, hi = body.motion.time_range()
        if t0 is None or t1 is None:
            t0 = lo if np.isfinite(lo) else 0.0
            t1 = hi if np.isfinite(hi) else 1.0
        # Outside [lo, hi] the pose is held: over the window the body takes the poses of
        # the window clamped into that range (a single end pose where they do not overlap).
        a, b = np.clip([t0, t1], lo, hi)
        smin, smax = body.motion.swept_bounds(*body.bounds_local, float(a), float(b))
        body.swept_min = mi.Point3f(*[float(v) for v in smin])
        body.swept_max = mi.Point3f(*[float(v) for v in smax])
        dr.make_opaque(body.swept_min, body.swept_max)

    def set_time_window(self, t0: float, t1: float):
        """Fit every body's swept bounds to the times [t0, t1] s (the exposure): rays
        whose times lie outside the window may then miss bodies that are there."""
        if not (np.isfinite(t0) and np.isfinite(t1) and t0 <= t1):
            raise ValueError(f"time window must be finite with t0 <= t1, got [{t0!r}, {t1!r}] s")
        for body in self.bodies:
            self._prepare_body(body, t0, t1)

    @property
    def sensor(self):
        sensors = self.static.sensors()
        if not sensors:
            raise SceneError(f"{self.source}: the scene has no sensor")
        return sensors[0]

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the sensor's film in pixels."""
        size = self.sensor.film().crop_size()
        return int(size[0]), int(size[1])

    # ------------------------------------------------------------------------------------
    # Per-lane queries

    def poses(self, time_s, precise: bool = False):
        """Pose of every body at per-lane times ``time_s`` (mi.Float64, s)."""
        return [body.motion.pose(time_s, precise) for body in self.bodies]

    @staticmethod
    def _box_hit(ray_o, ray_d, bmin, bmax, maxt):
        """Slab test of a world-space ray against an AABB (conservative)."""
        import drjit as dr

        inv = dr.rcp(ray_d)
        t_a = (bmin - ray_o) * inv
        t_b = (bmax - ray_o) * inv
        t_near = dr.max(dr.minimum(t_a, t_b))
        t_far = dr.min(dr.maximum(t_a, t_b))
        # NaNs (0 * inf on a slab boundary) must not reject: treat them as hits.
        return ~((t_near > t_far * 1.0000002) | (t_far < 0) | (t_near > maxt)) | dr.isnan(t_near) | dr.isnan(t_far)

    def intersect(self, ray, time_s, active=True, poses=None, coherent=False):
        """Closest hit of world-space ``ray`` at per-lane times; returns a :class:`Hit`."""
        import drjit as dr
        import mitsuba as mi

        active = mi.Bool(active)
        pi = self.static.ray_intersect_preliminary(ray, coherent=coherent, active=active)
        ray_hit = mi.Ray3f(ray)
        body_index = mi.UInt32(0)
        if self.bodies:
            poses = poses if poses is not None else self.poses(time_s)
            for b, (body, pose) in enumerate(zip(self.bodies, poses)):
                ray_local = mi.Ray3f(pose.point_to_local(ray.o), pose.vector_to_local(ray.d), ray.maxt, ray.time, ray.wavelengths)
                box = self._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, dr.minimum(ray.maxt, pi.t))
                pib = body.scene.ray_intersect_preliminary(ray_local, coherent=False, active=active & box)
                closer = active & box & pib.is_valid() & (pib.t < pi.t)
                pi = dr.select(closer, pib, pi)
                ray_hit = dr.select(closer, ray_local, ray_hit)
                body_index = dr.select(closer, mi.UInt32(b + 1), body_index)
        si = pi.compute_surface_interaction(ray_hit, mi.RayFlags.All, active)
        p_local, n_local = mi.Point3f(si.p), mi.Normal3f(si.n)
        is_mesh = active & si.is_valid() & si.shape.is_mesh()
        mesh = mi.MeshPtr(si.shape)
        first_vertex = mesh.vertex_position(mesh.face_indices(si.prim_index, is_mesh).x, is_mesh)
        plane_local = dr.select(is_mesh, mi.Point3f(first_vertex), p_local)
        if self.bodies:
            pose = self.select_pose(poses, body_index)
            si.p = pose.point_to_world(si.p)
            si.n = pose.normal_to_world(si.n)
            si.sh_frame = mi.Frame3f(
                dr.normalize(pose.vector_to_world(si.sh_frame.s)),
                dr.normalize(pose.vector_to_world(si.sh_frame.t)),
                pose.normal_to_world(si.sh_frame.n),
            )
            si.dp_du = pose.vector_to_world(si.dp_du)
            si.dp_dv = pose.vector_to_world(si.dp_dv)
        return Hit(si=si, body=body_index, p_local=p_local, n_local=n_local, plane_local=plane_local)

    def occluded(self, ray, time_s, active=True, poses=None):
        """True where world-space ``ray`` (up to ``ray.maxt``) is blocked at its lane's time."""
        import mitsuba as mi

        active = mi.Bool(active)
        blocked = self.static.ray_test(ray, active)
        if self.bodies:
            poses = poses if poses is not None else self.poses(time_s)
            for body, pose in zip(self.bodies, poses):
                box = self._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, ray.maxt)
                ray_local = mi.Ray3f(pose.point_to_local(ray.o), pose.vector_to_local(ray.d), ray.maxt, ray.time, ray.wavelengths)
                blocked |= body.scene.ray_test(ray_local, active & box & ~blocked)
        return blocked

    def select_pose(self, poses, body_index):
        """Per-lane pose of the body ``body_index`` (identity for 0 = static)."""
        import drjit as dr
        import mitsuba as mi

        from .motion import Pose

        F = type(poses[0].scale.x) if poses else mi.Float
        V = mi.Vector3d if F is mi.Float64 else mi.Vector3f
        out = Pose(q=(F(1), F(0), F(0), F(0)), scale=V(1), translation=V(0), omega=V(0), translation_rate=V(0), scale_rate=V(0))
        for b, pose in enumerate(poses):
            m = body_index == (b + 1)
            out = Pose(
                q=tuple(dr.select(m, x, y) for x, y in zip(pose.q, out.q)),
                scale=dr.select(m, pose.scale, out.scale),
                translation=dr.select(m, pose.translation, out.translation),
                omega=dr.select(m, pose.omega, out.omega),
                translation_rate=dr.select(m, pose.translation_rate, out.translation_rate),
                scale_rate=dr.select(m, pose.scale_rate, out.scale_rate),
            )
        return out

    def retime(self, p_world, body_index, time_from_s, time_to_s, poses_from=None, poses_to=None):
        """Move surface points of ``body_index`` from ``time_from_s`` to ``time_to_s``.

        The body-local point is kept: ``x' = M(t') M(t)⁻¹ x`` (static points do not move).
        """
        if not self.bodies:
            return p_world
        poses_from = poses_from if poses_from is not None else self.poses(time_from_s)
        poses_to = poses_to if poses_to is not None else self.poses(time_to_s)
        p_local = self.select_pose(poses_from, body_index).point_to_local(p_world)
        return self.select_pose(poses_to, body_index).point_to_world(p_local)

    def surface_velocity(self, p_world, body_index, time_s, poses=None):
        """World-space velocity (m/s) of the surface point ``p_world`` of ``body_index``."""
        import mitsuba as mi

        if not self.bodies:
            return mi.Vector3f(0)
        poses = poses if poses is not None else self.poses(time_s)
        return self.select_pose(poses, body_index).velocity(p_world)
