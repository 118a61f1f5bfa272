"""Exception types of the package beyond ``ValueError``/``TypeError`` for bad input."""


class MethodError(RuntimeError):
    """The method itself failed (a solver did not converge, no eligible set was found)."""
