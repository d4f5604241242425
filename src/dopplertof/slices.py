"""One Mitsuba scene per instant: ``traversal="slices"`` (DESIGN §6, issue 17).

Every lane of a kernel sees the scene at one instant per correlated member: a kernel holds
one group of every pixel of its pass's tile, member ``m`` of every group takes the same
time ``t_m`` (:func:`dopplertof.tracing.lanes.slice_times`), and before the kernel each
member's scene is placed at its time. A member's scene is one ``mi.Scene`` holding the
static shapes (the very objects of the static scene) and a copy of every body's shapes,
placed in the world at ``t_m``: a mesh's ``vertex_positions`` (and normals) are rewritten
from its rest positions, an analytic shape's or an instance's ``to_world`` is set, and
Embree rebuilds its tree. The moving meshes whose BSDFs are of one definition are merged
into one mesh (not an emitter's, a sensor's or a medium boundary's), so that a placement
updates one Mitsuba shape and one Embree geometry for them, not one per body (a group's
members: 2.5 ms with 8 moving cubes, 6.6 ms with 128, 14 ms on a street sample;
``benchmarks/slices_built.py``).
A ray is then one query of one scene, as for a static scene, whatever the number of bodies.

A pass of several groups traces one kernel per group
(:meth:`dopplertof.passes.PassTracer`): the first group's is traced in Python and recorded
(``dr.freeze``), the others replay it with their first sample, their times and the placed
bodies as data. The vertex buffers are overwritten in place, so the recorded kernel reads
them (a new array would make Dr.Jit record again); where recording fails, the render warns
and traces every group.

A hit keeps what the per-lane traversals give (:class:`~dopplertof.scene.Hit`): its body
(looked up from the hit shape, on a merged mesh from its triangle), the body's pose at the
lane's time, and, for a mesh, the hit triangle's plane in the body's frame from the rest
positions of the body's own scene (read from a table by the shape's registry id, not
through the meshes' methods); for an analytic shape the plane's point is the world hit
taken back into the body's frame (float32 at the world's scale, not the body's). Its
Float64 distance is recomputed against the hit primitive's plane in the world at the
member's instant (``Hit.plane64``): a triangle's, made on the host in float64 and read
from a table (a static triangle's once, a moving triangle's when the members are placed,
from its rest corners by its body's Float64 pose); an analytic shape's, its tangent plane
at the hit. Float64 distances of
correlated paths at different instants then differ by the motion alone (DESIGN §3.5), with
no pose evaluated in the kernel for them (the per-lane traversals take the ray into the
body's frame instead).

Emitter sampling and everything that is not a ray query stay as they are: bodies' area
emitters are sampled in their body's scene at the lane's time
(:mod:`dopplertof.lights`), moving lights and the camera at the lane's time.

The paired estimators (reconnection, adaptive, analytic) trace a group in one lane: its
primal in one member's scene and its partner in the other's, both scenes in the kernel
(analytic's members sit at the exposure's ends). A lane's member is the one whose placed
time is nearest its own, so every time a lane traces must be a member's.

Each pixel's estimator keeps its distribution (same mean, same per-pixel variance,
``benchmarks/slice_variance.py``); the errors of pixels in one kernel become correlated.
On the CPU only; its cost against the per-lane traversals: ``benchmarks/slices_built.py``.

=================  ======================================================================
what               where
=================  ======================================================================
member scenes      :class:`SliceScenes` (built on a render's first pass, kept with the
                   :class:`~dopplertof.scene.DynamicScene`:
                   :meth:`~dopplertof.scene.DynamicScene.slice_scenes`)
placing            :meth:`SliceScenes.place`
ray queries        :meth:`SliceScenes.intersect`, :meth:`SliceScenes.occluded`
slice times        :func:`dopplertof.tracing.lanes.slice_times`
=================  ======================================================================
"""

from __future__ import annotations

import numpy as np

from .jitdata import jit_array

BODY_KEY = "__dopplertof_slice_body_{}_{}"  # a body copy's shape in a member scene
MERGED_KEY = "__dopplertof_slice_meshes_{}"  # moving meshes merged into one in a member scene
MERGED = 0xFFFFFFFF  # a merged mesh's entry in the body table: its triangles give the body


def _merge_key(mesh):
    """What moving meshes merged into one must share (Mitsuba's ``Mesh.merge`` asks the
    same), or None for a mesh kept on its own: an emitter's (sampled per shape), a sensor's,
    a medium boundary, one with mesh attributes."""
    if mesh.emitter() is not None or mesh.sensor() is not None or mesh.has_mesh_attributes():
        return None
    if mesh.interior_medium() is not None or mesh.exterior_medium() is not None:
        return None
    return (str(mesh.bsdf()), mesh.has_vertex_normals(), mesh.has_vertex_texcoords(), mesh.has_face_normals(), mesh.has_flipped_normals())


def _same_bsdf(a, b) -> bool:
    """Whether BSDFs ``a`` and ``b`` are one object or two of one definition (a body's copy
    loads its own): the same description and every parameter's value the same, bit for bit."""
    import mitsuba as mi

    if a is b:
        return True
    if str(a) != str(b):
        return False
    pa, pb = mi.traverse(a), mi.traverse(b)
    if set(pa.keys()) != set(pb.keys()):
        return False
    try:
        return all(np.array_equal(np.asarray(getattr(pa[k], "matrix", pa[k])), np.asarray(getattr(pb[k], "matrix", pb[k]))) for k in pa.keys())
    except (TypeError, ValueError):  # a value numpy cannot compare: not known to be equal
        return False


def _merge_groups(meshes) -> list:
    """``meshes`` ((mesh, what the caller keeps with it) pairs) in groups that can be one
    mesh (:func:`_merge_key`, :func:`_same_bsdf`), each in the order given; a mesh that
    cannot be merged is a group of its own."""
    groups = []  # [key or None, [(mesh, part), ...]]
    for mesh, part in meshes:
        key = _merge_key(mesh)
        group = next((g for g in groups if key is not None and g[0] == key and _same_bsdf(g[1][0][0].bsdf(), mesh.bsdf())), None)
        if group is None:
            groups.append([key, [(mesh, part)]])
        else:
            group[1].append((mesh, part))
    return [members for _, members in groups]


def _one_mesh(meshes, name: str):
    """One Mitsuba mesh of ``meshes`` (compatible: :func:`_merge_groups`), their vertices
    and triangles in order (a triangle of the k-th keeps its index plus the triangles
    before), with the first's BSDF."""
    import mitsuba as mi

    if len(meshes) == 1:
        return meshes[0]
    first = meshes[0]
    props = mi.Properties()
    props["bsdf"] = first.bsdf()
    props["face_normals"] = first.has_face_normals()
    props["flip_normals"] = first.has_flipped_normals()
    counts = np.cumsum([0] + [m.vertex_count() for m in meshes])
    mesh = mi.Mesh(name, int(counts[-1]), sum(m.face_count() for m in meshes), props, first.has_vertex_normals(), first.has_vertex_texcoords())
    params = mi.traverse(mesh)

    def joined(buffer):
        return np.concatenate([np.array(getattr(m, buffer)()) for m in meshes])

    params["vertex_positions"] = jit_array(mi.Float, joined("vertex_positions_buffer"), np.float32)
    params["faces"] = jit_array(mi.UInt32, np.concatenate([np.array(m.faces_buffer(), np.uint32) + np.uint32(c) for m, c in zip(meshes, counts)]))
    if first.has_vertex_normals():
        params["vertex_normals"] = jit_array(mi.Float, joined("vertex_normals_buffer"), np.float32)
    if first.has_vertex_texcoords():
        params["vertex_texcoords"] = jit_array(mi.Float, joined("vertex_texcoords_buffer"), np.float32)
    params.update()
    return mesh


def _matrices(pose) -> np.ndarray:
    """(n, 4, 4) float64 matrices of a Float64 :class:`~dopplertof.motion.Pose` of n lanes
    (:func:`dopplertof.motion.compose`)."""
    from .motion import compose

    def stacked(components):
        return np.stack([np.asarray(c, np.float64) for c in components], -1)

    return compose(stacked(pose.translation), stacked(pose.q), stacked(pose.scale))


def _plane_table(planes):
    """(normals mi.Vector3d, offsets mi.Float64) of (n, 4) ``planes`` (:func:`_planes`),
    one row more of zeros (never empty), opaque."""
    import drjit as dr
    import mitsuba as mi

    planes = np.concatenate([planes, np.zeros((1, 4))])
    table = (mi.Vector3d(*(jit_array(mi.Float64, planes[:, i]) for i in range(3))), jit_array(mi.Float64, planes[:, 3]))
    dr.make_opaque(*table)
    return table


def _planes(corners, matrices=None) -> np.ndarray:
    """(n, 4) float64 planes ``(normal, offset)``, ``normal · x = offset``, of n triangles
    (``corners``: (n, 3, 3)), each first placed by its (4, 4) matrix where given. The normal
    is a unit vector (NaN for a degenerate triangle, whose distances then fall back to the
    hit's own)."""
    if matrices is not None:
        corners = corners @ np.swapaxes(matrices[:, :3, :3], 1, 2) + matrices[:, None, :3, 3]  # (matmul: einsum is 3x slower)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.concatenate([normal, np.einsum("ni,ni->n", normal, corners[:, 0])[:, None]], axis=1)


def kernel_inputs(*roots, leave_out=()) -> list:
    """Every Dr.Jit array and Mitsuba object (or other object Dr.Jit can traverse, such as
    the film filter's ``mi.ContinuousDistribution``) reachable from ``roots`` through attributes,
    containers and dataclass fields (private ones included, which a frozen function's own
    walk of its closure misses): the extra state of a frozen slice pass. Each replay walks
    them, so what a kernel does not read is left out: the member scenes' placements
    (:class:`_MemberPlacement`: their parameters hold nothing a kernel reads that the
    scenes do not) and the objects of ``leave_out`` (:func:`table_only_motions`). Dr.Jit
    refuses to record a pass that reads an array it was not given, so leaving out too much
    is an error (the render warns and traces every group), never a stale array."""
    import drjit as dr
    import mitsuba as mi

    found, seen, stack = [], {id(x) for x in leave_out}, list(roots)
    while stack:
        x = stack.pop()
        if x is None or id(x) in seen or isinstance(x, (bool, int, float, complex, str, bytes, type, np.ndarray, _MemberPlacement)):
            continue
        seen.add(id(x))
        if isinstance(x, (dr.ArrayBase, mi.Object)) or hasattr(x, "_traverse_1_cb_ro"):  # (Mitsuba's distributions are not Objects)
            found.append(x)
        elif isinstance(x, dict):
            stack.extend(x.values())
        elif isinstance(x, (list, tuple, set, frozenset)):
            stack.extend(x)
        elif hasattr(x, "__dict__") and not callable(x):
            stack.extend(vars(x).values())
        elif hasattr(x, "__slots__") and not callable(x):
            stack.extend(getattr(x, k, None) for k in x.__slots__)
    return found


def table_only_motions(scene) -> list:
    """The bodies' motions of ``scene`` (a :class:`~dopplertof.scene.DynamicScene`) that a
    slice pass reads only through the pose table's concatenation of their arrays
    (:class:`~dopplertof.scene.PoseTable`): keyframed or parametric motions of bodies
    without emitters, moving no camera or light. A pass's inputs leave them out
    (:func:`kernel_inputs`): with 128 moving cubes they were 2816 of its 3526 inputs, each
    walked on every replay."""
    from .scene import PoseTable

    read = [b.motion for b in scene.bodies if PoseTable.packed_model(b.motion) is None or b.scene.emitters()]
    read_ids = {id(m) for m in read + scene.motions()[len(scene.bodies) :]}  # + the camera's and the lights'
    return [b.motion for b in scene.bodies if id(b.motion) not in read_ids]


class _MemberPlacement:
    """Places the body shapes of one member scene: their parameters and rest state, the
    meshes' vertices and normals concatenated so that one product places them all.

    ``body_shapes``: (parameter key, body index) per shape, the index per vertex for a
    mesh that merges several bodies' (:func:`_merge_groups`)."""

    def __init__(self, mi_scene, body_shapes):
        import mitsuba as mi

        params = mi.traverse(mi_scene)
        keys = set(params.keys())
        spans, normal_spans, to_world = [], [], []
        vertices, vertex_body, normals, normal_body = [], [], [], []
        used = used_n = 0
        for key, body in body_shapes:
            if f"{key}.vertex_positions" in keys:
                v = np.array(params[f"{key}.vertex_positions"], np.float64).reshape(-1, 3)
                spans.append((key, used, used + len(v)))
                vertices.append(v)
                vertex_body.append(np.broadcast_to(body, len(v)))
                used += len(v)
                n = np.array(params[f"{key}.vertex_normals"], np.float64).reshape(-1, 3) if f"{key}.vertex_normals" in keys else np.zeros((0, 3))
                if len(n):
                    normal_spans.append((key, used_n, used_n + len(n)))
                    normals.append(n)
                    normal_body.append(np.broadcast_to(body, len(n)))
                    used_n += len(n)
            elif f"{key}.to_world" in keys:
                to_world.append((key, body, np.array(params[f"{key}.to_world"].matrix, np.float64).reshape(4, 4)))
            else:
                raise ValueError(f"a moving shape ({key}) has neither vertex positions nor a to_world to place it by")
        self.spans, self.normal_spans, self.to_world = spans, normal_spans, to_world
        placed = [f"{k}.vertex_positions" for k, _, _ in spans] + [f"{k}.vertex_normals" for k, _, _ in normal_spans] + [f"{k}.to_world" for k, _, _ in to_world]
        # What an update of these parameters does (``mi.SceneParameters.update``), without its
        # bookkeeping per parameter (a third of a street group's placement): each changed
        # shape is told which of its parameters changed, then the scene (Embree's rebuild).
        self.scene, self.fields, changed = mi_scene, {}, {}
        for key in placed:
            field, field_type, shape, _ = params.properties[key]
            self.fields[key] = (field, field_type, shape)
            changed.setdefault(id(shape), (shape, []))[1].append(key.rsplit(".", 1)[1])
        self.changed = list(changed.values())
        self.rest = np.concatenate(vertices) if vertices else np.zeros((0, 3))
        self.vertex_body = np.concatenate(vertex_body) if vertex_body else np.zeros(0, np.int64)
        self.rest_normals = np.concatenate(normals) if normals else np.zeros((0, 3))
        self.normal_body = np.concatenate(normal_body) if normal_body else np.zeros(0, np.int64)

    def _write(self, key, values):
        """Overwrite the parameter's buffer with ``values`` (float32) in place (no kernel
        may be reading it: :meth:`place`): its Dr.Jit variable stays the same, so a frozen
        pass replayed after the placement reads the new values (a new variable would make
        ``dr.freeze`` record the pass again). Embree shares the buffer; the update rebuilds
        its tree."""
        import ctypes

        import drjit as dr
        import mitsuba as mi

        buffer = mi.get_property(*self.fields[key])
        flat = np.ascontiguousarray(values, np.float32).ravel()  # as many values as it holds: a mesh keeps its size
        dr.eval(buffer)
        address = np.from_dlpack(buffer).ctypes.data  # the view is read-only: write through its address
        np.ctypeslib.as_array((ctypes.c_float * flat.size).from_address(address))[:] = flat

    def place(self, matrices):
        """Place every body shape by its body's matrix (``matrices``: (bodies, 4, 4))."""
        import drjit as dr
        import mitsuba as mi

        dr.sync_thread()  # no kernel reads the buffers while they are written
        linear, offset = matrices[:, :3, :3], matrices[:, :3, 3]
        v = (np.einsum("vij,vj->vi", linear[self.vertex_body], self.rest) + offset[self.vertex_body]).astype(np.float32)
        for key, a, b in self.spans:
            self._write(f"{key}.vertex_positions", v[a:b])
        if self.normal_spans:  # normals by the inverse transpose
            n = np.einsum("vji,vj->vi", np.linalg.inv(linear)[self.normal_body], self.rest_normals)
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
            n = n.astype(np.float32)
            for key, a, b in self.normal_spans:
                self._write(f"{key}.vertex_normals", n[a:b])
        for key, body, rest in self.to_world:  # from Python floats: Dr.Jit literals, which Mitsuba's update reads without a copy each
            field, field_type, _ = self.fields[f"{key}.to_world"]
            mi.set_property(field, field_type, mi.Transform4f((matrices[body] @ rest).tolist()))
        for shape, names in self.changed:  # the shapes, then the scene: Embree rebuilds its tree
            shape.parameters_changed(names)
        self.scene.parameters_changed([])
        dr.eval()


class SliceScenes:
    """The member scenes of a dynamic scene (module docstring).

    Parameters
    ----------
    scene : DynamicScene
        Its bodies carry ``load_copy`` (:class:`~dopplertof.scene.Body`).
    members : int
        Correlated times per group N: one scene per member.
    """

    def __init__(self, scene, members: int):
        import drjit as dr
        import mitsuba as mi

        self.members = members
        self.scenes, self.placements = [], []
        body_of = {}  # shape registry id -> body index (1-based), MERGED for a merged mesh
        rest_of = {}  # shape registry id of a mesh -> its parts' (the bodies' own, rest) shapes and bodies (1-based)
        static = {}  # the static shapes under their own ids (a key other than its id renames a shape)
        for i, shape in enumerate(scene.static.shapes()):
            static[shape.id() if shape.id() and shape.id() not in static else f"__dopplertof_static_{i}"] = shape

        def registry_id(shape):
            return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])

        for m in range(members):
            entries, body_shapes, meshes = dict(static), [], []
            for b, body in enumerate(scene.bodies):
                if body.load_copy is None:
                    raise ValueError(f"moving body {body.name!r} cannot be copied for traversal='slices' (it was not built by dopplertof.load_scene)")
                copy = body.load_copy()  # (not kept: its shapes live on in the member scene, all but the merged ones)
                for k, (shape, rest) in enumerate(zip(copy.shapes(), body.scene.shapes())):
                    if shape.is_mesh():
                        meshes.append((shape, (rest, b + 1)))
                        continue
                    entries[BODY_KEY.format(b, k)] = shape
                    body_shapes.append((BODY_KEY.format(b, k), b))
                    body_of[registry_id(shape)] = b + 1
            # Moving meshes of one material are one mesh: one update and one Embree geometry
            # per member, not one per body (a hit's body is then its triangle's).
            for g, group in enumerate(_merge_groups(meshes)):
                mesh = _one_mesh([shape for shape, _ in group], MERGED_KEY.format(g))
                parts = [part for _, part in group]
                bodies = {b for _, b in parts}
                entries[MERGED_KEY.format(g)] = mesh
                body_shapes.append((MERGED_KEY.format(g), np.concatenate([np.full(shape.vertex_count(), b - 1) for shape, (_, b) in group])))
                body_of[registry_id(mesh)] = bodies.pop() if len(bodies) == 1 else MERGED
                rest_of[registry_id(mesh)] = parts
            self.scenes.append(mi.load_dict({"type": "scene", **entries}))
            self.placements.append(_MemberPlacement(self.scenes[-1], body_shapes))
        static_of = {registry_id(shape): shape for shape in static.values()}
        size = max([*body_of, *rest_of, *static_of, 0]) + 1
        table = np.zeros(size, np.uint32)
        for shape_id, b in body_of.items():
            table[shape_id] = b
        self.body_table = jit_array(mi.UInt32, table)
        self._triangles, (rest, rest_body, static_planes) = self._triangle_tables(rest_of, static_of, size)
        self._plane_source = (rest, rest_body)  # the moving triangles' rest corners and bodies
        self._moving_triangles = len(rest)  # listed first in the triangle tables
        # The triangles' Float64 planes in the world: the static ones' once, the moving ones'
        # per member at its placed time (place).
        self._planes = (None, _plane_table(static_planes))
        self.pose_table = scene._pose_table()
        self.n_bodies = len(scene.bodies)
        self.times_s = np.full(members, np.nan)  # mutated in place: a frozen pass sees one object
        self._opaque_times = [dr.opaque(mi.Float64, 0.0) for _ in range(members)]
        self._poses = {}  # precise -> the bodies' poses at the members' times (member-major), opaque

    @staticmethod
    def _triangle_tables(rest_of, static_of, size):
        """What a hit on a mesh needs of its triangle, gathered by the shape's registry id
        (a table lookup, not two calls through every mesh of the registry): per id the
        offset of its triangles (-1: not a mesh); Float32 tables of their corners, the
        first for every mesh (a moving mesh's: its bodies' rest triangles; a static mesh's:
        its own), the other two for the moving meshes alone (listed first), whose rest
        normals they give; and the moving triangles' bodies (1-based), which give a merged
        mesh's hit its body. Second, on the host, what the triangles' world planes are made
        of (:meth:`place`): the moving triangles' rest corners (float64, (moving, 3, 3)), their
        bodies (0-based) and the static triangles' planes (:func:`_planes`).

        Parameters
        ----------
        rest_of : dict
            Registry id of a moving mesh in a member scene -> its parts in order: (the
            body's own mesh at rest, the body's index from 1).
        static_of : dict
            Registry id of a static shape -> the shape.
        size : int
            One more than the largest registry id.
        """
        import drjit as dr
        import mitsuba as mi

        offsets = np.full(size, -1, np.int64)
        chunks, bodies, used, moving = [], [], 0, 0
        for shape_id, parts in [*rest_of.items(), *((i, [(shape, 0)]) for i, shape in static_of.items())]:
            if not parts[0][0].is_mesh():
                continue
            offsets[shape_id] = used
            for shape, body in parts:
                v = np.array(shape.vertex_positions_buffer(), np.float32).reshape(-1, 3)
                f = np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)
                chunks.append(v[f])
                bodies.append(np.full(len(f), body, np.uint32))
                used += len(f)
            moving = used if shape_id in rest_of else moving
        triangles = np.concatenate([*chunks, np.zeros((1, 3, 3), np.float32)])  # never empty
        lengths = (len(triangles), max(moving, 1), max(moving, 1))
        corners = [mi.Point3f(*(jit_array(mi.Float, triangles[: lengths[k], k, i]) for i in range(3))) for k in range(3)]
        offsets_dr = jit_array(mi.Int32, offsets, np.int32)
        triangle_body = np.concatenate([*bodies, np.zeros(1, np.uint32)])
        triangle_body_dr = jit_array(mi.UInt32, triangle_body[: max(moving, 1)])
        dr.make_opaque(offsets_dr, triangle_body_dr, *corners)
        corners64 = triangles[:-1].astype(np.float64)
        static = _planes(corners64[moving:])
        return (offsets_dr, corners, triangle_body_dr), (corners64[:moving], triangle_body[:moving].astype(np.int64) - 1, static)

    def place(self, times_s):
        """Place member ``m``'s scene at ``times_s[m]`` (s) where it is elsewhere.

        Parameters
        ----------
        times_s : sequence of float, s
            One time per member.
        """
        import drjit as dr
        import mitsuba as mi

        times_s = [float(t) for t in times_s]
        if times_s == list(self.times_s):
            return
        # Every lane of a member shares its bodies' poses: evaluated here once (the pose
        # table's arithmetic), gathered per lane (:meth:`pose`); the shapes are placed by them.
        body = dr.tile(dr.arange(mi.UInt32, self.n_bodies), self.members)
        time = jit_array(mi.Float64, np.repeat(np.array(times_s), self.n_bodies))
        for precise in (True, False):
            pose = self.pose_table.pose(body, time, precise)
            dr.make_opaque(pose)
            self._poses[precise] = pose
        matrices = _matrices(self._poses[True])
        for m, t in enumerate(times_s):
            if self.times_s[m] != t:
                self.placements[m].place(matrices[m * self.n_bodies : (m + 1) * self.n_bodies])
                self.times_s[m] = t
                self._opaque_times[m] = dr.opaque(mi.Float64, t)
        # The moving triangles' planes in the world, in Float64, at each member's time
        # (member-major), from their rest corners by their bodies' Float64 poses: correlated
        # paths' distances to a moving triangle at two instants then differ by its motion
        # alone (DESIGN §3.5).
        rest, body = self._plane_source
        member_body = (np.arange(self.members)[:, None] * self.n_bodies + body[None, :]).ravel()
        self._planes = (_plane_table(_planes(np.tile(rest, (self.members, 1, 1)), matrices[member_body])), self._planes[1])

    def state(self) -> tuple:
        """Everything of the member scenes a pass's kernel reads (the scenes, the hit
        tables, the placed times and poses): the arguments of a frozen pass
        (:meth:`dopplertof.passes.PassTracer._sliced`), which :meth:`set_state` puts back."""
        return (self.scenes, self.body_table, self._triangles, self._planes, self._opaque_times, self._poses[False], self._poses[True])

    def set_state(self, state: tuple):
        """Use ``state`` (:meth:`state`'s layout) in what is traced next."""
        self.scenes, self.body_table, self._triangles, self._planes, times, poses32, poses64 = state
        self._opaque_times, self._poses = list(times), {False: poses32, True: poses64}

    def member_of(self, time_s):
        """Each lane's member (mi.UInt32): the member whose placed time is its time's nearest."""
        import drjit as dr
        import mitsuba as mi

        member = mi.UInt32(0)
        best = dr.abs(time_s - self._opaque_times[0])
        for m in range(1, self.members):
            gap = dr.abs(time_s - self._opaque_times[m])
            closer = gap < best
            member, best = dr.select(closer, m, member), dr.select(closer, gap, best)
        return member

    def pose(self, body, time_s, precise: bool):
        """Pose of moving ``body`` (mi.UInt32 per lane, 1-based; lanes with 0 get no pose:
        :meth:`~dopplertof.scene.DynamicScene.select_pose` gives static geometry the
        identity) at each lane's member's time, gathered from the poses :meth:`place`
        evaluated.

        Parameters
        ----------
        body : mi.UInt32
        time_s : mi.Float64
            The lanes' times (the placed times of their members).
        precise : bool
            Float64 components.

        Returns
        -------
        Pose
        """
        import drjit as dr

        moving = body > 0
        index = self.member_of(time_s) * self.n_bodies + dr.select(moving, body - 1, 0)
        return dr.gather(type(self._poses[precise]), self._poses[precise], index, moving)

    def _member_masks(self, time_s, active):
        """Per member, the active lanes whose time is that member's."""
        member = self.member_of(time_s)
        return [active & (member == m) for m in range(self.members)]

    def intersect(self, ray, time_s, active, coherent, select_pose, poses):
        """(preliminary intersection, body index, pose) of world-space ``ray`` in each lane's
        member scene; the pose (``select_pose(poses, body)``) is the body's at the lane's time."""
        import drjit as dr
        import mitsuba as mi

        pi = dr.zeros(mi.PreliminaryIntersection3f)  # a miss
        for scene_m, mask in zip(self.scenes, self._member_masks(time_s, active)):
            # A branch: a SIMD packet with no lane of this member (member-major lanes) skips its query.
            pi = dr.if_stmt(
                (ray, mask, pi), mask,
                lambda ray, mask, pi, scene_m=scene_m: scene_m.ray_intersect_preliminary(ray, coherent=coherent, active=mask),
                lambda ray, mask, pi: pi, label="dopplertof slices: member query",
            )  # fmt: skip
        hit = active & pi.is_valid()
        shape_id = dr.reinterpret_array(mi.UInt32, pi.shape)
        body = dr.gather(mi.UInt32, self.body_table, shape_id, hit & (shape_id < dr.width(self.body_table)))
        merged = body == MERGED  # a mesh of several bodies: the body is its triangle's
        offsets, _, triangle_body = self._triangles
        triangle = mi.UInt32(dr.gather(mi.Int32, offsets, shape_id, merged)) + pi.prim_index
        body = dr.select(merged, dr.gather(mi.UInt32, triangle_body, triangle, merged), body)
        return pi, body, select_pose(poses, body)

    def occluded(self, ray, time_s, active):
        """True where ``ray`` is blocked in its lane's member scene."""
        import drjit as dr
        import mitsuba as mi

        blocked = mi.Bool(False)
        for scene_m, mask in zip(self.scenes, self._member_masks(time_s, active)):
            blocked = dr.if_stmt(
                (ray, mask, blocked), mask,
                lambda ray, mask, blocked, scene_m=scene_m: blocked | scene_m.ray_test(ray, mask),
                lambda ray, mask, blocked: blocked, label="dopplertof slices: member test",
            )  # fmt: skip
        return blocked

    def local_frame(self, si, body, pose, time_s, active):
        """(p_local, n_local, plane_local, plane64) of world hits ``si``
        (:class:`~dopplertof.scene.Hit`): for static geometry (``body`` 0) the world's, a
        mesh's plane through its triangle's first vertex; on a body in the body's frame at
        ``pose`` (module docstring). ``plane64``: the hit primitive's plane in the world at
        the lane's member's time ``time_s``, in Float64 (normal, offset): a triangle's from
        the table :meth:`place` made, an analytic shape's the tangent plane at the hit."""
        import drjit as dr
        import mitsuba as mi

        from .motion import _conj, _rotate

        valid = active & si.is_valid()
        moving = valid & (body > 0)
        offsets, corners, _ = self._triangles
        shape_id = dr.reinterpret_array(mi.UInt32, si.shape)
        offset = dr.gather(mi.Int32, offsets, shape_id, valid & (shape_id < dr.width(offsets)))
        on_mesh = valid & (offset >= 0)
        triangle = mi.UInt32(offset) + si.prim_index
        p0 = dr.gather(mi.Point3f, corners[0], triangle, on_mesh)

        def on_body(p, n, p0, triangle, moving, on_mesh):
            rest = moving & on_mesh
            p1, p2 = (dr.gather(mi.Point3f, c, triangle, rest) for c in corners[1:])
            n_rest = dr.normalize(dr.cross(p1 - p0, p2 - p0))  # as Mitsuba computes a triangle's normal
            n_body = dr.normalize(pose.scale * _rotate(_conj(pose.q), n))  # a normal's inverse transpose
            return mi.Point3f(dr.select(moving, pose.point_to_local(p), p)), mi.Normal3f(dr.select(rest, n_rest, dr.select(moving, n_body, n)))

        # A branch: a SIMD packet whose lanes all hit static geometry skips the body's frame.
        p_local, n_local = dr.if_stmt(
            (mi.Point3f(si.p), mi.Normal3f(si.n), p0, triangle, moving, on_mesh), moving, on_body,
            lambda p, n, *_: (p, n), label="dopplertof slices: body frame",
        )  # fmt: skip
        plane_local = dr.select(on_mesh, p0, p_local)
        (moving_normals, moving_offsets), (static_normals, static_offsets) = self._planes
        moving = self._moving_triangles  # moving triangles first, then the static ones
        on_moving, on_static = on_mesh & (triangle < moving), on_mesh & (triangle >= moving)
        row = dr.select(on_moving, triangle + self.member_of(time_s) * moving, triangle - moving)  # moving planes are member-major
        n_hit = mi.Vector3d(si.n)
        n64 = dr.select(on_moving, dr.gather(mi.Vector3d, moving_normals, row, on_moving), dr.select(on_static, dr.gather(mi.Vector3d, static_normals, row, on_static), n_hit))
        c64 = dr.select(on_moving, dr.gather(mi.Float64, moving_offsets, row, on_moving), dr.select(on_static, dr.gather(mi.Float64, static_offsets, row, on_static), dr.dot(n_hit, mi.Vector3d(si.p))))
        return p_local, n_local, plane_local, (n64, c64)
