"""The type check of CI: basedpyright (the `test` extra; its wheel carries Node, so it runs with no
network) over `lerax_like/` and `tests/typed_example.py`, a script typed as a user writes one.

No error is allowed anywhere (the 110 the package had when the check came in are all fixed, and
there is no baseline to hide one). The check must also fail where it should: a misspelt keyword
or a wrong type in a constructor call is an error.
"""

import json
import pathlib
import subprocess
import sys

import pytest


ROOT = pathlib.Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.slow  # one basedpyright run over the package: 40-110 s on 2 loaded cores

BAD = '''
import lerax_like as ll
ll.CartPoleDynamics(pole_mas=0.2)
ll.CartPoleDynamics(gravity="strong")
ll.Pendulum(integrator=3)
ll.CartPoleDynamics(gravty=9.8)
ll.CartPole(dynamics=ll.PendulumDynamics())
ll.physics.contact.Walls(restitutoin=0.5)
ll.physics.contact.Walls(restitution="hard")
ll.make_integrator("rk4", stepsize_controler=None)
ll.make_integrator("rk4", max_steps=1.5)
ll.Pendulum(max_sped=8.0)
ll.physics.contact.Walls(restitution=0.5, max_events=2.5)
ll.CartPoleContinuous(reward_kind="sparse")
Spring(force_mgn=2.0)
SpringDynamics(stiffness="stiff")
'''
# The bad lines above, each an error: misspelt or mistyped keywords of dynamics, add-ons, scenes
# and the integrator, and of a user's own scene (`tests/typed_example.py`, beside the bad file).
BAD_LINES = list(range(2, 16))


def test_the_package_and_the_typed_example_type_check_and_a_bad_call_does_not(tmp_path):
    pytest.importorskip("basedpyright")  # in the test extra: a failure in CI (conftest)
    # The bad calls after the typed example, whose own scene (`Spring`) they call.
    example = (ROOT / "tests" / "typed_example.py").read_text().split('if __name__ == "__main__":')[0]
    offset = example.count("\n")
    bad = tmp_path / "bad_call.py"
    bad.write_text(example + BAD)
    baseline = tmp_path / "baseline.json"  # none: an empty one, so that no stray baseline file hides an error
    baseline.write_text(json.dumps({"files": {}}))
    result = subprocess.run(
        [sys.executable, "-m", "basedpyright", "--outputjson", "--baselinefile", str(baseline),
         "lerax_like", "tests/typed_example.py", str(bad)],
        cwd=ROOT, capture_output=True, text=True, timeout=900,
    )
    report = json.loads(result.stdout)
    errors = [d for d in report["generalDiagnostics"] if d["severity"] == "error"]
    elsewhere = [f"{d['file']}:{d['range']['start']['line'] + 1}: {d['message']}" for d in errors if d["file"] != str(bad)]
    assert not elsewhere, "type errors:\n" + "\n".join(elsewhere)
    assert report["summary"]["filesAnalyzed"] > 50  # the package was read, not skipped
    found = sorted((d["range"]["start"]["line"] - offset, d["message"].splitlines()[0]) for d in errors if d["file"] == str(bad))
    assert sorted({line for line, _ in found}) == BAD_LINES, found
    assert 'No parameter named "pole_mas"' in found[0][1]
    for misspelt in ("gravty", "restitutoin", "stepsize_controler", "max_sped", "force_mgn"):
        assert any(f'No parameter named "{misspelt}"' in message for _, message in found), misspelt
