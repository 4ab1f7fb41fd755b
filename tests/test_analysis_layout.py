"""Our own modules import with no deprecation warning (the old import paths of the studies and
gradient tools went: the CHANGELOG names each new place)."""

import subprocess
import sys

import pytest


@pytest.mark.slow  # 8.1 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_our_own_modules_import_with_no_deprecation_warning():
    # A fresh interpreter: a module imported earlier in this process would not warn again.
    code = (
        "import lerax_like, lerax_like.analysis, lerax_like.cli, lerax_like.gradients, "
        "lerax_like.analysis.gradient_variance, lerax_like.analysis.study, lerax_like.analysis.tables"
    )
    subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c", code], check=True)
