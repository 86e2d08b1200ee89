"""Issue 3's benchmark: the double pendulum and the 5-link pendulum on lagrgen's C and Python paths.

Per-call rhs and jacobian (from Python and inside C), cold and cached build, solve_ivp wall time with
nfev/njev/nlu. Prints a markdown table and writes benchmarks/results/compiled_path.{md,json}.

    python benchmarks/compiled_path.py [--quick]
"""
import argparse
import importlib.util
import json
import platform
import sys
from pathlib import Path

import numpy as np

import lagrgen
from lagrgen.bench import bench_model, markdown

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent / "examples"


def example(stem):
    """The module examples/<stem>.py, imported by path."""
    spec = importlib.util.spec_from_file_location(f"example_{stem}", EXAMPLES / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cases():
    """(label, make_model, y0): fresh models on every call so nothing is cached in memory."""
    nlink = example("nlink_pendulum")
    return [
        ("double pendulum", lambda: example("double_pendulum").model,
         np.array([0.5, 0.0, 0.0, 0.0])),
        ("5-link pendulum", lambda: nlink.make(5), np.concatenate([np.full(5, 0.5), np.zeros(5)])),
    ]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat, RK45 and Radau only")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 3
    header = (f"# lagrgen {lagrgen.__version__}: compiled vs pure-Python path\n\n"
              f"Python {platform.python_version()}, {platform.machine()}; t = 0..10 s, "
              "rtol = atol = 1e-8; medians of repeats (per-call: best of 5).\n")
    results, text = [], [header]
    for label, make, y0 in cases():
        result = bench_model(make, y0=y0, methods=("RK45", "Radau"), repeats=repeats)
        result["label"] = label
        results.append(result)
        text.append(markdown(result))
        print(text[-1], flush=True)
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "compiled_path.md").write_text("\n".join(text))
    (out / "compiled_path.json").write_text(json.dumps(results, indent=2))
    print(f"wrote {out / 'compiled_path.md'} and compiled_path.json", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
