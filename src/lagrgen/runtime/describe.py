"""How a built model (either backend) names itself: its coordinates, parameters with defaults and
inputs, and the formulation its build chose. Imports nothing heavy: a compiled model's module
uses it at import."""
import types


def describe(mod):
    """'<lagrgen model 'name' (c backend, dense formulation): coordinates a, b; parameters m=1,
    L=?; inputs F>' ('?' where a parameter has no default and must be given at run time)."""
    params = ", ".join(f"{p}={d:g}" if d == d else f"{p}=?"
                       for p, d in zip(mod.parameters, mod.defaults))
    parts = [f"coordinates {', '.join(mod.coordinates)}",
             f"parameters {params}" if params else "no parameters",
             f"inputs {', '.join(mod.inputs)}" if len(mod.inputs) else "no inputs"]
    return (f"<lagrgen model {mod.name!r} ({mod.backend} backend, {mod.formulation} "
            f"formulation): {'; '.join(parts)}>")


class BuiltModule(types.ModuleType):
    """The class of a compiled model's module: a module whose repr describes the model."""

    def __repr__(self):
        return describe(self)
