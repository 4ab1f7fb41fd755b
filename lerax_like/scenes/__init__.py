"""Scenes: a physics module, an integrator and a task (spaces, reward, termination)."""

from .cartpole import (
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .double_cartpole import DoubleCartPole as DoubleCartPole
from .n_link_pendulum import NLinkPendulum as NLinkPendulum
