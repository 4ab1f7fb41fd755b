"""jaxtyping aliases shared across the package."""

from jaxtyping import Array, ArrayLike, Bool, Float, Int, PRNGKeyArray

Scalar = Float[Array, ""]
ScalarLike = Float[ArrayLike, ""]
State = Float[Array, " n"]
Input = Float[Array, " m"]
Key = PRNGKeyArray
BoolScalar = Bool[Array, ""]
IntScalar = Int[Array, ""]

__all__ = [
    "Array",
    "ArrayLike",
    "Bool",
    "BoolScalar",
    "Float",
    "Input",
    "Int",
    "IntScalar",
    "Key",
    "Scalar",
    "ScalarLike",
    "State",
]
