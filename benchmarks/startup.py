"""Start-up times (medians): importing a compiled model against `import numpy`, `python -m lagrgen
build` of an unchanged model and `python -m lagrgen --help`, each in fresh processes (issue 9); and
a cached build in process of the 20-link pendulum described anew (issue 19: a hit derives nothing).

    python benchmarks/startup.py [--repeats 9]

Prints a table and writes it to benchmarks/results/startup.md.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MODEL_FILE = ROOT / "examples" / "double_pendulum.py"
RESULTS = ROOT / "benchmarks" / "results" / "startup.md"


def seconds(cmd, repeats):
    """Median wall time of `cmd` run `repeats` times in fresh processes."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure(repeats):
    """Rows of (figure, seconds, target description, met)."""
    py = sys.executable
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([py, "-m", "lagrgen", "build", str(MODEL_FILE), "--out", out, "--quiet"],
                       check=True)
        numpy_s = seconds([py, "-c", "import numpy"], repeats)
        model_s = seconds([py, "-c", f"import sys; sys.path.insert(0, {out!r}); "
                           "import double_pendulum"], repeats)
        build_s = seconds([py, "-m", "lagrgen", "build", str(MODEL_FILE), "--out", out, "--quiet"],
                          repeats)
        help_s = seconds([py, "-m", "lagrgen", "--help"], repeats)
        cached_s = cached_build_seconds(out, repeats)
    return [
        ("python -c 'import numpy'", numpy_s, "reference", True),
        ("import a compiled model (double_pendulum)", model_s,
         f"≤ 1.5 × numpy = {1.5 * numpy_s:.3f} s ({model_s / numpy_s:.2f}×)", model_s <= 1.5 * numpy_s),
        ("python -m lagrgen build (unchanged model)", build_s, "≤ 0.5 s", build_s <= 0.5),
        ("python -m lagrgen --help", help_s, "≤ 0.3 s", help_s <= 0.3),
        ("cached build in process, 20-link pendulum (a new equal Model)", cached_s, "≤ 0.020 s",
         cached_s <= 0.020),
    ]


def cached_build_seconds(out, repeats, n=20):
    """Median time of `lagrgen.build` of a freshly described, unchanged n-link pendulum whose
    build is cached in `out` (the Model is made before the clock starts)."""
    sys.path.insert(0, str(ROOT / "examples"))
    import lagrgen
    from nlink_pendulum import make
    lagrgen.build(make(n), out_dir=out, quiet=True)
    times = []
    for _ in range(repeats):
        model = make(n)
        start = time.perf_counter()
        module = lagrgen.build(model, out_dir=out, quiet=True)
        times.append(time.perf_counter() - start)
        assert module.build_info["cache_hit"]
    return statistics.median(times)


def markdown(rows, repeats):
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [f"Start-up (fresh processes, median of {repeats}; load average {load:.2f}; "
             f"Python {sys.version.split()[0]})", "",
             "| figure | seconds | target | met |", "|---|---|---|---|"]
    lines += [f"| {name} | {s:.3f} | {target} | {'yes' if ok else 'NO'} |"
              for name, s, target, ok in rows]
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()
    table = markdown(measure(args.repeats), args.repeats)
    print(table)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(table)


if __name__ == "__main__":
    main()
