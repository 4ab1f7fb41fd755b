"""One small picture per physics: a function `(scene, state, action) -> (height, width, 3) uint8`.

Each draws the state in the scene's own layout (NumPy float64) on a `Canvas`, with the
colours of Gymnasium's classic-control pictures where it has one of the kind (a black
cart, wooden poles, blue joints). `action` is the env's last action (None after a
reset), drawn where it is a visible force. They read the scene's parameters (lengths,
the slope, the wall) at every frame, so a scene whose parameters change is drawn as it is.
`lerax_like.gym.RENDERERS` says which scene or dynamics class each draws.
"""

import math
from typing import TYPE_CHECKING, cast

import numpy as np

from ..env import AbstractEnv
from ..physics.ball import FloorAndWall
from ._canvas import Canvas

if TYPE_CHECKING:  # for the casts below only: each picture reads its own scene's fields
    from ..physics import (
        AcrobotDynamics,
        CartChainDynamics,
        CartPoleDynamics,
        CompassGaitDynamics,
        NLinkPendulumDynamics,
        PendulumDynamics,
        PlanarQuadrotorDynamics,
        RimlessWheelDynamics,
        SimplestWalkerDynamics,
        RollingDiskDynamics,
        SlidingBlockDynamics,
    )
    from ..scenes.bouncing_ball import BouncingBall
    from ..scenes.mountain_car import AbstractMountainCar


CART: tuple[int, int, int] = (0, 0, 0)
ROD = (202, 152, 101)
JOINT = (129, 132, 203)
GROUND = (0, 0, 0)
FAINT = (200, 200, 200)
FORCE = (214, 39, 40)
TARGET = (44, 160, 44)
BODY = (60, 60, 60)

ROD_WIDTH = 10.0  # pixels, Gymnasium's pole width
JOINT_RADIUS = 5.0


def value(leaf) -> float:
    """A scalar parameter of a scene as a Python float."""
    return float(np.asarray(leaf))


def values(leaf) -> np.ndarray:
    return np.asarray(leaf, dtype=np.float64)


def chain(canvas: Canvas, start: tuple[float, float], angles, lengths) -> None:
    """Rods hinged end to end from `start`, each at its absolute angle from upright
    (positive towards +x), as `AbstractChainDynamics` measures them."""
    point = np.asarray(start, dtype=np.float64)
    joints = [point]
    for angle, length in zip(angles, lengths, strict=True):
        point = point + length * np.array([math.sin(angle), math.cos(angle)])
        joints.append(point)
    for a, b in zip(joints[:-1], joints[1:]):
        canvas.segment(tuple(a), tuple(b), ROD_WIDTH, ROD)
    for joint in joints[:-1]:
        canvas.disc(tuple(joint), JOINT_RADIUS, JOINT)


def arrow(canvas: Canvas, start, vector, colour=FORCE, width: float = 3.0) -> None:
    """An arrow from `start` along `vector` (world units), its head 10 pixels long."""
    start, vector = np.asarray(start, dtype=np.float64), np.asarray(vector, dtype=np.float64)
    length = float(np.hypot(*vector))
    if not length * canvas.scale > 1.0:
        return
    end = start + vector
    direction, head = vector / length, 10.0 / canvas.scale
    normal = np.array([-direction[1], direction[0]])
    canvas.segment(tuple(start), tuple(end - direction * head / 2), width, colour)
    canvas.polygon([tuple(end), tuple(end - direction * head + normal * head / 2), tuple(end - direction * head - normal * head / 2)], colour)


def _cart_and_poles(scene: AbstractEnv, x: float, angles, lengths) -> np.ndarray:
    """A cart on its track (the track's ends at `scene.x_threshold` where finite) with its poles."""
    reach = float(np.sum(lengths))
    threshold = value(getattr(scene, "x_threshold", math.inf))
    half_width = threshold if math.isfinite(threshold) else 2.4  # Gymnasium's view of its track
    canvas = Canvas((-half_width, half_width), (-reach - 0.25, reach + 0.25))
    canvas.segment((-2 * half_width, 0.0), (2 * half_width, 0.0), 1.0, GROUND)
    if math.isfinite(threshold):
        for end in (-threshold, threshold):
            canvas.segment((end, -0.1), (end, 0.1), 2.0, FAINT)
    cart_width, cart_height = 50.0 / canvas.scale, 30.0 / canvas.scale  # Gymnasium's cart, in pixels
    left, right, top, bottom = x - cart_width / 2, x + cart_width / 2, cart_height / 2, -cart_height / 2
    canvas.rectangle((left, bottom), (right, top), CART)
    chain(canvas, (x, 0.0), angles, lengths)
    return canvas.image()


def cart_pole(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`CartPoleDynamics`: state `[x, x_dot, theta, theta_dot]`, one pole of `2 half_length`."""
    del action
    return _cart_and_poles(scene, state[0], state[2:3], [2 * value(cast("CartPoleDynamics", scene.dynamics).half_length)])


def cart_chain(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`CartChainDynamics`: state `[x, theta_1, ..., theta_n, rates]`, poles of `pole_lengths`."""
    del action
    lengths = values(cast("CartChainDynamics", scene.dynamics).pole_lengths)
    return _cart_and_poles(scene, state[0], state[1 : 1 + lengths.size], lengths)


def n_link_pendulum(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`NLinkPendulumDynamics`: rods of `lengths` from a fixed pivot, angles from upright."""
    del action
    lengths = values(cast("NLinkPendulumDynamics", scene.dynamics).lengths)
    reach = float(np.sum(lengths)) + 0.2
    canvas = Canvas((-reach, reach), (-reach, reach))
    canvas.segment((-0.15, 0.0), (0.15, 0.0), 4.0, GROUND)  # the mount of the pivot
    chain(canvas, (0.0, 0.0), state[: lengths.size], lengths)
    return canvas.image()


def pendulum(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`PendulumDynamics`: a rod of `length` from its pivot, `theta` from upright counter-clockwise (Gymnasium's)."""
    del action
    length = value(cast("PendulumDynamics", scene.dynamics).length)
    reach = length + 0.2
    canvas = Canvas((-reach, reach), (-reach, reach))
    chain(canvas, (0.0, 0.0), [-state[0]], [length])
    return canvas.image()


def acrobot(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`AcrobotDynamics`: two rods from a pivot, `theta_1` from hanging down and `theta_2`
    relative to the first (Gymnasium's), with the line the tip must rise above (1 m up).

    The dynamics has no second length (it does not enter the motion); the second rod is
    drawn uniform, twice its `link_com_position_2` (Gymnasium's 1 m)."""
    del action
    dynamics = cast("AcrobotDynamics", scene.dynamics)
    lengths = [value(dynamics.link_length_1), 2 * value(dynamics.link_com_position_2)]
    reach = sum(lengths) + 0.2
    canvas = Canvas((-reach, reach), (-reach, reach))
    canvas.segment((-reach, 1.0), (reach, 1.0), 1.0, GROUND)
    theta_1, theta_2 = state[:2]
    chain(canvas, (0.0, 0.0), [math.pi - theta_1, math.pi - theta_1 - theta_2], lengths)
    return canvas.image()


def mountain_car(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`MountainCarDynamics`: the car on the hill `0.45 sin(3 x) + 0.55` (Gymnasium's,
    whose slope is the dynamics' `cos(3 x)`) between the scene's bounds, the flag at its goal."""
    del action
    scene = cast("AbstractMountainCar", scene)
    low, high = value(scene.min_position), value(scene.max_position)
    canvas = Canvas((low, high), (0.0, 1.25))
    xs = np.linspace(low, high, 31)
    ys = 0.45 * np.sin(3 * xs) + 0.55
    for a, b in zip(zip(xs[:-1], ys[:-1]), zip(xs[1:], ys[1:])):
        canvas.segment(a, b, 2.0, GROUND)
    goal = value(getattr(scene, "goal_position", high))
    foot = (goal, 0.45 * math.sin(3 * goal) + 0.55)
    top = (goal, foot[1] + 50 / canvas.scale)
    canvas.segment(foot, top, 2.0, GROUND)
    canvas.polygon([top, (goal, top[1] - 10 / canvas.scale), (goal + 25 / canvas.scale, top[1] - 5 / canvas.scale)], (204, 204, 0))
    x = float(np.clip(state[0], low, high))
    slope = 1.35 * math.cos(3 * x)
    normal = np.array([-slope, 1.0]) / math.hypot(slope, 1.0)
    centre = np.array([x, 0.45 * math.sin(3 * x) + 0.55]) + normal * (12 / canvas.scale)
    canvas.disc(tuple(centre), 12.0, CART)
    return canvas.image()


def planar_quadrotor(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`PlanarQuadrotorDynamics`: the body (its arm to scale) at `(x, z)` tilted by `theta`,
    each rotor's thrust an arrow (half a metre for the weight's share), the box
    `position_limit` and the target at the origin."""
    dynamics = cast("PlanarQuadrotorDynamics", scene.dynamics)
    limit = value(getattr(scene, "position_limit", 2.0))
    canvas = Canvas((-limit - 0.3, limit + 0.3), (-limit - 0.3, limit + 0.3))
    corners = [(-limit, -limit), (-limit, limit), (limit, limit), (limit, -limit)]
    for a, b in zip(corners, corners[1:] + corners[:1]):
        canvas.segment(a, b, 1.0, FAINT)
    canvas.segment((-0.1, 0.0), (0.1, 0.0), 2.0, TARGET)
    canvas.segment((0.0, -0.1), (0.0, 0.1), 2.0, TARGET)
    x, z, theta = state[:3]
    arm = value(dynamics.arm_length)
    along, up = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
    centre = np.array([x, z])
    rotors = (centre - arm * along, centre + arm * along)
    canvas.segment(tuple(rotors[0]), tuple(rotors[1]), 6.0, BODY)
    for rotor in rotors:
        mast = rotor + up * (8.0 / canvas.scale)
        canvas.segment(tuple(rotor), tuple(mast), 3.0, BODY)
        canvas.segment(tuple(mast - along * arm / 2.5), tuple(mast + along * arm / 2.5), 3.0, JOINT)
    canvas.disc(tuple(centre), 5.0, BODY)
    if action is not None:
        thrust = np.asarray(scene.physical_input(action), dtype=np.float64)
        weight = value(dynamics.mass) * value(dynamics.gravity)
        for rotor, each in zip(rotors, thrust, strict=True):
            arrow(canvas, rotor + up * (8.0 / canvas.scale), up * each / weight)
    return canvas.image()


def bouncing_ball(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`BouncingBall`: the floor, the wall of its `FloorAndWall`, the target, the ball and its thrust."""
    scene = cast("BouncingBall", scene)
    walls = [contact.wall_position for contact in scene.contacts if isinstance(contact, FloorAndWall)]
    wall = value(walls[0]) if walls else math.inf
    right = wall + 0.3 if math.isfinite(wall) else 1.5
    canvas = Canvas((-value(scene.left_limit), right), (-0.25, value(scene.ceiling)))
    far = 100.0  # beyond the picture's edges
    canvas.rectangle((-far, -far), (far, 0.0), FAINT)
    canvas.segment((-far, 0.0), (far, 0.0), 2.0, GROUND)
    if math.isfinite(wall):
        canvas.rectangle((wall, -far), (wall + far, far), FAINT)
        canvas.segment((wall, -far), (wall, far), 2.0, GROUND)
    target = (value(scene.target_x), value(scene.target_z))
    canvas.ring(target, 8.0, 2.0, TARGET)
    canvas.disc(target, 2.0, TARGET)
    # The ball is a point: drawn as a disc touching it from the open side, so that it rests
    # on the floor (and against the wall) exactly when the point does.
    radius = 10.0
    x, z = state[:2]
    centre = (x - radius / canvas.scale, z + radius / canvas.scale)
    canvas.disc(centre, radius, JOINT)
    if action is not None:
        arrow(canvas, centre, 0.5 * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0))
    return canvas.image()


def rimless_wheel(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`RimlessWheelDynamics`, seen from its hub: the slope (downhill to the right), the
    spokes `2 spoke_half_angle` apart, the stance spoke darker.

    The state holds no distance travelled, so the view follows the hub; the picture is
    continuous through a heel strike (the new stance spoke is the one that landed)."""
    del action
    dynamics = cast("RimlessWheelDynamics", scene.dynamics)
    length, alpha, slope = value(dynamics.leg_length), value(dynamics.spoke_half_angle), value(dynamics.slope)
    theta = state[0]
    canvas = Canvas((-1.6 * length, 1.6 * length), (-1.2 * length, 0.8 * length))
    foot = -length * np.array([math.sin(theta), math.cos(theta)])
    downhill = np.array([math.cos(slope), -math.sin(slope)])
    far = 10 * length
    canvas.below(tuple(foot), tuple(downhill), FAINT)
    canvas.segment(tuple(foot - far * downhill), tuple(foot + far * downhill), 2.0, GROUND)
    # Spokes k at theta + 2 alpha k around the hub (k = 0 the stance spoke), each drawn once.
    count = int(math.floor(math.pi / (2 * alpha) + 1e-9))
    for k in range(-count, count + 1):
        if k == -count and math.isclose(2 * alpha * count, math.pi):
            continue  # the same spoke as k = count
        angle = theta + 2 * alpha * k
        end = -length * np.array([math.sin(angle), math.cos(angle)])
        canvas.segment((0.0, 0.0), tuple(end), ROD_WIDTH if k else ROD_WIDTH + 2, BODY if k == 0 else ROD)
    canvas.disc((0.0, 0.0), 2 * JOINT_RADIUS, JOINT)
    return canvas.image()


def van_der_pol(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`VanDerPolDynamics`: the phase point `(x, v)` on the phase plane, with the circle
    of the scene's `target_amplitude` where it has one, and the force on `v` as an arrow."""
    target = value(getattr(scene, "target_amplitude", 0.0))
    half = max(3.0, 1.5 * target)
    canvas = Canvas((-half * 1.5, half * 1.5), (-half, half))
    canvas.segment((-2 * half, 0.0), (2 * half, 0.0), 1.0, FAINT)
    canvas.segment((0.0, -2 * half), (0.0, 2 * half), 1.0, FAINT)
    if target > 0:
        canvas.ring((0.0, 0.0), target * canvas.scale, 2.0, TARGET)
    point = (state[0], state[1])
    if action is not None:
        force = float(np.asarray(scene.physical_input(action), dtype=np.float64)[0])
        arrow(canvas, point, (0.0, force))
    canvas.disc(point, 8.0, JOINT)
    return canvas.image()


def _walker(canvas: Canvas, slope: float, hip, swing_foot, length: float) -> None:
    """Two legs from the hip, the stance foot at the origin, on a slope downhill to the right."""
    downhill = np.array([math.cos(slope), -math.sin(slope)])
    far = 10 * length
    canvas.below((0.0, 0.0), tuple(downhill), FAINT)
    canvas.segment(tuple(-far * downhill), tuple(far * downhill), 2.0, GROUND)
    canvas.segment(tuple(hip), tuple(swing_foot), ROD_WIDTH, ROD)
    canvas.segment((0.0, 0.0), tuple(hip), ROD_WIDTH + 2, BODY)
    canvas.disc(tuple(hip), 2 * JOINT_RADIUS, JOINT)


def simplest_walker(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`SimplestWalkerDynamics` (legs of unit length), seen from its stance foot: `theta` the
    stance leg's angle from the slope's normal (positive with the hip uphill of the foot),
    `phi` the angle from the stance leg to the swing leg; the stance leg darker."""
    del action
    slope = value(cast("SimplestWalkerDynamics", scene.dynamics).slope)
    theta, phi = state[0], state[1]
    # In the slope's frame (x downhill along it, y along its normal), then turned by the slope.
    turn = np.array([[math.cos(slope), math.sin(slope)], [-math.sin(slope), math.cos(slope)]])
    hip = turn @ np.array([-math.sin(theta), math.cos(theta)])
    swing_foot = hip - turn @ np.array([-math.sin(theta - phi), math.cos(theta - phi)])
    canvas = Canvas((-1.8, 1.8), (-1.0, 1.4))
    _walker(canvas, slope, hip, swing_foot, 1.0)
    return canvas.image()


def compass_gait(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`CompassGaitDynamics`, seen from its stance foot: each leg at its angle from the
    vertical (positive downhill, foot to hip), the stance leg darker, the leg masses as discs."""
    del action
    dynamics = cast("CompassGaitDynamics", scene.dynamics)
    a, b = value(dynamics.lower_length), value(dynamics.upper_length)
    length, slope = a + b, value(dynamics.slope)
    theta_s, theta_w = state[0], state[1]
    stance = np.array([math.sin(theta_s), math.cos(theta_s)])
    swing = np.array([math.sin(theta_w), math.cos(theta_w)])
    hip = length * stance
    canvas = Canvas((-1.8 * length, 1.8 * length), (-1.0 * length, 1.4 * length))
    _walker(canvas, slope, hip, hip - length * swing, length)
    for mass in (a * stance, hip - b * swing):
        canvas.disc(tuple(mass), JOINT_RADIUS + 2, JOINT)
    return canvas.image()


def sliding_block(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`SlidingBlockDynamics`: the block on its plane (rising to the right at `incline`), its
    position `s` along the plane (positive up the slope), the push as an arrow along it."""
    incline = value(cast("SlidingBlockDynamics", scene.dynamics).incline)
    along = np.array([math.cos(incline), math.sin(incline)])
    normal = np.array([-math.sin(incline), math.cos(incline)])
    position = state[0]
    canvas = Canvas((position - 2.0, position + 2.0), (position * along[1] - 1.0, position * along[1] + 1.67))
    far = 10.0 + abs(position)
    canvas.below(tuple(position * along), tuple(along), FAINT)
    canvas.segment(tuple(-far * along), tuple(far * along), 2.0, GROUND)
    for mark in range(math.floor(position) - 3, math.floor(position) + 4):  # a tick every metre
        canvas.segment(tuple(mark * along), tuple(mark * along - 0.08 * normal), 2.0, GROUND)
    half = 0.25
    centre = position * along + half * normal
    corners = [centre + a * half * along + b * half * normal for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    canvas.polygon([tuple(c) for c in corners], CART)
    if action is not None:
        push = float(np.asarray(scene.physical_input(action), dtype=np.float64)[0])
        arrow(canvas, tuple(centre), tuple(0.05 * push * along))
    return canvas.image()


def rolling_disk(scene: AbstractEnv, state: np.ndarray, action) -> np.ndarray:
    """`RollingDiskDynamics`: the floor with a tick every metre, the disk with a spoke that shows
    its angle (clockwise), the target, the motor's torque as an arrow along the floor."""
    radius = value(cast("RollingDiskDynamics", scene.dynamics).radius)
    x, z, angle = state[:3]
    half = max(1.0, 6 * radius)
    canvas = Canvas((x - half, x + half), (-0.25 * half, 1.25 * half))
    far = 10.0 + abs(x) + half
    canvas.rectangle((-far, -far), (far, 0.0), FAINT)
    canvas.segment((-far, 0.0), (far, 0.0), 2.0, GROUND)
    for mark in range(math.floor(x - half), math.floor(x + half) + 2):
        canvas.segment((mark, 0.0), (mark, -0.04 * half), 2.0, GROUND)
    target = getattr(scene, "target", None)
    if target is not None:
        canvas.ring((value(target), 0.0), 6.0, 2.0, TARGET)
    pixels = max(radius * canvas.scale, 3.0)
    canvas.disc((x, z), pixels, CART)
    rim = (x + radius * math.sin(angle), z + radius * math.cos(angle))
    canvas.segment((x, z), rim, 2.0, JOINT)
    if action is not None:
        torque = float(np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0).reshape(-1)[0])
        arrow(canvas, (x, z + radius), (0.5 * torque, 0.0))
    return canvas.image()

