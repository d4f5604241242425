"""The phases of a bounce, shared by the independent and the paired tracer.

======================  =================================================================
phase                   what it does
======================  =================================================================
:func:`camera_ray`      the camera ray of a pixel sample (film position from the filter,
                        aperture, wavelength), its weight, and its Float64 origin on the
                        aperture; :func:`place_camera_ray` puts it where a moving camera
                        is at the lane's time
:func:`next_hit`        the surface a ray hits at the lane's time; a camera ray with
                        ``hide_emitters`` passes through emitter surfaces (stock path)
:func:`extend`          the Float64 optical length to a new vertex: index × distance, the
                        distance recomputed against the hit primitive's plane in the body's
                        frame (DESIGN §3.5) where the path met motion
                        (:func:`float64_distances`, :func:`met_motion`). **The one place the
                        refractive index enters**, with :func:`segment_index` for the index
                        of a segment
:func:`emitter_hit`     the emitted radiance where a path hits (or escapes to) an emitter,
                        and the density with which emitter sampling would have found it
:func:`sample_emitter`  next-event estimation: a light sample, its visibility at the
                        lane's time, the BSDF value and density towards it and the optical
                        length of the path through it
:func:`ground_truth`    depth, radial velocities, camera-frame velocity, optical flow and
                        body id of the camera ray's hit
======================  =================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_HIDDEN_LAYERS = 4  # hidden emitter surfaces a camera ray may pass through


def aperture_point(sensor, ray):
    """Float64 point where the camera ray leaves the aperture (the camera plane z = 0).

    Mitsuba's perspective cameras start rays at the near-clip plane; optical path lengths
    and depths are measured from the aperture instead.

    Parameters
    ----------
    sensor : mi.Sensor
    ray : mi.Ray3f
        A camera ray in the sensor's rest frame.

    Returns
    -------
    mi.Point3d
    """
    import drjit as dr
    import mitsuba as mi

    to_world = sensor.world_transform()
    eye = to_world.translation()
    forward = dr.normalize(to_world @ mi.Vector3f(0, 0, 1))
    back = dr.dot(ray.o - eye, forward) / dr.dot(ray.d, forward)
    return mi.Vector3d(ray.o) - mi.Vector3d(ray.d) * mi.Float64(back)


def camera_ray(sensor, filter_sampler, setup, pixel, time_s, next_1d, next_2d):
    """(ray, weight, Float64 aperture point) of ``pixel``'s sample, in the sensor's rest
    frame (where the sensor's ``to_world`` puts it): :func:`place_camera_ray` moves it.

    Parameters
    ----------
    sensor : mi.Sensor
    filter_sampler : FilterSampler
    setup : LaneSetup
    pixel : mi.UInt32
        Each lane's pixel (row-major).
    time_s : mi.Float64
        Each lane's time, s.
    next_1d, next_2d : callable
        Draw the lane's next uniform numbers.

    Returns
    -------
    tuple of (mi.Ray3f, mi.Spectrum, mi.Point3d)
    """
    import mitsuba as mi

    px, py = pixel % setup.width, pixel // setup.width
    offset, filter_weight = filter_sampler.offset(next_2d(), px, py)
    aperture = next_2d()
    wavelength_sample = next_1d()
    film_pos = (mi.Point2f(mi.Float(px), mi.Float(py)) + 0.5 + offset) / mi.ScalarVector2f(setup.width, setup.height)
    ray, weight = sensor.sample_ray(mi.Float(time_s), wavelength_sample, film_pos, aperture)
    return ray, weight * filter_weight, aperture_point(sensor, ray)


def place_camera_ray(scene, ray, x0, time_s):
    """(ray, Float64 aperture point) of a camera ray from :func:`camera_ray` where the
    camera is at ``time_s``: a moving camera's ray leaves its aperture at the lane's time,
    and optical lengths start there. Correlated lanes at other times place the same
    rest-frame ray (the pixel sample replayed in the camera's frame).

    Parameters
    ----------
    scene : DynamicScene
    ray : mi.Ray3f
        From :func:`camera_ray`.
    x0 : mi.Point3d
        Its aperture point.
    time_s : mi.Float64
        Each lane's time, s.

    Returns
    -------
    tuple of (mi.Ray3f, mi.Point3d)
    """
    import drjit as dr
    import mitsuba as mi

    pose = scene.camera_pose(time_s)
    if pose is None:
        return ray, x0
    placed = mi.Ray3f(pose.point_to_world(ray.o), dr.normalize(pose.vector_to_world(ray.d)), ray.maxt, ray.time, ray.wavelengths)
    return placed, scene.camera_pose(time_s, precise=True).point_to_world(x0)


def next_hit(scene, ray, time_s, poses, hide_emitters, active=True, from_camera=True):
    """The surface ``ray`` hits at the lanes' times (a :class:`~dopplertof.scene.Hit`);
    where it is a camera ray (``from_camera``) and ``hide_emitters``, it passes through up
    to ``MAX_HIDDEN_LAYERS`` emitter surfaces.

    Parameters
    ----------
    scene : DynamicScene
    ray : mi.Ray3f
    time_s : mi.Float64
        Each lane's time, s.
    poses : object
        The bodies' poses at the lanes' times (``scene.poses``).
    hide_emitters : bool
    active : bool or mi.Bool, default True
    from_camera : bool or mi.Bool, default True
        The lanes whose ``ray`` is the camera ray.

    Returns
    -------
    Hit
    """
    import drjit as dr

    def pass_hidden(hit):
        for _ in range(MAX_HIDDEN_LAYERS):
            hidden = active & from_camera & hit.si.is_valid() & (hit.si.emitter(scene.static) != None)  # noqa: E711 - Dr.Jit pointer test
            beyond = scene.intersect(hit.si.spawn_ray(ray.d), time_s, hidden, poses=poses)
            hit = dr.select(hidden, beyond, hit)
        return hit

    hit = scene.intersect(ray, time_s, active, poses=poses)
    if not hide_emitters:
        return hit
    # A branch: in the path loop, where no lane's ray is a camera ray, the layers are skipped.
    return dr.if_stmt((hit,), active & from_camera, pass_hidden, lambda hit: hit, label="dopplertof: hidden emitters")


def hit_distance64(scene, poses64, hit, x_prev, direction):
    """Float64 distance from ``x_prev`` (mi.Vector3d) along ``direction`` to ``hit``, and the point.

    Recomputed against the hit primitive's plane in the body's frame (with
    ``traversal="slices"``: its plane in the world at the lane's instant, ``hit.plane64``),
    so two correlated paths hitting the same primitive at different times differ by the
    motion alone.

    Parameters
    ----------
    scene : DynamicScene
    poses64 : object
        The bodies' Float64 poses at the lanes' times.
    hit : Hit
    x_prev : mi.Vector3d
        The previous vertex.
    direction : mi.Vector3f
        The ray's direction.

    Returns
    -------
    tuple of (mi.Float64, mi.Point3d)
        Distance (m) and hit point.
    """
    import drjit as dr
    import mitsuba as mi

    d64 = mi.Vector3d(direction)
    d64 = d64 / dr.norm(d64)  # IEEE div and sqrt: dr.normalize of Float64 is approximate on CUDA

    def to_body(x_prev, d64, body):
        pose64 = scene.select_pose(poses64, body)
        return pose64.point_to_local(x_prev), pose64.vector_to_local(d64)

    if hit.plane64 is not None:  # traversal "slices": the plane at the lane's instant, in the world
        n64, offset64 = hit.plane64
        t64 = (offset64 - dr.dot(n64, mi.Vector3d(x_prev))) / dr.dot(n64, d64)
    else:
        o_local, d_local = mi.Vector3d(x_prev), d64  # static geometry's frame is the world
        if scene.bodies:  # a branch: a SIMD packet whose lanes all hit static geometry skips the pose
            o_local, d_local = dr.if_stmt((o_local, d64, hit.body), hit.body > 0, to_body, lambda x_prev, d64, body: (x_prev, d64), label="dopplertof: hit in the body's frame")
        n_local = mi.Vector3d(hit.n_local)
        t64 = dr.dot(n_local, mi.Vector3d(hit.plane_local) - o_local) / dr.dot(n_local, d_local)
    t64 = dr.select(dr.isfinite(t64) & (t64 > 0), t64, mi.Float64(hit.si.t))
    return t64, x_prev + d64 * t64


def float64_distances(scene, needs_length: bool) -> str:
    """Which lanes take Float64 distances (:func:`extend`'s ``precise``), in the independent
    tracer and, per member, in the paired one.

    The members of a group trace one path at their own instants. Where nothing on the path
    moves, it is the same path at every instant, the Float32 rounding of its distances is
    common to the members and the phases between them are exact; where it met motion, its
    segments differ by micrometres between members, which Float32 distances (rounded by
    up to a micrometre at 4 m) would blur (``tests/test_dtof.py``).

    Parameters
    ----------
    scene : DynamicScene
    needs_length : bool
        Whether the outputs read optical lengths (``Sink.needs_length``).

    Returns
    -------
    str
        ``"all"`` (a moving camera: every path moves), ``"none"`` (no lengths read, or no
        moving body: moving point lights' legs are Float64 anyway, :func:`length_to_emitter`)
        or ``"met-motion"`` (the lanes whose path has hit a moving body).
    """
    if not needs_length or (scene.camera_motion is None and not scene.bodies):
        return "none"
    return "all" if scene.camera_motion is not None else "met-motion"


def met_motion(rule: str, met, hit):
    """(met, precise) of a path reaching ``hit``: the lanes whose path has now met a moving
    body (``met``, loop state), and :func:`extend`'s ``precise`` for the segment to ``hit``
    under ``rule`` (:func:`float64_distances`).

    Parameters
    ----------
    rule : str
        :func:`float64_distances`' value.
    met : mi.Bool
        The lanes whose path had met a moving body (``mi.Bool(False)`` at the camera).
    hit : Hit

    Returns
    -------
    tuple of (mi.Bool, bool or mi.Bool)
    """
    if rule != "met-motion":
        return met, rule == "all"
    met = met | (hit.body > 0)
    return met, met


def extend(scene, poses64, hit, x_prev, direction, length_m, index, active, precise=True):
    """(optical length to ``hit``, Float64 hit point, Float64 distance): ``length_m`` plus
    ``index`` × the distance from ``x_prev``, where ``active`` and the ray hit.

    ``precise``: the distance from the primitive's plane in Float64, where the members of a
    group may see a segment at lengths that differ by micrometres (phases); else the
    Float32 hit distance (intensity only, or a path that is the same at every instant of
    its group: its rounding is common to the members). A bool for every lane, or an
    ``mi.Bool`` per lane (a branch: a SIMD packet with no precise lane skips the Float64
    work).

    Parameters
    ----------
    scene : DynamicScene
    poses64 : object
        The bodies' Float64 poses at the lanes' times.
    hit : Hit
    x_prev : mi.Point3d
        The previous vertex.
    direction : mi.Vector3f
    length_m : mi.Float64
        Optical length so far, m.
    index : mi.Float
        Refractive index of the segment.
    active : mi.Bool
    precise : bool or mi.Bool, default True

    Returns
    -------
    tuple of (mi.Float64, mi.Point3d, mi.Float64)
    """
    import drjit as dr
    import mitsuba as mi

    def exact(x_prev, direction):
        return hit_distance64(scene, poses64, hit, x_prev, direction)

    def rounded(x_prev, direction):  # from x_prev, not the ray's origin: camera rays start at the near-clip plane
        return mi.Float64(dr.norm(hit.si.p - mi.Point3f(x_prev))), mi.Vector3d(hit.si.p)

    if isinstance(precise, bool):
        t64, x_hit = (exact if precise else rounded)(x_prev, direction)
    else:
        t64, x_hit = dr.if_stmt((x_prev, direction), precise, exact, rounded, label="dopplertof: Float64 distance")
    hit_here = active & hit.si.is_valid()
    # A ray that escapes keeps its origin as the path's last vertex: light from an
    # infinitely distant emitter is measured to it (emitter_hit_length).
    return dr.select(hit_here, length_m + mi.Float64(index) * t64, length_m), dr.select(hit_here, x_hit, x_prev), t64


def segment_index(index, tables, bsdf, active, wi_local, wo_local):
    """Refractive index of the segment leaving a vertex of ``bsdf`` towards ``wo_local``,
    arriving from ``wi_local`` in a medium of ``index``: times η entering, 1/η leaving a
    refracting surface (η from :class:`~dopplertof.tracing.materials.MaterialTables`),
    unchanged on reflection, and everywhere in a scene without refracting surfaces.

    Parameters
    ----------
    index : mi.Float
        Index of the medium the path arrives from.
    tables : MaterialTables
    bsdf : mi.BSDFPtr
    active : mi.Bool
    wi_local, wo_local : mi.Vector3f
        Arriving and leaving directions in the local shading frame.

    Returns
    -------
    mi.Float
    """
    import drjit as dr

    if not tables.refracts:
        return index
    relative_ior = tables.gather(tables.relative_ior, bsdf, active)
    transmits = wi_local.z * wo_local.z < 0
    factor = dr.select(wi_local.z > 0, relative_ior, dr.rcp(relative_ior))
    return dr.select(transmits, index * factor, index)


def vertex_interaction(si):
    """The part of a vertex that the density of emitter sampling from it needs.

    Parameters
    ----------
    si : mi.SurfaceInteraction3f

    Returns
    -------
    mi.Interaction3f
    """
    import drjit as dr
    import mitsuba as mi

    return mi.Interaction3f(dr.detach(si.t), si.time, si.wavelengths, dr.detach(si.p), dr.detach(si.n))


def emitter_hit(scene, si, body, prev_it, prev_delta, time_s, active):
    """(Le, emitter-sampling density of this direction from ``prev_it``, mask) where a
    path meets ``si`` on ``body`` (:class:`~dopplertof.scene.Hit` numbering) at ``time_s``.

    ``si`` may be invalid (an escaped ray meets the environment). The density is 0 after
    a delta lobe, where emitter sampling cannot produce the direction.

    Parameters
    ----------
    scene : DynamicScene
    si : mi.SurfaceInteraction3f
    body : mi.UInt32
        The hit's body (:class:`~dopplertof.scene.Hit` numbering).
    prev_it : mi.Interaction3f
        The previous vertex (:func:`vertex_interaction`).
    prev_delta : mi.Bool
        Whether the previous bounce sampled a delta lobe.
    time_s : mi.Float64
        Each lane's time, s.
    active : mi.Bool

    Returns
    -------
    tuple of (mi.Spectrum, mi.Float, mi.Bool)
    """
    import drjit as dr

    emitter = si.emitter(scene.static)
    visible = active & (emitter != None)  # noqa: E711 - Dr.Jit pointer test
    pdf = dr.select(prev_delta, 0.0, scene.emitters.pdf_hit(prev_it, si, body, time_s, visible & ~prev_delta))
    return emitter.eval(si, visible), pdf, visible


def plane_wave_leg_m(scene, x, toward_light):
    """Distance light from an infinitely distant emitter (an environment, a directional
    light) travels to ``x`` from the direction ``toward_light``: a plane wave's, from the
    plane facing that direction that touches the static scene's bounding sphere
    (:meth:`~dopplertof.lights.Emitters.far_reference`), ``R − ω·(x − c)``. Its phase at
    ``x`` changes with ``ω·x`` as a far source's does, so a body moving into the wave
    shortens the light's leg by its speed along ω (Mitsuba's own sample points lie at a
    distance from ``x`` that depends on the scene's bounds, not on ω).

    Parameters
    ----------
    scene : DynamicScene
    x : mi.Point3d
        The path's last vertex, m.
    toward_light : mi.Vector3f
        Unit direction from ``x`` towards the emitter.

    Returns
    -------
    mi.Float64
        m (negative beyond the sphere on the light's side: only differences matter).
    """
    import drjit as dr
    import mitsuba as mi

    centre, radius = scene.emitters.far_reference()
    d = mi.Vector3d(toward_light)
    d = d / dr.norm(d)  # IEEE div and sqrt: dr.normalize of Float64 is approximate on CUDA
    return radius - dr.dot(d, mi.Vector3d(x) - mi.Vector3d(centre))


def emitter_hit_length(scene, si, length_m, index, x, direction):
    """Optical length of a path at the emitter its ray meets: ``length_m`` where the ray
    hit the surface ``si`` (its length already counts the segment), plus the plane wave's
    leg to ``x`` (:func:`plane_wave_leg_m`) where it escaped along ``direction`` to the
    environment.

    Parameters
    ----------
    scene : DynamicScene
    si : mi.SurfaceInteraction3f
        What the ray from ``x`` hit (invalid: it escaped).
    length_m : mi.Float64
        Optical length to the hit, or to ``x`` where the ray escaped, m.
    index : mi.Float
        Refractive index of the ray's segment.
    x : mi.Point3d
        The ray's origin, the path's last vertex.
    direction : mi.Vector3f

    Returns
    -------
    mi.Float64
        m.
    """
    import drjit as dr
    import mitsuba as mi

    if not scene.emitters.has_infinite:
        return length_m  # an escaped ray meets nothing: its length is never used
    return dr.select(si.is_valid(), length_m, length_m + mi.Float64(index) * plane_wave_leg_m(scene, x, direction))


def length_to_emitter(scene, length_m, index, x, ds, p_light):
    """Optical length of a path whose last vertex ``x`` connects to the emitter sample
    ``ds`` at ``p_light`` (Float64): the distance to ``p_light``, or a plane wave's
    (:func:`plane_wave_leg_m`) for an infinitely distant emitter.

    Parameters
    ----------
    scene : DynamicScene
    length_m : mi.Float64
        Optical length to ``x``, m.
    index : mi.Float
        Refractive index of the last segment.
    x : mi.Point3d
    ds : mi.DirectionSample3f
        The emitter sample.
    p_light : mi.Point3d

    Returns
    -------
    mi.Float64
        m.
    """
    import drjit as dr
    import mitsuba as mi

    leg = dr.norm(p_light - x)
    if scene.emitters.has_infinite:
        far = mi.has_flag(ds.emitter.flags(), mi.EmitterFlags.Infinite)
        leg = dr.select(far, plane_wave_leg_m(scene, x, ds.d), leg)
    return length_m + mi.Float64(index) * leg


@dataclass
class LightSample:
    """Result of :func:`sample_emitter` (all per lane).

    Parameters
    ----------
    ds : mi.DirectionSample3f
        The emitter sample.
    weight : mi.Spectrum
        Emitted radiance over the density.
    bsdf_value : mi.Spectrum
        The BSDF towards the light.
    bsdf_pdf : mi.Float
        The BSDF's density of that direction (for MIS).
    length_m : mi.Float64
        Optical length of the path through the light, m.
    active : mi.Bool
        Where the light is visible.
    """

    ds: object  # mi.DirectionSample3f
    weight: object  # emitter weight Le/p (mi.Spectrum)
    bsdf_value: object  # f·cos towards the light
    bsdf_pdf: object  # BSDF density of that direction (0 for delta lights)
    length_m: object  # Float64 optical length of the path through the light point
    active: object  # the sample counts (smooth BSDF, non-zero density, unoccluded)


def sample_emitter(scene, si, bsdf, bsdf_ctx, sample, time_s, poses, length_m, index, x, tables, active):
    """Next-event estimation at ``si`` with the uniform ``sample`` (mi.Point2f), the
    emitters (static and moving, :mod:`dopplertof.lights`) at the lane's time.

    Parameters
    ----------
    scene : DynamicScene
    si : mi.SurfaceInteraction3f
    bsdf : mi.BSDFPtr
    bsdf_ctx : mi.BSDFContext
    sample : mi.Point2f
    time_s : mi.Float64
        Each lane's time, s.
    poses : object
        The bodies' poses at the lanes' times.
    length_m : mi.Float64
        Optical length to ``x``, m.
    index : mi.Float
        Refractive index of the segment leaving ``x``.
    x : mi.Point3d
        The vertex.
    tables : MaterialTables
    active : mi.Bool

    Returns
    -------
    LightSample
    """
    import mitsuba as mi

    active = active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
    ds, weight, p_light = scene.emitters.sample(si, sample, time_s, active)
    active &= ds.pdf != 0
    active &= ~scene.occluded(si.spawn_ray_to(ds.p), time_s, active, poses=poses)
    wo = si.to_local(ds.d)
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, wo, active)
    index_out = segment_index(index, tables, bsdf, active, si.wi, wo)
    length = length_to_emitter(scene, length_m, index_out, x, ds, p_light)
    return LightSample(ds, weight, value, pdf, length, active)




def pinhole_scales(sensor):
    """(a, c): film pixels per unit of x/z and y/z in the sensor's frame, for sensors whose
    film position is a pinhole projection (perspective; thin lens through the aperture's
    centre), read off the sensor's own ``sample_direction``; None for others (orthographic).

    Parameters
    ----------
    sensor : mi.Sensor

    Returns
    -------
    tuple of (float, float) or None
    """
    import mitsuba as mi

    to_world = sensor.world_transform()
    step = 1e-3
    points = [mi.Point3f(0, 0, 1), mi.Point3f(step, 0, 1), mi.Point3f(0, step, 1)]
    try:
        uv = [image_position(sensor, to_world @ p) for p in points]
    except RuntimeError:  # no sample_direction (orthographic)
        return None
    (u0, v0), (ux, vx), (uy, vy) = ([float(c[0]) for c in (q.x, q.y)] for q in uv)
    # A cross term beyond float32 rounding (of film positions reached through a tilted
    # camera's world transform: 1e-6 px against steps of 0.02 px) is not a separable pinhole
    # projection; a bound at the rounding itself made every tilted camera's flow NaN.
    if abs(vx - v0) > 1e-3 * abs(ux - u0) or abs(uy - u0) > 1e-3 * abs(vy - v0):
        return None
    return (ux - u0) / step, (vy - v0) / step


def image_position(sensor, p_world):
    """Film position (pixels) of world points, through the sensor's own projection.

    Parameters
    ----------
    sensor : mi.Sensor
    p_world : mi.Point3f

    Returns
    -------
    mi.Point2f
    """
    import drjit as dr
    import mitsuba as mi

    it = dr.zeros(mi.Interaction3f)
    it.p = p_world
    ds, _ = sensor.sample_direction(it, mi.Point2f(0.5, 0.5))
    return ds.uv


def ground_truth(scene, hit, ray_d, depth_m, time_s, pinhole):
    """Ground-truth maps of the camera ray's hit: a dict of per-lane values (0 where no hit)
    and the hit mask. See :data:`dopplertof.outputs.OUTPUTS` for their meaning; with a
    moving camera, velocities are relative to its frame (the scene as the camera sees it).

    Parameters
    ----------
    scene : DynamicScene
    hit : Hit
        The camera ray's hit.
    ray_d : mi.Vector3f
        The camera ray's direction.
    depth_m : mi.Float64
        Distance from the aperture to the hit, m.
    time_s : mi.Float64
        Each lane's time, s.
    pinhole : tuple or None
        :func:`pinhole_scales` of the sensor (for the optical flow).

    Returns
    -------
    tuple of (dict, mi.Bool)
    """
    import drjit as dr
    import mitsuba as mi

    si = hit.si
    valid = si.is_valid()
    to_sensor = scene.sensor.world_transform().inverse()  # rest frame -> sensor (x left, y up, z forward)
    v = hit.pose.velocity(si.p)  # the hit body's rigid velocity; 0 for static geometry
    camera = scene.camera_pose(time_s)
    if camera is None:
        p_rest, v_rest = si.p, v
    else:  # relative to the moving camera: the scene as seen from its frame
        v = v - camera.velocity(si.p)
        p_rest, v_rest = camera.point_to_local(si.p), camera.vector_to_local(v)
    ray_fixed = dr.dot(si.n, v) / dr.dot(si.n, ray_d)
    v_camera = to_sensor @ mi.Vector3f(v_rest)
    if pinhole is None:  # no pinhole projection (orthographic): no flow
        flow = mi.Vector2f(dr.nan)
    else:  # d/dt of (a x/z, c y/z) in the sensor's frame; pinhole = (a, c), pinhole_scales
        p = to_sensor @ mi.Point3f(p_rest)
        z2 = dr.square(p.z)
        flow = mi.Vector2f(pinhole[0] * (v_camera.x * p.z - p.x * v_camera.z) / z2, pinhole[1] * (v_camera.y * p.z - p.y * v_camera.z) / z2)
    values = {
        "depth": mi.Float(depth_m),
        "velocity": dr.select(dr.isfinite(ray_fixed), ray_fixed, 0.0),
        "point_velocity": dr.dot(v, ray_d),
        "velocity_3d": v_camera,
        "flow": mi.Vector2f(flow),
    }
    values["instance_id"] = mi.Float(mi.Int32(hit.body)) - 1.0
    missed, _ = no_ground_truth()
    return {k: dr.select(valid, x, missed[k]) for k, x in values.items()}, valid


def no_ground_truth():
    """:func:`ground_truth` of a camera ray that hit nothing: every value 0 but the body id
    (-1), and the hit mask False (also the path loop's state before its camera ray's hit).

    Returns
    -------
    tuple of (dict, mi.Bool)
    """
    import mitsuba as mi

    zero = mi.Float(0)
    values = {"depth": zero, "velocity": zero, "point_velocity": zero, "velocity_3d": mi.Vector3f(0), "flow": mi.Vector2f(0), "instance_id": mi.Float(-1)}
    return values, mi.Bool(False)
