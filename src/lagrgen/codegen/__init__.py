"""Code generation: printers (expressions → C or Python), then writers of whole files from the
kernels and the function registry, with the templates they fill in."""
