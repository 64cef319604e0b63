"""The ecology knobs: dynamism (sphere speed), shaping (spawn distance), reset-free vs episodic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foodcollector import FoodCollectorParams, encode_action

NOOP = encode_action()


def random_actions(seed: int, n: int) -> list[int]:
    """A reproducible uniform random policy's actions."""
    return np.random.default_rng(seed).integers(0, 27, size=n).tolist()


def test_static_spheres_never_move(make_env):
    env = make_env(seed=2, dynamism=0.0, reset_free=True)
    u = env.unwrapped
    assert not u.sphere_velocities.any()
    before = u.sphere_positions
    eaten_before = 0
    for a in random_actions(2, 1500):
        _, _, _, _, info = env.step(a)
        now = u.sphere_positions
        eaten = info["green_eaten"] + info["red_eaten"]
        moved = np.flatnonzero((now != before).any(axis=1))
        assert len(moved) <= eaten - eaten_before  # only eaten spheres (teleported) change place
        before, eaten_before = now, eaten
    assert eaten_before > 0  # the check above was exercised
    assert not u.sphere_velocities.any()


@pytest.mark.parametrize("dynamism", [0.3, 1.0])
def test_dynamic_spheres_move_at_the_configured_speed_inside_the_arena(make_env, dynamism):
    env = make_env(seed=4, dynamism=dynamism, reset_free=True)
    u = env.unwrapped
    params = u.params
    speed = dynamism * params.max_sphere_speed
    bound = params.arena_half_size - params.sphere_radius
    step_length = speed * params.decision_seconds
    before = u.sphere_positions
    for a in random_actions(4, 1000):
        _, _, _, _, info = env.step(a)
        pos = u.sphere_positions
        assert np.allclose(np.hypot(*u.sphere_velocities.T), speed, rtol=1e-12)
        assert np.abs(pos).max() <= bound
        # Spheres that neither bounced nor respawned moved exactly speed × 0.1 s in a straight line.
        travelled = np.hypot(*(pos - before).T)
        straight = np.abs(pos).max(axis=1) < bound - step_length
        assert np.count_nonzero(np.isclose(travelled[straight], step_length, rtol=1e-9)) >= straight.sum() - 2
        before = pos


def test_dynamic_spheres_bounce_elastically():
    from foodcollector.spheres import SphereField

    params = FoodCollectorParams(num_green=1, num_red=0)
    field = SphereField(params, speed=10.0)
    bound = params.arena_half_size - params.sphere_radius
    field.pos[0] = (bound - 0.05, 0.0)
    field.vel[0] = (10.0, 3.0)
    field.advance(0.02)  # would overshoot by 0.15: mirrored back by 0.15
    assert field.pos[0].tolist() == pytest.approx([bound - 0.15, 0.06])
    assert field.vel[0].tolist() == [-10.0, 3.0]


def test_dynamism_draws_directions_uniformly(make_env):
    env = make_env(seed=9, dynamism=1.0)
    angles = np.arctan2(*env.unwrapped.sphere_velocities.T[::-1])
    assert len(np.unique(np.round(angles, 6))) == env.unwrapped.params.num_spheres
    assert angles.min() < -1.5 and angles.max() > 1.5  # spread over the circle


def test_full_shaping_spawns_within_near_radius(make_env):
    env = make_env(seed=6, shaping=1.0, reset_free=True)
    u = env.unwrapped
    near = u.params.near_radius
    x, y = u.arena.agent.position
    assert np.hypot(*(u.sphere_positions - (x, y)).T).max() <= near  # the initial layout too
    u.place_agent((30.0, -20.0), heading=90.0)
    for i in range(300):
        k = i % u.params.num_spheres
        u.place_sphere(k, (31.0, -20.0))  # overlapping the agent: eaten on the first physics step
        _, _, _, _, info = env.step(NOOP)
        d = math.dist(u.sphere_positions[k], (30.0, -20.0))
        assert u.params.spawn_clearance < d <= near
    assert info["green_eaten"] + info["red_eaten"] == 300


def test_no_shaping_spawns_over_the_whole_square(make_env):
    env = make_env(seed=6, shaping=0.0, reset_free=True)
    u = env.unwrapped
    u.place_agent((30.0, -20.0), heading=90.0)
    distances = []
    for _ in range(300):
        u.place_sphere(0, (31.0, -20.0))
        env.step(NOOP)
        distances.append(math.dist(u.sphere_positions[0], (30.0, -20.0)))
    assert max(distances) > 80 and np.mean(np.array(distances) > u.params.near_radius) > 0.9
    assert np.abs(u.sphere_positions).max() <= u.params.spawn_half_size


def test_spawn_distance_interpolates_linearly_over_the_schedule(make_env):
    env = make_env(seed=1, shaping="linear:1:0:100", reset_free=True)
    u = env.unwrapped
    p = u.params
    diagonal = 2 * math.sqrt(2) * p.arena_half_size
    assert u.max_spawn_distance == pytest.approx(p.near_radius)  # s(0) = 1
    for _ in range(50):
        env.step(NOOP)
    assert u.shaping_strength == pytest.approx(0.5)
    assert u.max_spawn_distance == pytest.approx(0.5 * diagonal + 0.5 * p.near_radius)
    for _ in range(60):
        env.step(NOOP)
    assert u.max_spawn_distance == pytest.approx(diagonal)  # s = 0 after the schedule


def test_spawns_never_touch_the_agent(make_env):
    env = make_env(seed=8, shaping=1.0, dynamism=1.0, reset_free=True)
    u = env.unwrapped
    for a in random_actions(8, 400):
        obs, *_ = env.step(a)
        x, y = u.arena.agent.position
        # Nothing overlaps the agent at observation time: touching spheres were eaten and moved away.
        assert np.hypot(*(u.sphere_positions - (x, y)).T).min() > u.params.sphere_radius + 0.5


def run_reset_free(make_env, decisions: int, seed: int) -> None:
    """Random decisions in a reset-free env: it never ends, spheres are never lost or leave the arena."""
    env = make_env(seed=seed, dynamism=0.5, shaping="linear:1:0:2000", reset_free=True)
    u = env.unwrapped
    p = u.params
    bound = p.arena_half_size - p.sphere_radius
    for t, a in enumerate(random_actions(seed, decisions), start=1):
        _, _, terminated, truncated, info = env.step(a)
        assert not terminated and not truncated
        if t % 250 == 0:
            pos = u.sphere_positions
            assert pos.shape == (p.num_spheres, 2) and np.abs(pos).max() <= bound
            assert u.sphere_is_green.sum() == 25 and (~u.sphere_is_green).sum() == 25
            assert max(abs(c) for c in info["agent_pos"]) < p.arena_half_size
    assert info["lifetime_step"] == decisions


def test_reset_free_5k_decisions(make_env):
    run_reset_free(make_env, 5_000, seed=13)


@pytest.mark.slow
def test_reset_free_100k_decisions(make_env):
    run_reset_free(make_env, 100_000, seed=14)


def test_pymunk_mirror_follows_the_numpy_spheres(make_env):
    env = make_env(seed=10, dynamism=1.0, reset_free=True)
    u = env.unwrapped
    for a in random_actions(10, 1500):
        env.step(a)
    mirror = np.array([tuple(b.position) for b in u.arena.sphere_bodies])
    # Both sides compute p + v·dt in float64 (bitwise equal here); a platform fusing multiply-add in
    # pymunk's C code could differ by rounding only, far below anything a ray could notice.
    assert np.allclose(mirror, u.sphere_positions, rtol=0, atol=1e-9)
