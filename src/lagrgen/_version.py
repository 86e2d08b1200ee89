"""lagrgen's version: a leaf module that every layer may import without loading anything else."""
__version__ = "0.2.0"
