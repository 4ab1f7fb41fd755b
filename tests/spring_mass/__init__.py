"""A scene added from outside the package, as a contributor adds one: a damped spring-mass.

Two files, `physics.py` (its dynamics) and `scene.py` (its task, registered with
`lerax_like.register_scene`), and no line changed anywhere else: `tests/conftest.py`
imports every `tests/*/scene.py` before collection, so the tests parametrised over
`lerax_like.SCENES` (the contract, bad input, failures) cover it as they cover the
package's own scenes. `test_spring_mass.py` checks its physics against the closed form.
"""
