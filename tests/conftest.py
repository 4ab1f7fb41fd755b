"""Tests run in float64 with strict dtype promotion, as diffrax's own suite does."""

import functools
import gc
import importlib
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from packaging.requirements import Requirement

import lerax_like


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

# Python's cyclic garbage collector, run a hundred times less often: tracing a program makes
# hundreds of thousands of small objects, and with Python's default threshold (700) the
# collector took 12% of a gradient test's time (docs/testing.md). Cycles are still collected,
# and every module ends with a full collection (`_release_compiled_programs`).
gc.set_threshold(100_000, 50, 1000)

# XLA compiles the suite's programs with LLVM's optimisation level 0 and its older CPU fusion
# emitters, where the programs users run compile with XLA's defaults. Compiling is most of the
# suite's time, and this cuts it by about a third (docs/testing.md). The program JAX hands XLA
# is the same; its machine code differs, and so the rounding: every check has a tolerance
# above rounding but those that measure rounding or depend on its bits, which compile with
# XLA's defaults: `test_rollouts_unchanged` (`XLA_DEFAULTS`, per program)
# and the tests marked `xla_defaults` (each in a process of its own, `pytest_pyfunc_call`
# below). A second rounding also finds code that relies on bits being the same in two places
# (2298295). Set here, before JAX starts its CPU client, so that the xdist workers and the
# processes tests start (the command line, the notebooks) inherit it; a user's own XLA_FLAGS
# come after, and win. LERAX_LIKE_TEST_XLA=default runs the whole suite with XLA's defaults.
SUITE_XLA_FLAGS = ("--xla_backend_optimization_level=0", "--xla_cpu_use_fusion_emitters=false")
XLA_DEFAULTS = {"xla_backend_optimization_level": 3, "xla_cpu_use_fusion_emitters": True}
TEST_XLA = "LERAX_LIKE_TEST_XLA"
_XLA_FLAGS_BEFORE = os.environ.get("XLA_FLAGS")
# The flags the user gave (an xdist worker inherits the suite's from the process that started the run).
_USER_XLA_FLAGS = [flag for flag in (_XLA_FLAGS_BEFORE or "").split() if flag not in SUITE_XLA_FLAGS]
if os.environ.get(TEST_XLA) != "default":
    os.environ["XLA_FLAGS"] = " ".join([*SUITE_XLA_FLAGS, *_USER_XLA_FLAGS])

# Scenes that tests define, as a contributor would (`tests/<name>/scene.py`, which calls
# `lerax_like.register_scene`): imported here, before collection, so that every test
# parametrised over `lerax_like.SCENES` covers them with no line changed elsewhere.
TEST_SCENES = tuple(
    importlib.import_module(f"{path.parent.name}.scene")
    for path in sorted(pathlib.Path(__file__).parent.glob("*/scene.py"))
)


def tree_allclose(x, y, *, rtol=1e-12, atol=0.0) -> bool:
    """Whether two pytrees have the same structure and all leaves are close."""
    x_leaves, x_def = jax.tree.flatten(x)
    y_leaves, y_def = jax.tree.flatten(y)
    if x_def != y_def:
        return False
    return all(
        np.allclose(np.asarray(a), np.asarray(b), rtol=rtol, atol=atol) for a, b in zip(x_leaves, y_leaves)
    )


def relative_error(estimate, reference) -> float:
    estimate = np.asarray(estimate, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    return float(np.max(np.abs(estimate - reference)) / max(np.max(np.abs(reference)), 1e-300))


# Relative tolerance of a state against Gymnasium's, by id (the Gymnasium and SB3 layers'
# parity tests): Gymnasium's MountainCarContinuous keeps its state in float32, the other
# envs compute in float64.
STATE_RTOL = {
    "lerax_like/CartPole-v1": 1e-12,
    "lerax_like/Pendulum-v1": 1e-12,
    "lerax_like/Acrobot-v1": 1e-12,
    "lerax_like/MountainCar-v0": 1e-12,
    "lerax_like/MountainCarContinuous-v0": 1e-6,
}


class NoisyCartPole(lerax_like.CartPole):
    """CartPole seen through noise drawn with the observation's key: a stochastic scene
    (every built-in scene is deterministic; the layers' key paths are for scenes like this)."""

    stochastic = True

    def observation(self, state, *, key):
        return state.y + 1e-3 * jax.random.normal(key, state.y.shape)


@pytest.fixture
def noisy_cartpole() -> type[NoisyCartPole]:
    """`NoisyCartPole`, the class (construct it with the keywords a test needs)."""
    return NoisyCartPole


@pytest.fixture
def getkey():
    """A fresh PRNG key on each call, from a fixed seed: keys are never reused."""
    keys = iter(jax.random.split(jax.random.key(0), 10_000))
    return lambda: next(keys)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs when a module's tests are done.

    Each program XLA compiles for the CPU keeps memory mappings, and a test process keeps
    every program until it exits. One worker runs about half the suite, which is more than
    60,000 mappings: past Linux's `vm.max_map_count` (65,530) the next compile fails, a
    segfault or an abort inside XLA, and pytest-xdist hangs after replacing the worker. A
    module's programs are rarely reused by another, so the suite loses little by dropping
    them: measured, a worker now stays under 2,200 mappings (the suite took 1530 s, as before).

    One cache `jax.clear_caches` leaves: JAX 0.10's `api_util.donation_vector`, an
    `lru_cache` of 4096 entries keyed by the pytree structure of each jitted call. Equinox's
    `filter_jit` (diffrax's `diffeqsolve`) puts the call's static part in that structure, and
    there diffrax's root-finding closure holds a tracer of the trace that made it, with its
    whole jaxpr: about 25,000 objects kept for every hybrid env traced. A worker held 2.8
    million objects after `test_functional_api`, and every module's `gc.collect()` then took
    2.2 s. Cleared here as well.
    """
    yield
    jax.clear_caches()
    donation_vector = getattr(importlib.import_module("jax._src.api_util"), "donation_vector", None)
    if donation_vector is not None:
        donation_vector.cache_clear()
    gc.collect()


def unforced_run_against(env, y0, reference, *, steps=100, every=25, atol=1e-6):
    """Step `env` unforced from `y0`, comparing the state with `reference(y0, t)` every
    `every` steps, and return the last state and the impacts and stick-slip switches made.

    The frictional-contact scenes' check against their SciPy references (the walled cart-pole
    with friction, the rolling disk): each step must succeed, and the state stay within `atol`.
    The steps run in one `lax.scan`: one dispatch and one read back, not one per step.
    """

    @eqx.filter_jit
    def run(env, state):
        def step(state, _):
            state, info = env.evolve(state, jnp.zeros(1))
            return state, (state.y, info["solver_ok"], info["impacts"], info["switches"])

        return jax.lax.scan(step, state, None, length=steps)

    state = lerax_like.EnvState(y=jnp.asarray(y0), steps=jnp.zeros((), int))
    state, (ys, ok, impacts, switches) = run(env, state)
    failed = np.flatnonzero(~np.asarray(ok))
    assert failed.size == 0, f"steps {failed + 1} failed"
    for k in range(every, steps + 1, every):
        t = k * float(env.dt)
        np.testing.assert_allclose(np.asarray(ys[k - 1]), reference(y0, t), rtol=0, atol=atol, err_msg=f"t = {t}")
    return state, int(np.sum(impacts)), int(np.sum(switches))


def jacfwd_and_value(loss):
    """`jax.jacfwd` of `loss`, which returns `(value, aux)`, with `(value, aux)` as its auxiliary
    output: one forward-mode program gives the derivative and the value, so that, vmapped over
    a point and its shifted copies, it gives the central differences' values too."""

    def value_as_aux(*args):
        value, aux = loss(*args)
        return value, (value, aux)

    return jax.jacfwd(value_as_aux, has_aux=True)


def hybrid(name: str) -> bool:
    """Whether the registered scene `name` is hybrid (located impacts, stick-slip, a floor)."""
    return lerax_like.SCENES[name]().modes() is not None


def quick_unless_hybrid(name: str, *values, id: str | None = None):
    """A parameter of a test over scenes, marked `slow` where the scene is hybrid: its located
    events make the compiles the longest (5 to 10 s a case against 1 to 3), so the quick loop
    (`-m "not slow"`) runs the smooth scenes and CI runs every one."""
    return pytest.param(name, *values, marks=[pytest.mark.slow] if hybrid(name) else [], id=id)


__all__ = ["STATE_RTOL", "XLA_DEFAULTS", "hybrid", "jacfwd_and_value", "jnp", "quick_unless_hybrid", "relative_error", "tree_allclose", "unforced_run_against"]


# JAX's persistent compilation cache, shared by every process of one run. Most of the suite's
# time is XLA compiling (docs/testing.md), and much of it compiles a program that another
# module, or the other xdist worker, has compiled already: the same scene and solver stepped
# in many modules. `_release_compiled_programs` drops each module's programs (it must, for
# `vm.max_map_count`), so without this cache every later module compiles them again; with
# it, a program compiled once in the run is read back from disk (tracing and lowering are
# still paid, XLA's compile is not). The folder is the run's own, made by the process that
# starts the run (the controller under xdist), never the user's home, and removed when the
# run ends. It reaches the xdist workers in their `workerinput`, and the processes that tests
# start (the command line, the docs' scripts, nbmake's notebook kernels) through JAX's own
# variables, which JAX reads when it is imported.
COMPILATION_CACHE_SETTINGS = {
    # By default JAX keeps only programs that took a second or more to compile: a test
    # compiles hundreds of small ones, and they add up.
    "jax_persistent_cache_min_compile_time_secs": 0.0,
    # -1: every entry, however small, and no size chosen for us by the filesystem.
    "jax_persistent_cache_min_entry_size_bytes": -1,
}
NOTEBOOK_SETTINGS = "LERAX_LIKE_NOTEBOOKS"
SB3_LOGS = "SB3_LOGDIR"
_CACHE_INPUT = "lerax_like_compilation_cache_dir"
# The cache's folder, and the variables this run set with the values they had before.
_RUN_ENVIRONMENT = pytest.StashKey[tuple[str, dict[str, str | None]]]()


def _use_compilation_cache(folder: str) -> dict[str, str | None]:
    """Point this process, and those it starts, at `folder`; return the variables it replaced."""
    settings = {"jax_compilation_cache_dir": folder, **COMPILATION_CACHE_SETTINGS}
    replaced = {name.upper(): os.environ.get(name.upper()) for name in settings}
    for name, value in settings.items():
        os.environ[name.upper()] = str(value)
        # This process imported JAX (above) before the variables were set.
        jax.config.update(name, value)
    return replaced


def pytest_addoption(parser):
    parser.addoption(
        "--timings", metavar="FILE", type=pathlib.Path,
        help="append each test's wall and CPU seconds and JAX's compile seconds to FILE (JSON lines) "
        "and end with a table per module (tests/timings.py)",
    )


def pytest_configure(config):
    worker_input = getattr(config, "workerinput", None)
    if config.getoption("timings") is not None:
        # Imported only when asked for: test_ci_skips's probe runs copy this conftest alone.
        import timings  # tests/timings.py
        config.pluginmanager.register(
            timings.Timings(config.getoption("timings"), starts_the_run=worker_input is None), "lerax_like_timings"
        )
    if worker_input is not None:
        _use_compilation_cache(worker_input[_CACHE_INPUT])
    else:  # the process that starts the run: the controller under xdist, or the only process
        folder = tempfile.mkdtemp(prefix="lerax_like-tests-jax-cache-")
        replaced = _use_compilation_cache(folder)
        # nbmake's kernels run the notebooks with their small settings: the same code in
        # seconds, where their committed outputs are from the full settings and tests or
        # benchmarks check the claims at full size (each notebook names which). Set
        # LERAX_LIKE_NOTEBOOKS=full to run them in full.
        replaced[NOTEBOOK_SETTINGS] = os.environ.get(NOTEBOOK_SETTINGS)
        os.environ.setdefault(NOTEBOOK_SETTINGS, "small")
        # Stable-Baselines3's `learn` makes a log folder even when it logs to stdout only, in
        # the system's temporary folder by default (`SB3-<date and time>`, one a run, left
        # behind): here it is the run's own, removed with it.
        replaced[SB3_LOGS] = os.environ.get(SB3_LOGS)
        os.environ.setdefault(SB3_LOGS, os.path.join(folder, "sb3-logs"))
        config.stash[_RUN_ENVIRONMENT] = (folder, replaced)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    # pytest-xdist, in the controller, before it starts a worker.
    node.workerinput[_CACHE_INPUT] = node.config.stash[_RUN_ENVIRONMENT][0]


def pytest_unconfigure(config):
    if _XLA_FLAGS_BEFORE is None:
        os.environ.pop("XLA_FLAGS", None)
    else:
        os.environ["XLA_FLAGS"] = _XLA_FLAGS_BEFORE
    if _RUN_ENVIRONMENT not in config.stash:
        return
    folder, replaced = config.stash[_RUN_ENVIRONMENT]
    for name, value in replaced.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
    shutil.rmtree(folder, ignore_errors=True)


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """A test marked `xla_defaults` runs in a process of its own whose programs, the package's
    own `jax.jit`s included, compile with XLA's defaults (the suite's do not: `SUITE_XLA_FLAGS`).
    It passes only if that process ran it and it passed there."""
    if pyfuncitem.get_closest_marker("xla_defaults") is None or os.environ.get(TEST_XLA) == "default":
        return None
    environment = {**os.environ, TEST_XLA: "default", "XLA_FLAGS": " ".join(_USER_XLA_FLAGS)}
    # The run's own options are not the test's: `--timings=FILE` there would empty FILE.
    environment.pop("PYTEST_ADDOPTS", None)
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-o", "addopts=", "-q", "-rs", pyfuncitem.nodeid]
    run = subprocess.run(command, cwd=pyfuncitem.config.rootpath, env=environment, capture_output=True, text=True)
    summary = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else ""
    if run.returncode == 0 and re.fullmatch(r"=* ?1 skipped in .*", summary):
        pytest.skip(f"skipped with XLA's defaults, in its own process:\n{run.stdout[-2000:]}")
    if run.returncode != 0 or not re.fullmatch(r"=* ?1 passed(, \d+ warnings?)? in .*", summary):
        pytest.fail(
            f"with XLA's defaults, in its own process ({' '.join(command)}), exit status {run.returncode}:\n"
            f"{run.stdout[-8000:]}\n{run.stderr[-4000:]}",
            pytrace=False,
        )
    return True


def pytest_collection_modifyitems(config, items):
    # Every notebook run by nbmake trains, fits or studies something: all take more than
    # about 20 s on 2 cores, so all leave the quick loop (python -m pytest -m "not slow").
    # (Here rather than in notebooks/: a second module named conftest would shadow this
    # one for the tests' `from conftest import ...`; the top level is fixed.)
    for item in items:
        if item.path.suffix == ".ipynb":
            item.add_marker(pytest.mark.slow)


# CI installs the test extra; a test skipped there because something that extra installs
# is missing is a broken install, not a test that does not apply, and must fail. Elsewhere
# (a contributor without stable-baselines3, say) it stays a skip, and so does a skip for a
# dependency that the test extra leaves out (gymnax's pin on Gymnasium, say). The extra is
# read from pyproject.toml, so that adding a dependency there is all it takes. Two forms
# of skip are recognised, those the suite uses: pytest.importorskip's reason ("could not
# import 'scipy.linalg'"), whose top-level module must be a distribution's name (as
# scipy, stable_baselines3), and an install hint ("pip install -e '.[docs]'",
# "pip install matplotlib").
IMPORT_SKIP = re.compile(r"could not import '([\w.]+)'")
INSTALL_HINT = re.compile(r"pip install\s+([^);]*)")


def _normalised(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


class ExtraInstalls(NamedTuple):
    """What installing the package's `test` extra brings, by normalised name."""

    package: str
    distributions: frozenset[str]  # the package's own dependencies included
    extras: frozenset[str]  # `test` and the extras it includes


@functools.cache
def _test_extra(pyproject: pathlib.Path) -> ExtraInstalls:
    project = tomllib.loads(pyproject.read_text())["project"]
    package = _normalised(project["name"])
    optional = project.get("optional-dependencies", {})
    distributions = {_normalised(Requirement(line).name) for line in project.get("dependencies", [])}
    extras, pending = set(), ["test"]
    while pending:
        extra = _normalised(pending.pop())
        if extra in extras:
            continue
        extras.add(extra)
        for line in optional.get(extra, []):
            requirement = Requirement(line)
            if _normalised(requirement.name) == package:
                pending.extend(requirement.extras)
            else:
                distributions.add(_normalised(requirement.name))
    return ExtraInstalls(package, frozenset(distributions), frozenset(extras))


def _installed_by_the_test_extra(reason: str, test_extra: ExtraInstalls) -> bool:
    imported = IMPORT_SKIP.search(reason)
    if imported and _normalised(imported.group(1).split(".")[0]) in test_extra.distributions:
        return True
    hint = INSTALL_HINT.search(reason)
    for target in hint.group(1).split() if hint else ():
        target = target.strip("'\"")
        if not target or target.startswith("-"):
            continue
        name, _, wanted = target.partition("[")
        wanted = {_normalised(extra) for extra in wanted.rstrip("]").split(",") if extra.strip()}
        # "." (or the package's name) is the package, with the extras in its brackets.
        if name == "." or _normalised(name) == test_extra.package:
            if wanted <= test_extra.extras:
                return True
        elif _normalised(name) in test_extra.distributions:
            return True
    return False


def _in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def _fail_if_missing_from_the_test_extra(report, config):
    if not (report.skipped and _in_ci() and isinstance(report.longrepr, tuple)):
        return report
    reason = report.longrepr[2].removeprefix("Skipped: ")
    pyproject = config.rootpath / "pyproject.toml"
    if pyproject.is_file() and _installed_by_the_test_extra(reason, _test_extra(pyproject)):
        report.outcome = "failed"
        report.longrepr = f"CI is set, and the test extra (pyproject.toml) should have installed this: {reason}"
    return report


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector):
    # A module-level pytest.importorskip skips the whole module at collection.
    return _fail_if_missing_from_the_test_extra((yield), collector.config)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    return _fail_if_missing_from_the_test_extra((yield), item.config)
