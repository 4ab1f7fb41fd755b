"""The committed notebooks show what they compute: each draws a figure, kept with its outputs.

Every notebook under notebooks/ trains, fits or studies something (tests/conftest.py marks
them all slow for that reason), so every one must hold a figure in its committed outputs:
a reader of the rendered documentation (mkdocs-jupyter, `execute: false`) sees only those.
nbmake runs the notebooks themselves; these checks read the committed files only.
"""

import base64
import json
import pathlib
import struct

import pytest


NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _code_cells(path):
    return [cell for cell in json.loads(path.read_text())["cells"] if cell["cell_type"] == "code"]


def _png_sizes(path):
    """(width, height) in pixels of every PNG among the notebook's outputs."""
    sizes = []
    for cell in _code_cells(path):
        for output in cell.get("outputs", []):
            data = output.get("data", {}).get("image/png")
            if data is None:
                continue
            png = base64.b64decode("".join(data) if isinstance(data, list) else data)
            assert png.startswith(PNG_SIGNATURE), f"{path.name}: an image/png output that is not a PNG"
            # The IHDR chunk comes first: width and height are its first two big-endian words.
            sizes.append(struct.unpack(">II", png[16:24]))
    return sizes


def test_there_are_notebooks():
    assert NOTEBOOKS


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda path: path.stem)
def test_a_notebook_holds_a_figure_in_its_committed_outputs(path):
    sizes = _png_sizes(path)
    assert sizes, (
        f"{path.name} trains or studies but shows no figure: draw one (matplotlib, inline PNG) and commit "
        "the executed notebook (jupyter nbconvert --to notebook --execute --inplace)"
    )
    # A figure a reader can read, not an empty or thumbnail canvas.
    assert all(width >= 300 and height >= 150 for width, height in sizes), (path.name, sizes)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda path: path.stem)
def test_a_notebook_is_committed_from_one_run_top_to_bottom(path):
    cells = _code_cells(path)
    counts = [cell.get("execution_count") for cell in cells]
    # Outputs from one run in order (1, 2, 3, ...), none from an edit not re-executed.
    assert counts == list(range(1, len(cells) + 1)), (path.name, counts)
    errors = [output for cell in cells for output in cell.get("outputs", []) if output["output_type"] == "error"]
    assert not errors, (path.name, [error["ename"] for error in errors])
