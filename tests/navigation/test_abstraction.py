"""The abstraction pyramid: obstacleness per level, projection between levels."""

import numpy as np
import pytest
from anytime_navigation.planning.abstraction import Pyramid, cell_bounds, project
from hypothesis import given, settings
from hypothesis import strategies as st


def direct_obstacleness(blocked: np.ndarray, level: int) -> np.ndarray:
    """Reference: the mean of each 2^level x 2^level block, one block at a time."""
    side = 1 << level
    m = blocked.shape[0] // side
    out = np.empty((m, m))
    for y in range(m):
        for x in range(m):
            out[y, x] = blocked[y * side : (y + 1) * side, x * side : (x + 1) * side].mean()
    return out


@pytest.mark.parametrize("size", [1, 2, 16, 64], ids=lambda n: f"{n}x{n}")
def test_pyramid_equals_the_direct_computation(size: int) -> None:
    rng = np.random.default_rng(size)
    for _ in range(5):
        blocked = rng.random((size, size)) < rng.uniform(0, 1)
        pyramid = Pyramid.build(blocked)
        assert pyramid.top == size.bit_length() - 1
        assert pyramid.levels[-1].shape == (1, 1)
        for level in range(pyramid.top + 1):
            np.testing.assert_array_equal(
                pyramid.levels[level], direct_obstacleness(blocked, level)
            )


def test_papers_example() -> None:
    # (3 3 1) stands for (6 6 0) (6 7 0) (7 6 0) (7 7 0); one blocked gives 0.25.
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[7, 6] = True
    pyramid = Pyramid.build(blocked)
    assert pyramid.obstacleness((3, 3), 1) == 0.25
    assert pyramid.cell_bounds((3, 3), 1) == (6, 6, 8, 8)
    assert pyramid.obstacleness((0, 0), 4) == 1 / 256
    assert pyramid.obstacleness((6, 7), 0) == 1.0  # position (x, y) is blocked[y, x]
    assert pyramid.obstacleness((7, 6), 0) == 0.0


def test_chosen_top_and_sides() -> None:
    pyramid = Pyramid.build(np.zeros((32, 32), dtype=bool), top=3)
    assert pyramid.top == 3
    assert [pyramid.side(n) for n in range(4)] == [32, 16, 8, 4]
    assert pyramid.size == 32


def test_pyramid_is_read_only_and_comparable() -> None:
    blocked = np.random.default_rng(0).random((8, 8)) < 0.3
    pyramid = Pyramid.build(blocked)
    with pytest.raises(ValueError, match="read-only"):
        pyramid.levels[1][0, 0] = 0.5
    assert pyramid == Pyramid.build(blocked)
    assert pyramid != Pyramid.build(~blocked)
    assert hash(pyramid) is not None


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: Pyramid.build(np.zeros((6, 6), dtype=bool)), "power-of-two side"),
        (lambda: Pyramid.build(np.zeros((8, 4), dtype=bool)), "power-of-two side"),
        (lambda: Pyramid.build(np.zeros((8, 8), dtype=bool), top=4), r"top must be in \[0, 3\]"),
        (lambda: Pyramid.build(np.zeros((8, 8), dtype=bool)).side(4), r"level must be in \[0, 3\]"),
        (
            lambda: Pyramid.build(np.zeros((8, 8), dtype=bool)).obstacleness((4, 0), 1),
            r"\(4, 0\) is outside level 1 \(4x4 cells\)",
        ),
        (
            lambda: Pyramid.build(np.zeros((8, 8), dtype=bool)).project((0, 0), 0, 5),
            r"level must be in \[0, 3\], got 5",
        ),
        (lambda: project((0, 0), 2, 0, anchor="middle"), "anchor must be 'corner' or 'centre'"),
        (lambda: project((0, 0), -1, 0), "levels must be >= 0"),
    ],
    ids=["not-power", "not-square", "top", "side", "outside", "project-level", "anchor", "neg"],
)
def test_errors(call: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        call()  # type: ignore[operator]


def test_project_examples() -> None:
    assert project((6, 7), 0, 1) == (3, 3)
    assert project((13, 2), 0, 3) == (1, 0)
    assert project((3, 3), 1, 0) == (6, 6)
    assert project((3, 3), 1, 0, anchor="centre") == (6, 6)
    assert project((1, 2), 3, 0, anchor="centre") == (11, 19)  # block 8..15 x 16..23
    assert project((1, 2), 3, 1) == (4, 8)
    assert project((5, 9), 2, 2) == (5, 9)


@given(
    x=st.integers(0, 255),
    y=st.integers(0, 255),
    a=st.integers(0, 8),
    b=st.integers(0, 8),
    anchor=st.sampled_from(["corner", "centre"]),
)
def test_project_round_trips(x: int, y: int, a: int, b: int, anchor: str) -> None:
    low, high = min(a, b), max(a, b)
    base = (x, y)
    cell = project(base, 0, high)
    # Down then up is the identity, and the projected cell lies inside the block.
    down = project(cell, high, low, anchor)  # type: ignore[arg-type]
    assert project(down, low, high) == cell
    x0, y0, x1, y1 = cell_bounds(cell, high - low)
    assert x0 <= down[0] < x1 and y0 <= down[1] < y1
    # Up from the base lands in the cell whose bounds contain the base position.
    x0, y0, x1, y1 = cell_bounds(cell, high)
    assert x0 <= x < x1 and y0 <= y < y1
    # Up in two steps equals up in one.
    assert project(project(base, 0, low), low, high) == cell


def test_cell_bounds_cover_the_grid_exactly() -> None:
    counts = np.zeros((16, 16), dtype=int)
    for y in range(4):
        for x in range(4):
            x0, y0, x1, y1 = cell_bounds((x, y), 2)
            counts[y0:y1, x0:x1] += 1
    assert (counts == 1).all()


@settings(deadline=None)  # the first call loads the compiled code
@given(st.integers(0, 2**31), st.integers(1, 60), st.integers(0, 200), st.integers(1, 8))
def test_the_compiled_grouped_components_are_scipys(
    seed: int, n: int, edge_count: int, groups: int
) -> None:
    """The build's union-find (`corridor_search.grouped_components`) labels the graph of the
    edges within each group as scipy's connected components did before it, numbered by group,
    then by first cell."""
    from anytime_navigation.planning.search import compiled
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(seed)
    side = 16
    group = np.sort(rng.integers(0, groups, n))
    first_cell = rng.permutation(side * side)[:n].astype(np.int64)  # distinct, as cells are
    a, b = rng.integers(0, n, edge_count), rng.integers(0, n, edge_count)
    keep = a != b
    low, high = np.minimum(a, b)[keep], np.maximum(a, b)[keep]
    inside = group[low] == group[high]
    graph = csr_matrix((np.ones(int(inside.sum())), (low[inside], high[inside])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    first = np.full(count, side * side, dtype=np.int64)
    np.minimum.at(first, label, first_cell)
    where = np.zeros(count, dtype=np.int64)
    where[label] = group
    order = np.argsort(where * side * side + first)
    rank = np.zeros(count, dtype=np.int64)
    rank[order] = np.arange(count)
    component, found, firsts = compiled().grouped_components(low, high, group, first_cell, side)
    assert found == count
    assert np.array_equal(component, rank[label])
    assert np.array_equal(firsts, first[order])
