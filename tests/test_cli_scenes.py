"""A user's scene on the command line: `lerax-like study mymod:MyScene`, as `--solver mod:attr`."""

import csv
import os
import re
import subprocess
import sys
import textwrap

import pytest

from lerax_like.cli import main


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# A user's module, written as docs/new_scene.md teaches: a damped oscillator and its task. Not
# registered by the module itself: the command line registers it.
USER_SCENE = textwrap.dedent(
    """
    import typing
    from typing import ClassVar

    import jax
    import equinox as eqx
    import jax.numpy as jnp

    import lerax_like as ll
    from lerax_like.env import episode_limit


    @typing.final
    class OscillatorDynamics(ll.AbstractConservativeDynamics):
        velocity_indices: ClassVar[tuple[int, ...]] = (1,)

        stiffness: jax.Array = eqx.field(default=4.0, converter=ll.POSITIVE)

        def vector_field(self, t, y, u):
            return jnp.stack([y[1], -self.stiffness * y[0] + u[0]])

        def energy(self, y):
            return 0.5 * y[1] ** 2 + 0.5 * self.stiffness * y[0] ** 2


    @typing.final
    class MyScene(ll.AbstractUnitActionEnv):
        \"\"\"Hold an oscillator at rest.

        ## Description
        A unit mass on a spring.

        ## Action Space
        `Box(-1, 1, (1,))`, a force of `force_mag * action`.

        ## Observation Space
        The state `[x, x_dot]`.

        ## Rewards
        `-min(x^2, 100)`.

        ## Starting State
        Uniform in `(-1, 1)`.

        ## Episode End
        Truncated after 100 steps.

        ## Arguments
        `stiffness`, `force_mag`, `dt`.
        \"\"\"

        stochastic: ClassVar[bool] = False
        action_size: ClassVar[int] = 1
        action_scale: ClassVar[str] = "force_mag"

        dynamics: OscillatorDynamics = eqx.field(default_factory=OscillatorDynamics)
        integrator: ll.Integrator = eqx.field(default="rk4", converter=ll.make_integrator)
        force_mag: jax.Array = eqx.field(default=1.0, converter=ll.POSITIVE)
        dt: jax.Array = eqx.field(default=0.05, converter=ll.POSITIVE)
        max_episode_steps: int | None = episode_limit(100)

        @property
        def initial_bounds(self):
            return -jnp.ones(2, self.dt.dtype), jnp.ones(2, self.dt.dtype)

        def reward(self, state, action, next_state, *, key):
            return -jnp.minimum(next_state.y[0] ** 2, 100.0)

        @property
        def worst_reward(self):
            return -100.0 * jnp.ones((), self.dt.dtype)
    """
)


@pytest.mark.slow
def test_the_command_studies_a_scene_from_the_working_directory(tmp_path):
    (tmp_path / "mymod.py").write_text(USER_SCENE)
    # `python -m lerax_like` from the user's folder: this checkout's package on PYTHONPATH, the
    # user's module found in the working directory only.
    environment = {**os.environ, "PYTHONPATH": ROOT, "JAX_PLATFORMS": "cpu"}
    completed = subprocess.run(
        [sys.executable, "-m", "lerax_like", "study", "mymod:MyScene", "--quick", "--no-plot",
         "--solver", "rk4", "--out", "out"],
        cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=900,
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    with open(tmp_path / "out" / "MyScene.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert rows and {row["scene"] for row in rows} == {"MyScene"} and all(row["solver_ok"] == "True" for row in rows)
    # RK4 on a harmonic oscillator: fourth order, fitted from the study's own steps.
    orders = [float(match) for match in re.findall(r"^\s*recorded rk4\s+order ([0-9.]+)", completed.stdout, re.M)]
    assert len(orders) == 1 and abs(orders[0] - 4) < 0.3, completed.stdout
    # Read on its own: the table's legend; and no progress bar into a pipe (no --no-progress above).
    assert "error: max-norm of the state error at the final time" in completed.stdout
    assert "seconds: the fastest of the repeats" in completed.stdout and "reference's floor" in completed.stdout
    assert "study MyScene" not in completed.stderr and "it/s" not in completed.stderr, completed.stderr[-2000:]


# gradient-variance: 6.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
@pytest.mark.parametrize("command", ["study", "gradients", pytest.param("gradient-variance", marks=pytest.mark.slow)])
def test_a_bad_scene_is_a_usage_error_that_names_it(command, capsys, tmp_path, monkeypatch):
    (tmp_path / "not_scenes.py").write_text("import math\nclass Plain:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for spec, words in [("NoSuchScene", "unknown scene 'NoSuchScene'"), ("no_such_module:X", "cannot import module"),
                        ("not_scenes:Missing", "has no attribute 'Missing'"),
                        ("not_scenes:Plain", "is not a scene class")]:
        with pytest.raises(SystemExit) as exit_info:
            main([command, spec, "--quick"])
        assert exit_info.value.code == 2
        error = capsys.readouterr().err
        assert f"lerax-like {command}:" in error and words in error, (spec, error)
