"""A solver (or any object) named on a command line as `module:attribute`, and why one failed.

`solver_from_spec` is what `lerax-like ... --solver` reads; `attribute_from_spec` is shared
with the scenes that `lerax-like study module:Class` names.
"""

import importlib
import linecache
import os
import traceback
from typing import Any

import diffrax

from ._presets import SOLVERS, solver_instance


def solver_from_spec(spec: str) -> "str | diffrax.AbstractSolver":
    """The solver a command line names: a preset name, or `module:attribute`.

    `module:attribute` imports `module` (from `sys.path`: `PYTHONPATH`, and the current
    directory, which the `lerax-like` command puts there) and takes `attribute`: a diffrax
    solver instance, or a solver class built with no arguments (`diffrax:Bosh3`,
    `my_methods:RALSTON3`). Returns the preset name (lower case) or the solver instance.
    A module or a solver that cannot be built (a Butcher tableau that fails diffrax's
    checks) is refused with a `ValueError` that names the module, the attribute and the
    failed check, before any solve.
    """
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"solver must be a preset name or 'module:attribute', got {spec!r}")
    if ":" not in spec:
        return SOLVERS.find(spec).name
    value = attribute_from_spec(spec, "solver")
    try:
        return solver_instance(value)
    except TypeError as error:
        raise ValueError(f"solver {spec!r}: {error}") from None
    except Exception as error:  # a solver class whose construction fails a check
        raise ValueError(f"solver {spec!r}: building it failed: {failed_check(error)}") from None


def attribute_from_spec(spec: str, what: str) -> Any:
    """The object `module:attribute` names, imported from `sys.path`; `ValueError` naming the failure."""
    module_name, _, attribute = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ValueError(f"{what} {spec!r}: cannot import module {module_name!r} ({error})") from None
    except Exception as error:  # the module's own code failed: a tableau's check, a typo
        raise ValueError(
            f"{what} {spec!r}: importing module {module_name!r} failed: {failed_check(error)}"
        ) from None
    value = module
    for part in attribute.split("."):
        try:
            value = getattr(value, part)
        except AttributeError:
            raise ValueError(f"{what} {spec!r}: module {module_name!r} has no attribute {attribute!r}") from None
    return value


# diffrax's `ButcherTableau` checks itself with bare asserts: what each one means.
_TABLEAU_CHECKS = {
    "sum(self.b_sol), 1.0": "the weights b_sol must sum to 1 (else the method is not even first order)",
    "sum(self.b_error), 0.0": "the error weights b_error must sum to 0",
    "sum(a_i) + diagonal, c_i": "each row of a_lower (with its diagonal) must sum to its node c",
    "sum(a_predictor_i), 1.0": "each row of a_predictor must sum to 1",
}


def failed_check(error: BaseException) -> str:
    """An exception in words: where the user's code raised it and, for a failed assert, which check."""
    frames = traceback.extract_tb(error.__traceback__)
    # The innermost frame outside the libraries (the user's line) and the innermost of all.
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

    def users(frame) -> bool:  # not a library's, not generated code's (`<string>`), not ours
        name = frame.filename
        return not (name.startswith("<") or "site-packages" in name or "importlib" in name
                    or os.path.abspath(name).startswith(package))

    user = next((f for f in reversed(frames) if users(f)), frames[-1] if frames else None)
    innermost = frames[-1] if frames else None
    where = "" if user is None else f" at {os.path.basename(user.filename)}:{user.lineno}"
    if isinstance(error, AssertionError) and not str(error) and innermost is not None:
        check = (innermost.line or linecache.getline(innermost.filename, innermost.lineno or 0)).strip()
        meaning = next((words for key, words in _TABLEAU_CHECKS.items() if key in check), None)
        owner = "diffrax's ButcherTableau" if "diffrax" in innermost.filename else os.path.basename(innermost.filename)
        text = f"{owner} check `{check}` failed{where}"
        return text + (f": {meaning}" if meaning else "")
    return f"{type(error).__name__}: {error}{where}"
