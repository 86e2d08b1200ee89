"""`Model`: a mechanical system as the user describes it (`lagrgen.description.Description`) with
its derived equations of motion and their display.

This is the face of the description: it stands after the derivation and the display code it
calls, so the description itself (`description`, `records`, `checks`) imports neither.
"""
from .checks import (SUPPORTED_FUNCTIONS, as_vector, check_unit,  # noqa: F401
                     split_names, split_units)
from .numbers import fits_a_double  # noqa: F401
from .description import SHAPES, Description  # noqa: F401
from .errors import ModelError
from .names import check_model_name, check_name  # noqa: F401
from .records import (AUTOMATIC_OUTPUTS, BAUMGARTE_DEFAULTS, ENERGY_OUTPUTS,  # noqa: F401
                      ModelSpec)


class Model(Description):
    """A mechanical system described by its energies, dissipation and generalized forces.

    Lagrange's equations d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q + ∂R/∂q̇ = Q are derived from what is added here
    (the declaring methods are those of `Description`).
    """

    def equations(self):
        """Return the derived `lagrgen.lagrange.Equations` (cached until the model changes)."""
        from .lagrange import derived
        return derived(self.spec())

    def mass_matrix(self):
        """M = ∂²T/∂q̇∂q̇ᵀ as a SymPy Matrix in the model's own symbols."""
        return self.equations().user_matrix("M")

    def forcing(self):
        """F(q, q̇, t, u), so that M·q̈ = F, as a SymPy column Matrix in the model's own symbols."""
        return self.equations().user_matrix("F")

    def __repr__(self):
        return (f"Model({self.name!r}: coordinates {self.coordinate_names}, "
                f"parameters {self.parameter_names}, inputs {self.input_names})")

    def _repr_latex_(self):
        """The equations of motion Σ_j M_ij·q̈_j = F_i as a LaTeX aligned block (what
        `lagrgen show --latex` prints), for notebooks; None (plain repr) if they cannot be derived."""
        from .outputs.display import latex_block
        try:
            return latex_block(self)
        except ModelError:
            return None

