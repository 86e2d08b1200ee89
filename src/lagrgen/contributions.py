"""One contribution function per physics record: what each adds to Lagrange's equations.

A record of `lagrgen.records` enters the equations d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q + ∂R/∂q̇ = Q through
its share of T, V, R or Q. `CONTRIBUTIONS` maps each record type to its function
`f(record, sums)`, which adds that share to a `Sums` (in SymEngine, internal symbols): kinetic
energy of constant-mass bodies straight into M and F (term by term, `lagrgen.terms.Terms`), any
other kinetic energy to the terms differentiated as a whole, V, R and Q to their sums, and every
share of T, V, R and Q to the energies the outputs report.
"""
import symengine as se

from .calculus import diff, rate
from .records import (Articulation, Body3D, Damper, Dissipation, Force, GeneralizedForce,
                      KineticEnergy, Particle, PlanarBody, PotentialEnergy, Spring, Torque)
from .terms import Terms, expanded_terms


class _TermsRow(dict):
    """A row of M's `Terms` accumulators, each made when first used (`row[j]`): a model whose M is
    sparse, or is never formed (the recursive formulation), makes few of the n² accumulators."""

    def __init__(self, kinematic):
        super().__init__()
        self.kinematic = kinematic

    def __missing__(self, j):
        terms = self[j] = Terms(self.kinematic)
        return terms


class Sums:
    """What the physics records add up to, for n coordinates.

    `M` (lower triangle) and `F` receive the kinetic terms of constant-mass bodies directly;
    `general_T` the kinetic energies differentiated as a whole (`add_kinetic_energy`); `V`, `R` and
    `Q` (n generalized forces) the potential, Rayleigh and applied terms; `T` every kinetic share.
    `convert` turns a record's SymPy expression into the internal symbols (q, qd, t).
    """

    def __init__(self, convert, q, qd, t, kinematic):
        n = len(q)
        self.convert, self.q, self.qd, self.t = convert, q, qd, t
        self.M = [_TermsRow(kinematic) for _ in range(n)]
        self.F = [Terms(kinematic) for _ in range(n)]
        self.general_T = []
        self.particles = []     # constant masses (m, r), added to M and F by add_particles()
        self.deferred = []      # what adds its kinetic terms to M and F only when they are formed
        self.T = self.V = self.R = se.Integer(0)
        self.Q = [se.Integer(0)] * n
        self.articulations = []   # Articulation records: their energies formed on first use
        self._frames = {}

    def frames_of(self, record):
        """The world frames of the Articulation `record`'s segments (`lagrgen.frames`), once."""
        from . import frames
        if id(record) not in self._frames:
            self._frames[id(record)] = frames.frames(record, self.convert, self.q, self.qd,
                                                     self.t)
        return self._frames[id(record)]

    def tree_energies(self):
        """(T, V) of the articulations' bodies: the sums of each body's kinetic and potential
        energy (`lagrgen.frames`), each sum formed once."""
        from . import frames
        T, V = [], []
        for record in self.articulations:
            gravity = [self.convert(g) for g in record.gravity]
            for frame in self.frames_of(record):
                T.append(frames.kinetic_energy(frame))
                V.append(frames.potential_energy(frame, gravity))
        return se.Add(*T), se.Add(*V)

    def add_mass(self, mass, position):
        """T += ½·mass·ṙ·ṙ for a mass at `position` (internal symbols)."""
        q, qd, t = self.q, self.qd, self.t
        v = [rate(rc, q, qd, t) for rc in position]
        T = mass * sum(vc * vc for vc in v) / 2
        self.T += T
        if mass.free_symbols & (set(q) | {t}):
            self.general_T.append(T)
        else:
            self.particles.append((mass, position))

    def add_particles(self):
        """Add the constant masses collected by `add_mass` to M and F (`add_particles`), once all
        records are in: bodies sharing Jacobian columns are summed as composite bodies."""
        add_particles(self.M, self.F, self.particles, self.q, self.qd, self.t)
        self.particles = []

    def add_virtual_work(self, vector, position):
        """Q_j += vector · ∂position/∂q_j (internal symbols; only for the q_j it holds)."""
        free = set().union(*(rc.free_symbols for rc in position))
        for j, qj in enumerate(self.q):
            if qj in free:
                self.Q[j] += sum(fc * diff(rc, qj) for fc, rc in zip(vector, position))

    @property
    def power(self):
        """Σ Q_j·q̇_j, the power of the applied forces."""
        return sum((Qj * qdj for Qj, qdj in zip(self.Q, self.qd)), se.Integer(0))


# -- one function per record type ------------------------------------------------------------------
def particle(record, sums):
    """T += ½·m·ṙ·ṙ."""
    c = sums.convert
    sums.add_mass(c(record.mass), [c(e) for e in record.position])


def planar_body(record, sums):
    """T += ½·m·ṙ·ṙ + ½·I·θ̇² (the rotation as a mass I at the 1-D 'position' θ)."""
    c = sums.convert
    sums.add_mass(c(record.mass), [c(e) for e in record.position])
    sums.add_mass(c(record.inertia), [c(record.angle)])


def body_3d(record, sums):
    """T += ½·m·ṙ·ṙ + ½·ωᵀ·I·ω."""
    c = sums.convert
    sums.add_mass(c(record.mass), [c(e) for e in record.position])
    inertia = [[c(e) for e in row] for row in record.inertia.tolist()]
    omega = [c(e) for e in record.omega]
    sums.T += sum(omega[i] * inertia[i][j] * omega[j] for i in range(3) for j in range(3)) / 2
    add_rotation(sums.M, sums.F, inertia, omega, sums.q, sums.qd, sums.t)


def articulation(record, sums):
    """Nothing formed now: T and V of every segment's body (`Sums.tree_energies`, for the
    outputs), and their terms of M and F (`dense_articulation`, when the dense equations are
    formed), are formed on first use; the recursive formulation forms each body's terms itself
    (`lagrgen.tree3d`), and a long chain's nested world frames are never built for it."""
    sums.articulations.append(record)
    for segment in record.segments:
        if segment.kind == "free" and segment.radial:
            T = free_radial_energy(segment, sums)
            sums.T += T
            sums.general_T.append(T)
    sums.deferred.append(lambda: dense_articulation(record, sums.frames_of(record), sums))


def free_radial_energy(segment, sums):
    """½·J·(d|ζ|/dt)² = ½·J·(ζ·ζ̇)²/|ζ|² of a free segment's quaternion length (J its `radial`):
    the length moves nothing, and this inertia makes it a coordinate of its own (M positive
    definite) that keeps its rate."""
    from . import frames
    _, z, _, zd = frames.free_motion(segment, sums.convert, sums.q, sums.qd, sums.t)
    dot = se.Add(*(a * b for a, b in zip(z, zd)))
    return se.Float(segment.radial) * dot * dot / (2 * se.Add(*(a * a for a in z)))


def dense_articulation(record, world, sums):
    """Add each segment body's kinetic terms to M and F: a mass at its centre and its rotation
    (`add_rotation`) when its mass is a nonzero number; otherwise a mass at the frame's origin,
    the rotation about it and the cross term ṗ·(ω × R·h) as a general kinetic energy."""
    from . import frames
    omegas = frames.body_omega(record, sums.convert, sums.q, sums.qd, sums.t)
    for frame, omega in zip(world, omegas):
        m, h = frame.inertia[0], frame.inertia[1:4]
        I_O = frames.symmetric(frame.inertia[4:])
        if all(x == 0 for x in frame.inertia):
            continue
        if m.is_Number and m != 0 and all(x.is_Number for x in h):
            c = [x / m for x in h]
            I_c = [[I_O[i][j] - m * ((sum(x * x for x in c) if i == j else 0) - c[i] * c[j])
                    for j in range(3)] for i in range(3)]
            centre = [a + b for a, b in zip(frame.p, frames.apply(frame.R, c))]
            sums.particles.append((m, centre))
            add_rotation(sums.M, sums.F, I_c, omega, sums.q, sums.qd, sums.t)
            continue
        if m != 0:
            sums.particles.append((m, frame.p))
        add_rotation(sums.M, sums.F, I_O, omega, sums.q, sums.qd, sums.t)
        if any(x != 0 for x in h):
            sums.general_T.append(se.Add(*(a * b for a, b in zip(
                frame.velocity, frames.cross(frame.omega, frames.apply(frame.R, h))))))


def kinetic_energy(record, sums):
    """T += expr (differentiated as a whole)."""
    T = sums.convert(record.expr)
    sums.general_T.append(T)
    sums.T += T


def potential_energy(record, sums):
    """V += expr."""
    sums.V += sums.convert(record.expr)


def spring(record, sums):
    """V += ½·k·(length − rest)²."""
    c = sums.convert
    sums.V += c(record.k) * (c(record.length) - c(record.rest)) ** 2 / 2


def damper(record, sums):
    """R += ½·c·(d length/dt)²."""
    c = sums.convert
    sums.R += c(record.c) * rate(c(record.length), sums.q, sums.qd, sums.t) ** 2 / 2


def dissipation(record, sums):
    """R += expr."""
    sums.R += sums.convert(record.expr)


def force(record, sums):
    """Q_j += f · ∂r/∂q_j."""
    c = sums.convert
    sums.add_virtual_work([c(e) for e in record.vector], [c(e) for e in record.at])


def torque(record, sums):
    """Q_j += moment · ∂angle/∂q_j."""
    sums.add_virtual_work([sums.convert(record.moment)], [sums.convert(record.angle)])


def generalized_force(record, sums):
    """Q_j += expr for its coordinate j."""
    sums.add_virtual_work([sums.convert(record.expr)], [sums.convert(record.coordinate)])


#: Record type -> its contribution function (one entry per physics kind of `lagrgen.records`).
CONTRIBUTIONS = {
    Particle: particle, PlanarBody: planar_body, Body3D: body_3d, Articulation: articulation,
    KineticEnergy: kinetic_energy, PotentialEnergy: potential_energy, Spring: spring,
    Damper: damper, Dissipation: dissipation,
    Force: force, Torque: torque, GeneralizedForce: generalized_force,
}


#: The records that add only to V, R or Q: none carries kinetic energy.
APPLIED = (PotentialEnergy, Spring, Damper, Dissipation, Force, Torque, GeneralizedForce)


def generalized_forces(records, convert, q, qd, t):
    """Q_j = (applied forces)_j − ∂V/∂q_j − ∂R/∂q̇_j of the `records` (of the APPLIED kinds),
    in the internal symbols."""
    rest = Sums(convert, q, qd, t, kinematic=set())
    for record in records:
        CONTRIBUTIONS[type(record)](record, rest)
    return [rest.Q[j] - diff(rest.V, q[j]) - diff(rest.R, qd[j]) for j in range(len(q))]


# -- how kinetic energy enters M and F ------------------------------------------------------------
def add_particles(M, F, particles, q, qd, t):
    """Add point masses of constant mass, [(m, r)]: M += Σ m·JᵀJ, F −= Σ m·Jᵀ·b, with J = ∂r/∂q
    and b = r̈ at q̈ = 0.

    Composite bodies first: the masses of the particles whose Jacobian columns i and j are the
    same expressions (every body beyond joint max(i, j) of a chain) are summed before their product
    Σ_c J_ci·J_cj is formed, and each b is expanded once, its terms summed by mass per column i;
    so a chain of n bodies forms O(n²) kinematic products instead of O(n³) (the bookkeeping that
    groups them is O(n³) dictionary updates). The products go into the `Terms` accumulators
    M[i][j], F[i] with the summed masses as their weights (see `Terms.expr`); F's plain sum is
    recorded per particle, as the products were before they were grouped.
    """
    n = len(q)
    pair_masses = {}   # (i, j, column i, column j) -> [m]
    force = {}         # (i, column i) -> per component {term: {numeric coefficient: [m]}}
    for mass, position in particles:
        J = [[diff(rc, qi) if qi in free else se.Integer(0) for qi in q]
             for rc, free in ((rc, rc.free_symbols) for rc in position)]
        v = [sum((Jc[i] * qd[i] for i in range(n) if Jc[i] != 0), diff(rc, t))
             for Jc, rc in zip(J, position)]
        rates = [rate(vc, q, qd, t) for vc in v]
        b = [expanded_terms(bc) for bc in rates]
        active = [i for i in range(n) if any(Jc[i] != 0 for Jc in J)]
        columns = {i: tuple(Jc[i] for Jc in J) for i in active}
        for i in active:
            for j in active:
                if j <= i:
                    pair_masses.setdefault((i, j, columns[i], columns[j]), []).append(mass)
            F[i].record(-mass * sum(Jci * bc for Jci, bc in zip(columns[i], rates)))
            sums = force.setdefault((i, columns[i]), [{} for _ in b])
            for by_term, terms in zip(sums, b):
                for coeff, term in terms:
                    by_term.setdefault(term, {}).setdefault(coeff, []).append(mass)
    for (i, j, ci, cj), masses in pair_masses.items():
        M[i][j].add(sum(a * c for a, c in zip(ci, cj)), se.Add(*masses))
    for (i, column), sums in force.items():
        for Jci, by_term in zip(column, sums):
            if Jci == 0:
                continue
            for term, by_coeff in by_term.items():
                weight = se.Add(*(coeff * se.Add(*masses) for coeff, masses in by_coeff.items()))
                F[i].add(Jci * term, -weight, plain=False)


def add_rotation(M, F, inertia, omega, q, qd, t):
    """M += Wᵀ·I·W, F −= Wᵀ·(I·b + ω × I·ω) for T = ½·ωᵀ·I·ω with ω = W·q̇ + w₀ (SymEngine,
    internal symbols; W = ∂ω/∂q̇, b = Σ ∂ω/∂q_j·q̇_j + ∂ω/∂t the part of ω̇ without q̈)."""
    n = len(q)
    W = [[diff(w, s) for s in qd] for w in omega]
    b = [sum((diff(w, qj) * qdj for qj, qdj in zip(q, qd)), diff(w, t)) for w in omega]
    Iw = [sum(inertia[a][c] * omega[c] for c in range(3)) for a in range(3)]
    h = [sum(inertia[a][c] * b[c] for c in range(3)) for a in range(3)]
    h = [h[0] + omega[1] * Iw[2] - omega[2] * Iw[1],
         h[1] + omega[2] * Iw[0] - omega[0] * Iw[2],
         h[2] + omega[0] * Iw[1] - omega[1] * Iw[0]]
    active = [j for j in range(n) if any(W[a][j] != 0 for a in range(3))]
    IW = {j: [sum(inertia[a][c] * W[c][j] for c in range(3)) for a in range(3)] for j in active}
    for i in active:
        for j in active:
            if j <= i:
                M[i][j] += sum(W[a][i] * IW[j][a] for a in range(3))
        F[i] -= sum(W[a][i] * h[a] for a in range(3))


def add_kinetic_energy(M, F, T, q, qd, t):
    """Add a general T: M += ∂²T/∂q̇∂q̇ᵀ, F += ∂T/∂q − (∂²T/∂q̇∂qᵀ)·q̇ − ∂²T/∂q̇∂t."""
    n = len(q)
    dT_dqd = [diff(T, s) for s in qd]
    for i in range(n):
        for j in range(i + 1):
            M[i][j] += diff(dT_dqd[i], qd[j])
        F[i] += diff(T, q[i]) - sum(diff(dT_dqd[i], q[j]) * qd[j] for j in range(n)) \
            - diff(dT_dqd[i], t)
