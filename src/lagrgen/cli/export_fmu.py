"""`python -m lagrgen export-fmu MODEL.py`: each model as an FMU (FMI 2.0 or 3.0, Model Exchange
or Co-Simulation)."""
from .arguments import (add_model_file, command_parser, models_in, parameters_option,
                        urdf_options)


def add(sub):
    from ..methods import NATIVE_METHODS
    e = command_parser(sub, "export-fmu", help="write each model as an FMU (FMI 2.0 or 3.0, Model "
                       "Exchange or Co-Simulation)",
                       description="Compile every model in MODEL.py into DIR/<name>.fmu, an FMU "
                       "for this platform (default: FMI 2.0 Model Exchange): states q and q' "
                       "(named like the coordinates and <coordinate>_dot), parameters (tunable, "
                       "starting at their defaults), inputs, the coordinates as outputs, "
                       "directional derivatives from the analytic Jacobian, and FMU states that "
                       "can be saved, restored and serialized. A Co-Simulation FMU (--kind cs) "
                       "steps itself with lagrgen's native engine; its method and tolerances are "
                       "the parameters solver.method, solver.rtol and solver.atol.",
                       example=("python -m lagrgen export-fmu examples/double_pendulum.py --out fmus",
                                "python -m lagrgen export-fmu examples/double_pendulum.py --kind cs "
                                "--method Radau --out fmus"))
    add_model_file(e)
    e.add_argument("--out", default=".", help="output directory (default: the current one)")
    e.add_argument("--kind", choices=("me", "cs"), default="me",
                   help="me: Model Exchange (the importer integrates); cs: Co-Simulation (the "
                   "FMU integrates with the native engine). Default me")
    e.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="FMI version (default 2)")
    e.add_argument("--method", choices=NATIVE_METHODS,
                   default="DOP853", help="co-simulation: the native engine's method (DOP853)")
    e.add_argument("--rtol", type=float, help="co-simulation: relative tolerance (default "
                   "--tolerance, or 1e-6)")
    e.add_argument("--atol", type=float, help="co-simulation: absolute tolerance (rtol/1000)")
    e.add_argument("--params", action="append", metavar="NAME=VALUE,...",
                   help="parameter start values in place of the defaults")
    e.add_argument("--start-time", type=float, default=0.0, help="DefaultExperiment start (0)")
    e.add_argument("--stop-time", type=float, default=10.0, help="DefaultExperiment stop (10)")
    e.add_argument("--tolerance", type=float, help="DefaultExperiment relative tolerance")
    e.add_argument("--quiet", action="store_true", help="print nothing but errors")
    e.set_defaults(run=run)


def run(args):
    from ..build import export_fmu
    from ..codegen.fmu import KIND_TITLES
    for model in models_in(args.model_file, args.model, urdf_options(args)):
        params = parameters_option(args, model)
        path = export_fmu(model, args.out, params=params, start_time=args.start_time,
                          stop_time=args.stop_time, tolerance=args.tolerance, kind=args.kind,
                          fmi_version=args.fmi_version, method=args.method, rtol=args.rtol,
                          atol=args.atol)
        if not args.quiet:
            print(f"{model.name}: FMI {args.fmi_version}.0 {KIND_TITLES[args.kind]} FMU -> {path}")
    return 0
