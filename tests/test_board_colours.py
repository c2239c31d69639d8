"""`hier_agents.estimators.board_colours.BoardColours.filled`: what an
unlearnt cell of the empty board is taken to look like."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hier_agents.estimators.board_colours import BoardColours

WOOD = np.array([240.0, 215.0, 135.0])
LINE = np.array([190.0, 135.0, 90.0])
STAR = np.array([20.0, 20.0, 20.0])


def _colours(background: np.ndarray) -> BoardColours:
    """A `BoardColours` of one row of cells, one unit apart, alternating in
    parity, with ``background`` (n, k, 3) learnt (NaN where not)."""
    n = len(background)
    colours = BoardColours.__new__(BoardColours)
    colours.view = SimpleNamespace(
        row=np.zeros(n, int),
        parity=np.arange(n) % 2,
        centres=np.stack([np.zeros(n), np.arange(n, dtype=float)], axis=1),
    )
    colours.game = SimpleNamespace(players=lambda state: np.full(n, -1))  # all empty
    colours.background = background
    colours.prior = np.full(background.shape, np.nan)
    colours._filled = None
    return colours


def _row(n: int = 7, k: int = 4) -> np.ndarray:
    """(n, k, 3): wood with a line on every cell's last sample."""
    background = np.broadcast_to(WOOD, (n, k, 3)).copy()
    background[:, -1] = LINE
    return background


def test_a_mark_on_one_cell_is_not_lent_to_its_neighbours():
    """Cell 4 is not learnt; its nearest cells of its parity are 2 (a star
    point on its first sample) and 6, then 0. It is lent their median, sample
    by sample: wood and the line, not the star point."""
    background = _row()
    background[2, 0] = STAR
    background[4] = np.nan
    filled = _colours(background).filled()
    np.testing.assert_array_equal(filled[4], _row()[4])
    np.testing.assert_array_equal(filled[2], background[2])  # a learnt cell is kept


def test_a_sample_only_some_cells_have_is_lent_by_the_nearest_that_have_it():
    """Only cell 0 has sample 1 learnt (of parity 0): cell 4 borrows it from
    there; its other samples are the median of cells 2, 6 and 0."""
    background = _row()
    background[[2, 6], 1] = np.nan
    background[0, 1] = [100.0, 100.0, 100.0]
    background[4] = np.nan
    filled = _colours(background).filled()
    np.testing.assert_array_equal(filled[4, 1], [100.0, 100.0, 100.0])
    np.testing.assert_array_equal(filled[4, [0, 2, 3]], _row()[4, [0, 2, 3]])


def test_two_cells_lend_their_mean_and_none_leaves_the_sample_unknown():
    """A board of three cells: cell 1 is lent the mean of cells 0 and 2
    (its parity has no cell learnt: the others lend); with nothing learnt
    at all, nothing is lent (NaN: not read)."""
    background = _row(n=3)
    background[2, 0] = WOOD + 20.0
    background[1] = np.nan
    filled = _colours(background).filled()
    np.testing.assert_array_equal(filled[1, 0], WOOD + 10.0)
    np.testing.assert_array_equal(filled[1, 1:], _row(n=3)[1, 1:])
    assert np.isnan(_colours(np.full((3, 4, 3), np.nan)).filled()).all()


def test_across_parity_only_the_pattern_is_lent_on_the_cells_own_colour():
    """A checkerboard row: dark cells (0, 2, 4) learnt whole, with a line on
    their last sample; the light cells have only cell 1's first sample
    learnt. The dark cells lend their pattern (the line 40 below their
    colour), not their colour: cell 1 is light with the line 40 below it,
    and cell 3 (nothing of its own) takes its parity's colour from cell 1."""
    dark, light = np.array([76.0, 76.0, 76.0]), np.array([250.0, 240.0, 230.0])
    background = np.full((5, 4, 3), np.nan)
    background[[0, 2, 4]] = dark
    background[[0, 2, 4], -1] = dark - 40.0
    background[1, 0] = light
    filled = _colours(background).filled()
    for cell in (1, 3):
        np.testing.assert_array_equal(filled[cell, :-1], np.broadcast_to(light, (3, 3)))
        np.testing.assert_array_equal(filled[cell, -1], light - 40.0)
    np.testing.assert_array_equal(filled[[0, 2, 4]], background[[0, 2, 4]])


def test_the_filled_board_is_kept_until_a_sample_is_learnt():
    """`filled` answers with the same read-only array while nothing is
    learnt, and a sample learnt afterwards shows in its next answer (not
    the one lent before)."""
    background = _row()
    background[4] = np.nan
    colours = _colours(background)
    before = colours.filled()
    assert colours.filled() is before and not before.flags.writeable
    seen = np.broadcast_to(WOOD + 5.0, background.shape)
    keep = np.zeros(background.shape[:2], bool)
    keep[4] = True
    colours.learn(None, seen, keep)
    np.testing.assert_array_equal(colours.filled()[4], seen[4])
    np.testing.assert_array_equal(before[4], _row()[4])
