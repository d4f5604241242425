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
    from .backend import ensure_variant
    from .loader import load_scene

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
    return load_scene(scene)


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
