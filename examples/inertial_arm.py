"""A three-joint spatial arm whose links' inertial parameters are the model's parameters.

Joint 1 turns about the vertical z axis, joints 2 and 3 about their links' y axes (a shoulder and
an elbow); link 2 is `a2` long along its x axis, and joint 2 sits `d1` above the base. Each link i
has the ten inertial parameters of `lagrgen.identify_inertial` as parameters: m_i, (mx_i, my_i, mz_i) = m_i·c_i (c_i
the centre of mass in the link frame) and the inertia about the link frame's origin
(Ixx_i, Ixy_i, Iyy_i, Ixz_i, Iyz_i, Izz_i), so the equations are linear in them:

    T_i = ½·m_i·|v_O|² + v_O·(ω × R·h_i) + ½·ωᵀ·I_O·ω  (h_i = m_i·c_i, I_O about the origin O)
    V_i = g·(m_i·z_O + (R·h_i)_z)

(the body is declared by its centre of mass c_i and the inertia about it,
I_c = I_O − m_i·(‖c_i‖²·1 − c_i·c_iᵀ), which is the same energy). Each joint is driven by its
input torque tau_<joint>. `make(name)` returns the model; `TRUTH` holds physically consistent
values of the 30 parameters (the defaults are 20 % off them, as a CAD model would be).
"""
import sympy as sp

from lagrgen import Model, rotation

FIELDS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")

#: The links' true inertial parameters: mass, centre of mass (link frame), inertia about the centre.
LINKS = {
    "link1": (4.0, (0.0, 0.02, 0.12), (0.030, 0.028, 0.012)),
    "link2": (3.0, (0.22, 0.0, 0.03), (0.008, 0.060, 0.058)),
    "link3": (1.5, (0.18, 0.01, 0.0), (0.002, 0.025, 0.024)),
}


def inertial_values(mass, centre, principal):
    """The ten parameters (FIELDS order) of a body of `mass`, centre `centre` and principal
    moments `principal` about its centre along the link axes: I_O = I_c + m(‖c‖²·1 − c·cᵀ)."""
    c = sp.Matrix(centre)
    I_O = sp.diag(*principal) + mass * (c.dot(c) * sp.eye(3) - c * c.T)
    h = mass * c
    return dict(zip(FIELDS, [float(v) for v in (mass, h[0], h[1], h[2], I_O[0, 0], I_O[0, 1],
                                                 I_O[1, 1], I_O[0, 2], I_O[1, 2], I_O[2, 2])]))


TRUTH = {f"{field}_{link}": value for link, body in LINKS.items()
         for field, value in inertial_values(*body).items()}


def make(name="inertial_arm", a2=0.45, d1=0.3, g=9.81):
    """The arm as a Model; parameters the 30 inertial ones, defaults 1.2·TRUTH."""
    model = Model(name)
    q1, q2, q3 = model.coordinates("q1 q2 q3")
    for joint, torque in zip((q1, q2, q3), model.inputs("tau_q1 tau_q2 tau_q3")):
        model.generalized_force(joint, torque)
    frames = [(sp.zeros(3, 1), rotation.z(q1))]
    frames.append((sp.Matrix([0, 0, d1]), rotation.z(q1) * rotation.y(q2)))
    frames.append((frames[1][0] + frames[1][1] * sp.Matrix([a2, 0, 0]),
                   rotation.z(q1) * rotation.y(q2) * rotation.y(q3)))
    for link, (origin, R) in zip(LINKS, frames):
        values = model.parameters(**{f"{f}_{link}": 1.2 * TRUTH[f"{f}_{link}"] for f in FIELDS})
        m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz = values
        h = sp.Matrix([mx, my, mz])
        I_O = sp.Matrix([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        I_c = I_O - (h.dot(h) * sp.eye(3) - h * h.T) / m
        model.rigid_body_3d(m, I_c, origin + R * h / m, R)
        model.potential_energy(g * (m * origin[2] + (R * h)[2]))
    return model


model = make()
