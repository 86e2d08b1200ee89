"""The model functions every built model provides, each declared once.

An entry names the function, how it is called from Python (its arguments), its outputs with their
shapes, and its formula. From this table come the C prototypes and the function table of the
standalone C model (`lagrgen.codegen`), the compiled runtime's methods and the Python backend's
methods. Every C model function has the one signature

    int <model>_<function>(double t, const double *y, const double *p, const double *u, double *out)

with y = [q, q̇] (q̇ ignored by the functions of q alone; y = [q, q̇, q̈, λ] for the functions of the
implicit form), the outputs concatenated row-major in `out`, and the result 0 on success, 1 when
the mass matrix is not positive definite, or NO_MEMORY when its work arrays could not be
allocated; a function of the call style "directions" also takes k directions
(`DIRECTIONS_SIGNATURE`).
This module imports nothing: the compiled runtime reads it at import time.
"""
from dataclasses import dataclass

#: How a function is called from Python: the argument names before (p, u).
CALL_STYLES = {
    "q": ("q", "t"),            # f(q, t=0.0, p=None, u=None)
    "q_qd": ("q", "qd", "t"),   # f(q, qd, t=0.0, p=None, u=None)
    "state": ("t", "y"),        # f(t, y, p=None, u=None)
    "directions": ("t", "y", "dy", "dp"),   # f(t, y, dy, dp=None, p=None, u=None)
    "implicit": ("q", "qd", "a", "t"),   # f(q, qd, a, t=0.0, p=None, u=None), a = [q̈, λ]
    "link": ("link", "q", "point"),      # f(link, q, point=(0, 0, 0), p=None); in C
                                         # y = [q, point, the link's index]
    "weighted": ("q", "qd", "a", "mu", "t"),   # f(q, qd, a, mu, t=0.0, p=None, u=None): weights
                                               # mu of the implicit form's rows; y = [q, q̇, a, mu]
}


@dataclass(frozen=True)
class Output:
    """One output array: its name and its shape as dimension names ("n", "2n", "n_inputs", ...)."""
    name: str
    shape: tuple


#: The compiled units of a built model. "model" is its module, what running it needs; any other
#: label is a unit compiled on first use into its own module, `<model>_<label>` (lagrgen.units):
#: "parameters" (the parameter Jacobian), "directions" (the directional derivatives of the
#: sensitivities), "manifold" (the constraint residuals' Jacobian of the linearization), "hessian"
#: (the residual's second derivatives, for collocation), "links" (link poses and Jacobians).
MODEL_UNIT = "model"


@dataclass(frozen=True)
class ModelFunction:
    """A function of a built model: name, call style (a key of CALL_STYLES), outputs, formula,
    the kernels its C body calls (names in lagrgen.kernels.KERNELS) and the unit it is compiled
    into (MODEL_UNIT, or the label of a unit compiled on first use, such as "parameters")."""
    name: str
    call: str
    outputs: tuple
    formula: str
    kernels: tuple = ()
    unit: str = MODEL_UNIT
    exported: bool = True   # in the standalone C model export_c writes (False: only compiled
                            # on first use, where its unit's derivation may take long)

    def shapes(self, dims):
        """The output shapes as tuples of ints, for the dimensions `dims` (name -> size)."""
        return [tuple(dims[d] for d in out.shape) for out in self.outputs]

    def size(self, dims):
        """The length of the concatenated output buffer."""
        total = 0
        for shape in self.shapes(dims):
            k = 1
            for d in shape:
                k *= d
            total += k
        return total


#: What a model function returns when the heap has no room for its work arrays (LG_NO_MEMORY of
#: the C templates' linalg.c.in).
NO_MEMORY = 2

#: The C signature of the functions of call style "directions": k directions (dy_s, dp_s), each
#: dy_s of 2n and dp_s of n_params doubles, stored one after the other (dp never NULL).
DIRECTIONS_SIGNATURE = ("double t, const double *y, const double *p, const double *u, int k, "
                        "const double *dy, const double *dp, double *out")

FUNCTIONS = (
    ModelFunction("mass_matrix", "q", (Output("M", ("n", "n")),),
                  "M(q, t) = ∂²T/∂q̇∂q̇ᵀ", ("mf",)),
    ModelFunction("forcing", "q_qd", (Output("F", ("n",)),),
                  "F(q, q̇, t, u), so that M·q̈ = F", ("mf",)),
    ModelFunction("rhs", "state", (Output("ydot", ("2n",)),),
                  "ẏ = [q̇, M⁻¹·F] for y = [q, q̇]", ("mf", "constraints")),
    ModelFunction("jacobian", "state", (Output("J", ("2n", "2n")),),
                  "∂ẏ/∂y = [[0, I], [M⁻¹·(∂F/∂q − ∂(M·q̈)/∂q), M⁻¹·∂F/∂q̇]]",
                  ("mf", "constraints", "jacobian_b", "constraint_jacobian")),
    ModelFunction("parameter_jacobian", "state", (Output("dydp", ("2n", "n_params")),),
                  "∂ẏ/∂p = [0; M⁻¹·(∂F/∂p − ∂(M·q̈)/∂p)] (with constraints: through the same "
                  "saddle-point solve as the Jacobian)",
                  ("mf", "constraints", "parameter_b", "constraint_parameter_jacobian"),
                  "parameters"),
    ModelFunction("directional_derivatives", "directions",
                  (Output("ydot", ("2n",)), Output("dydot", ("k", "2n"))),
                  "ẏ, and for each direction s: J·dy_s + ∂ẏ/∂p·dp_s (forward mode on the "
                  "kernels, or tangent sweeps of the recursion; J never formed)", ("motion_tape", "motion_tangent", "constraints"),
                  "directions"),
    ModelFunction("linear_terms", "q_qd",
                  (Output("M", ("n", "n")), Output("dF_dq", ("n", "n")),
                   Output("dF_dqd", ("n", "n")), Output("dF_du", ("n", "n_inputs"))),
                  "M, ∂F/∂q, ∂F/∂q̇ and ∂F/∂u at one point", ("mf", "jacobian_b", "dF_du")),
    ModelFunction("power_terms", "state", (Output("P", ("n_power",)),),
                  "[Σ Q_j·q̇_j, R]: the power of the applied forces and the Rayleigh function",
                  ("outputs",)),
    ModelFunction("outputs", "state", (Output("y", ("n_outputs",)),),
                  "the outputs: the user's, then T, V, T + V, Σ Q_j·q̇_j and R", ("outputs",)),
    ModelFunction("constraint_forces", "state", (Output("lam", ("n_constraints",)),),
                  "λ of M·q̈ = F + Aᵀ·λ, A·q̈ = γ (Aᵀλ: the generalized forces of constraint)",
                  ("mf", "constraints")),
    ModelFunction("constraint_residuals", "state", (Output("residuals", ("n_residuals",)),),
                  "Φ(q, t) of the holonomic constraints, then A·q̇ + b of all constraints",
                  ("constraint_residuals",)),
    ModelFunction("constraint_residual_jacobian", "state",
                  (Output("dr_dy", ("n_residuals", "2n")),),
                  "∂[Φ; A·q̇ + b]/∂[q, q̇]: the tangent space of the constraint manifold is its "
                  "null space", ("constraint_residual_jacobian",), "manifold"),
    ModelFunction("constraint_terms", "q_qd",
                  (Output("A", ("n_constraints", "n")), Output("lam", ("n_constraints",)),
                   Output("H", ("n", "n"))),
                  "A, λ and ∂(Aᵀλ)/∂q (λ held fixed) at one point",
                  ("mf", "constraints", "constraint_jacobian")),
    ModelFunction("events", "state", (Output("g", ("n_events",)),),
                  "g_k(t, q, q̇, u): the model's event functions (model.event)", ("events",)),
    ModelFunction("hybrid_terms", "state",
                  (Output("M", ("n", "n")), Output("F", ("n",)),
                   Output("A", ("n_constraints", "n")), Output("gamma", ("n_constraints",)),
                   Output("terms", ("n_hybrid",))),
                  "M, F, the constraints' A and γ, and the impacts' and frictions' terms "
                  "(lagrgen.nonsmooth) that the hybrid drivers assemble each mode from",
                  ("mf", "constraints", "nonsmooth")),
    ModelFunction("residual_terms", "implicit",
                  (Output("r", ("n_implicit",)), Output("dr_dy", ("n_implicit", "2n")),
                   Output("dr_da", ("n_implicit", "n_implicit")),
                   Output("dr_du", ("n_implicit", "n_inputs"))),
                  "r = [M·q̈ − F − Aᵀλ; A·q̈ − γ] of the implicit form at a given a = [q̈, λ], "
                  "and its derivatives ∂r/∂[q, q̇], ∂r/∂a, ∂r/∂u",
                  ("mf", "constraints", "jacobian_b", "dF_du", "constraint_jacobian")),
    ModelFunction("residual_hessian", "weighted", (Output("H", ("n_point", "n_point")),),
                  "∇²_z(Σ mu_i·r_i) of r = [M·q̈ − F − Aᵀλ; A·q̈ − γ], z = [q, q̇, q̈, λ, u] "
                  "(symmetric): for a three-dimensional tree by the second-order derivatives "
                  "of its recursion, otherwise from the symbolic second derivatives",
                  ("residual_hessian",), "hessian", exported=False),
    ModelFunction("regressor", "implicit", (Output("Y", ("n", "n_inertial")),),
                  "Y(q, q̇, q̈) with M·q̈ − F = Y·π for the bodies' inertial parameters π "
                  "(inertial_parameters; forces of inputs, springs and dampers left out): "
                  "∂(M·q̈ − F)/∂π", ("parameter_b", "body_poses"), "regressor"),
    ModelFunction("link_pose", "link", (Output("position", ("3",)), Output("rotation", ("3", "3"))),
                  "the world position p + R·point of a point fixed in a link and the link's "
                  "rotation R (x_world = R·x_link), from the tree's link frames",
                  ("link_frames",), "links"),
    ModelFunction("link_jacobian", "link", (Output("J", ("6", "n")),),
                  "J with [velocity of the point; angular velocity of the link] = J·q̇, world "
                  "axes: the columns of the joints above the link, [v_j + ω_j × x; ω_j] from "
                  "their twists [ω_j; v_j]", ("link_frames",), "links"),
    ModelFunction("residual_parameter_jacobian", "implicit",
                  (Output("dr_dp", ("n_implicit", "n_params")),),
                  "∂r/∂p of r = [M·q̈ − F − Aᵀλ; A·q̈ − γ] at a given a = [q̈, λ]",
                  ("parameter_b", "constraint_parameter_jacobian"), "parameters"),
)

BY_NAME = {f.name: f for f in FUNCTIONS}
#: The functions of the standalone C model (`lagrgen.export_c`): all but the second derivatives.
EXPORTED = tuple(f for f in FUNCTIONS if f.exported)
#: The unit labels, the model's first.
UNITS = tuple(dict.fromkeys([MODEL_UNIT] + [f.unit for f in FUNCTIONS]))


def functions_of(unit):
    """The registered functions compiled into `unit`, in registry order."""
    return tuple(f for f in FUNCTIONS if f.unit == unit)


#: What `power_terms` returns, beside the outputs: d(T + V)/dt = input_power − 2·R for a
#: scleronomic model with R quadratic in q̇.
POWER_TERMS = ("input_power", "rayleigh_dissipation")

#: Entries of `hybrid_terms`' `terms` per impact and per friction, beside the n of each of its
#: HYBRID_GRADIENTS gradients (the layout is in `lagrgen.nonsmooth`).
HYBRID_FIELDS = {"impact": 4, "friction": 5, "planar_friction": 7}
HYBRID_GRADIENTS = {"impact": 1, "friction": 1, "planar_friction": 2}

