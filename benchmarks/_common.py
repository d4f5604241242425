"""Plumbing shared by the benchmark scripts: the machine line, the common command-line
options, a run (:class:`Run`: variant, header, progress log, CSV and plot) and the
Cornell room the throughput and variance scenes are built in.

The scripts run as ``python benchmarks/<name>.py``; Python puts the script's folder first on
``sys.path``, so ``import _common`` finds this module whatever the working directory.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import subprocess
import sys
import tempfile
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

# The built-in scenes' building blocks (one home for them): transform(translate, rotate_y_deg,
# scale, rotate_x_deg) -> ScalarTransform4f, diffuse(rgb) -> BSDF dict.
from dopplertof.scenes import GREEN, RED, WHITE
from dopplertof.scenes import _diffuse as diffuse
from dopplertof.scenes import _transform as transform

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_VARIANT = "llvm_ad_rgb"

# h ∈ {0, ½, 1} x ψ ∈ {0, π/2}: the six cameras rendered from the same paths
CAMERA_GRID = [(h, psi) for h in (0.0, 0.5, 1.0) for psi in (0.0, math.pi / 2)]


REPO = os.path.dirname(HERE)


def import_baseline(revision, folder, name="dopplertof_baseline"):
    """The package ``dopplertof`` at git ``revision``, imported as ``name`` beside the current
    one (its imports within the package are relative), extracted into ``folder``.

    Parameters
    ----------
    revision : str
        A commit of this repository.
    folder : str
        An empty folder that outlives the import (a ``tempfile.TemporaryDirectory``).
    name : str, default "dopplertof_baseline"

    Returns
    -------
    module
    """
    import importlib

    archive = subprocess.run(["git", "-C", REPO, "archive", revision, "src/dopplertof"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
    os.rename(os.path.join(folder, "src", "dopplertof"), os.path.join(folder, name))
    sys.path.insert(0, folder)
    return importlib.import_module(name)


# ----------------------------------------------------------------------------------------
# Machine


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_line(variant, *extra):
    """One line naming the CPU, thread count and software versions; ``extra`` parts appended."""
    import drjit as dr
    import mitsuba as mi

    try:
        threads = dr.thread_count()
    except Exception:  # noqa: BLE001
        threads = "?"
    llvm = os.environ.get("DRJIT_LIBLLVM_PATH", "?")
    parts = [
        f"machine: {cpu_model()}", f"{os.cpu_count()} cores (Dr.Jit threads: {threads})", f"Mitsuba {mi.__version__}",
        f"Dr.Jit {dr.__version__}", f"variant {variant}", f"dopplertof {dopplertof.__version__}",
        f"Python {platform.python_version()}", f"libLLVM {os.path.basename(llvm)}", *extra,
    ]  # fmt: skip
    return " | ".join(parts)


def loadavg():
    try:
        return "%.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        return "?"


def run_with_empty_kernel_cache(script, args, runs=1, **run_options):
    """Run ``python script *args`` in a process whose Dr.Jit kernel cache is empty, and
    ``runs - 1`` times more, each in a new process with the cache the runs before left.

    Dr.Jit keeps every compiled kernel in ``$HOME/.drjit`` across processes, so a run that
    times new scenes (compilation included) would find an earlier run's kernels: the child's
    ``$HOME`` is a temporary folder (processes it starts, Ray workers among them, inherit it).

    Parameters
    ----------
    script : str
        The script's path.
    args : list of str
        Its arguments.
    runs : int, default 1
        Processes run one after the other, sharing the temporary ``$HOME``.
    **run_options
        Passed to ``subprocess.run`` (its ``env`` is this process's with ``HOME`` replaced).

    Returns
    -------
    subprocess.CompletedProcess, or a list of ``runs`` of them where ``runs`` > 1
    """
    with tempfile.TemporaryDirectory(prefix="dopplertof-bench-home-") as home:
        env = {**os.environ, **run_options.pop("env", {}), "HOME": home}
        done = [subprocess.run([sys.executable, os.path.abspath(script), *args], env=env, **run_options) for _ in range(runs)]
    return done[0] if runs == 1 else done


FRESH_KERNEL_CACHE_ENV = "DOPPLERTOF_BENCH_FRESH_KERNEL_CACHE"  # set in a script's rerun with an empty kernel cache


def rerun_with_empty_kernel_cache(script, argv):
    """The exit status of ``script`` rerun with ``argv`` (None: ``sys.argv[1:]``) in a
    process whose Dr.Jit kernel cache is empty (:func:`run_with_empty_kernel_cache`); None
    where this process is that rerun, which then goes on itself.

    Parameters
    ----------
    script : str
        The script's path (its ``__file__``).
    argv : list of str or None

    Returns
    -------
    int or None
    """
    if os.environ.get(FRESH_KERNEL_CACHE_ENV):
        return None
    args = sys.argv[1:] if argv is None else argv
    return run_with_empty_kernel_cache(script, args, env={FRESH_KERNEL_CACHE_ENV: "1"}).returncode


def compile_seconds(history):
    """Seconds Dr.Jit spent generating and compiling the kernels of ``history``
    (``drjit.kernel_history()``, whose times are in ms).

    Parameters
    ----------
    history : list of dict

    Returns
    -------
    float
    """
    return sum(k.get("backend_time", 0.0) + k.get("codegen_time", 0.0) for k in history) / 1e3


def kernels_compiled(history):
    """How many kernels of ``history`` (``drjit.kernel_history()``) Dr.Jit compiled: found
    neither in its memory nor on disk.

    Parameters
    ----------
    history : list of dict

    Returns
    -------
    int
    """
    return sum(1 for k in history if compiled_here(k))


def compiled_here(kernel) -> bool:
    """Whether Dr.Jit compiled ``kernel`` (an entry of ``drjit.kernel_history()``): found
    neither in its memory nor on disk."""
    return kernel.get("cache_hit") == 0 and not kernel.get("cache_disk") and kernel.get("backend_time", 0.0) > 0


# ----------------------------------------------------------------------------------------
# Command line


def argument_parser(doc):
    """An argument parser whose description is the first paragraph of the script's docstring."""
    return argparse.ArgumentParser(description=doc.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)


def add_output_options(parser, name, quick_help, plot=True, quiet_help="only print the machine line and the tables"):
    """--variant, --csv, --plot (with ``plot``), --quick and --quiet; ``name``: the script's, for the default CSV."""
    parser.add_argument("--variant", default=None, help=f"Mitsuba variant (default {DEFAULT_VARIANT})")
    parser.add_argument("--csv", default=None, help=f"CSV output (default benchmarks/results/{name}.csv; quick: {name}_quick.csv)")
    if plot:
        parser.add_argument("--plot", default=None, help="PNG output (default: the CSV path with .png)")
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--quiet", action="store_true", help=quiet_help)


def add_sweep_options(parser, scene_names, ref_spp_help, methods=None, correlations=None):
    """--ref-spp, --max-depth, --scenes, --methods and --correlations of the scripts that sweep
    time sampling x correlation against a reference; ``methods``/``correlations``: the
    defaults (None: all of ``METHODS``/``MODES``)."""
    from dopplertof.correlation import MODES
    from dopplertof.timesampling import METHODS

    parser.add_argument("--ref-spp", type=int, default=None, help=f"paths per pixel of the reference ({ref_spp_help})")
    parser.add_argument("--max-depth", type=int, default=4, help="path depth, Mitsuba semantics (default 4, as the paper's Cornell box)")
    parser.add_argument("--scenes", nargs="+", choices=scene_names, default=list(scene_names))
    parser.add_argument(
        "--methods", nargs="+", choices=METHODS, default=list(methods or METHODS),
        help=f"time samplings (default {' '.join(methods) if methods else 'all of METHODS'})",
    )  # fmt: skip
    parser.add_argument(
        "--correlations", nargs="+", choices=MODES, default=list(correlations or MODES),
        help=f"correlations (default {' '.join(correlations) if correlations else 'all of MODES'})",
    )  # fmt: skip


def paired_times(method):
    """Render settings drawing *pairs* of times of ``method`` (``n_times=2``); the antithetic
    shift and per-interval stratification are the render defaults (½ for antithetic, 0 for
    the mirror, stratification on), as in ``dopplertof experiment``."""
    return dict(time_sampling=method, n_times=2)


def fill_defaults(args, defaults):
    """Set every option of ``defaults`` that the command line left None."""
    for key, value in defaults.items():
        if getattr(args, key) is None:
            setattr(args, key, value)


def require_positive(parser, args, names):
    """Exit with a usage error unless every option of ``names`` (attribute names) is > 0."""
    for name in names:
        if getattr(args, name) <= 0:
            parser.error(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)}")


def default_output_paths(args, name):
    """benchmarks/results/<name>.csv (``<name>_quick.csv`` with --quick), the plot beside it."""
    if args.csv is None:
        args.csv = os.path.join(HERE, "results", f"{name}_quick.csv" if args.quick else f"{name}.csv")
    if getattr(args, "plot", False) is None:
        args.plot = os.path.splitext(args.csv)[0] + ".png"


# ----------------------------------------------------------------------------------------
# A run: header, progress, outputs


class Run:
    """One benchmark run: sets the Mitsuba variant of ``args.variant``, prints the machine
    and settings lines and starts the clock; :meth:`log` prints progress unless --quiet;
    :meth:`finish` prints the total time and writes the CSV (and the plot).

    ``name``: the script's (benchmarks/<name>.py), ``argv``: its arguments (None: sys.argv),
    ``machine_extra``: parts appended to the machine line.
    """

    def __init__(self, name, args, argv, settings, *machine_extra):
        self.name, self.args, self.argv, self.settings = name, args, argv, settings
        variant = dopplertof.set_variant(args.variant or DEFAULT_VARIANT)
        self.machine = machine_line(variant, *machine_extra)
        print(self.machine, flush=True)
        print(settings, flush=True)
        self.started = time.perf_counter()

    def log(self, msg):
        if not self.args.quiet:
            print(msg, flush=True)

    def description(self):
        """The CSV's comment line: the command that made it, the machine and the settings."""
        command = f"python benchmarks/{self.name}.py " + " ".join(sys.argv[1:] if self.argv is None else self.argv)
        return f"{command.strip()} || {self.machine} || {self.settings}"

    def finish(self, rows, fieldnames, plot=None, total_note="", digits=6, **writer_options):
        """Print the total time (then ``total_note``), write ``rows`` to ``args.csv`` (see
        :func:`write_csv`) and, with ``plot`` (a function of the path), the plot to
        ``args.plot``; print where they went. Returns 0, the exit status."""
        print(f"total {time.perf_counter() - self.started:.1f} s{total_note}")
        write_csv(self.args.csv, rows, fieldnames, self.description(), digits, **writer_options)
        written = [f"CSV: {self.args.csv}"]
        if plot is not None:
            plot(self.args.plot)
            written.append(f"plot: {self.args.plot}")
        print("\n".join(written))
        return 0


def _make_folder_of(path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)


def write_csv(path, rows, fieldnames, meta, digits=6, **writer_options):
    """Rows (dicts) under a ``# meta`` comment line; floats with ``digits`` significant digits;
    ``writer_options`` go to ``csv.DictWriter``."""
    _make_folder_of(path)
    with open(path, "w", newline="") as f:
        f.write(f"# {meta}\n")
        w = csv.DictWriter(f, fieldnames=fieldnames, **writer_options)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{v:.{digits}g}" if isinstance(v, float) else v) for k, v in row.items()})


def save_figure(figure, legend_axes, path):
    """Put the legend of ``legend_axes`` right of ``figure`` and write it to ``path`` (PNG)."""
    handles, labels = legend_axes.get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside right center", fontsize=8)
    _make_folder_of(path)
    figure.savefig(path, dpi=110)


# ----------------------------------------------------------------------------------------
# Scenes


def cornell_room(resolution):
    """Scene dict of the Cornell box's room without its boxes: walls [−1, 1] x [0, 2] x [−1, 1] m,
    camera at (0, 1, 6.8) looking down −z (fov 19.5°, box filter), point light (intensity
    100 W/sr) at the camera."""
    import mitsuba as mi

    return {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": 19.5,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 1, 6.8], target=[0, 1, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
        },
        "floor": {"type": "rectangle", "to_world": transform((0, 0, 0), rotate_x_deg=-90), "bsdf": diffuse(WHITE)},
        "ceiling": {"type": "rectangle", "to_world": transform((0, 2, 0), rotate_x_deg=90), "bsdf": diffuse(WHITE)},
        "back": {"type": "rectangle", "to_world": transform((0, 1, -1)), "bsdf": diffuse(WHITE)},
        "red-wall": {"type": "rectangle", "to_world": transform((-1, 1, 0), rotate_y_deg=90), "bsdf": diffuse(RED)},
        "green-wall": {"type": "rectangle", "to_world": transform((1, 1, 0), rotate_y_deg=-90), "bsdf": diffuse(GREEN)},
        "light": {"type": "point", "position": [0.0, 1.0, 6.8], "intensity": {"type": "rgb", "value": [100.0] * 3}},
    }
