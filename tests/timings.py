"""Where the suite's time goes: `python -m pytest --timings=FILE` (tests/conftest.py adds the option).

Each test process appends one JSON object a line to FILE per test: its wall and CPU seconds
(the CPU of this process only, not of the processes a test starts: nbmake's kernels, the
command line), the seconds XLA spent compiling the programs the test compiled and how many
(a program read from the persistent cache is counted as compiled, and as a cache hit, its
seconds those of reading it), and the seconds lowering them to XLA. The process that starts
the run empties FILE first and ends the run with a table per module (docs/testing.md).
"""

import collections
import json
import pathlib
import time

import pytest
from jax import monitoring


# JAX's names for what it measures (jax/_src/dispatch.py, jax/_src/compiler.py, JAX 0.10).
_COMPILE = "/jax/core/compile/backend_compile_duration"
_LOWER = "/jax/core/compile/jaxpr_to_mlir_module_duration"
_CACHE_HIT = "/jax/compilation_cache/cache_hits"


class Timings:
    """A pytest plugin: one per process, registered by tests/conftest.py when --timings is given."""

    def __init__(self, path: pathlib.Path, *, starts_the_run: bool):
        self.path = path
        self.starts_the_run = starts_the_run
        self.test = None  # the counts of the test running now, None between tests
        if starts_the_run:
            path.write_text("")
        monitoring.register_event_duration_secs_listener(self._duration)
        monitoring.register_event_listener(self._event)

    def _duration(self, event, seconds, **_):
        if self.test is not None and event in (_COMPILE, _LOWER):
            self.test[event] += seconds
            self.test[event + ":count"] += 1

    def _event(self, event, **_):
        if self.test is not None and event == _CACHE_HIT:
            self.test[event] += 1

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_protocol(self, item, nextitem):
        self.test = collections.Counter()
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            return (yield)
        finally:
            row = {
                "test": item.nodeid,
                "wall": time.perf_counter() - wall,
                "cpu": time.process_time() - cpu,
                "compile": self.test[_COMPILE],
                "compiled": self.test[_COMPILE + ":count"],
                "cache_hits": self.test[_CACHE_HIT],
                "lower": self.test[_LOWER],
            }
            self.test = None
            with self.path.open("a") as file:  # one short line a test: appends from two workers do not mix
                file.write(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()}) + "\n")

    def pytest_terminal_summary(self, terminalreporter):
        if not self.starts_the_run:
            return
        modules = collections.defaultdict(collections.Counter)
        for line in self.path.read_text().splitlines():
            row = json.loads(line)
            module = modules[row.pop("test").split("::")[0]]
            module["tests"] += 1
            module.update(row)
        columns = ("tests", "wall", "cpu", "compile", "compiled", "cache_hits", "lower")
        write = terminalreporter.write_line
        terminalreporter.section(f"time per module (--timings={self.path})")
        write(f"{'module':<52}" + "".join(f"{name:>11}" for name in columns))
        for name, module in sorted(modules.items(), key=lambda item: -item[1]["cpu"]):
            write(f"{name:<52}" + "".join(f"{module[c]:>11.0f}" for c in columns))
        total = sum(modules.values(), collections.Counter())
        write(f"{'all':<52}" + "".join(f"{total[c]:>11.0f}" for c in columns))
