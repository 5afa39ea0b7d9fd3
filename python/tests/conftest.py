"""Shared paths and small scenes for the Python package's tests."""

import os
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
TEST_SCENES = ROOT / "tests" / "scenes"


def snell_command():
    """The `snell` console script installed beside this Python."""
    exe = Path(sys.executable).parent / ("snell.exe" if os.name == "nt" else "snell")
    if exe.exists():
        return str(exe)
    found = shutil.which("snell")
    if found is None:
        pytest.skip("the snell command is not installed")
    return found


def commands():
    """The command lines to compare Python with: the installed `snell`
    script (the same extension module) and, where the repository's own
    release build exists, the Rust binary (built by another compiler setup:
    fat LTO, one codegen unit)."""
    out = [("script", snell_command())]
    binary = ROOT / "target" / "release" / ("snell.exe" if os.name == "nt" else "snell")
    if binary.exists():
        out.append(("binary", str(binary)))
    return out


@pytest.fixture
def cornell():
    return str(SCENES / "cornell-box.xml")


@pytest.fixture
def polarized_scene():
    return str(TEST_SCENES / "polarized-glass-metal.xml")
