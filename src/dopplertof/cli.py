"""Command line: ``dopplertof render | scenes``.

Errors in the input (a bad scene file, parameter or camera) print one line,
``error: ...``, and exit with status 2; no traceback.
"""

from __future__ import annotations

import math
import os
import sys

import click

from .modulation import WAVEFORMS, Camera

_CAMERA_KEYS = {
    "h": "heterodyne",
    "heterodyne": "heterodyne",
    "psi": "phase",
    "phase": "phase",
    "f": "modulation_frequency",
    "frequency": "modulation_frequency",
    "T": "exposure",
    "exposure": "exposure",
    "waveform": "waveform",
    "g1": "g1",
    "g0": "g0",
    "low_pass": "low_pass",
}


def parse_camera(text: str, exposure: float | None = None) -> Camera:
    """A :class:`Camera` from ``"h=1,psi=0,f=30e6,waveform=sinusoidal"``.

    ``psi`` accepts radians or degrees with a ``deg`` suffix (``psi=90deg``); ``f`` is Hz.
    """
    kwargs: dict = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        if "=" not in item:
            raise ValueError(f"camera {text!r}: expected key=value, got {item!r}")
        key, value = (s.strip() for s in item.split("=", 1))
        if key not in _CAMERA_KEYS:
            raise ValueError(f"camera {text!r}: unknown key {key!r}; use {', '.join(sorted(set(_CAMERA_KEYS)))}")
        name = _CAMERA_KEYS[key]
        if name == "waveform":
            kwargs[name] = value
        elif name == "low_pass":
            kwargs[name] = value.lower() in ("1", "true", "yes")
        else:
            try:
                kwargs[name] = math.radians(float(value[:-3])) if name == "phase" and value.endswith("deg") else float(value)
            except ValueError:
                raise ValueError(f"camera {text!r}: {key}={value!r} is not a number") from None
    if exposure is not None:
        kwargs.setdefault("exposure", exposure)
    return Camera(**kwargs)


def _fail(message: str):
    click.echo(f"error: {message}", err=True)
    sys.exit(2)


def _load(scene_arg: str, resolution):
    from . import scenes
    from .loader import load_scene

    if scene_arg in scenes.SCENES:
        return scenes.build(scene_arg, **({} if resolution is None else {"resolution": resolution}))
    if resolution is not None:
        raise ValueError("--resolution applies to built-in scenes; set the film size in the scene file")
    if not os.path.exists(scene_arg):
        raise ValueError(f"{scene_arg}: no such scene file or built-in scene (see 'dopplertof scenes')")
    return load_scene(scene_arg)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--variant", default=None, help="Mitsuba variant (llvm_ad_rgb, llvm_ad_mono, cuda_ad_rgb, cuda_ad_mono).")
def main(variant):
    """dopplertof: render Doppler time-of-flight measurements of dynamic scenes."""
    from .backend import BackendError, set_variant

    if variant:
        try:
            set_variant(variant)
        except (ValueError, BackendError) as exc:
            _fail(str(exc))


@main.command()
def scenes():
    """List the built-in scenes."""
    from .scenes import SCENES

    for name, (_, description) in SCENES.items():
        click.echo(f"{name:20s} {description}")


@main.command()
@click.argument("scene")
@click.option("--spp", type=int, default=None, help="Paths per pixel (default: the scene's sampler, else 64).")
@click.option("-o", "--output", "output", default="out", show_default=True, help="Output folder.")
@click.option("--camera", "camera_specs", multiple=True, help="A camera, e.g. 'h=1,psi=0' or 'h=0,psi=90deg,f=30e6'. Repeatable.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--max-depth", type=int, default=None, help="Path depth (default: the scene's, else 5).")
@click.option("--time-sampling", default=None, help="uniform | stratified | antithetic | antithetic_mirror (default antithetic).")
@click.option("--correlation", default=None,
              help="none | pixel | replay | reconnection | adaptive (default replay; the last two need pairs of times).")
@click.option("--correlation-depth", type=int, default=None, help="Replay cut-off in bounces + 1 (default: all).")
@click.option("--reconnection-threshold", type=float, default=None,
              help="adaptive: reconnect where both surfaces are rougher than this GGX/Beckmann alpha (default 0.5).")
@click.option("--exposure", type=float, default=None, help="Exposure T in seconds (default 1.5e-3).")
@click.option("--resolution", type=int, default=None, help="Film size of a built-in scene (pixels).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def render(scene, spp, output, camera_specs, seed, max_depth, time_sampling, correlation, correlation_depth,
           reconnection_threshold, exposure, resolution, quiet):
    """Render SCENE (an XML file or a built-in scene name) into OUTPUT."""
    import dataclasses

    from .backend import BackendError
    from .plugin import render_settings
    from .render import render as run_render
    from .scene import SceneError

    try:
        dyn = _load(scene, resolution)
        # The scene's <integrator> (original parameter names) first; options replace it.
        settings = render_settings(dyn.integrator_params, f"{scene}: <integrator>") if dyn.integrator_params else {}
        if camera_specs:
            settings["cameras"] = [parse_camera(c, exposure) for c in camera_specs]
        elif exposure is not None and settings.get("cameras"):
            settings["cameras"] = [dataclasses.replace(c, exposure=exposure) for c in settings["cameras"]]
        cameras = settings.setdefault("cameras", [])
        if time_sampling is not None:
            settings["time_sampling"] = time_sampling
            if "antithetic_shift" not in dyn.integrator_params:  # the file's default suited its method
                settings.pop("antithetic_shift", None)
        settings.setdefault("time_sampling", "antithetic" if cameras else "uniform")
        settings["correlation"] = correlation or settings.get("correlation", "replay")
        if correlation is not None and "correlation_depth" not in dyn.integrator_params:
            settings.pop("correlation_depth", None)  # the file's path_correlation_depth chose its own mode
        if correlation_depth is not None:
            settings["correlation_depth"] = correlation_depth
        if reconnection_threshold is not None:
            settings["reconnection_threshold"] = reconnection_threshold
        settings["max_depth"] = max_depth if max_depth is not None else settings.get("max_depth", 5)
        spp = spp if spp is not None else (dyn.spp_hint or 64)
        result = run_render(dyn, spp=spp, seed=seed, exposure=None if cameras else exposure, progress=not quiet, **settings)
        written = write_result(result, output)
    except (ValueError, SceneError, BackendError, FileNotFoundError) as exc:
        _fail(str(exc))
    status = " (interrupted: partial result)" if result.interrupted else ""
    click.echo(f"rendered {scene} at {result.spp} spp{status}; images in {os.path.abspath(output)}/")
    for path in written:
        click.echo(f"  {path}")


def write_result(result, folder: str) -> list[str]:
    """Write a :class:`RenderResult` as EXR + PNG previews + metadata.json; returns the paths."""
    from . import io, viz

    os.makedirs(folder, exist_ok=True)
    out = []

    def path(name):
        p = os.path.join(folder, name)
        out.append(p)
        return p

    io.write_exr(path("intensity.exr"), result.intensity)
    viz.save_intensity_png(path("intensity.png"), result.intensity)
    io.write_exr(path("stderr.exr"), result.stderr)
    io.write_exr(path("depth.exr"), result.depth)
    io.write_exr(path("velocity.exr"), result.velocity)
    viz.save_velocity_png(path("velocity.png"), result.velocity)
    io.write_exr(path("point_velocity.exr"), result.point_velocity)
    for i, cam in enumerate(result.cameras):
        stem = f"measurement_{i}_h{cam.heterodyne:g}_psi{math.degrees(cam.phase):g}deg"
        io.write_exr(path(f"{stem}.exr"), result.measurements[i])
        io.write_exr(path(f"{stem}_stderr.exr"), result.measurement_stderr[i])
        viz.save_signed_png(path(f"{stem}.png"), result.measurements[i], colorbar=True, title=cam.label())
    io.write_json(
        path("metadata.json"),
        {
            "spp": result.spp,
            "seed": result.seed,
            "interrupted": result.interrupted,
            "settings": result.settings,
            "cameras": [vars(c) for c in result.cameras],
        },
    )
    return out


from .experiments.cli import experiment  # noqa: E402  (last: it uses the helpers above)

main.add_command(experiment)

from .animate import animate_command  # noqa: E402
from .render_folder import reconstruct_command  # noqa: E402

main.add_command(animate_command)
main.add_command(reconstruct_command)

from .dataset.cli import dataset_group  # noqa: E402

main.add_command(dataset_group)


if __name__ == "__main__":  # pragma: no cover
    main()
