"""`python -m lagrgen show MODEL.py`: the equations of motion as text or LaTeX."""
from .arguments import (add_model_file, command_parser, is_urdf, models_in, read_urdf,
                        urdf_options)


def add(sub):
    s = command_parser(sub, "show", help="print the equations of motion (plain text or LaTeX)",
                       description="Print each model's equations of motion, one line per "
                       "coordinate: sum_j M_ij q_j'' = F_i, with q' and q'' for the velocities and "
                       "accelerations (LaTeX: \\dot{q}, \\ddot{q}); for a URDF file, the robot's "
                       "kinematic tree.",
                       example="python -m lagrgen show examples/double_pendulum.py --latex")
    add_model_file(s)
    s.add_argument("--latex", action="store_true", help="print LaTeX (an aligned environment)")
    s.add_argument("--matrices", action="store_true", help="also print M and F entry by entry")
    s.add_argument("--raw", action="store_true", help="skip the (cheap) trigonometric simplification")
    s.set_defaults(run=run)


def run(args):
    from ..outputs.display import render
    if is_urdf(args.model_file):
        from ..urdf import read, tree_text
        robot = read_urdf(args.model_file, read, check_inertias=args.check_inertias)
        print(tree_text(robot, args.base))
        return 0
    texts = [render(model, latex=args.latex, matrices=args.matrices, simplify=not args.raw)
             for model in models_in(args.model_file, args.model, urdf_options(args))]
    print("\n\n".join(texts))
    return 0
