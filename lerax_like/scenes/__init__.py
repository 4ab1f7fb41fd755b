"""Scenes: a physics module, an integrator and a task (spaces, reward, termination)."""

from .cartpole import (
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .pendulum import Pendulum as Pendulum
