"""The world: random rectangle worlds, the connectivity guarantee, reachability."""

from collections import deque

import numpy as np
import pytest
from anytime_navigation.world import World, random_world, reachable


def bfs_reachable(blocked: np.ndarray, start: tuple[int, int], movement: int) -> np.ndarray:
    """Reference: breadth-first search over the movement model itself (no corner cutting)."""
    n_rows, n_cols = blocked.shape
    seen = np.zeros_like(blocked)
    x, y = start
    if blocked[y, x]:
        return seen
    seen[y, x] = True
    queue = deque([start])
    steps = [(1, 0), (-1, 0), (0, 1), (0, -1)]
    if movement == 8:
        steps += [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    while queue:
        x, y = queue.popleft()
        for dx, dy in steps:
            nx, ny = x + dx, y + dy
            if not (0 <= nx < n_cols and 0 <= ny < n_rows) or blocked[ny, nx] or seen[ny, nx]:
                continue
            if dx and dy and (blocked[y, nx] or blocked[ny, x]):
                continue  # a diagonal step needs both orthogonal neighbours free
            seen[ny, nx] = True
            queue.append((nx, ny))
    return seen


@pytest.mark.parametrize("movement", [4, 8], ids=["4", "8"])
def test_reachable_equals_a_search_over_the_movement_model(movement: int) -> None:
    rng = np.random.default_rng(1)
    for _ in range(40):
        blocked = rng.random((24, 24)) < rng.uniform(0.2, 0.5)
        start = (int(rng.integers(24)), int(rng.integers(24)))
        np.testing.assert_array_equal(
            reachable(blocked, start, movement), bfs_reachable(blocked, start, movement)
        )


def test_corner_cutting_is_not_reachability() -> None:
    # Free cells touching only at a corner are 8-connected but not reachable without cutting it.
    blocked = np.array([[False, True], [True, False]])
    assert not reachable(blocked, (0, 0), 8)[1, 1]
    assert reachable(blocked, (0, 0), 8).sum() == 1


def test_reachable_from_a_blocked_cell_is_empty() -> None:
    assert not reachable(np.ones((4, 4), dtype=bool), (1, 1)).any()


@pytest.mark.parametrize("movement", [4, 8], ids=["4", "8"])
def test_random_worlds_are_connected(movement: int) -> None:
    for seed in range(60):
        world = random_world(32, seed=seed, density=0.35, min_side=1, max_side=6, movement=movement)
        assert world.start == (0, 0) and world.goal == (31, 31)
        assert world.movement == movement
        assert bfs_reachable(world.blocked, world.start, movement)[31, 31], seed
        assert world.is_connected()


@pytest.mark.parametrize("movement", [4, 8], ids=["4", "8"])
def test_default_worlds_are_connected_and_near_the_density(movement: int) -> None:
    for seed in range(8):
        world = random_world(seed=seed, movement=movement)
        assert world.size == 128
        assert bfs_reachable(world.blocked, world.start, movement)[127, 127], seed
        assert 0.2 <= world.blocked.mean() < 0.25
        assert world.blocked.any(axis=0).sum() > 64  # obstacles spread over the map


def test_random_world_is_reproducible_from_the_seed() -> None:
    a = random_world(64, seed=7, density=0.3)
    assert a == random_world(64, seed=7, density=0.3)
    np.testing.assert_array_equal(a.blocked, random_world(64, seed=7, density=0.3).blocked)
    assert a != random_world(64, seed=8, density=0.3)


def test_rectangles_respect_the_side_range() -> None:
    world = random_world(64, seed=3, density=0.1, min_side=4, max_side=4)
    # Every blocked run along a row is clipped at the border or a union of 4-wide rectangles.
    row_runs = np.diff(np.pad(world.blocked.astype(int), ((0, 0), (1, 1))), axis=1)
    for row in row_runs:
        starts, ends = np.flatnonzero(row == 1), np.flatnonzero(row == -1)
        assert all(e - s >= 4 or e == 64 for s, e in zip(starts, ends, strict=True))


def test_world_is_read_only_hashable_and_copies_its_grid() -> None:
    grid = np.zeros((8, 8), dtype=bool)
    world = World(grid, (0, 0), (7, 7))
    grid[3, 3] = True
    assert not world.blocked[3, 3]
    with pytest.raises(ValueError, match="read-only"):
        world.blocked[0, 1] = True
    assert hash(world) is not None
    assert world.movement == 4


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"blocked": np.zeros((8, 4), dtype=bool)}, r"must be square, got shape \(8, 4\)"),
        ({"blocked": np.zeros((6, 6), dtype=bool)}, "must be a power of two, got 6"),
        ({"start": (8, 0)}, r"start \(8, 0\) is outside the 8x8 grid"),
        ({"goal": (1, 1)}, r"goal \(1, 1\) is a blocked cell"),
        ({"movement": 6}, "movement must be 4 or 8, got 6"),
    ],
    ids=["not-square", "not-power-of-two", "outside", "blocked", "movement"],
)
def test_world_validation(kwargs: dict[str, object], message: str) -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[1, 1] = True
    arguments: dict[str, object] = {"blocked": blocked, "start": (0, 0), "goal": (7, 7)}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        World(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"size": 100}, "size must be a power of two >= 2, got 100"),
        ({"density": 1.0}, r"density must be in \[0, 1\), got 1.0"),
        ({"min_side": 5, "max_side": 3}, "need 1 <= min_side <= max_side, got 5 and 3"),
        ({"movement": 2}, "movement must be 4 or 8, got 2"),
    ],
    ids=["size", "density", "sides", "movement"],
)
def test_random_world_validation(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        random_world(**kwargs)  # type: ignore[arg-type]


def test_zero_density_is_an_empty_world() -> None:
    assert not random_world(16, density=0.0).blocked.any()
