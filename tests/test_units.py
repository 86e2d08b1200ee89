"""Units compiled on first use (issue 30): a build compiles what running the model needs; the
analysis functions (parameter Jacobian, directional derivatives, ...) are compiled the first time
they are called, once, into their own module in the model's cache entry, the same after
`lagrgen.load()` or `import <name>` in a fresh process, from any number of threads; and a unit
that cannot be made says why."""
import ast
import pickle
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import cache
from lagrgen.functions import FUNCTIONS, MODEL_UNIT


def chain(name, stiffer=1):
    """Two masses on springs, with a damper and a parameter in the inertia (the first spring
    `stiffer` times as stiff: another model of the same names)."""
    model = lagrgen.Model(name)
    x1, x2 = model.coordinates("x1 x2")
    m1, m2, k, c = model.parameters(m1=1.0, m2=2.0, k=3.0, c=0.2)
    model.particle(m1, sp.Matrix([x1]))
    model.particle(m2, sp.Matrix([x2]))
    model.spring(stiffer * k, x1)
    model.spring(k, x2 - x1)
    model.damper(c, x2 - x1)
    return model


Y = np.array([0.1, -0.2, 0.3, 0.05])


def analysis_units(out, name):
    """The directories of the units compiled on first use in the entries of `name`."""
    return sorted(p for p in (out / cache.CACHE_DIR).glob(f"{name}-*/*") if p.is_dir())


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("units")
    return out, lagrgen.build(chain("lazy_chain"), out_dir=out, quiet=True)


def test_a_build_compiles_only_what_running_needs(built):
    out, mod = built
    source = (out / "lazy_chain_model.c").read_text()
    assert "lazy_chain_rhs(" in source and "lazy_chain_jacobian(" in source
    assert "lg_parameter_b" not in source and "lg_motion_tape" not in source
    assert "lazy_chain_parameter_jacobian" not in source
    assert not analysis_units(out, "lazy_chain")
    assert {f.unit for f in FUNCTIONS} > {MODEL_UNIT}


def test_an_analysis_function_compiles_its_unit_once_on_first_use(built):
    out, mod = built
    python = lagrgen.build(chain("lazy_chain"), backend="python")
    results = []

    def call():
        results.append(mod.parameter_jacobian(0.2, Y))
    threads = [threading.Thread(target=call) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(results) == 4 and len(analysis_units(out, "lazy_chain")) == 1
    for result in results:
        assert_allclose(result, python.parameter_jacobian(0.2, Y), rtol=1e-12, atol=1e-14)
    ydot, products = mod.directional_derivatives(0.2, Y, np.eye(4))
    assert_allclose(products, mod.jacobian(0.2, Y).T, rtol=1e-12, atol=1e-14)
    assert [p.name.split("-")[0] for p in analysis_units(out, "lazy_chain")] == \
        sorted(["parameters", "directions"])


FRESH = """
import sys, numpy as np
{prelude}
P = mod.parameter_jacobian(0.2, np.array({y}))
print(repr(P.tolist()), 'sympy' in sys.modules)
"""


@pytest.mark.parametrize("how", ["load", "import"])
def test_a_fresh_process_compiles_or_finds_the_unit(built, how):
    out, mod = built
    prelude = (f"import lagrgen\nmod = lagrgen.load('lazy_chain', {str(out)!r})" if how == "load"
               else f"sys.path.insert(0, {str(out)!r})\nimport lazy_chain as mod")
    if how == "load":          # compiled anew in the fresh process, from the kept description
        for unit in analysis_units(out, "lazy_chain"):
            if unit.name.startswith("parameters-"):
                shutil.rmtree(unit)
    run = subprocess.run([sys.executable, "-c", FRESH.format(prelude=prelude, y=Y.tolist())],
                         capture_output=True, text=True, check=True)
    values, sympy_imported = run.stdout.rsplit(" ", 1)
    assert_allclose(np.array(ast.literal_eval(values)), mod.parameter_jacobian(0.2, Y),
                    rtol=1e-12)
    assert [p.name.startswith("parameters-") for p in analysis_units(out, "lazy_chain")].count(
        True) == 1
    if how == "import":        # found in the entry: nothing derived, SymPy not even imported
        assert sympy_imported.strip() == "False"


def test_a_unit_that_cannot_be_made_says_why(built, tmp_path):
    out, mod = built
    module_file = next(out.glob("lazy_chain.*"))
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(module_file, alone)
    script = (f"import sys\nsys.path.insert(0, {str(alone)!r})\nimport lazy_chain\n"
              f"lazy_chain.parameter_jacobian(0.0, [0.0] * 4)")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert run.returncode != 0
    assert "BuildError" in run.stderr and "compiled on first use from its cache entry" in run.stderr
    with pytest.raises(ValueError, match="no function"):
        mod.compiled_model.address("no_such_function")
    moved = tmp_path / "moved"
    shutil.copytree(out, moved)
    for unit in analysis_units(moved, "lazy_chain"):
        shutil.rmtree(unit)
    entry = next((moved / cache.CACHE_DIR).glob("lazy_chain-*"))
    other = chain("lazy_chain")
    other.parameters(extra=1.0)
    (entry / cache.DESCRIPTION).write_bytes(pickle.dumps(other.spec()))
    script = (f"import lagrgen\nlagrgen.load('lazy_chain', {str(moved)!r})"
              f".parameter_jacobian(0.0, [0.0] * 4)")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert run.returncode != 0
    assert "keeps the description.pickle of another model ('lazy_chain' with coordinates x1, " \
           "x2) than compiled model 'lazy_chain'" in run.stderr and "force=True" in run.stderr
    (entry / cache.GENERATOR).write_text("0" * 64 + "\n")    # as another lagrgen made it
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert run.returncode != 0 and "built by another version" in run.stderr


def test_a_recursive_models_units_hold_its_tree_kernels(tmp_path):
    """The model unit of a recursive model compiles the tree kernels running needs (node records,
    their slopes for the Jacobian); tree_parameters waits for the parameters unit, and the
    directions unit sweeps the recursion; in a fresh process the unit is derived again in the
    model's formulation."""
    mod = lagrgen.build(chain("tree_chain"), out_dir=tmp_path, formulation="recursive", quiet=True)
    python = lagrgen.build(chain("tree_chain"), backend="python", formulation="recursive")
    assert mod.formulation == "recursive"
    source = (tmp_path / "tree_chain_model.c").read_text()
    defined = set(re.findall(r"^LG_FN static (?:void|int) (lg_\w+)\(", source, re.M))
    assert {"lg_tree_nodes", "lg_tree_slopes", "lg_tree_jacobian"} <= defined
    assert "#define LG_TREE_PARAMETERS 0" in source and "lg_tree_parameters" not in defined
    P = mod.parameter_jacobian(0.2, Y)
    assert_allclose(P, python.parameter_jacobian(0.2, Y), rtol=1e-12, atol=1e-14)
    unit, = analysis_units(tmp_path, "tree_chain")
    assert re.search(r"^LG_FN static int lg_tree_parameters\(",
                     (unit / "tree_chain_parameters_model.c").read_text(), re.M)
    dy, dp = np.vstack([np.eye(4), Y]), np.arange(20.0).reshape(5, 4) / 10
    ydot, products = mod.directional_derivatives(0.2, Y, dy, dp)
    assert_allclose(ydot, mod.rhs(0.2, Y), rtol=1e-14)
    assert_allclose(products, dy @ mod.jacobian(0.2, Y).T + dp @ P.T, rtol=1e-12, atol=1e-14)
    shutil.rmtree(unit)
    prelude = f"import lagrgen\nmod = lagrgen.load('tree_chain', {str(tmp_path)!r})"
    run = subprocess.run([sys.executable, "-c", FRESH.format(prelude=prelude, y=Y.tolist())],
                         capture_output=True, text=True, check=True)
    assert_allclose(np.array(ast.literal_eval(run.stdout.rsplit(" ", 1)[0])), P, rtol=1e-12)


# -- issue 37: damaged, foreign and private units ------------------------------------------------
def unit_dir(out, name, label="parameters"):
    unit, = (p for p in analysis_units(out, name) if p.name.startswith(f"{label}-"))
    return unit


def forge(directory, module, data):
    """Put `data` in place of the module file of the unit in `directory`, with a matching
    module.sha256 (a damage or a copy its digest cannot catch)."""
    import hashlib
    target = directory / f"{module}{cache.EXT_SUFFIX}"
    target.unlink()
    target.write_bytes(data)
    (directory / "module.sha256").write_text(hashlib.sha256(data).hexdigest() + "\n")


CALL = """
import sys, lagrgen, numpy as np
mod = lagrgen.load(sys.argv[1], sys.argv[2])
print(repr(mod.parameter_jacobian(0.2, np.array({y})).tolist()))
""".format(y=Y.tolist())


def call_in_fresh_process(name, out):
    run = subprocess.run([sys.executable, "-c", CALL, name, str(out)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, f"the process died ({run.returncode}): {run.stderr[-1500:]}"
    return np.array(ast.literal_eval(run.stdout.strip()))


def test_a_truncated_unit_with_a_matching_digest_is_compiled_again(tmp_path):
    """Issue 37.5: a unit cut short whose module.sha256 was made to match is not whole (its
    segments reach past its end): it is compiled again, never imported (which killed every
    process with SIGBUS); the model's own module alike."""
    mod = lagrgen.build(chain("cut_unit"), out_dir=tmp_path, quiet=True)
    expected = mod.parameter_jacobian(0.2, Y)
    unit = unit_dir(tmp_path, "cut_unit")
    whole = (unit / f"cut_unit_parameters{cache.EXT_SUFFIX}").read_bytes()
    forge(unit, "cut_unit_parameters", whole[:len(whole) * 3 // 4])
    assert f'"content_hash": "{mod.content_hash}"'.encode() in whole[:len(whole) * 3 // 4]
    for _ in range(2):
        assert_allclose(call_in_fresh_process("cut_unit", tmp_path), expected, rtol=1e-14)
    assert (unit / f"cut_unit_parameters{cache.EXT_SUFFIX}").read_bytes() != \
        whole[:len(whole) * 3 // 4]
    assert cache.whole_module(whole) and not cache.whole_module(whole[:-1])
    entry = next((tmp_path / cache.CACHE_DIR).glob("cut_unit-*"))
    main = (entry / f"cut_unit{cache.EXT_SUFFIX}").read_bytes()
    forge(entry, "cut_unit", main[:len(main) * 3 // 4])
    with pytest.raises(lagrgen.BuildError, match="cannot be verified"):
        lagrgen.load("cut_unit", tmp_path)
    script = ("import sys, lagrgen\nsys.path.insert(0, sys.argv[2])\nfrom test_units import chain\n"
              "mod = lagrgen.build(chain('cut_unit'), out_dir=sys.argv[1], quiet=True)\n"
              "print(mod.build_info['cache_hit'], mod.rhs(0.2, [0.1, -0.2, 0.3, 0.05])[2])")
    run = subprocess.run([sys.executable, "-c", script, str(tmp_path), str(Path(__file__).parent)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-1500:]
    hit, value = run.stdout.split()
    assert hit == "False" and float(value) == mod.rhs(0.2, Y)[2]


def test_a_foreign_unit_is_discarded_and_compiled_again(tmp_path):
    """Issue 37.8: a unit copied from another model with its digests (module.sha256,
    content.sha256) does not carry the model's content hash: it is discarded and compiled again
    like a damaged one, never imported, so the model's own numbers come back at once, in this
    process and the next."""
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    mod = lagrgen.build(chain("foreign_unit"), out_dir=ours, quiet=True)
    other = lagrgen.build(chain("foreign_unit", stiffer=4), out_dir=theirs, quiet=True)
    foreign = other.parameter_jacobian(0.2, Y)
    call_in_fresh_process("foreign_unit", ours)         # our unit, made in another process
    python = lagrgen.build(chain("foreign_unit"), backend="python").parameter_jacobian(0.2, Y)
    assert np.abs(foreign - python).max() > 0.1
    unit = unit_dir(ours, "foreign_unit")
    for path in unit_dir(theirs, "foreign_unit").iterdir():
        if path.name != "foreign_unit_parameters_model.c":
            shutil.copy(path, unit / path.name)
    assert_allclose(call_in_fresh_process("foreign_unit", ours), python, rtol=1e-12, atol=1e-14)
    for path in unit_dir(theirs, "foreign_unit").iterdir():      # and in this process
        shutil.copy(path, unit / path.name)
    assert_allclose(mod.parameter_jacobian(0.2, Y), python, rtol=1e-12, atol=1e-14)
    assert f'"content_hash": "{mod.content_hash}"'.encode() in \
        (unit / f"foreign_unit_parameters{cache.EXT_SUFFIX}").read_bytes()


def test_a_read_only_cache_leaves_no_private_units_behind(tmp_path, monkeypatch):
    """Issue 37.14: a unit compiled into a private directory (its cache cannot be written) is
    imported and its directory removed."""
    import tempfile
    mod = lagrgen.build(chain("private_unit"), out_dir=tmp_path / "out", quiet=True)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))

    def no_lock(path):
        raise PermissionError(13, "Read-only file system", str(path))
    monkeypatch.setattr(cache, "locked", no_lock)
    python = lagrgen.build(chain("private_unit"), backend="python")
    assert_allclose(mod.parameter_jacobian(0.2, Y), python.parameter_jacobian(0.2, Y),
                    rtol=1e-12, atol=1e-14)
    assert not analysis_units(tmp_path / "out", "private_unit")
    assert not list(scratch.iterdir())
