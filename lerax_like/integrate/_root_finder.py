"""The root finders of the implicit presets, and the check for tolerances borrowed from a controller."""

import diffrax
import optimistix
# diffrax's marker for "take this tolerance from the step-size controller": diffrax (0.7)
# exports no public name for it, so this one import from a private module stays.
from diffrax._root_finder import use_stepsize_tol


def adaptive_root_finder() -> optimistix.Chord:
    """`optimistix.Chord` at the step-size controller's tolerances, for an adaptive step."""
    # With diffrax 0.7.2 and optimistix 0.1.0 the default VeryChord rejects about half
    # of Kvaerno5's steps on stiff problems; Chord with the controller's tolerances does not.
    return diffrax.with_stepsize_controller_tols(optimistix.Chord)()


def fixed_step_root_finder() -> optimistix.Chord:
    """`optimistix.Chord` with tolerances of its own (1e-6), for a constant step."""
    # A constant step size has no tolerances for the root finder to borrow, and diffrax
    # refuses to guess them; these are tight enough that the Newton error stays below the
    # truncation error of any fixed step worth taking, and loose enough for float32.
    return optimistix.Chord(rtol=1e-6, atol=1e-6, norm=optimistix.rms_norm)


def uses_controller_tolerances(solver: diffrax.AbstractSolver) -> bool:
    """Whether `solver`'s root finder takes its tolerances from the step-size controller."""
    root_finder = getattr(solver, "root_finder", None)
    return any(
        getattr(root_finder, name, None) is use_stepsize_tol for name in ("rtol", "atol", "norm")
    )
