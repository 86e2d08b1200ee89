"""Builds lagrgen's compiled runtime (Cython, compiled once at install) and ships the C templates."""
import numpy
from Cython.Build import cythonize
from setuptools import Extension, find_packages, setup

TEMPLATES = "src/lagrgen/codegen/templates"

# Directories of C templates and FMI headers: data, not Python packages (no __init__.py), shipped whole.
TEMPLATE_PACKAGES = ["lagrgen.codegen.templates", "lagrgen.codegen.templates.functions",
                     "lagrgen.codegen.templates.fmi2", "lagrgen.codegen.templates.fmi3"]

runtime = Extension(
    "lagrgen.runtime._compiled",
    ["src/lagrgen/runtime/_compiled.pyx"],
    include_dirs=[numpy.get_include(), TEMPLATES],
    define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
    extra_compile_args=["-O2"],
)

# The native integration engine: lagrgen/native/lg_ode.c, a C port of SciPy's _ivp, and its wrapper.
native = Extension(
    "lagrgen.native._ode",
    ["src/lagrgen/native/_ode.pyx", "src/lagrgen/native/lg_ode.c",
     "src/lagrgen/native/lg_hybrid.c", "src/lagrgen/native/lg_sensitivity.c"],
    include_dirs=[numpy.get_include(), "src/lagrgen/native", TEMPLATES],
    define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
    extra_compile_args=["-O3", "-std=c99", "-fno-math-errno", "-fno-fast-math"],
)

# The collocation NLP's loops over points (lagrgen/collocation/_points.pyx).
collocation = Extension(
    "lagrgen.collocation._points",
    ["src/lagrgen/collocation/_points.pyx"],
    include_dirs=[numpy.get_include(), TEMPLATES],
    define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
    extra_compile_args=["-O2"],
)

# The stage-structured QP solver's Riccati recursion (lagrgen/collocation/_riccati.pyx).
riccati = Extension(
    "lagrgen.collocation._riccati",
    ["src/lagrgen/collocation/_riccati.pyx"],
    include_dirs=[numpy.get_include()],
    define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
    extra_compile_args=["-O3", "-fno-math-errno"],
)

setup(
    packages=find_packages("src") + TEMPLATE_PACKAGES,
    package_dir={"": "src"},
    package_data={"lagrgen.codegen.templates": ["*.in", "*.h"],
                  "lagrgen.codegen.templates.functions": ["*.c"],
                  "lagrgen.codegen.templates.fmi2": ["*.h", "*.txt"],
                  "lagrgen.codegen.templates.fmi3": ["*.h", "*.txt"],
                  "lagrgen.runtime": ["*.pxd"],
                  "lagrgen.native": ["*.c", "*.h", "*.pxd", "LICENSE.scipy", "README.md"],
                  "lagrgen.collocation": ["*.pyx"]},
    ext_modules=cythonize([runtime, native, collocation, riccati], compiler_directives={"language_level": "3"},
                          quiet=True, include_path=["src"]),
    zip_safe=False,
)
