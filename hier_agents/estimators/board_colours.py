"""`BoardColours`: what a camera learns of a board's colours over an episode.

For the board games' camera estimator
(`hier_agents.estimators.camera_board`), which reads each frame with a
`hier_agents.estimators.board_view.BoardView` against these colours:

* **The empty board**, per patch sample (``background``, (n, k, 3) RGB,
  NaN where not learnt yet). Learnt from the first frame (the cells empty
  in the game's initial position; when the opponent has moved first, less
  any that stand out from their row: a piece it played) and from later
  frames (cells a confirmed state says are empty), where the arm leaves
  them in view (`BoardView.clear`). `filled` lends each sample not learnt
  the median of the same sample of the three nearest cells that have it
  (of the same checkerboard parity, in its row first), so that a mark
  on one cell (a star point) is not lent; a cell of the other parity
  lends only its pattern, moved onto this cell's colour (a dark square's
  line on a light square); where no cell has it (a board full of pieces
  at the start: clobber) it is taken through the first frame's
  see-through pieces (``prior``).
* **The arm's shadow** (under a light that casts shadows, the original's
  looks). The share of light it leaves (``shade``) is measured on cells
  known empty in it (`BoardView.shade_ratios`), from the first frame on;
  it stays None (the cells in the shadow are hidden as those under the
  arm) until `SHADE_SAMPLES` samples are in.
"""

from __future__ import annotations

import warnings

import numpy as np

from envs.boards.games import BoardGame
from hier_agents.estimators.board_view import BoardView

__all__ = ["BoardColours"]

#: Learning the empty board (`BoardColours.learn`): RGB distance from the
#: row's median beyond which a sample is odd, and the largest fraction of
#: odd samples of a cell learnt.
BACKGROUND_SPREAD = 60.0
BACKGROUND_ODD = 0.3
#: The board under the first frame's pieces (`BoardColours.prior`): pieces
#: more see-through than opacity `UNMIX_ALPHA` show it; samples nearer their
#: point than `UNMIX_INSIDE` of a piece's radius see it through the piece,
#: samples farther than `UNMIX_OUTSIDE` see it bare.
UNMIX_ALPHA = 0.6
UNMIX_INSIDE = 0.9
UNMIX_OUTSIDE = 1.15
#: The arm's shadow: samples measured before ``shade`` is set, and the range
#: it is kept in (`BoardColours.learn_shade`).
SHADE_SAMPLES = 50
SHADE_RANGE = (0.2, 0.95)
#: A sample not learnt is the median of this many nearest cells' that have
#: it (`BoardColours.filled`).
DONORS = 3


class BoardColours:
    """The empty board's colours and the arm shadow's share of light, learnt
    from one episode's frames. See the module docstring.

    Args:
      view: the `BoardView` the frames are read with.
      game: the episode's `envs.boards.games.BoardGame`.
      initial: the game's initial state, settled (the position of the first frame).
      samples: (n, k, 3) the first frame's patch samples (`BoardView.samples`).
      keep: (n, k) bool, the samples of ``samples`` out of the arm's way
        (`BoardView.clear`).
      check: whether a move may already have been played on the first frame
        (the opponent moved first): then a cell whose samples stand out
        from its row's is not learnt (`learn`).

    Attributes:
      background: (n, k, 3) the empty board's colour per patch sample, NaN
        where not learnt.
      prior: (n, k, 3) the board seen through the first frame's see-through
        pieces, NaN where none lies (`prior`).
      shade: the share of light the arm's shadow leaves, in `SHADE_RANGE`,
        or None (no light that casts shadows, or not measured yet).
    """

    def __init__(self, view: BoardView, game: BoardGame, initial, samples, keep, check: bool):
        self.view, self.game = view, game
        self.background = np.full(samples.shape, np.nan)
        self.prior = self._prior(game.players(initial), samples, keep)
        self.shade: float | None = None
        self._ratios: list[np.ndarray] = []
        self._filled: np.ndarray | None = None  # `filled`'s answer until `learn` learns more
        self.learn(initial, samples, keep, check)

    @property
    def complete(self) -> bool:
        """Whether every patch sample's background is learnt."""
        return not np.isnan(self.background[..., 0]).any()

    def learn(self, state, samples, keep, check: bool = False) -> None:
        """Learns the background of the cells ``state`` says are empty, from
        their samples ``keep`` (n, k) not learnt yet (`BoardView.clear`).
        With ``check``, a cell is learnt only if at most `BACKGROUND_ODD`
        (times the view's `BoardView.scale`) of its samples kept lie farther
        than `BACKGROUND_SPREAD` from their median over the candidate cells
        of its row and parity (all of its parity's in a row with fewer than
        three): a piece already there is not taken for the board. With two
        such cells, only the samples that lie towards a piece's colour
        count; a lone cell is not learnt here."""
        view = self.view
        keep = keep & np.isnan(self.background[..., 0])
        new = keep.any(axis=1) & (self.game.players(state) < 0)
        shown = np.where(keep[..., None], samples, np.nan)
        for key in set(zip(view.row[new], view.parity[new])):
            group = np.flatnonzero(new & (view.row == key[0]) & (view.parity == key[1]))
            # Compared with its row's cells of its parity, or in a short row
            # with all of its parity's.
            pool = group if len(group) >= 3 else np.flatnonzero(new & (view.parity == key[1]))
            if check and len(pool) >= 2:
                with warnings.catch_warnings():  # a sample no cell of the pool shows
                    warnings.simplefilter("ignore", RuntimeWarning)
                    median = np.nanmedian(shown[pool], axis=0)
                odd = np.linalg.norm(samples[group] - median, axis=-1) > BACKGROUND_SPREAD
                if len(pool) == 2:
                    # The median is halfway between the two cells: the odd
                    # samples of the one holding a piece lie towards its colour.
                    d_bg, d_pieces = view.distances(
                        samples[group], np.broadcast_to(median, samples[group].shape)
                    )
                    odd &= d_pieces.min(axis=0) < d_bg
                odd = (odd & keep[group]).sum(axis=1) / keep[group].sum(axis=1)
                group = group[odd <= BACKGROUND_ODD * view.scale]
            elif check:
                continue  # a lone cell cannot be checked: learnt once confirmed empty
            if len(group):
                self.background[group] = np.where(
                    keep[group][..., None], samples[group], self.background[group]
                )
                self._filled = None

    def learn_shade(self, frame, qpos, background, state) -> None:
        """Measures how dark the arm's shadow makes the cells empty in
        ``state`` in ``frame`` (`BoardView.shade_ratios` against
        ``background``, the arm at ``qpos``) until `SHADE_SAMPLES` samples are
        in: then ``shade`` is their median (shadowed samples are then read:
        `BoardView.read`). Nothing once ``shade`` is set, nor without a light
        that casts shadows."""
        view = self.view
        if self.shade is not None or view.silhouette.light is None:
            return
        empty = self.game.players(state) < 0
        self._ratios.append(view.shade_ratios(frame, qpos, background, empty))
        ratios = np.concatenate(self._ratios)
        if len(ratios) >= SHADE_SAMPLES:
            self.shade = float(np.clip(np.median(ratios), *SHADE_RANGE))

    def filled(self) -> np.ndarray:
        """(n, k, 3): the background, each sample not learnt borrowed from
        the same sample of the nearest cells of its parity that have it
        learnt (those in its row first), else of the other parity (the
        samples lie at the same offsets from each point, so a wooden board's
        lines fall on the same samples): the median of the first `DONORS`
        such cells' (the mean of two when only two have it), so that a mark
        on one cell (a Go board's star point) is not lent to its neighbours.
        A cell of the other parity lends its sample less its own colour
        (per channel, the median of its samples learnt) plus this cell's
        (of its samples learnt, else of its parity's), clipped to 0-255: the
        squares of a checkerboard differ in colour, not in pattern; as it
        is when this cell's parity has nothing learnt. Else its cell's
        median, else ``prior``, else NaN (unknown: `BoardView.read` does not
        read it).

        The same array is returned until `learn` learns a sample: callers
        must not write to it (a copy of the background is read-only)."""
        if self._filled is None:
            self._filled = self._fill()
        return self._filled

    def _fill(self) -> np.ndarray:
        """`filled`'s answer, computed."""
        bg = self.background
        known = ~np.isnan(bg[..., 0])
        if known.all():
            return bg
        out = bg.copy()
        view = self.view
        some = np.asarray(known.any(axis=1))
        with warnings.catch_warnings():  # a cell or parity with nothing learnt
            warnings.simplefilter("ignore", RuntimeWarning)
            level = np.nanmedian(bg, axis=1)  # (n, 3): each cell's own colour
            parity_level = {
                p: np.nanmedian(bg[view.parity == p].reshape(-1, 3), axis=0)
                for p in np.unique(view.parity).tolist()
            }
        for cell in np.flatnonzero(~known.all(axis=1)).tolist():
            missing = ~known[cell]
            same = some & (view.parity == view.parity[cell])
            row = same & (view.row == view.row[cell])
            near = self._nearest
            # Across parity only the pattern is lent (each donor's samples
            # less its own colour), on this cell's colour or its parity's;
            # as they are when its parity has nothing learnt.
            own = level[cell] if some[cell] else parity_level[int(view.parity[cell])]
            shift = None if np.isnan(own).any() else own
            tiers = (
                (near(cell, row) + near(cell, same & ~row), None),
                (near(cell, some & ~same), shift),
            )
            lent = np.zeros(missing.shape, bool)
            for donors, onto in tiers:
                if not donors:
                    continue
                # Per sample still missing, the first DONORS donors that have it.
                has = known[donors] & (missing & ~lent)[None]
                use = has & (np.cumsum(has, axis=0) <= DONORS)
                lend = bg[donors]
                if onto is not None:
                    lend = np.clip(lend - level[donors][:, None] + onto, 0.0, 255.0)
                with warnings.catch_warnings():  # a sample no donor has
                    warnings.simplefilter("ignore", RuntimeWarning)
                    median = np.nanmedian(np.where(use[..., None], lend, np.nan), axis=0)
                new = use.any(axis=0)
                out[cell][new] = median[new]
                lent |= new
            rest = missing & ~lent
            if rest.any():
                out[cell][rest] = (
                    np.median(bg[cell][known[cell]], axis=0)
                    if known[cell].any()
                    else self.prior[cell][rest]
                )
        out.flags.writeable = False
        return out

    def _nearest(self, cell: int, pool) -> list[int]:
        """The cells of ``pool`` (n,) bool other than ``cell``, nearest first."""
        others = np.flatnonzero(pool)
        others = others[others != cell]
        distance = np.linalg.norm(self.view.centres[others] - self.view.centres[cell], axis=1)
        return [int(c) for c in others[np.argsort(distance, kind="stable")]]

    def _prior(self, players, samples, keep) -> np.ndarray:
        """(n, k, 3): the empty board's colour, as the pieces' colour model
        (`BoardView.distances`) sees it, from the first frame's pieces
        (``players`` (n,): each cell's player, -1 empty) where they are
        see-through (opacity below `UNMIX_ALPHA`): a board full of pieces
        (clobber's) leaves no empty cell to learn from. Per parity, sample
        by sample, the median over the cells holding such a piece of the
        samples ``keep`` (out of the arm's way): within `UNMIX_INSIDE` of a
        piece's radius from the point a sample shows alpha * piece + (1 -
        alpha) * board, beyond `UNMIX_OUTSIDE` the board itself; in between,
        the median of the others. NaN (unknown) where no such piece lies
        (opaque pieces hide the board; with square patches a piece may lie
        anywhere on its square)."""
        view = self.view
        prior = np.full(samples.shape, np.nan)
        if view.square:
            return prior
        inside = view.sample_reach < UNMIX_INSIDE * view.piece_radius
        outside = view.sample_reach > UNMIX_OUTSIDE * view.piece_radius
        for parity in np.unique(view.parity):
            layers = []
            for player in (0, 1):
                alpha = view.piece_alpha[player]
                cells = np.flatnonzero((players == player) & (view.parity == parity))
                if alpha >= UNMIX_ALPHA or not len(cells):
                    continue
                board = np.full(samples[cells].shape, np.nan)
                board[:, inside] = (samples[cells][:, inside] - alpha * view.piece_rgb[player]) / (
                    1.0 - alpha
                )
                board[:, outside] = samples[cells][:, outside]
                layers.append(np.where(keep[cells][..., None], board, np.nan))
            if not layers:
                continue
            with warnings.catch_warnings():  # a sample every such cell hides
                warnings.simplefilter("ignore", RuntimeWarning)
                median = np.nanmedian(np.concatenate(layers), axis=0)
                median = np.where(np.isnan(median), np.nanmedian(median, axis=0), median)
            prior[view.parity == parity] = np.clip(np.nan_to_num(median), 0.0, 255.0)
        return prior
