"""The documentation site (issue 21): it builds with warnings as errors and its tutorials
run (``scripts/docs.sh``), its internal links resolve, every CLI option is on the CLI page,
every public name of :mod:`dopplertof` has a docstring that documents each parameter (and
what it returns) in numpy sections, the top-level names' examples run, every error message
of the source has its entry on the troubleshooting page, and the README's links name files
of the repository.

The build runs once for this module (``site``, 1 to 1.5 min on 2 shared cores: the six
tutorials and the executed pages render at 16² to 32²). The checkers are tested on small
pages of their own, so that they can fail.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import click
import pytest

ROOT = Path(__file__).resolve().parent.parent
SITE = ROOT / "docs" / "_build" / "html"
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import error_catalogue  # noqa: E402
import public_api  # noqa: E402

# A link with a scheme (https:, mailto:, javascript:) leaves the site.
_EXTERNAL = re.compile(r"^([a-zA-Z][a-zA-Z0-9+.-]*:|//)")


class _Page(HTMLParser):
    """The links (href, src), element ids and text of one HTML page."""

    def __init__(self):
        super().__init__()
        self.links, self.ids, self.text = [], set(), []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("href", "src") and value:
                self.links.append(value)
            if name == "id" and value:
                self.ids.add(value)

    def handle_data(self, data):
        self.text.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def broken_links(site: Path) -> list[str]:
    """Every internal link of the HTML pages under ``site`` whose file or anchor is missing,
    as ``page: link``."""
    pages = {path.resolve(): _parse(path) for path in site.rglob("*.html")}
    broken = []
    for path, page in pages.items():
        for link in page.links:
            if _EXTERNAL.match(link):
                continue
            target, _, anchor = link.partition("#")
            target = target.split("?")[0]
            resolved = (path.parent / target).resolve() if target else path
            if not resolved.exists():
                broken.append(f"{path.relative_to(site.resolve())}: {link}")
            elif anchor and resolved.suffix == ".html" and anchor not in pages[resolved].ids:
                broken.append(f"{path.relative_to(site.resolve())}: {link} (no anchor)")
    return broken


def cli_options(group: click.Group) -> list[str]:
    """Every command path and option (``dopplertof render --spp``, ``--no-…`` forms
    included) of the command tree, lazily loaded commands included."""
    found = []

    def walk(command, path):
        found.append(path)
        for param in command.params:
            if isinstance(param, click.Option) and not param.hidden:
                found.extend(f"{path} {opt}" for opt in (*param.opts, *param.secondary_opts))
        if isinstance(command, click.Group):
            context = click.Context(command)
            for name in command.list_commands(context):
                walk(command.get_command(context, name), f"{path} {name}")

    walk(group, "dopplertof")
    return found


def missing_from_cli_page(text: str, group: click.Group) -> list[str]:
    """The commands and options of ``group`` whose name (last word) ``text`` does not hold."""
    words = set(re.findall(r"[\w-]+", text))
    return [entry for entry in cli_options(group) if entry.split()[-1] not in words]


# ------------------------------------------------------------------------------ the site


@pytest.fixture(scope="module")
def site():
    run = subprocess.run(["bash", "scripts/docs.sh"], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, f"{run.stdout[-8000:]}\n{run.stderr[-8000:]}"
    assert (SITE / "index.html").exists()
    return SITE


@pytest.mark.slow
def test_internal_links_resolve(site):
    assert broken_links(site) == []


@pytest.mark.slow
def test_every_cli_option_is_on_the_cli_page(site):
    from dopplertof.cli import main

    assert missing_from_cli_page(" ".join(_parse(site / "cli.html").text), main) == []


@pytest.mark.slow
def test_tutorials_show_their_images(site):
    tutorials = sorted((ROOT / "docs" / "tutorials").glob("0*.md"))
    assert len(tutorials) == 6
    for source in tutorials:
        page = _parse(site / "tutorials" / f"{source.stem}.html")
        images = [link for link in page.links if link.endswith(".png")]
        assert images, f"{source.name}: no image in the built page"
    settings = " ".join(_parse(site / "cli.html").text)
    from dopplertof.settings import FIELDS

    assert all(name in settings for name in FIELDS), "the settings table is missing settings"


def test_the_readmes_links_resolve():
    """The README links into the docs pages (their Markdown sources) and shows an image: each
    relative link names a file of the repository."""
    links = re.findall(r"\]\(([^)\s]+)\)", (ROOT / "README.md").read_text())
    targets = [link.partition("#")[0] for link in links if not _EXTERNAL.match(link)]
    assert [t for t in targets if t and not (ROOT / t).exists()] == []


# ------------------------------------------------------------------------------ docstrings


def test_every_public_name_has_a_docstring():
    assert public_api.undocumented() == []


def test_the_top_level_names_have_examples_that_run():
    """Every name of ``dopplertof.__all__`` (modules aside) and ``reconstruct.velocity`` has
    an Examples section, and every example of a public name gives what it shows (doctest)."""
    import doctest

    import mitsuba as mi

    import dopplertof

    required = [f"dopplertof.{n}" for n in dopplertof.__all__ if not isinstance(getattr(dopplertof, n), type(dopplertof))]
    required.append("dopplertof.reconstruct.velocity")
    names = [*required, *(f"{m}.{n}" for m in public_api.public_modules() for n in public_api.module_members(m))]
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report, variant, seen = [], mi.variant(), set()
    try:
        dopplertof.set_variant("llvm_ad_rgb")  # the examples show RGB shapes
        for name in names:
            module, _, attribute = name.rpartition(".")
            obj = getattr(importlib.import_module(module), attribute)
            tests = [t for t in finder.find(obj, name, globs={}) if t.examples] if callable(obj) else []
            assert tests or name not in required, f"{name}: no example in its docstring"
            for test in tests:
                if id(obj) not in seen:  # a name exported twice runs once
                    runner.run(test, out=report.append)
            seen.add(id(obj))
    finally:
        dopplertof.set_variant(variant)
    assert runner.failures == 0, "".join(report)
    assert runner.tries >= 2 * len(required)


def test_an_undocumented_name_is_found(monkeypatch):
    import dopplertof.reconstruct

    monkeypatch.setattr(dopplertof.reconstruct.velocity, "__doc__", None)
    monkeypatch.setattr(dopplertof.reconstruct.VelocityResult, "__doc__", "")
    assert {"dopplertof.reconstruct.VelocityResult", "dopplertof.reconstruct.velocity"} <= set(public_api.undocumented())


def test_every_public_callable_documents_its_parameters_and_returns():
    assert public_api.incomplete_docstrings() == []


# ------------------------------------------------------------------------------ error messages

PACKAGE = ROOT / "src" / "dopplertof"


def test_every_error_message_is_in_the_troubleshooting_catalogue():
    messages = error_catalogue.source_messages(PACKAGE)
    assert len(messages) > 300
    assert error_catalogue.uncatalogued(messages) == []


def test_every_catalogue_entry_matches_a_message():
    """An entry whose message was reworded or removed goes (or follows the new wording)."""
    assert error_catalogue.unused_entries(error_catalogue.source_messages(PACKAGE)) == []


def test_an_uncatalogued_message_is_found(tmp_path):
    (tmp_path / "module.py").write_text(
        "NEEDS_RAY = 'this needs the ray package'\n"
        "def f(x, where):\n"
        "    if x:\n"
        "        raise ValueError(f'{where}: speed must be > 0 m/s, got {x!r}')\n"
        "    if where:\n"
        "        fail(f'brand new problem with {x}')\n"
        "    click.echo('error: stopped early', err=True)\n"
        "    click.echo('stopped early', err=True)\n"  # not an error line
        "    raise ValueError(f'{where}: {x}')\n"  # passes another message on: not a message of its own
        "    raise ValueError(NEEDS_RAY)\n"
    )
    messages = error_catalogue.source_messages(tmp_path)
    assert [m[2] for m in messages] == ["…: speed must be > 0 m/s, got …", "brand new problem with …", "stopped early", "this needs the ray package"]
    topics = [("topic", "", [("…: speed must be", "means", "do")])]
    assert error_catalogue.uncatalogued(messages, topics) == [
        "module.py:6: brand new problem with …", "module.py:7: stopped early", "module.py:10: this needs the ray package",
    ]
    assert error_catalogue.unused_entries(messages[:1], topics + [("more", "", [("gone", "", "")])]) == ["gone"]


def test_a_printed_message_finds_its_entry():
    """Values filled in, a ``where:`` prefix added by a caller, the most specific entry wins."""
    general = ("… must be …, got …", "out of range", "")
    specific = ("'seed' must be < 2**32, got …", "seeds are 32-bit", "")
    topics = [("topic", "", [general, specific])]
    assert error_catalogue.entry_for("scene.xml: 'seed' must be < 2**32, got 5000000000", topics) == specific
    assert error_catalogue.entry_for("'spp' must be >= 1,\n got 0", topics) == general
    assert error_catalogue.entry_for("no such scene", topics) is None


@pytest.mark.slow
def test_the_troubleshooting_page_shows_the_catalogue(site):
    text = " ".join(" ".join(_parse(site / "troubleshooting.html").text).split())
    missing = [entry[0] for _, _, entries in error_catalogue.TOPICS for entry in entries if entry[0] not in text]
    assert missing == []


# ------------------------------------------------------------------------------ the checkers


def test_broken_links_are_found(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.html").write_text('<a href="sub/b.html#there">ok</a> <a href="#top" id="top">self</a> <a href="https://example.org/x">out</a> <img src="pic.png">')
    (tmp_path / "pic.png").write_bytes(b"")
    (tmp_path / "sub" / "b.html").write_text('<h1 id="there"></h1> <a href="../a.html#nowhere">bad anchor</a> <a href="gone.html">gone</a>')
    assert sorted(broken_links(tmp_path)) == ["sub/b.html: ../a.html#nowhere (no anchor)", "sub/b.html: gone.html"]


def test_a_missing_cli_option_is_found():
    @click.group()
    def group():
        """A group."""

    @group.command()
    @click.option("--fast/--no-fast")
    @click.option("-n", "--count")
    def run(fast, count):
        """A command."""

    page = "dopplertof run --fast --no-fast -n"
    assert missing_from_cli_page(page, group) == ["dopplertof run --count"]


def test_a_missing_parameter_or_returns_section_is_found():
    def documented(distance_m, speed_m_s=1.0, **extra):
        """A function.

        Parameters
        ----------
        distance_m : float, metres
            How far.
        speed_m_s : float, m/s, default 1
        **extra
            More.
        """

    def one_missing(distance_m, speed_m_s=1.0):
        """A function.

        Parameters
        ----------
        distance_m, other : float. How far.
        """

    def no_section(distance_m):
        """A function without sections."""

    def twice(distance_m):
        """A function.

        Parameters
        ----------
        distance_m : float, m

        Parameters
        ----------
        distance_m : float, m
        """

    class Plugin:
        """A plugin with a table.

        ============  ==============
        name          meaning
        ============  ==============
        ``props``     its properties,
                      all of them
        ============  ==============
        """

        def __init__(self, props):
            pass

        def move(self, speed_m_s):
            """Move (``self`` needs no entry).

            Parameters
            ----------
            speed_m_s : float, m/s
            """

    assert public_api.docstring_gaps(documented) == []
    assert public_api.docstring_gaps(Plugin.move) == []
    assert public_api.docstring_gaps(one_missing) == ["missing parameter speed_m_s"]
    assert public_api.docstring_gaps(no_section) == ["no parameter section"]
    assert public_api.docstring_gaps(twice) == ["section Parameters twice"]
    assert public_api.docstring_gaps(Plugin) == []
    assert public_api.docstring_gaps(lambda: None) == []

    def returns_a_value() -> float:
        """A number, without saying so in a section."""

    def says_what_it_returns() -> float:
        """A number.

        Returns
        -------
        float
        """

    assert public_api.docstring_gaps(returns_a_value) == ["no Returns section"]
    assert public_api.docstring_gaps(says_what_it_returns) == []
