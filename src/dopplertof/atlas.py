"""The moving bodies in one Mitsuba scene, each in a cell of its own: the tree's leaf
queries without ``dr.switch``, for CUDA.

The swept-box tree (:mod:`dopplertof.scene`) asks, at each leaf, the one body the lane's
ray enters. On the CPU that query is a ``dr.switch`` over the bodies' scenes. On CUDA a
``dr.switch`` becomes OptiX direct callables, inside which tracing is not sanctioned, and
the per-body loop, the only other way, unrolls every body into the kernel: on an H200 a
32-body scene's kernel did not finish compiling in 168 s (docs/performance.md, "On a GPU").

The atlas is one scene holding a copy of every body's shapes in the body's own frame,
body ``b`` shifted by ``D_b`` into a cell of a cubic grid (cells 1.25× the largest body
plus 1 cm: no two bodies' cells overlap). A leaf query moves the ray, already in the body's
frame, by ``D_b``, starts it where it enters the body's cell and ends it where it leaves,
and makes one trace against the atlas: one trace site per query whatever the number of
bodies, no ``dr.switch``, and, loaded as a guest of the scene's pipeline host
(:func:`dopplertof.loader.pipeline_host`), the same OptiX pipeline and shader binding
table as every other scene of the kernel.

A hit on a copy is handed back as a hit on the body's own shape (its distance along the
unshifted ray, its shape pointer: the body's BSDF, emitter and mesh data), so the surface
interaction is computed on the body's shape exactly as the per-body loop computes it.

It holds meshes and the analytic shapes placed by ``to_world`` alone
(:data:`ATLAS_ANALYTIC_SHAPES`); a body with another shape (an instance, a curve) cannot
be held, and the caller takes the per-body loop (:meth:`BodyAtlas.unsupported`).
"""

from __future__ import annotations

import numpy as np

from .jitdata import jit_array

ATLAS_ANALYTIC_SHAPES = ("Sphere", "Disk", "Cylinder")  # Mitsuba class names placed by to_world alone
CELL_SCALE = 1.25  # cell side over the largest body's bounding-box side
CELL_MARGIN_M = 1e-2  # added to the cell side, m
CELL_PAD = 1e-4  # a cell's query box is padded by this fraction of the largest body side


class BodyAtlas:
    """One scene of every body's shapes, body ``b`` shifted by ``offsets[b]``.

    ===============  ========  ============================================================
    scene            mi.Scene  the copies (a guest of the pipeline host where there is one)
    offsets_m        ndarray   (K, 3) shift of each body's frame into its cell, m
    ===============  ========  ============================================================

    Build with :meth:`build`; :meth:`unsupported` says why a body list cannot be held.
    """

    def __init__(self, scene, offsets_m, cell_min, cell_max, original_ids):
        import drjit as dr
        import mitsuba as mi

        self.scene = scene
        self.offsets_m = offsets_m
        self._offsets = jit_array(mi.Float, offsets_m, np.float32)
        self._cell_min = jit_array(mi.Float, cell_min, np.float32)
        self._cell_max = jit_array(mi.Float, cell_max, np.float32)
        self._original_ids = jit_array(mi.UInt32, original_ids, np.uint32)  # a copy's registry id -> its original's
        dr.make_opaque(self._offsets, self._cell_min, self._cell_max, self._original_ids)

    @staticmethod
    def unsupported(bodies) -> str | None:
        """The first shape the atlas cannot hold, as ``"body 'name': shape Class"``; None
        where it holds them all."""
        import mitsuba as mi

        for body in bodies:
            for shape in body.scene.shapes():
                if not isinstance(shape, mi.Mesh) and shape.class_name() not in ATLAS_ANALYTIC_SHAPES:
                    return f"body {body.name!r}: shape {shape.class_name()}"
        return None

    @classmethod
    def build(cls, bodies, host=None) -> BodyAtlas:
        """The atlas of ``bodies`` (:class:`~dopplertof.scene.Body` list; each body's
        ``bounds_local``), a guest of ``host`` where given.

        Raises
        ------
        ValueError
            A shape the atlas cannot hold (:meth:`unsupported`).
        """
        import drjit as dr
        import mitsuba as mi

        reason = cls.unsupported(bodies)
        if reason is not None:
            raise ValueError(f"the body atlas cannot hold {reason}")
        lo = np.array([b.bounds_local[0] for b in bodies], dtype=np.float64)
        hi = np.array([b.bounds_local[1] for b in bodies], dtype=np.float64)
        largest = float((hi - lo).max())
        cell = largest * CELL_SCALE + CELL_MARGIN_M
        n = int(np.ceil(len(bodies) ** (1 / 3) - 1e-9))
        index = np.arange(len(bodies))
        grid = np.stack([index % n, (index // n) % n, index // (n * n)], axis=1) - (n - 1) / 2
        offsets = grid * cell - 0.5 * (lo + hi)
        originals = [(b, shape) for b, body in enumerate(bodies) for shape in body.scene.shapes()]
        copies = [_shifted_copy(shape, offsets[b]) for b, shape in originals]
        entries = {"type": "scene", **{f"atlas-{k}": copy for k, copy in enumerate(copies)}}
        if host is not None:
            from .loader import HOST_KEY

            entries[HOST_KEY] = host
        scene = mi.load_dict(entries)
        copy_ids = np.array(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(copies)))
        table = np.zeros(int(copy_ids.max()) + 1, dtype=np.uint32)
        table[copy_ids] = np.array(dr.reinterpret_array(mi.UInt32, mi.ShapePtr([shape for _, shape in originals])))
        pad = CELL_PAD * largest + 1e-6
        return cls(scene, offsets, lo + offsets - pad, hi + offsets + pad, table)

    def _enter(self, body, ray_local, query):
        """``ray_local`` (in ``body``'s frame) shifted into the body's cell, from where it
        enters the cell's box to where it leaves it (or its end): (ray, distance skipped,
        lanes whose ray meets the box)."""
        import drjit as dr
        import mitsuba as mi

        offset = dr.gather(mi.Vector3f, self._offsets, body, query)
        cell_min = dr.gather(mi.Point3f, self._cell_min, body, query)
        cell_max = dr.gather(mi.Point3f, self._cell_max, body, query)
        o = ray_local.o + offset
        inv = dr.rcp(ray_local.d)
        t_a, t_b = (cell_min - o) * inv, (cell_max - o) * inv
        t_in = dr.maximum(dr.max(dr.minimum(t_a, t_b)), 0.0)
        t_out = dr.minimum(dr.min(dr.maximum(t_a, t_b)), ray_local.maxt)
        meets = query & (t_in <= t_out)
        return mi.Ray3f(o + ray_local.d * t_in, ray_local.d, t_out - t_in, ray_local.time, ray_local.wavelengths), t_in, meets

    def closest(self, body, ray_local, query):
        """The preliminary intersection of ``ray_local`` with body ``body`` (0-based, per
        lane) where ``query``: its distance along ``ray_local``, its shape the body's own."""
        import drjit as dr
        import mitsuba as mi

        ray, skipped, meets = self._enter(body, ray_local, query)
        pi = self.scene.ray_intersect_preliminary(ray, coherent=False, active=meets)
        hit = meets & pi.is_valid()
        pi.t = dr.select(hit, pi.t + skipped, dr.inf)
        copy_id = dr.reinterpret_array(mi.UInt32, pi.shape)
        pi.shape = dr.reinterpret_array(mi.ShapePtr, dr.gather(mi.UInt32, self._original_ids, copy_id, hit))
        return pi

    def blocked(self, body, ray_local, query):
        """Whether body ``body`` (0-based, per lane) blocks ``ray_local`` where ``query``."""
        ray, _, meets = self._enter(body, ray_local, query)
        # Inside a symbolic loop ray_test is true on masked-off lanes: mask its result.
        return meets & self.scene.ray_test(ray, meets)


def _shifted_copy(shape, offset_m):
    """A copy of ``shape`` shifted by ``offset_m`` (a mesh: its vertices; an analytic shape:
    its ``to_world``), for intersection only (no BSDF, no emitter)."""
    import mitsuba as mi

    if isinstance(shape, mi.Mesh):
        copy = mi.Mesh(f"{shape.id()}-atlas", shape.vertex_count(), shape.face_count())
        target = mi.traverse(copy)  # (a rectangle or disk mesh lists only its to_world)
        positions = np.array(shape.vertex_positions_buffer(), dtype=np.float64).reshape(-1, 3) + offset_m
        target["vertex_positions"] = jit_array(mi.Float, positions, np.float32)
        target["faces"] = jit_array(mi.UInt32, shape.faces_buffer(), np.uint32)
        target.update()
        return copy
    shift = mi.ScalarTransform4f().translate(mi.ScalarVector3f(*np.asarray(offset_m, dtype=np.float32)))
    to_world = mi.traverse(shape)["to_world"]
    return mi.load_dict({"type": shape.class_name().lower(), "to_world": shift @ mi.ScalarTransform4f(np.array(to_world.matrix, dtype=np.float64).reshape(4, 4))})
