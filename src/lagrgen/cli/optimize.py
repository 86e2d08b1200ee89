"""`python -m lagrgen optimize PROBLEM.py`: solve the collocation problem a file defines."""
from ..errors import LagrgenError
from .arguments import command_parser, run_file


def add(sub):
    o = command_parser(
        sub, "optimize", help="solve an optimal-control or identification problem (collocation)",
        description="Run PROBLEM.py, a Python file that builds a lagrgen.Collocation at module "
        "level under the name `problem` (and optionally a starting point `guess`), solve it with "
        "IPOPT printing the solver's progress, and print the result: objective, duration, "
        "estimates with their standard errors, and the deviation of a re-simulation from the "
        "found inputs.",
        example="python -m lagrgen optimize examples/pendulum_swing_up.py --plot swing.png "
                "--animate swing.gif")
    o.add_argument("problem_file", help="a Python file defining `problem` (a Collocation)")
    o.add_argument("--hessian", choices=("exact", "quasi-newton"), default="exact",
                   help="exact second derivatives (default) or IPOPT's quasi-Newton update")
    o.add_argument("--tol", type=float, default=1e-8, help="IPOPT's tolerance (default 1e-8)")
    o.add_argument("--max-iter", type=int, default=3000, help="iteration limit (default 3000)")
    o.add_argument("--mesh-tol", type=mesh_tolerance, default=1e-6, metavar="TOL",
                   help="refine the mesh until the relative dynamics error is at most TOL "
                        "(default 1e-6); 'none' solves on the problem's grid alone")
    o.add_argument("--max-meshes", type=int, default=10,
                   help="the most meshes the refinement may use (default 10)")
    o.add_argument("--no-check", action="store_true",
                   help="skip the re-simulation from the found inputs")
    o.add_argument("--plot", metavar="OUT.png", help="plot states and inputs to this image")
    o.add_argument("--animate", metavar="OUT.gif",
                   help="write an animation of the mechanism (GIF, or MP4 with ffmpeg)")
    o.add_argument("--quiet", action="store_true", help="print only the result")
    o.set_defaults(run=run)


def mesh_tolerance(text):
    """--mesh-tol: a number, or "none"."""
    return None if text.strip().lower() == "none" else float(text)


def problem_in(path):
    """(problem, guess) defined at top level of the file `path`."""
    from ..collocation import Collocation
    namespace = run_file(path, "problem")
    problem = namespace.get("problem")
    if not isinstance(problem, Collocation):
        raise LagrgenError(f"{path} defines no `problem` (a lagrgen.Collocation at module level; "
                           f"got {type(problem).__name__ if problem is not None else 'nothing'})")
    return problem, namespace.get("guess")


def run(args):
    problem, guess = problem_in(args.problem_file)
    result = problem.solve(guess=guess, hessian=args.hessian, tol=args.tol,
                           max_iter=args.max_iter, progress=not args.quiet,
                           mesh_tol=args.mesh_tol, max_meshes=args.max_meshes)
    if args.quiet:
        print(result.summary())
    if not args.no_check and result.success:
        deviation = result.check()
        worst = max(deviation.by_state, key=deviation.by_state.get)
        print(deviation.message or f"re-simulated from the found inputs: largest deviation "
              f"{float(deviation):.3g} ({worst})")
    if args.plot:
        result.plot(args.plot)
        print(f"plot -> {args.plot}")
    if args.animate:
        result.animate(args.animate)
        print(f"animation -> {args.animate}")
    return 0 if result.success else 2
