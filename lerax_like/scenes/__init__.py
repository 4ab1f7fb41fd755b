"""Scenes: a physics module, an integrator and a task (spaces, reward, termination)."""

from .cartpole import (
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .acrobot import Acrobot as Acrobot
from .mountain_car import (
    AbstractMountainCar as AbstractMountainCar,
    MountainCar as MountainCar,
    MountainCarContinuous as MountainCarContinuous,
)
from .pendulum import Pendulum as Pendulum
