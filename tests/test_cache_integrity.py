"""Issue 28.5: the cache serves only what it built. `load` imports a module only after checking
it against the digest and the content hash recorded when it was made (a truncated or foreign
module is refused, never imported); a marker holding binary junk counts as absent; an entry whose
module and digest were copied from another model is rebuilt by `build` and refused by `load`;
published standalone C is repaired like the module."""
import os
import subprocess
import sys
import textwrap

import pytest
import sympy as sp

import lagrgen
from lagrgen import BuildError, Model
from lagrgen.cache import CACHE_DIR, EXT_SUFFIX


def spring(k, name="integrity"):
    model = Model(name)
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.spring(k, x)
    return model


def replace_bytes(path, data):
    """Write `data` as a new file in place of `path` (a module this process has loaded stays
    mapped: its file is replaced, never written over)."""
    fresh = path.with_name(path.name + ".new")
    fresh.write_bytes(data)
    os.replace(fresh, path)


def entry_of(out, name="integrity"):
    (entry,) = (out / CACHE_DIR).glob(f"{name}-*/")
    return entry


LOAD = textwrap.dedent("""
    import sys, lagrgen
    try:
        mod = lagrgen.load(sys.argv[1], out_dir=sys.argv[2])
        print("loaded", mod.rhs(0.0, [1.0, 0.0])[1])
    except lagrgen.BuildError as error:
        print("refused:", error)
""")


def load_in_fresh_process(name, out):
    run = subprocess.run([sys.executable, "-c", LOAD, name, str(out)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, f"the process died ({run.returncode}): {run.stderr[-1500:]}"
    return run.stdout.strip()


def test_load_never_imports_a_module_it_cannot_verify(tmp_path):
    lagrgen.build(spring(9.0, "truncated"), out_dir=tmp_path)
    assert load_in_fresh_process("truncated", tmp_path) == "loaded -9.0"
    published = tmp_path / f"truncated{EXT_SUFFIX}"
    replace_bytes(published, published.read_bytes()[:4096])
    (tmp_path / CACHE_DIR / "truncated.current").unlink()
    out = load_in_fresh_process("truncated", tmp_path)
    assert out.startswith("refused:") and "cannot be verified before import" in out
    module = entry_of(tmp_path, "truncated") / f"truncated{EXT_SUFFIX}"
    replace_bytes(module, module.read_bytes()[:4096])        # the entry itself damaged
    (tmp_path / CACHE_DIR / "truncated.current").write_text(entry_of(
        tmp_path, "truncated").name.split("-")[-1] + "\n")
    out = load_in_fresh_process("truncated", tmp_path)
    assert out.startswith("refused:") and "is missing, damaged or holds another model" in out


def test_a_marker_of_binary_junk_counts_as_absent(tmp_path):
    model = spring(4.0, "junk_marker")
    lagrgen.build(model, out_dir=tmp_path)
    marker = tmp_path / CACHE_DIR / "junk_marker.current"
    key = marker.read_text().strip()
    marker.write_bytes(b"\xff\xfe\x00junk\x80")
    with pytest.raises(BuildError, match="no readable record of its build"):
        lagrgen.load("junk_marker", out_dir=tmp_path)
    again = lagrgen.build(model, out_dir=tmp_path)
    assert again.build_info["cache_hit"] and marker.read_text().strip() == key
    assert lagrgen.load("junk_marker", out_dir=tmp_path).rhs(0.0, [1.0, 0.0])[1] == -4.0
    marker.write_text("../../elsewhere\n")                  # not a key: never a path
    with pytest.raises(BuildError, match="no readable record"):
        lagrgen.load("junk_marker", out_dir=tmp_path)


def test_an_entry_copied_from_another_model_is_rebuilt_and_refused_by_load(tmp_path):
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    lagrgen.build(spring(9.0), out_dir=ours)
    other = lagrgen.build(spring(100.0), out_dir=theirs)
    assert other.rhs(0.0, [1.0, 0.0])[1] == -100.0
    for file_name in (f"integrity{EXT_SUFFIX}", "module.sha256"):
        replace_bytes(entry_of(ours) / file_name, (entry_of(theirs) / file_name).read_bytes())
    with pytest.raises(BuildError, match="holds another model's module"):
        lagrgen.load("integrity", out_dir=ours)
    rebuilt = subprocess.run(
        [sys.executable, "-c", "import sys, runpy, lagrgen, sympy as sp\n"
         "from lagrgen import Model\n"
         "m = Model('integrity'); x, = m.coordinates('x'); m.particle(1, sp.Matrix([x]))\n"
         "m.spring(9.0, x); mod = lagrgen.build(m, out_dir=sys.argv[1])\n"
         "print(mod.build_info['cache_hit'], mod.rhs(0.0, [1.0, 0.0])[1])", str(ours)],
        capture_output=True, text=True, timeout=300)
    assert rebuilt.stdout.split() == ["False", "-9.0"], rebuilt.stderr[-1500:]
    assert load_in_fresh_process("integrity", ours) == "loaded -9.0"


def test_published_standalone_c_is_repaired_like_the_module(tmp_path):
    model = spring(4.0, "published_c")
    lagrgen.build(model, out_dir=tmp_path)
    source, header = tmp_path / "published_c_model.c", tmp_path / "published_c_model.h"
    good = source.read_text(), header.read_text()
    source.write_text(good[0][:100])
    header.unlink()
    assert lagrgen.build(model, out_dir=tmp_path).build_info["cache_hit"]
    assert (source.read_text(), header.read_text()) == good


def test_a_killed_builds_work_directory_is_removed_by_the_next_build(tmp_path):
    """kill -9 during a compile left out_dir/__lagrgen__/.build-<module>-*/ for good; the next
    build of that model removes those untouched for an hour (a build under way is younger)."""
    cache = tmp_path / CACHE_DIR
    cache.mkdir()
    abandoned, running = cache / ".build-abandoned-x1y2", cache / ".build-abandoned-z3w4"
    for folder in (abandoned, running):
        folder.mkdir()
        (folder / "abandoned.c").write_text("/* half written */")
    two_hours_ago = abandoned.stat().st_mtime - 7200
    os.utime(abandoned, (two_hours_ago, two_hours_ago))
    mod = lagrgen.build(spring(2.0, "abandoned"), out_dir=tmp_path, quiet=True)
    assert mod.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-2.0)
    assert not abandoned.exists() and running.exists()
