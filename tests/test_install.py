"""The installed package holds every module and data file of the source tree (checked on the
install the README makes: a wheel, not the working copy)."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

import lagrgen
from conftest import ROOT

SOURCE = ROOT / "src" / "lagrgen"
INSTALLED = Path(lagrgen.__file__).parent
SHIPPED_SUFFIXES = {".in", ".h", ".c", ".pxd", ".txt"}


def _source_modules():
    return sorted(".".join(("lagrgen",) + p.relative_to(SOURCE).with_suffix("").parts)
                  .replace(".__init__", "")
                  for p in SOURCE.rglob("*.py") if "__pycache__" not in p.parts)


def _source_data_files():
    return sorted(p.relative_to(SOURCE) for p in SOURCE.rglob("*")
                  if p.suffix in SHIPPED_SUFFIXES and p.is_file()
                  and not (p.suffix == ".c" and p.with_suffix(".pyx").exists()))


@pytest.mark.parametrize("name", _source_modules())
def test_every_source_module_is_installed(name):
    assert importlib.util.find_spec(name) is not None, f"{name} is in src/ but not in the install"


def test_every_template_and_native_source_is_installed():
    missing = [str(p) for p in _source_data_files() if not (INSTALLED / p).is_file()]
    assert not missing, f"files in src/lagrgen missing from the installed package: {missing}"


def test_the_command_line_runs_from_the_install():
    out = subprocess.run([sys.executable, "-m", "lagrgen", "--help"], capture_output=True, text=True,
                         cwd=ROOT.parent, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "build" in out.stdout
