"""Ray casts against a slow, analytic reference sphere cast (reference-parity over random rollouts)."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

from foodcollector import RAY_ANGLES_DEG
from foodcollector.arena import RAY_VALUES, Tag

TAG_OF = {"green": Tag.FOOD, "red": Tag.BAD_FOOD, "wall": Tag.WALL}


def reference_cast(env) -> list[tuple[str | None, float]]:
    """Per ray (what, fraction): a circle of radius ray_radius swept from the agent's centre, Unity-style.

    Exact maths, one shape at a time; a shape the cast starts inside of (or touching) is ignored, as
    Unity's SphereCast ignores colliders it starts overlapping, and a wall hit beyond the arena's faces
    (reached by travelling through an ignored wall) does not count.
    """
    u, p = env.unwrapped, env.unwrapped.params
    x, y = u.arena.agent.position
    heading = math.radians(u.agent_heading)
    reach = p.arena_half_size - p.ray_radius  # the swept circle touches a wall face here
    out = []
    for angle in RAY_ANGLES_DEG:
        a = heading - math.pi / 2 + math.radians(angle)
        d = (math.cos(a), math.sin(a))
        best: tuple[str | None, float] = (None, math.inf)
        for (qx, qy), green in zip(u.sphere_positions.tolist(), u.sphere_is_green.tolist(), strict=True):
            mx, my = x - qx, y - qy
            radius = p.sphere_radius + p.ray_radius
            b, c = mx * d[0] + my * d[1], mx * mx + my * my - radius * radius
            if c > 0 and b * b - c >= 0:
                t = -b - math.sqrt(b * b - c)
                if 0 <= t < best[1]:
                    best = ("green" if green else "red", t)
        for o, di in ((x, d[0]), (y, d[1])):
            for sign in (1.0, -1.0):
                if sign * o < reach and sign * di > 0:
                    t = (sign * reach - o) / di
                    hx, hy = x + t * d[0], y + t * d[1]
                    inside = max(abs(hx), abs(hy)) <= p.arena_half_size
                    if inside and t < best[1]:
                        best = ("wall", t)
        out.append(best if best[1] <= p.ray_length else (None, math.inf))
    return [(what, t / p.ray_length if what else 1.0) for what, t in out]


def assert_rays_match(env, obs: np.ndarray) -> None:
    """The observation's 7 rays equal the reference cast (fractions to float32 precision)."""
    rows = obs[:7 * RAY_VALUES].reshape(7, RAY_VALUES)
    for k, (what, fraction) in enumerate(reference_cast(env)):
        onehot = np.zeros(5)
        if what is not None:
            onehot[TAG_OF[what]] = 1
        assert rows[k, :5].tolist() == onehot.tolist(), f"ray {k}: expected {what}, got {rows[k]}"
        assert rows[k, 5] == (what is None), f"ray {k}: miss flag"
        assert rows[k, 6] == pytest.approx(fraction, abs=2e-6), f"ray {k}: fraction"


def test_pymunk_fat_segment_queries_miss_off_axis_shapes():
    """Why the arena inflates shapes and casts thin rays: documents pymunk 7.3.1's behaviour."""
    space = pymunk.Space()
    for p in [(1.0, 20.0), (30.0, 30.0), (-30.0, -30.0)]:
        body = pymunk.Body(body_type=pymunk.Body.STATIC)
        body.position = p
        space.add(body, pymunk.Circle(body, 0.75))
    fat = space.segment_query_first((0, 0), (0, 50), 0.5, pymunk.ShapeFilter())
    thin_inflated = pymunk.Circle(pymunk.Body(body_type=pymunk.Body.STATIC), 1.25, (1.0, 20.0))
    # The swept circle (0.5) passes 1.0 from the sphere's centre < 0.5 + 0.75: it should be a hit.
    assert thin_inflated.segment_query((0, 0), (0, 50), 0.0) is not None
    if fat is not None:
        pytest.skip("this pymunk finds off-axis shapes in fat queries; the workaround is harmless")


def test_sphere_just_off_the_ray_axis_is_seen(quiet_env):
    quiet_env.unwrapped.place_sphere(0, (1.0, 20.0))  # 1.0 < 0.5 + 0.75 from the forward ray's axis
    obs, *_ = quiet_env.step(0)
    assert obs[:5].tolist() == [1, 0, 0, 0, 0]
    assert obs[6] == pytest.approx((20.0 - math.sqrt(1.25 ** 2 - 1.0)) / 50.0, abs=1e-6)


def test_pressed_against_a_wall_rays_ignore_that_wall(quiet_env):
    u = quiet_env.unwrapped
    u.place_agent((0.0, 45.0), heading=90.0)
    for _ in range(15):
        obs, *_ = quiet_env.step(9)  # drive into the top wall and keep pushing
    assert u.arena.agent.position.y > 49.5  # the centre is inside the wall's inflated sight shape
    assert_rays_match(quiet_env, obs)


@pytest.mark.parametrize("knobs", [{"dynamism": 0.0}, {"dynamism": 0.3}, {"dynamism": 1.0, "shaping": 1.0}])
def test_rays_match_the_reference_over_a_random_rollout(make_env, knobs):
    env = make_env(seed=5, reset_free=True, **knobs)
    rng = np.random.default_rng(5)
    obs, _ = env.reset(seed=5)
    for _ in range(1500):
        assert_rays_match(env, obs)
        # Half the time straight ahead: the agent crosses the arena and spends time pressed on walls.
        obs, *_ = env.step(9 if rng.random() < 0.5 else int(rng.integers(27)))
