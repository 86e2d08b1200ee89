"""The cache's units: an entry holds its model's module and further units keyed by their own
digests, each stored atomically, checked against its recorded digest, and gone with its entry
(no compiler needed: a unit's "module" here is a file of bytes)."""
import pytest

import lagrgen
from lagrgen import cache


def write_module(unit, text):
    def make(work):
        cache.Unit(work, unit.module).module_file.write_text(text)
    return make


def test_an_entry_holds_units_keyed_by_their_own_digests(tmp_path):
    entry = cache.Entry(tmp_path, "m", cache.key("digest of m", ["-O2"]))
    a, b = entry.unit("pjac", "digest A"), entry.unit("pjac", "digest B")
    assert a.directory.parent == b.directory.parent == entry.directory and a != b
    assert a.module == "m_pjac" and a.module_file.name.startswith("m_pjac.")
    assert cache.key("digest of m", ["-O2"]) != cache.key("digest of m", ["-O3"])
    assert not cache.lookup(entry.main) and not cache.lookup(a)
    with cache.writing(entry):
        cache.store(entry.main, write_module(entry.main, "main"))
        cache.store(a, write_module(a, "unit a"))
    assert cache.lookup(entry.main) and cache.lookup(a) and not cache.lookup(b)
    assert a.module_file.read_text() == "unit a"
    a.module_file.write_text("damaged")
    assert not cache.lookup(a) and cache.lookup(entry.main)
    with cache.writing(entry):
        cache.store(entry.main, write_module(entry.main, "main again"))  # a new main: units go
    assert cache.lookup(entry.main) and not a.directory.exists()


def test_a_store_that_dies_halfway_leaves_nothing(tmp_path):
    entry = cache.Entry(tmp_path, "m", "k")

    def dies(work):
        cache.Unit(work, "m").module_file.write_text("half")
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt), cache.writing(entry):
        cache.store(entry.main, dies)
    assert not cache.lookup(entry.main)
    assert [p.name for p in entry.cache.iterdir()] == ["m.lock"]


def test_a_unit_label_must_make_a_module_name(tmp_path):
    entry = cache.Entry(tmp_path, "m", "k")
    with pytest.raises(lagrgen.ModelError, match="model name"):
        entry.unit("not a name", "d")
