"""Pieces of Mitsuba scene dicts that tests build their small scenes from.

Import after ``conftest`` has set the variant (pytest does): the transforms are Mitsuba's.
"""

import mitsuba as mi

T = mi.ScalarTransform4f


def grey(value):
    """A diffuse BSDF of reflectance ``value`` in every channel."""
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [value] * 3}}


def perspective(origin, target, fov_deg, resolution, **extra):
    """A perspective sensor at ``origin`` (m) looking at ``target`` (up +y), ``fov_deg``
    degrees, a square film of ``resolution`` pixels with a box filter (a pixel is the average
    over its own area, as in dopplertof.render); ``extra`` entries (e.g. a sampler) added."""
    return {
        "type": "perspective",
        "fov": fov_deg,
        "to_world": T().look_at(origin=list(origin), target=list(target), up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
        **extra,
    }
