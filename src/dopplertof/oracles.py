"""Closed-form oracles: scenes whose D-ToF measurement is known exactly, to validate the renderer.

A diffuse plane receding along the optical axis
-----------------------------------------------

:func:`moving_plane_scene`: a large diffuse plane (reflectance ``PLANE_REFLECTANCE``) faces
a camera at the origin at ``PLANE_DISTANCE_M`` and recedes along the optical axis at speed
v; a point light of intensity ``PLANE_LIGHT_INTENSITY`` (W/sr) sits at the camera. With
direct light only (``max_depth=2``) its measurement has a closed form (original-implementation
reference §5.2): a film point seeing along d̂ sees the plane at distance
s(t) = (z0 + v t)/|d_z| (m), the round trip is L = 2 s and the radiance A = (ρ/π) I |d_z| / s²,
so a pixel holds

    (1/T) ∫₀ᵀ (g₁/2) Λ(2π h t/T + ψ + k L(t)) A(t) dt,      k = 2π f_g / c.

§5.2's one-line form assumes constant A and linear L; :func:`moving_plane_measurement_mean`
keeps both exact and integrates over the film and the exposure by Gauss-Legendre quadrature,
so its only error is the quadrature's, which refining the nodes bounds.

Translating bodies, pixel by pixel, from stock Mitsuba
------------------------------------------------------

:func:`direct_light_pixels`: the direct-light measurement of chosen pixels of any scene
dict whose shapes translate (a pinhole camera, point lights, any reconstruction filter),
integrated over the exposure by quadrature over stock ``mi.load_dict`` scenes with the
bodies baked at fixed instants (:func:`baked_scene_dict`), stock rays and shading, and W at
each ray's own optical length; unbiased, with a standard error from independent
replicates. It shares no code with the tracer, so it settles what the tracer does where
the moving plane has nothing to say: on moving outlines (:func:`moving_outline_pixels`;
``tests/test_edges.py``).
"""

from __future__ import annotations

import math

import numpy as np

PLANE_FOV_DEG = 30.0  # field of view of the camera, degrees
PLANE_DISTANCE_M = 5.0  # camera to plane at t = 0, m
PLANE_REFLECTANCE = 0.8  # diffuse albedo ρ of the plane (all channels)
PLANE_LIGHT_INTENSITY = 50.0  # point light at the camera, W/sr (all channels)
PLANE_EXPOSURE_S = 1.5e-3  # default exposure T, s


def moving_plane_scene(speed_m_s, exposure=PLANE_EXPOSURE_S, resolution=16, mover="plane", duration=None):
    """The moving-plane scene (module docstring) as a :class:`~dopplertof.scene.DynamicScene`.

    Parameters
    ----------
    speed_m_s : float, m/s. Receding speed of the plane along the optical axis (−z).
    exposure : float, s. The plane moves ``speed_m_s * exposure`` over [0, exposure]; render
        it with cameras of this exposure for :func:`moving_plane_measurement_mean` to apply.
    resolution : int. Film side, pixels (square film, box filter).
    mover : str. ``"plane"``: the plane moves; ``"camera"``: the plane stays and the
        camera, with its light attached, moves away from it at ``speed_m_s`` (the same
        relative motion, so the same measurement).
    duration : float, s, optional. How long the mover moves, from t = 0 (default
        ``exposure``; it then stands still): longer for cameras whose windows open later
        (``Camera.exposure_start``).

    The plane is the front face (z = −``PLANE_DISTANCE_M`` at t = 0) of a flattened
    40 m x 40 m cube, so that hits are on a triangle mesh.
    """
    from .loader import load_scene

    return load_scene(moving_plane_dict(speed_m_s, exposure, resolution, mover, duration))


def moving_plane_dict(speed_m_s, exposure=PLANE_EXPOSURE_S, resolution=16, mover="plane", duration=None):
    """The scene dict of :func:`moving_plane_scene`, in the dict form of
    :func:`dopplertof.load_scene` (for :func:`direct_light_pixels`, which bakes it).

    Parameters
    ----------
    speed_m_s : float, m/s
        Receding speed of the plane (or of the camera) along the optical axis.
    exposure : float, s, default ``PLANE_EXPOSURE_S``
        The mover moves over [0, exposure] unless ``duration`` says otherwise.
    resolution : int, default 16
        Film side, pixels (square film, box filter).
    mover : str, default "plane"
        ``"plane"`` or ``"camera"`` (see :func:`moving_plane_scene`).
    duration : float, s, optional
        How long the mover moves, from t = 0 (default ``exposure``).

    Returns
    -------
    dict
        The scene dict (the variant set first if none is: it holds Mitsuba transforms).

    Raises
    ------
    ValueError
        For a ``mover`` other than ``"plane"`` or ``"camera"``.
    """
    from .backend import ensure_variant

    ensure_variant()
    import mitsuba as mi

    # Keys in double precision: a float32 5.5 m translation is quantised to 0.5 µm, which
    # would misstate a 15 µm displacement by up to 1.6 %.
    if mover not in ("plane", "camera"):
        raise ValueError(f"mover must be 'plane' or 'camera', got {mover!r}")
    duration = exposure if duration is None else duration
    plane = mi.ScalarTransform4d().translate([0, 0, -PLANE_DISTANCE_M - 0.5]) @ mi.ScalarTransform4d().scale([20, 20, 0.5])
    look = mi.ScalarTransform4d().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0])
    shift = mi.ScalarTransform4d().translate([0, 0, -speed_m_s * duration])
    light = {"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": [PLANE_LIGHT_INTENSITY] * 3}}
    sensor = {"type": "perspective", "fov": PLANE_FOV_DEG, "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}}}
    plane = {"type": "cube", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [PLANE_REFLECTANCE] * 3}}, "to_world": plane}
    scene = {"type": "scene", "sensor": sensor, "plane": plane}
    if mover == "plane":
        sensor["to_world"] = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0])
        start = plane.pop("to_world")
        plane["motion"] = {"type": "keyframes", "keys": [(0.0, start), (duration, shift @ start)]}
        scene["light"] = light
    else:  # the camera recedes from the plane, with its light (in its frame, at the aperture)
        sensor["motion"] = {"type": "keyframes", "keys": [(0.0, look), (duration, shift.inverse() @ look)]}
        sensor["light"] = light
    return scene


def _gauss_legendre_01(panels, order):
    """Nodes and weights of composite Gauss-Legendre quadrature on [0, 1]: ``panels`` equal
    panels of ``order`` nodes each (order 1 is the midpoint rule)."""
    x, w = np.polynomial.legendre.leggauss(order)
    edges = np.arange(panels)[:, None] / panels
    nodes = (edges + 0.5 * (x[None] + 1.0) / panels).ravel()
    weights = np.tile(0.5 * w / panels, panels)
    return nodes, weights


def moving_plane_measurement_mean(camera, speed_m_s, nodes_xy=48, time_panels=64, time_order=8):
    """Exact image mean of the moving plane's direct-light measurement (module docstring).

    Parameters
    ----------
    camera : dopplertof.Camera (low-pass model; any waveform). Its window,
        [``exposure_start`` (None: 0), + ``exposure``] (s), must lie in the plane's motion
        (:func:`moving_plane_scene`'s ``duration``).
    speed_m_s : float, m/s. Receding speed of the plane.
    nodes_xy : int. Gauss-Legendre nodes per film axis.
    time_panels, time_order : int. Composite Gauss-Legendre over the exposure: ``time_panels``
        panels of ``time_order`` nodes (the sinusoid converges with few panels; the kinked
        waveforms need many).

    Returns
    -------
    float : the image mean, in the units of ``RenderResult.measurements`` (radiance, W sr⁻¹ m⁻²,
        times the dimensionless correlation weight).
    """
    return float(moving_plane_measurement_pixels(camera, speed_m_s, 1, nodes_xy, time_panels, time_order)[0, 0])


def moving_plane_measurement_pixels(camera, speed_m_s, resolution, nodes_per_pixel=6, time_panels=64, time_order=8):
    """Exact per-pixel values (resolution × resolution) of the moving plane's direct-light
    measurement with a box filter: Gauss-Legendre over each pixel and the exposure (see
    :func:`moving_plane_measurement_mean` for the parameters).

    Parameters
    ----------
    camera : dopplertof.Camera
        As for :func:`moving_plane_measurement_mean`.
    speed_m_s : float, m/s
        Receding speed of the plane.
    resolution : int
        Film size in pixels (square).
    nodes_per_pixel : int, default 6
        Gauss-Legendre nodes per pixel along each film axis.
    time_panels, time_order : int, default 64 and 8
        Composite Gauss-Legendre over the exposure (:func:`moving_plane_measurement_mean`).

    Returns
    -------
    ndarray
        (resolution, resolution) float64, in the units of ``RenderResult.measurements``.
    """
    from .modulation import lowpass_weight

    tau = math.tan(math.radians(PLANE_FOV_DEG) / 2)
    f, w = _gauss_legendre_01(resolution, nodes_per_pixel)  # nodes_per_pixel in each pixel
    fx, fy = np.meshgrid(f, f, indexing="ij")
    cos_axis = 1.0 / np.sqrt(((2 * fx - 1) * tau) ** 2 + ((2 * fy - 1) * tau) ** 2 + 1.0).ravel()
    u, w_t = _gauss_legendre_01(time_panels, time_order)
    start_s = camera.window()[0]  # the default render window opens at 0
    field = np.zeros(cos_axis.size)
    for chunk in range(0, u.size, 256):  # bounded memory: 256 times x the film's nodes at once
        uc = u[chunk:chunk + 256, None]
        s = (PLANE_DISTANCE_M + speed_m_s * (start_s + camera.exposure * uc)) / cos_axis[None]
        radiance = PLANE_REFLECTANCE / math.pi * PLANE_LIGHT_INTENSITY * cos_axis[None] / s**2
        phase = 2 * math.pi * camera.heterodyne * uc + camera.phase + camera.wavenumber * 2 * s
        integrand = lowpass_weight(camera, phase) * radiance
        field += w_t[chunk:chunk + 256] @ integrand
    n = nodes_per_pixel
    weights = (w * resolution).reshape(resolution, n)  # each pixel's nodes average to 1
    blocks = field.reshape(resolution, n, resolution, n)
    return np.einsum("anbm,an,bm->ab", blocks, weights, weights).T


# ----------------------------------------------------------------------------------------
# Moving outlines: the exposure integral by quadrature over stock renders at fixed instants


def _matrix(transform):
    """A keyframe's transform (Mitsuba transform or 4x4 array) as a float64 4x4 array."""
    return np.asarray(getattr(transform, "matrix", transform), dtype=np.float64).reshape(4, 4)


def baked_scene_dict(scene_dict, time_s):
    """A stock ``mi.load_dict`` scene dict with every keyframed shape at its pose at ``time_s``.

    The shapes' ``"motion"`` entries (keyframes whose transforms differ by translations
    only: a translating rigid body) are replaced by the ``to_world`` at ``time_s``, the
    translation interpolated linearly between the bracketing keys and held before the
    first and after the last key, as :mod:`dopplertof.motion` does. It is written here
    again on purpose, so that the oracle does not share the renderer's motion code.

    Parameters
    ----------
    scene_dict : dict
        A scene in the dict form of :func:`dopplertof.load_scene` (for example
        :func:`dopplertof.scenes.cornell_box_dict`).
    time_s : float, s
        The instant of scene time.

    Returns
    -------
    dict
        The same scene, every entry shared except the moving shapes' (copied and baked).

    Raises
    ------
    ValueError
        For a motion that is not keyframed or whose keys rotate or scale (naming the
        entry), a moving sensor or emitter, and a ``time_s`` that is not a finite number.
    """
    import mitsuba as mi

    from .validation import checked

    time_s = checked("time_s", time_s, "float", "baked_scene_dict")
    baked = dict(scene_dict)
    for name, entry in scene_dict.items():
        if not isinstance(entry, dict) or "motion" not in entry:
            continue
        if entry.get("type") in ("perspective", "thinlens", "orthographic", "point", "spot"):
            raise ValueError(f"baked_scene_dict: {name!r} is a moving sensor or emitter; only shapes may move")
        motion = entry["motion"]
        if not isinstance(motion, dict) or motion.get("type") != "keyframes":
            raise ValueError(f"baked_scene_dict: {name!r} has motion {motion!r}; only keyframes are supported")
        times = np.array([float(t) for t, _ in motion["keys"]])
        matrices = np.stack([_matrix(m) for _, m in motion["keys"]])
        if np.any(np.abs(matrices[:, :3, :3] - matrices[:1, :3, :3]) > 1e-7 * np.abs(matrices[:1, :3, :3]).max()):
            raise ValueError(f"baked_scene_dict: the keys of {name!r} rotate or scale; only translations are supported")
        pose = matrices[0].copy()
        pose[:3, 3] = [np.interp(time_s, times, matrices[:, i, 3]) for i in range(3)]
        shape = {k: v for k, v in entry.items() if k != "motion"}
        shape["to_world"] = mi.ScalarTransform4f(pose.astype(np.float32))
        baked[name] = shape
    return baked


class _Footprint:
    """Where a pixel's film positions lie and how they are weighted: Mitsuba's pixel
    estimate converges to ∫∫ f(x − c) f(y − c') L / ∫∫ f f over the film (c, c' the pixel's
    centre, f the reconstruction filter); the box filter is the uniform average over the
    pixel. Stock ``rfilter.eval`` gives f; its integral over the part of the support inside
    the film, per pixel column and row, by a fine midpoint rule."""

    NORM_NODES = 8192

    def __init__(self, scene_dict):
        import mitsuba as mi

        _, sensor, _ = _stock_scene(scene_dict, 0.0)
        film = sensor.film()
        self.size = tuple(int(v) for v in film.crop_size())
        self.rfilter = film.rfilter()
        self.box = bool(self.rfilter.is_box_filter())
        self.radius = 0.5 if self.box else float(self.rfilter.radius())
        if not self.box:
            self.norms = []
            for n in self.size:
                centres = np.arange(n) + 0.5
                lo, hi = np.maximum(-self.radius, -centres), np.minimum(self.radius, n - centres)
                x = lo[:, None] + (hi - lo)[:, None] * (np.arange(self.NORM_NODES) + 0.5) / self.NORM_NODES
                f = np.asarray(self.rfilter.eval(mi.Float(x.ravel().astype(np.float32))), dtype=np.float64).reshape(x.shape)
                self.norms.append(f.mean(axis=1) * (hi - lo))

    def positions(self, pixels, offsets):
        """Film positions (..., 2; pixels) of ``offsets`` in [0, 1)² of the filter's
        support around ``pixels`` (n, 2), and each one's weight in its pixel's estimate
        (the mean of weight × value over uniform offsets is the pixel's value)."""
        import mitsuba as mi

        span = 2.0 * self.radius
        xy = pixels + 0.5 + (offsets - 0.5) * span
        if self.box:
            return xy, np.ones(xy.shape[:-1])
        o = (offsets - 0.5) * span
        f = np.asarray(self.rfilter.eval(mi.Float(o.ravel().astype(np.float32))), dtype=np.float64).reshape(o.shape)
        inside = np.all((xy >= 0) & (xy < self.size), axis=-1)
        norm = self.norms[0][pixels[:, 0].astype(int)] * self.norms[1][pixels[:, 1].astype(int)]
        return xy, np.where(inside, f[..., 0] * f[..., 1] * span * span / norm, 0.0)


def _stock_scene(scene_dict, time_s):
    """(stock mi.Scene at ``time_s``, its sensor, the shapes that move) with the checks
    the oracle's model of the measurement needs."""
    import mitsuba as mi

    scene = mi.load_dict(baked_scene_dict(scene_dict, time_s), optimize=False)  # unmerged: the moving shapes keep their ids
    sensor = scene.sensors()[0]
    if sensor.class_name() != "PerspectiveCamera":
        raise ValueError("scene_dict: the outline oracle needs a perspective (pinhole) camera")
    if not all(mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition) for e in scene.emitters()):
        raise ValueError("scene_dict: the outline oracle needs point lights only (its light paths are camera, surface, light)")
    moving = {name for name, entry in scene_dict.items() if isinstance(entry, dict) and "motion" in entry}
    return scene, sensor, [s for s in scene.shapes() if s.id() in moving]


def _trace_instant(scene, sensor, moving, film_xy, time_s):
    """Per film position (n, 2; pixels): (luminance of the direct light, optical length m,
    hits a moving shape) in the stock ``scene`` at ``time_s``."""
    import drjit as dr
    import mitsuba as mi

    width, height = (int(v) for v in sensor.film().crop_size())
    position = mi.Point2f(mi.Float((film_xy[:, 0] / width).astype(np.float32)), mi.Float((film_xy[:, 1] / height).astype(np.float32)))
    ray, ray_weight = sensor.sample_ray(mi.Float(time_s), mi.Float(0.5), position, mi.Point2f(0.5))
    si = scene.ray_intersect(ray)
    valid = si.is_valid()
    ds, emitter_weight = scene.sample_emitter_direction(si, mi.Point2f(0.5), True, valid)
    bsdf_value = si.bsdf(ray).eval(mi.BSDFContext(), si, si.to_local(ds.d), valid)
    luminance = dr.select(valid & (ds.pdf > 0), mi.luminance(ray_weight * emitter_weight * bsdf_value), 0.0)
    on_moving = mi.Bool(False)
    for shape in moving:
        on_moving |= valid & (si.shape == mi.ShapePtr(shape))
    dr.eval(luminance, si.p, ds.dist, on_moving)  # one kernel: converting each unevaluated output would trace again
    eye = np.asarray(sensor.world_transform().translation(), dtype=np.float64).reshape(3)
    p = np.stack([np.asarray(c, dtype=np.float64) for c in (si.p.x, si.p.y, si.p.z)], axis=1)
    length_m = np.linalg.norm(p - eye, axis=1) + np.asarray(ds.dist, dtype=np.float64)
    return np.asarray(luminance, dtype=np.float64), length_m, np.asarray(on_moving, dtype=bool)


def moving_outline_pixels(scene_dict, start_s, end_s, grid=16):
    """The pixels on the outlines of the moving shapes: partly covered by one at the
    exposure's start or end, or covered differently at the two.

    Parameters
    ----------
    scene_dict : dict
        As for :func:`baked_scene_dict` (a pinhole camera, point lights).
    start_s, end_s : float, s
        The exposure's ends in scene time.
    grid : int, default 16
        Film positions per pixel side at which coverage is tested (centres of a grid).

    Returns
    -------
    numpy.ndarray, int, shape (n, 2)
        (x, y) of the outline pixels, row-major order.

    Raises
    ------
    ValueError
        For a ``grid`` below 1, times that are not finite numbers, and the scenes
        :func:`direct_light_pixels` refuses.
    """
    from .validation import checked

    if checked("grid", grid, "int", "moving_outline_pixels") < 1:
        raise ValueError(f"moving_outline_pixels: 'grid' must be >= 1, got {grid!r}")
    start_s, end_s = (checked(name, value, "float", "moving_outline_pixels") for name, value in (("start_s", start_s), ("end_s", end_s)))
    coverage = []
    for time_s in (start_s, end_s):
        scene, sensor, moving = _stock_scene(scene_dict, time_s)
        width, height = (int(v) for v in sensor.film().crop_size())
        offsets = (np.arange(grid) + 0.5) / grid
        y, x, oy, ox = np.meshgrid(np.arange(height), np.arange(width), offsets, offsets, indexing="ij")
        xy = np.stack([(x + ox).ravel(), (y + oy).ravel()], axis=1)
        hits = _trace_instant(scene, sensor, moving, xy, time_s)[2]
        coverage.append(hits.reshape(height, width, grid * grid).mean(axis=2))
    a, b = coverage
    outline = ((a > 0) & (a < 1)) | ((b > 0) & (b < 1)) | (a != b)
    y, x = np.nonzero(outline)
    return np.stack([x, y], axis=1)


def direct_light_pixels(scene_dict, cameras, pixels, *, time_strata=8, grid=16, replicates=16, seed=0, frozen_at_s=None):
    """The direct-light D-ToF measurement of chosen pixels by quadrature over stock
    Mitsuba scenes at fixed instants, with its standard error.

    A pixel holds (1/T)∫ dt ∫ w(x) W(u, L(x, t)) X(x, t) dx, u = (t − t₀)/T, w the film's
    reconstruction filter about the pixel's centre normalised over the film (the box
    filter: the uniform average over the pixel; :class:`_Footprint`), X the luminance of the light reaching film position x from a point light over one
    bounce and L that path's optical length (from the pinhole). Each replicate takes
    2J instants, u = (j + ξ)/J and its mirror image (j + 1 − ξ)/J for j < J =
    ``time_strata``, with one uniform random shift ξ; at each instant the scene is baked
    (:func:`baked_scene_dict`) and loaded by stock ``mi.load_dict``, and the pixel
    integral is a ``grid`` × ``grid`` jittered-stratified sum over the filter's support
    (fresh jitter at each instant) of stock camera rays, intersections, emitter samples and BSDF evaluations,
    each weighted by :func:`dopplertof.modulation.lowpass_weight` at its own L (the
    weight is the one piece shared with the renderer; the tests check it against closed
    forms of its own). Every instant is uniform in
    its stratum and every film position in its cell, so each replicate is unbiased; the
    spread of ``replicates`` independent ones is the standard error. The pixel integral
    at an instant is smooth in time (the outline sweeps the pixel continuously). Each
    half of the rule integrates trigonometric polynomials of degree < J exactly (W over
    a still region, for an integer h, is one), and the mirror pairs cancel the linear
    part of what is not periodic (the outlines' motion, a non-integer h), so the error
    left falls as J⁻², not J⁻¹. Stock scenes hold float32 positions (0.5 µm steps at
    5 m): meant for displacements of millimetres, not micrometres.

    Parameters
    ----------
    scene_dict : dict
        As for :func:`baked_scene_dict`: a pinhole camera, any reconstruction filter,
        point lights, shapes translated by keyframes. Equal to ``dt.render(..., max_depth=2)`` of
        ``dt.load_scene(scene_dict)`` in expectation.
    cameras : list of dopplertof.Camera
        Low-pass cameras of one exposure window (``Camera.window``; default start 0 s).
    pixels : array_like of int, shape (n, 2)
        (x, y) of the pixels (for example :func:`moving_outline_pixels`).
    time_strata : int, default 8
        J: each replicate takes 2J instants (above).
    grid : int, default 16
        Film positions per side of the filter's support at each instant.
    replicates : int, default 16
        Independent replicates (at least 2).
    seed : int, default 0
        Seed of the jitter (numpy).
    frozen_at_s : float or None, s, default None
        If given, the shapes stay at their pose at this instant while W still runs
        over the exposure: the measurement of a renderer whose geometry ignores the
        motion, to show that a comparison resolves the outlines' motion.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray), each float64 of shape (n_cameras, n)
        The measurement (units of ``RenderResult.measurements``) and its standard error.

    Raises
    ------
    ValueError
        For cameras of different windows or in the full-waveform model, fewer than 2
        replicates, ``time_strata`` or ``grid`` below 1, pixels off the film, a scene
        other than a pinhole camera lit by point lights, and the
        scenes :func:`baked_scene_dict` refuses.
    """
    from .modulation import lowpass_phase, lowpass_weight
    from .validation import checked

    cameras = list(cameras)
    windows = {camera.window() for camera in cameras}
    if len(windows) != 1 or any(not camera.low_pass for camera in cameras):
        raise ValueError(f"direct_light_pixels: cameras must be low-pass and share one exposure window, got {cameras!r}")
    for name, value, minimum in (("replicates", replicates, 2), ("time_strata", time_strata, 1), ("grid", grid, 1)):
        if checked(name, value, "int", "direct_light_pixels") < minimum:
            why = " (the standard error needs a spread)" if name == "replicates" else ""
            raise ValueError(f"direct_light_pixels: {name!r} must be >= {minimum}{why}, got {value!r}")
    (start_s, exposure_s), = windows
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    footprint = _Footprint(scene_dict)
    width, height = footprint.size
    if len(pixels) == 0 or np.any((pixels < 0) | (pixels >= [width, height]) | (pixels != np.round(pixels))):
        raise ValueError(f"direct_light_pixels: 'pixels' must be (x, y) integer pairs on the {width}x{height} film, got {pixels.tolist()!r}")
    rng = np.random.default_rng(seed)
    cells = (np.arange(grid * grid)[:, None] // grid, np.arange(grid * grid)[:, None] % grid)
    estimates = np.zeros((replicates, len(cameras), len(pixels)))
    for r in range(replicates):
        shift = rng.random()
        instants = np.concatenate([np.arange(time_strata) + shift, np.arange(time_strata) + 1.0 - shift]) / time_strata
        for u in instants:
            time_s = start_s + u * exposure_s
            scene, sensor, moving = _stock_scene(scene_dict, time_s if frozen_at_s is None else frozen_at_s)
            jitter = rng.random((grid * grid, len(pixels), 2))
            offsets = np.stack([(cells[1] + jitter[..., 0]) / grid, (cells[0] + jitter[..., 1]) / grid], axis=-1)
            xy, weight = footprint.positions(pixels, offsets)
            luminance, length_m, _ = _trace_instant(scene, sensor, moving, xy.reshape(-1, 2), time_s)
            luminance = luminance * weight.ravel()
            for c, camera in enumerate(cameras):
                value = lowpass_weight(camera, lowpass_phase(camera, u, length_m)) * luminance
                estimates[r, c] += value.reshape(grid * grid, len(pixels)).mean(axis=0) / len(instants)
    return estimates.mean(axis=0), estimates.std(axis=0, ddof=1) / math.sqrt(replicates)
