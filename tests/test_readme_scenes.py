"""The README's scene table against `lerax_like.SCENES`: one row per scene of the package,
in the registry's order, each column read off the scene class, so that the table cannot
fall behind the registry."""

import dataclasses
import pathlib
import re

import gymnasium
import numpy as np
import pytest

import lerax_like as ll


README = pathlib.Path(__file__).resolve().parent.parent / "README.md"
PACKAGE_SCENES = {name: scene for name, scene in ll.SCENES.items() if scene.__module__.startswith("lerax_like.")}


def _table_rows() -> list[list[str]]:
    """The cells of each row of the first table under `## Scenes`."""
    section = README.read_text().split("\n## Scenes\n", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in section.splitlines() if line.startswith("|")]
    header, rule, *rows = lines
    assert header.split("|")[1].strip() == "scene" and set(rule) <= set("|-: ")
    return [[cell.strip() for cell in row.strip().strip("|").split("|")] for row in rows]


def _ticked(cell: str) -> str | None:
    """The first `code` span of a cell, or None."""
    match = re.search(r"`([^`]*)`", cell)
    return match.group(1) if match else None


def _space(space) -> str:
    if isinstance(space, ll.Discrete):
        return f"Discrete({space.n})"
    low, high = np.asarray(space.low), np.asarray(space.high)
    assert np.all(low == low.flat[0]) and np.all(high == high.flat[0]), "describe a box of mixed bounds by hand"
    return f"Box({low.flat[0]:g}, {high.flat[0]:g}, {space.shape})"


def _default_solver(scene) -> str:
    field = next(field for field in dataclasses.fields(scene) if field.name == "integrator")
    return f'"{field.default}"'


def _expected(name: str, scene) -> list[str]:
    env = scene()
    return [name, type(env.dynamics).__name__, _space(env.action_space), _default_solver(scene)]


def test_the_table_has_a_row_per_scene_in_the_registrys_order():
    names = [_ticked(row[0]) for row in _table_rows()]
    expected = [
        "| " + " | ".join(f"`{cell}`" for cell in _expected(name, scene)) + " | |"
        for name, scene in PACKAGE_SCENES.items()
        if name not in names
    ]
    assert names == list(PACKAGE_SCENES), "README.md's scene table, rows to add:\n" + "\n".join(expected)


@pytest.mark.parametrize("row", _table_rows(), ids=lambda row: _ticked(row[0]))
def test_each_row_reads_off_its_scene(row):
    name = _ticked(row[0])
    scene = PACKAGE_SCENES[name]
    physics, actions, solver = _expected(name, scene)[1:]
    assert _ticked(row[1]) == physics
    assert _ticked(row[2]) == actions
    assert _ticked(row[3]) == solver


def test_the_gymnasium_ids_are_those_registered():
    listed = [_ticked(row[4]) for row in _table_rows() if _ticked(row[4])]
    registered = sorted(env_id for env_id in gymnasium.registry if env_id.startswith("lerax_like/"))
    assert sorted(listed) == registered


@pytest.mark.slow
def test_each_gymnasium_id_stands_for_its_rows_scene():
    for row in _table_rows():
        env_id = _ticked(row[4])
        if env_id:
            env = gymnasium.make(env_id, disable_env_checker=True)
            assert type(env.unwrapped.scene) is PACKAGE_SCENES[_ticked(row[0])], env_id
            env.close()


@pytest.mark.slow  # 3.0 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_each_rows_dynamics_is_at_the_top_level():
    # The table shows `ll.<Dynamics>` beside `ll.<Scene>`: both must be there.
    for row in _table_rows():
        scene, dynamics = _ticked(row[0]), _ticked(row[1])
        assert getattr(ll, scene) is ll.SCENES[scene]
        assert dynamics in ll.__all__ and getattr(ll, dynamics) is type(ll.SCENES[scene]().dynamics), dynamics
