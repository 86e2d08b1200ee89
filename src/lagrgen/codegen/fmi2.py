"""The FMI 2.0 model description of an exported FMU, and the variables every FMU shares.

Variables in value-reference order: q, q̇ (`<q>_dot`), der(q), der(q̇), parameters, inputs, then
the co-simulation solver settings, time and the event indicators (FMI 3.0) and the outputs, as
`templates/fmu_core.c.in` numbers them. The FMI 3.0 description is in `fmi3.py`; building and
zipping in `fmu.py`.
"""
import math
import uuid
from xml.etree import ElementTree as ET

from .._version import __version__
from ..errors import ModelError
from ..methods import BY_NAME, NATIVE_CODES, NATIVE_METHODS

def variable_names(info, reserved=()):
    """The names of the model's FMU variables in value-reference order: q, q̇ (`<q>_dot`),
    der(q), der(q̇), parameters, inputs; ModelError if two coincide, or coincide with one of the
    outputs (variables of their own, after these) or of the `reserved` names."""
    q = info.coordinates
    qd = [f"{c}_dot" for c in q]
    names = [*q, *qd, *(f"der({c})" for c in (*q, *qd)), *info.parameters, *info.inputs]
    seen = set()
    for name in [*names, *info.output_names, *reserved]:
        if name in seen:
            raise ModelError(
                f"model {info.name!r}: the FMU variable name {name!r} would be used twice (the "
                "velocities are named <coordinate>_dot, the outputs by their names"
                + (", and " + ", ".join(reserved) + " is the FMU's own" if reserved else "")
                + "): rename the coordinate, parameter, input or output")
        seen.add(name)
    return names


def parameter_start_values(info, params=None):
    """Start values of the parameters: the defaults, overridden by `params` (name -> value);
    ModelError for a parameter that has neither or an unknown or non-finite value."""
    names = info.parameters
    values = dict(zip(names, info.defaults))
    for key, value in (params or {}).items():
        if key not in values:
            raise ModelError(f"params: model {info.name!r} has no parameter {key!r} (its "
                             f"parameters are {', '.join(names) or 'none'})")
        values[key] = value
    out = []
    for name in names:
        value = values[name]
        if value is None:
            raise ModelError(f"parameter {name!r} of model {info.name!r} has no default, and an "
                             "FMU needs a start value for every parameter: give it a default or "
                             "a value at export (params={...} or --params)")
        value = float(value)
        if not math.isfinite(value):
            raise ModelError(f"parameter {name!r}: start value {value} is not finite")
        out.append(value)
    return out


def state_start_values(info):
    """Start values of the states [q, q̇]: the model's initial state, else zeros."""
    return [float(v) for v in info.initial_state] or [0.0] * (2 * len(info.coordinates))


def fmu_guid(info, start_values, start_time, stop_time, settings=()):
    """A GUID determined by the model's content hash and what the description adds to it
    (`settings`: the kind, FMI version and solver start values)."""
    text = repr((info.content_hash, start_values, start_time, stop_time, __version__,
                 *settings))
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "lagrgen:" + text)) + "}"


def number_text(value):
    return repr(float(value))


def value_references(info):
    """{what: value reference} of the variables after the model's: the solver settings of a
    co-simulation FMU, time and the first event indicator (FMI 3.0), the first output, as
    fmu_core.c.in numbers them."""
    end = 4 * len(info.coordinates) + len(info.parameters) + len(info.inputs)
    return {"solver.rtol": end, "solver.atol": end + 1, "solver.method": end + 2, "time": end + 3,
            "events": end + 4, "outputs": end + 4 + len(info.event_definitions)}


def source_file_names(name, kind):
    """The C files an importer compiles to rebuild the FMU (the glue includes the others)."""
    return [f"{name}_fmu.c", *(["lg_ode.c"] if kind == "cs" else [])]


def method_items():
    """(name, value, description) of the enumeration solver.method: the native engine's methods
    with their codes in lg_ode.h."""
    return [(m, NATIVE_CODES[m], BY_NAME[m].description) for m in NATIVE_METHODS]


def model_description(info, guid, start_values, start_time=0.0, stop_time=10.0, tolerance=None,
                      kind="me", solver=None):
    """The text of modelDescription.xml (FMI 2.0, Model Exchange or Co-Simulation). The model's
    variables are listed in value-reference order, so such a variable's index is its value
    reference + 1; a co-simulation FMU's solver settings (`solver` = (method index, rtol,
    atol)) follow them."""
    name, q = info.name, info.coordinates
    n, names = len(q), variable_names(info)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": name, "guid": guid,
        "description": f"{name}: M(q, t)·q'' = F(q, q', t, u), states q and q'",
        "generationTool": f"lagrgen {__version__}", "variableNamingConvention": "flat",
        "numberOfEventIndicators": str(len(info.event_definitions) if kind == "me" else 0)})
    common = {"modelIdentifier": name, "canGetAndSetFMUstate": "true",
              "canSerializeFMUstate": "true", "providesDirectionalDerivative": "true",
              "canNotUseMemoryManagementFunctions": "false"}
    if kind == "me":
        element = ET.SubElement(root, "ModelExchange", {
            **common, "completedIntegratorStepNotNeeded": "true"})
    else:
        element = ET.SubElement(root, "CoSimulation", {
            **common, "canHandleVariableCommunicationStepSize": "true",
            "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false", "canBeInstantiatedOnlyOncePerProcess": "false"})
    sources = ET.SubElement(element, "SourceFiles")
    for file_name in source_file_names(name, kind):
        ET.SubElement(sources, "File", {"name": file_name})
    if kind == "cs":
        types = ET.SubElement(root, "TypeDefinitions")
        enumeration = ET.SubElement(ET.SubElement(types, "SimpleType", {
            "name": "lagrgen.Method", "description": "the native engine's integration method"}),
            "Enumeration")
        for item, value, what in method_items():
            ET.SubElement(enumeration, "Item", {"name": item, "value": str(value),
                                                "description": what})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError",
                                           "description": "errors"})
    experiment = {"startTime": number_text(start_time), "stopTime": number_text(stop_time)}
    if tolerance is not None:
        experiment["tolerance"] = number_text(tolerance)
    ET.SubElement(root, "DefaultExperiment", experiment)
    variables = ET.SubElement(root, "ModelVariables")

    def variable(vr, attributes, real, description, name=None, type_="Real"):
        sv = ET.SubElement(variables, "ScalarVariable", {
            "name": name or names[vr], "valueReference": str(vr), "description": description,
            **attributes})
        ET.SubElement(sv, type_, real)

    start = state_start_values(info)
    for i, c in enumerate(q):
        variable(i, {"causality": "output", "variability": "continuous", "initial": "exact"},
                 {"start": number_text(start[i])}, f"coordinate {c} (a state)")
    for i, c in enumerate(q):
        variable(n + i, {"causality": "local", "variability": "continuous", "initial": "exact"},
                 {"start": number_text(start[n + i])}, f"rate of {c} (a state)")
    for i in range(2 * n):
        variable(2 * n + i, {"causality": "local", "variability": "continuous",
                             "initial": "calculated"},
                 {"derivative": str(i + 1)}, f"time derivative of {names[i]}")
    base = 4 * n
    for j, (p, value) in enumerate(zip(info.parameters, start_values)):
        variable(base + j, {"causality": "parameter", "variability": "tunable",
                            "initial": "exact"}, {"start": number_text(value)}, f"parameter {p}")
    base += len(info.parameters)
    for k, u in enumerate(info.inputs):
        variable(base + k, {"causality": "input", "variability": "continuous"},
                 {"start": "0.0"}, f"input {u}")
    if kind == "cs":
        vr = value_references(info)
        method, rtol, atol = solver
        tunable = {"causality": "parameter", "variability": "tunable", "initial": "exact"}
        variable(vr["solver.rtol"], tunable, {"start": number_text(rtol)},
                 "relative tolerance of the native engine (the experiment's tolerance, when "
                 "the importer gives one, replaces it)", name="solver.rtol")
        variable(vr["solver.atol"], tunable, {"start": number_text(atol)},
                 "absolute tolerance of the native engine", name="solver.atol")
        variable(vr["solver.method"], tunable,
                 {"declaredType": "lagrgen.Method", "start": str(method)},
                 "integration method of the native engine", name="solver.method",
                 type_="Enumeration")
    vr = value_references(info)
    for k, output in enumerate(info.output_names):
        variable(vr["outputs"] + k, {"causality": "local", "variability": "continuous",
                                     "initial": "calculated"}, {}, output_description(info, output),
                 name=output)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure, "Outputs")
    for i in range(n):
        ET.SubElement(outputs, "Unknown", {"index": str(i + 1)})
    derivatives = ET.SubElement(structure, "Derivatives")
    initial = ET.SubElement(structure, "InitialUnknowns")
    for i in range(2 * n):
        ET.SubElement(derivatives, "Unknown", {"index": str(2 * n + i + 1)})
        ET.SubElement(initial, "Unknown", {"index": str(2 * n + i + 1)})
    return xml_text(root)


def output_description(info, output):
    """The description of the variable of a model output (`model.output` or an energy)."""
    unit = info.units.get(output)
    return f"model output {output}" + (f" [{unit}]" if unit else "") + \
        " (computed from the state; no directional derivative)"


def xml_text(root):
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"


def numbers_text(values, empty="0.0"):
    return ", ".join(number_text(v) for v in values) or empty
