"""Sphinx configuration of the dopplertof documentation (``bash scripts/docs.sh``).

Pages are MyST Markdown; the tutorials are MyST notebooks that myst-nb executes at every
build. The CLI page is generated from the click command tree (sphinx-click), the settings
table from :meth:`dopplertof.RenderSettings.table` and the API reference from the
docstrings (autodoc, numpy style through napoleon) of the names ``_ext/public_api.py``
lists. Nothing is fetched from the network.
"""

import importlib
import os
import re
import shutil
import sys
from pathlib import Path

import click

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
# The executed pages' kernels import from _ext too (the troubleshooting page's error catalogue).
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(DOCS / "_ext"), os.environ.get("PYTHONPATH")]))

import dopplertof  # noqa: E402
import error_catalogue  # noqa: E402
import public_api  # noqa: E402
from dopplertof.cli import main as cli_main  # noqa: E402

project = "dopplertof"
author = "the dopplertof developers"
copyright = "2026, the dopplertof developers"
release = version = dopplertof.__version__

extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx_click"]
# The error catalogue is read only where troubleshooting.md includes it (its headings and links are that page's).
exclude_patterns = ["_build", "_ext", "README.md", "**.ipynb_checkpoints", "_generated/errors.md"]
html_theme = "furo"
html_title = f"dopplertof {release}"

myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# Tutorials run at every build: a failing cell fails the build.
nb_execution_mode = "force"
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_execution_in_temp = True  # what a tutorial writes (a scene file, a dataset) stays out of docs/
nb_execution_show_tb = True
# Markdown a cell outputs (the troubleshooting table) is MyST, so its links resolve as the pages'.
nb_render_markdown_format = "myst"

# Docstrings write "name : type. description" one-liners; a word of such a type text that
# names two objects (``windows``) is left unlinked rather than failing the build.
suppress_warnings = ["ref.python"]

autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

# The click group loads its larger commands on first use; sphinx-click documents only the
# loaded ones, so load them all.
_context = click.Context(cli_main)
for _name in cli_main.list_commands(_context):
    cli_main.get_command(_context, _name)

GENERATED = DOCS / "_generated"
shutil.rmtree(GENERATED, ignore_errors=True)  # no page of a module that is gone
(GENERATED / "api").mkdir(parents=True)


def _settings_table() -> str:
    from dopplertof.settings import FIELDS, RenderSettings

    # The options as the render command declares them (cameras: its --camera).
    render = cli_main.get_command(_context, "render")
    options = {p.name: p.opts[-1] for p in render.params}
    options["cameras"] = options["camera_specs"]
    rows = ["| setting (API) | option | unit | default | meaning |", "|---|---|---|---|---|"]
    for name, unit, default, meaning in RenderSettings.table():
        option = options[name]
        meaning = meaning.replace("|", r"\|")
        choices = FIELDS[name].metadata["choices"]
        if choices:
            meaning += ": " + ", ".join(f"`{c}`" for c in choices)
        rows.append(f"| `{name}` | `{option}` | {unit or '–'} | `{default}` | {meaning} |")
    return "\n".join(rows) + "\n"


def _api_pages() -> None:
    # An object is indexed (a link target) on the page of the module that defines it; where
    # a package or the top level re-exports it, it is shown again without an index entry.
    modules = public_api.public_modules()
    top = ["# `dopplertof`", "", "```{eval-rst}", ".. automodule:: dopplertof", "   :no-members:", ""]
    for name in sorted(dopplertof.__all__):
        obj = getattr(dopplertof, name)
        if isinstance(obj, type(dopplertof)):
            continue  # a lazy module: a page of its own
        kind = "autoclass" if isinstance(obj, type) else "autofunction"
        top += [f".. {kind}:: dopplertof.{name}", *(["   :members:"] if kind == "autoclass" else [])]
        top += ["   :no-index:" if obj.__module__ in modules else "", ""]
    (GENERATED / "api" / "dopplertof.md").write_text("\n".join([*top, "```", ""]))
    for module in modules:
        page = [f"# `{module}`", "", "```{eval-rst}", f".. automodule:: {module}", "   :members:"]
        if hasattr(importlib.import_module(module), "__path__"):
            page.append("   :no-index:")  # a package: its members are indexed in their modules
        (GENERATED / "api" / f"{module}.md").write_text("\n".join([*page, "```", ""]))


_BAR = re.compile(r"(?<!\\)\|")


def _literal_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for an absolute value, as ``help()`` shows it; reStructuredText
    would read a substitution. Bars are escaped except in grid tables and literals."""
    in_grid = False
    for i, line in enumerate(lines):
        text = line.lstrip()
        in_grid = text.startswith(("+-", "+=")) or (in_grid and text.startswith(("|", "+")))
        if not in_grid:
            parts = re.split(r"(``.*?``)", line)
            lines[i] = "".join(part if k % 2 else _BAR.sub(r"\\|", part) for k, part in enumerate(parts))


def setup(app):
    app.connect("autodoc-process-docstring", _literal_bars)


(GENERATED / "settings_table.md").write_text(_settings_table())
(GENERATED / "errors.md").write_text(error_catalogue.markdown())
_api_pages()
