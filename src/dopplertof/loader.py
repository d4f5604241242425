"""Loading dynamic scenes from Mitsuba 3 XML files and from Python dicts.

XML: the Mitsuba 3 format (or the original CPU code's Mitsuba 0.6 format, translated by
:mod:`dopplertof.mitsuba06`; ``<include>`` is expanded here for both), plus the original
D-ToF code's motion syntax inside a shape::

    <shape type="cube">
        <animation name="to_world">
            <transform time="0">      <translate x="0" y="0" z="0"/> </transform>
            <transform time="0.0015"> <translate x="0" y="0" z="0.015"/> </transform>
        </animation>
    </shape>

Key times are seconds and strictly increasing; inside each ``<transform>`` the usual
operations (``translate``, ``rotate``, ``scale``, ``matrix``, ``lookat``) compose as in
Mitsuba (each one left-multiplies). Elements the original Mitsuba 3 fork needed that stock
Mitsuba lacks are translated: the ``correlated`` / ``timestratified`` samplers become an
``independent`` sampler (their ``sample_count`` is kept as the default spp), and the
``<integrator>`` element is not instantiated by Mitsuba: its parameters are kept in
``DynamicScene.integrator_params`` for :func:`dopplertof.render`.

Dict: as for ``mi.load_dict``; a shape may carry ``"motion"``:

* a :class:`dopplertof.motion.Motion` object;
* ``{"type": "keyframes", "keys": [(time_s, transform), ...]}`` (transform: 4x4 array,
  ``mi.ScalarTransform4d`` or ``mi.ScalarTransform4f``), replacing the shape's ``to_world``.
  Build keys in double precision (4d or float64 arrays) for slow motions: a float32
  translation of 5 m is quantised to 0.5 µm, 3 % of a 15 µm displacement;
* ``{"type": "parametric", "linear_velocity": ..., "angular_velocity": ..., "pivot": ...}``
  applied on top of the shape's ``to_world``.

In both forms, shapes with identical motion (the same keyframe times and transforms, or
the same parametric velocities and pivot, whatever their ``to_world``) form one rigid body:
each body costs a sub-scene intersection per ray.

Cameras and lights move the same way: an ``<animation>`` in the ``<sensor>`` or in a point
or spot ``<emitter>`` (a ``"motion"`` entry in a dict), area emitters with the shape they
are on. An ``<emitter>`` inside the ``<sensor>`` (in a dict, an emitter dict inside the
sensor's) rides with the camera, placed in its frame. Emitters that cannot move, and
motions that would scale a camera or a point or spot light, are refused.
"""

from __future__ import annotations

import copy
import hashlib
import math
import os
import re
import xml.etree.ElementTree as ET

import numpy as np

from . import mitsuba06
from .modulation import SPEED_OF_LIGHT_M_S
from .motion import SUSPICIOUS_SPEED_M_S, Keyframed, Motion, Parametric, check_speed
from .settings import PLUGIN_NAMES, STOCK_OTHER_INTEGRATORS, STOCK_PATH_INTEGRATORS, check_layer, integrator_layer
from .lights import MovingLight
from .scene import Body, DynamicScene, SceneError
from .tracing.materials import relative_ior
from .xmlsource import Sources
from .xmlvalues import property_value

_SHAPE_TAGS = {"shape"}
_DEFINITION_TAGS = {"bsdf", "texture", "spectrum", "rgb", "default", "medium"}
_ORIGINAL_SAMPLERS = {"correlated", "timestratified"}
MOVABLE_EMITTERS = ("point", "spot")
SHUTTER_PARAMETERS = ("shutter_open", "shutter_close")
SENSOR_TYPES = {"perspective", "thinlens", "orthographic", "radiancemeter", "irradiancemeter", "distant", "batch"}
# Sensors Mitsuba loads that the tracer cannot start paths from (class name -> what to call it).
UNSUPPORTED_SENSORS = {  # class name: (what it is, why not, what to do instead)
    "IrradianceMeter": ("an irradiancemeter", "its rays start on a shape, with no film position",
                        "use radiancemeter or a perspective camera"),
    "BatchSensor": ("a batch sensor", "its cameras' ground truth (radial velocity, velocity_3d, flow) would be taken in the "
                    "batch's frame, not each camera's", "render each of its cameras as a scene of its own"),
}
BLACKBODY_REFUSAL = ("a blackbody spectrum needs a spectral Mitsuba variant, and dopplertof renders in RGB (or mono): "
                     "give the emitter an <rgb> value (its colour and brightness)")
# Sampler properties kept as the render's defaults (DynamicScene fields); its type is not
# (dopplertof draws its own stratified pixel positions and times: docs/scene-format.md).
_SAMPLER_HINTS = {"sample_count": "spp_hint", "seed": "seed_hint"}
EMITTER_TYPES = {"point", "spot", "area", "constant", "envmap", "directional", "directionalarea", "projector"}


def load_scene(source, *, film_resolution=None, **params) -> DynamicScene:
    """Load a dynamic scene from an XML file path or a scene dict.

    Parameters
    ----------
    source : str, os.PathLike or dict
        Path of a Mitsuba 3 XML file (with optional ``<animation>`` motion), of a Mitsuba
        0.6 file of the original D-ToF code (translated by :mod:`dopplertof.mitsuba06`), or
        a dict in ``mi.load_dict`` form (shapes may carry ``"motion"``).
    film_resolution : int or (int, int), optional
        Film (width, height) in pixels (an int: square), replacing the scene's.
    **params
        XML ``$name`` substitutions, as in ``mi.load_file`` (they override ``<default>``).
        A name the file (with its includes) neither declares nor uses is a SceneError
        listing the names it has.

    Returns
    -------
    DynamicScene

    Raises
    ------
    SceneError (a ValueError)
        Naming the file or dict entry: malformed input, an emitter whose radiance,
        intensity or irradiance is not finite or negative, more than one sensor, a
        shutter interval that is not finite or of zero length, a motion key beyond
        :data:`~dopplertof.motion.MAX_COORDINATE_M`, a speed at or above the speed of
        light, bad ``<integrator>`` parameters, unknown ``$name`` parameters.

    Examples
    --------
    A sphere moving at 1 m/s along +z in a dict (``"motion"`` beside the shape's entries):

    >>> import dopplertof as dt
    >>> scene = dt.load_scene({
    ...     "type": "scene",
    ...     "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}},
    ...     "ball": {"type": "sphere", "motion": {"type": "parametric", "linear_velocity": [0, 0, 1]}},
    ...     "light": {"type": "point", "position": [0, 0, -4]},
    ... })
    >>> len(scene.bodies)
    1
    >>> try:
    ...     dt.load_scene("missing.xml")
    ... except dt.SceneError as error:
    ...     print(error)
    missing.xml: scene file not found
    """
    from .backend import ensure_variant

    ensure_variant()
    size = None if film_resolution is None else _film_size(film_resolution)
    if isinstance(source, dict):
        if params:
            raise SceneError(f"<dict>: $name substitutions {sorted(params)} apply to scene files only")
        return _load_dict(source if size is None else _dict_with_film_size(source, size))
    if isinstance(source, (str, os.PathLike)):
        scene = _load_xml(os.fspath(source), params, size)
        scene.recipe = ("file", os.path.abspath(source), params, size)
        return scene
    raise SceneError(f"load_scene expects a file path or a dict, got {type(source).__name__}{loaded_scene_hint(source)}")


def loaded_scene_hint(value) -> str:
    """What to do instead where ``value``, given as a scene, is a loaded ``mi.Scene``: its
    motions, if any, are gone once Mitsuba loaded it.

    Parameters
    ----------
    value : object
        What was given as a scene.

    Returns
    -------
    str
        ``"; …"`` to end an error message with, or empty where ``value`` is no ``mi.Scene``.
    """
    import mitsuba as mi

    if not isinstance(value, mi.Scene):
        return ""
    return ("; a loaded mi.Scene cannot be taken apart again: give its file or dict to dopplertof.load_scene, "
            "or render it with mi.render and the 'dopplertof' integrator (static scenes: docs, the Mitsuba plugin)")


def _film_size(resolution) -> tuple[int, int]:
    """(width, height) from an int or a pair of positive ints."""
    size = (resolution, resolution) if isinstance(resolution, (int, np.integer)) else tuple(resolution) if isinstance(resolution, (tuple, list)) else ()
    if len(size) != 2 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0 for v in size):
        raise SceneError(f"film_resolution must be a positive int or a (width, height) pair of them, got {resolution!r}")
    return int(size[0]), int(size[1])


def _refuse_crop_with_new_size(names, where: str) -> None:
    """A film's crop window is in its own pixels: with another film size it would crop
    something else."""
    crop = [name for name in names if name.startswith("crop_")]
    if crop:
        raise SceneError(f"{where}: <film> has {', '.join(crop)}, a crop window of its own size; a new film size "
                         f"(--resolution, film_resolution=) would crop something else: remove the crop window or keep the size")


def _dict_with_film_size(scene_dict: dict, size) -> dict:
    out = dict(scene_dict)
    for key, value in scene_dict.items():
        if isinstance(value, dict) and isinstance(value.get("film"), dict):
            _refuse_crop_with_new_size(value["film"], f"<dict>: {key}")
            out[key] = {**value, "film": {**value["film"], "width": size[0], "height": size[1]}}
    return out


# ----------------------------------------------------------------------------------------
# Errors


WHAT_MOVES = ("only a top-level shape, emitter or the sensor may move, not a BSDF, a film, an emitter inside a shape, "
              "a shape inside a shapegroup (move the shapegroup's instance) or an emitter inside the sensor (it moves with the camera)")


def _mitsuba_error(where: str, exc: Exception, locate=None) -> SceneError:
    """One readable line from a Mitsuba/Dr.Jit loader exception; ``locate`` (text -> text)
    rewrites a position in the string Mitsuba parsed to the user's file and line."""
    text = " ".join(str(exc).split())
    if locate is not None:
        text = locate(text)
    for marker in ("Error while loading", "Exception: "):
        if marker in text and len(text) > 300:
            text = text[text.find(marker):]
    if "unreferenced" in text.lower():
        hint = " (unknown parameter)"
    elif re.search(r'Plugin "(parametric|keyframed)" not found', text):
        hint = f" (a 'motion' was given where nothing moves: {WHAT_MOVES})"
    elif re.search(r'Plugin "[^"]*" not found', text):
        hint = " (unknown plugin type)"
    elif "not found" in text.lower() or "does not exist" in text.lower():
        hint = " (missing file)"
    else:
        hint = ""
    return SceneError(f"{where}: {text[:500]}{hint}")


# ----------------------------------------------------------------------------------------
# XML


def _floats(text: str, where: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise SceneError(f"{where}: expected numbers, got {text!r}") from None


def _vec(el, where, default=0.0):
    if "value" in el.attrib:
        vals = _floats(el.attrib["value"], where)
        if len(vals) == 1:
            return vals * 3
        if len(vals) != 3:
            raise SceneError(f"{where}: expected 1 or 3 numbers in value={el.attrib['value']!r}")
        return vals
    return [float(_floats(el.attrib.get(k, str(default)), where)[0]) for k in "xyz"]


def _transform_ops(element, where: str) -> np.ndarray:
    """4x4 matrix of the transform operations inside ``element`` (Mitsuba semantics)."""
    import mitsuba as mi

    m = mi.ScalarTransform4d()
    for op in element:
        here = f"{where}, <{op.tag}>"
        if op.tag == "translate":
            m = mi.ScalarTransform4d().translate(_vec(op, here)) @ m
        elif op.tag == "scale":
            m = mi.ScalarTransform4d().scale(_vec(op, here, default=1.0)) @ m
        elif op.tag == "rotate":
            axis = _vec(op, here)
            angle = _floats(op.attrib.get("angle", "nan"), here)[0]
            if not np.isfinite(angle):
                raise SceneError(f"{here}: rotate needs angle=\"degrees\"")
            norm = float(np.linalg.norm(axis))
            if norm == 0:
                raise SceneError(f"{here}: rotate needs a non-zero axis (x, y, z)")
            m = mi.ScalarTransform4d().rotate([a / norm for a in axis], angle) @ m  # Mitsuba's XML normalises it too
        elif op.tag == "matrix":
            vals = _floats(op.attrib.get("value", ""), here)
            if len(vals) not in (9, 16):
                raise SceneError(f"{here}: matrix needs 9 or 16 numbers, got {len(vals)}")
            mat = np.eye(4)
            if len(vals) == 16:
                mat = np.array(vals).reshape(4, 4)
            else:
                mat[:3, :3] = np.array(vals).reshape(3, 3)
            m = mi.ScalarTransform4d(mat.tolist()) @ m
        elif op.tag == "lookat":
            origin = _floats(op.attrib.get("origin", ""), here)
            target = _floats(op.attrib.get("target", ""), here)
            up = _floats(op.attrib.get("up", "0 1 0"), here)
            m = mi.ScalarTransform4d().look_at(origin=origin, target=target, up=up) @ m
        else:
            raise SceneError(f"{here}: unknown transform operation")
    return np.array(m.matrix, dtype=np.float64)


def _parse_animation(anim, where: str) -> Keyframed:
    if anim.attrib.get("name") != "to_world":
        raise SceneError(f"{where}: only <animation name=\"to_world\"> is supported, got name={anim.attrib.get('name')!r}")
    times, mats = [], []
    for i, key in enumerate(anim):
        here = f"{where}, keyframe {i}"
        if key.tag != "transform":
            raise SceneError(f"{here}: <animation> may only contain <transform time=\"...\">, found <{key.tag}>")
        if "time" not in key.attrib:
            raise SceneError(f"{here}: <transform> needs a time=\"seconds\" attribute")
        try:
            t = float(key.attrib["time"])
        except ValueError:
            raise SceneError(f"{here}: keyframe time {key.attrib['time']!r} is not a number") from None
        times.append(t)
        mats.append(_transform_ops(key, here))
    if not times:
        raise SceneError(f"{where}: <animation> has no keyframes")
    try:
        return Keyframed(times, mats, where=where)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _describe(el, index: int) -> str:
    ident = el.attrib.get("id") or el.attrib.get("name")
    return f"<{el.tag} type=\"{el.attrib.get('type', '?')}\"{' id=' + repr(ident) if ident else ''}> #{index}"


_TOKEN = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


def _substitute(root, values: dict, path: str, found: dict) -> dict:
    """Replace ``$name`` in attributes by ``values`` (which win) or the file's ``<default>``s,
    and return the values in force. As Mitsuba 3 (``src/core/xml.cpp``): the first
    definition of a name wins, a default may use earlier ones, and the longest name is
    replaced first, so with ``res`` and ``resx`` defined ``$resx`` is resx's value.
    ``found["defaults"]`` gains the names the file declares, ``found["texts"]`` the
    attribute values that hold a ``$`` (to tell given names the scene does not use)."""
    values = dict(values)

    def replace(el, key):
        val = el.attrib[key]
        found["texts"].append(val)
        for name in sorted(values, key=len, reverse=True):
            val = val.replace(f"${name}", values[name])
        if "$" in val:
            missing = ", ".join(sorted({f"${m}" for m in _TOKEN.findall(val)})) or val
            raise SceneError(f"{path}: unresolved parameter {missing} in <{el.tag} {key}={el.attrib[key]!r}>")
        return val

    for d in root.findall("default"):
        found["defaults"].update([d.attrib["name"]] if "name" in d.attrib else [])
        if "name" in d.attrib and d.attrib["name"] not in values:  # the first definition wins
            values[d.attrib["name"]] = replace(d, "value") if "value" in d.attrib else ""
        root.remove(d)
    for el in root.iter():
        for key, val in el.attrib.items():
            if "$" in val:
                el.attrib[key] = replace(el, key)
    return values


def _parse(path: str, where: str, sources: Sources):
    if not os.path.isfile(path):
        raise SceneError(f"{where}: scene file not found")
    try:
        return sources.parse(path)
    except ET.ParseError as exc:
        raise SceneError(f"{where}: malformed XML ({exc})") from None


def _read_scene(path: str, values: dict, where: str, found: dict, stack: tuple = ()):
    """The ``<scene>`` root of ``path`` with ``$name`` substituted and every ``<include
    filename="...">`` replaced by the included file's elements, recursively (a file name
    is relative to the including file, else to the scene's folder, where Mitsuba's resolver
    looks). ``values`` gains each file's ``<default>``s; a cycle of includes is an error,
    and so is mixing Mitsuba 0.6 and 3 versions."""
    root = _parse(path, where, found["sources"])
    stack = (*stack, os.path.abspath(path))
    values.update(_substitute(root, values, path, found))
    for parent in list(root.iter()):
        for index, inc in reversed(list(enumerate(parent))):
            if inc.tag != "include":
                continue
            name = inc.attrib.get("filename", "")
            here = f"{path}: <include filename={name!r}>"
            candidates = [os.path.join(os.path.dirname(stack[-1]), name), os.path.join(os.path.dirname(stack[0]), name)]
            target = os.path.abspath(next((c for c in candidates if name and os.path.isfile(c)), candidates[0]))
            if target in stack:
                raise SceneError(f"{here}: include cycle ({' -> '.join(os.path.basename(p) for p in (*stack, target))})")
            included = _read_scene(target, values, f"{here}: {target}", found, stack)
            if included.tag != "scene":
                parent[index:index + 1] = [included]
                continue
            versions = [r.attrib.get("version", "") for r in (root, included)]
            if "" not in versions and len({v.startswith("0.") for v in versions}) > 1:
                raise SceneError(f"{here}: version {versions[1]!r} mixes the Mitsuba 0.6 and 3 formats (the scene is {versions[0]!r})")
            parent[index:index + 1] = list(included)
    return root


def _set_film_size(root, size, path: str) -> None:
    for film in root.iter("film"):
        _refuse_crop_with_new_size([p.attrib.get("name", "") for p in film], path)
        for p in [p for p in film if p.attrib.get("name") in ("width", "height")]:
            film.remove(p)
        film.extend(ET.Element("integer", {"name": n, "value": str(v)}) for n, v in zip(("width", "height"), size))


def _load_xml(path: str, params: dict, film_size=None) -> DynamicScene:
    import mitsuba as mi

    sources = Sources()
    found = {"defaults": set(), "texts": [], "sources": sources}
    root = _read_scene(path, {k: str(v) for k, v in params.items()}, path, found)
    digest = hashlib.sha256(ET.tostring(root)).hexdigest()  # includes expanded, $names substituted
    known = found["defaults"] | {m for text in found["texts"] for m in _TOKEN.findall(text)}
    unknown = [n for n in params if n not in known]  # whole names: -D sp=8 does not set $spp
    if unknown:
        known = sorted(known)
        raise SceneError(
            f"{path}: unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join('$' + n for n in unknown)}; "
            f"the scene's parameters: {', '.join('$' + n for n in known) if known else 'none'}"
        )
    if root.tag != "scene":
        raise SceneError(f"{path}: the root element must be <scene>, got <{root.tag}>")
    strict_normals = mitsuba06.is_legacy(root) and mitsuba06.translate(root, path)
    if film_size is not None:
        _set_film_size(root, film_size, path)
    scene_dir = os.path.dirname(os.path.abspath(path))

    integrator_params: dict = {}
    hints = {}  # the sampler's sample_count and seed
    definitions = [el for el in root if el.tag in _DEFINITION_TAGS and "id" in el.attrib]
    shape_groups = {el.attrib["id"]: el for el in root if el.tag == "shape" and el.get("type") == "shapegroup" and "id" in el.attrib}
    moving = []  # (motion, (index, element)) of every animated shape
    moving_lights = []  # (where, element, motion) of every animated emitter
    attached = []  # (element, where) of the emitters inside the sensor
    camera_motion = None
    shutter_given = False
    for index, el in enumerate(list(root)):
        where = f"{path}: {_describe(el, index)}"
        if any(sp.get("type") == "blackbody" for sp in el.iter("spectrum")):
            raise SceneError(f"{where}: {BLACKBODY_REFUSAL}")
        if el.tag in ("sampler", "film"):
            raise SceneError(f"{where}: a <{el.tag}> outside the <sensor> is ignored by Mitsuba; move it into the <sensor>")
        if el.tag == "integrator":
            if integrator_params:
                raise SceneError(f"{where}: a second <integrator>; a scene has one (Mitsuba refuses two as well)")
            integrator_params["type"] = el.attrib.get("type")
            for p in el:
                if "name" in p.attrib:
                    integrator_params[p.attrib["name"]] = property_value(p, where)
            root.remove(el)
        elif el.tag == "sensor":
            camera_motion = _pull_animation(el, where) or camera_motion
            shutter_given |= any(p.attrib.get("name") in SHUTTER_PARAMETERS for p in el)
            attached += [(em, f"{where}, <emitter> #{k}") for k, em in enumerate(el.findall("emitter"))]
            for em in el.findall("emitter"):
                el.remove(em)
            for sampler in el.findall("sampler"):
                for p in sampler:
                    if p.attrib.get("name") in _SAMPLER_HINTS:
                        hints[_SAMPLER_HINTS[p.attrib["name"]]] = property_value(p, where)
                if sampler.attrib.get("type") in _ORIGINAL_SAMPLERS:
                    sampler.attrib["type"] = "independent"
                    for p in list(sampler):
                        if p.attrib.get("name") not in ("sample_count", "seed"):
                            sampler.remove(p)
        elif el.tag == "emitter":
            motion = _pull_animation(el, where)
            if motion is not None:
                _check_movable_emitter(el.attrib.get("type"), where)
                if el.find("point[@name='position']") is not None:
                    raise SceneError(f"{where}: has both a position and an <animation>; keyframes place the light, remove the position")
                moving_lights.append((where, el, motion))
                root.remove(el)
        elif el.tag in _SHAPE_TAGS:
            motion = _pull_animation(el, where)
            if motion is not None:
                moving.append((motion, (index, el)))
                root.remove(el)

    for element in [root] + [el for _, (_, el) in moving] + [el for _, el, _ in moving_lights] + [el for el, _ in attached]:
        for parent in element.iter():
            for anim in parent.findall("animation"):
                raise SceneError(f"{path}: an <animation> inside <{parent.tag} type=\"{parent.attrib.get('type', '?')}\"> "
                                 f"({sources.where(anim) or 'in the scene'}): {WHAT_MOVES}")
    host = None
    if moving:
        elements = [root] + [el for _, (_, el) in moving]
        host = pipeline_host({shape.attrib.get("type") for el in elements for shape in el.iter("shape")}, path)

    def load_all():
        """The static scene, the bodies and the moving lights (relative paths resolved in the scene's folder)."""
        try:
            xml = ET.tostring(root, encoding="unicode")
            static = mi.load_string(xml) if host is None else _load_guest_string(xml, host)
        except Exception as exc:  # noqa: BLE001
            raise _mitsuba_error(path, exc, lambda text: sources.locate(text, xml, root)) from None
        if not static.sensors():
            raise SceneError(f"{path}: the scene has no <sensor>")
        bodies = []
        for motion, members in _group_by_motion(moving):
            body_root = ET.Element("scene", {"version": root.attrib.get("version", "3.0.0")})
            for d in definitions:
                body_root.append(copy.deepcopy(d))
            used_groups = {ref.get("id") for _, el in members for ref in el.iter("ref")} & shape_groups.keys()
            for group in sorted(used_groups):  # a moving instance's shapegroup (it renders nothing itself)
                body_root.append(copy.deepcopy(shape_groups[group]))
            for _, el in members:
                body_root.append(el)
            name = ", ".join(el.attrib.get("id", f"shape #{i}") for i, el in members)
            body_xml = ET.tostring(body_root, encoding="unicode")
            try:
                body_scene = _load_guest_string(body_xml, host)
            except Exception as exc:  # noqa: BLE001
                raise _mitsuba_error(f"{path}: moving shape(s) {name}", exc, lambda text: sources.locate(text, body_xml, body_root)) from None
            bodies.append(_make_body(name, body_scene, motion, f"{path}: moving shape(s) {name}",
                                     load_copy=lambda xml=body_xml: _in_folder(scene_dir, lambda: _load_guest_string(xml, host))))

        def light_scene(element, where):
            light_root = ET.Element("scene", {"version": root.attrib.get("version", "3.0.0")})
            light_root.extend([copy.deepcopy(d) for d in definitions] + [element])
            light_xml = ET.tostring(light_root, encoding="unicode")
            try:
                return mi.load_string(light_xml)
            except Exception as exc:  # noqa: BLE001
                raise _mitsuba_error(where, exc, lambda text: sources.locate(text, light_xml, light_root)) from None

        lights = [MovingLight(where, light_scene(el, where), motion) for where, el, motion in moving_lights]
        for el, where in attached:
            _check_movable_emitter(el.attrib.get("type"), where, attached=True)
            lights.append(MovingLight(where, light_scene(el, where), _camera_light_motion(static, camera_motion, path), with_camera=True))
        return static, bodies, lights

    static, bodies, lights = _in_folder(scene_dir, load_all)
    if strict_normals:
        mitsuba06.check_flat_shading([static, *(b.scene for b in bodies)], path)
    scene = DynamicScene(
        static=static, bodies=bodies, integrator_params=integrator_params, **hints, source=path, content_digest=digest,
        camera_motion=camera_motion, lights=lights, pipeline_host=host,
    )  # fmt: skip
    return _checked_scene(scene, shutter_given)


def _pull_animation(el, where: str):
    """The keyframed motion of ``el``'s ``<animation>`` (removed from it), or None."""
    anims = el.findall("animation")
    if not anims:
        return None
    if len(anims) > 1:
        raise SceneError(f"{where}: more than one <animation>")
    if any(t.attrib.get("name") == "to_world" for t in el.findall("transform")):
        raise SceneError(f"{where}: has both <transform name=\"to_world\"> and <animation>; keep one")
    motion = _parse_animation(anims[0], where)
    el.remove(anims[0])
    return motion


def _check_movable_emitter(kind, where: str, attached: bool = False) -> None:
    if kind not in MOVABLE_EMITTERS:
        if attached:
            raise SceneError(f"{where}: an emitter of type {kind!r} inside the <sensor> would move with the camera, and it cannot move; "
                             f"the lights a camera carries are {', '.join(MOVABLE_EMITTERS)} emitters")
        raise SceneError(f"{where}: an emitter of type {kind!r} cannot move; moving lights are {', '.join(MOVABLE_EMITTERS)} emitters, or area emitters on a moving shape")


def _camera_light_motion(static, camera_motion, where: str) -> Motion:
    """The motion of a light attached to the camera (placed in the sensor's frame): the
    camera's motion after the sensor's own ``to_world``."""
    to_world = np.array(static.sensors()[0].world_transform().matrix, dtype=np.float64).reshape(4, 4)  # (4, 4, 1): one lane
    if camera_motion is None:
        return Parametric(base=to_world, where=f"{where}: the sensor's to_world")
    if isinstance(camera_motion, Parametric) and np.array_equal(camera_motion.base, np.eye(4)):
        return Parametric(camera_motion.linear_velocity, camera_motion.angular_velocity, camera_motion.pivot, base=to_world, where=where)
    if np.allclose(to_world, np.eye(4), rtol=0, atol=1e-6):  # the camera's motion places it
        return camera_motion
    raise SceneError(f"{where}: a light attached to a camera whose motion is a {type(camera_motion).__name__} on top of a to_world is not supported")


def _checked_scene(scene: DynamicScene, shutter_given: bool = False) -> DynamicScene:
    """Refuse what the tracer would silently drop, and validate the ``<integrator>`` now
    (not after a long render): participating media, emitters or sensors on moving bodies,
    more than one sensor, a shutter interval that is not finite or (``shutter_given``: the
    scene sets it) of zero length, bad integrator parameters."""
    import mitsuba as mi

    where = scene.source
    n_sensors = len(scene.static.sensors())
    if n_sensors > 1:
        raise SceneError(f"{where}: the scene has {n_sensors} sensors; dopplertof renders one (remove the others)")
    if scene.sensor.class_name() in UNSUPPORTED_SENSORS:
        what, why, instead = UNSUPPORTED_SENSORS[scene.sensor.class_name()]
        raise SceneError(f"{where}: the sensor is {what} ({why}), which dopplertof does not render; {instead}")
    pixel_format = re.search(r"pixel_format = (\w+)", str(scene.sensor.film()))
    if pixel_format and pixel_format.group(1) != ("rgb" if mi.is_rgb else "y"):  # y: luminance, which a mono variant sets
        named = {"y": "luminance", "ya": "luminance_alpha"}.get(pixel_format.group(1), pixel_format.group(1))  # Mitsuba's short names
        raise SceneError(f"{where}: the film's pixel_format is {named!r}; dopplertof writes the intensity as RGB "
                         "(luminance in a mono variant, coverage.exr for what alpha holds): remove pixel_format or give 'rgb'")
    open_s, length_s = float(scene.sensor.shutter_open()), float(scene.sensor.shutter_open_time())
    if not (np.isfinite(open_s) and np.isfinite(length_s)):
        raise SceneError(f"{where}: the sensor's shutter_open={open_s!r} and shutter_close={open_s + length_s!r} s must be finite")
    if shutter_given and length_s == 0:
        raise SceneError(
            f"{where}: the sensor's shutter_open and shutter_close are both {open_s!r} s, a shutter that never opens; "
            "give shutter_close > shutter_open, or neither (the exposure is then the <integrator>'s or the default)"
        )
    for label, mi_scene in [("", scene.static)] + [(f"moving body {b.name!r}: ", b.scene) for b in scene.bodies]:
        for shape in mi_scene.shapes():
            try:
                if shape.bsdf() is not None:
                    relative_ior(shape.bsdf())
            except ValueError as exc:
                raise SceneError(f"{where}: {label}shape {shape.id() or shape.class_name()!r}: {exc}") from None
            box = shape.bbox()  # (an empty mesh's box is invalid, +inf to -inf: nothing to refuse)
            corners = [float(v) for c in (box.min, box.max) for v in (c.x, c.y, c.z)]
            if any(math.isnan(v) for v in corners) or (box.valid() and not all(map(math.isfinite, corners))):
                raise SceneError(f"{where}: {label}shape {shape.id() or shape.class_name()!r} has a position or size that is not finite "
                                 "(NaN or inf in its transform or its parameters); it would render as nothing")
            if shape.interior_medium() is not None or shape.exterior_medium() is not None:
                raise SceneError(f"{where}: {label}shape {shape.id() or shape.class_name()!r} has a participating medium; media are not supported (remove the <medium> or render with stock Mitsuba's volpath)")
        if label and mi_scene.sensors():
            raise SceneError(f"{where}: {label}carries a sensor; a camera moves by its own <animation> (XML) or 'motion' (dict)")
    for label, motion in [("the sensor", scene.camera_motion)] + [(f"moving light {light.name!r}", light.motion) for light in scene.lights]:
        if motion is not None and not motion.is_rigid():
            raise SceneError(f"{where}: {label} has a motion that scales (its keys carry a scale, even one that does not change, "
                             "such as an orthographic sensor's extent); cameras and point or spot lights may only move rigidly")
    for body in scene.bodies:
        if body.scene.emitters() and not body.motion.is_conformal():
            raise SceneError(
                f"{where}: moving body {body.name!r} carries an emitter and its motion's keys scale the axes differently; "
                "give the shape its own to_world and a parametric motion, or keys that scale every axis equally"
            )
    for sensor in scene.static.sensors():
        if sensor.get_medium() is not None:
            raise SceneError(f"{where}: the sensor is inside a participating medium; media are not supported")
    from .tracing.film import FilterSampler

    width, height = scene.resolution
    if width < 1 or height < 1:
        raise SceneError(f"{where}: the film must be at least 1x1 pixels, got {width}x{height}")
    try:
        FilterSampler(scene.sensor.film())
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None
    if scene.integrator_params:
        try:
            check_layer(integrator_layer(scene.integrator_params, f"{where}: <integrator>"), f"{where}: <integrator>")
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return scene


def _motion_key(motion: Motion):
    """Hashable identity of a motion: equal keys move every point the same way."""
    if isinstance(motion, Keyframed):
        return ("keyframes", motion.times.tobytes(), motion.translations.tobytes(), motion.quaternions.tobytes(), motion.scales.tobytes())
    if isinstance(motion, Parametric):
        parts = (motion.linear_velocity, motion.angular_velocity, motion.pivot, motion.base)
        return ("parametric", *(np.asarray(x, dtype=np.float64).tobytes() for x in parts))
    return ("object", id(motion))


def _group_by_motion(moving):
    """Group ``(motion, member)`` pairs by identical motion: ``[(motion, [members])]`` in
    order of first appearance. Every body is a sub-scene intersected by every ray (DESIGN
    §3.1), so shapes moving together are one body."""
    groups: dict = {}
    for motion, member in moving:
        groups.setdefault(_motion_key(motion), (motion, []))[1].append(member)
    return list(groups.values())


# ----------------------------------------------------------------------------------------
# One OptiX pipeline and shader binding table per DynamicScene (gpu-notes §1)
#
# Dr.Jit allows one OptiX pipeline and SBT per kernel and turns every other trace into a
# silent miss; the static scene and the bodies' scenes are traced in one kernel. So they
# are loaded as *guests* of one *host* (Mitsuba's shared-SBT mechanism: a scene given a
# ``Scene`` property appends its hit records to that scene's SBT and uses its pipeline).
# The host is never traced: a small rectangle (triangles) plus one shape of each analytic
# type the scene uses, since a guest's shape types must be in the host's pipeline. Every
# guest names that one host, never another guest (a guest's SBT is a snapshot). On LLVM
# the same code runs (Embree ignores the host), so the CPU tests exercise it.

ANALYTIC_SHAPES = ("sphere", "disk", "cylinder")  # the analytic shape plugins a host covers
# Analytic shapes a host cannot cover (they need data files): refused on CUDA, where a
# guest of theirs would fail to load ("shape type not mapped").
UNCOVERED_SHAPES = ("bsplinecurve", "linearcurve", "sdfgrid", "ellipsoids")
HOST_KEY = "parent_scene"  # the property Mitsuba itself names a host by


def pipeline_host(types, where: str):
    """The host scene (above) of guests whose plugin names are among ``types``; a
    SceneError naming ``where`` and the shape type where CUDA cannot host them."""
    import mitsuba as mi

    uncovered = sorted(set(types) & set(UNCOVERED_SHAPES))
    if uncovered and mi.variant().startswith("cuda"):
        raise SceneError(
            f"{where}: a scene with moving bodies cannot use shape type {uncovered[0]!r} on {mi.variant()} "
            f"(its OptiX pipeline covers meshes and {', '.join(ANALYTIC_SHAPES)}); use a mesh or the llvm variant"
        )
    entries = {"probe-mesh": {"type": "rectangle"}}
    entries.update({f"probe-{name}": {"type": name} for name in ANALYTIC_SHAPES if name in types})
    return mi.load_dict({"type": "scene", **entries})


def _plugin_types(value) -> set:
    """Every plugin name (``"type"``) in a scene dict (or a part of one)."""
    if isinstance(value, dict):
        found = {value["type"]} if isinstance(value.get("type"), str) else set()
        return found.union(*(_plugin_types(v) for v in value.values()))
    return set()


def _load_guest_string(xml: str, host):
    """``mi.load_string(xml)`` as a guest of ``host`` (what load_string does, the host
    added before the objects are made)."""
    import mitsuba as mi

    config = mi.parser.ParserConfig(mi.variant())
    state = mi.parser.parse_string(config, xml)
    mi.parser.transform_all(config, state)
    state.root.props[HOST_KEY] = host
    return mi.parser.instantiate(config, state)


def _in_folder(folder: str, load):
    """``load()`` with ``folder`` first on Mitsuba's search path (a scene's relative mesh
    and texture paths), the search path restored after."""
    import mitsuba as mi

    resolver = mi.file_resolver()
    saved_paths = [str(resolver[i]) for i in range(len(resolver))]
    resolver.prepend(folder)
    try:
        return load()
    finally:
        resolver.clear()
        for entry in saved_paths:
            resolver.append(entry)


def _make_body(name: str, scene, motion: Motion, where: str, load_copy=None) -> Body:
    """A moving body; SceneError where a point of it would move at or above the speed of
    light (rotation included), a warning above :data:`dopplertof.motion.SUSPICIOUS_SPEED_M_S`."""
    bbox = scene.bbox()
    lo = np.array([bbox.min.x, bbox.min.y, bbox.min.z], dtype=np.float64)
    hi = np.array([bbox.max.x, bbox.max.y, bbox.max.z], dtype=np.float64)
    speed = motion.max_point_speed(lo, hi)
    if speed > SUSPICIOUS_SPEED_M_S >= motion.checked_speed_m_s or speed >= SPEED_OF_LIGHT_M_S:
        try:  # (a fast translation alone the motion itself has warned of)
            check_speed(speed, "the fastest corner of its bounding box, rotation included", where)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return Body(name=name, scene=scene, motion=motion, bounds_local=(lo, hi), load_copy=load_copy)


# ----------------------------------------------------------------------------------------
# Dict


def _as_matrix(value, where: str) -> np.ndarray:
    import mitsuba as mi

    if isinstance(value, (mi.ScalarTransform4d, mi.ScalarTransform4f)):
        return np.array(value.matrix, dtype=np.float64)
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (4, 4):
        raise SceneError(f"{where}: expected a 4x4 transform, got shape {arr.shape}")
    return arr


_MOTION_KEYS = {
    "keyframes": {"type", "keys"},
    "parametric": {"type", "linear_velocity", "angular_velocity", "pivot"},
}


def _motion_from_dict(spec, has_to_world: bool, where: str) -> Motion:
    """The motion of a dict shape. A parametric one is returned about the world origin
    (no base): it acts on top of the shape's ``to_world``, which stays with the shape
    (see :func:`_shared_placement_as_base`)."""
    if isinstance(spec, Motion):
        return spec
    if not isinstance(spec, dict) or spec.get("type") not in _MOTION_KEYS:
        raise SceneError(f"{where}: 'motion' must be a Motion or a dict with type 'keyframes' or 'parametric', got {spec!r}")
    unknown = set(spec) - _MOTION_KEYS[spec["type"]]
    if unknown:
        raise SceneError(f"{where}: unknown motion parameter(s) {sorted(unknown)} for type {spec['type']!r}")
    try:
        if spec["type"] == "keyframes":
            if has_to_world:
                raise SceneError(f"{where}: keyframed motion replaces 'to_world'; remove one of them")
            keys = spec.get("keys") or []
            times = []
            for k in keys:
                if not isinstance(k, (tuple, list)) or len(k) != 2:
                    got = f"{len(k)} entries" if isinstance(k, (tuple, list)) else f"a {type(k).__name__}"
                    raise SceneError(f"{where}: a keyframe is a pair (time_s, transform), got {got}")
                if isinstance(k[0], (str, bool)):
                    raise SceneError(f"{where}: keyframe time {k[0]!r} is not a number")
                try:
                    times.append(float(k[0]))
                except (TypeError, ValueError):
                    raise SceneError(f"{where}: keyframe time {k[0]!r} is not a number") from None
            return Keyframed(times, [_as_matrix(k[1], where) for k in keys], where=where)
        return Parametric(
            spec.get("linear_velocity", (0, 0, 0)),
            spec.get("angular_velocity", (0, 0, 0)),
            spec.get("pivot", (0, 0, 0)),
            where=where,
        )
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _shared_placement_as_base(motion: Motion, members):
    """Make the ``to_world`` shared by every shape of a parametric body its motion's base.

    ``members`` are ``(key, shape dict, to_world matrix or None)``. Shapes placed
    differently keep their ``to_world`` and the body's frame is the world at t = 0; a
    shared one (a lone shape's, say) moves into the motion, so the body's frame is the
    shapes' own, where their geometry is smallest and Float32 hit points most precise.
    Returns ``(motion, [(key, shape dict)])``.
    """
    import mitsuba as mi

    placements = [placement for _, _, placement in members]
    shared = placements[0] is not None and all(p is not None and np.array_equal(p, placements[0]) for p in placements)
    if isinstance(motion, Parametric) and shared:
        try:
            based = Parametric(motion.linear_velocity, motion.angular_velocity, motion.pivot, base=placements[0])
        except ValueError:  # sheared: a shape's to_world may be, a rigid motion's base may not
            pass
        else:
            carries_emitter = any(isinstance(v, dict) and v.get("type") in EMITTER_TYPES for _, shape, _ in members for v in shape.values())
            if not (carries_emitter and not based.is_conformal()):  # an emitter keeps a per-axis scale in its shape
                return based, [(key, {k: v for k, v in shape.items() if k != "to_world"}) for key, shape, _ in members]
    # Mitsuba takes a transform object, not the 4x4 arrays a motion's base may be given as.
    return motion, [(key, shape if p is None else {**shape, "to_world": mi.ScalarTransform4d(p)}) for key, shape, p in members]


def _referencer(scene_dict: dict):
    """A function of ``entries`` (a dict of scene entries) giving the top-level entries of
    ``scene_dict`` they refer to by ``{"type": "ref", "id": ...}``, directly or through
    each other, in the scene's order (a definition before its users).

    A moving shape or light is loaded into a scene of its own, which must hold the objects
    it refers to (``mi.cornell_box()``'s boxes refer to its top-level ``"white"`` BSDF), as
    the XML loader copies the file's definitions into each body's scene. The scene is
    indexed once, so that a scene of N bodies takes time linear in N."""
    by_id = {(v.get("id", k) if isinstance(v, dict) else k): (k, v) for k, v in scene_dict.items() if k != "type"}
    order = {k: i for i, k in enumerate(scene_dict)}

    def referenced(entries: dict) -> dict:
        found: dict = {}
        pending = list(entries.values())
        while pending:
            value = pending.pop()
            if isinstance(value, dict):
                ident = value.get("id") if value.get("type") == "ref" else None
                if isinstance(ident, str) and ident in by_id and by_id[ident][0] not in found and by_id[ident][0] not in entries:
                    key, target = by_id[ident]
                    found[key] = target
                    pending.append(target)
                pending.extend(value.values())
        return {k: found[k] for k in sorted(found, key=order.__getitem__)}

    return referenced


def _is_integrator(value) -> bool:
    """Whether a scene dict's entry is an integrator: ours, a stock one (C++ plugins by
    Mitsuba's plugin registry, the Python ones by name) or any other Mitsuba knows."""
    import mitsuba as mi

    kind = value.get("type") if isinstance(value, dict) else None
    if not isinstance(kind, str):
        return False
    if kind in PLUGIN_NAMES + STOCK_PATH_INTEGRATORS + STOCK_OTHER_INTEGRATORS:
        return True
    return mi.PluginManager.instance().plugin_type(kind) == mi.ObjectType.Integrator


def _load_dict(scene_dict: dict) -> DynamicScene:
    import mitsuba as mi

    if scene_dict.get("type") != "scene":
        raise SceneError("<dict>: a scene dict needs 'type': 'scene'")
    static_dict = {}
    moving = []  # (motion, (key, shape dict, to_world matrix or None)) of every moving shape
    moving_lights = []  # (where, emitter dict, motion) of every moving emitter
    attached = []  # (where, emitter dict) of the emitters inside the sensor
    camera_motion = None
    shutter_given = False
    integrator_params = {}
    hints = {}  # the sampler's sample_count and seed
    for key, value in scene_dict.items():
        where = f"<dict>: entry {key!r}"
        if "blackbody" in _plugin_types(value):
            raise SceneError(f"{where}: {BLACKBODY_REFUSAL}")
        if _is_integrator(value):  # kept for the render, which refuses what it cannot honour
            if integrator_params:
                raise SceneError(f"{where}: a second integrator; a scene has one (Mitsuba refuses two as well)")
            integrator_params = {k: v for k, v in value.items()}
            continue
        kind = value.get("type") if isinstance(value, dict) else None
        if kind in SENSOR_TYPES:
            sensor = dict(value)
            shutter_given |= any(k in sensor for k in SHUTTER_PARAMETERS)
            sampler = sensor.get("sampler")
            if isinstance(sampler, dict):
                hints.update({_SAMPLER_HINTS[k]: v for k, v in sampler.items() if k in _SAMPLER_HINTS})
            if "motion" in sensor:
                spec = sensor.pop("motion")
                if isinstance(spec, Motion):
                    sensor.pop("to_world", None)  # a Motion object places the camera itself
                camera_motion = _motion_from_dict(spec, "to_world" in sensor, where)
            for name, child in list(sensor.items()):
                if isinstance(child, dict) and child.get("type") in EMITTER_TYPES:
                    _check_movable_emitter(child["type"], f"{where}, {name!r}")
                    attached.append((f"{where}, {name!r}", sensor.pop(name)))
            static_dict[key] = sensor
        elif kind in EMITTER_TYPES and "motion" in value:
            _check_movable_emitter(kind, where)
            light = dict(value)
            spec = light.pop("motion")
            if isinstance(spec, Motion):
                light.pop("to_world", None)
            moving_lights.append((where, light, _motion_from_dict(spec, "to_world" in light or "position" in light, where)))
        elif isinstance(value, dict) and "motion" in value:
            shape = dict(value)
            spec = shape.pop("motion")
            if isinstance(spec, Motion):
                shape.pop("to_world", None)  # a Motion object places the shape itself
            motion = _motion_from_dict(spec, "to_world" in shape, where)
            placement = _as_matrix(shape["to_world"], where) if "to_world" in shape else None
            moving.append((motion, (key, shape, placement)))
        else:
            static_dict[key] = value
    host = pipeline_host(_plugin_types(scene_dict), "<dict>") if moving else None
    referenced = _referencer(scene_dict)
    guest = {} if host is None else {HOST_KEY: host}
    bodies = []
    for motion, members in _group_by_motion(moving):
        motion, shapes = _shared_placement_as_base(motion, members)
        keys = [key for key, _ in shapes]
        where = f"<dict>: entr{'y' if len(keys) == 1 else 'ies'} {', '.join(repr(k) for k in keys)}"
        body_dict = {"type": "scene", **guest, **referenced(dict(shapes)), **dict(shapes)}
        try:
            body_scene = mi.load_dict(body_dict)
        except Exception as exc:  # noqa: BLE001
            raise _mitsuba_error(where, exc) from None
        bodies.append(_make_body(", ".join(keys), body_scene, motion, where, load_copy=lambda d=body_dict: mi.load_dict(d)))
    try:
        static = mi.load_dict({**static_dict, **guest})
    except Exception as exc:  # noqa: BLE001
        raise _mitsuba_error("<dict>", exc) from None
    if not static.sensors():
        raise SceneError("<dict>: the scene has no sensor")

    def light_scene(emitter, where):
        try:
            return mi.load_dict({"type": "scene", **referenced({"light": emitter}), "light": emitter})
        except Exception as exc:  # noqa: BLE001
            raise _mitsuba_error(where, exc) from None

    lights = [MovingLight(where, light_scene(light, where), motion) for where, light, motion in moving_lights]
    lights += [MovingLight(where, light_scene(light, where), _camera_light_motion(static, camera_motion, where), with_camera=True) for where, light in attached]
    scene = DynamicScene(static=static, bodies=bodies, integrator_params=integrator_params, **hints, camera_motion=camera_motion, lights=lights, pipeline_host=host)
    return _checked_scene(scene, shutter_given)
