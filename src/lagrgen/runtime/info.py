"""`ModelInfo`: what a built model says about itself, written once by the build.

The build makes one record from the description and the derived equations
(`lagrgen.build.model_info`); the C templates embed it as JSON (`<name>_metadata`), and both
backends read every name, size and flag of a built model from it (`INFO_ATTRIBUTES`). Imports
nothing heavy: a compiled model's module reads it at import.
"""
import json
from dataclasses import asdict, dataclass, field, fields

from ..errors import BuildError
from ..functions import HYBRID_FIELDS, HYBRID_GRADIENTS, POWER_TERMS


@dataclass(frozen=True)
class ModelInfo:
    """A built model's names, defaults, units, sizes and flags.

    `defaults` are floats, None where a value must be given at run time; `event_definitions` are
    (name, terminal, direction) triples; `n_holonomic` counts the holonomic constraints, which come
    first in `constraint_names`; `nonsmooth_definitions` are (name, "impact" | "friction", normal)
    triples of the impacts and frictions (`lagrgen.nonsmooth`), normal None or (kind, index);
    `initial_state` the declared [q0, q̇0] (2n floats), or () when none was declared;
    `formulation` how q̈ and the Jacobian are computed: "dense" (Cholesky of M) or "recursive"
    (over the kinematic tree, `lagrgen.tree`); `inertial_parameters` the parameters that are the
    bodies' ten inertial parameters (m, m·c, I about the body frame's origin), ten per body, the
    columns of the regressor; `coordinate_limits` the declared limits (`Model.limit`) as
    (coordinate, lower, upper, velocity, effort), None where absent; `link_names` the names of
    the links of a three-dimensional tree (`link_pose`, `link_jacobian`), in order;
    `limit_stops` the enforced limits (`Model.limit(..., enforce=True)`), unilateral contacts of
    the hybrid solves, as (name, coordinate index, sign, bound, restitution): gap
    sign·(q − bound) ≥ 0; `tree_structure` of a
    three-dimensional tree in the recursive formulation (else empty): its nodes' `coordinate` and
    `parent` (−1: a root), and the nonzero entries (row, col) of its generalized forces' first
    derivatives `dq`, `dqd`, `du` (coordinate, variable) and second derivatives `qh` (point
    indices z = [q, q̇, q̈, λ, u], lower triangle): what the sparsity of its residual's
    derivatives follows from (`lagrgen.collocation`).
    """

    name: str
    coordinates: tuple
    parameters: tuple
    inputs: tuple
    defaults: tuple
    units: dict
    output_names: tuple
    constraint_names: tuple = ()
    n_holonomic: int = 0
    event_definitions: tuple = ()
    explicit_time: bool = False
    content_hash: str = ""
    lagrgen_version: str = ""
    nonsmooth_definitions: tuple = ()
    initial_state: tuple = ()
    formulation: str = "dense"
    inertial_parameters: tuple = ()
    coordinate_limits: tuple = ()
    link_names: tuple = ()
    limit_stops: tuple = ()
    tree_structure: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("coordinates", "parameters", "inputs", "defaults", "output_names",
                     "constraint_names", "initial_state", "inertial_parameters",
                     "link_names"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "event_definitions",
                           tuple(tuple(e) for e in self.event_definitions))
        object.__setattr__(self, "units", dict(self.units))
        object.__setattr__(self, "tree_structure", dict(self.tree_structure))
        object.__setattr__(self, "coordinate_limits",
                           tuple(tuple(entry) for entry in self.coordinate_limits))
        object.__setattr__(self, "limit_stops", tuple(tuple(entry) for entry in self.limit_stops))
        object.__setattr__(self, "nonsmooth_definitions", tuple(
            (name, kind, None if normal is None else tuple(normal))
            for name, kind, normal in self.nonsmooth_definitions))

    @property
    def n_coordinates(self):
        return len(self.coordinates)

    @property
    def limits(self):
        """{coordinate name: (lower, upper, velocity, effort)}, None where a limit is absent."""
        return {name: tuple(values) for name, *values in self.coordinate_limits}

    @property
    def n_constraints(self):
        """m, the number of constraint multipliers (holonomic, then velocity constraints)."""
        return len(self.constraint_names)

    @property
    def dimensions(self):
        """The sizes the output shapes of `lagrgen.functions` name ("n", "2n", "n_inputs", ...)."""
        n, m = self.n_coordinates, self.n_constraints
        return {"n": n, "2n": 2 * n, "n_params": len(self.parameters),
                "n_inputs": len(self.inputs), "n_constraints": m,
                "n_holonomic": self.n_holonomic, "n_residuals": self.n_holonomic + m,
                "n_implicit": n + m, "n_point": 3 * n + m + len(self.inputs),
                "n_events": len(self.event_definitions), "n_power": len(POWER_TERMS),
                "n_outputs": len(self.output_names),
                "n_inertial": len(self.inertial_parameters), "n_links": len(self.link_names),
                "3": 3, "6": 6,
                "n_hybrid": sum(HYBRID_FIELDS[kind] + HYBRID_GRADIENTS[kind] * n
                                for _, kind, _ in self.nonsmooth_definitions)}

    def to_json(self):
        """The record as JSON (with its dimensions, for readers of the C metadata)."""
        return json.dumps({**asdict(self), "dimensions": self.dimensions}, sort_keys=True)

    @classmethod
    def from_json(cls, text):
        """The record of `to_json`'s text; BuildError if it was written by another layout."""
        data = json.loads(text)
        names = {f.name for f in fields(cls)}
        missing = names - set(data)
        if missing:
            raise BuildError(f"the metadata of compiled model {data.get('name', '?')!r} lacks "
                             f"{', '.join(sorted(missing))}: it was built by another lagrgen "
                             "version; rebuild it")
        return cls(**{name: data[name] for name in names})


#: What both backends expose from their ModelInfo, each as an attribute of the same name.
INFO_ATTRIBUTES = ("name", "coordinates", "parameters", "inputs", "units", "output_names",
                   "constraint_names", "event_definitions", "explicit_time", "content_hash",
                   "lagrgen_version", "n_coordinates", "n_constraints", "dimensions",
                   "nonsmooth_definitions", "formulation", "inertial_parameters",
                   "limits", "link_names")
