"""Pinocchio (pip `pin`) as a peer: the benchmark's models built through its Python API, and the
conversion of states between its coordinates and lagrgen's.

Two models, each written the same way in both tools:

* `chain(n)`: the planar n-link pendulum of examples/nlink_pendulum.py (point masses m_i at the
  link ends, lengths l_i, gravity along −y). lagrgen's coordinates are absolute angles from the
  downward vertical; Pinocchio's revolute joints about z turn relative to the parent link, so its
  angles (and rates, accelerations) are differences of lagrgen's: q_rel = T·q_abs with T the
  bidiagonal difference matrix, and ∂q̈_abs/∂q_abs = T⁻¹·(∂q̈_rel/∂q_rel)·T.
* `humanoid()`: a branched 3-D model of 27 coordinates, the same joints in the same order in both
  (a fixed pelvis carrying a torso with a head and two arms, and two legs; hinges about body axes,
  rigid bodies with offset centres of mass), so their coordinates agree.

`pin` is not a lagrgen dependency: `available()` says whether it is installed.
"""
from dataclasses import dataclass

import numpy as np

G = 9.81


def available():
    """The installed pin version, or None."""
    try:
        from importlib.metadata import version
        return version("pin")
    except Exception:
        return None


# -- the chain -----------------------------------------------------------------------------------
def chain(n, masses=None, lengths=None, g=G):
    """The Pinocchio model of the planar n-link pendulum (relative angles, see the module)."""
    import pinocchio as pin
    masses = np.ones(n) if masses is None else np.asarray(masses, dtype=float)
    lengths = np.ones(n) if lengths is None else np.asarray(lengths, dtype=float)
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0.0, -g, 0.0]), np.zeros(3))
    parent = 0
    for i in range(n):
        offset = np.array([0.0, -lengths[i - 1], 0.0]) if i else np.zeros(3)
        joint = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(np.eye(3), offset), f"j{i}")
        model.appendBodyToJoint(joint, pin.Inertia(masses[i], np.array([0.0, -lengths[i], 0.0]),
                                                   np.zeros((3, 3))), pin.SE3.Identity())
        parent = joint
    return model


def differences(n):
    """T with q_rel = T·q_abs (T⁻¹ is the lower triangle of ones)."""
    return np.eye(n) - np.eye(n, k=-1)


@dataclass
class ChainState:
    """A lagrgen state y = [q, q̇] of the chain and the same state in Pinocchio's coordinates."""
    y: np.ndarray
    q: np.ndarray
    v: np.ndarray

    @classmethod
    def of(cls, y):
        n = len(y) // 2
        T = differences(n)
        return cls(np.asarray(y, dtype=float), T @ y[:n], T @ y[n:])


def chain_results(model, data, state):
    """(q̈, ∂q̈/∂q, ∂q̈/∂q̇, M) of Pinocchio's chain at `state`, in lagrgen's absolute
    coordinates (aba, computeABADerivatives and crba, converted)."""
    import pinocchio as pin
    n = len(state.q)
    T = differences(n)
    C = np.linalg.inv(T)
    tau = np.zeros(n)
    qdd = C @ pin.aba(model, data, state.q, state.v, tau)
    pin.computeABADerivatives(model, data, state.q, state.v, tau)
    dq, dv = C @ data.ddq_dq @ T, C @ data.ddq_dv @ T
    M = np.triu(pin.crba(model, data, state.q))
    M = M + np.triu(M, 1).T
    return qdd, dq, dv, T.T @ M @ T


# -- the humanoid ----------------------------------------------------------------------------------
#: (name, parent link or None, joints as axes ("px" slides, "rz" hinges, ...), where the first joint
#:  sits in the parent link's frame, mass, centre of mass in the link frame, principal inertia).
HUMANOID = (
    ("torso", None, ("rz", "ry", "rx"), (0.0, 0.0, 0.15), 14.0,
     (0.0, 0.0, 0.22), (0.35, 0.30, 0.12)),
    ("head", "torso", ("rz", "ry"), (0.0, 0.0, 0.5), 4.0, (0.0, 0.0, 0.11), (0.02, 0.02, 0.015)),
    ("upper_arm_l", "torso", ("ry", "rx", "rz"), (0.0, 0.2, 0.42), 2.0,
     (0.0, 0.0, -0.14), (0.015, 0.015, 0.004)),
    ("forearm_l", "upper_arm_l", ("ry",), (0.0, 0.0, -0.28), 1.2, (0.0, 0.0, -0.12),
     (0.008, 0.008, 0.002)),
    ("hand_l", "forearm_l", ("rx",), (0.0, 0.0, -0.25), 0.4, (0.0, 0.0, -0.06),
     (0.001, 0.001, 0.0005)),
    ("upper_arm_r", "torso", ("ry", "rx", "rz"), (0.0, -0.2, 0.42), 2.0,
     (0.0, 0.0, -0.14), (0.015, 0.015, 0.004)),
    ("forearm_r", "upper_arm_r", ("ry",), (0.0, 0.0, -0.28), 1.2, (0.0, 0.0, -0.12),
     (0.008, 0.008, 0.002)),
    ("hand_r", "forearm_r", ("rx",), (0.0, 0.0, -0.25), 0.4, (0.0, 0.0, -0.06),
     (0.001, 0.001, 0.0005)),
    ("thigh_l", None, ("rz", "rx", "ry"), (0.0, 0.1, -0.05), 7.0, (0.0, 0.0, -0.2),
     (0.1, 0.1, 0.02)),
    ("shank_l", "thigh_l", ("ry",), (0.0, 0.0, -0.42), 3.5, (0.0, 0.0, -0.2),
     (0.05, 0.05, 0.006)),
    ("foot_l", "shank_l", ("ry", "rx"), (0.0, 0.0, -0.42), 1.0, (0.05, 0.0, -0.04),
     (0.003, 0.004, 0.004)),
    ("thigh_r", None, ("rz", "rx", "ry"), (0.0, -0.1, -0.05), 7.0, (0.0, 0.0, -0.2),
     (0.1, 0.1, 0.02)),
    ("shank_r", "thigh_r", ("ry",), (0.0, 0.0, -0.42), 3.5, (0.0, 0.0, -0.2),
     (0.05, 0.05, 0.006)),
    ("foot_r", "shank_r", ("ry", "rx"), (0.0, 0.0, -0.42), 1.0, (0.05, 0.0, -0.04),
     (0.003, 0.004, 0.004)),
)


def humanoid_coordinates():
    """The coordinate names, in joint order: <link>_<axis>."""
    return [f"{name}_{axis}" for name, _, axes, *_ in HUMANOID for axis in axes]


def humanoid_pinocchio(g=G):
    """The humanoid in Pinocchio: one 1-DOF joint per coordinate (each link's inertia on the last
    joint of its group), identity placements within a group."""
    import pinocchio as pin
    joint_models = {"px": pin.JointModelPX, "py": pin.JointModelPY, "pz": pin.JointModelPZ,
                    "rx": pin.JointModelRX, "ry": pin.JointModelRY, "rz": pin.JointModelRZ}
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0.0, 0.0, -g]), np.zeros(3))
    last = {}
    for name, parent, axes, offset, mass, com, inertia in HUMANOID:
        joint = 0 if parent is None else last[parent]
        for k, axis in enumerate(axes):
            place = pin.SE3(np.eye(3), np.array(offset, dtype=float) if k == 0 else np.zeros(3))
            joint = model.addJoint(joint, joint_models[axis](), place, f"{name}_{axis}")
        model.appendBodyToJoint(joint, pin.Inertia(mass, np.array(com, dtype=float),
                                                   np.diag(inertia)), pin.SE3.Identity())
        last[name] = joint
    return model


def humanoid_lagrgen(name="humanoid", g=G):
    """The humanoid in lagrgen: rigid_body_3d per link, orientations as products of
    lagrgen.rotation factors, positions through the parents' frames, gravity along −z."""
    import sympy as sp
    import lagrgen
    from lagrgen import rotation
    model = lagrgen.Model(name)
    q = dict(zip(humanoid_coordinates(), model.coordinates(humanoid_coordinates())))
    gravity, = model.parameters(g=g)
    frames = {}
    for link, parent, axes, offset, mass, com, inertia in HUMANOID:
        R, origin = frames.get(parent, (None, sp.zeros(3, 1)))

        def fixed(v, R=R):
            return sp.Matrix(v) if R is None else R * sp.Matrix(v)
        origin = origin + fixed(offset)
        for axis in axes:
            angle = q[f"{link}_{axis}"]
            if axis[0] == "p":
                origin = origin + fixed([int(axis[1] == c) for c in "xyz"]) * angle
            else:
                step = getattr(rotation, axis[1])(angle)
                R = step if R is None else R * step
                fixed = (lambda v, R=R: R * sp.Matrix(v))
        frames[link] = (R, origin)
        centre = origin + R * sp.Matrix(com)
        model.rigid_body_3d(mass, list(inertia), centre, R)
        model.potential_energy(mass * gravity * centre[2])
    return model


# -- as a peer of benchmarks/nlink.py --------------------------------------------------------------
def build(n, work, deadline):
    """The chain as a `_built.Built`: rhs and Jacobian in lagrgen's absolute coordinates (aba and
    computeABADerivatives with the states converted, which adds two small products per call)."""
    import time

    import pinocchio as pin
    from _built import Built
    start = time.perf_counter()
    model = chain(n)
    data = model.createData()
    T = differences(n)
    C = np.linalg.inv(T)
    tau = np.zeros(n)

    def rhs(t, y):
        qdd = pin.aba(model, data, T @ y[:n], T @ y[n:], tau)
        return np.concatenate([y[n:], C @ qdd])

    def jac(t, y):
        pin.computeABADerivatives(model, data, T @ y[:n], T @ y[n:], tau)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = C @ data.ddq_dq @ T
        J[n:, n:] = C @ data.ddq_dv @ T
        return J

    seconds = time.perf_counter() - start
    return Built("Pinocchio", rhs, jac, build={"derive": seconds, "cold": seconds},
                 notes=["Pinocchio: the chain built through its Python API (relative angles); "
                        "rhs and Jacobian converted to lagrgen's absolute angles in the callable"])
