"""Where a compiled model's units compiled on first use come from.

A built model's module holds what running it needs (`lagrgen.functions.MODEL_UNIT`); a function
of another unit (the parameter Jacobian, the directional derivatives, ...) is compiled the first
time it is called, into its own module, by the build stage (`lagrgen.units`), which registers its
provider here when imported. The runtime asks for a unit by the model's module file and label;
when no provider is registered yet (a model module imported by itself, `import <name>`), the build
stage is imported by name: the one late binding of the runtime, as a model module's own glue
imports `lagrgen.runtime._compiled` by name.
"""
import importlib
import threading

#: The module that provides units (and registers itself here on import).
PROVIDER = "lagrgen.units"
#: Held while a unit is being looked up or made, so that threads make each unit once.
LOCK = threading.RLock()
_provider = None


def register(provider):
    """Make `provider(model_file, info, label)` (returns the unit's module) the source of units."""
    global _provider
    _provider = provider


def unit_module(model_file, info, label):
    """The module of the unit `label` of the compiled model whose module file is `model_file` and
    whose `ModelInfo` is `info` (compiled on first use)."""
    if _provider is None:
        importlib.import_module(PROVIDER)
    return _provider(model_file, info, label)
