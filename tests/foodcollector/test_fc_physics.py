"""Movement, rays and contacts against the reference numbers (reference/unity-foodcollector.md §1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foodcollector import RAY_ANGLES_DEG, FoodCollectorParams, encode_action
from foodcollector.spheres import SphereField

NOOP = encode_action()
FORWARD = encode_action(forward=1)
BACKWARD = encode_action(forward=2)
STRAFE_RIGHT = encode_action(strafe=1)
TURN_LEFT = encode_action(turn=1)
TURN_RIGHT = encode_action(turn=2)
RAY = 7  # values per ray
FOOD, WALL, BAD_FOOD, MISS, FRACTION = 0, 2, 3, 5, 6


def unity_speed(steps: int) -> float:
    """The reference recurrence from rest: v ← (0.95·v if v > 5 else v) + 2, then drag × (1 − 0.5·0.02)."""
    v = 0.0
    for _ in range(steps):
        v = ((0.95 * v if v > 5.0 else v) + 2.0) * (1.0 - 0.5 * 0.02)
    return v


def ray(obs: np.ndarray, k: int) -> np.ndarray:
    """The 7 values of ray k."""
    return obs[RAY * k:RAY * (k + 1)]


def test_ray_angles_are_unitys():
    assert np.allclose(RAY_ANGLES_DEG, [90, 66.667, 113.333, 43.333, 136.667, 20, 160], atol=1e-3)


@pytest.mark.parametrize(("steps", "reference"), [(1, 1.98), (5, 9.0), (10, 15.4), (50, 31.7)])
def test_forward_speed_from_rest(make_env, steps, reference):
    # One physics step per decision (substeps=1) exposes every physics step through the public API.
    env = make_env(substeps=1)
    env.unwrapped.place_agent((0.0, -40.0), heading=90.0)  # ~20 units of travel: far from any wall
    for _ in range(steps):
        env.step(FORWARD)
    vx, vy = env.unwrapped.agent_velocity
    # The env runs the same recurrence; only pymunk's damping**dt = (0.99**50)**0.02 differs from 0.99 by
    # float rounding (~1e-16 per step), so 1e-9 relative is generous yet catches any modelling change.
    assert math.hypot(vx, vy) == pytest.approx(unity_speed(steps), rel=1e-9)
    assert vx == pytest.approx(0.0, abs=1e-9)
    # The reference rounds to 0.1, hence ±0.05.
    assert math.hypot(vx, vy) == pytest.approx(reference, abs=0.05)


def test_decision_is_five_physics_steps(make_env):
    env = make_env()
    env.unwrapped.place_agent((0.0, -40.0), heading=90.0)
    for _ in range(10):
        obs, *_ = env.step(FORWARD)
    assert math.hypot(*env.unwrapped.agent_velocity) == pytest.approx(unity_speed(50), rel=1e-9)
    assert obs[50] == pytest.approx(unity_speed(50), rel=1e-6)  # forward local velocity (float32)
    assert obs[49] == pytest.approx(0.0, abs=1e-5)


def test_speed_never_exceeds_terminal(make_env):
    env = make_env()
    env.unwrapped.place_agent((0.0, -45.0), heading=90.0)
    for _ in range(200):
        env.step(encode_action(forward=1, turn=1))  # circles: never reaches a wall at ≤33 u/s
    params = FoodCollectorParams()
    assert math.hypot(*env.unwrapped.agent_velocity) <= params.max_agent_speed
    assert params.max_agent_speed == pytest.approx(33.28, abs=0.01)


@pytest.mark.parametrize(("action", "expected"), [(TURN_LEFT, 180.0), (TURN_RIGHT, 0.0)])
def test_quarter_turn_takes_three_decisions(make_env, action, expected):
    env = make_env()
    env.unwrapped.place_agent((0.0, 0.0), heading=90.0)
    headings = []
    for _ in range(3):
        env.step(action)
        headings.append(env.unwrapped.agent_heading)
    step = 30.0 if action == TURN_LEFT else -30.0
    assert headings == pytest.approx([90 + step, 90 + 2 * step, expected], abs=1e-9)


def test_strafe_overrides_forward(make_env):
    both, strafe = make_env(), make_env()
    for env in (both, strafe):
        env.unwrapped.place_agent((0.0, 0.0), heading=90.0)
    both.step(encode_action(forward=1, strafe=1))
    strafe.step(STRAFE_RIGHT)
    assert both.unwrapped.agent_velocity == strafe.unwrapped.agent_velocity
    vx, vy = strafe.unwrapped.agent_velocity
    assert vx > 0 and vy == pytest.approx(0.0, abs=1e-12)  # facing +y, the right is +x


def test_backward_moves_backward(make_env):
    env = make_env()
    env.unwrapped.place_agent((0.0, 0.0), heading=0.0)  # facing +x
    env.step(BACKWARD)
    vx, vy = env.unwrapped.agent_velocity
    assert vx < 0 and vy == pytest.approx(0.0, abs=1e-12)


def test_drift_keeps_world_velocity_while_turning(make_env):
    env = make_env()
    env.unwrapped.place_agent((0.0, 0.0), heading=90.0, velocity=(0.0, 4.0))
    env.step(TURN_LEFT)
    vx, vy = env.unwrapped.agent_velocity
    assert vx == pytest.approx(0.0, abs=1e-12)  # turning does not rotate the velocity (Unity drifts)
    assert vy == pytest.approx(4.0 * 0.99 ** 5, rel=1e-9)


def test_walls_stop_the_agent(make_env):
    env = make_env()
    env.unwrapped.place_agent((0.0, 30.0), heading=90.0)
    for _ in range(60):
        _, _, _, _, info = env.step(FORWARD)
    x, y = info["agent_pos"]
    # Against the wall; the agent pushes 2 u/s into it every physics step and pymunk corrects overlaps
    # gradually, so it settles ~0.05 units deep (see arena.COLLISION_SLOP).
    assert y <= 50.0 - 0.5 + 0.07
    assert y > 48.0


def test_green_sphere_on_the_forward_ray(quiet_env):
    quiet_env.unwrapped.place_sphere(0, (0.0, 20.0))
    obs, *_ = quiet_env.step(NOOP)
    values = ray(obs, 0)
    assert values[:5].tolist() == [1, 0, 0, 0, 0] and values[MISS] == 0
    # The swept circle (0.5) touches the sphere (0.75) after 20 − 1.25 units of the 50-unit ray.
    assert values[FRACTION] == pytest.approx((20.0 - 1.25) / 50.0, abs=1e-6)


def test_red_sphere_on_a_side_ray(quiet_env):
    u = quiet_env.unwrapped
    k, dist = 3, 30.0  # ray 3 points 43.3° counter-clockwise from the right (+x when facing +y)
    a = math.radians(RAY_ANGLES_DEG[k])
    red = u.params.num_green  # first red index
    u.place_sphere(red, (dist * math.cos(a), dist * math.sin(a)))
    obs, *_ = quiet_env.step(NOOP)
    values = ray(obs, k)
    assert values[:5].tolist() == [0, 0, 0, 1, 0] and values[MISS] == 0
    assert values[FRACTION] == pytest.approx((dist - 1.25) / 50.0, abs=1e-6)


def test_nearest_sphere_occludes(quiet_env):
    u = quiet_env.unwrapped
    u.place_sphere(0, (0.0, 30.0))  # green behind
    u.place_sphere(u.params.num_green, (0.0, 10.0))  # red in front
    obs, *_ = quiet_env.step(NOOP)
    assert ray(obs, 0)[:5].tolist() == [0, 0, 0, 1, 0]
    assert ray(obs, 0)[FRACTION] == pytest.approx((10.0 - 1.25) / 50.0, abs=1e-6)


def test_walls_are_seen_as_walls(quiet_env):
    u = quiet_env.unwrapped
    u.place_agent((0.0, 10.0), heading=90.0)
    obs, *_ = quiet_env.step(NOOP)
    # Straight ahead: the circle's edge reaches the wall face (y = 50) after 50 − 10 − 0.5 units.
    assert ray(obs, 0)[:5].tolist() == [0, 0, 1, 0, 0]
    assert ray(obs, 0)[FRACTION] == pytest.approx(39.5 / 50.0, abs=1e-6)
    # Ray 1 (66.7°) rises 50·sin(66.7°) ≈ 45.9 > 39.5: it hits the same wall further along.
    a = math.radians(RAY_ANGLES_DEG[1])
    assert ray(obs, 1)[:5].tolist() == [0, 0, 1, 0, 0]
    assert ray(obs, 1)[FRACTION] == pytest.approx(39.5 / (50.0 * math.sin(a)), abs=1e-6)
    # Ray 5 (20°) rises only 17.1 and runs 47 to the right: it misses everything.
    assert ray(obs, 5).tolist() == [0, 0, 0, 0, 0, 1, 1]


def test_touching_green_gives_plus_one_and_respawns(quiet_env):
    u = quiet_env.unwrapped
    u.place_sphere(0, (0.0, 1.5))  # 0.25 in front of the agent's face: reached within one decision
    _, reward, _, _, info = quiet_env.step(FORWARD)
    assert reward == 1.0
    assert (info["green_eaten"], info["red_eaten"]) == (1, 0)
    assert np.hypot(*(u.sphere_positions[0] - info["agent_pos"])) > u.params.spawn_clearance
    assert not np.allclose(u.sphere_positions[0], (0.0, 1.5))


def test_touching_red_gives_minus_one_and_respawns(quiet_env):
    u = quiet_env.unwrapped
    red = u.params.num_green
    u.place_sphere(red, (1.2, 0.0))  # overlapping the agent's right face: eaten on the first physics step
    _, reward, _, _, info = quiet_env.step(NOOP)
    assert reward == -1.0
    assert (info["green_eaten"], info["red_eaten"]) == (0, 1)
    assert not np.allclose(u.sphere_positions[red], (1.2, 0.0))
    assert u.sphere_is_green.sum() == u.params.num_green  # colours never change


def test_two_contacts_in_one_decision_add_up(quiet_env):
    u = quiet_env.unwrapped
    u.place_sphere(0, (0.0, 1.2))
    u.place_sphere(u.params.num_green, (0.0, -1.2))
    _, reward, _, _, info = quiet_env.step(NOOP)
    assert reward == 0.0 and (info["green_eaten"], info["red_eaten"]) == (1, 1)


@pytest.mark.parametrize(("offset", "touching"), [
    ((1.24, 0.0), True), ((1.26, 0.0), False),  # face: 0.5 + 0.75 = 1.25
    ((1.0, 1.0), True), ((1.05, 1.05), False),  # corner: |(0.5, 0.5)| away, 0.707 vs 0.778 > 0.75
])
def test_contact_is_square_versus_circle(offset, touching):
    field = SphereField(FoodCollectorParams(num_green=1, num_red=0), speed=0.0)
    field.pos[0] = offset
    assert (field.touching(0.0, 0.0, 1.0, 0.0) == [0]) is touching
    # Rotated by 90°, the square is the same set: the test must not depend on the axis used.
    assert (field.touching(0.0, 0.0, 0.0, 1.0) == [0]) is touching
