"""A dynamic scene: static geometry plus rigid bodies, with ray queries at per-lane times.

Stock Mitsuba 3.9 has no motion blur (DESIGN §3.1), so a :class:`DynamicScene` holds

* ``static``: one ``mi.Scene`` with the sensor, every emitter and the static shapes;
* ``bodies``: one small ``mi.Scene`` per rigid body, its shapes in the body's local frame,
  and the body's :class:`~dopplertof.motion.Motion`. Shapes that share a motion are
  grouped into one body.

A ray with its own time is intersected with the static scene and, mapped into a body's
frame by ``M_b(t)⁻¹``, with the scenes of the bodies whose swept bounding boxes (over the
exposure window) it enters; the closest hit wins and is mapped back to the world. ``wi``,
``t`` and ``uv`` are invariant under rigid motion, so BSDFs work unchanged.

Two traversals of the bodies give the same hits (DESIGN §5.3):

==============  ==========================================================================
``per-body``    every body in a Python loop: K masked sub-scene queries and K poses per
                ray, cheapest for a few bodies
``tree``        a bounding-volume tree over the swept boxes, walked per lane in a Dr.Jit
                loop (stackless: depth-first order with skip links); a lane queries, through
                one ``dr.switch``, only the bodies whose boxes it enters before its closest
                hit so far, and evaluates only those bodies' poses: O(log K) per ray
==============  ==========================================================================

``DynamicScene.traversal`` picks one (``"auto"``: ``tree`` above
:data:`PER_BODY_MAX_BODIES` bodies).

Emitters must be static (they live in ``static``); a moving shape carrying an area
emitter is rejected when the scene is built.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .motion import Motion

# Above this many bodies ``traversal="auto"`` walks the tree of swept boxes; at or below,
# the per-body loop is as fast or faster (benchmarks/README.md, "Many moving bodies").
PER_BODY_MAX_BODIES = 4

TRAVERSALS = ("auto", "per-body", "tree")


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
    swept_box: tuple = None  # the same AABB as (min xyz, max xyz) numpy float64 arrays
    swept_times: tuple = None  # the times (t0, t1) s it covers, clamped into the key range


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


class LanePoses:
    """Poses of every body at per-lane times, for the tree traversal: nothing is evaluated
    here; :meth:`DynamicScene.select_pose` evaluates, per lane, the one body it asks for.

    ========  ==============  ===================================================
    time_s    mi.Float64      per-lane times (s)
    precise   bool            Float64 components (``mi.Vector3d``), else Float32
    ========  ==============  ===================================================
    """

    __slots__ = ("time_s", "precise")  # a plain object, so Dr.Jit never takes it for loop state

    def __init__(self, time_s, precise: bool):
        self.time_s, self.precise = time_s, precise


@dataclass
class BoxTree:
    """Bounding-volume tree over the bodies' swept boxes, in depth-first order, as flat
    Dr.Jit arrays (rebuilt as data when the window changes: no recompile).

    =========  ===========  ==============================================================
    lo, hi     mi.Float     world-space box of node ``i`` at ``[3i, 3i + 3)`` (m)
    body       mi.UInt32    ``b + 1`` at the leaf holding ``bodies[b]``, 0 at inner nodes
    skip       mi.UInt32    the node after node ``i``'s subtree (``size`` after the last)
    size       int          number of nodes, ``2K − 1``
    =========  ===========  ==============================================================

    A walk visits node ``i + 1`` (its first child) where the ray enters node ``i``'s box,
    else ``skip[i]``, so it needs no stack.
    """

    lo: object
    hi: object
    body: object
    skip: object
    size: int

    @classmethod
    def build(cls, box_min, box_max):
        """Tree over boxes ``box_min``, ``box_max`` ((K, 3) arrays, m): median split of the
        box centres along their widest axis, one box per leaf."""
        import mitsuba as mi

        centres = 0.5 * (box_min + box_max)
        lo, hi, body, skip = [], [], [], []

        def add(members):
            node = len(body)
            lo.append(box_min[members].min(axis=0))
            hi.append(box_max[members].max(axis=0))
            body.append(members[0] + 1 if len(members) == 1 else 0)
            skip.append(None)
            if len(members) > 1:
                spread = centres[members]
                axis = int(np.argmax(spread.max(axis=0) - spread.min(axis=0)))
                ordered = members[np.argsort(spread[:, axis], kind="stable")]
                half = len(ordered) // 2
                add(ordered[:half])
                add(ordered[half:])
            skip[node] = len(body)

        add(np.arange(len(box_min)))
        flat = lambda rows: mi.Float(np.asarray(rows, dtype=np.float32).ravel())  # noqa: E731
        return cls(lo=flat(lo), hi=flat(hi), body=mi.UInt32(np.asarray(body, np.uint32)), skip=mi.UInt32(np.asarray(skip, np.uint32)), size=len(body))


@dataclass
class DynamicScene:
    """Static scene + moving bodies. Build with :func:`dopplertof.load_scene`.

    ============  ========  =============================================================
    static        mi.Scene  sensor, emitters and static shapes
    bodies        list      :class:`Body` per rigid motion
    traversal     str       how a ray finds the bodies it hits (module docstring):
                            ``"auto"`` (default), ``"per-body"`` or ``"tree"``
    ============  ========  =============================================================
    """

    static: object  # mi.Scene
    bodies: list = field(default_factory=list)
    integrator_params: dict = field(default_factory=dict)
    spp_hint: int | None = None
    source: str = "<dict>"
    traversal: str = "auto"

    def __post_init__(self):
        if self.traversal not in TRAVERSALS:
            raise ValueError(f"traversal must be one of {TRAVERSALS}, got {self.traversal!r}")
        self._tree = None
        self._targets = {}  # dr.switch targets per query, traced once per body list
        self._fit_bounds(None, None)

    # ------------------------------------------------------------------------------------
    def _fit_bounds(self, t0: float | None, t1: float | None):
        """Swept bounds of every body over the times [t0, t1] s (without a window, over
        each body's key range, [0, 1] s for an unbounded motion), and the tree over them."""
        import drjit as dr
        import mitsuba as mi

        for body in self.bodies:
            lo, hi = body.motion.time_range()
            a = t0 if t0 is not None else (lo if np.isfinite(lo) else 0.0)
            b = t1 if t1 is not None else (hi if np.isfinite(hi) else 1.0)
            # Outside [lo, hi] the pose is held: over the window the body takes the poses of
            # the window clamped into that range (a single end pose where they do not overlap).
            times = tuple(float(x) for x in np.clip([a, b], lo, hi))
            if times == body.swept_times:
                continue  # every render sets its window: ~20 ms a body of host-side sweeps saved
            smin, smax = body.motion.swept_bounds(*body.bounds_local, *times)
            body.swept_times = times
            body.swept_box = (smin, smax)
            body.swept_min = mi.Point3f(*[float(v) for v in smin])
            body.swept_max = mi.Point3f(*[float(v) for v in smax])
            dr.make_opaque(body.swept_min, body.swept_max)
        if self.bodies:
            self._tree = BoxTree.build(np.array([b.swept_box[0] for b in self.bodies]), np.array([b.swept_box[1] for b in self.bodies]))

    def set_time_window(self, t0: float, t1: float):
        """Fit every body's swept bounds to the times [t0, t1] s (the exposure): rays
        whose times lie outside the window may then miss bodies that are there."""
        if not (np.isfinite(t0) and np.isfinite(t1) and t0 <= t1):
            raise ValueError(f"time window must be finite with t0 <= t1, got [{t0!r}, {t1!r}] s")
        self._fit_bounds(t0, t1)

    def uses_tree(self) -> bool:
        """Whether ray queries walk the tree of swept boxes (see ``traversal``)."""
        if self.traversal not in TRAVERSALS:
            raise ValueError(f"traversal must be one of {TRAVERSALS}, got {self.traversal!r}")
        if not self.bodies or self.traversal == "per-body":
            return False
        return self.traversal == "tree" or len(self.bodies) > PER_BODY_MAX_BODIES

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
        """Pose of every body at per-lane times ``time_s`` (mi.Float64, s): a list with the
        per-body traversal, a :class:`LanePoses` (evaluated on demand) with the tree."""
        import mitsuba as mi

        if self.uses_tree():
            return LanePoses(mi.Float64(time_s), precise)
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

    @staticmethod
    def _to_local(ray, pose, maxt):
        """``ray`` in the frame of a body at ``pose``, up to ``maxt``."""
        import mitsuba as mi

        return mi.Ray3f(pose.point_to_local(ray.o), pose.vector_to_local(ray.d), maxt, ray.time, ray.wavelengths)

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
            if isinstance(poses, LanePoses):
                pi, body_index = self._tree_closest(ray, poses.time_s, pi, active)
                pose = self.select_pose(poses, body_index)
                ray_hit = dr.select(body_index > 0, self._to_local(ray, pose, ray.maxt), ray_hit)
            else:
                for b, (body, pose) in enumerate(zip(self.bodies, poses)):
                    ray_local = self._to_local(ray, pose, ray.maxt)
                    box = self._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, dr.minimum(ray.maxt, pi.t))
                    pib = body.scene.ray_intersect_preliminary(ray_local, coherent=False, active=active & box)
                    closer = active & box & pib.is_valid() & (pib.t < pi.t)
                    pi = dr.select(closer, pib, pi)
                    ray_hit = dr.select(closer, ray_local, ray_hit)
                    body_index = dr.select(closer, mi.UInt32(b + 1), body_index)
                pose = self.select_pose(poses, body_index)
        si = pi.compute_surface_interaction(ray_hit, mi.RayFlags.All, active)
        p_local, n_local = mi.Point3f(si.p), mi.Normal3f(si.n)
        is_mesh = active & si.is_valid() & si.shape.is_mesh()
        mesh = mi.MeshPtr(si.shape)
        first_vertex = mesh.vertex_position(mesh.face_indices(si.prim_index, is_mesh).x, is_mesh)
        plane_local = dr.select(is_mesh, mi.Point3f(first_vertex), p_local)
        if self.bodies:
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
            if isinstance(poses, LanePoses):
                return self._tree_blocked(ray, poses.time_s, blocked, active)
            for body, pose in zip(self.bodies, poses):
                box = self._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, ray.maxt)
                blocked |= body.scene.ray_test(self._to_local(ray, pose, ray.maxt), active & box & ~blocked)
        return blocked

    # ------------------------------------------------------------------------------------
    # Tree traversal

    def _switch_targets(self, query: str):
        """One function per body for ``dr.switch`` (traced once per body list):

        * ``"closest"``: (ray, time_s, maxt, active) -> that body's preliminary intersection;
        * ``"blocked"``: (ray, time_s, active) -> whether that body blocks the ray;
        * ``"pose"``, ``"pose64"``: (time_s) -> its Float32 / Float64 pose, with the
          identity first for static geometry (index 0).
        """
        key = (query, tuple(id(b) for b in self.bodies))
        if key in self._targets:
            return self._targets[key]

        def closest(body):
            return lambda ray, time_s, maxt, active: body.scene.ray_intersect_preliminary(
                self._to_local(ray, body.motion.pose(time_s), maxt), coherent=False, active=active
            )

        def blocked(body):
            return lambda ray, time_s, active: body.scene.ray_test(self._to_local(ray, body.motion.pose(time_s), ray.maxt), active)

        def pose(body, precise):
            return lambda time_s: body.motion.pose(time_s, precise)

        if query == "closest":
            targets = [closest(b) for b in self.bodies]
        elif query == "blocked":
            targets = [blocked(b) for b in self.bodies]
        else:
            precise = query == "pose64"
            targets = [lambda time_s: _identity_pose(precise)] + [pose(b, precise) for b in self.bodies]
        self._targets = {k: v for k, v in self._targets.items() if k[1] == key[1]}  # drop those of an old body list
        self._targets[key] = targets
        return targets

    def _tree_closest(self, ray, time_s, pi, active):
        """Walk the tree: the closest of ``pi`` (the static scene's preliminary intersection)
        and the bodies' hits; returns it and the body index (0: static)."""
        import drjit as dr
        import mitsuba as mi

        tree, targets = self._tree, self._switch_targets("closest")

        def step(node, pi, body_index):
            t_best_m = dr.minimum(ray.maxt, pi.t)
            enters = self._box_hit(ray.o, ray.d, dr.gather(mi.Point3f, tree.lo, node), dr.gather(mi.Point3f, tree.hi, node), t_best_m)
            leaf_body = dr.gather(mi.UInt32, tree.body, node)
            query = enters & (leaf_body > 0)
            pib = dr.switch(dr.select(query, leaf_body - 1, 0), targets, ray, time_s, t_best_m, query)
            closer = query & pib.is_valid() & (pib.t < t_best_m)
            pi = dr.select(closer, pib, pi)
            body_index = dr.select(closer, leaf_body, body_index)
            node = dr.select(enters, node + 1, dr.gather(mi.UInt32, tree.skip, node))
            return node, pi, body_index

        node = dr.select(active, mi.UInt32(0), tree.size)
        _, pi, body_index = dr.while_loop(
            (node, pi, mi.UInt32(0)), lambda node, pi, body_index: node < tree.size, step, labels=("node", "pi", "body_index"), label="dopplertof bodies: closest"
        )  # fmt: skip
        return pi, body_index

    def _tree_blocked(self, ray, time_s, blocked, active):
        """Walk the tree: ``blocked`` (by the static scene) or blocked by a body."""
        import drjit as dr
        import mitsuba as mi

        tree, targets = self._tree, self._switch_targets("blocked")

        def step(node, blocked):
            enters = self._box_hit(ray.o, ray.d, dr.gather(mi.Point3f, tree.lo, node), dr.gather(mi.Point3f, tree.hi, node), ray.maxt)
            leaf_body = dr.gather(mi.UInt32, tree.body, node)
            query = enters & (leaf_body > 0)
            blocked |= dr.switch(dr.select(query, leaf_body - 1, 0), targets, ray, time_s, query)
            node = dr.select(enters, node + 1, dr.gather(mi.UInt32, tree.skip, node))
            return node, blocked

        node = dr.select(active & ~blocked, mi.UInt32(0), tree.size)
        _, blocked = dr.while_loop(
            (node, blocked), lambda node, blocked: (node < tree.size) & ~blocked, step, labels=("node", "blocked"), label="dopplertof bodies: blocked"
        )  # fmt: skip
        return blocked

    # ------------------------------------------------------------------------------------
    def select_pose(self, poses, body_index):
        """Per-lane pose of the body ``body_index`` (identity for 0 = static)."""
        import drjit as dr
        import mitsuba as mi

        from .motion import Pose

        if isinstance(poses, LanePoses):
            targets = self._switch_targets("pose64" if poses.precise else "pose")
            return dr.switch(mi.UInt32(body_index), targets, poses.time_s)
        out = _identity_pose(bool(poses) and type(poses[0].scale.x) is mi.Float64)
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


def _identity_pose(precise: bool):
    """The pose of static geometry (Float64 components with ``precise``)."""
    import mitsuba as mi

    from .motion import Pose

    F, V = (mi.Float64, mi.Vector3d) if precise else (mi.Float, mi.Vector3f)
    return Pose(q=(F(1), F(0), F(0), F(0)), scale=V(1), translation=V(0), omega=V(0), translation_rate=V(0), scale_rate=V(0))
