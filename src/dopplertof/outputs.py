"""Every output of a render, declared once.

The tracer produces per-lane values under these names (:mod:`dopplertof.tracing.sink`),
the renderer reduces them as their ``kind`` says (:mod:`dopplertof.render`),
:class:`~dopplertof.render.RenderResult` holds them as attributes, and the writers, the
plugin's channels and the experiments' cache iterate over :data:`OUTPUTS`.

Kinds:

* ``estimate``: a Monte Carlo estimate, mean over the pixel's samples, with a standard
  error (``stderr_name``) from independent replicates;
* ``truth``: ground truth of the camera ray's first hit, averaged over the samples that
  hit (NaN where none did), accumulated in Float64;
* ``coverage``: the fraction of samples whose camera ray hit a surface;
* ``label``: an integer label of the pixel's first sample (sample 0).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Output:
    """One output of a render: its name, its kind (estimate, truth, coverage or label), its
    channels, unit and meaning, the name of its standard error and of its preview kind.
    :data:`OUTPUTS` lists them, once for the kernel, the writers, the plugin and the caches.

    Parameters
    ----------
    name : str
        The file and attribute name (``intensity``, ``velocity``, …).
    kind : str
        ``estimate``, ``truth``, ``coverage`` or ``label``.
    channels : int or str
        An int, ``"color"`` (3 in RGB variants, 1 in mono) or ``"cameras"`` (one image each).
    unit : str
        The unit of its values.
    meaning : str
        One line for tables and file headers.
    stderr_name : str or None, default None
        The name of its standard error (estimates only).
    components : tuple of str, default ()
        Names of the channels of a multi-channel truth map.
    preview : str or None, default None
        ``intensity``, ``signed``, ``velocity`` or ``labels``: how its PNG is drawn.
    """
    name: str
    kind: str  # estimate | truth | coverage | label
    channels: object  # int, "color" (3 in RGB variants, 1 in mono) or "cameras" (one image each)
    unit: str
    meaning: str
    stderr_name: str | None = None
    components: tuple = ()  # names of the channels of a multi-channel truth map
    preview: str | None = None  # intensity | signed | velocity | labels

    def n_channels(self, color_channels: int, n_cameras: int) -> int:
        """How many channels this output has in a render with ``color_channels`` colour
        channels (3 in RGB variants, 1 in mono) and ``n_cameras`` cameras.

        Parameters
        ----------
        color_channels : int
            3 in RGB variants, 1 in mono.
        n_cameras : int
            Cameras of the render.

        Returns
        -------
        int
        """
        return {"color": color_channels, "cameras": n_cameras}.get(self.channels, self.channels)


OUTPUTS = (
    Output("intensity", "estimate", "color", "radiance", "standard (intensity) image, in the units of a Mitsuba render", "stderr", preview="intensity"),
    Output(
        "measurements", "estimate", "cameras", "radiance",
        "D-ToF measurements, one image per camera: the exposure average of the low-pass correlation (1/T)∫W f dt (luminance; signed)",
        "measurement_stderr", preview="signed",
    ),  # fmt: skip
    Output("depth", "truth", 1, "m", "distance from the aperture to the camera ray's first hit", preview="depth"),
    Output("velocity", "truth", 1, "m/s", "radial velocity as the camera sees it: d/dt of the hit distance along the camera ray fixed in the (possibly moving) camera's frame, positive receding", preview="velocity"),
    Output("point_velocity", "truth", 1, "m/s", "(v − v_aperture)·d̂ of the hit surface point (d̂ the camera ray's direction): d/dt of its distance from the moving aperture, positive receding"),
    Output("velocity_3d", "truth", 3, "m/s", "velocity of the hit point relative to the camera, in the camera frame (x left, y up, z forward)", components=("x", "y", "z")),
    Output("flow", "truth", 2, "pixels/s", "optical flow: rate of change of the hit point's film position (x right, y down); NaN for sensors without a projection (orthographic)", components=("u", "v")),
    Output("coverage", "coverage", 1, "", "fraction of samples whose camera ray hit a surface"),
    Output("instance_id", "label", 1, "", "moving body hit by the pixel's first sample (its index in scene.bodies); -1 static geometry or background", preview="labels"),
)

BY_NAME = {o.name: o for o in OUTPUTS}
TRUTH = tuple(o for o in OUTPUTS if o.kind == "truth")
ESTIMATES = tuple(o for o in OUTPUTS if o.kind == "estimate")
STDERR_NAMES = {o.stderr_name: o for o in ESTIMATES}

MOVING_PIXEL_M_S = 1e-3
"""A pixel moves where its ground-truth radial ``velocity`` exceeds this, m/s, in absolute
value (the reconstruction's error summary, the velocity experiment, dataset statistics)."""
