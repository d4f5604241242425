"""Shared test setup: the Mitsuba variant, and the file resolver kept intact between tests.

The tests run on the LLVM (CPU) backend unless ``DOPPLERTOF_VARIANT`` says otherwise, so a
machine with a GPU still tests the CPU path by default.
"""

import os
from pathlib import Path

os.environ.setdefault("DOPPLERTOF_VARIANT", "llvm_ad_rgb")

import pytest  # noqa: E402

import dopplertof as dt  # noqa: E402  (sets up libLLVM before Dr.Jit starts)

dt.set_variant(os.environ["DOPPLERTOF_VARIANT"])

import mitsuba as mi  # noqa: E402

DATA_DIR = Path(__file__).parent / "data"


def _resolver_paths():
    resolver = mi.file_resolver()
    return [str(resolver[i]) for i in range(len(resolver))]


_INITIAL_RESOLVER_PATHS = _resolver_paths()


@pytest.fixture(autouse=True)
def _restore_file_resolver():
    """Put Mitsuba's file resolver back as it was at start-up after every test.

    Mitsuba finds its plugins through the file resolver: a test that leaves it without
    Mitsuba's own directory makes every later load of a not-yet-used plugin fail with
    "Plugin ... not found", far from the cause. `test_loader.py::
    test_loading_xml_keeps_the_file_resolver` checks that the loader itself keeps it
    intact; this fixture only stops one failure from cascading into unrelated tests.
    """
    _reset_file_resolver()  # also after module/session fixtures that loaded XML scenes
    yield
    _reset_file_resolver()


def _reset_file_resolver():
    if _resolver_paths() != _INITIAL_RESOLVER_PATHS:
        resolver = mi.file_resolver()
        resolver.clear()
        for path in _INITIAL_RESOLVER_PATHS:
            resolver.append(path)


@pytest.fixture(scope="session")
def data_dir():
    return DATA_DIR
