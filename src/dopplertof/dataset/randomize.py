"""Procedural random scenes for datasets: indoor rooms and streets built from primitives.

Two steps, so that a sample's JSON record alone re-renders it:

1. :func:`sample_scene` draws a *scene description* (plain JSON: numbers, strings, lists)
   from the configuration (:mod:`dopplertof.dataset.config`) with a
   ``numpy.random.Generator``; nothing here touches Mitsuba.
2. :func:`build_scene` turns a description into a :class:`~dopplertof.scene.DynamicScene`
   (a Mitsuba scene dict with a ``"motion"`` per moving body and for a moving camera, loaded by
   :func:`dopplertof.load_scene`).

The description (all lengths in m, world frame, y up):

====================  ==================================================================
key                   meaning
====================  ==================================================================
``kind``              ``indoor`` or ``street``
``camera``            ``origin``, ``target``, ``up`` (m), ``fov_deg`` (horizontal): the pose
                      at t = 0; its motion (ego-motion) ``linear_velocity_m_s``,
                      ``angular_velocity_rad_s`` (world frame) about ``pivot_m`` (the
                      aperture), all zeros for a static camera
``light``             ``position`` (m, world, t = 0: the camera's origin) and
                      ``intensity_w_sr`` of the modulated point light, attached to the
                      camera: it moves with it (its offset from ``camera.origin`` is
                      kept in the camera's frame)
``static``            list of primitives of the static scene (walls, floor, furniture,
                      buildings, poles, bodies drawn as static)
``bodies``            list of moving bodies, in the order of their instance id (0, 1, …):
                      ``name``, ``shape``, ``parts`` (primitives), ``pivot_m``,
                      ``linear_velocity_m_s``, ``angular_velocity_rad_s``
``static_bodies``     the bodies drawn as static (same keys, zero velocities); their parts
                      are in ``static`` too (instance −1)
====================  ==================================================================

A primitive is ``{"type": "box", "center", "half_size", "yaw_deg", "material"}``,
``{"type": "sphere", "center", "radius", "material"}`` or ``{"type": "cylinder", "p0",
"p1", "radius", "material"}`` (open tube); a material is ``{"type": "diffuse", "rgb"}``,
``{"type": "plastic", "rgb", "alpha"}`` (rough plastic), ``{"type": "roughconductor",
"metal", "alpha"}``, ``{"type": "conductor", "metal"}``, ``{"type": "dielectric", "ior"}``
or ``{"type": "checkerboard", "rgb0", "rgb1", "scale"}`` (diffuse, checkerboard texture).

Every body moves rigidly over the exposure: constant linear velocity plus a rotation at a
constant rate about an axis through its centre (``pivot_m``). Vehicles drive along the
road and turn about the vertical axis; people walk horizontally; boxes, spheres and
cylinders fly in a random direction and spin about a random axis.

The camera moves too with probability ``ego.<kind>_probability`` (ego-motion; the same
rigid motion about its aperture): in a street along the road, the way it looks (−z), in a
room horizontally in a random direction, at ``ego.<kind>_speed_m_s``, turning about the
vertical at ``ego.<kind>_yaw_rate_rad_s`` (random sign). The ego-motion is drawn last, so
a description differs from that of a static camera only in the camera's velocities. The
ground truth is relative to the moving camera (static geometry has a velocity; its
instance id stays −1: ``bodies`` are what moves in the world).
"""

from __future__ import annotations

import math

import numpy as np

from .config import CONDUCTORS, choose, draw

_CAMERA_HEIGHT_M = (1.2, 1.8)
_SIDEWALK_HEIGHT_M = 0.15
_SLAB_M = 0.1  # wall / floor thickness


def _f(x) -> float:
    return float(x)


def _vec(v) -> list[float]:
    return [float(c) for c in v]


def _rgb(rng, config) -> list[float]:
    lo, hi = config["materials"]["albedo"]
    return _vec(rng.uniform(lo, hi, size=3))


def _grey(rng, lo=0.3, hi=0.7) -> list[float]:
    g = float(rng.uniform(lo, hi))
    return [g, g, g]


def _material(rng, config, name: str | None = None) -> dict:
    """A body material drawn from ``materials.weights`` (or the named type)."""
    m = config["materials"]
    name = name or choose(rng, m["weights"])
    if name == "diffuse":
        return {"type": "diffuse", "rgb": _rgb(rng, config)}
    if name == "plastic":
        return {"type": "plastic", "rgb": _rgb(rng, config), "alpha": draw(rng, config, "materials.roughness")}
    if name == "roughconductor":
        return {"type": "roughconductor", "metal": CONDUCTORS[int(rng.integers(len(CONDUCTORS)))], "alpha": draw(rng, config, "materials.roughness")}
    if name == "conductor":
        return {"type": "conductor", "metal": CONDUCTORS[int(rng.integers(len(CONDUCTORS)))]}
    if name == "dielectric":
        return {"type": "dielectric", "ior": draw(rng, config, "materials.dielectric_ior")}
    if name == "checkerboard":
        return {"type": "checkerboard", "rgb0": _rgb(rng, config), "rgb1": _rgb(rng, config), "scale": draw(rng, config, "materials.checker_scale")}
    raise ValueError(f"unknown material {name!r}")


def _structure_material(rng, config, checker: bool = False) -> dict:
    """Walls, floors, buildings: diffuse, or a checkerboard."""
    if checker:
        return {"type": "checkerboard", "rgb0": _grey(rng, 0.55, 0.8), "rgb1": _grey(rng, 0.1, 0.35), "scale": draw(rng, config, "materials.checker_scale")}
    return {"type": "diffuse", "rgb": _rgb(rng, config)}


def _box(center, half_size, material, yaw_deg=0.0) -> dict:
    return {"type": "box", "center": _vec(center), "half_size": _vec(half_size), "yaw_deg": _f(yaw_deg), "material": material}


def _unit(rng) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _horizontal(angle_rad) -> np.ndarray:
    return np.array([math.cos(angle_rad), 0.0, math.sin(angle_rad)])


# ------------------------------------------------------------------------------------------
# Bodies


def _body_parts(rng, config, shape: str, base: np.ndarray, heading_rad: float, size: float) -> tuple[list, np.ndarray]:
    """Primitives of a body standing on ``base`` (a floor point, m) and its centre (pivot)."""
    yaw = -math.degrees(heading_rad)  # rotate_y(yaw) maps +x to the heading
    mat = _material(rng, config)
    if shape == "box":
        half = 0.5 * size * rng.uniform(0.6, 1.0, size=3)
        lift = float(rng.uniform(0.0, 0.8)) * (rng.random() < 0.5)  # some float
        centre = base + [0.0, half[1] + lift, 0.0]
        return [_box(centre, half, mat, float(rng.uniform(0, 90)))], centre
    if shape == "sphere":
        r = 0.5 * size
        lift = float(rng.uniform(0.0, 1.0)) * (rng.random() < 0.5)
        centre = base + [0.0, r + lift, 0.0]
        return [{"type": "sphere", "center": _vec(centre), "radius": _f(r), "material": mat}], centre
    if shape == "cylinder":
        r, h = 0.25 * size, size * float(rng.uniform(0.8, 1.6))
        p0, p1 = base.copy(), base + [0.0, h, 0.0]
        return [{"type": "cylinder", "p0": _vec(p0), "p1": _vec(p1), "radius": _f(r), "material": mat}], 0.5 * (p0 + p1)
    if shape == "person":
        height = float(rng.uniform(1.5, 1.9))
        torso_r = float(rng.uniform(0.17, 0.24))
        head_r = 0.11
        top = base + [0.0, height - 2 * head_r, 0.0]
        skin = {"type": "diffuse", "rgb": _vec(np.array([0.8, 0.6, 0.45]) * rng.uniform(0.4, 1.0))}
        parts = [
            {"type": "cylinder", "p0": _vec(base), "p1": _vec(top), "radius": _f(torso_r), "material": mat},
            {"type": "sphere", "center": _vec(top + [0.0, head_r, 0.0]), "radius": _f(head_r), "material": skin},
        ]
        return parts, base + [0.0, 0.5 * height, 0.0]
    if shape == "vehicle":
        length, width = float(rng.uniform(3.6, 4.8)), float(rng.uniform(1.6, 1.9))
        wheel_r = 0.32
        body_h = float(rng.uniform(0.55, 0.8))
        cabin_h = float(rng.uniform(0.45, 0.65))
        fwd, side = _horizontal(heading_rad), _horizontal(heading_rad + 0.5 * math.pi)
        body_c = base + [0.0, wheel_r + 0.5 * body_h, 0.0]
        cabin_c = base + [0.0, wheel_r + body_h + 0.5 * cabin_h, 0.0] - 0.1 * length * fwd
        glass = {"type": "dielectric", "ior": 1.5} if rng.random() < 0.5 else {"type": "diffuse", "rgb": _grey(rng, 0.05, 0.2)}
        tyre = {"type": "diffuse", "rgb": [0.04, 0.04, 0.04]}
        parts = [
            _box(body_c, [0.5 * length, 0.5 * body_h, 0.5 * width], mat, yaw),
            _box(cabin_c, [0.28 * length, 0.5 * cabin_h, 0.45 * width], glass, yaw),
        ]
        for a in (-0.32, 0.32):
            for s in (-1.0, 1.0):
                hub = base + [0.0, wheel_r, 0.0] + a * length * fwd + s * 0.5 * width * side
                parts.append({"type": "cylinder", "p0": _vec(hub - 0.12 * side), "p1": _vec(hub + 0.12 * side), "radius": wheel_r, "material": tyre})
        return parts, body_c
    raise ValueError(f"unknown body shape {shape!r}")


def _motion(rng, config, shape: str, heading_rad: float) -> tuple[list, list]:
    """(linear velocity m/s, angular velocity rad/s) of a moving body."""
    spin = draw(rng, config, "bodies.spin_rad_s")
    if shape == "vehicle":
        speed = draw(rng, config, "bodies.vehicle_speed_m_s")
        return _vec(speed * _horizontal(heading_rad)), [0.0, _f(spin * (0.1 if rng.random() < 0.5 else -0.1)), 0.0]
    if shape == "person":
        speed = draw(rng, config, "bodies.person_speed_m_s")
        return _vec(speed * _horizontal(heading_rad)), [0.0, _f(spin * (0.2 if rng.random() < 0.5 else -0.2)), 0.0]
    speed = draw(rng, config, "bodies.speed_m_s")
    return _vec(speed * _unit(rng)), _vec(spin * _unit(rng))


# ------------------------------------------------------------------------------------------
# Scenes


def _camera(origin, yaw_rad, pitch_rad, fov_deg) -> dict:
    direction = np.array([math.cos(pitch_rad) * math.sin(yaw_rad), math.sin(pitch_rad), -math.cos(pitch_rad) * math.cos(yaw_rad)])
    return {"origin": _vec(origin), "target": _vec(np.asarray(origin) + direction), "up": [0.0, 1.0, 0.0], "fov_deg": _f(fov_deg)}


def _indoor(rng, config) -> tuple[dict, list, callable]:
    s = config["scene"]
    width, depth, height = (draw(rng, config, f"scene.indoor_{k}") for k in ("width_m", "depth_m", "height_m"))
    hw, hd = 0.5 * width, 0.5 * depth
    checker = rng.random() < s["checker_floor_probability"]
    t = _SLAB_M
    static = [
        _box([0, -0.5 * t, 0], [hw + t, 0.5 * t, hd + t], _structure_material(rng, config, checker)),  # floor
        _box([0, height + 0.5 * t, 0], [hw + t, 0.5 * t, hd + t], _structure_material(rng, config)),  # ceiling
        _box([0, 0.5 * height, -hd - 0.5 * t], [hw + t, 0.5 * height, 0.5 * t], _structure_material(rng, config)),  # back
        _box([0, 0.5 * height, hd + 0.5 * t], [hw + t, 0.5 * height, 0.5 * t], _structure_material(rng, config)),  # front
        _box([-hw - 0.5 * t, 0.5 * height, 0], [0.5 * t, 0.5 * height, hd], _structure_material(rng, config)),  # left
        _box([hw + 0.5 * t, 0.5 * height, 0], [0.5 * t, 0.5 * height, hd], _structure_material(rng, config)),  # right
    ]
    for _ in range(draw(rng, config, "scene.indoor_furniture")):
        half = [float(rng.uniform(0.3, 0.9)), float(rng.uniform(0.2, 0.6)), float(rng.uniform(0.25, 0.6))]
        x = float(rng.uniform(-hw + half[0], hw - half[0])) if hw > half[0] else 0.0
        z = float(rng.uniform(-hd + half[2], 0.3 * hd))
        static.append(_box([x, half[1], z], half, _structure_material(rng, config), float(rng.uniform(-20, 20))))
    fov = draw(rng, config, "camera.fov_deg")
    origin = np.array([float(rng.uniform(-0.25, 0.25)) * width, float(rng.uniform(*_CAMERA_HEIGHT_M)), hd - 0.3])
    yaw = math.radians(float(rng.uniform(-15, 15)))
    camera = _camera(origin, yaw, math.radians(float(rng.uniform(-15, -3))), fov)

    def place(distance, azimuth, margin):
        """A floor point ``distance`` m from the camera at ``azimuth`` rad off its heading."""
        a = yaw + azimuth
        p = origin + distance * np.array([math.sin(a), 0.0, -math.cos(a)])
        p[0] = np.clip(p[0], -hw + margin, hw - margin) if hw > margin else 0.0
        p[2] = np.clip(p[2], -hd + margin, hd - 1.0) if hd > margin + 0.5 else 0.0
        p[1] = 0.0
        return p

    return camera, static, place


def _street(rng, config) -> tuple[dict, list, callable, float, float]:
    s = config["scene"]
    road_w = draw(rng, config, "scene.street_road_width_m")
    walk_w = draw(rng, config, "scene.street_sidewalk_width_m")
    length = 120.0
    checker = rng.random() < s["checker_floor_probability"]
    static = [_box([0, -0.5 * _SLAB_M, -0.5 * length + 5], [0.5 * road_w, 0.5 * _SLAB_M, 0.5 * length], _structure_material(rng, config, checker))]
    for side in (-1.0, 1.0):
        x = side * (0.5 * road_w + 0.5 * walk_w)
        static.append(_box([x, 0.5 * _SIDEWALK_HEIGHT_M - 0.05, -0.5 * length + 5], [0.5 * walk_w, 0.5 * _SIDEWALK_HEIGHT_M + 0.05, 0.5 * length],
                           {"type": "diffuse", "rgb": _grey(rng, 0.4, 0.7)}))
        z = 3.0
        for _ in range(draw(rng, config, "scene.street_buildings_per_side")):
            front = float(rng.uniform(6.0, 20.0))
            bdepth, bheight = float(rng.uniform(6.0, 15.0)), float(rng.uniform(6.0, 25.0))
            bx = side * (0.5 * road_w + walk_w + 0.5 * bdepth)
            static.append(_box([bx, 0.5 * bheight, z - 0.5 * front], [0.5 * bdepth, 0.5 * bheight, 0.5 * front], _structure_material(rng, config)))
            z -= front + float(rng.uniform(0.0, 4.0))
        for _ in range(draw(rng, config, "scene.street_poles")):
            pz = float(rng.uniform(-40.0, 0.0))
            px = side * (0.5 * road_w + 0.4)
            static.append({"type": "cylinder", "p0": [px, 0.0, pz], "p1": [px, float(rng.uniform(3.0, 6.0)), pz], "radius": 0.08,
                           "material": {"type": "diffuse", "rgb": _grey(rng, 0.2, 0.6)}})
    fov = draw(rng, config, "camera.fov_deg")
    side = 1.0 if rng.random() < 0.5 else -1.0
    origin = np.array([side * (0.5 * road_w + float(rng.uniform(0.3, 0.8)) * walk_w), _SIDEWALK_HEIGHT_M + float(rng.uniform(*_CAMERA_HEIGHT_M)), 2.0])
    yaw = -side * math.radians(float(rng.uniform(5, 25)))  # towards the road
    camera = _camera(origin, yaw, math.radians(float(rng.uniform(-10, -2))), fov)

    def place(distance, azimuth, margin):
        a = yaw + azimuth
        p = origin + distance * np.array([math.sin(a), 0.0, -math.cos(a)])
        on_walk = abs(p[0]) > 0.5 * road_w
        p[1] = _SIDEWALK_HEIGHT_M if on_walk else 0.0
        return p

    return camera, static, place, road_w, walk_w


def _ego_motion(rng, config, kind: str, camera: dict) -> None:
    """Add the camera's motion (ego-motion; zeros for a static camera) to ``camera``."""
    e = config["ego"]
    linear, angular = np.zeros(3), np.zeros(3)
    if rng.random() < e[f"{kind}_probability"]:
        speed = draw(rng, config, f"ego.{kind}_speed_m_s")
        heading = np.array([0.0, 0.0, -1.0]) if kind == "street" else _horizontal(float(rng.uniform(0, 2 * math.pi)))
        linear = speed * heading
        angular[1] = draw(rng, config, f"ego.{kind}_yaw_rate_rad_s") * (1.0 if rng.random() < 0.5 else -1.0)
    camera.update(linear_velocity_m_s=_vec(linear), angular_velocity_rad_s=_vec(angular), pivot_m=list(camera["origin"]))


def sample_scene(rng: np.random.Generator, config: dict) -> dict:
    """Draw one scene description (see the module docstring) from ``config``.

    Parameters
    ----------
    rng : numpy.random.Generator
        The sample's scene stream; the same stream gives the same description.
    config : dict
        A validated configuration (:func:`dopplertof.dataset.config.load_config`).

    Returns
    -------
    dict
        JSON-ready scene description; :func:`build_scene` makes it a Mitsuba scene.
    """
    kind = choose(rng, config["scene"]["kinds"])
    if kind == "indoor":
        camera, static, place = _indoor(rng, config)
        road_w = walk_w = None
    else:
        camera, static, place, road_w, walk_w = _street(rng, config)
    half_fov = 0.5 * math.radians(camera["fov_deg"])
    bodies, static_bodies = [], []
    for _ in range(draw(rng, config, "bodies.count")):
        shape = choose(rng, config["bodies"]["shapes"])
        if shape == "vehicle" and kind != "street":
            shape = "box"
        size = draw(rng, config, "bodies.size_m")
        distance = draw(rng, config, "bodies.distance_m")
        azimuth = float(rng.uniform(-0.8, 0.8)) * half_fov
        if shape == "vehicle":
            distance = max(distance, 5.0)
            base = place(distance, azimuth, 1.0)
            lane = 0.25 * road_w * (1.0 if rng.random() < 0.5 else -1.0)
            base[0], base[1] = lane, 0.0
            heading = -0.5 * math.pi if lane > 0 else 0.5 * math.pi  # right-hand traffic: away / towards the camera
            heading += float(rng.uniform(-0.05, 0.05))
        else:
            base = place(distance, azimuth, 0.6)
            heading = float(rng.uniform(0, 2 * math.pi))
            if shape == "person" and kind == "street" and rng.random() < 0.7:  # walk along the sidewalk
                heading = 0.5 * math.pi * (1.0 if rng.random() < 0.5 else -1.0) + float(rng.uniform(-0.3, 0.3))
        parts, centre = _body_parts(rng, config, shape, base, heading, size)
        moving = rng.random() < config["bodies"]["moving_probability"]
        linear, angular = _motion(rng, config, shape, heading) if moving else ([0.0] * 3, [0.0] * 3)
        body = {"shape": shape, "parts": parts, "pivot_m": _vec(centre), "linear_velocity_m_s": linear, "angular_velocity_rad_s": angular}
        if moving and (any(linear) or any(angular)):
            bodies.append(body)
        else:
            static_bodies.append(body)
            static.extend(parts)
    for i, body in enumerate(bodies):
        body["name"] = f"body-{i}"
    for i, body in enumerate(static_bodies):
        body["name"] = f"static-body-{i}"
    light = {"position": list(camera["origin"]), "intensity_w_sr": draw(rng, config, "camera.light_intensity_w_sr")}
    _ego_motion(rng, config, kind, camera)
    return {"kind": kind, "camera": camera, "light": light, "static": static, "bodies": bodies, "static_bodies": static_bodies}


# ------------------------------------------------------------------------------------------
# Mitsuba


def _bsdf(material: dict) -> dict:
    t = material["type"]
    if t == "diffuse":
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": material["rgb"]}}
    if t == "plastic":
        return {"type": "roughplastic", "distribution": "ggx", "alpha": material["alpha"], "diffuse_reflectance": {"type": "rgb", "value": material["rgb"]}}
    if t == "roughconductor":
        return {"type": "roughconductor", "material": material["metal"], "distribution": "ggx", "alpha": material["alpha"]}
    if t == "conductor":
        return {"type": "conductor", "material": material["metal"]}
    if t == "dielectric":
        return {"type": "dielectric", "int_ior": material["ior"], "ext_ior": 1.0}
    if t == "checkerboard":
        import mitsuba as mi

        s = material["scale"]
        tex = {"type": "checkerboard", "color0": {"type": "rgb", "value": material["rgb0"]}, "color1": {"type": "rgb", "value": material["rgb1"]},
               "to_uv": mi.ScalarTransform4f().scale([s, s, 1.0])}
        return {"type": "diffuse", "reflectance": tex}
    raise ValueError(f"unknown material type {t!r}")


def _shape(prim: dict) -> dict:
    import mitsuba as mi

    t = prim["type"]
    bsdf = _bsdf(prim["material"])
    if t == "box":
        to_world = mi.ScalarTransform4d().translate(prim["center"]) @ mi.ScalarTransform4d().rotate([0, 1, 0], prim["yaw_deg"]) @ mi.ScalarTransform4d().scale(prim["half_size"])
        return {"type": "cube", "to_world": to_world, "bsdf": bsdf}
    if t == "sphere":
        return {"type": "sphere", "center": prim["center"], "radius": prim["radius"], "bsdf": bsdf}
    if t == "cylinder":
        return {"type": "cylinder", "p0": prim["p0"], "p1": prim["p1"], "radius": prim["radius"], "bsdf": bsdf}
    raise ValueError(f"unknown primitive type {t!r}")


def camera_rotation(camera: dict) -> np.ndarray:
    """The (3, 3) rotation from the camera frame (x left, y up, z forward) to the world at
    t = 0 of a description's ``camera``: that of the sensor's ``look_at``, in float64.

    Parameters
    ----------
    camera : dict
        A description's ``camera``.

    Returns
    -------
    ndarray
        (3, 3) float64.
    """
    import mitsuba as mi

    look = mi.ScalarTransform4d().look_at(origin=camera["origin"], target=camera["target"], up=camera["up"])
    return np.array(look.matrix, dtype=np.float64)[:3, :3]


def camera_motion(camera: dict) -> dict | None:
    """The sensor's ``"motion"`` (a parametric dict) of a description's ``camera``; None for
    a static camera (and for descriptions written before cameras moved).

    Parameters
    ----------
    camera : dict
        A description's ``camera``.

    Returns
    -------
    dict or None
    """
    linear = camera.get("linear_velocity_m_s", [0.0] * 3)
    angular = camera.get("angular_velocity_rad_s", [0.0] * 3)
    if not (any(linear) or any(angular)):
        return None
    return {"type": "parametric", "linear_velocity": linear, "angular_velocity": angular, "pivot": camera.get("pivot_m", camera["origin"])}


def scene_dict(description: dict, resolution: int) -> dict:
    """The Mitsuba scene dict (with ``"motion"`` entries) of a scene description.

    The light is attached to the camera: with a moving camera it sits in the sensor dict
    (its position in the camera frame) and moves with it; a static camera's light is the
    same light placed in the world, which takes the renderer's static-emitter path (the
    renders of static cameras are those of the releases before ego-motion, bit for bit).

    Parameters
    ----------
    description : dict
        A scene description (a sample's record).
    resolution : int
        Film size in pixels (square).

    Returns
    -------
    dict
    """
    import mitsuba as mi

    cam = description["camera"]
    sensor = {
        "type": "perspective",
        "fov": cam["fov_deg"],
        "to_world": mi.ScalarTransform4f().look_at(origin=cam["origin"], target=cam["target"], up=cam["up"]),
        "film": {"type": "hdrfilm", "width": int(resolution), "height": int(resolution), "rfilter": {"type": "box"}},
    }
    light = {"type": "point", "intensity": {"type": "rgb", "value": [description["light"]["intensity_w_sr"]] * 3}}
    out = {"type": "scene", "sensor": sensor}
    motion = camera_motion(cam)
    if motion is None:
        out["light"] = {**light, "position": description["light"]["position"]}
    else:
        offset = camera_rotation(cam).T @ (np.asarray(description["light"]["position"], dtype=np.float64) - np.asarray(cam["origin"], dtype=np.float64))
        sensor["motion"] = motion
        sensor["light"] = {**light, "position": _vec(offset)}  # camera frame: [0, 0, 0] is the aperture
    for i, prim in enumerate(description["static"]):
        out[f"static-{i:03d}"] = _shape(prim)
    for body in description["bodies"]:
        motion = {"type": "parametric", "linear_velocity": body["linear_velocity_m_s"], "angular_velocity": body["angular_velocity_rad_s"], "pivot": body["pivot_m"]}
        for j, prim in enumerate(body["parts"]):
            out[f"{body['name']}-part-{j}"] = {**_shape(prim), "motion": dict(motion)}
    return out


def build_scene(description: dict, resolution: int):
    """A :class:`~dopplertof.scene.DynamicScene` from a scene description.

    Body ``k`` of the description is ``scene.bodies[k]`` (its instance id); a ValueError
    says so if the loader grouped them otherwise. A moving camera is ``scene.camera_motion``
    and its light ``scene.lights[0]`` (see :func:`scene_dict`).

    Parameters
    ----------
    description : dict
        A scene description (a sample's record).
    resolution : int
        Film size in pixels (square).

    Returns
    -------
    DynamicScene

    Raises
    ------
    ValueError
        The loader grouped the bodies otherwise than the description.
    """
    from ..loader import load_scene

    scene = load_scene(scene_dict(description, resolution))
    if len(scene.bodies) != len(description["bodies"]):
        raise ValueError(f"scene has {len(scene.bodies)} bodies, its description {len(description['bodies'])}: two bodies share a motion")
    return scene
