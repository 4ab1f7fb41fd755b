"""Physics modules: parameters and a vector field, nothing else."""

from ._base import (
    AbstractChainDynamics as AbstractChainDynamics,
    AbstractConservativeDynamics as AbstractConservativeDynamics,
    AbstractDynamics as AbstractDynamics,
)
from .acrobot import AcrobotDynamics as AcrobotDynamics
from .cartpole import CartPoleDynamics as CartPoleDynamics
from .mountain_car import MountainCarDynamics as MountainCarDynamics
from .pendulum import PendulumDynamics as PendulumDynamics
from .planar_quadrotor import PlanarQuadrotorDynamics as PlanarQuadrotorDynamics
from .van_der_pol import VanDerPolDynamics as VanDerPolDynamics
from .chain import (
    CartChainDynamics as CartChainDynamics,
    NLinkPendulumDynamics as NLinkPendulumDynamics,
)
from .forces import (
    AbstractGeneralisedForce as AbstractGeneralisedForce,
    EndStops as EndStops,
    ForcedDynamics as ForcedDynamics,
    JointDamping as JointDamping,
)
from .contact import (
    AbstractContact as AbstractContact,
    AbstractImpulseContact as AbstractImpulseContact,
    Walls as Walls,
)
from .ball import BallDynamics as BallDynamics, FloorAndWall as FloorAndWall
from .rimless_wheel import RimlessWheelDynamics as RimlessWheelDynamics, SpokeContact as SpokeContact
from .walker import AbstractWalkerDynamics as AbstractWalkerDynamics, HeelStrike as HeelStrike
from .simplest_walker import SimplestWalkerDynamics as SimplestWalkerDynamics
from .compass_gait import CompassGaitDynamics as CompassGaitDynamics
from .friction import (
    AbstractCoulombFriction as AbstractCoulombFriction,
    CartFriction as CartFriction,
    PlaneFriction as PlaneFriction,
)
from .sliding_block import SlidingBlockDynamics as SlidingBlockDynamics
from .rolling_disk import DiskFloor as DiskFloor, RollingDiskDynamics as RollingDiskDynamics
