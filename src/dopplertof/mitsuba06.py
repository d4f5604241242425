"""Mitsuba 0.6 scene files (the original D-ToF CPU code's format) as Mitsuba 3 trees.

:func:`translate` rewrites, in place, the XML tree of a 0.6 scene into the Mitsuba 3
tree :mod:`dopplertof.loader` reads, and the ``<integrator type="dopplertofpath">``
element's 0.6 keys into the parameter names :func:`dopplertof.settings.integrator_layer`
takes. A file is 0.6 when its root's ``version`` starts with ``0.`` or it holds 0.6-only
constructs (:func:`is_legacy`). ``<include>`` is expanded by the loader before this runs.

Scene elements
--------------
* property names go from camelCase to snake_case by Mitsuba 3's own upgrade rule
  (``toWorld`` → ``to_world``, also ``<animation name="toWorld">``; ``sampleCount``,
  ``fovAxis``, ``nearClip``, ``focusDistance``, ``apertureRadius``, ``shutterOpen``,
  ``intIOR`` → ``int_ior``, ``specularReflectance``, ``faceNormals``, ``flipNormals``, ...),
  ``<lookAt>`` → ``<lookat>``, a diffuse ``diffuseReflectance`` → ``reflectance``;
* ``<srgb>`` (gamma-encoded, ``#rrggbb`` or three numbers) → linear ``<rgb>``; the
  ``intent`` attribute of ``<rgb>``/``<srgb>``/``<spectrum>`` is dropped: it only steers
  spectral upsampling, which an RGB build (the original's) does not do;
* ``mfilm`` → ``hdrfilm`` with mfilm's defaults made explicit (1×1 pixels, box filter), but
  its default luminance output: the measurements are one number a pixel anyway, and the
  intensity is written as RGB (a ``pixelFormat`` other than ``rgb`` given is refused);
  ``fileFormat`` (matlab/mathematica/numpy), ``digits``, ``variable``, ``banner`` and
  ``attachLog`` only shape the written file and are dropped; ``pixelFormat`` keeps its
  value (``luminanceAlpha`` → ``luminance_alpha``; ``spectrum*`` has no Mitsuba 3
  equivalent: error); ``highQualityEdges`` → ``sample_border``;
* every sampler → ``independent`` (dopplertof draws from its own streams; only the count
  and ``seed`` matter, ``dimension``/``scramble`` are dropped). 0.6's ``sampleCount``
  counts camera samples, each tracing every one of the integrator's n times; our spp counts
  paths, so ``sample_count`` = sampleCount × n;
* ``conductor``/``roughconductor`` without ``material``/``eta``/``k`` get 0.6's default
  ``material="Cu"`` (Mitsuba 3's default is a perfect mirror); ``roughdiffuse``
  (Oren–Nayar, absent from Mitsuba 3) is ``diffuse`` when ``alpha`` is 0, else an error;
* the D-ToF sensor leftovers ``timeSampleCount``, ``timeSamplingType``,
  ``useSameTimeSamplesOverPathSpace``, ``useAntitheticSampling``, ``usePixelCorrelation``
  and ``sampleTime`` were read by no code (reference §2.1) and are dropped;
* with the D-ToF integrator the sensor's shutter must be [0, ``time``] (the original maps
  u ∈ [0, 1) to ``shutterOpen + u·(shutterClose − shutterOpen)`` and modulates with that
  absolute time; its default shutter is [0, 0]).

Anything else Mitsuba 3 does not know stays as it is and Mitsuba 3 refuses it, naming it
(an unreferenced property, an unknown plugin or tag).

Integrator ``dopplertofpath`` (reference §8.1)
----------------------------------------------
==================================  ======  =================================  =========================================
0.6 key                             type    our setting                        note
==================================  ======  =================================  =========================================
``maxDepth``                        int     ``max_depth``                      same semantics
``rrDepth``                         int     ``rr_depth``                       paired modes use no RR (as the original)
``hideEmitters``                    bool    ``hide_emitters``
``strictNormals``                   bool    –                                  false is Mitsuba 3's behaviour; true is
                                                                               accepted where it changes nothing (every
                                                                               shading normal is the geometric one: no
                                                                               smooth-shaded mesh, no bump/normal map),
                                                                               else an error
``time``, ``w_g``, ``w_s``,         float   same names                         exposure T [s], MHz, rad, fractions of 2π
``g_1``, ``g_0``,
``sensor_phase_offset``,
``hetero_offset``,
``hetero_frequency``
``wave_function_type``              string  ``wave_function_type``
``low_srequency_component_only``    bool    ``low_frequency_component_only``   the key the original really read
``low_frequency_component_only``    bool    (same)                             the documented key, which the original
                                                                               ignored (always low-pass): true is
                                                                               accepted, false is an error (ambiguous)
``time_sampling_mode``              string  ``time_sampling``                  uniform (0.6 default), stratified,
                                                                               antithetic, antithetic_mirror, analytic
``antithetic_shifts``               string  ``antithetic_shift`` /             whitespace-separated; default "0.5"
                                            ``n_times``                        ("0.0" for mirror); one shift → the
                                                                               shift, n = 2; k shifts → n = k + 1, which
                                                                               antithetic needs to be {i/n}; uniform and
                                                                               stratified use only the count
``antithetic_shifts_number``        int     ``n_times``                        K > 0: shifts {i/K}, n = K (not mirror)
``use_full_time_stratification``    bool    ``stratify_intervals``             default false (ours: true)
``spatial_correlation_mode``        string  ``correlation``                    none → none, pixel → pixel, sampler →
                                                                               replay, ray_position → reconnection,
                                                                               ray_sampler → replay, ray_adaptive →
                                                                               adaptive; mis → error. The README swaps
                                                                               the two ray_* labels; the code's meaning
                                                                               is used (reference §3.1)
``m_reconnection_threshold``        float   ``m_reconnection_threshold``       ray_adaptive roughness threshold
``primal_antithetic_mis_power``     float   –                                  only 1 (balance heuristic, ours)
``force_constant_attenuation``      bool    –                                  only false (first order, ours)
``image_offset``                    float   –                                  0 or 1 (the default); our output has no
                                                                               offset and no factor T: ours =
                                                                               (0.6 pixel − image_offset) / T
==================================  ======  =================================  =========================================

``ray_sampler`` is the original's paired tracing with random replay, whose primal/partner
weights are ½ each: the same estimator as ``replay`` here. In ``analytic`` mode, ours adds
ψ, which the original omitted (reference §1.7), and needs a paired mode
(``ray_position``/``ray_sampler``/``ray_adaptive``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from .scene import SceneError
from .xmlvalues import property_value

CORRELATION_MODES = {
    "none": "none",
    "pixel": "pixel",
    "sampler": "replay",
    "ray_position": "reconnection",
    "ray_sampler": "replay",
    "ray_adaptive": "adaptive",
}
_PAIRED_0_6 = ("ray_position", "ray_sampler", "ray_adaptive")
TIME_SAMPLING_MODES = ("uniform", "stratified", "antithetic", "antithetic_mirror", "analytic")

# 0.6 key -> (type, our name): copied through under our name
_RENAMED = {
    "maxDepth": ("int", "max_depth"),
    "rrDepth": ("int", "rr_depth"),
    "hideEmitters": ("bool", "hide_emitters"),
    **{k: ("float", k) for k in ("time", "w_g", "w_s", "g_1", "g_0", "sensor_phase_offset", "hetero_offset", "hetero_frequency")},
    "wave_function_type": ("str", "wave_function_type"),
    "low_srequency_component_only": ("bool", "low_frequency_component_only"),
    "m_reconnection_threshold": ("float", "m_reconnection_threshold"),
}
# 0.6 keys with their own rule in integrator_params
_SPECIAL = {
    "strictNormals": "bool",
    "low_frequency_component_only": "bool",
    "time_sampling_mode": "str",
    "antithetic_shifts": "str",
    "antithetic_shifts_number": "int",
    "use_full_time_stratification": "bool",
    "spatial_correlation_mode": "str",
    "primal_antithetic_mis_power": "float",
    "force_constant_attenuation": "bool",
    "image_offset": "float",
}
_DTOF_TYPES = ("dopplertofpath",)
_ONLY_0_6_KEYS = set(_SPECIAL) - {"low_frequency_component_only"} | {"low_srequency_component_only"}  # not M3 names
# Sensor properties of the original's example files that no code read (reference §2.1).
_UNREAD_SENSOR_KEYS = {"time_sample_count", "time_sampling_type", "use_same_time_samples_over_path_space",
                       "use_antithetic_sampling", "use_pixel_correlation", "sample_time"}
_FILE_ONLY_FILM_KEYS = {"banner", "attach_log", "digits", "variable"}  # shape the written file only
_PIXEL_FORMATS = {"luminance": "luminance", "luminancealpha": "luminance_alpha", "rgb": "rgb", "rgba": "rgba", "xyz": "xyz", "xyza": "xyza"}


# ----------------------------------------------------------------------------------------
# Detection


def snake_case(name: str) -> str:
    """Mitsuba 3's upgrade of a 0.6 property name (``src/core/xml.cpp``, ``upgrade_tree``):
    after a lower-case letter, an upper-case run becomes ``_`` + lower case
    (``toWorld`` → ``to_world``, ``intIOR`` → ``int_ior``). Reproduced exactly, including
    its skipping of the character after each run."""
    chars = list(name)
    i = 0
    while i < len(chars) - 1:
        if chars[i].islower() and chars[i + 1].isupper():
            chars.insert(i + 1, "_")
            i += 2
            while i < len(chars) and chars[i].isupper():
                chars[i] = chars[i].lower()
                i += 1
        i += 1
    return "".join(chars)


def is_legacy(root) -> bool:
    """Is ``root`` (a ``<scene>`` element) a Mitsuba 0.6 scene?

    Yes if its ``version`` starts with ``0.``, or if it holds a construct only 0.6 has: a
    camelCase property name, ``<srgb>``, ``<lookAt>``, an ``mfilm``, or a 0.6-only key of
    the D-ToF integrator (Mitsuba 3 names are snake_case, so none of these is ambiguous).
    """
    if root.attrib.get("version", "").strip().startswith("0."):
        return True
    for el in root.iter():
        if el.tag in ("srgb", "lookAt") or (el.tag == "film" and el.attrib.get("type") == "mfilm"):
            return True
        name = el.attrib.get("name")
        if el.tag != "default" and name and (snake_case(name) != name or name in _ONLY_0_6_KEYS):
            return True
    return False


# ----------------------------------------------------------------------------------------
# The integrator


def _typed(key, value, kind, where):
    ok = {
        "bool": isinstance(value, bool),
        "int": isinstance(value, int) and not isinstance(value, bool),
        "float": isinstance(value, (int, float)) and not isinstance(value, bool),
        "str": isinstance(value, str),
    }[kind]
    if not ok:
        noun = {"bool": "<boolean>", "int": "<integer>", "float": "<float>", "str": "<string>"}[kind]
        raise SceneError(f"{where}: {key!r} must be a {noun}, got {value!r}")
    return float(value) if kind == "float" else value


def _shifts(text: str, where: str) -> list[float]:
    try:
        values = [float(v) for v in text.split()]  # whitespace, as the original's istream >>
    except ValueError:
        raise SceneError(f"{where}: 'antithetic_shifts' must be whitespace-separated numbers, got {text!r}") from None
    if not values:
        raise SceneError(f"{where}: 'antithetic_shifts' is empty")
    return values


def _times_and_shift(mode: str, props: dict, where: str) -> tuple[int, float | None]:
    """(n_times, antithetic_shift or None) from the 0.6 shift keys (reference §2.1)."""
    k = props.get("antithetic_shifts_number")
    text = props.get("antithetic_shifts")
    if k is not None and k < 0:
        raise SceneError(f"{where}: 'antithetic_shifts_number' must be >= 0, got {k}")
    if mode == "antithetic_mirror":
        if k not in (None, 0, 2):
            raise SceneError(f"{where}: antithetic_mirror pairs 2 times; 'antithetic_shifts_number'={k} (which the original ignored here) does not fit")
        shifts = _shifts(text if text is not None else "0.0", where)
        if len(shifts) != 1:
            raise SceneError(f"{where}: antithetic_mirror takes one shift, got antithetic_shifts={text!r} (the original left the extra times stale)")
        return 2, shifts[0]
    if k:
        n, shifts = k, [i / k for i in range(1, k)]
        if text is not None and _shifts(text, where) != shifts:
            raise SceneError(f"{where}: 'antithetic_shifts'={text!r} contradicts 'antithetic_shifts_number'={k} (shifts i/{k}); give one")
    else:
        shifts = _shifts(text if text is not None else "0.5", where)
        n = len(shifts) + 1
    if mode != "antithetic":
        return n, None  # uniform/stratified draw fresh times, analytic uses the ends: no shift
    if n == 2:
        return 2, shifts[0]
    if any(abs(a - i / n) > 1e-6 for i, a in enumerate(sorted(shifts), 1)):
        raise SceneError(f"{where}: antithetic with {len(shifts)} shifts needs the evenly spaced set i/{n} (i = 1..{n - 1}), got antithetic_shifts={text!r}")
    return n, None


def integrator_params(props: dict, where: str = "integrator") -> tuple[dict, bool]:
    """Parameters for :func:`dopplertof.settings.integrator_layer` from the properties of a
    0.6 ``dopplertofpath`` integrator (module table).

    Parameters
    ----------
    props : dict
        0.6 key → Python value (bool, int, float or str, as the XML element typed it).
    where : str
        Prefix of error messages.

    Returns
    -------
    (params, strict_normals): ``params`` in ``integrator_layer`` names (with ``"type"``);
    ``strict_normals`` whether the file asked for it (see :func:`check_flat_shading`).

    Raises
    ------
    SceneError
        An unknown key, a value of the wrong type, or a setting with no equivalent here.
    """
    out, special = {"type": "dopplertofpath"}, {}
    for key, value in props.items():
        if key in _RENAMED:
            kind, ours = _RENAMED[key]
            out[ours] = _typed(key, value, kind, where)
        elif key in _SPECIAL:
            special[key] = _typed(key, value, _SPECIAL[key], where)
        else:
            raise SceneError(f"{where}: unknown Mitsuba 0.6 dopplertofpath parameter {key!r}")
    props = special

    if props.get("low_frequency_component_only") is False:
        raise SceneError(f"{where}: 'low_frequency_component_only'=false was ignored by the original (it read 'low_srequency_component_only', "
                         "so it rendered low-pass); set 'low_srequency_component_only' to choose")
    for key, allowed, why in (
        ("primal_antithetic_mis_power", (1.0,), "only the balance heuristic (1) is implemented"),
        ("force_constant_attenuation", (False,), "analytic mode here is first order (false) only"),
        ("image_offset", (0.0, 1.0), "the output here has no offset (ours = (0.6 pixel - image_offset) / T)"),
    ):
        if key in props and props[key] not in allowed:
            raise SceneError(f"{where}: {key!r}={props[key]!r} is not supported: {why}")

    mode = props.get("time_sampling_mode", "uniform")  # 0.6 default
    if mode not in TIME_SAMPLING_MODES:
        raise SceneError(f"{where}: unknown time_sampling_mode {mode!r}; choose one of {', '.join(TIME_SAMPLING_MODES)}")
    spatial = props.get("spatial_correlation_mode", "none")
    if spatial == "mis":
        raise SceneError(f"{where}: spatial_correlation_mode 'mis' (the original's experimental five-path mode) has no equivalent here; "
                         "use ray_position, ray_sampler or ray_adaptive")
    if spatial not in CORRELATION_MODES:
        raise SceneError(f"{where}: unknown spatial_correlation_mode {spatial!r}; choose one of {', '.join(CORRELATION_MODES)}")
    n_times, shift = _times_and_shift(mode, props, where)
    if spatial in _PAIRED_0_6 and n_times != 2:
        raise SceneError(f"{where}: {spatial} pairs 2 times (the original used only the first two), got {n_times}")
    if mode == "analytic" and spatial not in _PAIRED_0_6:
        raise SceneError(f"{where}: analytic time sampling needs a paired spatial_correlation_mode (ray_position, ray_sampler or "
                         f"ray_adaptive); with {spatial!r} the original traced two plain samples at 0 and T")
    out.update(time_sampling=mode, n_times=n_times, correlation=CORRELATION_MODES[spatial],
               stratify_intervals=props.get("use_full_time_stratification", False))
    if shift is not None:
        out["antithetic_shift"] = shift
    return out, props.get("strictNormals", False)


def _property_element(name: str, value) -> ET.Element:
    tag = {bool: "boolean", int: "integer", float: "float", str: "string"}[type(value)]
    text = ("true" if value else "false") if isinstance(value, bool) else repr(value) if isinstance(value, float) else str(value)
    return ET.Element(tag, {"name": name, "value": text})


def check_flat_shading(scenes, where: str) -> None:
    """Raise unless every shading normal in ``scenes`` (``mi.Scene``) is the geometric one,
    where 0.6's ``strictNormals=true`` and Mitsuba 3 (no such test) agree: analytic
    shapes, and meshes without vertex normals or whose vertex normals equal their faces'."""
    import numpy as np

    for scene in scenes:
        for shape in scene.shapes():
            if not shape.is_mesh() or not shape.has_vertex_normals():
                continue
            p = np.asarray(shape.vertex_positions_buffer(), dtype=np.float64).reshape(-1, 3)
            n = np.asarray(shape.vertex_normals_buffer(), dtype=np.float64).reshape(-1, 3)
            f = np.asarray(shape.faces_buffer(), dtype=np.int64).reshape(-1, 3)
            face_n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
            face_n /= np.maximum(np.linalg.norm(face_n, axis=1, keepdims=True), 1e-30)
            if not np.all(np.einsum("fvk,fk->fv", n[f], face_n) > 1 - 1e-5):
                raise SceneError(f"{where}: strictNormals=true differs from Mitsuba 3 on the smooth-shaded mesh {shape.id()!r}; "
                                 "give it faceNormals=true or set strictNormals=false")


# ----------------------------------------------------------------------------------------
# The tree


def _props(el, where):
    return {p.attrib["name"]: property_value(p, where) for p in el if "name" in p.attrib}


def _srgb_to_linear(el, where):
    text = el.attrib.get("value", "").strip()
    try:
        if text.startswith("#") and len(text) == 7:
            values = [int(text[i:i + 2], 16) / 255.0 for i in (1, 3, 5)]
        else:
            values = [float(v) for v in text.replace(",", " ").split()]
            values = values * 3 if len(values) == 1 else values
        if len(values) != 3:
            raise ValueError
    except ValueError:
        raise SceneError(f"{where}: <srgb name={el.attrib.get('name')!r}>: expected #rrggbb or 1 or 3 numbers, got {text!r}") from None
    linear = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in values]
    el.tag = "rgb"
    el.attrib["value"] = " ".join(repr(c) for c in linear)


def _child(el, name):
    return next((p for p in el if p.attrib.get("name") == name), None)


def _film(film, where):
    if film.attrib.get("type") == "mfilm":
        film.attrib["type"] = "hdrfilm"
        for name, value in (("width", "1"), ("height", "1")):  # mfilm's defaults, not hdrfilm's 768 x 576
            if _child(film, name) is None:
                film.append(ET.Element("integer", {"name": name, "value": value}))
        if film.find("rfilter") is None:
            film.append(ET.Element("rfilter", {"type": "box"}))
        fmt = _child(film, "file_format")
        if fmt is not None:
            film.remove(fmt)  # matlab/mathematica/numpy: the written file's encoding
    for p in list(film):
        name = p.attrib.get("name")
        if name in _FILE_ONLY_FILM_KEYS:
            film.remove(p)
        elif name == "high_quality_edges":
            p.attrib["name"] = "sample_border"
        elif name in ("pixel_format", "file_format", "component_format"):
            value = p.attrib.get("value", "").lower()  # 0.6 compares them case-insensitively
            if name == "pixel_format":
                if value not in _PIXEL_FORMATS:
                    raise SceneError(f"{where}: film pixelFormat {p.attrib.get('value')!r} has no Mitsuba 3 equivalent; use one of luminance, luminanceAlpha, rgb, rgba, xyz, xyza")
                value = _PIXEL_FORMATS[value]
            p.attrib["value"] = value


def _bsdf(bsdf, where):
    kind = bsdf.attrib.get("type")
    if kind in ("conductor", "roughconductor") and not any(_child(bsdf, k) is not None for k in ("material", "eta", "k")):
        bsdf.append(ET.Element("string", {"name": "material", "value": "Cu"}))  # 0.6's default; Mitsuba 3's is a mirror
    elif kind == "diffuse" and _child(bsdf, "diffuse_reflectance") is not None:
        _child(bsdf, "diffuse_reflectance").attrib["name"] = "reflectance"
    elif kind == "roughdiffuse":
        alpha = _child(bsdf, "alpha")
        if alpha is None or alpha.tag != "float" or float(alpha.attrib.get("value", "nan")) != 0.0:
            raise SceneError(f"{where}: roughdiffuse (Oren-Nayar) has no Mitsuba 3 equivalent unless alpha is 0 (then it is diffuse)")
        bsdf.attrib["type"] = "diffuse"
        for name in ("alpha", "use_fast_approx"):
            if _child(bsdf, name) is not None:
                bsdf.remove(_child(bsdf, name))


def translate(root, where: str) -> bool:
    """Rewrite the 0.6 scene ``root`` in place as a Mitsuba 3 tree (module docstring).

    Runs after ``$name`` substitution and ``<include>`` expansion. The D-ToF integrator's
    children become typed elements named as :func:`integrator_params` returns them.
    Returns whether the integrator asked for ``strictNormals``, which the loader checks
    on the loaded shapes with :func:`check_flat_shading`.
    """
    root.attrib["version"] = "3.0.0"
    strict, n_times, exposure = False, 1, None
    for integrator in root.iter("integrator"):
        here = f"{where}: <integrator type={integrator.attrib.get('type')!r}>"
        if integrator.attrib.get("type") in _DTOF_TYPES:
            params, strict = integrator_params(_props(integrator, here), here)
            params.pop("type")
            for p in list(integrator):
                integrator.remove(p)
            integrator.extend(_property_element(k, v) for k, v in params.items())
            n_times, exposure = params["n_times"], params.get("time", 0.0015)
        else:  # a stock integrator: strictNormals has the same meaning there
            for p in list(integrator):
                if p.attrib.get("name") == "strictNormals":
                    strict = _typed("strictNormals", _props(integrator, here)["strictNormals"], "bool", here)
                    integrator.remove(p)
    for el in root.iter():
        if el.tag != "default" and "name" in el.attrib:
            el.attrib["name"] = snake_case(el.attrib["name"])
    for parent in root.iter():
        for el in list(parent):
            here = f"{where}: <{el.tag} type={el.attrib.get('type')!r}>" if "type" in el.attrib else f"{where}: <{el.tag}>"
            if el.tag in ("rgb", "srgb", "spectrum"):
                el.attrib.pop("intent", None)
            if el.tag == "lookAt":
                el.tag = "lookat"
            elif el.tag == "srgb":
                _srgb_to_linear(el, where)
            elif el.tag == "film":
                _film(el, here)
            elif el.tag == "bsdf":
                _bsdf(el, here)
                if strict and el.attrib.get("type") in ("bumpmap", "normalmap"):
                    raise SceneError(f"{here}: strictNormals=true differs from Mitsuba 3 where a bump or normal map bends the shading normal; set strictNormals=false")
            elif el.tag == "sampler":
                _sampler(el, n_times, here)
            elif el.tag == "sensor":
                for p in list(el):
                    if p.attrib.get("name") in _UNREAD_SENSOR_KEYS:
                        el.remove(p)
                if exposure is not None:
                    _check_shutter(el, exposure, here)
    return strict


def _sampler(sampler, n_times, where):
    sampler.attrib["type"] = "independent"
    for p in list(sampler):
        if p.attrib.get("name") in ("dimension", "scramble"):  # steer 0.6's sequences, which ours replace
            sampler.remove(p)
    count = _child(sampler, "sample_count")
    if count is not None and n_times != 1:
        count.attrib["value"] = str(property_value(count, where) * n_times)


def _check_shutter(sensor, exposure, where):
    shutter = {k: property_value(_child(sensor, k), where) if _child(sensor, k) is not None else 0.0 for k in ("shutter_open", "shutter_close")}
    if shutter["shutter_open"] != 0.0 or abs(shutter["shutter_close"] - exposure) > 1e-12 * max(1.0, exposure):
        raise SceneError(f"{where}: the D-ToF integrator needs shutterOpen=0 and shutterClose=time={exposure!r} (Mitsuba 0.6's default is 0, 0), "
                         f"got [{shutter['shutter_open']!r}, {shutter['shutter_close']!r}]")
