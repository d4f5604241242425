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

Three traversals of the bodies give the same hits (DESIGN §5.3; the atlas to float32
rounding):

==============  ==========================================================================
``per-body``    every body in a Python loop, its work behind a ``dr.if_stmt`` on its
                swept-box test: a SIMD packet none of whose lanes enter the box skips the
                body's pose, the change of frame and the sub-scene query, and only lanes
                inside the body's own (local) bounds are traced; K box tests per ray,
                cheapest up to a few dozen bodies
``tree``        a bounding-volume tree over the swept boxes, walked per lane in a Dr.Jit
                loop (stackless: depth-first order with skip links); a lane queries, through
                one ``dr.switch``, only the bodies whose boxes it enters before its closest
                hit so far, and evaluates only those bodies' poses: O(log K) per ray
``atlas``       the same tree, each leaf query one trace against one scene of every body
                shifted into a cell of its own (:mod:`dopplertof.atlas`): no ``dr.switch``,
                one trace site whatever the number of bodies. The traversal for CUDA, where
                a trace inside ``dr.switch`` is not sanctioned and the per-body loop's
                kernel compiles for minutes; 0-15 % slower than ``tree`` on the CPU
==============  ==========================================================================

``DynamicScene.traversal`` picks one (``"auto"``: on the CPU ``tree`` above
:data:`PER_BODY_MAX_BODIES` bodies, else ``per-body``; on CUDA ``atlas`` where it can hold
every body's shapes, else ``per-body``). Each takes the bodies' poses from
:meth:`DynamicScene.poses`: all evaluated up front up to :data:`LISTED_POSES_MAX_BODIES`
bodies, else per lane for the one body asked for. ``"slices"`` is the fourth way, chosen by name only: every
lane of a pass sees the bodies at one instant per correlated member, placed in one Mitsuba
scene per member with the static shapes (:mod:`dopplertof.slices`; DESIGN §6). It samples
times differently (shared by all pixels of a pass), so its images are another estimate of
the same expectation, not the same bits.

What a moving body costs on the CPU is its Embree calls: each SIMD packet with a lane near
a body pays a call of about a static query's price, even where it traces one lane
(``benchmarks/body_cost.py``; benchmarks/README.md, "Many moving bodies").

The camera may move too (``camera_motion``: the sensor's frame at time t is
``camera_motion.pose(t)`` applied to the sensor's own ``to_world``), and so may emitters:
area emitters on moving bodies, and point or spot lights with a motion of their own
(``lights``, among them a light attached to a moving camera); emitter sampling covers
them all (:mod:`dopplertof.lights`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .jitdata import jit_array
from .motion import Motion

# Above this many bodies ``traversal="auto"`` walks the tree of swept boxes. The per-body
# loop is unrolled, so its kernel grows with every body and a new scene's first render
# compiles it: at 16 / 32 / 64 cubes 3.3 / 7.9 / 21 s against the tree's 1.6 / 1.6 / 1.9 s,
# while renders of a compiled kernel cost the same (1.00×, 0.79×, 0.55× with the tree); at
# 8 the tree's first render is 0.78-0.91× and later ones 1.06-1.13× (benchmarks/README.md,
# "The first render of a new scene"; 256², 32 spp, D-ToF with 4 cameras).
PER_BODY_MAX_BODIES = 8
# At or below this many bodies :meth:`DynamicScene.poses` evaluates every body's pose up
# front (a list, selected per lane); above, one pose per lane and use, from the pose table.
# The list is code per body too: at 16 bodies it cost the tree's first render 1.0 s more.
LISTED_POSES_MAX_BODIES = 8

TRAVERSALS = ("auto", "per-body", "tree", "atlas", "slices")
# Emitter parameters that hold emitted power: their textures' values, an envmap's pixels and scale.
EMITTED_PARAMETERS = ("radiance", "intensity", "irradiance", "data", "scale")


def check_emitters(mi_scene, where: str) -> None:
    """SceneError naming the emitter and its parameter where an emitted radiance,
    intensity or irradiance (or its scale) is not finite or is negative: a NaN light makes
    every pixel NaN, a negative one is no light."""
    import mitsuba as mi

    for index, emitter in enumerate(mi_scene.emitters()):
        params = mi.traverse(emitter)
        for key in params.keys():
            if key.split(".")[0] not in EMITTED_PARAMETERS:
                continue
            try:
                values = np.asarray(params[key], dtype=np.float64).ravel()
            except (TypeError, ValueError):  # not numbers: a texture's to_uv, say
                continue
            bad = ~(np.isfinite(values) & (values >= 0))
            if not bad.any():
                continue
            shape = emitter.get_shape() if hasattr(emitter, "get_shape") else None
            name = repr(emitter.id()) if emitter.id() else f"#{index}"
            on = f" on shape {shape.id()!r}" if shape is not None and shape.id() else ""
            shown = f"= {values.tolist()}" if values.size <= 6 else f"has {bad.sum()} bad values of {values.size}, the first {float(values[bad][0])!r}"
            raise SceneError(
                f"{where}: emitter {name} ({emitter.class_name()}{on}): {key!r} {shown}; "
                "emitted radiance, intensity and irradiance must be finite and >= 0"
            )


class SceneError(ValueError):
    """A scene description that cannot be loaded; the message says what and where.

    A ``ValueError``, raised by :func:`dopplertof.load_scene`.

    Examples
    --------
    >>> import dopplertof as dt
    >>> try:
    ...     dt.load_scene({"type": "scene", "ball": {"type": "sphere"}})
    ... except dt.SceneError as error:
    ...     print(error)
    <dict>: the scene has no sensor
    """


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
    local_min: object = None  # bounds_local padded a little, mi.Point3f (opaque)
    local_max: object = None
    load_copy: object = None  # () -> mi.Scene: the body's shapes loaded afresh, in its frame (traversal "slices")


@dataclass
class Hit:
    """World-space result of :meth:`DynamicScene.intersect`.

    ``si`` is a ``mi.SurfaceInteraction3f`` in world space; ``body`` is 0 for static
    geometry and ``b + 1`` for ``bodies[b]``; ``p_local`` is the hit in the frame of the
    body (world frame for static geometry); ``n_local`` the geometric normal there;
    ``plane_local`` a point of the hit primitive's plane in that frame that is the same
    for every hit of the primitive (a triangle's first vertex; ``p_local`` for analytic
    shapes), so distances recomputed against it cancel exactly between correlated paths;
    ``pose`` the body's float32 :class:`~dopplertof.motion.Pose` at the lane's time (the
    identity for static geometry and misses), evaluated once per hit; ``plane64`` with
    ``traversal="slices"`` the hit primitive's plane in the world at the lane's instant,
    Float64 ``(normal, offset)`` (:meth:`dopplertof.slices.SliceScenes.local_frame`), which
    the distance is then recomputed against instead (else None).
    """

    si: object
    body: object
    p_local: object
    n_local: object
    plane_local: object
    pose: object
    plane64: object = None


class LanePoses:
    """Poses of every body at per-lane times, above :data:`LISTED_POSES_MAX_BODIES` bodies:
    nothing is evaluated here; :meth:`DynamicScene.select_pose` evaluates, per lane, the one
    body it asks for.

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
    """Bounding-volume tree over the bodies' swept boxes as flat Dr.Jit arrays, rebuilt as
    data when the window changes (no recompile).

    Its nodes are stored in depth-first order once per ray octant (the signs of the ray's
    direction), children nearest-first for rays of that octant: a walk visits node
    ``i + 1`` (the near child) where the ray enters node ``i``'s box, else ``skip[i]``, so
    it needs no stack and meets the boxes roughly in the order the ray does.

    =========  ===========  ==============================================================
    lo, hi     mi.Float     box of node ``i`` of octant ``o`` at ``3 (o·size + i)`` (m)
    body       mi.UInt32    ``b + 1`` at the leaf holding ``bodies[b]``, 0 at inner nodes
    skip       mi.UInt32    the node after node ``i``'s subtree (``size`` after the last)
    size       int          nodes per octant, ``2K − 1``
    =========  ===========  ==============================================================
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

        def add(members, octant):
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
                near, far = ordered[:half], ordered[half:]
                if octant >> axis & 1:  # the ray runs towards −axis: the high half is nearer
                    near, far = far, near
                add(near, octant)
                add(far, octant)
            skip[node] = len(body)

        size = 2 * len(box_min) - 1
        for octant in range(8):
            first = len(body)
            add(np.arange(len(box_min)), octant)
            skip[first:] = [k - first for k in skip[first:]]
        return cls(lo=jit_array(mi.Float, lo, np.float32), hi=jit_array(mi.Float, hi, np.float32), body=jit_array(mi.UInt32, body, np.uint32), skip=jit_array(mi.UInt32, skip, np.uint32), size=size)

    def walk_to_leaf(self, ray, octant, node, t_max_m, box_hit):
        """From ``node`` on (in the order of ``octant``), the first leaf whose box ``ray``
        enters before ``t_max_m``: (node, body index b + 1); node = ``size`` where none."""
        import drjit as dr
        import mitsuba as mi

        base = octant * self.size

        def step(node, leaf_body):
            at = base + node
            enters = box_hit(ray.o, ray.d, dr.gather(mi.Point3f, self.lo, at), dr.gather(mi.Point3f, self.hi, at), t_max_m)
            leaf_body = dr.select(enters, dr.gather(mi.UInt32, self.body, at), 0)
            node = dr.select(leaf_body > 0, node, dr.select(enters, node + 1, dr.gather(mi.UInt32, self.skip, at)))
            return node, leaf_body

        return dr.while_loop(
            (node, mi.UInt32(0)), lambda node, leaf_body: (node < self.size) & (leaf_body == 0), step, labels=("node", "leaf_body"), label="dopplertof bodies: walk"
        )  # fmt: skip


class PoseTable:
    """Pose of body ``b`` (per lane) at per-lane times, gathered from one table per motion
    model, so a kernel holds one pose evaluation whatever the number of bodies.

    The arithmetic is that of :meth:`Keyframed.pose <dopplertof.motion.Keyframed.pose>` and
    :meth:`Parametric.pose <dopplertof.motion.Parametric.pose>`, with the motion's arrays
    concatenated over the bodies (the results are bit-identical: tests/test_many_bodies.py);
    other motion models go through ``dr.switch`` to their own ``pose``.

    ==========  =====================================================================
    motions     list of :class:`~dopplertof.motion.Motion`, one per body
    ==========  =====================================================================
    """

    KEYFRAMED_FIELDS = ("t", "b0", "b1", "b2", "db0", "db1", "db2", "s0", "s1", "s2", "ds0", "ds1", "ds2", "q0", "q1", "q2", "q3", "axis0", "axis1", "axis2", "angle", "duration")
    PARAMETRIC_FIELDS = ("v", "axis", "rate", "pivot", "b0", "q0", "s0")

    @staticmethod
    def packed_model(motion):
        """The motion model whose arrays the table concatenates for ``motion``
        (:class:`~dopplertof.motion.Keyframed` or :class:`~dopplertof.motion.Parametric`,
        exactly), or None for one it reaches through ``dr.switch`` to the motion's own
        ``pose``."""
        from .motion import Keyframed, Parametric

        return type(motion) if type(motion) in (Keyframed, Parametric) else None

    def __init__(self, motions):
        import mitsuba as mi

        from .motion import Keyframed, Parametric

        self.motions = list(motions)
        models = [self.packed_model(m) for m in self.motions]
        rows = {model: [b for b, m in enumerate(models) if m is model] for model in (Keyframed, Parametric, None)}
        self.keyframed, self.parametric, self.other = rows[Keyframed], rows[Parametric], rows[None]
        model_code = np.array([0 if m is Keyframed else 1 if m is Parametric else 2 for m in models], np.uint32)
        row = np.zeros(len(models), np.uint32)
        for members in rows.values():
            row[members] = np.arange(len(members))
        self.model = _opaque(jit_array(mi.UInt32, model_code))
        self.row = _opaque(jit_array(mi.UInt32, row))

        def cat(bodies, name, length):
            return _opaque(jit_array(mi.Float64, np.concatenate([np.asarray(self.motions[b]._data[name])[: length(b)] for b in bodies]), np.float64))

        if self.keyframed:
            counts = np.array([len(self.motions[b].times) for b in self.keyframed], np.uint32)
            self.key_offset = _opaque(jit_array(mi.UInt32, np.concatenate([[0], np.cumsum(counts)[:-1]]), np.uint32))
            self.key_count = _opaque(jit_array(mi.UInt32, counts))
            # Search steps of Keyframed.pose for the longest key list; more steps leave a
            # converged search where it is.
            self.search_steps = int(np.floor(np.log2(counts.max() - 2))) + 1 if counts.max() > 2 else 0
            self.keys = {f: cat(self.keyframed, f, lambda b: len(self.motions[b].times)) for f in self.KEYFRAMED_FIELDS}
        if self.parametric:
            self.params = {f: cat(self.parametric, f, lambda b, f=f: len(self.motions[b]._data[f])) for f in self.PARAMETRIC_FIELDS}

    def pose(self, body, time_s, precise: bool, active=True):
        """Pose of ``bodies[body]`` (mi.UInt32 per lane) at ``time_s`` (mi.Float64, s); the
        identity where not ``active``."""
        import drjit as dr
        import mitsuba as mi

        from .motion import Pose

        active = mi.Bool(active)
        model = dr.gather(mi.UInt32, self.model, body, active)
        row = dr.gather(mi.UInt32, self.row, body, active)
        out = _identity_pose(precise)
        parts = []
        if self.keyframed:
            parts.append((active & (model == 0), self._keyframed(row, time_s, precise, active & (model == 0))))
        if self.parametric:
            parts.append((active & (model == 1), self._parametric(row, time_s, precise, active & (model == 1))))
        if self.other:
            targets = [lambda t, m=self.motions[b]: m.pose(t, precise) for b in self.other]
            parts.append((active & (model == 2), dr.switch(row, targets, mi.Float64(time_s), active & (model == 2))))
        for mask, pose in parts:
            out = Pose(*(tuple(dr.select(mask, a, b) for a, b in zip(x, y)) if isinstance(x, tuple) else dr.select(mask, x, y) for x, y in zip(_fields(pose), _fields(out))))
        return out

    def _keyframed(self, row, time_s, precise, active):
        """Keyframed.pose over the concatenated keys (see there)."""
        import drjit as dr
        import mitsuba as mi

        from .motion import segment_pose

        d = self.keys
        first = dr.gather(mi.UInt32, self.key_offset, row, active)
        n = dr.gather(mi.UInt32, self.key_count, row, active)
        t = mi.Float64(time_s)
        searching = active & (n > 1)
        start, end = first + 1, first + dr.maximum(n, 2) - 1
        for _ in range(self.search_steps):  # dr.binary_search with per-lane bounds
            middle = (start + end) >> 1
            below = dr.gather(mi.Float64, d["t"], middle, searching) <= t
            start = dr.select(below, dr.minimum(middle + 1, end), start)
            end = dr.select(below, end, middle)
        idx = dr.select(n > 1, start - 1, first)
        t0 = dr.gather(mi.Float64, d["t"], idx, active)
        duration = dr.gather(mi.Float64, d["duration"], idx, active)
        inside = (t >= dr.gather(mi.Float64, d["t"], first, active)) & (t <= dr.gather(mi.Float64, d["t"], first + n - 1, active))
        alpha64 = dr.clip((t - t0) / duration, 0.0, 1.0)
        alpha64 = dr.select(n > 1, alpha64, mi.Float64(0.0))
        F = mi.Float64 if precise else mi.Float
        V = mi.Vector3d if precise else mi.Vector3f
        alpha = F(alpha64)
        rate = F(dr.select(inside, 1.0 / duration, 0.0))

        return segment_pose(lambda name: F(dr.gather(mi.Float64, d[name], idx, active)), alpha, rate, V)

    def _parametric(self, row, time_s, precise, active):
        """Parametric.pose over the concatenated parameters (see there)."""
        import drjit as dr
        import mitsuba as mi

        from .motion import parametric_pose

        F = mi.Float64 if precise else mi.Float
        V = mi.Vector3d if precise else mi.Vector3f
        d = self.params
        widths = {"rate": 1, "q0": 4}
        return parametric_pose(lambda name, k: dr.gather(mi.Float64, d[name], row * widths.get(name, 3) + k, active), time_s, F, V)


def _fields(pose):
    return (pose.q, pose.scale, pose.translation, pose.omega, pose.translation_rate, pose.scale_rate)


def _opaque(array):
    import drjit as dr

    dr.make_opaque(array)
    return array


@dataclass
class DynamicScene:
    """Static scene + moving bodies. Build with :func:`dopplertof.load_scene`.

    =================  ========  ============================================================
    static             mi.Scene  sensor, static emitters and static shapes
    bodies             list      :class:`Body` per rigid motion
    integrator_params  dict      the file's ``<integrator>`` parameters (default none)
    spp_hint           int       the file's sampler ``sample_count`` (None: none given)
    seed_hint          int       the file's sampler ``seed`` (None: none given)
    source             str       where it was loaded from (a path; ``"<dict>"`` by default)
    traversal          str       how a ray finds the bodies it hits (module docstring):
                                 ``"auto"`` (default), ``"per-body"``, ``"tree"``,
                                 ``"atlas"`` or ``"slices"`` (one scene per instant,
                                 :mod:`dopplertof.slices`; CPU; chosen by name
                                 only)
    camera_motion      Motion    the sensor's motion (None: static), applied on top of its
                                 ``to_world``
    lights             list      :class:`~dopplertof.lights.MovingLight` per moving point or
                                 spot emitter
    recipe             tuple     how to build it again elsewhere
                                 (:func:`dopplertof.scenes.from_recipe`); None: from a dict
    content_digest     str       SHA-256 of what it was built from: a file's XML with its
                                 includes and ``$name`` values, a built-in's name and
                                 arguments; None from a dict (:meth:`identity`)
    pipeline_host      object    the never-traced scene whose OptiX pipeline and SBT the
                                 others share (:mod:`dopplertof.loader`); None without bodies
    =================  ========  ============================================================

    Raises
    ------
    ValueError
        An unknown ``traversal``.

    Examples
    --------
    >>> import dopplertof as dt
    >>> scene = dt.scenes.cornell_box(resolution=16)   # two boxes moving during the exposure
    >>> len(scene.bodies), scene.camera_motion is None
    (2, True)
    """

    static: object  # mi.Scene
    bodies: list = field(default_factory=list)
    integrator_params: dict = field(default_factory=dict)
    spp_hint: int | None = None
    seed_hint: int | None = None
    source: str = "<dict>"
    traversal: str = "auto"
    camera_motion: Motion | None = None
    lights: list = field(default_factory=list)
    recipe: tuple | None = None  # how to build it again elsewhere (scenes.from_recipe); None: from a dict
    content_digest: str | None = None  # SHA-256 of the file's expanded XML or the built-in's arguments (identity)
    # The never-traced scene whose OptiX pipeline and SBT ``static`` and every body's scene
    # share (loader.pipeline_host); it must outlive them. None without bodies.
    pipeline_host: object = None

    def __post_init__(self):
        if self.traversal not in TRAVERSALS:
            raise ValueError(f"traversal must be one of {TRAVERSALS}, got {self.traversal!r}")
        self._tree = None
        self._tree_key = None  # the swept boxes the tree was built over (bytes)
        self._poses = None  # PoseTable of the bodies' motions, built on first use
        self._targets = {}  # dr.switch targets per query, traced once per body list
        self._atlas = None  # (body scenes' ids, BodyAtlas) of the body list it was built for
        self._emitters = None
        self._slices = None  # SliceScenes of traversal "slices", built on first use
        groups = [(self.source, self.static)] + [(f"{self.source}: moving body {b.name!r}", b.scene) for b in self.bodies]
        for where, mi_scene in groups + [(light.name, light.scene) for light in self.lights]:
            check_emitters(mi_scene, where)
        self._fit_bounds(None, None)

    # ------------------------------------------------------------------------------------
    def _fit_bounds(self, t0: float | None, t1: float | None):
        """Swept bounds of every body over the times [t0, t1] s (without a window, over
        each body's key range, [0, 1] s for an unbounded motion), and the tree over them."""
        import drjit as dr
        import mitsuba as mi

        for body in self.bodies:
            if body.local_min is None:
                # The body's own bounds, padded so that the slab test stays conservative
                # for hits on the bounds themselves (a cube's faces).
                lo, hi = body.bounds_local
                pad = 1e-4 * float(np.max(hi - lo)) + 1e-6
                body.local_min = mi.Point3f(*[float(v) for v in lo - pad])
                body.local_max = mi.Point3f(*[float(v) for v in hi + pad])
                dr.make_opaque(body.local_min, body.local_max)
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
        # Every render sets its window: the tree is built again only where a box changed
        # (1024 bodies take ~0.3 s).
        key = b"".join(np.concatenate(b.swept_box).tobytes() for b in self.bodies)
        if self.bodies and key != self._tree_key:
            self._tree = BoxTree.build(np.array([b.swept_box[0] for b in self.bodies]), np.array([b.swept_box[1] for b in self.bodies]))
            self._tree_key = key

    def identity(self) -> dict:
        """What tells this scene from another, for checkpoints, Ray workers and clips: its
        :attr:`content_digest`, else (a dict) its shape, emitter and body counts and bounds.

        Returns
        -------
        dict (JSON-able)
        """
        if self.content_digest is not None:
            named = {"builtin": self.recipe[1]} if self.recipe is not None and self.recipe[0] == "builtin" else {}
            return {**named, "content_sha256": self.content_digest}
        parts = [self.static, *(b.scene for b in self.bodies)]
        return {
            "source": self.source, "shapes": [len(m.shapes()) for m in parts], "emitters": len(self.static.emitters()) + len(self.lights),
            "bounds": [[round(float(v), 6) for v in (*box.min, *box.max)] for box in (m.bbox() for m in parts)],
        }  # fmt: skip

    def set_time_window(self, t0: float, t1: float):
        """Fit every body's swept bounds to the times [t0, t1] s (the exposure): rays
        whose times lie outside the window may then miss bodies that are there.

        Parameters
        ----------
        t0, t1 : float, s
            The window.
        """
        if not (np.isfinite(t0) and np.isfinite(t1) and t0 <= t1):
            raise ValueError(f"time window must be finite with t0 <= t1, got [{t0!r}, {t1!r}] s")
        self._fit_bounds(t0, t1)
        if self.traversal_in_use() == "atlas":
            # Built before a render's kernel is traced: shapes made while it is traced change
            # the layout of its calls over shapes, and the next render compiles it again.
            self._body_atlas()

    def traversal_in_use(self) -> str:
        """The traversal ray queries take: ``"per-body"``, ``"tree"`` or ``"atlas"`` (see
        ``traversal``; ``"per-body"`` without bodies). ``"tree"`` is refused on CUDA: it
        traces inside ``dr.switch``, which OptiX compiles to direct callables, from which
        tracing is not sanctioned (gpu-notes §2.2).

        Returns
        -------
        str

        Raises
        ------
        ValueError
            An unknown ``traversal``, ``"tree"`` on CUDA, or ``"atlas"`` for a body whose
            shape the atlas cannot hold.
        """
        import mitsuba as mi

        from .atlas import BodyAtlas

        if self.traversal not in TRAVERSALS:
            raise ValueError(f"traversal must be one of {TRAVERSALS}, got {self.traversal!r}")
        if not self.bodies or self.traversal == "per-body":
            return "per-body"
        cuda = mi.variant().startswith("cuda")
        if self.traversal == "slices":
            if cuda:
                raise ValueError(f"traversal='slices' traces one scene per member in a kernel, which OptiX does not allow yet on {mi.variant()}; use 'atlas' or 'auto'")
            return "slices"
        if self.traversal == "tree" and cuda:
            raise ValueError(f"traversal='tree' traces inside dr.switch (OptiX direct callables) and is not supported on {mi.variant()}; use 'atlas', 'per-body' or 'auto'")
        if self.traversal == "atlas" or (self.traversal == "auto" and cuda):
            reason = BodyAtlas.unsupported(self.bodies)
            if reason is None:
                return "atlas"
            if self.traversal == "atlas":
                raise ValueError(f"traversal='atlas' cannot hold {reason}; use 'per-body' or 'auto'")
            return "per-body"
        return "tree" if self.traversal == "tree" or len(self.bodies) > PER_BODY_MAX_BODIES else "per-body"

    def uses_tree(self) -> bool:
        """Whether ray queries walk the tree of swept boxes (``"tree"`` or ``"atlas"``,
        :meth:`traversal_in_use`).

        Returns
        -------
        bool
        """
        return self.traversal_in_use() in ("tree", "atlas")

    def mitsuba_scenes(self) -> list:
        """Every ``mi.Scene`` whose shapes a ray may hit: the static scene, the bodies' and,
        once built, the member scenes of ``traversal="slices"`` (their copies of the
        bodies' shapes have BSDFs of their own).

        Returns
        -------
        list of mi.Scene
        """
        return [self.static, *(b.scene for b in self.bodies), *(self._slices.scenes if self._slices is not None else [])]

    def _slices_in_use(self):
        """The member scenes where ``traversal="slices"`` is in use and they are built (a
        render builds them: :meth:`slice_scenes`), else None: the ray queries then take the
        per-body loop at the lanes' own times."""
        return self._slices if self.traversal_in_use() == "slices" else None

    def slice_scenes(self, members: int):
        """The member scenes of ``traversal="slices"`` (:class:`dopplertof.slices.SliceScenes`),
        built on first use for ``members`` correlated times per group.

        Parameters
        ----------
        members : int

        Returns
        -------
        SliceScenes
        """
        from .slices import SliceScenes

        if self._slices is None or self._slices.members != members:
            self._slices = SliceScenes(self, members)
        return self._slices

    def _body_atlas(self):
        """The :class:`~dopplertof.atlas.BodyAtlas` of the current body list (built once per
        list, a guest of the pipeline host)."""
        from .atlas import BodyAtlas

        key = tuple(id(b.scene) for b in self.bodies)
        if self._atlas is None or self._atlas[0] != key:
            self._atlas = (key, BodyAtlas.build(self.bodies, self.pipeline_host))
        return self._atlas[1]

    @property
    def sensor(self):
        """The scene's Mitsuba sensor (the first; dopplertof renders one camera).

        Raises
        ------
        SceneError
            If the scene has no sensor.
        """
        sensors = self.static.sensors()
        if not sensors:
            raise SceneError(f"{self.source}: the scene has no sensor")
        return sensors[0]

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the sensor's film in pixels."""
        size = self.sensor.film().crop_size()
        return int(size[0]), int(size[1])

    def light_sources_in_motion(self) -> list[str]:
        """The names of the lights that move on their own (not with the camera) and of the
        moving bodies that emit: with them a measured dL/dt holds more than the motion of the
        camera rays' hits, which the ground-truth velocity is.

        Returns
        -------
        list of str
        """
        return [light.name for light in self.lights if not light.with_camera] + [body.name for body in self.bodies if len(body.scene.emitters())]

    def motions(self) -> list:
        """Every motion of the scene: its bodies', its camera's and its moving lights'.

        Returns
        -------
        list of Motion
        """
        camera = [] if self.camera_motion is None else [self.camera_motion]
        return [b.motion for b in self.bodies] + camera + [light.motion for light in self.lights]

    @property
    def emitters(self):
        """The scene's :class:`~dopplertof.lights.Emitters` (static and moving)."""
        from .lights import Emitters

        if self._emitters is None:
            self._emitters = Emitters(self)
        return self._emitters

    # ------------------------------------------------------------------------------------
    # Per-lane queries

    def camera_pose(self, time_s, precise: bool = False):
        """The camera's motion at per-lane times ``time_s`` (a :class:`~dopplertof.motion.Pose`
        mapping the sensor's rest frame to the world), None for a static camera.

        Parameters
        ----------
        time_s : mi.Float64
            Per-lane times, s.
        precise : bool, default False
            Evaluate in Float64 (for optical lengths).

        Returns
        -------
        Pose or None
        """
        return None if self.camera_motion is None else self.camera_motion.pose(time_s, precise)

    def poses(self, time_s, precise: bool = False):
        """Pose of every body at per-lane times ``time_s`` (mi.Float64, s): a list up to
        :data:`LISTED_POSES_MAX_BODIES` bodies (each lane selects among them), above that a
        :class:`LanePoses`, evaluated per lane for the body asked for (a lane's K-way select
        grows with K, a table lookup does not).

        Parameters
        ----------
        time_s : mi.Float64
            Per-lane times, s.
        precise : bool, default False
            Evaluate in Float64 (for optical lengths).

        Returns
        -------
        list of Pose or LanePoses
        """
        import mitsuba as mi

        if len(self.bodies) > LISTED_POSES_MAX_BODIES or (self.bodies and self.traversal == "slices"):
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
        """Closest hit of world-space ``ray`` at per-lane times; returns a :class:`Hit`.

        Parameters
        ----------
        ray : mi.Ray3f
            World space.
        time_s : mi.Float64
            Per-lane times, s.
        active : bool or mi.Bool, default True
        poses : list of Pose, LanePoses or None, default None
            :meth:`poses` at ``time_s``, where the caller has them.
        coherent : bool, default False
            A hint for Embree (camera rays).

        Returns
        -------
        Hit
        """
        import drjit as dr
        import mitsuba as mi

        active = mi.Bool(active)
        slices = self._slices_in_use()
        if slices is not None:  # one scene per member, each at its instant: hits in the world
            pi, body_index, pose = slices.intersect(ray, mi.Float64(time_s), active, coherent, self.select_pose, LanePoses(mi.Float64(time_s), False))
            si = pi.compute_surface_interaction(ray, mi.RayFlags.All, active)
            p_local, n_local, plane_local, plane64 = slices.local_frame(si, body_index, pose, mi.Float64(time_s), active)
            return Hit(si=si, body=body_index, p_local=p_local, n_local=n_local, plane_local=plane_local, pose=pose, plane64=plane64)
        pi = self.static.ray_intersect_preliminary(ray, coherent=coherent, active=active)
        ray_hit = mi.Ray3f(ray)
        body_index = mi.UInt32(0)
        pose = _identity_pose(False)
        if self.bodies:
            if self.uses_tree():
                pi, body_index, pose = self._tree_closest(ray, mi.Float64(time_s), pi, active)
                ray_hit = dr.select(body_index > 0, self._to_local(ray, pose, ray.maxt), ray_hit)
            else:
                poses = poses if poses is not None else self.poses(time_s)
                pi, ray_hit, body_index, pose = self._per_body_closest(ray, poses, pi, active)
        si = pi.compute_surface_interaction(ray_hit, mi.RayFlags.All, active)
        p_local, n_local = mi.Point3f(si.p), mi.Normal3f(si.n)
        is_mesh = active & si.is_valid() & si.shape.is_mesh()
        mesh = mi.MeshPtr(si.shape)
        first_vertex = mesh.vertex_position(mesh.face_indices(si.prim_index, is_mesh).x, is_mesh)
        plane_local = dr.select(is_mesh, mi.Point3f(first_vertex), p_local)
        if self.bodies:

            def to_world(si, ray_d):
                si.p = pose.point_to_world(si.p)
                si.n = pose.normal_to_world(si.n)
                # A body's scale may differ per axis: tangents then stay tangents but not at
                # right angles, so the world frame is rebuilt from the normal and one tangent.
                n = pose.normal_to_world(si.sh_frame.n)
                tangent = pose.vector_to_world(si.sh_frame.s)
                tangent = dr.normalize(tangent - n * dr.dot(n, tangent))
                si.sh_frame = mi.Frame3f(tangent, dr.cross(n, tangent), n)
                # Mitsuba set wi from the ray in the body's frame, whose direction a scale
                # stretches (not a unit vector, bent where the scale differs per axis): BSDFs
                # other than diffuse read it (a glass body gave NaN).
                si.wi = si.to_local(-ray_d)
                si.dp_du = pose.vector_to_world(si.dp_du)
                si.dp_dv = pose.vector_to_world(si.dp_dv)
                return si

            # A branch: a SIMD packet whose lanes all hit static geometry (already in the world) skips it.
            si = dr.if_stmt((si, ray.d), active & (body_index > 0), to_world, lambda si, ray_d: si, label="dopplertof: body hit to the world")
        return Hit(si=si, body=body_index, p_local=p_local, n_local=n_local, plane_local=plane_local, pose=pose)

    def occluded(self, ray, time_s, active=True, poses=None):
        """True where world-space ``ray`` (up to ``ray.maxt``) is blocked at its lane's time.

        Parameters
        ----------
        ray : mi.Ray3f
            World space.
        time_s : mi.Float64
            Per-lane times, s.
        active : bool or mi.Bool, default True
        poses : list of Pose, LanePoses or None, default None
            :meth:`poses` at ``time_s``, where the caller has them.

        Returns
        -------
        mi.Bool
        """
        import mitsuba as mi

        active = mi.Bool(active)
        slices = self._slices_in_use()
        if slices is not None:
            return slices.occluded(ray, mi.Float64(time_s), active)
        blocked = self.static.ray_test(ray, active)
        if not self.bodies:
            return blocked
        if self.uses_tree():
            return self._tree_blocked(ray, mi.Float64(time_s), blocked, active)
        return self._per_body_blocked(ray, poses if poses is not None else self.poses(time_s), blocked, active)

    # ------------------------------------------------------------------------------------
    # Per-body traversal

    def _body_pose(self, poses, b):
        """The pose of ``bodies[b]`` from ``poses`` (a list or :class:`LanePoses`)."""
        return poses[b] if isinstance(poses, list) else self.bodies[b].motion.pose(poses.time_s, poses.precise)

    def _per_body_visit(self, ray, poses, active, state, t_max_m, on_body, done, label):
        """Visit each body whose swept box ``ray`` enters before ``t_max_m(state)`` (unless
        ``done(state)``): ``on_body(state, b, ray_local, pose, near)`` returns the new state
        (``ray_local``: the ray in the body's frame at the lane's time, ``near``: the lanes
        whose ray enters the body's padded local bounds, the only ones to trace).

        Each body's work (pose, ray to its frame, sub-scene query) sits in a ``dr.if_stmt``
        on its swept-box test, which the LLVM backend compiles to a branch: a SIMD packet
        none of whose lanes enter the box skips it. ``on_body`` runs in a second branch, only
        for packets with a lane ``near`` the body: a sub-scene call costs about a
        static-scene query whatever the number of lanes it traces (benchmarks/README.md,
        "Many moving bodies")."""
        import drjit as dr

        for b, body in enumerate(self.bodies):
            enters = active & ~done(state) & self._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, t_max_m(state))

            def query(*state, b=b, body=body, enters=enters):
                pose = self._body_pose(poses, b)
                ray_local = self._to_local(ray, pose, ray.maxt)
                near = enters & self._box_hit(ray_local.o, ray_local.d, body.local_min, body.local_max, t_max_m(state))
                trace = lambda *state: on_body(state, b, ray_local, pose, near)  # noqa: E731
                return dr.if_stmt(state, near, trace, lambda *state: state, label=f"dopplertof body {b}: {label}, traced")

            state = dr.if_stmt(state, enters, query, lambda *state: state, label=f"dopplertof body {b}: {label}")
        return state

    def _per_body_closest(self, ray, poses, pi, active):
        """The closest of ``pi`` (the static scene's) and the bodies' hits, the ray it was
        found with (in the body's frame), the body index (0: static) and the body's pose."""
        import drjit as dr
        import mitsuba as mi

        def on_body(state, b, ray_local, pose, near):
            pi, body_index, pose_hit = state
            pib = self.bodies[b].scene.ray_intersect_preliminary(ray_local, coherent=False, active=near)
            closer = near & pib.is_valid() & (pib.t < pi.t)
            return dr.select(closer, pib, pi), dr.select(closer, mi.UInt32(b + 1), body_index), dr.select(closer, pose, pose_hit)

        state = (pi, mi.UInt32(0), _identity_pose(False))
        state = self._per_body_visit(ray, poses, active, state, lambda state: dr.minimum(ray.maxt, state[0].t), on_body, lambda state: mi.Bool(False), "closest")
        pi, body_index, pose = state
        return pi, dr.select(body_index > 0, self._to_local(ray, pose, ray.maxt), mi.Ray3f(ray)), body_index, pose

    def _per_body_blocked(self, ray, poses, blocked, active):
        """``blocked`` (by the static scene) or blocked by a body."""

        def on_body(state, b, ray_local, pose, near):
            return (state[0] | self.bodies[b].scene.ray_test(ray_local, near),)

        return self._per_body_visit(ray, poses, active, (blocked,), lambda state: ray.maxt, on_body, lambda state: state[0], "blocked")[0]

    # ------------------------------------------------------------------------------------
    # Tree traversal

    def _pose_table(self) -> PoseTable:
        motions = [b.motion for b in self.bodies]
        if self._poses is None or self._poses.motions != motions:
            self._poses = PoseTable(motions)
        return self._poses

    def _switch_targets(self, query: str):
        """One function per body for ``dr.switch``, traced once per body list:
        ``"closest"``: (ray_local, active) -> the body's preliminary intersection;
        ``"blocked"``: (ray_local, active) -> whether the body blocks the ray."""
        scenes = [b.scene for b in self.bodies]
        key = (query, tuple(map(id, scenes)))
        if key not in self._targets:
            if query == "closest":
                targets = [lambda ray, active, s=s: s.ray_intersect_preliminary(ray, coherent=False, active=active) for s in scenes]
            else:
                targets = [lambda ray, active, s=s: s.ray_test(ray, active) for s in scenes]
            self._targets = {k: v for k, v in self._targets.items() if k[1] == key[1]}  # those of an old body list go
            self._targets[key] = targets
        return self._targets[key]

    def _walk(self, ray, time_s, active, state, t_max_m, on_leaf, done, label):
        """Visit, in ``ray``'s order, each body whose swept box the ray enters before
        ``t_max_m(state)`` until ``done(state)``: ``on_leaf(state, b, ray_local, pose, query)``
        returns the new state (``b``: 0-based body index, ``ray_local`` the ray in its
        frame at the lane's time up to ``ray.maxt``, as in the per-body loop: a shorter one
        would drop hits tied with the closest so far; ``pose`` the body's pose there;
        ``query`` the lanes that visit a body)."""
        import drjit as dr
        import mitsuba as mi

        tree, poses = self._tree, self._pose_table()
        octant = mi.UInt32(ray.d.x < 0) | (mi.UInt32(ray.d.y < 0) << 1) | (mi.UInt32(ray.d.z < 0) << 2)

        def step(node, state):
            node, leaf_body = tree.walk_to_leaf(ray, octant, node, t_max_m(state), self._box_hit)
            query = leaf_body > 0
            body = dr.select(query, leaf_body - 1, 0)
            pose = poses.pose(body, time_s, False, query)
            state = on_leaf(state, body, self._to_local(ray, pose, ray.maxt), pose, query)
            return dr.select(query, node + 1, node), state

        node = dr.select(active & ~done(state), mi.UInt32(0), tree.size)
        return dr.while_loop((node, state), lambda node, state: (node < tree.size) & ~done(state), step, labels=("node", "state"), label=label)[1]

    def _tree_closest(self, ray, time_s, pi, active):
        """The closest of ``pi`` (the static scene's preliminary intersection) and the
        bodies' hits, the body index (0: static) and the body's pose (the identity for 0),
        carried by the walk so that the hit's pose is not evaluated again."""
        import drjit as dr
        import mitsuba as mi

        if self.traversal_in_use() == "atlas":
            leaf_closest = self._body_atlas().closest
        else:
            targets = self._switch_targets("closest")
            leaf_closest = lambda body, ray_local, query: dr.switch(body, targets, ray_local, query)  # noqa: E731

        def on_leaf(state, body, ray_local, pose, query):
            pi, body_index, pose_hit = state
            pib = leaf_closest(body, ray_local, query)
            # Ties (coplanar faces of overlapping bodies) go to the lower index, as in the
            # per-body loop, so that the tree gives the per-body loop's hits bit for bit
            # (the atlas, finding each body's hit in a shifted cell, breaks them by rounding).
            tie = (pib.t == pi.t) & (body_index > 0) & (body + 1 < body_index)
            closer = query & pib.is_valid() & ((pib.t < dr.minimum(ray.maxt, pi.t)) | tie)
            return dr.select(closer, pib, pi), dr.select(closer, body + 1, body_index), dr.select(closer, pose, pose_hit)

        return self._walk(
            ray, time_s, active, (pi, mi.UInt32(0), _identity_pose(False)), lambda state: dr.minimum(ray.maxt, state[0].t), on_leaf,
            lambda state: mi.Bool(False), "dopplertof bodies: closest",
        )  # fmt: skip

    def _tree_blocked(self, ray, time_s, blocked, active):
        """``blocked`` (by the static scene) or blocked by a body."""
        import drjit as dr

        if self.traversal_in_use() == "atlas":
            leaf_blocked = self._body_atlas().blocked
        else:
            targets = self._switch_targets("blocked")
            leaf_blocked = lambda body, ray_local, query: dr.switch(body, targets, ray_local, query)  # noqa: E731

        def on_leaf(blocked, body, ray_local, pose, query):
            return blocked | leaf_blocked(body, ray_local, query)

        return self._walk(ray, time_s, active, blocked, lambda blocked: ray.maxt, on_leaf, lambda blocked: blocked, "dopplertof bodies: blocked")

    # ------------------------------------------------------------------------------------
    def select_pose(self, poses, body_index):
        """Per-lane pose of the body ``body_index`` (identity for 0 = static).

        Parameters
        ----------
        poses : list of Pose or LanePoses
            :meth:`poses`.
        body_index : mi.UInt32
            Per-lane body (0: static).

        Returns
        -------
        Pose
        """
        import drjit as dr
        import mitsuba as mi

        body_index = mi.UInt32(body_index)
        precise = poses.precise if isinstance(poses, LanePoses) else bool(poses) and type(poses[0].scale.x) is mi.Float64
        identity = _identity_pose(precise)
        if not self.bodies:
            return identity
        # A branch: a SIMD packet whose lanes are all on static geometry skips the poses.
        return dr.if_stmt((body_index,), body_index > 0, lambda b: self._moving_pose(poses, b, identity), lambda b: identity, label="dopplertof: a body's pose")

    def _moving_pose(self, poses, body_index, identity):
        """:meth:`select_pose` where some lane's body moves (``identity`` elsewhere)."""
        import drjit as dr

        from .motion import Pose

        moving = body_index > 0
        slices = self._slices_in_use()
        if isinstance(poses, LanePoses) and slices is not None:
            return dr.select(moving, slices.pose(body_index, poses.time_s, poses.precise), identity)
        if isinstance(poses, LanePoses):
            return self._pose_table().pose(dr.select(moving, body_index - 1, 0), poses.time_s, poses.precise, moving)
        out = identity
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

        Parameters
        ----------
        p_world : mi.Point3f or mi.Point3d
            World-space points at ``time_from_s``.
        body_index : mi.UInt32
            Per-lane body (0: static).
        time_from_s, time_to_s : mi.Float64
            Per-lane times, s.
        poses_from, poses_to : list of Pose, LanePoses or None, default None
            :meth:`poses` at those times, where the caller has them.

        Returns
        -------
        mi.Point3f or mi.Point3d
            The points at ``time_to_s``.
        """
        if not self.bodies:
            return p_world
        poses_from = poses_from if poses_from is not None else self.poses(time_from_s)
        poses_to = poses_to if poses_to is not None else self.poses(time_to_s)
        p_local = self.select_pose(poses_from, body_index).point_to_local(p_world)
        return self.select_pose(poses_to, body_index).point_to_world(p_local)

    def surface_velocity(self, p_world, body_index, time_s, poses=None):
        """World-space velocity (m/s) of the surface point ``p_world`` of ``body_index``.

        Parameters
        ----------
        p_world : mi.Point3f
        body_index : mi.UInt32
            Per-lane body (0: static).
        time_s : mi.Float64
            Per-lane times, s.
        poses : list of Pose, LanePoses or None, default None
            :meth:`poses` at ``time_s``, where the caller has them.

        Returns
        -------
        mi.Vector3f
            m/s.
        """
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
