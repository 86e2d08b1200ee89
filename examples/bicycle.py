"""The Whipple bicycle of the benchmark of Meijaard, Papadopoulos, Ruina and Schwab (2007),
"Linearized dynamics equations for the balance and steer of a bicycle: a benchmark and review",
Proc. R. Soc. A 463, 1955–1982, built with SymPy's KanesMethod (the model of SymPy's own test
`test_kane3.py`, itself ported from Autolev, with readable names).

Four rigid bodies (rear frame with rider, front fork with handlebar, two knife-edge wheels) roll
without slipping on level ground. Coordinates: yaw, roll, steer, and the frame's pitch, which the
front wheel's contact with the ground makes dependent (a holonomic constraint). Speeds: the rates
of those four and the two wheels' spins, which have no coordinate (their angles are ignorable):
`lagrgen.from_sympy` gives them the ignorable coordinates int_rear_spin and int_front_spin. The
front wheel's contact point does not slip (two velocity constraints) and does not leave the
ground (the time derivative of the holonomic one).

Upright at forward speed v the benchmark's linear model is stable between the weave speed
4.292 m/s and the capsize speed 6.024 m/s:

    python -m lagrgen stability examples/bicycle.py --sweep v=0:10:101 \\
        --qd0 "int_rear_spin=v/rr;int_front_spin=v/rf" --plot bicycle_root_locus.png
"""
import sympy as sp
import sympy.physics.mechanics as me

import lagrgen


def whipple_bicycle():
    """The KanesMethod of the Whipple bicycle (equations formed) and its parameter symbols."""
    yaw, roll, pitch, steer = me.dynamicsymbols("yaw roll pitch steer")
    yaw_rate, roll_rate, rear_spin, pitch_rate, steer_rate, front_spin = me.dynamicsymbols(
        "yaw_rate roll_rate rear_spin pitch_rate steer_rate front_spin")
    (rf, rr, head_angle, fork_offset, fork_length, frame_length, fork_cg_par, fork_cg_norm,
     frame_cg_norm, frame_cg_par, Irw11, Irw22, Ifw11, Ifw22, Ifork11, Ifork22, Ifork33, Ifork31,
     Iframe11, Iframe22, Iframe33, Iframe31, m_fork, m_frame, m_fw, m_rw, g) = symbols = \
        sp.symbols("rf rr head_angle fork_offset fork_length frame_length fork_cg_par "
                   "fork_cg_norm frame_cg_norm frame_cg_par Irw11 Irw22 Ifw11 Ifw22 Ifork11 "
                   "Ifork22 Ifork33 Ifork31 Iframe11 Iframe22 Iframe33 Iframe31 m_fork m_frame "
                   "m_fw m_rw g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [yaw, N.z])
    R = Y.orientnew("R", "Axis", [roll, Y.x])
    frame = R.orientnew("frame", "Axis", [pitch + head_angle, R.y])
    rear_wheel = me.ReferenceFrame("rear_wheel")
    frame_axes = frame.orientnew("frame_axes", "Axis", [-head_angle, frame.y])
    fork = frame.orientnew("fork", "Axis", [steer, frame.x])
    fork_axes = fork.orientnew("fork_axes", "Axis", [-head_angle, fork.y])
    front_wheel = me.ReferenceFrame("front_wheel")

    rear_contact = me.Point("rear_contact")
    rear_centre = rear_contact.locatenew("rear_centre", rr * R.z)
    steer_axis = rear_centre.locatenew("steer_axis", frame_length * frame.z)
    frame_cg = rear_centre.locatenew("frame_cg", -frame_cg_norm * frame.x
                                     + frame_cg_par * frame.z)
    fork_cg = steer_axis.locatenew("fork_cg", -fork_cg_par * fork.x + fork_cg_norm * fork.z)
    front_centre = steer_axis.locatenew("front_centre", fork_length * fork.x
                                        + fork_offset * fork.z)
    front_contact = front_centre.locatenew(
        "front_contact", rf * (me.dot(fork.y, Y.z) * fork.y - Y.z).normalize())

    Y.set_ang_vel(N, yaw_rate * Y.z)
    R.set_ang_vel(Y, roll_rate * R.x)
    rear_wheel.set_ang_vel(frame, rear_spin * frame.y)
    frame.set_ang_vel(R, pitch_rate * frame.y)
    fork.set_ang_vel(frame, steer_rate * fork.x)
    front_wheel.set_ang_vel(fork, front_spin * fork.y)
    rear_contact.set_vel(N, 0)
    rear_centre.v2pt_theory(rear_contact, N, rear_wheel)
    steer_axis.v2pt_theory(rear_centre, N, frame)
    frame_cg.v2pt_theory(rear_centre, N, frame)
    fork_cg.v2pt_theory(steer_axis, N, fork)
    front_centre.v2pt_theory(steer_axis, N, fork)
    front_contact.v2pt_theory(front_centre, N, front_wheel)

    bodies = [
        me.RigidBody("frame", frame_cg, frame, m_frame,
                     (me.inertia(frame_axes, Iframe11, Iframe22, Iframe33, 0, 0, Iframe31),
                      frame_cg)),
        me.RigidBody("fork", fork_cg, fork, m_fork,
                     (me.inertia(fork_axes, Ifork11, Ifork22, Ifork33, 0, 0, Ifork31), fork_cg)),
        me.RigidBody("rear_wheel", rear_centre, rear_wheel, m_rw,
                     (me.inertia(frame, Irw11, Irw22, Irw11), rear_centre)),
        me.RigidBody("front_wheel", front_centre, front_wheel, m_fw,
                     (me.inertia(fork, Ifw11, Ifw22, Ifw11), front_centre)),
    ]
    loads = [(frame_cg, -m_frame * g * Y.z), (fork_cg, -m_fork * g * Y.z),
             (front_centre, -m_fw * g * Y.z), (rear_centre, -m_rw * g * Y.z)]
    kd = [yaw.diff() - yaw_rate, roll.diff() - roll_rate, pitch.diff() - pitch_rate,
          steer.diff() - steer_rate]
    no_slip = [me.dot(front_contact.vel(N), Y.x), me.dot(front_contact.vel(N), Y.y),
               me.dot(front_contact.vel(N), Y.z)]
    on_ground = [me.dot(front_contact.pos_from(rear_contact), Y.z)]
    km = me.KanesMethod(N, q_ind=[yaw, roll, steer], q_dependent=[pitch],
                        configuration_constraints=on_ground,
                        u_ind=[roll_rate, rear_spin, steer_rate],
                        u_dependent=[yaw_rate, pitch_rate, front_spin],
                        velocity_constraints=no_slip, kd_eqs=kd, constraint_solver="CRAMER")
    km.kanes_equations(bodies, loads)
    return km, symbols


def benchmark_parameters():
    """The benchmark bicycle's values (Meijaard et al. 2007, table 1) in this model's
    geometry, as SymPy's test converts them; the inertia products' signs follow its frames."""
    from math import acos, cos, pi, sin, sqrt
    rr, rf, trail, wheelbase = 0.3, 0.35, 0.08, 1.02
    head_angle = pi / 2 - pi / 10
    rake = -(trail * sin(head_angle) - rf * cos(head_angle))
    frame_cg_x, frame_cg_z, fork_cg_x, fork_cg_z = 0.3, 0.9, 0.9, 0.7
    frame_length = wheelbase * sin(head_angle) - (rake - (rf - rr) * cos(head_angle))
    frame_cg_norm = (frame_cg_z - rr - frame_cg_x / sin(head_angle) * cos(head_angle)) \
        * sin(head_angle)
    frame_cg_par = frame_cg_x / sin(head_angle) + (frame_cg_z - rr - frame_cg_x
                                                    / sin(head_angle) * cos(head_angle)) \
        * cos(head_angle)
    a, b = fork_cg_z - rf, wheelbase - fork_cg_x
    c = sqrt(a**2 + b**2)
    fork_length = wheelbase * cos(head_angle) - (rf - rr) * sin(head_angle)
    fork_cg_norm = rake + c * sin(pi / 2 - head_angle - acos(a / c))
    fork_cg_par = c * cos(pi / 2 - head_angle - acos(a / c)) - fork_length
    return dict(rf=rf, rr=rr, head_angle=head_angle, fork_offset=rake, fork_length=fork_length,
                frame_length=frame_length, fork_cg_par=fork_cg_par, fork_cg_norm=fork_cg_norm,
                frame_cg_norm=frame_cg_norm, frame_cg_par=frame_cg_par, Irw11=0.0603,
                Irw22=0.12, Ifw11=0.1405, Ifw22=0.28, Ifork11=0.05892, Ifork22=0.06,
                Ifork33=0.00708, Ifork31=0.00756, Iframe11=9.2, Iframe22=11.0, Iframe33=2.8,
                Iframe31=-2.4, m_fork=4.0, m_frame=85.0, m_fw=3.0, m_rw=2.0, g=9.81)


def upright(v, rr=0.3, rf=0.35):
    """The operating point rolling upright and straight at forward speed v: (q0, qd0, None) in
    the model's coordinates (yaw, roll, steer, pitch, int_rear_spin, int_front_spin)."""
    return [0.0] * 6, [0.0, 0.0, 0.0, 0.0, v / rr, v / rf], None


model = lagrgen.from_sympy(whipple_bicycle()[0], "bicycle", defaults=benchmark_parameters())
