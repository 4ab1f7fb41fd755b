"""Physics modules: parameters and a vector field, nothing else."""

from ._base import (
    AbstractConservativeDynamics as AbstractConservativeDynamics,
    AbstractDynamics as AbstractDynamics,
)
from .cartpole import CartPoleDynamics as CartPoleDynamics
from .chain import (
    CartChainDynamics as CartChainDynamics,
    NLinkPendulumDynamics as NLinkPendulumDynamics,
)
