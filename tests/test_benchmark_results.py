"""The committed benchmark results name no machine's paths and one row per robot file (issue 45
item 14)."""
import re
import sys
from pathlib import Path

from conftest import ROOT

RESULTS = ROOT / "benchmarks" / "results"
#: An absolute path of two or more folders (POSIX or Windows) inside a word boundary.
ABSOLUTE = re.compile(r"""(?:^|[\s"'(=:`])(/(?:[\w.-]+/){2,}|[A-Za-z]:\\)""")


def test_no_result_holds_an_absolute_path():
    for path in sorted(RESULTS.iterdir()):
        if path.suffix in (".md", ".json", ".txt", ".csv"):
            found = ABSOLUTE.search(path.read_text(encoding="utf-8"))
            assert found is None, f"{path.name} holds the absolute path {found.group(1)!r}"


def test_every_robot_row_names_its_own_file():
    robots_table = (RESULTS / "robots.md").read_text(encoding="utf-8").split("\n## ")[0]
    rows = [line.split("|")[1].strip() for line in robots_table.splitlines()
            if line.startswith("| ") and not line.startswith(("| robot ", "| :--"))]
    assert len(rows) > 60 and len(set(rows)) == len(rows)
    assert "anymal_b_simple_description/robots/anymal" in rows
    assert "anymal_c_simple_description/urdf/anymal" in rows


def test_rows_are_named_by_their_path_under_the_robots_folder(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import robots
    finally:
        sys.path.pop(0)
    root = tmp_path / "share" / "robots"
    files = [root / "anymal_b_simple_description/robots/anymal.urdf",
             root / "anymal_c_simple_description/urdf/anymal.urdf"]
    names = [robots.row_name(f, root) for f in files]
    assert names == ["anymal_b_simple_description/robots/anymal",
                     "anymal_c_simple_description/urdf/anymal"]
    message = f"{files[0]} defines no <link>"
    assert robots.without_root(message, root) == \
        "anymal_b_simple_description/robots/anymal.urdf defines no <link>"
