"""Run the fenced code blocks of a Markdown page as its reader would, top to bottom.

Works on any CommonMark page (the README, docs pages): :func:`fenced_blocks` finds the
fenced blocks (backtick or tilde fences, any length, an info string naming the language),
:func:`shell_commands` splits a shell block into its commands (``\\`` continuations
joined, comments and blank lines dropped), and :func:`session_script` writes one Python
script that runs a page's blocks in order in one process: Python blocks share one
namespace, as in a reader's interpreter session, and each shell command runs in ``bash``
(``set -euo pipefail``). The first failure stops the script with exit status 1 and a line
``PAGE:LINE: ...`` naming the block; tracebacks of Python blocks carry the page's own line
numbers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

SHELL = ("sh", "bash", "shell")
PYTHON = ("python", "py", "python3")

_FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`]*)$")


@dataclass(frozen=True)
class Block:
    """A fenced block: its language (first word of the info string, lower case, "" if
    none), its text and the 1-based line of the page its first text line is on."""

    language: str
    text: str
    line: int


@dataclass(frozen=True)
class Command:
    """One shell command of a block (continuations joined) and the page line it starts on."""

    text: str
    line: int


def fenced_blocks(markdown: str) -> list[Block]:
    """Every fenced code block of ``markdown``, in order. An unclosed fence runs to the end
    of the page, as CommonMark says."""
    blocks = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        opening = _FENCE.match(lines[i])
        if not opening:
            i += 1
            continue
        fence, indent = opening["fence"], len(opening["indent"])
        info = opening["info"].strip().split()
        body = []
        j = i + 1
        while j < len(lines):
            closing = _FENCE.match(lines[j])
            if closing and closing["fence"][0] == fence[0] and len(closing["fence"]) >= len(fence) and not closing["info"].strip():
                break
            # CommonMark: up to the fence's own indentation is removed from each line.
            body.append(re.sub(rf"^ {{0,{indent}}}", "", lines[j]))
            j += 1
        blocks.append(Block(info[0].lower() if info else "", "\n".join(body) + "\n", i + 2))
        i = j + 1
    return blocks


def shell_commands(block: Block) -> list[Command]:
    """The commands of a shell block: backslash continuations joined, blank and comment
    lines dropped (a trailing comment stays: bash ignores it)."""
    commands = []
    pending, start = "", None
    for offset, line in enumerate(block.text.splitlines()):
        if start is None:
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            start = block.line + offset
        if line.endswith("\\"):
            pending += line[:-1]
            continue
        commands.append(Command(pending + line, start))
        pending, start = "", None
    if start is not None:
        commands.append(Command(pending, start))
    return commands


_PRELUDE = '''\
import linecache, subprocess, sys, time
_namespace = {"__name__": "__main__"}

def _fail(where, message):
    print(f"{where}: {message}", flush=True)
    sys.exit(1)

def _python(where, code):
    print(f"--- {where}: python block", flush=True)
    start = time.perf_counter()
    filename = where.split(":")[0] + " (as run)"  # tracebacks show the code run, substitutions made
    linecache.cache[filename] = (len(code), None, code.splitlines(True), filename)
    try:
        exec(compile(code, filename, "exec"), _namespace)
    except BaseException:
        import traceback
        traceback.print_exc()
        sys.stderr.flush()
        _fail(where, "this Python block failed (traceback above)")
    print(f"    {time.perf_counter() - start:.1f} s", flush=True)

def _shell(where, command):
    print(f"--- {where}: $ {command}", flush=True)
    start = time.perf_counter()
    status = subprocess.run(["bash", "-c", "set -euo pipefail\\n" + command]).returncode
    if status:
        _fail(where, f"exit status {status}: {command}")
    print(f"    {time.perf_counter() - start:.1f} s", flush=True)
'''


def session_script(page: str, steps: list[tuple[str, int, str]]) -> str:
    """A Python script that runs ``steps`` in order: (kind, line, code) with kind
    ``"python"`` (a block's text, first line at page line ``line``) or ``"shell"`` (one
    command); ``page`` names the page in messages and tracebacks."""
    out = [_PRELUDE]
    for kind, line, code in steps:
        where = f"{page}:{line}"
        if kind == "python":
            padded = "\n" * (line - 1) + code  # tracebacks then show the page's line numbers
            out.append(f"_python({where!r}, {padded!r})")
        elif kind == "shell":
            out.append(f"_shell({where!r}, {code!r})")
        else:
            raise ValueError(f"unknown step kind {kind!r}")
    return "\n".join(out) + "\n"
