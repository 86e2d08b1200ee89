"""The FMI 3.0 model description of an exported FMU (Model Exchange or Co-Simulation).

Same variables and value references as the FMI 2.0 FMU (see `fmu_core.c.in`), as Float64
variables (solver.method an enumeration); FMI 3.0 adds the independent variable `time` and, in
Model Exchange, the event indicators as variables `event.<name>`; a derivative names its state by
value reference. The C side is `templates/fmi3.c.in`; the shared variables in `fmi2.py`, building and zipping in `fmu.py`.
"""
from xml.etree import ElementTree as ET

from .._version import __version__
from .fmi2 import (method_items, number_text, output_description, source_file_names,
                   state_start_values, value_references, variable_names, xml_text)


def model_description_fmi3(info, token, start_values, start_time=0.0, stop_time=10.0,
                           tolerance=None, kind="me", solver=None):
    """The text of modelDescription.xml (FMI 3.0). `token` is the instantiation token; a
    co-simulation FMU's solver settings (`solver` = (method index, rtol, atol)) are tunable
    parameters."""
    name, q = info.name, info.coordinates
    n, names = len(q), variable_names(info, reserved=("time",))
    vr = value_references(info)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": name, "instantiationToken": token,
        "description": f"{name}: M(q, t)·q'' = F(q, q', t, u), states q and q'",
        "generationTool": f"lagrgen {__version__}", "variableNamingConvention": "flat"})
    common = {"modelIdentifier": name, "canGetAndSetFMUState": "true",
              "canSerializeFMUState": "true", "providesDirectionalDerivatives": "true"}
    if kind == "me":
        ET.SubElement(root, "ModelExchange", {**common, "needsCompletedIntegratorStep": "false"})
    else:
        ET.SubElement(root, "CoSimulation", {
            **common, "canHandleVariableCommunicationStepSize": "true",
            "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
            "providesIntermediateUpdate": "false", "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0"})
        types = ET.SubElement(root, "TypeDefinitions")
        enumeration = ET.SubElement(types, "EnumerationType", {
            "name": "lagrgen.Method", "description": "the native engine's integration method"})
        for item, value, what in method_items():
            ET.SubElement(enumeration, "Item", {"name": item, "value": str(value),
                                                "description": what})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError", "description": "errors"})
    experiment = {"startTime": number_text(start_time), "stopTime": number_text(stop_time)}
    if tolerance is not None:
        experiment["tolerance"] = number_text(tolerance)
    ET.SubElement(root, "DefaultExperiment", experiment)
    variables = ET.SubElement(root, "ModelVariables")

    def variable(ref, attributes, description, name=None, type_="Float64"):
        ET.SubElement(variables, type_, {"name": name or names[ref], "valueReference": str(ref),
                                         "description": description, **attributes})

    variable(vr["time"], {"causality": "independent", "variability": "continuous"},
             "simulation time", name="time")
    start = state_start_values(info)
    for i, c in enumerate(q):
        variable(i, {"causality": "output", "variability": "continuous", "initial": "exact",
                     "start": number_text(start[i])}, f"coordinate {c} (a state)")
    for i, c in enumerate(q):
        variable(n + i, {"causality": "local", "variability": "continuous", "initial": "exact",
                         "start": number_text(start[n + i])}, f"rate of {c} (a state)")
    for i in range(2 * n):
        variable(2 * n + i, {"causality": "local", "variability": "continuous",
                             "initial": "calculated", "derivative": str(i)},
                 f"time derivative of {names[i]}")
    base = 4 * n
    for j, (p, value) in enumerate(zip(info.parameters, start_values)):
        variable(base + j, {"causality": "parameter", "variability": "tunable",
                            "start": number_text(value)}, f"parameter {p}")
    base += len(info.parameters)
    for k, u in enumerate(info.inputs):
        variable(base + k, {"causality": "input", "variability": "continuous", "start": "0.0"},
                 f"input {u}")
    if kind == "me":
        for k, (event, _, _) in enumerate(info.event_definitions):
            variable(vr["events"] + k, {"causality": "local", "variability": "continuous"},
                     f"event indicator: the function of the event {event} (a terminal "
                     "event's crossings end the simulation)", name=f"event.{event}")
    if kind == "cs":
        method, rtol, atol = solver
        tunable = {"causality": "parameter", "variability": "tunable"}
        variable(vr["solver.rtol"], {**tunable, "start": number_text(rtol)},
                 "relative tolerance of the native engine (the experiment's tolerance, when "
                 "the importer gives one, replaces it)", name="solver.rtol")
        variable(vr["solver.atol"], {**tunable, "start": number_text(atol)},
                 "absolute tolerance of the native engine", name="solver.atol")
        variable(vr["solver.method"], {**tunable, "declaredType": "lagrgen.Method",
                                       "start": str(method)},
                 "integration method of the native engine", name="solver.method",
                 type_="Enumeration")
    for k, output in enumerate(info.output_names):
        variable(vr["outputs"] + k, {"causality": "local", "variability": "continuous",
                                     "initial": "calculated"}, output_description(info, output),
                 name=output)
    structure = ET.SubElement(root, "ModelStructure")
    for i in range(n):
        ET.SubElement(structure, "Output", {"valueReference": str(i)})
    if kind == "me":     # a co-simulation FMU's states are internal: no derivatives listed
        for element in ("ContinuousStateDerivative", "InitialUnknown"):
            for i in range(2 * n):
                ET.SubElement(structure, element, {"valueReference": str(2 * n + i)})
        for k in range(len(info.event_definitions)):
            ET.SubElement(structure, "EventIndicator", {"valueReference": str(vr["events"] + k)})
    return xml_text(root)



def build_description(name, kind):
    """The text of sources/buildDescription.xml: the C files that rebuild the FMU (the glue
    includes the model and the FMU core; a co-simulation FMU adds the native engine)."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    files = ET.SubElement(ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": name}),
                          "SourceFileSet", {"language": "C99"})
    for file_name in source_file_names(name, kind):
        ET.SubElement(files, "SourceFile", {"name": file_name})
    return xml_text(root)
