"""Direct collocation on the compiled equations: optimal motions and identification
(`Collocation`, solved with IPOPT; `CollocationResult`)."""
from .problem import Collocation  # noqa: F401
from .result import CollocationResult  # noqa: F401
