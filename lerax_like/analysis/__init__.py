"""Studies of the envs' numerics: gradient checks, gradient accuracy."""

from .gradcheck import GradCheckReport as GradCheckReport, LeafCheck as LeafCheck, gradcheck as gradcheck
