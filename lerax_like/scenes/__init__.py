"""Scenes: a physics module, an integrator and a task (spaces, reward, termination)."""

from .cartpole import (
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .van_der_pol import VanDerPol as VanDerPol
