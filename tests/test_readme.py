"""The README executed: every fenced ``sh`` and ``python`` block runs, in order, as a reader
would run it (issue 16).

Each page of :data:`PAGES` runs as one session (:mod:`markdown_blocks`) in a fresh folder
that holds the repository's files (links) and the environment running the tests as
``.venv``: Python blocks share one interpreter, shell commands run in ``bash`` with the
environment's ``bin`` first on ``PATH``. Render sizes are made small by the explicit
:data:`SUBSTITUTIONS`; only what cannot run in CI is skipped, by :data:`SKIP_COMMANDS` and
:data:`SKIP_BLOCKS`, each with its reason. A table entry that matches nothing fails, so the
tables cannot outlive the text they were written for. Also here: what the README states
about the package's version and the benchmarks' ``--quick`` runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from markdown_blocks import PYTHON, SHELL, Block, fenced_blocks, session_script, shell_commands

import dopplertof as dt

ROOT = Path(__file__).resolve().parent.parent

# The pages whose blocks run (paths from the repository root): the README and the docs pages
# with shell or Python blocks (the executed notebook pages run in tests/test_docs.py).
PAGES = ("README.md", "docs/installation.md", "docs/quickstart.md", "docs/cli.md", "docs/python-api.md", "docs/scene-format.md",
         "docs/reconstruction.md", "docs/sensors.md", "docs/datasets.md", "docs/paper.md")

# The repository's files and folders a page's commands use (linked into the session folder,
# which keeps what the commands write: out/, data/, my.toml).
LINKED = ("README.md", "pyproject.toml", "scripts", "src", "benchmarks", "tests")

# Files a page's commands take as the reader's own: name in the session folder -> source.
FILES = {
    "my_scene.xml": "tests/data/readme_scene.xml",  # "render my_scene.xml": a file written from the "Scene format" section
}

# (text in the page, text run instead): sizes small enough for CI, the same commands.
SUBSTITUTIONS = (
    ("bash scripts/demo.sh ", "bash scripts/demo.sh --spp 4 --resolution 32 "),  # extra arguments go to its render
    ("render cornell-box --spp 256 -o out/cb", "render cornell-box --spp 4 --resolution 32 -o out/cb"),
    ("render my_scene.xml --spp 1024", "render my_scene.xml --spp 4"),
    ("animate falling-box --fps 30 --spp 256 --resolution 128", "animate falling-box --fps 30 --frames 2 --spp 4 --resolution 16"),
    ("experiment time-sampling cornell-box ", "experiment time-sampling cornell-box --quick "),
    ("experiment shifts cornell-box ", "experiment shifts cornell-box --quick "),
    ("experiment velocity cornell-box ", "experiment velocity cornell-box --quick "),
    ("experiment paper-fig12 cornell-box ", "experiment paper-fig12 cornell-box --quick "),
    ("experiment paper-fig9 cornell-box ", "experiment paper-fig9 cornell-box --quick "),
    ("experiment paper-fig15 cornell-box ", "experiment paper-fig15 cornell-box --quick "),
    ("dt.scenes.cornell_box(resolution=128)", "dt.scenes.cornell_box(resolution=16)"),
    ("dt.scenes.cornell_box(resolution=64)", "dt.scenes.cornell_box(resolution=16)"),
    ("result = dt.render(scene, cameras=cameras, spp=64, max_depth=4)", "result = dt.render(scene, cameras=cameras, spp=4, max_depth=4)"),
    ("render cornell-box --spp 64 --resolution 64 -o out/quick", "render cornell-box --spp 4 --resolution 16 -o out/quick"),
    ("dt.scenes.rotating(resolution=64)", "dt.scenes.rotating(resolution=16)"),
    ("res = dt.render(scene, sensor=S, spp=64)", "res = dt.render(scene, sensor=S, spp=4)"),
    ("spp=256, seed=0, max_depth=4", "spp=4, seed=0, max_depth=4"),
    ("result = dt.render(scene, cameras=cameras, spp=256)", "result = dt.render(scene, cameras=cameras, spp=4)"),
    ("res = dt.render(scene, cameras=cameras, spp=256)", "res = dt.render(scene, cameras=cameras, spp=4)"),
    ("moving = dt.render(driving, cameras=cameras, spp=64", "moving = dt.render(driving, cameras=cameras, spp=4"),
    ("render falling-box -o out/seq", "render falling-box --spp 4 --resolution 16 -o out/seq"),
    ("--samples 10000 --seed 0 --config my.toml \\\n    --resolution 128 --spp 64", "--samples 2 --seed 0 --config my.toml \\\n    --resolution 16 --spp 4"),
    ('generate("data/ds", 10000, seed=0, config="my.toml", resolution=128, spp=64', 'generate("data/ds", 2, seed=0, config="my.toml", resolution=16, spp=4'),
    ("img = mi.render(scene, spp=64)", "img = mi.render(scene, spp=4)"),
)

# Shell commands that cannot run in CI (a command containing the text is skipped).
SKIP_COMMANDS = (
    ("bash scripts/test.sh", "the whole test suite, of which this test is part"),
    ("pip install", "installs packages: CI's environment is made by scripts/setup.sh"),
    ("pip wheel", "its isolated build needs the package index (setuptools); test_one_version checks the version it gets"),
    ("conda install", "conda is not part of CI's environment"),
    ("bash scripts/docs.sh", "the documentation build: tests/test_docs.py runs it"),
)

# Blocks that cannot run in CI (a block containing the text is skipped whole).
SKIP_BLOCKS = (("#SBATCH", "a Slurm batch script: needs a Slurm cluster"),)

# Languages of blocks that do not run, and why; a block in any other language fails the test.
NOT_RUN = {
    "xml": "fragments of scene files; a whole file written from them, tests/data/readme_scene.xml, is the session's my_scene.xml",
    "{include}": "a Sphinx directive inserting a generated file (the settings table); tests/test_docs.py builds it",
    "{eval-rst}": "reStructuredText for Sphinx (the generated CLI reference); tests/test_docs.py builds it",
}


def _steps(page: str) -> tuple[list[tuple[str, int, str]], set, set]:
    """The session's steps for ``page`` (after substitutions and skips), and the entries of
    the tables that matched."""
    text = (ROOT / page).read_text()
    substituted = set()
    for old, new in SUBSTITUTIONS:
        if old in text:
            text = text.replace(old, new)
            substituted.add(old)
    skipped, steps = set(), []
    for block in fenced_blocks(text):
        if block.language in NOT_RUN:
            continue
        assert block.language in SHELL + PYTHON, f"{page}:{block.line}: a ```{block.language} block: run it (SHELL, PYTHON) or say why not (NOT_RUN)"
        reasons = [marker for marker, _ in SKIP_BLOCKS if marker in block.text]
        if reasons:
            skipped.update(reasons)
            continue
        if block.language in PYTHON:
            steps.append(("python", block.line, block.text))
            continue
        for command in shell_commands(block):
            reasons = [marker for marker, _ in SKIP_COMMANDS if marker in command.text]
            skipped.update(reasons)
            if not reasons:
                steps.append(("shell", command.line, command.text))
    return steps, substituted, skipped


def test_every_table_entry_applies():
    substituted, skipped = set(), set()
    for page in PAGES:
        _, s, k = _steps(page)
        substituted |= s
        skipped |= k
    assert [old for old, _ in SUBSTITUTIONS if old not in substituted] == []
    assert [m for m, _ in (*SKIP_COMMANDS, *SKIP_BLOCKS) if m not in skipped] == []


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES)
def test_page_runs(page, tmp_path):
    """Every block of ``page`` runs, in order, in one session (the README: 30-60 s on 2
    shared cores)."""
    steps, _, _ = _steps(page)
    for name in LINKED:
        (tmp_path / name).symlink_to(ROOT / name)
    (tmp_path / ".venv").symlink_to(sys.prefix)  # the README's .venv/bin/...: the environment under test
    for name, source in FILES.items():
        (tmp_path / name).write_bytes((ROOT / source).read_bytes())
    script = tmp_path / "session.py"
    script.write_text(session_script(page, steps))
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
        "DOPPLERTOF_CACHE": str(tmp_path / "cache"),  # the experiments' references: not the user's cache
        "MPLBACKEND": "Agg",
    }
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"{run.stdout[-6000:]}\n{run.stderr[-6000:]}"


# ------------------------------------------------------------------------------ the extractor


def test_fenced_blocks_and_commands():
    page = "\n".join([
        "text", "```sh", "a \\", "  --x 1   # note", "", "# a comment", "b", "```",
        "  ~~~~ Python extra", "  x = 1", "  ```", "  y = 2", "  ~~~~", "```", "unclosed",
    ])  # fmt: skip
    blocks = fenced_blocks(page)
    assert blocks == [
        Block("sh", "a \\\n  --x 1   # note\n\n# a comment\nb\n", 3),
        Block("python", "x = 1\n```\ny = 2\n", 10),  # a shorter or other fence does not close it
        Block("", "unclosed\n", 15),
    ]
    assert [(c.text, c.line) for c in shell_commands(blocks[0])] == [("a   --x 1   # note", 3), ("b", 7)]


def test_a_failing_block_names_its_line(tmp_path):
    script = tmp_path / "s.py"
    script.write_text(session_script("PAGE.md", [("python", 3, "x = 1\n"), ("shell", 7, "false"), ("python", 9, "raise SystemExit")]))
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 1 and "PAGE.md:7: exit status 1" in run.stdout and "PAGE.md:9" not in run.stdout
    script.write_text(session_script("PAGE.md", [("python", 3, "x = 1\n"), ("python", 5, "\ny = x + undefined\n")]))
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 1 and "PAGE.md:5: this Python block failed" in run.stdout
    assert 'File "PAGE.md (as run)", line 6' in run.stderr and "y = x + undefined" in run.stderr  # the page's own line


# ------------------------------------------------------------------------------ what the README states


def test_one_version():
    """pyproject takes its version from the package (no second copy); the CLI shows it."""
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "dopplertof.__version__"}
    run = subprocess.run([sys.executable, "-m", "dopplertof.cli", "--version"], capture_output=True, text=True)
    assert run.returncode == 0 and run.stdout == f"dopplertof {dt.__version__}\n"


def test_quick_benchmarks_keep_the_committed_results():
    """A ``--quick`` run writes ``<name>_quick.csv``: every benchmark with ``--quick`` gets
    its output paths from ``_common.default_output_paths``, which says so."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import _common
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    for quick in (False, True):
        args = type("Args", (), {"csv": None, "plot": None, "quick": quick})()
        _common.default_output_paths(args, "x")
        assert Path(args.csv).name == ("x_quick.csv" if quick else "x.csv") and Path(args.plot).name == Path(args.csv).stem + ".png"
    for script in sorted((ROOT / "benchmarks").glob("[!_]*.py")):
        source = script.read_text()
        if "--quick" in source:
            assert "_common.default_output_paths(args" in source, f"{script.name}: --quick must not write the full run's CSV"
            assert not re.search(r'"--csv", default=[^N]', source), f"{script.name}: its --csv default bypasses default_output_paths"
