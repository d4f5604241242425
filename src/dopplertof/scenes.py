"""Built-in procedural scenes (no downloads).

``SCENES`` maps a name to (builder, description); :func:`build` builds one by name and
:func:`clip_duration` gives the length of its motion (s), the default length of an
animation (frame ``i`` renders the exposure [i/fps, i/fps + T]).

=====================  ==============================================================
name                   what moves
=====================  ==============================================================
``cornell-box``        the original D-ToF Cornell box, boxes at −10 and +10 m/s
``cornell-box-area``   the same, lit by a ceiling area light
``rotating``           a merry-go-round: platform and four objects about a vertical axis
``falling-box``        a tumbling box dropped under gravity onto the floor
``dominoes``           a chain of dominoes toppling one after another
``glossy``             rough/smooth conductors, a rolling glass sphere, diffuse walls
``street``             the camera itself, on a car in traffic: cars, pedestrians, a
                       cyclist (``STREET_MOVING_BODIES``); automotive modulation (150 MHz, 1 ms)
=====================  ==============================================================

Every builder returns a :class:`~dopplertof.scene.DynamicScene` and takes ``resolution``
(pixels, square film) plus scene-specific keyword arguments in SI units. Each is lit by
a point light at the camera (the D-ToF camera's co-located source; in ``street`` attached
to the moving camera), in ``glossy`` one more overhead.
:func:`clip_duration` takes the same keyword arguments as the builder, so an animation of
a modified scene gets the matching length.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import math
import os

import numpy as np

WHITE = [0.725, 0.71, 0.68]
RED = [0.63, 0.065, 0.05]
GREEN = [0.14, 0.45, 0.091]
GREY = [0.4, 0.4, 0.4]
BLUE = [0.1, 0.2, 0.6]
YELLOW = [0.75, 0.6, 0.1]
ORANGE = [0.8, 0.35, 0.05]

STANDARD_GRAVITY_M_S2 = 9.81
CORNELL_EXPOSURE_S = 1.5e-3


# ----------------------------------------------------------------------------------------
# Building blocks


def _transform(translate=(0, 0, 0), rotate_y_deg=0.0, scale=(1, 1, 1), rotate_x_deg=0.0):
    import mitsuba as mi

    t = mi.ScalarTransform4f().translate(list(translate))
    t = t @ mi.ScalarTransform4f().rotate([0, 1, 0], rotate_y_deg) @ mi.ScalarTransform4f().rotate([1, 0, 0], rotate_x_deg)
    return t @ mi.ScalarTransform4f().scale(list(scale))


def _diffuse(rgb):
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb)}}


def _sensor(origin, target, fov_deg, resolution, up=(0, 1, 0)):
    import mitsuba as mi

    if not isinstance(resolution, (int, np.integer)) or isinstance(resolution, bool) or resolution <= 0:
        raise ValueError(f"resolution must be a positive integer, got {resolution!r}")
    return {
        "type": "perspective",
        "fov": fov_deg,
        "to_world": mi.ScalarTransform4f().look_at(origin=list(origin), target=list(target), up=list(up)),
        "film": {"type": "hdrfilm", "width": int(resolution), "height": int(resolution), "rfilter": {"type": "box"}},
    }


def _point_light(position, intensity):
    """Isotropic point light (intensity in W/sr, as Mitsuba's ``point``)."""
    return {"type": "point", "position": [float(v) for v in position], "intensity": {"type": "rgb", "value": [float(intensity)] * 3}}


def _floor(half_size, rgb=GREY):
    """Square floor in the plane y = 0, facing up, ``half_size`` m from the origin to an edge."""
    return {"type": "rectangle", "to_world": _transform(rotate_x_deg=-90, scale=(half_size, half_size, 1)), "bsdf": _diffuse(rgb)}


def _checker_floor(half_size, light=(0.75, 0.75, 0.75), dark=(0.25, 0.25, 0.25)):
    """Floor of :func:`_floor` with a checkerboard of 0.5 m squares."""
    checks = 2.0 * half_size  # the checkerboard texture has 2 × 2 squares per unit of uv
    reflectance = {
        "type": "checkerboard",
        "color0": {"type": "rgb", "value": list(light)},
        "color1": {"type": "rgb", "value": list(dark)},
        "to_uv": _transform(scale=(checks, checks, 1.0)),
    }
    return {**_floor(half_size), "bsdf": {"type": "diffuse", "reflectance": reflectance}}


def _positive(name, value):
    """``value`` as a float, or ValueError unless it is a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _translation_keys(matrix, displacement, exposure):
    """Keyframes moving ``matrix`` by ``displacement`` (m) over [0, exposure] s."""
    import mitsuba as mi

    end = mi.ScalarTransform4f().translate(list(displacement)) @ matrix
    return {"type": "keyframes", "keys": [(0.0, matrix), (exposure, end)]}


def _load(scene):
    from .loader import load_scene

    return load_scene(scene)


# ----------------------------------------------------------------------------------------
# Cornell box



def _builtin(name: str):
    """Decorate the builder of built-in scene ``name``: the scene it returns knows how to be
    built again (``recipe``, for Ray workers) and what it is (``content_digest``, for
    checkpoints and clips), however the builder was called."""

    def decorate(builder):
        signature = inspect.signature(builder)

        @functools.wraps(builder)
        def built(*args, **kwargs):
            scene = builder(*args, **kwargs)
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()  # the same scene, however its arguments were given
            arguments = dict(bound.arguments)
            scene.recipe = ("builtin", name, arguments)
            scene.content_digest = hashlib.sha256(json.dumps(["builtin", name, arguments], sort_keys=True, default=repr).encode()).hexdigest()
            return scene

        return built

    return decorate


@_builtin("cornell-box")
def cornell_box(resolution=256, light="point", exposure=CORNELL_EXPOSURE_S, displacement=0.015):
    """The original D-ToF Cornell box (its dict: :func:`cornell_box_dict`).

    Room [−1, 1] × [0, 2] × [−1, 1] m; camera at (0, 1, 6.8) looking down −z, fov 19.5°;
    a point light (intensity 100) at the camera (``light="point"``) or an area light in the
    ceiling (``light="area"``). Over [0, exposure] the short box moves ``displacement`` m
    in +z (towards the camera, −10 m/s by default) and the tall box the same distance in −z
    (away, +10 m/s).

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    light : str, default "point"
        ``"point"`` (at the camera) or ``"area"`` (in the ceiling).
    exposure : float, s, default 1.5e-3
        Exposure T: the sensor's shutter interval, over which the boxes move.
    displacement : float, m, default 0.015
        How far each box moves during the exposure (speed = displacement / exposure).

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).

    Examples
    --------
    >>> import dopplertof as dt
    >>> len(dt.scenes.cornell_box(resolution=16).bodies)
    2
    """
    return _load(cornell_box_dict(resolution, light, exposure, displacement))


def cornell_box_dict(resolution=256, light="point", exposure=CORNELL_EXPOSURE_S, displacement=0.015):
    """The scene dict of :func:`cornell_box`, in ``mi.load_dict`` form with the boxes'
    ``"motion"`` entries, for :func:`dopplertof.load_scene` or for baking the boxes at one
    instant (:func:`dopplertof.oracles.baked_scene_dict`).

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    light : str, default "point"
        ``"point"`` (at the camera) or ``"area"`` (in the ceiling).
    exposure : float, s, default 1.5e-3
        Exposure T, over which the boxes move.
    displacement : float, m, default 0.015
        How far each box moves during the exposure.

    Returns
    -------
    dict
        The scene dict (the variant set first if none is: it holds Mitsuba transforms).

    Raises
    ------
    ValueError
        For a ``light`` other than ``"point"`` or ``"area"``, or a ``resolution`` that is
        not a positive integer.
    """
    from .backend import ensure_variant

    ensure_variant()
    if light not in ("point", "area"):
        raise ValueError(f"light must be 'point' or 'area', got {light!r}")
    scene = {
        "type": "scene",
        "sensor": _sensor((0, 1, 6.8), (0, 1, 0), 19.5, resolution),
        "floor": {"type": "rectangle", "to_world": _transform((0, 0, 0), rotate_x_deg=-90), "bsdf": _diffuse(WHITE)},
        "ceiling": {"type": "rectangle", "to_world": _transform((0, 2, 0), rotate_x_deg=90), "bsdf": _diffuse(WHITE)},
        "back": {"type": "rectangle", "to_world": _transform((0, 1, -1)), "bsdf": _diffuse(WHITE)},
        "red-wall": {"type": "rectangle", "to_world": _transform((-1, 1, 0), rotate_y_deg=90), "bsdf": _diffuse(RED)},
        "green-wall": {"type": "rectangle", "to_world": _transform((1, 1, 0), rotate_y_deg=-90), "bsdf": _diffuse(GREEN)},
    }
    short = _transform((0.33, 0.3, 0.37), rotate_y_deg=-17, scale=(0.3, 0.3, 0.3))
    tall = _transform((-0.33, 0.6, -0.29), rotate_y_deg=17, scale=(0.3, 0.6, 0.3))
    scene["short-box"] = {"type": "cube", "bsdf": _diffuse(WHITE), "motion": _translation_keys(short, (0, 0, displacement), exposure)}
    scene["tall-box"] = {"type": "cube", "bsdf": _diffuse(WHITE), "motion": _translation_keys(tall, (0, 0, -displacement), exposure)}
    if light == "point":
        scene["light"] = _point_light((0.0, 1.0, 6.8), 100.0)
    else:
        scene["light"] = {
            "type": "rectangle",
            "to_world": _transform((0, 1.99, 0), rotate_x_deg=90, scale=(0.25, 0.2, 1)),
            "bsdf": _diffuse(WHITE),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [17.0, 12.0, 4.0]}},
        }
    return scene


@_builtin("cornell-box-area")
def cornell_box_area(resolution=256, exposure=CORNELL_EXPOSURE_S, displacement=0.015):
    """The Cornell box of :func:`cornell_box` lit by a ceiling area light.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    exposure : float, s, default 1.5e-3
        Exposure T (see :func:`cornell_box`).
    displacement : float, m, default 0.015
        How far each box moves during the exposure.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    return cornell_box(resolution, light="area", exposure=exposure, displacement=displacement)


def _cornell_clip(exposure, **_):
    return _positive("exposure", exposure)


# ----------------------------------------------------------------------------------------
# Merry-go-round

ROTATING_PLATFORM_HEIGHT_M = 0.25


@_builtin("rotating")
def rotating(resolution=256, radius=1.2, rim_speed=3.0):
    """A merry-go-round: a round platform and four objects spinning about a vertical axis.

    The platform (radius ``radius`` m, 0.25 m high, centred on the origin) turns
    counter-clockwise seen from above (angular velocity +y) with ``rim_speed`` m/s at its
    rim, so ω = rim_speed / radius rad/s; a red cube, a green sphere, a yellow post and a
    blue sphere ride on it at 0.8 · radius. Camera at (0, 2.4, 4.4) looking at
    (0, 0.35, 0), fov 40°, point light at the camera; grey floor. The motion is parametric
    (unbounded); its clip is one revolution, 2π · radius / rim_speed s.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    radius : float, m, default 1.2
        Radius of the platform.
    rim_speed : float, m/s, default 3.0
        Speed of the platform's rim.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    from .backend import ensure_variant

    ensure_variant()
    radius = _positive("radius", radius)
    omega = _positive("rim_speed", rim_speed) / radius
    camera = (0.0, 2.4, 4.4)
    top = ROTATING_PLATFORM_HEIGHT_M
    ring = 0.8 * radius
    spin = {"type": "parametric", "angular_velocity": [0.0, omega, 0.0], "pivot": [0.0, 0.0, 0.0]}

    def rider(angle_deg):
        """Position on the ring at ``angle_deg`` counter-clockwise from +x seen from above."""
        a = math.radians(angle_deg)
        return ring * math.cos(a), ring * -math.sin(a)

    def riding(shape):
        return {**shape, "motion": dict(spin)}

    (x0, z0), (x1, z1), (x2, z2), (x3, z3) = rider(0), rider(90), rider(180), rider(270)
    scene = {
        "type": "scene",
        "sensor": _sensor(camera, (0.0, 0.35, 0.0), 40.0, resolution),
        "floor": _floor(12.0),
        "platform-top": riding(
            {"type": "disk", "to_world": _transform((0, top, 0), rotate_x_deg=-90, scale=(radius, radius, 1)), "bsdf": _diffuse(WHITE)}
        ),
        "platform-side": riding({"type": "cylinder", "p0": [0, 0, 0], "p1": [0, top, 0], "radius": radius, "bsdf": _diffuse(RED)}),
        "red-cube": riding({"type": "cube", "to_world": _transform((x0, top + 0.2, z0), rotate_y_deg=20, scale=(0.2, 0.2, 0.2)), "bsdf": _diffuse(RED)}),
        "green-sphere": riding({"type": "sphere", "center": [x1, top + 0.22, z1], "radius": 0.22, "bsdf": _diffuse(GREEN)}),
        "yellow-post": riding({"type": "cube", "to_world": _transform((x2, top + 0.35, z2), scale=(0.12, 0.35, 0.12)), "bsdf": _diffuse(YELLOW)}),
        "blue-sphere": riding({"type": "sphere", "center": [x3, top + 0.18, z3], "radius": 0.18, "bsdf": _diffuse(BLUE)}),
        "light": _point_light(camera, 160.0),
    }
    return _load(scene)


def _rotating_clip(radius, rim_speed, **_):
    return 2.0 * math.pi * _positive("radius", radius) / _positive("rim_speed", rim_speed)


# ----------------------------------------------------------------------------------------
# Falling box


def fall_time(drop_height, gravity=STANDARD_GRAVITY_M_S2):
    """Time (s) to fall ``drop_height`` m from rest under ``gravity`` m/s².

    Parameters
    ----------
    drop_height : float, m
    gravity : float, m/s², default 9.81

    Returns
    -------
    float
        Seconds.
    """
    return math.sqrt(2.0 * _positive("drop_height", drop_height) / _positive("gravity", gravity))


@_builtin("falling-box")
def falling_box(resolution=256, drop_height=1.5, size=0.5, gravity=STANDARD_GRAVITY_M_S2, spin_deg=90.0, keyframes=24):
    """A box dropped from rest that tumbles and lands flat on the floor.

    The box (edge ``size`` m, centre above (0, ·, 0)) starts at rest with its bottom
    ``drop_height`` m above the floor and falls under ``gravity`` m/s², turning at a
    constant rate about the x axis by ``spin_deg`` degrees in all (a multiple of 90 lands
    it flat). The fall lasts ``fall_time(drop_height, gravity)`` s (0.55 s by default;
    5.4 m/s at impact) and is keyframed at ``keyframes`` + 1 equally spaced times, so the
    velocity is piecewise constant: g · t at the middle of each interval. A white block
    stands beside it on a checkered floor, a wall behind. Camera at (0, 2.6, 3.6) looking
    at (0, 0.9, 0), fov 40°, point light at the camera.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    drop_height : float, m, default 1.5
        Height of the box's bottom above the floor at t = 0.
    size : float, m, default 0.5
        Edge of the box.
    gravity : float, m/s², default 9.81
        Gravitational acceleration.
    spin_deg : float, degrees, default 90
        Rotation about the x axis over the fall.
    keyframes : int, default 24
        Keyframe intervals over the fall.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    from .backend import ensure_variant

    ensure_variant()
    duration = fall_time(drop_height, gravity)
    half = 0.5 * _positive("size", size)
    if isinstance(keyframes, bool) or not isinstance(keyframes, (int, np.integer)) or keyframes < 1:
        raise ValueError(f"keyframes must be a positive integer (intervals of the fall), got {keyframes!r}")
    if not isinstance(spin_deg, (int, float)) or not math.isfinite(spin_deg):
        raise ValueError(f"spin_deg must be a finite number of degrees, got {spin_deg!r}")
    # Slerp takes the short arc: a key interval must turn the box by less than 180°.
    if abs(spin_deg) / keyframes >= 180.0:
        raise ValueError(f"spin_deg={spin_deg!r} is too much for {keyframes} keyframe intervals (< 180° each)")
    start_y = float(drop_height) + half
    keys = []
    for t in np.linspace(0.0, duration, int(keyframes) + 1):
        y = start_y - 0.5 * gravity * t * t
        angle = spin_deg * t / duration
        keys.append((float(t), _transform((0.0, y, 0.0), rotate_x_deg=angle, scale=(half, half, half))))
    camera = (0.0, 2.6, 3.6)
    scene = {
        "type": "scene",
        "sensor": _sensor(camera, (0.0, 0.9, 0.0), 40.0, resolution),
        "floor": _checker_floor(6.0),
        "wall": {"type": "rectangle", "to_world": _transform((0, 2.5, -2.0), scale=(6.0, 2.5, 1.0)), "bsdf": _diffuse(WHITE)},
        "block": {"type": "cube", "to_world": _transform((-0.9, 0.35, -0.8), rotate_y_deg=25, scale=(0.3, 0.35, 0.3)), "bsdf": _diffuse(WHITE)},
        "box": {"type": "cube", "bsdf": _diffuse(ORANGE), "motion": {"type": "keyframes", "keys": keys}},
        "light": _point_light(camera, 80.0),
    }
    return _load(scene)


def _falling_clip(drop_height, gravity, **_):
    return fall_time(drop_height, gravity)


# ----------------------------------------------------------------------------------------
# Dominoes


def _rectangle(pivot_s, theta, height, thickness):
    """Corners (..., 4, 2) in the (s, y) tipping plane of dominoes whose front bottom edge
    is at (``pivot_s``, 0), tipped forward (towards +s) by ``theta`` rad (array)."""
    theta = np.asarray(theta, dtype=np.float64)[..., None]
    c, s = np.cos(theta), np.sin(theta)
    along = np.array([0.0, -thickness, -thickness, 0.0])
    up = np.array([0.0, 0.0, height, height])
    return np.stack([pivot_s + along * c + up * s, -along * s + up * c], axis=-1)


def _overlap(a, b):
    """Separating-axis test of convex quadrilaterals ``a``, ``b`` (..., 4, 2): True where
    they overlap (touching does not count)."""
    edges = np.concatenate([np.roll(a, -1, axis=-2) - a, np.roll(b, -1, axis=-2) - b], axis=-2)
    normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1)  # (..., 8, 2)
    proj_a = np.einsum("...kd,...cd->...kc", normals, a)
    proj_b = np.einsum("...kd,...cd->...kc", normals, b)
    separated = (proj_a.max(-1) <= proj_b.min(-1) + 1e-12) | (proj_b.max(-1) <= proj_a.min(-1) + 1e-12)
    return ~separated.any(-1)


def _contact_angle(next_theta, spacing, height, thickness):
    """Largest tip angle (rad, ≤ π/2: the floor) of a domino before it touches the next
    one, ``spacing`` m ahead and tipped by ``next_theta`` rad (array)."""
    ahead = _rectangle(spacing, next_theta, height, thickness)
    lo = np.zeros(np.shape(next_theta))
    hi = np.full(np.shape(next_theta), 0.5 * math.pi)
    blocked = _overlap(_rectangle(0.0, hi, height, thickness), ahead)
    for _ in range(40):  # bisection to ~1e-12 rad
        mid = 0.5 * (lo + hi)
        hit = _overlap(_rectangle(0.0, mid, height, thickness), ahead)
        lo, hi = np.where(hit, lo, mid), np.where(hit, mid, hi)
    return np.where(blocked, lo, 0.5 * math.pi)


def _free_fall(push, height, thickness, gravity, dt=1e-4):
    """Tip angle (rad) against time (s) of a domino pivoting on its front bottom edge,
    started upright with angular velocity ``push`` rad/s, until it lies flat (π/2).

    A rigid slab about an edge: θ'' = (3g / 2L) sin(θ − atan(thickness/height)),
    L = √(height² + thickness²) (its centre of mass starts behind the edge).
    """
    diagonal = math.hypot(height, thickness)
    rate = 1.5 * gravity / diagonal
    lean = math.atan2(thickness, height)
    times, angles = [0.0], [0.0]
    theta, omega = 0.0, push

    def accel(th):
        return rate * math.sin(th - lean)

    while theta < 0.5 * math.pi:
        if omega <= 0.0:
            raise ValueError(f"push={push!r} rad/s does not tip a domino over its edge; use a larger push")
        k1 = (omega, accel(theta))
        k2 = (omega + 0.5 * dt * k1[1], accel(theta + 0.5 * dt * k1[0]))
        k3 = (omega + 0.5 * dt * k2[1], accel(theta + 0.5 * dt * k2[0]))
        k4 = (omega + dt * k3[1], accel(theta + dt * k3[0]))
        theta += dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        omega += dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        times.append(times[-1] + dt)
        angles.append(min(theta, 0.5 * math.pi))
    return np.array(times), np.array(angles)


def domino_chain(count=10, height=0.5, thickness=0.08, spacing=0.3, push=3.0, gravity=STANDARD_GRAVITY_M_S2, dt=2e-3):
    """Tip angles (rad) of a toppling domino chain on a time grid.

    Each domino, when the previous one touches it (domino 0 at t = 0), starts tipping about
    its front bottom edge with angular velocity ``push`` rad/s and falls freely
    (:func:`_free_fall`), but never into the next one: it stops where it leans on it
    (``_contact_angle`` of the next one's angle at the same time); the last one falls flat.

    Parameters
    ----------
    count : int, default 10
        Dominoes, > 0.
    height, thickness : float, m, default 0.5 and 0.08
        Size of a domino.
    spacing : float, m, default 0.3
        Distance between neighbours: more than ``thickness``, less than ``height``.
    push : float, rad/s, default 3
        Angular velocity given to domino 0 at t = 0.
    gravity : float, m/s², default 9.81
    dt : float, s, default 0.002
        Time step of the grid.

    Returns
    -------
    tuple of (ndarray, ndarray)
        ``(times, angles)``: times (N,) s from 0 to when the chain is at rest, and angles
        (count, N) rad, each row non-decreasing.

    Raises
    ------
    ValueError
        A ``count`` that is not a positive integer, or a ``spacing`` with which the
        dominoes overlap or cannot knock each other over.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"count must be a positive integer, got {count!r}")
    height, thickness = _positive("height", height), _positive("thickness", thickness)
    spacing, push, gravity = _positive("spacing", spacing), _positive("push", push), _positive("gravity", gravity)
    if spacing <= thickness:
        raise ValueError(f"spacing={spacing!r} m must exceed the thickness {thickness!r} m (dominoes would overlap)")
    if spacing - thickness >= height:
        raise ValueError(f"spacing={spacing!r} m leaves a gap of at least the height {height!r} m: the dominoes could not knock each other over")
    free_t, free_theta = _free_fall(push, height, thickness, gravity)
    upright_contact = float(_contact_angle(0.0, spacing, height, thickness))
    delay = float(np.interp(upright_contact, free_theta, free_t))  # one domino to the next
    end = delay * (count - 1) + free_t[-1]
    times = np.arange(0.0, end + dt, dt)
    # The contact angle is smooth in the next domino's angle: tabulate it once.
    next_angles = np.linspace(0.0, 0.5 * math.pi, 257)
    contact = _contact_angle(next_angles, spacing, height, thickness)
    angles = np.empty((count, len(times)))
    angles[-1] = np.interp(times - delay * (count - 1), free_t, free_theta, left=0.0, right=0.5 * math.pi)
    for j in range(count - 2, -1, -1):
        free = np.interp(times - delay * j, free_t, free_theta, left=0.0, right=0.5 * math.pi)
        angles[j] = np.minimum(free, np.interp(angles[j + 1], next_angles, contact))
    return times, angles


def _domino_keys(times, angles, segments):
    """Key times where a non-decreasing angle curve crosses ``segments`` equal steps."""
    final = angles[-1]
    moving = np.nonzero(angles > 0.0)[0]
    if final <= 0.0 or not len(moving):
        return np.array([0.0]), np.array([0.0])
    start = times[max(moving[0] - 1, 0)]
    settled = times[np.nonzero(angles >= final - 1e-6)[0][0]]
    levels = final * np.arange(1, segments) / segments
    crossings = times[np.searchsorted(angles, levels)]
    key_times = np.unique(np.concatenate([[start], crossings, [settled]]))
    return key_times, np.interp(key_times, times, angles)


@_builtin("dominoes")
def dominoes(resolution=256, count=10, height=0.5, thickness=0.08, width=0.25, spacing=0.3, push=3.0, gravity=STANDARD_GRAVITY_M_S2):
    """A chain of ``count`` dominoes that topple one after another.

    Dominoes (``height`` × ``thickness`` × ``width`` m) stand ``spacing`` m apart on a
    line through the origin that recedes to the right (30° from the x axis). Each one is a
    body of its own, keyframed by its tip angle about its front bottom edge (see
    :func:`domino_chain`: pushed at ``push`` rad/s, falling under ``gravity``, leaning on
    the next one; the last falls flat), with keys at equal steps of angle so the angular
    velocity is piecewise constant. About 1.75 s from the first push to rest by default.
    Camera at (−0.4, 1.7, 3.4) looking at (0, 0.2, −0.05), fov 50°, point light at
    the camera.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    count : int, default 10
        Number of dominoes.
    height, thickness, width : float, m, defaults 0.5, 0.08, 0.25
        Size of a domino.
    spacing : float, m, default 0.3
        Distance between neighbouring dominoes.
    push : float, rad/s, default 3.0
        Angular velocity the first domino is pushed with.
    gravity : float, m/s², default 9.81
        Gravitational acceleration.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    import mitsuba as mi

    from .backend import ensure_variant

    ensure_variant()
    width = _positive("width", width)
    times, angles = domino_chain(count, height, thickness, spacing, push, gravity)

    yaw_deg = 30.0
    along = np.array([math.cos(math.radians(yaw_deg)), 0.0, -math.sin(math.radians(yaw_deg))])
    axis = np.cross([0.0, 1.0, 0.0], along)  # tipping towards +along is a positive turn about it
    first = -0.5 * spacing * (count - 1)
    camera = (-0.4, 1.7, 3.4)
    scene = {
        "type": "scene",
        "sensor": _sensor(camera, (0.0, 0.2, -0.05), 50.0, resolution),
        "floor": _floor(12.0, [0.45, 0.42, 0.38]),
        "light": _point_light(camera, 50.0),
    }
    colours = [WHITE, RED, WHITE, BLUE]
    for j in range(count):
        centre_s = first + j * spacing
        pivot = (centre_s + 0.5 * thickness) * along
        rest = _transform(tuple(centre_s * along + [0.0, 0.5 * height, 0.0]), rotate_y_deg=yaw_deg, scale=(0.5 * thickness, 0.5 * height, 0.5 * width))
        key_times, key_angles = _domino_keys(times, angles[j], segments=8)
        keys = [
            (
                float(t),
                mi.ScalarTransform4f().translate(list(pivot))
                @ mi.ScalarTransform4f().rotate(list(axis), math.degrees(a))
                @ mi.ScalarTransform4f().translate(list(-pivot))
                @ rest,
            )
            for t, a in zip(key_times, key_angles)
        ]
        scene[f"domino-{j}"] = {"type": "cube", "bsdf": _diffuse(colours[j % len(colours)]), "motion": {"type": "keyframes", "keys": keys}}
    return _load(scene)


def _dominoes_clip(count, height, thickness, spacing, push, gravity, **_):
    times, _angles = domino_chain(count, height, thickness, spacing, push, gravity)
    return float(times[-1])


# ----------------------------------------------------------------------------------------
# Glossy materials


GLOSSY_ROLL_DISTANCE_M = 2.0


@_builtin("glossy")
def glossy(resolution=256, speed=2.0, spin_rate=2.0, roughness=0.15):
    """Smooth and rough conductors, a rolling glass sphere and diffuse surfaces.

    A mirror-like aluminium sphere (``conductor``) and a diffuse white block stand still; a
    gold cube (``roughconductor``, GGX ``roughness``) spins about its vertical axis at
    ``spin_rate`` rad/s; a glass sphere (``dielectric``, IOR 1.5, radius 0.3 m) rolls
    without slipping across the front at ``speed`` m/s, from (−1.4, 0.3, −0.1) along
    (0.8, 0, 0.6) (towards the camera and to the right); its clip is 2 m of rolling,
    2 / speed s. Checkered floor, a diffuse back wall. Camera at (0, 1.6, 4) looking at
    (0, 0.45, −0.3), fov 45°; a point light at the camera and one 3 m above the floor.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    speed : float, m/s, default 2.0
        Speed of the rolling glass sphere.
    spin_rate : float, rad/s, default 2.0
        Spin of the gold cube about its vertical axis.
    roughness : float, default 0.15
        GGX α of the gold cube.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    from .backend import ensure_variant

    ensure_variant()
    speed, spin_rate, roughness = _positive("speed", speed), _positive("spin_rate", spin_rate), _positive("roughness", roughness)
    radius = 0.3
    start = np.array([-1.4, radius, -0.1])
    direction = np.array([0.8, 0.0, 0.6])
    # Rolling without slipping: ω = (ŷ × v̂) · v / r about the centre, which moves with v.
    omega = np.cross([0.0, 1.0, 0.0], direction) * speed / radius
    cube_centre = (0.25, 0.32, -0.9)
    camera = (0.0, 1.6, 4.0)
    scene = {
        "type": "scene",
        "sensor": _sensor(camera, (0.0, 0.45, -0.3), 45.0, resolution),
        "floor": _checker_floor(6.0),
        "wall": {"type": "rectangle", "to_world": _transform((0, 2.0, -1.8), scale=(6.0, 2.0, 1.0)), "bsdf": _diffuse(WHITE)},
        "mirror-sphere": {"type": "sphere", "center": [-0.9, 0.4, -0.7], "radius": 0.4, "bsdf": {"type": "conductor", "material": "Al"}},
        "block": {"type": "cube", "to_world": _transform((1.15, 0.3, -0.5), rotate_y_deg=-30, scale=(0.3, 0.3, 0.3)), "bsdf": _diffuse(WHITE)},
        "gold-cube": {
            "type": "cube",
            "to_world": _transform(cube_centre, rotate_y_deg=15, scale=(0.32, 0.32, 0.32)),
            "bsdf": {"type": "roughconductor", "material": "Au", "distribution": "ggx", "alpha": roughness},
            "motion": {"type": "parametric", "angular_velocity": [0.0, spin_rate, 0.0], "pivot": list(cube_centre)},
        },
        "glass-sphere": {
            "type": "sphere",
            "center": start.tolist(),
            "radius": radius,
            "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
            "motion": {"type": "parametric", "linear_velocity": (direction * speed).tolist(), "angular_velocity": omega.tolist(), "pivot": start.tolist()},
        },
        "light": _point_light(camera, 80.0),
        # Seen through the glass, the floor lit by the camera's light is the sphere's own
        # shadow: a second point light (noiseless, unlike an area light) lights it.
        "overhead-light": _point_light((0.0, 3.0, 0.8), 10.0),
    }
    return _load(scene)


def _glossy_clip(speed, **_):
    return GLOSSY_ROLL_DISTANCE_M / _positive("speed", speed)


# ----------------------------------------------------------------------------------------
# Street: an automotive D-ToF camera driving through traffic

STREET_MODULATION_HZ = 150e6  # automotive iToF/D-ToF modulation
STREET_EXPOSURE_S = 1e-3
STREET_LENGTH_M = 160.0  # of road ahead of the camera
ASPHALT = [0.08, 0.08, 0.09]
PAVEMENT = [0.45, 0.44, 0.42]
PAINTS = ([0.6, 0.05, 0.04], [0.05, 0.12, 0.45], [0.75, 0.75, 0.72], [0.05, 0.05, 0.05], [0.3, 0.32, 0.35], [0.7, 0.55, 0.1])
FACADES = ([0.55, 0.45, 0.38], [0.62, 0.6, 0.55], [0.4, 0.3, 0.25], [0.5, 0.52, 0.55])
CLOTHES = ([0.2, 0.25, 0.5], [0.5, 0.1, 0.1], [0.15, 0.15, 0.15], [0.3, 0.45, 0.2], [0.6, 0.5, 0.35])


def _box(centre, size, bsdf, rotate_y_deg=0.0):
    """A cube of ``size`` (x, y, z extents, m) centred at ``centre``."""
    return {"type": "cube", "to_world": _transform(centre, rotate_y_deg=rotate_y_deg, scale=[0.5 * v for v in size]), "bsdf": bsdf}


def _vehicle(x, z, heading_deg, paint, length=4.4, width=1.8):
    """A low-poly car: body and cabin (shapes; give them one motion to make one body)."""
    paint_bsdf = {"type": "roughplastic", "diffuse_reflectance": {"type": "rgb", "value": list(paint)}, "alpha": 0.15}
    glass = _diffuse([0.05, 0.06, 0.08])
    body = _box((x, 0.55, z), (width, 0.7, length), paint_bsdf, heading_deg)
    a = math.radians(heading_deg)
    back = (-0.15 * length * math.sin(a), -0.15 * length * math.cos(a))  # the cabin sits a little back
    cabin = _box((x + back[0], 1.15, z + back[1]), (0.9 * width, 0.55, 0.5 * length), glass, heading_deg)
    return {"body": body, "cabin": cabin}


def _person(x, z, clothes, height=1.75):
    """A pedestrian: a cylinder body and a sphere head."""
    body = {"type": "cylinder", "p0": [x, 0.0, z], "p1": [x, height - 0.25, z], "radius": 0.2, "bsdf": _diffuse(clothes)}
    head = {"type": "sphere", "center": [x, height - 0.12, z], "radius": 0.12, "bsdf": _diffuse([0.6, 0.45, 0.35])}
    return {"body": body, "head": head}


# The street's traffic, one moving body per entry; the scene's description counts them.
_ONCOMING_Z_M = (-22.0, -41.0, -67.0, -88.0, -115.0, -140.0)  # cars in the other lane
_AHEAD_Z_M = (-30.0, -75.0, -125.0)  # cars in the camera's lane, the same way
_CROSSING_X_M = ((-14.0, 1), (19.0, -1), (30.0, -1))  # cars at the intersection: (x, direction)
_WALKERS = 8  # pedestrians along the sidewalks
_CROSSWALK_X_M = (-4.0, 1.0, 5.0)  # pedestrians on the crosswalk
STREET_MOVING_BODIES = len(_ONCOMING_Z_M) + len(_AHEAD_Z_M) + len(_CROSSING_X_M) + _WALKERS + len(_CROSSWALK_X_M) + 1  # + the cyclist


@_builtin("street")
def street(resolution=256, speed=15.0, seed=0):
    """A D-ToF camera on a car driving down a street at ``speed`` m/s.

    The camera (1.3 m up, in the right lane, looking down the road, its modulated light
    source 8 cm beside the lens and moving with it) passes static buildings and parked
    cars; ahead are cars in both lanes (oncoming at 11–16 m/s, the same way at 9–12 m/s),
    cars crossing at an intersection 50 m ahead, pedestrians walking along and across the
    street and a cyclist (:data:`STREET_MOVING_BODIES` moving bodies). Cameras default to
    automotive modulation, 150 MHz, over a 1 ms exposure (``<integrator>`` of the scene);
    ``seed`` varies the buildings, the parked cars and the colours.

    Parameters
    ----------
    resolution : int, default 256
        Film width and height in pixels.
    speed : float, m/s, default 15.0
        Speed of the car carrying the camera.
    seed : int, default 0
        Varies the buildings, the parked cars and the colours.

    Returns
    -------
    DynamicScene
        The loaded scene (the variant set first if none is).
    """
    from .backend import ensure_variant

    ensure_variant()
    speed = _positive("speed", speed)
    rng = np.random.default_rng(seed)
    lane, road_half, walk = 1.75, 7.0, 3.0
    scene = {
        "type": "scene",
        "integrator": {"type": "dopplertof", "modulation_frequency": STREET_MODULATION_HZ, "exposure": STREET_EXPOSURE_S, "max_depth": 3},
        "sensor": {
            **_sensor((lane, 1.3, 0.0), (lane, 1.0, -40.0), 55.0, resolution),
            "motion": {"type": "parametric", "linear_velocity": [0.0, 0.0, -speed]},
            "light": _point_light((-0.08, 0.0, 0.0), 4000.0),  # camera frame: 8 cm beside the lens
        },
        "road": {"type": "rectangle", "to_world": _transform((0, 0, -STREET_LENGTH_M / 2), scale=(road_half, STREET_LENGTH_M, 1), rotate_x_deg=-90), "bsdf": _diffuse(ASPHALT)},
    }
    for side in (-1, 1):
        scene[f"sidewalk{side}"] = _box((side * (road_half + walk / 2), 0.075, -STREET_LENGTH_M / 2), (walk, 0.15, 2 * STREET_LENGTH_M), _diffuse(PAVEMENT))
        z = 10.0
        k = 0
        while z > -STREET_LENGTH_M:
            width = float(rng.uniform(8, 16))
            if not (-62 < z - width / 2 < -38 or -62 < z < -38):  # the intersection stays open
                height, depth = float(rng.uniform(6, 22)), float(rng.uniform(8, 14))
                centre = (side * (road_half + walk + depth / 2), height / 2, z - width / 2)
                scene[f"building{side}_{k}"] = _box(centre, (depth, height, width - 0.4), _diffuse(FACADES[rng.integers(len(FACADES))]))
            z -= width
            k += 1
        for k, z in enumerate(np.arange(-12.0, -STREET_LENGTH_M, -9.0)):
            if rng.random() < 0.6 and not -62 < z < -38:
                for part, shape in _vehicle(side * (road_half - 1.1), float(z), 0.0, PAINTS[rng.integers(len(PAINTS))]).items():
                    scene[f"parked{side}_{k}_{part}"] = shape

    def moving(name, shapes, velocity):
        for part, shape in shapes.items():
            scene[f"{name}_{part}"] = {**shape, "motion": {"type": "parametric", "linear_velocity": [float(v) for v in velocity]}}

    for k, z in enumerate(_ONCOMING_Z_M):
        moving(f"oncoming{k}", _vehicle(-lane, z, 180.0, PAINTS[k % len(PAINTS)]), (0, 0, float(rng.uniform(11, 16))))
    for k, z in enumerate(_AHEAD_Z_M):  # slower than the camera
        moving(f"ahead{k}", _vehicle(lane, z, 0.0, PAINTS[(k + 3) % len(PAINTS)]), (0, 0, -float(rng.uniform(9, 12))))
    for k, (x, direction) in enumerate(_CROSSING_X_M):
        moving(f"crossing{k}", _vehicle(x, -50.0 + 2.5 * direction, 90.0, PAINTS[(k + 1) % len(PAINTS)]), (direction * float(rng.uniform(7, 10)), 0, 0))
    for k in range(_WALKERS):
        side, z = (-1, 1)[k % 2], -8.0 - 13.0 * k
        moving(f"walker{k}", _person(side * (road_half + 1.0 + rng.uniform(0, 1.5)), z, CLOTHES[k % len(CLOTHES)]), (0, 0, float(rng.choice([-1, 1]) * rng.uniform(1.1, 1.7))))
    for k, x in enumerate(_CROSSWALK_X_M):
        moving(f"crossing_walker{k}", _person(x, -37.5 - 1.2 * k, CLOTHES[(k + 2) % len(CLOTHES)]), ((1 if k % 2 else -1) * float(rng.uniform(1.1, 1.6)), 0, 0))
    cyclist = {
        "frame": _box((2 * lane + 0.8, 0.7, -18.0), (0.15, 0.9, 1.7), _diffuse([0.1, 0.1, 0.1])),
        **{part: shape for part, shape in _person(2 * lane + 0.8, -18.0, CLOTHES[1], height=1.9).items()},
    }
    moving("cyclist", cyclist, (0, 0, -5.0))
    return _load(scene)


def _street_clip(speed, **_):
    return 40.0 / _positive("speed", speed)  # 40 m of driving


# ----------------------------------------------------------------------------------------
# Registry

SCENES = {
    "cornell-box": (cornell_box, "the original D-ToF Cornell box: point light at the camera, boxes at -10 and +10 m/s"),
    "cornell-box-area": (cornell_box_area, "the Cornell box lit by a ceiling area light"),
    "rotating": (rotating, "merry-go-round: platform and four objects about a vertical axis, 3 m/s at the rim"),
    "falling-box": (falling_box, "a tumbling box dropped 1.5 m under gravity (5.4 m/s at impact)"),
    "dominoes": (dominoes, "ten dominoes toppling one after another, each about its bottom edge"),
    "glossy": (glossy, "mirror and rough gold conductors, a rolling glass sphere (2 m/s), diffuse walls"),
    "street": (street, f"a camera with its light on a car at 15 m/s in traffic: {STREET_MOVING_BODIES} moving bodies, 150 MHz"),
}

# Length of each scene's motion (s) from the builder's keyword arguments (defaults filled in).
_CLIPS = {
    "cornell-box": _cornell_clip,
    "cornell-box-area": _cornell_clip,
    "rotating": _rotating_clip,
    "falling-box": _falling_clip,
    "dominoes": _dominoes_clip,
    "glossy": _glossy_clip,
    "street": _street_clip,
}


def _check_name(name):
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")


def build(name: str, **kwargs):
    """Build the built-in scene ``name`` (see ``SCENES``).

    Parameters
    ----------
    name : str
        A key of ``SCENES``.
    **kwargs
        The builder's keyword arguments (``resolution`` and the scene's own).

    Returns
    -------
    DynamicScene

    Raises
    ------
    ValueError
        An unknown ``name`` or a value out of range.
    TypeError
        A keyword argument the builder does not take.
    """
    _check_name(name)
    return SCENES[name][0](**kwargs)  # its builder records the recipe (_builtin)


def from_recipe(recipe: tuple):
    """The scene a :attr:`DynamicScene.recipe <dopplertof.scene.DynamicScene>` describes,
    built again (a Ray worker's copy): ``("builtin", name, kwargs)`` by :func:`build`,
    ``("file", path, params, film_resolution)`` by :func:`dopplertof.load_scene`.

    Parameters
    ----------
    recipe : tuple
        As above.

    Returns
    -------
    DynamicScene

    Raises
    ------
    ValueError
        An unknown recipe.
    """
    from .loader import load_scene

    kind, *args = recipe
    if kind == "builtin":
        name, kwargs = args
        return build(name, **kwargs)
    if kind == "file":
        path, params, size = args
        return load_scene(path, film_resolution=size, **params)
    raise ValueError(f"unknown scene recipe {recipe!r}")


def clip_duration(name: str, **kwargs) -> float:
    """Length (s) of the motion of built-in scene ``name``: the default animation length.

    ``kwargs`` are the builder's scene-specific keyword arguments (``resolution`` is
    accepted and ignored); the cornell boxes move only during their exposure (1.5 ms), the
    merry-go-round's clip is one revolution, the falling box's its fall, the dominoes' the
    time until the chain is at rest, the glossy scene's 2 m of rolling.

    Parameters
    ----------
    name : str
        A key of ``SCENES``.
    **kwargs
        As above.

    Returns
    -------
    float
        Seconds.

    Raises
    ------
    ValueError
        An unknown ``name`` or a parameter the scene does not take.
    """
    _check_name(name)
    params = inspect.signature(SCENES[name][0]).parameters
    unknown = sorted(set(kwargs) - set(params))
    if unknown:
        raise ValueError(f"scene {name!r} has no parameter(s) {unknown}; it takes {', '.join(params)}")
    values = {key: p.default for key, p in params.items() if p.default is not inspect.Parameter.empty}
    values.update(kwargs)
    values.pop("resolution", None)
    return float(_CLIPS[name](**values))


# ----------------------------------------------------------------------------------------
# Opening a scene as the commands do


def parse_resolution(text):
    """``"N"`` (or an int) → N, square; ``"WxH"`` → (W, H); None stays None.

    Parameters
    ----------
    text : str, int or None

    Returns
    -------
    int, tuple of (int, int) or None

    Raises
    ------
    ValueError
        Anything but N or WxH of positive integers.
    """
    if text is None:
        return None
    try:
        size = (text,) if isinstance(text, int) else tuple(int(v) for v in text.lower().split("x"))
    except ValueError:
        size = ()
    if len(size) not in (1, 2) or min(size) <= 0:
        raise ValueError(f"--resolution {text!r}: expected N or WxH (positive integers)")
    return size[0] if len(size) == 1 else size


def parse_defines(items) -> dict:
    """``-D name=value`` options as ``{name: value}``.

    Parameters
    ----------
    items : iterable of str
        ``"name=value"`` strings.

    Returns
    -------
    dict

    Raises
    ------
    ValueError
        An item that is not ``name=value`` with a name of letters, digits and ``_``.
    """
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not name.strip().replace("_", "a").isalnum():
            raise ValueError(f"-D {item!r}: expected name=value (name: letters, digits, _)")
        out[name.strip()] = value
    return out


def open_scene(scene_arg: str, resolution=None, defines=()):
    """A scene by built-in name or XML file path, as the commands take it.

    Parameters
    ----------
    scene_arg : str
        A built-in scene name or an XML file path.
    resolution : int, str or None, default None
        N or ``"WxH"``: replaces the film size (built-in scenes: N only).
    defines : iterable of str, default ()
        ``"name=value"`` strings that set a file's ``$name`` values (files only).

    Returns
    -------
    DynamicScene

    Raises
    ------
    ValueError
        No such file or scene, a bad ``resolution`` or ``defines``.
    SceneError
        A file that does not load.
    """
    from .loader import load_scene

    size, params = parse_resolution(resolution), parse_defines(defines)
    if scene_arg in SCENES:
        if params:
            raise ValueError(f"-D applies to scene files; {scene_arg!r} is a built-in scene")
        if isinstance(size, tuple) and size[0] != size[1]:
            raise ValueError(f"--resolution {resolution!r}: built-in scenes are square; give one number")
        return build(scene_arg, **({} if size is None else {"resolution": size if isinstance(size, int) else size[0]}))
    if not os.path.exists(scene_arg):
        raise ValueError(f"{scene_arg}: no such scene file or built-in scene (see 'dopplertof scenes')")
    return load_scene(scene_arg, film_resolution=size, **params)
