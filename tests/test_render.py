"""A picture of every registered scene, and the Gymnasium ids of the scenes that stand for no Gymnasium env.

Every scene of `lerax_like.SCENES` (a test's or a contributor's included) must have a
renderer (`lerax_like.gym.RENDERERS`): a scene without one fails here, by name. The
pictures are checked against the geometry they show (where a rod's tip is, which way
the ball moves), not against stored frames; the ids with Gymnasium's own `check_env`.
"""

import os
import pathlib

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lerax_like
from lerax_like.gym import SPECS, render_frame


os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # the human mode's window, on no screen
OWN_IDS = tuple(env_id for env_id, spec in SPECS.items() if not spec.stands_for_gymnasium)


def two_states(scene) -> tuple[np.ndarray, np.ndarray]:
    """The middle of the scene's starts, and that state with every coordinate moved by 0.3."""
    low, high = (np.asarray(bound, dtype=np.float64) for bound in scene.initial_bounds)
    middle = (low + high) / 2
    return middle, middle + 0.3


def colour_pixels(frame: np.ndarray, colour) -> tuple[np.ndarray, np.ndarray]:
    """The rows and columns of the pixels of exactly `colour`."""
    return np.nonzero(np.all(frame == np.asarray(colour, dtype=np.uint8), axis=-1))


@pytest.mark.parametrize("name", tuple(lerax_like.SCENES))
def test_every_scene_is_drawn_and_its_picture_changes_with_its_state(name):
    scene = lerax_like.SCENES[name]()
    first, second = two_states(scene)
    frame = render_frame(scene, first)  # a scene without a renderer fails here, by name
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 2  # something drawn on the background
    np.testing.assert_array_equal(render_frame(scene, first), frame)  # one state, one picture
    moved = render_frame(scene, second)
    assert moved.shape == frame.shape and np.count_nonzero(np.any(moved != frame, axis=-1)) > 50


def test_a_scene_without_a_renderer_is_refused_by_name(monkeypatch):
    from lerax_like.gym import _renderers

    monkeypatch.delitem(_renderers._RENDERERS, lerax_like.VanDerPolDynamics)
    with pytest.raises(LookupError, match=r"no renderer draws scene VanDerPol \(dynamics VanDerPolDynamics\).*register_renderer"):
        render_frame(lerax_like.SCENES["VanDerPol"](), np.zeros(2))


def test_a_renderer_must_return_an_rgb_array(monkeypatch):
    from lerax_like.gym import _renderers

    monkeypatch.setitem(_renderers._RENDERERS, lerax_like.VanDerPolDynamics, lambda scene, state, action: np.zeros((4, 4)))
    with pytest.raises(TypeError, match=r"renderer of VanDerPol must return an \(height, width, 3\) uint8 array"):
        render_frame(lerax_like.SCENES["VanDerPol"](), np.zeros(2))


def test_a_chain_is_drawn_where_its_rods_reach():
    # Three rods of 1 m, all at +pi/2 from upright: level, to the right of the pivot, 3 m
    # long. The view is the square of half-width 3.2 m in 400 rows: 62.5 px per metre,
    # the pivot in the middle, rods 10 px wide with round ends.
    scene = lerax_like.SCENES["NLinkPendulum"]()
    frame = render_frame(scene, np.concatenate([np.full(3, np.pi / 2), np.zeros(3)]))
    rows, columns = colour_pixels(frame, (202, 152, 101))
    height, width = frame.shape[:2]
    assert columns.min() >= width / 2 - 5 and abs(columns.max() + 1 - (width / 2 + 3 * 62.5 + 5)) <= 1
    assert abs(rows.min() - (height / 2 - 5)) <= 1 and abs(rows.max() + 1 - (height / 2 + 5)) <= 1


def test_the_ball_moves_in_its_picture_as_it_moves():
    # The ball's pixels shift right in proportion to its x, and up with its z, by the same scale.
    scene = lerax_like.SCENES["BouncingBall"]()
    centres = []
    for x, z in [(0.0, 1.0), (0.25, 1.0), (0.5, 1.0), (0.0, 1.5)]:
        rows, columns = colour_pixels(render_frame(scene, np.array([x, z, 0.0, 0.0])), (129, 132, 203))
        centres.append((columns.mean(), rows.mean()))
    (c0, r0), (c1, r1), (c2, r2), (c3, r3) = centres
    scale = (c2 - c0) / 0.5
    assert scale > 50 and abs((c1 - c0) - 0.25 * scale) < 0.5 and abs(r1 - r0) < 0.5
    assert abs((r0 - r3) - 0.5 * scale) < 0.5 and abs(c3 - c0) < 0.5  # rows grow downwards


def _direction(frame: np.ndarray, colour, pivot) -> float:
    """The angle (degrees, clockwise from up) from `pivot` (column, row) to the centroid of `colour`'s pixels."""
    rows, columns = colour_pixels(frame, colour)
    return float(np.degrees(np.arctan2(columns.mean() - pivot[0], pivot[1] - rows.mean())))


def _centre(frame: np.ndarray, colour=None) -> tuple[float, float]:
    if colour is None:
        return frame.shape[1] / 2, frame.shape[0] / 2
    rows, columns = colour_pixels(frame, colour)
    return columns.mean() + 0.5, rows.mean() + 0.5


# Gymnasium's own pictures: the rods' colour and where the pivot is (the axle's colour, or the middle).
GYMNASIUMS_RODS = {
    "CartPole": ((202, 152, 101), (129, 132, 203), [np.array([0.3, 0.0, 0.5, 0.0]), np.array([-0.5, 0.0, -1.2, 0.0])]),
    "Pendulum": ((204, 77, 77), None, [np.array([0.6, 0.0]), np.array([-2.3, 0.0])]),
    "Acrobot": ((0, 204, 204), None, [np.array([0.7, 0.9, 0.0, 0.0]), np.array([-2.0, 0.5, 0.0, 0.0])]),
}


@pytest.mark.parametrize("name", tuple(GYMNASIUMS_RODS))
def test_the_classic_scenes_point_their_rods_as_gymnasiums_pictures_do(name):
    # Our pictures of the scenes standing for Gymnasium's envs against Gymnasium's own, on the
    # same states: the rods point the same way from their pivot (the sign conventions).
    pytest.importorskip("pygame")
    colour, axle, states = GYMNASIUMS_RODS[name]
    reference = gymnasium.make(SPECS[f"lerax_like/{name}-v1"].name, render_mode="rgb_array").unwrapped
    reference.reset(seed=0)
    scene = lerax_like.SCENES[name]()
    for state in states:
        reference.state = state.copy()
        theirs, ours = reference.render(), render_frame(scene, state)
        expected = _direction(theirs, colour, _centre(theirs, axle))
        got = _direction(ours, (202, 152, 101), _centre(ours, None if axle is None else (129, 132, 203)))
        assert abs((got - expected + 180) % 360 - 180) < 3.0, (name, state, got, expected)
    reference.close()


def test_the_documentation_shows_every_scene_of_the_package():
    # docs/scenes.md shows an animation of every scene of the package (docs/scene_pictures.py writes them).
    root = pathlib.Path(__file__).resolve().parents[1]
    page = (root / "docs" / "scenes.md").read_text()
    for name, scene in lerax_like.SCENES.items():
        if scene.__module__.startswith("lerax_like."):
            image = f"images/scenes/{name}.gif"
            assert f"]({image})" in page and (root / "docs" / image).is_file(), name


@pytest.mark.slow
@pytest.mark.parametrize("env_id", OWN_IDS)
def test_every_new_id_passes_gymnasiums_check_env(env_id):
    env = gymnasium.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped)
    assert env.spec.max_episode_steps == SPECS[env_id].scene().max_episode_steps
    # A frame after a seeded reset is the picture of the env's state.
    env.reset(seed=3)
    np.testing.assert_array_equal(env.render(), render_frame(env.unwrapped.scene, env.unwrapped.state))
    env.close()


@pytest.mark.slow  # 2.5 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_a_new_id_renders_in_every_mode_of_its_vector_env_and_in_human():
    pytest.importorskip("pygame")
    env_id = "lerax_like/VanDerPol-v0"
    vector = gymnasium.make_vec(env_id, 3, render_mode="rgb_array")
    vector.reset(seed=0)
    vector.step(np.full((3, 1), 0.5))
    frames = vector.render()
    assert len(frames) == 3
    for index, frame in enumerate(frames):
        np.testing.assert_array_equal(frame, render_frame(vector.scene, vector.state[:, index], np.array([0.5])))
    vector.close()
    human = gymnasium.make(env_id, render_mode="human")
    human.reset(seed=0)
    human.step(np.array([0.5]))
    import pygame

    window = np.transpose(pygame.surfarray.array3d(pygame.display.get_surface()), (1, 0, 2))
    np.testing.assert_array_equal(window, render_frame(human.unwrapped.scene, human.unwrapped.state, np.array([0.5])))
    assert human.render() is None
    human.close()


def test_an_array_needs_no_pygame_and_a_window_hints_the_extra(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pygame", None)  # makes `import pygame` fail
    env = gymnasium.make("lerax_like/VanDerPol-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().shape == (400, 600, 3)
    human = gymnasium.make("lerax_like/VanDerPol-v0", render_mode="human")
    with pytest.raises(gymnasium.error.DependencyNotInstalled, match=r"lerax_like\[render\]"):
        human.reset(seed=0)
