"""Robots from URDF files: the file read and checked (`read`), then made a `lagrgen.Model`
(`from_urdf`) whose bodies form a kinematic tree the recursive formulation runs in O(n).

A URDF file (the Unified Robot Description Format of ROS) lists links (rigid bodies: mass, centre of
mass and inertia about it, in the link frame) and joints (a parent link, a child link, the child
frame's placement in the parent's, an axis and a type). Read here with the standard library's
ElementTree: the format is a small XML vocabulary of which lagrgen needs links, joints, inertials,
limits, dynamics and mimic tags, and every value must be checked anyway (a positive definite
inertia, one root, no loop), which the URDF libraries of ROS (urdf_parser_py, yourdfpy, urchin) do
not do; they would add lxml or trimesh for geometry lagrgen does not use. Documents with a DOCTYPE
are refused (no entity is expanded).

A fixed joint merges its child into its parent (the inertias added about a common frame). Each
moving joint becomes one coordinate, named as the joint (characters a Python identifier does not
allow become "_", a leading digit gets a leading "_"), and one input `tau_<joint>`, the torque
(revolute, continuous) or force (prismatic) of its actuator.
"""
import keyword
import math
import re
import xml.etree.ElementTree as ET
from contextlib import contextmanager
from dataclasses import astuple, dataclass, field, replace
from pathlib import Path

import numpy as np

from .errors import ModelError
from .frames import quaternion_matrix, rodrigues
from .numbers import finite_number

#: Joint types that carry a coordinate, and the fixed joint that merges two links.
MOVING = ("revolute", "continuous", "prismatic")
SUPPORTED = MOVING + ("fixed",)
#: Tolerance of the checks of an inertia (positive semi-definite, triangle inequality): relative
#: to its largest principal moment, and absolute (kg·m²) for inertias that are round-off of zero.
INERTIA_TOL = 1e-9
INERTIA_ATOL = 1e-12


class URDFError(ModelError):
    """A URDF file cannot be read as a robot: the message names the element and what is wrong.

    `option` is the from_urdf option (name, value) the message suggests, spelled in it as
    `suggestion(name, value)` (the command line names its flag instead), or None."""

    def __init__(self, message, option=None):
        super().__init__(message)
        self.option = option


def suggestion(option, value):
    """How a message suggests the from_urdf option `option` = `value`."""
    return f"from_urdf(..., {option}={value!r})"


class URDFWarning(UserWarning):
    """Something of a URDF file lagrgen took as it is, though it is not physical (an inertia no
    mass distribution has, read with check_inertias=False)."""


@dataclass(frozen=True)
class Inertial:
    """A link's mass, centre of mass `com` (link frame) and inertia about the centre (3×3, link
    axes)."""
    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    @property
    def origin_inertia(self):
        """The inertia about the link frame's origin: I_c + m·(|c|²·1 − c·cᵀ) (3×3 array)."""
        c = np.array(self.com)
        return np.array(self.inertia) + self.mass * (c @ c * np.eye(3) - np.outer(c, c))


@dataclass(frozen=True)
class Limit:
    """A joint's limits; None where the file gives none."""
    lower: float = None
    upper: float = None
    velocity: float = None
    effort: float = None


@dataclass(frozen=True)
class Joint:
    """A joint of the file: the child frame is placed at `xyz`, rotated by `rotation` (3×3, from
    the roll–pitch–yaw angles) in the parent's frame, and moves about / along the unit `axis`
    (child frame) by its coordinate."""
    name: str
    kind: str
    parent: str
    child: str
    xyz: tuple
    rotation: tuple
    axis: tuple
    limit: Limit
    damping: float = 0.0
    friction: float = 0.0
    mimic: tuple = None      # (joint name, multiplier, offset)


@dataclass
class Robot:
    """A URDF robot: its links' inertials and its joints, checked to form one tree."""
    name: str
    links: dict                     # name -> Inertial
    joints: list                    # Joint, in file order
    root: str = None
    children: dict = field(default_factory=dict)    # link -> [joints whose parent it is]

    def parent_joint(self, link):
        """The joint whose child is `link` (None for the root)."""
        return next((j for j in self.joints if j.child == link), None)


# -- reading -----------------------------------------------------------------------------------------
def read(path, check_inertias=True):
    """The `Robot` of the URDF file at `path`, checked (URDFError naming the element otherwise;
    an inertia no mass distribution has is a URDFWarning instead with check_inertias=False)."""
    path = Path(path)
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise URDFError(f"cannot read the URDF file {str(path)!r}: {exc.strerror or exc}") from None
    return parse(text, str(path), check_inertias)


def parse(text, where="<string>", check_inertias=True):
    """The `Robot` of the URDF document `text` (bytes or str)."""
    root = _element_tree(text, where)
    if root.tag != "robot":
        raise URDFError(f"{where}: the root element is <{root.tag}>, a URDF file has <robot>")
    name = root.get("name") or Path(where).stem
    links = {}
    for element in root.findall("link"):
        link = _attribute(element, "name", "<link>")
        if link in links:
            raise URDFError(f"{where}: two <link> elements are named {link!r}")
        links[link] = _inertial(element, link, check_inertias)
    joints, seen = [], set()
    for element in root.findall("joint"):
        joint = _joint(element, links)
        if joint.name in seen:
            raise URDFError(f"{where}: two <joint> elements are named {joint.name!r}")
        seen.add(joint.name)
        joints.append(joint)
    if not links:
        raise URDFError(f"{where} defines no <link>: a robot needs at least one")
    robot = Robot(name, links, joints)
    _check_tree(robot, where)
    return robot


def _element_tree(text, where):
    """The document's root element, built from expat's events as ElementTree builds it; a DOCTYPE
    or entity declaration is refused at the parser's own event, wherever it stands and in whatever
    encoding, before anything in it is declared or expanded."""
    from xml.parsers import expat

    def refuse(*_):
        raise URDFError(f"{where}: the document declares a DOCTYPE or ENTITY; URDF files need "
                        "none, and lagrgen expands none (remove the declaration)")

    def qualified(name):
        return "{" + name if "}" in name else name

    builder = ET.TreeBuilder()
    parser = expat.ParserCreate(namespace_separator="}")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.StartElementHandler = lambda tag, attributes: builder.start(
        qualified(tag), {qualified(k): v for k, v in attributes.items()})
    parser.EndElementHandler = lambda tag: builder.end(qualified(tag))
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        raise URDFError(f"{where} is not well-formed XML: {exc}") from None
    return builder.close()


def _attribute(element, key, what):
    value = element.get(key)
    if value is None or not value.strip():
        raise URDFError(f"{what} has no {key!r} attribute")
    return value.strip()


def _number(text, what):
    return finite_number(text, what, URDFError)


def _vector(element, key, what, default=(0.0, 0.0, 0.0)):
    if element is None or element.get(key) is None:
        return tuple(default)
    parts = element.get(key).split()
    if len(parts) != 3:
        raise URDFError(f"{what} {key}={element.get(key)!r} must have 3 numbers")
    return tuple(_number(p, f"{what} {key}") for p in parts)


def rpy_matrix(rpy):
    """R = Rz(yaw)·Ry(pitch)·Rx(roll) of URDF's fixed-axis roll–pitch–yaw angles (3×3 tuple)."""
    r, p, y = rpy
    cr, sr, cp, sp_, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    return ((cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr),
            (sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr),
            (-sp_, cp * sr, cp * cr))


def _inertial(element, link, check_inertias=True):
    what = f"link {link!r}"
    inertial = element.find("inertial")
    if inertial is None:
        return Inertial()
    mass_element = inertial.find("mass")
    if mass_element is None:
        raise URDFError(f"the <inertial> of {what} has no <mass>: give <mass value=\"...\"/> "
                        "(a link without mass has no <inertial>; urdfdom refuses it too)")
    mass = _number(mass_element.get("value"), f"the mass of {what}")
    if mass < 0:
        raise URDFError(f"the mass of {what} is {mass:g}: a mass cannot be negative")
    origin = inertial.find("origin")
    com = _vector(origin, "xyz", f"the <inertial><origin> of {what}")
    R = np.array(rpy_matrix(_vector(origin, "rpy", f"the <inertial><origin> of {what}")))
    tensor = inertial.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    missing = [k for k in ("ixx", "iyy", "izz") if tensor is None or tensor.get(k) is None]
    if tensor is not None and missing:
        raise URDFError(f"the <inertia> of {what} gives no {', '.join(missing)}: give the three "
                        "moments (products of inertia left out are 0)")
    values = {k: _number(tensor.get(k, "0") if tensor is not None else "0",
                         f"the inertia {k} of {what}") for k in keys}
    I = np.array([[values["ixx"], values["ixy"], values["ixz"]],
                  [values["ixy"], values["iyy"], values["iyz"]],
                  [values["ixz"], values["iyz"], values["izz"]]])
    check_inertia(I, what, check_inertias)
    I = R @ I @ R.T
    return Inertial(mass, com, tuple(map(tuple, (I + I.T) / 2)))


def check_inertia(I, what, strict=True):
    """Raise URDFError (a URDFWarning unless `strict`) unless the 3×3 inertia I about the centre
    of mass is positive semi-definite and its principal moments satisfy the triangle inequality
    (each at most the sum of the other two), within INERTIA_TOL of the largest or INERTIA_ATOL."""
    import warnings
    moments = np.linalg.eigvalsh(I)
    tol = max(INERTIA_TOL * abs(moments).max(), INERTIA_ATOL)
    a, b, c = moments
    problem = None
    if a < -tol:
        problem = (f"is not positive semi-definite (principal moments "
                   f"{np.array2string(moments, precision=6)}): check the signs of ixy, ixz, iyz")
    elif c > a + b + tol:
        problem = (f"breaks the triangle inequality (principal moments "
                   f"{np.array2string(moments, precision=6)}: the largest exceeds the sum of the "
                   "other two, which no mass distribution gives)")
    if problem is None:
        return
    if strict:
        raise URDFError(f"the inertia of {what} {problem}; correct the file's <inertia>, or read "
                        f"it as it is with {suggestion('check_inertias', False)}",
                        ("check_inertias", False))
    warnings.warn(f"the inertia of {what} {problem}; taken as it is", URDFWarning, stacklevel=4)


def _joint(element, links):
    name = _attribute(element, "name", "<joint>")
    what = f"joint {name!r}"
    kind = _attribute(element, "type", what)
    if kind not in SUPPORTED:
        raise URDFError(f"{what} has type {kind!r}, which lagrgen does not support: use revolute, "
                        "continuous, prismatic or fixed (a floating base is "
                        "from_urdf(..., base='free') or base='floating')")
    ends = {}
    for end in ("parent", "child"):
        tag = element.find(end)
        if tag is None or not tag.get("link"):
            raise URDFError(f"{what} has no <{end} link=...>")
        if tag.get("link") not in links:
            raise URDFError(f"{what} names the {end} link {tag.get('link')!r}, which the file "
                            "does not define")
        ends[end] = tag.get("link")
    origin = element.find("origin")
    xyz = _vector(origin, "xyz", f"the <origin> of {what}")
    rotation = rpy_matrix(_vector(origin, "rpy", f"the <origin> of {what}"))
    axis = _vector(element.find("axis"), "xyz", f"the <axis> of {what}", (1.0, 0.0, 0.0))
    if kind in MOVING:
        axis = _unit_axis(axis, what)
    limit = _limit(element.find("limit"), what, kind)
    dynamics = element.find("dynamics")
    damping = _number(dynamics.get("damping", "0"), f"the damping of {what}") \
        if dynamics is not None else 0.0
    friction = _number(dynamics.get("friction", "0"), f"the friction of {what}") \
        if dynamics is not None else 0.0
    if damping < 0 or friction < 0:
        raise URDFError(f"the <dynamics> of {what} has a negative damping or friction")
    mimic = element.find("mimic")
    if mimic is not None and kind in MOVING:
        mimic = (_attribute(mimic, "joint", f"the <mimic> of {what}"),
                 _number(mimic.get("multiplier", "1"), f"the mimic multiplier of {what}"),
                 _number(mimic.get("offset", "0"), f"the mimic offset of {what}"))
    else:
        mimic = None
    return Joint(name, kind, ends["parent"], ends["child"], xyz, rotation, axis, limit, damping,
                 friction, mimic)


def _unit_axis(axis, what):
    """The unit vector along `axis`, scaled by its largest component first (its squared norm
    overflows from about 1e154 and underflows below 1e-154)."""
    largest = max(abs(a) for a in axis)
    if largest * math.sqrt(3) < 1e-12:
        raise URDFError(f"the <axis> of {what} is zero: give the direction it moves about or "
                        "along")
    scaled = [a / largest for a in axis]
    norm = math.hypot(*scaled)
    return tuple(a / norm for a in scaled)


def _limit(element, what, kind):
    if element is None:
        return Limit()
    values = {}
    for key in ("lower", "upper", "velocity", "effort"):
        text = element.get(key)
        values[key] = None if text is None else _number(text, f"the limit {key} of {what}")
    if kind == "continuous":
        values["lower"] = values["upper"] = None
    if values["lower"] is not None and values["upper"] is not None and \
            values["lower"] > values["upper"]:
        raise URDFError(f"the limits of {what} have lower {values['lower']:g} > upper "
                        f"{values['upper']:g}")
    for key in ("velocity", "effort"):
        if values[key] is not None and values[key] < 0:
            raise URDFError(f"the {key} limit of {what} is negative")
    return Limit(**values)


def _check_tree(robot, where):
    """One root link, every other link the child of exactly one joint, no loop."""
    parent_of = {}
    for joint in robot.joints:
        if joint.child in parent_of:
            raise URDFError(f"link {joint.child!r} is the child of two joints "
                            f"({parent_of[joint.child].name!r} and {joint.name!r}): a URDF robot "
                            "is a tree, so a closed loop cannot be described")
        if joint.child == joint.parent:
            raise URDFError(f"joint {joint.name!r} joins link {joint.child!r} to itself")
        parent_of[joint.child] = joint
    roots = [link for link in robot.links if link not in parent_of]
    if not roots:
        raise URDFError(f"{where}: every link is the child of a joint: the joints form a loop")
    if len(roots) > 1:
        raise URDFError(f"{where} has {len(roots)} root links ({', '.join(map(repr, roots[:5]))}"
                        f"{', ...' if len(roots) > 5 else ''}): a robot has one link that is no "
                        "joint's child; join the others with fixed joints")
    robot.root = roots[0]
    robot.children = {link: [] for link in robot.links}
    for joint in robot.joints:
        robot.children[joint.parent].append(joint)
    reached, stack = set(), [robot.root]
    while stack:
        link = stack.pop()
        reached.add(link)
        stack.extend(j.child for j in robot.children[link])
    lost = [link for link in robot.links if link not in reached]
    if lost:
        joint = parent_of[lost[0]]
        raise URDFError(f"the joints form a loop through link {lost[0]!r} (joint "
                        f"{joint.name!r}): it cannot be reached from the root {robot.root!r}")


def _check_mimics(robot):
    moving = {j.name: j for j in robot.joints if j.kind in MOVING}
    for joint in robot.joints:
        if joint.mimic is None:
            continue
        target = moving.get(joint.mimic[0])
        if target is None:
            raise URDFError(f"joint {joint.name!r} mimics {joint.mimic[0]!r}, which is not a "
                            "moving joint of the file: correct its <mimic>, or read every joint "
                            f"as independent with {suggestion('mimic', False)}", ("mimic", False))
        if target.mimic is not None:
            raise URDFError(f"joint {joint.name!r} mimics {target.name!r}, which itself mimics "
                            f"{target.mimic[0]!r}: mimic the joint that moves, or read every "
                            f"joint as independent with {suggestion('mimic', False)}",
                            ("mimic", False))


def identifier(name):
    """The Python identifier a URDF name becomes: other characters as "_", a leading digit with
    a leading "_", a keyword with a trailing "_"."""
    out = re.sub(r"\W", "_", name, flags=re.ASCII)
    if not out or out[0].isdigit():
        out = "_" + out
    return out + "_" if keyword.iskeyword(out) else out


# -- the model -------------------------------------------------------------------------------------
#: The floating base's coordinates (API order) and, in tree order, the joints that realise
#: R = Rz(yaw)·Ry(pitch)·Rx(roll) after the translation: (name, kind, axis).
FLOATING_BASE = (("base_x", "prismatic", (1.0, 0.0, 0.0)), ("base_y", "prismatic", (0.0, 1.0, 0.0)),
                 ("base_z", "prismatic", (0.0, 0.0, 1.0)), ("base_yaw", "revolute", (0.0, 0.0, 1.0)),
                 ("base_pitch", "revolute", (0.0, 1.0, 0.0)),
                 ("base_roll", "revolute", (1.0, 0.0, 0.0)))
FLOATING_ORDER = ("base_x", "base_y", "base_z", "base_roll", "base_pitch", "base_yaw")
#: The free base's coordinates: its frame's origin and a quaternion (Pinocchio's order, scalar
#: last) whose direction is its orientation (`lagrgen.frames`); its inputs: a force and a moment
#: on the base frame's origin, in fixed axes.
FREE_BASE = ("base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw")
FREE_INPUTS = ("force_base_x", "force_base_y", "force_base_z",
               "torque_base_x", "torque_base_y", "torque_base_z")
#: The roll–pitch–yaw angles of the free base, outputs for people.
FREE_OUTPUTS = ("base_roll", "base_pitch", "base_yaw")
#: The ten inertial parameters of a body, in Pinocchio's order, and their units.
INERTIAL_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
INERTIAL_UNITS = ("kg",) + ("kg*m",) * 3 + ("kg*m^2",) * 6


@dataclass
class Part:
    """A moving joint of the robot as the model sees it: its joint (None for a floating base's
    own), parent part (−1: the fixed base), placement (R, o) in the parent's frame, kind, axis,
    the body it carries (link name, 10 parameters about its origin) and its coordinate name."""
    joint: object
    name: str
    parent: int
    rotation: np.ndarray
    offset: np.ndarray
    kind: str
    axis: tuple
    link: str = ""
    body: np.ndarray = field(default_factory=lambda: np.zeros(10))


def parts(robot, base="fixed", frozen=None, frames=None):
    """The robot's moving joints as `Part`s, parents first (depth first from the root link, in
    file order), with the links that fixed joints join merged into the body before them; the
    joints of `frozen` ({name: position}) are fixed at that position. `frames`, a dict, receives
    {link: (the Part whose frame it is fixed in, or None for the fixed frame, R, p)}."""
    frozen = frozen or {}
    frames = {} if frames is None else frames
    out = []
    if base == "floating":
        for name, kind, axis in FLOATING_BASE:
            out.append(Part(None, name, len(out) - 1, np.eye(3), np.zeros(3),
                            kind, axis))
    elif base == "free":
        out.append(Part(None, "base", -1, np.eye(3), np.zeros(3), "free", ()))
    owner0 = len(out) - 1
    stack = [(robot.root, owner0, np.eye(3), np.zeros(3))]
    if owner0 >= 0:
        out[owner0].link = robot.root
    while stack:
        link, owner, R, p = stack.pop()
        frames[link] = (out[owner] if owner >= 0 else None, R, p)
        if owner >= 0:
            out[owner].body = _merged(out[owner].body, robot.links[link], R, p, link)
        pending = []
        for joint in robot.children[link]:
            Rj, pj = R @ np.array(joint.rotation), p + R @ np.array(joint.xyz)
            if joint.kind == "fixed" or joint.name in frozen:
                if joint.kind in ("revolute", "continuous"):
                    Rj = Rj @ rodrigues(joint.axis, [frozen[joint.name]])[0]
                elif joint.kind == "prismatic":
                    pj = pj + Rj @ np.array(joint.axis) * frozen[joint.name]
                pending.append((joint.child, owner, Rj, pj))
                continue
            out.append(Part(joint, identifier(joint.name), owner, Rj, pj,
                            "prismatic" if joint.kind == "prismatic" else "revolute",
                            joint.axis, joint.child))
            pending.append((joint.child, len(out) - 1, np.eye(3), np.zeros(3)))
        stack.extend(reversed(pending))
    return _parents_first(out)


def _parents_first(out):
    """The parts renumbered depth first (each subtree contiguous, siblings in file order)."""
    children = {i: [] for i in range(-1, len(out))}
    for i, part in enumerate(out):
        children[part.parent].append(i)
    order = []

    def visit(i):
        order.append(i)
        for c in sorted(children[i]):
            visit(c)
    for root in sorted(children[-1]):
        visit(root)
    index = {old: new for new, old in enumerate(order)}
    result = []
    for old in order:
        part = out[old]
        part.parent = index[part.parent] if part.parent >= 0 else -1
        result.append(part)
    return result


def _merged(body, inertial, R, p, link):
    """`body` with the link placed at (R, p) added; URDFError naming the link when the sum
    overflows a double (a mass times its squared distance from the joint's frame beyond 1.8e308)."""
    with np.errstate(over="ignore", invalid="ignore"):
        total = body + _placed(inertial, R, p)
    if not np.isfinite(total).all():
        with np.errstate(over="ignore"):
            distance = np.linalg.norm(p + R @ np.array(inertial.com))
        raise URDFError(f"the inertia of link {link!r} about its joint's frame overflows a double "
                        f"(mass {inertial.mass:g} kg with its centre {distance:g} m from the "
                        "frame): give the file's masses in kg and lengths in m")
    return total


def _placed(inertial, R, p):
    """A link's 10 parameters about the origin of the frame it is placed in at (R, p)."""
    m = inertial.mass
    c = p + R @ np.array(inertial.com)
    I_O = R @ np.array(inertial.inertia) @ R.T + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([m, *(m * c), I_O[0, 0], I_O[0, 1], I_O[1, 1], I_O[0, 2], I_O[1, 2],
                     I_O[2, 2]])


def massless_coordinates(found, followers):
    """The parts (coordinates) whose joints' subtrees carry no mass or inertia (their rows of M
    would be zero); a joint that others follow (`followers`: {part name: (joint, multiplier,
    offset)}) counts what they carry."""
    carried = [np.abs(part.body).max() for part in found]
    for i in reversed(range(len(found))):
        if found[i].parent >= 0:
            carried[found[i].parent] = max(carried[found[i].parent], carried[i])
    total = {}
    for part, amount in zip(found, carried):
        key = identifier(followers[part.name][0]) if part.name in followers else part.name
        total[key] = max(total.get(key, 0.0), amount)
    return [part for part in found if part.name not in followers and total[part.name] == 0.0]


def _check_base_carries(robot, found):
    """URDFError when a floating base's root link (with the links fixed to it) has no mass or
    inertia and one moving joint below it: the base turning (or sliding) about that joint's axis
    then moves the same bodies as the joint, and M is singular along the difference."""
    base = next(k for k, part in enumerate(found) if part.link == robot.root)
    children = [part for part in found if part.parent == base]
    if np.abs(found[base].body).max() > 0.0 or len(children) != 1:
        return
    joint = children[0].joint
    raise URDFError(f"the root link {robot.root!r} of {robot.name!r} has no mass or inertia and "
                    f"one moving joint below it ({joint.name!r}): a floating base turning about "
                    "that joint's axis moves the same bodies as the joint does, so the motion is "
                    f"not determined (a singular mass matrix): give {robot.root!r} an <inertial>, "
                    f"make the joint fixed, or float the robot from {children[0].link!r} (a file "
                    "whose root is that link)")


def _frozen_massless(robot, found, followers, massless):
    """{joint name: position} of the joints to fix: none, or (massless="fixed") those of the
    massless coordinates at 0 and the joints that follow them at their offset; URDFError naming
    the first massless coordinate when massless="error"."""
    empty = massless_coordinates(found, followers)
    if not empty:
        return {}
    part = empty[0]
    what = f"joint {part.joint.name!r}" if part.joint else f"the floating base ({part.name})"
    if massless == "error" or part.joint is None:
        raise URDFError(f"{what} of {robot.name!r} moves no mass or inertia (every link below "
                        "it, and below the joints that follow it, is massless), so the motion it "
                        "allows has no inertia: give a link below it an <inertial>, make the "
                        f"joint fixed, or read the file with {suggestion('massless', 'fixed')}",
                        ("massless", "fixed"))
    import warnings
    names = {p.joint.name for p in empty if p.joint is not None}
    frozen = {name: 0.0 for name in names}
    for p in found:
        if p.name in followers and followers[p.name][0] in names:
            frozen[p.joint.name] = followers[p.name][2]
    warnings.warn(f"{robot.name!r}: {len(names)} joint(s) move no mass or inertia and are held "
                  f"fixed at 0 ({', '.join(sorted(names)[:4])}{', ...' if len(names) > 4 else ''})",
                  URDFWarning, stacklevel=3)
    return frozen


def from_urdf(path, name=None, base="fixed", gravity=(0.0, 0.0, -9.81), joint_dynamics=True,
              parameters=None, mimic=True, check_inertias=True, massless="error", limits=True,
              limit_restitution=0.0):
    """A `lagrgen.Model` of the robot in the URDF file `path`.

    Parameters
    ----------
    path : str or pathlib.Path
        The URDF file.
    name : str, optional
        The model's name (default: the robot's, made an identifier).
    base : "fixed", "floating" or "free"
        "floating": the root link moves freely, with the coordinates base_x, base_y, base_z,
        base_roll, base_pitch, base_yaw first (orientation Rz(yaw)·Ry(pitch)·Rx(roll), singular
        at pitch ±π/2). "free": the root link moves freely without singularity, with the
        coordinates base_x, base_y, base_z, base_qx, base_qy, base_qz, base_qw first (its
        origin and a quaternion, see the robots guide), the inputs force_base_x, ...,
        torque_base_z (a force and a moment on its origin, fixed axes) and the outputs
        base_roll, base_pitch, base_yaw; its initial state is upright.
    gravity : 3 numbers or expressions
        The uniform gravity in the fixed frame, m/s².
    joint_dynamics : bool
        True: each joint's <dynamics damping friction> as viscous damping and Coulomb friction
        (with sticking, `Model.friction`); False: rigid-body dynamics only (as Pinocchio's aba).
    parameters : None or "inertial"
        "inertial": each moving body's mass, mass times centre and inertia about its frame's
        origin are parameters (names m_<link>, mx_<link>, ..., Izz_<link>) with the file's values
        as defaults; None: the numbers folded into the generated code.
    mimic : bool
        True: a <mimic> joint follows its joint (q = multiplier·q_joint + offset) and has no
        coordinate of its own; False: it is an independent joint (as Pinocchio reads it).
    check_inertias : bool
        True: an inertia that is not positive semi-definite or breaks the triangle inequality
        (no mass distribution has it) is a URDFError; False: a URDFWarning, and it is taken as it
        is (as ROS and Pinocchio do).
    massless : "error" or "fixed"
        A joint that moves no mass or inertia (every link below it massless: its row of M would
        be zero): a URDFError, or ("fixed") the joint held fixed at 0 with a URDFWarning.
    limits : bool
        True: the joints' position limits act in simulations as unilateral contacts, stops
        <joint>_lower and <joint>_upper (`Model.limit(..., enforce=True)`); False: declared
        (`model.limits`, collocation bounds), not enforced.
    limit_restitution : float in [0, 1]
        The stops' coefficient of restitution (0: inelastic).

    Returns
    -------
    lagrgen.Model
        One coordinate per moving joint (revolute, continuous: an angle in rad; prismatic: a
        displacement in m), named as the joint, and one input `tau_<joint>` each; every
        joint's limits in `model.limits` (None where the file gives none). Its initial state
        is at rest with every joint at 0, or, where enforced limits exclude 0, at the limit
        nearest 0.
    """
    import sympy as sp

    from .model import Model
    from .records import Articulation, Segment
    if base not in ("fixed", "floating", "free"):
        raise ModelError(f"base must be 'fixed', 'floating' or 'free', got {base!r}")
    if parameters not in (None, "inertial"):
        raise ModelError(f"parameters must be None or 'inertial', got {parameters!r}")
    try:
        gravity = [sp.sympify(g) for g in gravity]
    except (TypeError, sp.SympifyError):
        raise ModelError(f"gravity must be 3 numbers (m/s² in the fixed frame), got "
                         f"{gravity!r}") from None
    if len(gravity) != 3:
        raise ModelError(f"gravity must have 3 components, got {len(gravity)}")
    if any(g.has(sp.nan, sp.oo, -sp.oo, sp.zoo) for g in gravity):
        raise ModelError(f"gravity must be finite (m/s² in the fixed frame), got "
                         f"{tuple(gravity)}")
    robot = read(path, check_inertias)
    if mimic:
        _check_mimics(robot)
    if massless not in ("error", "fixed"):
        raise ModelError(f"massless must be 'error' or 'fixed', got {massless!r}")
    frames = {}
    found = parts(robot, base, frames=frames)
    names = [p.name for p in found]
    clash = {n for n in names if names.count(n) > 1}
    if clash:
        raise URDFError(f"joints of {robot.name!r} have names that become the same coordinate "
                        f"{sorted(clash)[0]!r}: rename one of them")
    followers = {p.name: p.joint.mimic for p in found
                 if mimic and p.joint is not None and p.joint.mimic is not None}
    if base == "free" and followers:
        follower, (target, _, _) = next(iter(followers.items()))
        raise URDFError(f"joint {follower!r} of {robot.name!r} mimics {target!r}: the "
                        "recursion of a free base takes no mimic joints yet; read the file with "
                        f"{suggestion('mimic', False)} (the joints independent, as Pinocchio "
                        "reads them)", ("mimic", False))
    frozen = _frozen_massless(robot, found, followers, massless)
    if frozen:
        found = parts(robot, base, frozen, frames)
        followers = {name: f for name, f in followers.items()
                     if any(p.name == name for p in found)}
    if base in ("floating", "free"):
        _check_base_carries(robot, found)
    coordinate_parts = [p for p in found if p.name not in followers]
    if not coordinate_parts:
        raise URDFError(f"robot {robot.name!r} has no moving joint (every joint is fixed), so a "
                        "fixed base leaves it nothing to move: let it move freely with "
                        f"{suggestion('base', 'floating')}", ("base", "floating"))
    if base == "floating":
        by_name = {p.name: p for p in coordinate_parts}
        coordinate_parts = [by_name[n] for n in FLOATING_ORDER] + coordinate_parts[6:]
    joint_parts = coordinate_parts[1:] if base == "free" else coordinate_parts
    model = Model(name if name is not None else identifier(robot.name))
    units = " ".join("m" if p.kind == "prismatic" else "rad" for p in joint_parts)
    names = [p.name for p in joint_parts]
    if base == "free":
        units, names = "m m m 1 1 1 1 " + units, list(FREE_BASE) + names
    with _names_of(robot):
        q = dict(zip(names, model.coordinates(names, units=units)))
        inertias = _inertias(model, found, parameters)
        tau = model.inputs([f"tau_{p.name}" for p in joint_parts],
                           units=" ".join("N" if p.kind == "prismatic" else "N*m"
                                          for p in joint_parts)) if joint_parts else ()
    motion = {}
    for p in found:
        if p.name in followers:
            target, multiplier, offset = followers[p.name]
            motion[p.name] = sp.Float(multiplier) * q[identifier(target)] + sp.Float(offset)
        elif p.kind == "free":
            motion[p.name] = sp.ImmutableMatrix([q[c] for c in FREE_BASE])
        else:
            motion[p.name] = q[p.name]
    segments = tuple(Segment(p.name, p.link, p.parent, p.kind, tuple(float(a) for a in p.axis),
                             _exact(_clean(p.rotation)), _exact(_clean(p.offset).reshape(3, 1)),
                             motion[p.name], inertias[k],
                             _radial_inertia(p.body) if p.kind == "free" else 0.0)
                     for k, p in enumerate(found))
    record = Articulation(segments, sp.ImmutableMatrix(gravity), _link_frames(frames, found))
    model._add(record)
    model._drawables.append(("robot", (record,)))
    for p, u in zip(joint_parts, tau):
        model.generalized_force(q[p.name], u)
    if base == "free":
        _free_base(model, [q[c] for c in FREE_BASE])
    if joint_dynamics:
        _joint_dynamics(model, found, motion)
    model.urdf = robot
    start = {"base_qw": 1.0} if base == "free" else {}
    for p in coordinate_parts:
        limit = p.joint.limit if p.joint is not None else None
        limit = _narrowed_by_followers(p, limit, found, followers)
        if limit is not None and any(v is not None for v in astuple(limit)):
            model.limit(p.name, *astuple(limit), enforce=bool(limits),
                        restitution=limit_restitution)
            if limits:
                start.update(_within(p.name, limit.lower, limit.upper))
        elif p.joint is not None:
            model.limit(p.name)              # listed in model.limits, None where absent
    if start:
        model.initial_state(q=start)
    return model


def _narrowed_by_followers(part, limit, found, followers):
    """A leader joint's limits narrowed by those of the joints that follow it (q = m·q_leader + o
    within [lower, upper] puts q_leader within [(lower − o)/m, (upper − o)/m], and |q̇| ≤ v puts
    |q̇_leader| ≤ v/|m|); `limit` as it is for a joint that none follows."""
    for follower in found:
        target, multiplier, offset = followers.get(follower.name, (None, 0.0, 0.0))
        if target is None or identifier(target) != part.name or not multiplier:
            continue
        own = follower.joint.limit
        if own is None:
            continue
        limit = limit or Limit()
        lower, upper, velocity = limit.lower, limit.upper, limit.velocity
        if own.lower is not None and own.upper is not None:
            ends = sorted(((own.lower - offset) / multiplier, (own.upper - offset) / multiplier))
            lower = ends[0] if lower is None else max(lower, ends[0])
            upper = ends[1] if upper is None else min(upper, ends[1])
        if own.velocity is not None:
            implied = own.velocity / abs(multiplier)
            velocity = implied if velocity is None else min(velocity, implied)
        limit = replace(limit, lower=lower, upper=upper, velocity=velocity)
    return limit


@contextmanager
def _names_of(robot):
    """The model's names made from the file's joints and links: a name the model refuses (one
    taken, or reserved) is a URDFError of the file."""
    try:
        yield
    except URDFError:
        raise
    except ModelError as exc:
        raise URDFError(f"{robot.name!r}: {exc}") from None


def _within(name, lower, upper):
    """{name: the bound nearest 0} for a joint whose enforced limits exclude 0, else {}."""
    if lower is not None and lower > 0:
        return {name: float(lower)}
    if upper is not None and upper < 0:
        return {name: float(upper)}
    return {}


def _link_frames(frames, found):
    """The `LinkFrame` of every link, in the order of the file's links met depth first."""
    from .records import LinkFrame
    index = {id(part): k for k, part in enumerate(found)}
    return tuple(LinkFrame(link, -1 if owner is None else index[id(owner)], _exact(_clean(R)),
                           _exact(_clean(p).reshape(3, 1)))
                 for link, (owner, R, p) in frames.items())


def _radial_inertia(body):
    """The inertia J of a free base's quaternion length (`records.Segment.radial`): 4/3 of the
    trace of the base body's inertia about its origin (so that M's quaternion block has the
    scale of its rotation's, 4·I), 1 kg·m² for a base without inertia."""
    trace = float(body[4] + body[6] + body[9])
    return 4.0 * trace / 3.0 if trace > 0 else 1.0


def _free_base(model, coordinates):
    """A free base's inputs (a force and a moment on its origin, fixed axes: Q_p = f,
    Q_ζ = Gᵀ·n with ω = G·ζ̇), its roll–pitch–yaw outputs and its initial state, upright at rest."""
    import sympy as sp
    p, z = coordinates[:3], sp.Matrix(coordinates[3:])
    inputs = model.inputs(list(FREE_INPUTS), units="N N N N*m N*m N*m")
    force, moment = sp.Matrix(inputs[:3]), sp.Matrix(inputs[3:])
    x, y, zc, w = z
    G = 2 * sp.Matrix([[w, -zc, y, -x], [zc, w, -x, -y], [-y, x, w, -zc]]) / (z.T * z)[0]
    for coordinate, value in zip(p, force):
        model.generalized_force(coordinate, value)
    for coordinate, column in zip(z, (G.T * moment)):
        model.generalized_force(coordinate, column)
    for name, angle in zip(FREE_OUTPUTS, _rpy_of_matrix(sp.Matrix(
            quaternion_matrix(list(z), homogeneous=True)))):
        model.output(name, angle, units="rad")


def _rpy_of_matrix(R):
    """URDF's (roll, pitch, yaw) of R = Rz(yaw)·Ry(pitch)·Rx(roll) given times any positive
    number (SymPy): atan2 forms, pitch in [−π/2, π/2]; the yaw from R·Rx(−roll) = Rz(yaw)·Ry(pitch),
    whose second column is (−sin yaw, cos yaw, 0), so that the three angles give R back at the
    gimbal lock too, where the roll is whatever round-off makes it (the yaw read off R's first
    column there was round-off of its own: R(rpy) was 1.96 off R at pitch π/2)."""
    import sympy as sp
    roll = sp.atan2(R[2, 1], R[2, 2])
    c, s = sp.cos(roll, evaluate=False), sp.sin(roll, evaluate=False)
    return (roll, sp.atan2(-R[2, 0], sp.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2)),
            sp.atan2(s * R[0, 2] - c * R[0, 1], c * R[1, 1] - s * R[1, 2]))


def _clean(array):
    """Floats with the round-off of exact angles (|x| < 1e-15 beside ±1) set to 0: a placement
    rotated by exactly π/2 folds to zeros and ones in the generated code."""
    a = np.array(array, dtype=float)
    a[np.abs(a) < 1e-15] = 0.0
    return a


def _exact(array):
    """A SymPy matrix of the floats of `array`, integers where they are (0 and ±1 fold)."""
    import sympy as sp
    return sp.ImmutableMatrix([[sp.Integer(int(x)) if float(x).is_integer() else sp.Float(x)
                                for x in row] for row in np.atleast_2d(array)])


def _inertias(model, found, parameters):
    """Each part's 10 inertial parameters: numbers, or with parameters="inertial" the parameters
    m_<link>, ... (defaults the file's values) of every part that carries a link."""
    import sympy as sp
    out = []
    for p in found:
        values = _clean(p.body)
        if parameters != "inertial" or not p.link:
            out.append(tuple(_exact(values.reshape(1, -1))))
            continue
        link = identifier(p.link)
        symbols = model.parameters(**{f"{n}_{link}": (float(v), unit) for n, v, unit in
                                      zip(INERTIAL_NAMES, values, INERTIAL_UNITS)})
        out.append(tuple(symbols))
    return out


def _joint_dynamics(model, found, motion):
    """Viscous damping (a damper on the joint's motion) and Coulomb friction with sticking
    (`Model.friction` on its rate, normal force 1, coefficient the friction torque or force)."""
    for p in found:
        if p.joint is None:
            continue
        if p.joint.damping > 0:
            model.damper(p.joint.damping, motion[p.name])
        if p.joint.friction > 0:
            model.friction(f"friction_{p.name}", motion[p.name].diff(model.t), 1,
                           mu=p.joint.friction)


def tree_text(robot, base="fixed"):
    """The robot's kinematic tree as text: one line per link, below the joint that carries it
    (type, axis, limits), its mass, and which links fixed joints merge into one body."""
    moving = sum(1 for j in robot.joints if j.kind in MOVING)
    mass = sum(link.mass for link in robot.links.values())
    extra = {"floating": 6, "free": 7}.get(base, 0)
    lines = [f"robot {robot.name}: {moving + extra} coordinates, "
             f"{len(robot.links)} links, {len(robot.joints)} joints, {mass:.4g} kg "
             f"({base if base in ('floating', 'free') else 'fixed'} base)"]

    def joint_text(joint):
        if joint.kind == "fixed":
            return f"{joint.name} (fixed: merged into the body above)"
        axis = " ".join(f"{a:g}" for a in joint.axis)
        unit = "m" if joint.kind == "prismatic" else "rad"
        limit = joint.limit
        span = "" if limit.lower is None else f" [{limit.lower:g}, {limit.upper:g}] {unit}"
        follows = f", mimics {joint.mimic[0]}" if joint.mimic else ""
        return f"{joint.name} ({joint.kind} along {axis}{span}{follows})" \
            if joint.kind == "prismatic" else \
            f"{joint.name} ({joint.kind} about {axis}{span}{follows})"

    def visit(link, prefix, last, joint):
        mass_text = f"{robot.links[link].mass:.4g} kg"
        head = link if joint is None else f"{joint_text(joint)} -> {link}"
        marker = "" if joint is None else ("`-- " if last else "|-- ")
        lines.append(f"{prefix}{marker}{head}, {mass_text}")
        children = robot.children[link]
        for i, child in enumerate(children):
            visit(child.child, prefix + ("" if joint is None else ("    " if last else "|   ")),
                  i == len(children) - 1, child)
    if base == "floating":
        lines.append("floating base: base_x, base_y, base_z, base_roll, base_pitch, base_yaw "
                     "(orientation Rz(yaw)·Ry(pitch)·Rx(roll))")
    elif base == "free":
        lines.append("free base: base_x, base_y, base_z, base_qx, base_qy, base_qz, base_qw "
                     "(origin and orientation quaternion, no singularity)")
    visit(robot.root, "", True, None)
    return "\n".join(lines)
