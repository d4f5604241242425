"""What every command-line command shares: one-line errors, stopping on signals, and the
render-setting options generated from :class:`dopplertof.settings.RenderSettings`.

Bad input prints one line ``error: …`` and exits with status 2, no traceback; a legal
but suspicious value (a Python warning) prints one line ``warning: …`` and goes on.
SIGINT, SIGTERM and SIGHUP stop a render at the end of the pass in progress
(:class:`StopOnSignal`); the command then writes what is done and exits with 128 + the
signal's number (130, 143, 129). A second signal of the same kind acts at once.
"""

from __future__ import annotations

import dataclasses
import signal
import sys

import click

from .backend import STOP_SIGNALS
from .settings import FIELDS

EXIT_BAD_INPUT = 2


def fail(message: str):
    """Print ``error: message`` on stderr and exit with status 2."""
    click.echo(f"error: {' '.join(str(message).split())}", err=True)
    sys.exit(EXIT_BAD_INPUT)


def output_folder(output: str | None, default: str) -> str:
    """``-o/--output``, else ``default``; an empty name (an unset shell variable, say) is
    refused with one ``error:`` line instead of writing to the default folder."""
    if output is not None and not output.strip():
        fail(f"-o/--output is empty; leave it out for the default folder ({default})")
    return output or default


_WARNED: set[str] = set()


def show_warning(message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` of the command line: one line ``warning: message`` on stderr,
    once per message (a value checked again where it is used, e.g. a sensor's frames when the
    render schedules them, says nothing new the second time)."""
    text = " ".join(str(message).split())
    if text not in _WARNED:
        _WARNED.add(text)
        click.echo(f"warning: {text}", err=True)


class StopOnSignal:
    """A ``stop()`` callable for :func:`dopplertof.render` that turns true on a signal.

    The render calls it before each pass, so once it has been called a pass may be in
    progress, and a signal says it stops after that pass; before (during start-up) it says
    nothing, and the command's one ``error:`` line follows when the render sees the stop.
    """

    SIGNALS = STOP_SIGNALS

    def __init__(self):
        self.signum = None
        self._saved = {}
        self._polled = False

    def _handle(self, signum, frame):
        if self.signum == signum:  # asked twice: stop now
            signal.signal(signum, self._saved.get(signum, signal.SIG_DFL))
            raise KeyboardInterrupt
        self.signum = signum
        if self._polled:
            click.echo(f"\n{signal.Signals(signum).name}: stopping after the pass in progress (again to stop at once)", err=True)

    def __enter__(self):
        for s in self.SIGNALS:
            self._saved[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc):
        for s, handler in self._saved.items():
            signal.signal(s, handler)
        return False

    def __call__(self) -> bool:
        self._polled = True
        return self.signum is not None

    @property
    def exit_status(self) -> int:
        return 128 + (self.signum or signal.SIGINT)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum or signal.SIGINT).name


quiet_option = click.option("--quiet", is_flag=True, help="No progress bar.")  # every command that renders


# Settings the command line sets through options of its own (cameras) or not at all.
_NOT_OPTIONS = ("cameras",)


def _option_for(name, f):
    meta = f.metadata
    flag = "--" + name.replace("_", "-")
    unit = f" [{meta['unit']}]" if meta["unit"] else ""
    default = "the scene's, else " + repr(f.default) if f.default is not None else "see meaning"
    text = f"{meta['doc']}{unit} (default: {default})"
    if meta["kind"] == "bool":
        return click.option(f"{flag}/--no-{flag[2:]}", name, default=None, help=text)
    kind = {"int": int, "float": float}.get(meta["kind"])
    if meta["choices"]:
        kind = click.Choice(meta["choices"])
    return click.option(flag, name, type=kind, default=None, help=text)


def settings_options(exclude=()):
    """A decorator adding one option per render setting (:data:`dopplertof.settings.FIELDS`)
    but ``cameras`` (``--camera``) and ``exclude``; their values arrive under the
    settings' names, None where not given."""

    def decorate(function):
        for name, f in reversed(list(FIELDS.items())):
            if name not in _NOT_OPTIONS and name not in exclude:
                function = _option_for(name, f)(function)
        return function

    return decorate


def given_settings(options: dict) -> dict:
    """The settings layer of the options the user gave (not None)."""
    return {k: v for k, v in options.items() if k in FIELDS and v is not None}


def cameras_layer(camera_specs, exposure, scene_layer: dict, scene) -> dict:
    """``--camera`` specs, or the scene's cameras with ``--exposure``.

    A spec without ``T`` takes ``--exposure``, else the length of ``scene``'s shutter
    interval, else the default: ``--camera`` replaces the ``<integrator>``'s cameras (and
    their T), not the sensor's shutter.
    """
    from .modulation import parse_camera
    from .settings import shutter_interval

    if camera_specs:
        if exposure is None and (shutter := shutter_interval(scene)) is not None:
            exposure = shutter[1]
        return {"cameras": [parse_camera(c, exposure) for c in camera_specs]}
    if exposure is not None and scene_layer.get("cameras"):
        return {"cameras": [dataclasses.replace(c, exposure=exposure) for c in scene_layer["cameras"]]}
    return {}
