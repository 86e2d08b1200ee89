"""What a built model runs on: the compiled runtime, the Python backend, argument conversion and
the `BuiltModel` protocol. Nothing here imports SymPy, SciPy or the model description."""
