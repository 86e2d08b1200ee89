"""URDF files at the edges of the format (issue 45 items 11, 12): declarations refused by the
parser's own events wherever they stand and in any encoding, axes and inertias whose arithmetic
overflows."""
import numpy as np
import pytest

import lagrgen
from lagrgen.urdf import URDFError, parse

LINKS = ('<link name="a"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/>'
         '</inertial></link><link name="b"><inertial><origin xyz="0 0 -0.1"/><mass value="0.5"/>'
         '<inertia ixx="0.002" iyy="0.002" izz="0.001"/></inertial></link>')


def document(joint_axis="0 0 1", prolog="", doctype="", links=LINKS):
    return (f'<?xml version="1.0"?>{prolog}{doctype}<robot name="r">{links}'
            f'<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
            f'<axis xyz="{joint_axis}"/></joint></robot>')


ENTITY = '<!DOCTYPE robot [<!ENTITY big "0.5">]>'
PROLOG = "<!--" + "x" * 70_000 + "-->"


def test_a_clean_file_is_read_in_utf8_and_utf16():
    for text in (document(), document().encode("utf-8"),
                 document().replace('"1.0"?>', '"1.0" encoding="UTF-16"?>').encode("utf-16"),
                 document(prolog=PROLOG)):
        robot = parse(text)
        assert list(robot.links) == ["a", "b"] and robot.joints[0].name == "j"
        assert robot.links["b"].mass == 0.5


@pytest.mark.parametrize("case", ["after a long prolog", "in UTF-16", "in UTF-16 after a prolog",
                                  "a bare DOCTYPE"])
def test_a_doctype_is_refused_wherever_it_stands_and_in_any_encoding(case, tmp_path):
    if case == "a bare DOCTYPE":
        text = document(doctype="<!DOCTYPE robot>").encode()
    else:
        prolog = PROLOG if "prolog" in case else ""
        text = document(prolog=prolog, doctype=ENTITY, links=LINKS.replace('"0.5"', '"&big;"'))
        text = text.replace('"1.0"?>', '"1.0" encoding="UTF-16"?>').encode("utf-16") \
            if "UTF-16" in case else text.encode()
    path = tmp_path / "entity.urdf"
    path.write_bytes(text)
    with pytest.raises(URDFError, match="DOCTYPE or ENTITY"):
        lagrgen.from_urdf(path)


def test_namespaced_names_read_as_elementtree_reads_them():
    robot = parse(document().replace('<robot name="r">', '<robot name="r" xmlns:xacro='
                                     '"http://www.ros.org/wiki/xacro">'))
    assert robot.name == "r"
    with pytest.raises(URDFError, match="root element is <{urn:x}robot>"):
        parse(document().replace('<robot name="r">', '<robot name="r" xmlns="urn:x">'))


def test_an_axis_whose_squared_norm_overflows_keeps_its_direction(tmp_path):
    for huge, unit in (("0 1e200 1e200", "0 1 1"), ("1.7e308 0 -1.7e308", "1 0 -1"),
                       ("0 3e-9 3e-9", "0 1 1")):
        axis = parse(document(joint_axis=huge)).joints[0].axis
        assert np.allclose(axis, np.array(unit.split(), float) / np.sqrt(2), rtol=0, atol=1e-15)
    rhs = []
    for k, axis in enumerate(("0 1e200 1e200", "0 1 1")):
        path = tmp_path / f"axis{k}.urdf"
        path.write_text(document(joint_axis=axis))
        mod = lagrgen.build(lagrgen.from_urdf(path), backend="python")
        rhs.append(mod.rhs(0.0, [0.3, 0.2]))
    assert abs(rhs[0][1]) > 0.1 and np.allclose(rhs[0], rhs[1], rtol=1e-14, atol=0)
    for zero in ("0 0 0", "1e-13 0 -1e-13"):
        with pytest.raises(URDFError, match="axis> of joint 'j' is zero"):
            parse(document(joint_axis=zero))


@pytest.mark.parametrize("links", [
    LINKS.replace('"0.5"', '"1e10"').replace('xyz="0 0 -0.1"', 'xyz="1e150 0 0"'),
    LINKS.replace('"0.5"', '"1e300"').replace('xyz="0 0 -0.1"', 'xyz="0 1e5 0"')])
def test_an_inertia_that_overflows_is_an_error_naming_its_link(links, tmp_path):
    path = tmp_path / "huge.urdf"
    path.write_text(document(links=links))
    with pytest.raises(URDFError, match="inertia of link 'b' .* overflows a double"):
        lagrgen.from_urdf(path)
