"""Built-in procedural scenes (no downloads). ``SCENES`` maps a name to (builder, description).

Every builder returns a :class:`~dopplertof.scene.DynamicScene` and takes ``resolution``
(pixels, square film) plus scene-specific keyword arguments.
"""

from __future__ import annotations

import numpy as np

WHITE = [0.725, 0.71, 0.68]
RED = [0.63, 0.065, 0.05]
GREEN = [0.14, 0.45, 0.091]


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


def _translation_keys(matrix, displacement, exposure):
    """Keyframes moving ``matrix`` by ``displacement`` (m) over [0, exposure] s."""
    import mitsuba as mi

    end = mi.ScalarTransform4f().translate(list(displacement)) @ matrix
    return {"type": "keyframes", "keys": [(0.0, matrix), (exposure, end)]}


def cornell_box(resolution=256, light="point", exposure=1.5e-3, displacement=0.015):
    """The original D-ToF Cornell box.

    Room [−1, 1] × [0, 2] × [−1, 1] m; camera at (0, 1, 6.8) looking down −z, fov 19.5°;
    a point light (intensity 100) at the camera (``light="point"``) or an area light in the
    ceiling (``light="area"``). Over [0, exposure] the short box moves ``displacement`` m
    in +z (towards the camera, −10 m/s by default) and the tall box the same distance in −z
    (away, +10 m/s).
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
        scene["light"] = {"type": "point", "position": [0.0, 1.0, 6.8], "intensity": {"type": "rgb", "value": [100.0] * 3}}
    else:
        scene["light"] = {
            "type": "rectangle",
            "to_world": _transform((0, 1.99, 0), rotate_x_deg=90, scale=(0.25, 0.2, 1)),
            "bsdf": _diffuse(WHITE),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [17.0, 12.0, 4.0]}},
        }
    from .loader import load_scene

    return load_scene(scene)


SCENES = {
    "cornell-box": (cornell_box, "the original D-ToF Cornell box: point light at the camera, boxes at -10 and +10 m/s"),
    "cornell-box-area": (lambda resolution=256, **kw: cornell_box(resolution, light="area", **kw), "the Cornell box lit by a ceiling area light"),
}


def build(name: str, **kwargs):
    """Build the built-in scene ``name`` (see ``SCENES``)."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")
    return SCENES[name][0](**kwargs)
