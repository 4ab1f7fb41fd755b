"""Physics modules: parameters and a vector field, nothing else."""

from ._base import (
    AbstractConservativeDynamics as AbstractConservativeDynamics,
    AbstractDynamics as AbstractDynamics,
)
from .acrobot import AcrobotDynamics as AcrobotDynamics
from .cartpole import CartPoleDynamics as CartPoleDynamics
from .mountain_car import MountainCarDynamics as MountainCarDynamics
from .pendulum import PendulumDynamics as PendulumDynamics
