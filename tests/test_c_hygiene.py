"""Issues 28.11 and 28.16: the C that lagrgen writes is ISO C. Every example model's exported C
and FMU sources compile with `-std=c99 -trigraphs -Wall -Wextra -pedantic -Werror` (no unused
parameter when a model has no inputs, no string literal longer than C99 guarantees), and user
text (unit labels, names) reaches C only as escaped string literals: a label holding a trigraph
`??/` and C code neither ends its literal nor compiles as code, and reads back unchanged."""
import importlib.util
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor

import pytest
import sympy as sp

import lagrgen
from lagrgen import Model
from lagrgen.build import derived, model_info
from lagrgen.codegen import fmu
from lagrgen.codegen.c_model import standalone_files
from lagrgen.description import Description

from conftest import EXAMPLES

ISO_C = ["-std=c99", "-trigraphs", "-Wall", "-Wextra", "-pedantic", "-Werror", "-fsyntax-only"]
FMU_KINDS = [(kind, version) for kind in ("me", "cs") for version in (2, 3)]
#: A unit label that, pasted into a C string as it is, ends the literal under ISO C trigraphs
#: (??/ is a backslash) and compiles the rest as code.
HOSTILE = '??/";int/**/injected(void){return/**/1;}const/**/char*x="'

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")


def example_models():
    """Every Model defined at top level by the example files."""
    models = []
    for path in sorted(EXAMPLES.glob("*.py")):
        spec = importlib.util.spec_from_file_location(f"lagrgen_hygiene_{path.stem}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        models += [v for v in vars(module).values()
                   if isinstance(v, Description) and all(v is not m for m in models)]
    return models


def write_sources(model, directory, kinds=FMU_KINDS):
    """The exported C files of `model` and, for a smooth model, its FMU sources of the `kinds`:
    the arguments of each compilation (files, then include options)."""
    equations = derived(model.spec())
    info = model_info(model.spec(), equations)
    directory.mkdir(parents=True)
    units = []
    for file_name, text in standalone_files(info, equations).items():
        (directory / file_name).write_text(text, encoding="utf-8")
    units.append([directory / f"{info.name}_model.c"])
    if not info.nonsmooth_definitions:
        for kind, version in kinds:
            folder = directory / f"{kind}{version}"
            folder.mkdir()
            files = fmu.fmu_sources(info, equations, kind=kind, fmi_version=version)
            if kind == "cs":
                files.update({f: (fmu.NATIVE / f).read_text(encoding="utf-8")
                              for f in fmu.NATIVE_FILES})
            for file_name, text in files.items():
                (folder / file_name).write_text(text, encoding="utf-8")
            units.append([folder / f for f in fmu.source_file_names(info.name, kind)]
                         + ["-I", fmu.FMI_HEADERS[version]])
    return units


def iso_c_errors(arguments):
    result = subprocess.run(["gcc", *ISO_C, *map(str, arguments)], capture_output=True,
                            text=True)
    return "" if result.returncode == 0 else result.stderr[:3000]


def compile_all(units):
    with ThreadPoolExecutor(2) as pool:
        return [e for e in pool.map(iso_c_errors, units) if e]


def test_every_example_models_c_and_fmu_sources_compile_as_iso_c(tmp_path):
    units = []
    for model in example_models():
        units += write_sources(model, tmp_path / model.name, [("me", 2), ("cs", 3)])
    assert len(units) > 40
    assert compile_all(units) == []


def hostile_model():
    model = Model("hostile_labels")
    x, = model.coordinates("x", units=[HOSTILE])
    m, k = model.parameters(m=(1.0, "kg??="), k=4.0)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.output("speed", sp.diff(x, model.t), units="é??/??'")
    for i in range(80):        # metadata longer than the 4095 characters C99 guarantees
        model.output(f"an_output_with_a_long_name_{i}", x, units="m/s??/" * 4)
    return model


def test_a_hostile_unit_label_reaches_c_only_as_an_escaped_string(tmp_path):
    model = hostile_model()
    assert compile_all(write_sources(model, tmp_path / "sources")) == []
    model_c = (tmp_path / "sources" / "hostile_labels_model.c").read_text()
    assert "??" not in model_c
    mod = lagrgen.build(model, out_dir=tmp_path / "built")
    assert mod.units["x"] == HOSTILE and mod.units["speed"] == "é??/??'"
    assert mod.units["an_output_with_a_long_name_79"] == "m/s??/" * 4
