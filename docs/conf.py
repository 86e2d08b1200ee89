"""Sphinx configuration of lagrgen's manual: the user guide (MyST Markdown pages in guide/), the
API reference (api.rst, filled from `API` below with autodoc and numpydoc) and the gallery
(sphinx-gallery running examples/gallery/plot_*.py).

Build it from the repository's root:

    python -m sphinx -W -b html docs docs/_build/html

A page added to guide/ appears in the guide without an edit here: index.md's toctree holds the
glob `guide/*`, which `generated_parts` spells out as the pages of `GUIDE_ORDER` that exist, then
every other page of guide/ by name. A public name goes into the reference by one entry of `API`;
entries whose object does not exist (yet) are left out, so the list may name what a branch is
still adding.
"""
import importlib
import inspect
import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))          # the gallery's `from examples.four_bar import model`
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import lagrgen  # noqa: E402

project = "lagrgen"
author = "the lagrgen developers"
copyright = "the lagrgen developers"
release = version = lagrgen.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "gallery/*.ipynb", "gallery/*.py",
                    "gallery/*.zip", "gallery/*.md5", "gallery/*.json"]
templates_path = []
html_static_path = ["_static"]
html_theme = "furo"
html_title = f"lagrgen {release}"
default_role = "literal"              # `name` in docstrings and pages: code, as in the sources
nitpicky = False

myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples" / "gallery"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib", "gallery_figures"),
    "matplotlib_animations": False,
    "show_memory": False,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
}

#: The order of the guide's pages (file names in guide/ without .md); pages not named here follow
#: by name.
GUIDE_ORDER = ["model", "build", "running", "ensembles", "vibration", "stability", "constraints",
               "bodies3d", "robots", "sympy", "nonsmooth", "identification", "inertial",
               "optimization", "export", "notebooks", "outputs", "command_line", "speed"]


def guide_pages():
    """The guide's pages in reading order: those of GUIDE_ORDER, then the others by name."""
    found = sorted(p.stem for p in (DOCS / "guide").glob("*.md"))
    return [n for n in GUIDE_ORDER if n in found] + [n for n in found if n not in GUIDE_ORDER]


#: The API reference: (section title, entries). An entry names an object from `lagrgen`
#: (`"build"`, `"vibration.Modes"`, `"rotation"` for a module's public functions). An object that
#: does not exist is left out (see `existing`), so names of API.md that a branch is still adding
#: (`eigenvalue_sweep`, `Collocation`) appear once they exist, with no edit here.
API = [
    ("Describing a model", ["Model", "rotation", "from_sympy", "from_urdf", "base_state",
                            "urdf.URDFError"]),
    ("Building, loading, exporting", ["build", "load", "export_fmu",
                                      "runtime.protocol.BuiltModel"]),
    ("Running", ["simulate", "results.SimulationResult", "Signal", "evaluate_outputs",
                 "output_event", "consistent_state", "methods.Method",
                 "NearSingularMassMatrixWarning"]),
    ("Ensembles and sweeps", ["simulate_many", "EnsembleResult", "open_ensemble", "sweep",
                              "sweep.SweepResult"]),
    ("Vibration and stability", ["equilibrium", "linearize", "modes", "frequency_response",
                                 "eigenvalue_sweep", "vibration.Linearization", "vibration.Modes",
                                 "stability.EigenvalueSweep", "stability.Crossing",
                                 "FrozenTimeWarning", "UnstableModeWarning",
                                 "NotAnEquilibriumWarning"]),
    ("Identification", ["fit", "fit_modes", "fit.FitResult", "fit.ModalUpdate", "FitWarning",
                        "IdentifiabilityWarning"]),
    ("Inertial identification of robots", ["base_parameters", "identify_inertial",
                                           "exciting_trajectory", "inertial.BaseParameters",
                                           "inertial.InertialEstimate",
                                           "inertial.ExcitingTrajectory"]),
    ("Optimal motions", ["Collocation", "CollocationResult", "collocation.result.MeshRecord",
                         "collocation.refine.DiscretizationWarning"]),
    ("Exceptions", ["LagrgenError", "ModelError", "UnknownNameError", "BuildError", "CompileError",
                    "MassMatrixError", "ConstraintError", "NonFiniteError"]),
]


def resolve(entry):
    """The object `lagrgen.<entry>`, or None: a public name of the package's face, or a module of
    the package and a name in it (`"sweep.SweepResult"`: the module lagrgen.sweep, not the
    function lagrgen.sweep)."""
    module, _, name = entry.rpartition(".")
    try:
        owner = importlib.import_module(f"lagrgen.{module}") if module else lagrgen
    except ImportError:
        return None
    return getattr(owner, name, None)


def existing(entries):
    """The entries whose object exists in this checkout."""
    return [e for e in entries if resolve(e) is not None]


def directive(entry):
    """The autodoc directive documenting `lagrgen.<entry>`."""
    obj = resolve(entry)
    path = f"lagrgen.{entry}"
    if inspect.ismodule(obj):
        names = ", ".join(getattr(obj, "__all__", ()))
        return [f".. automodule:: {path}", f"   :members: {names}", ""]
    if inspect.isclass(obj):
        lines = [f".. autoclass:: {path}", "   :members:"]
        if entry == "Model":
            lines.append("   :inherited-members:")
        if issubclass(obj, BaseException):
            lines = [f".. autoexception:: {path}"]
        return lines + [""]
    return [f".. autofunction:: {path}", ""]


def api_reference():
    """The reStructuredText of the reference's sections, for the names that exist."""
    lines = []
    for title, entries in API:
        present = existing(entries)
        if not present:
            continue
        lines += [title, "-" * len(title), ""]
        for entry in present:
            lines += directive(entry)
    return "\n".join(lines)


def generated_parts(app, docname, source):
    """Spell out the guide's pages in index.md's toctree; add the sections of api.rst."""
    if docname == "index":
        source[0] = source[0].replace("\nguide/*\n", "".join(f"\nguide/{n}" for n in
                                                             guide_pages()) + "\n")
    if docname == "api":
        source[0] += "\n\n" + api_reference() + "\n"


def always_read(app, env, added, changed, removed):
    """The documents with generated parts are read again on every build (new pages, new names)."""
    return ["index", "api"]


def setup(app):
    app.connect("source-read", generated_parts)
    app.connect("env-get-outdated", always_read)
