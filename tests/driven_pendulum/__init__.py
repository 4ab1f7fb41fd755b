"""A scene whose vector field reads the time: a damped pendulum driven by `cos(2/3 t)`.

Added from outside the package as `tests/spring_mass` is (`physics.py`, `scene.py`,
registered with `lerax_like.register_scene`), so that every test parametrised over
`lerax_like.SCENES` covers a non-autonomous scene. `test_driven_pendulum.py` checks it
against SciPy, the drive read at the episode's time.
"""
