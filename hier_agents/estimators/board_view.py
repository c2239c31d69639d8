"""`BoardView`: one camera frame of a board read cell by cell.

For the board games' camera estimator (`hier_agents.estimators.camera_board`):
the points come from the task's description, the pieces' colours from the
game's rules (`envs.boards.games.GameRules.colours`), the selection disc's
from the arena's look (`envs.boards.arena.SELECTION_RGBA`).

* **Cells.** Each point's patch is a disc of `PATCH` half-spacings around
  the point, projected into the frame with the described camera. Where a
  piece may lie farther from its point than its own radius
  (``piece_spread`` > ``piece_radius`` in the description: MuJoXO's small
  markers, anywhere on their touch pad) it may miss that disc, and part of
  it may show on the next square: the patch is then the point's whole
  square (`SQUARE_SAMPLES` per side, on a grid that runs on evenly across
  the board), each patch of piece colour that hangs together on that grid
  counts wholly for the square its centre lies on (one much larger than a
  piece, `MERGED` times, two pieces touching, is left split by square), and `OCCUPIED`,
  `EMPTY` and the reported fractions are scaled by a piece's share of the
  square against its share of a disc patch (`REFERENCE_SHARE`); a cell
  more than `HIDDEN_PIECE` of a piece's share under the arm is then never
  read empty (the piece could hide there).
* **The arm.** The arm's own model is posed at the observed joints; each of
  its geoms' convex hulls is projected, and the patch samples within
  `ARM_MARGIN` pixels of one are not read; a cell with less than
  `MIN_VISIBLE` of its samples left is hidden this frame.
* **Pieces.** A sample shows player p's piece when it is nearer to that
  piece's colour over the empty board there (the game's rgba, blended by
  its alpha) than to the empty board and to the other piece, and within
  `PIECE_RADIUS` (RGB, 0-255) of it. A visible cell holds a player's piece
  when at least `OCCUPIED` of its patch shows it, is empty when at most
  `EMPTY` shows either, and is unsure otherwise.
* **Selection** (move games): the cell whose ring (`RING`, around its
  piece) shows the most of the selection disc's colour, at least `SELECTED`
  of it; a selection hidden under the arm is remembered.

The empty board's colour per patch sample (``background``) and the share
of light the arm's shadow leaves (``shade``) are the caller's: the
estimator learns them (`hier_agents.estimators.board_colours.BoardColours`).
"""

from __future__ import annotations

import numpy as np

from envs.boards.arena import SELECTION_RGBA
from envs.boards.games import BoardGame
from hier_agents.estimators.arm_silhouette import ArmSilhouette
from hier_agents.estimators.base import EstimationError

__all__ = ["BoardView", "UNSEEN", "EMPTY_CELL"]

#: A cell's patch radius, in half-spacings between neighbouring points.
PATCH = 0.8
#: Height (m) above the board's top at which patches are projected (a piece's top half).
PATCH_HEIGHT = 0.005
#: Pixels: how near a patch sample may come to the arm's outline and still be
#: read; a cell with less than `MIN_VISIBLE` of its samples read is hidden.
ARM_MARGIN = 1.5
MIN_VISIBLE = 0.6
#: RGB distance (0-255) within which a pixel has a piece's colour.
PIECE_RADIUS = 110.0
#: RGB distance within which a pixel has the selection disc's colour.
SELECTION_RADIUS = 90.0
#: Fractions of a patch: a piece when at least `OCCUPIED` has its colour,
#: empty when at most `EMPTY` has a piece colour.
OCCUPIED = 0.3
EMPTY = 0.1
#: Radii (half-spacings) of the rings read for the selection disc, which
#: shows between a piece's edge (0.7) and the disc's (0.95).
RING = (0.8, 0.9)
#: Fraction of a cell's ring showing the selection disc's colour that marks
#: a selection; the arm can hide the disc but never shows its colour, so a
#: partly hidden ring still counts.
SELECTED = 0.15
#: The square patch (see the module docstring): samples per side; a piece's
#: share of a disc patch that `OCCUPIED` and `EMPTY` are set for (a piece of
#: 0.7 half-spacings); the share of a piece that may hide under the arm in a
#: cell read empty; how many pieces' worth of samples one patch of piece
#: colour may have and still count for one square.
SQUARE_SAMPLES = 11
REFERENCE_SHARE = (0.7 / PATCH) ** 2
HIDDEN_PIECE = 0.6
MERGED = 1.6

#: Background samples darker than this (RGB norm) tell nothing of a shadow's share.
SHADE_FLOOR = 60.0

UNSEEN = -2  # a cell not read this frame (hidden or unsure)
EMPTY_CELL = -1  # a cell read empty


def _lit_distance(px, colour, shade: float) -> np.ndarray:
    """RGB distance of ``px`` (..., 3) from ``colour`` (broadcast) under the
    share of light in [``shade``, 1] that brings it nearest."""
    fit = (px * colour).sum(-1) / np.maximum((colour**2).sum(-1), 1.0)
    return np.linalg.norm(px - np.clip(fit, shade, 1.0)[..., None] * colour, axis=-1)


class BoardView:
    """Reads one frame of a board: each cell's piece (or none, or unsure)
    and the selected cell. See the module docstring.

    Args:
      description: the task's `envs.description.BoardDescription`.
      game: its `envs.boards.games.BoardGame`.
      camera: the `envs.description.CameraDescription` of the frames read.

    Attributes:
      square: whether cells are read over their whole square.
      occupied, empty: the `OCCUPIED` and `EMPTY` fractions this board reads with.
      scale: their ratio to `OCCUPIED` and `EMPTY` (1 with disc patches).
    """

    def __init__(self, description, game: BoardGame, camera) -> None:
        if camera is None or camera.shape is None:
            raise EstimationError("the camera the board view reads is off (its shape is None)")
        self.camera, self.shape = camera, tuple(camera.shape)
        points = np.asarray(description.point_positions, float)
        n = len(points)
        gaps = np.linalg.norm(points[:, None, :2] - points[None, :, :2], axis=-1)
        gaps[np.arange(n), np.arange(n)] = np.inf
        half = 0.5 * float(gaps.min())
        #: Half the distance between neighbouring points (m).
        self.half = half
        self.points_xy = points[:, :2]
        piece_radius = float(description.piece_radius)
        self.square = float(description.piece_spread) > piece_radius
        if self.square:
            # Sub-square centres: the grid runs on evenly from square to square.
            grid = (2 * np.arange(SQUARE_SAMPLES) + 1) / SQUARE_SAMPLES - 1
            offsets = np.array([(x, y) for x in grid for y in grid])
            share = np.pi * (piece_radius / half) ** 2 / 4.0  # a piece's share of its square
            self.scale, self.hidden_empty = share / REFERENCE_SHARE, HIDDEN_PIECE * share
            reach = 1.0
        else:
            grid = np.linspace(-1, 1, 9)
            offsets = np.array([(x, y) for x in grid for y in grid if x * x + y * y <= 1.0])
            self.scale, self.hidden_empty = 1.0, 1.0
            reach = PATCH
        self.occupied, self.empty = OCCUPIED * self.scale, EMPTY * self.scale
        #: (k,) each patch sample's distance from its point on the board (m),
        #: and a piece's radius there.
        self.sample_reach = reach * half * np.linalg.norm(offsets, axis=1)
        self.piece_radius = piece_radius
        world = (
            points[:, None, :]
            + np.c_[reach * half * offsets, np.full(len(offsets), PATCH_HEIGHT)][None]
        )
        if self.square:
            # Each sample's place on the board-wide grid, and a piece's worth of samples.
            step = 2 * half / SQUARE_SAMPLES
            xy = world[..., :2] - world[..., :2].reshape(-1, 2).min(axis=0)
            self.grid_at = np.rint(xy / step).astype(int)  # (n, k, 2)
            self.grid_shape = tuple(self.grid_at.reshape(-1, 2).max(axis=0) + 1)
            self.sample_xy = world[..., :2]
            self.piece_samples = share * len(offsets)
        px = camera.project(world, self.shape)
        h, w = self.shape
        rows = np.clip(np.floor(px[..., 0]).astype(int), 0, h - 1)
        cols = np.clip(np.floor(px[..., 1]).astype(int), 0, w - 1)
        self.index = rows * w + cols  # (n, k) flat pixel of each sample
        self.sample_px = px  # (n, k, 2) their (row, col)
        angles = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ring = np.concatenate(
            [r * np.stack([np.cos(angles), np.sin(angles)], axis=1) for r in RING]
        )
        world = points[:, None, :] + np.c_[half * ring, np.zeros(len(ring))][None]
        px = camera.project(world, self.shape)
        self.ring = np.clip(np.floor(px[..., 0]).astype(int), 0, h - 1) * w + np.clip(
            np.floor(px[..., 1]).astype(int), 0, w - 1
        )
        self.centres = camera.project(points + [0, 0, PATCH_HEIGHT], self.shape)
        radius = np.maximum(
            np.linalg.norm(px - self.centres[:, None], axis=-1).max(axis=1),
            np.linalg.norm(self.sample_px - self.centres[:, None], axis=-1).max(axis=1),
        )
        #: Each patch's radius in pixels plus `ARM_MARGIN`: a cell wholly clear of the arm.
        self.radius = radius + ARM_MARGIN
        colours = game.rules.colours
        self.piece_rgb = np.array([c[:3] for c in colours], float) * 255.0
        self.piece_alpha = np.array([c[3] for c in colours], float)
        #: Each cell's row, and its parity: on a checkerboard (`GameRules.look`
        #: ``"checker"``) its square's colour, else 0 for every cell (one
        #: colour of tile or wood throughout). A background learnt on one
        #: cell stands in for an unlearnt cell of the same parity, its row's
        #: first (the light falls off towards the board's edges); a cell of
        #: the other parity lends only its pattern (`BoardColours.filled`).
        self.row = np.arange(n) // description.cols
        checker = game.rules.look == "checker"
        self.parity = (self.row + np.arange(n) % description.cols) % 2 * int(checker)
        self.selection_rgb = np.array(SELECTION_RGBA[:3], float) * 255.0
        self.silhouette = ArmSilhouette(
            description.arm,
            camera,
            self.shape,
            light=getattr(description, "shadow_light", None),
            plane_z=float(np.median(points[:, 2])),
        )

    def clear(self, qpos, cells=None) -> np.ndarray:
        """(n, k) bool: the patch samples that show the board, not the arm
        posed at ``qpos``, and may be learnt as the empty board: with disc
        patches all of each cell wholly clear of the arm (none of it within
        `radius` pixels of its centre), or of each cell in ``cells`` (n,)
        bool when given (a cell read empty) clear of the arm's shadow; with
        square patches each
        sample farther than `ARM_MARGIN` pixels from it, of the cells
        (``cells``, else those with at least `MIN_VISIBLE` of them)."""
        n, k = self.index.shape
        if not self.square:
            if cells is None:
                whole = ~self.silhouette.hidden(qpos, self.centres, self.radius)
            else:
                whole = np.asarray(cells, bool)
                if self.silhouette.light is not None:  # read in the shadow: not as the board
                    whole = whole & ~self.silhouette.hidden(
                        qpos, self.centres, self.radius, part="shadow"
                    )
            return np.repeat(whole[:, None], k, axis=1)
        shown = ~self.silhouette.hidden(
            qpos, self.sample_px.reshape(-1, 2), ARM_MARGIN + 0.5
        ).reshape(n, k)
        keep = shown.mean(axis=1) >= MIN_VISIBLE if cells is None else np.asarray(cells, bool)
        return shown & keep[:, None]

    def samples(self, frame) -> np.ndarray:
        """(n, k, 3) float RGB of each cell's patch samples in ``frame``."""
        img = np.asarray(frame, float).reshape(-1, 3)
        if img.shape[0] != self.shape[0] * self.shape[1]:
            raise EstimationError(
                f"{self.camera.name} frames are {np.asarray(frame).shape[:2]}, "
                f"the description says {self.shape}"
            )
        return img[self.index]

    def distances(self, px, background, shade: float | None = None):
        """(d_bg, d_pieces): the RGB distances of samples ``px`` (..., 3) from
        ``background`` (same shape) and, stacked on a first axis of 2, from
        each player's piece over it (its rgba blended with alpha). Under a
        light that casts shadows (``shade``: the share of light a shadow
        leaves), each colour is taken at the light between ``shade`` and
        all that brings it nearest (in the arm's shadow, at its edge, or
        lit), and a piece may shade the board it shows through: the
        nearer of the two."""
        alpha = self.piece_alpha.reshape((2,) + (1,) * px.ndim)
        own = alpha * self.piece_rgb.reshape((2,) + (1,) * (px.ndim - 1) + (3,))
        pieces = own + (1 - alpha) * background[None]
        if shade is None:
            return (
                np.linalg.norm(px - background, axis=-1),
                np.linalg.norm(px[None] - pieces, axis=-1),
            )
        shaded = own + (1 - alpha) * shade * background[None]
        return _lit_distance(px, background, shade), np.minimum(
            _lit_distance(px[None], pieces, shade), _lit_distance(px[None], shaded, shade)
        )

    def read(self, frame, qpos, background, shade: float | None = None):
        """(cells, hidden, selection, fractions) of one frame.

        ``background`` (n, k, 3): each patch sample's colour on the empty
        board (a selected cell's is the selection disc). A sample shows
        player p's piece when it is nearer to that piece's colour over the
        background (its rgba blended with alpha) than to the background and
        to the other piece, and within `PIECE_RADIUS` of it. Under a light
        that casts shadows the samples in the arm's shadow are read when
        ``shade`` (the share of light the shadow leaves: `shade_ratios`)
        is given, each colour at the light that fits it best (`distances`),
        and are hidden with the arm's when it is None. A sample whose board
        colour is unknown (NaN in ``background``) is not read.

        Returns ``cells`` (n,) int8: 0 or 1 (a player's piece), -1 (empty)
        or `UNSEEN` (hidden or unsure); ``hidden`` (n,) bool: under the arm;
        ``selection`` (n,) float: the fraction of each cell's ring showing
        the selection disc's colour; ``fractions`` (n, 2): the fraction of
        each patch showing each player's piece (divided by `scale`, at most 1).
        """
        px = self.samples(frame)
        unknown = np.isnan(background[..., 0])
        background = np.nan_to_num(background)
        img = np.asarray(frame, float).reshape(-1, 3)
        selection = (
            np.linalg.norm(img[self.ring] - self.selection_rgb, axis=-1) < SELECTION_RADIUS
        ).mean(axis=1)
        # A selected piece stands on the selection disc, seen through it.
        background = np.where(
            (selection >= SELECTED)[:, None, None], self.selection_rgb, background
        )
        # Not read: samples where the board's colour is unknown, and those
        # within ARM_MARGIN pixels of the arm's outline or its shadow's; with
        # a known ``shade``, those in the shadow are read (`distances`), but
        # not within twice the margin of the arm itself (a finger drawn off
        # its model, dark as a black stone, is no longer kept apart by its
        # shadow's outline). A cell with less than MIN_VISIBLE of its
        # samples read is hidden.
        n, k = self.index.shape
        flat = self.sample_px.reshape(-1, 2)
        if self.silhouette.light is None:
            shade = None
        if shade is None:
            near = self.silhouette.hidden(qpos, flat, ARM_MARGIN + 0.5)
        else:
            near = self.silhouette.hidden(qpos, flat, 2 * ARM_MARGIN + 0.5, part="arm")
        covered = unknown | near.reshape(n, k)
        d_bg, (d0, d1) = self.distances(px, background, shade)
        shown = (~covered).sum(axis=1)
        hidden = shown < MIN_VISIBLE * k
        is0 = (d0 < PIECE_RADIUS) & (d0 < d_bg) & (d0 < d1) & ~covered
        is1 = (d1 < PIECE_RADIUS) & (d1 < d_bg) & (d1 <= d0) & ~covered
        counts = (
            [self._by_centre(is0), self._by_centre(is1)]
            if self.square
            else [is0.sum(axis=1), is1.sum(axis=1)]
        )
        f0, f1 = (c / np.maximum(shown, 1) for c in counts)
        cells = np.full(len(px), UNSEEN, np.int8)
        cells[(f0 >= self.occupied) & (f0 >= f1)] = 0
        cells[(f1 >= self.occupied) & (f1 > f0)] = 1
        cells[(f0 + f1 <= self.empty) & (k - shown <= self.hidden_empty * k)] = EMPTY_CELL
        cells[hidden] = UNSEEN
        fractions = np.stack([f0, f1], axis=1)
        return cells, hidden, selection, np.minimum(fractions / self.scale, 1.0)

    def shaded(self, qpos) -> np.ndarray:
        """(n, k) bool: the patch samples wholly in the arm's shadow (more
        than `ARM_MARGIN` pixels inside it) and clear of the arm itself;
        none without a light casting shadows."""
        n, k = self.index.shape
        if self.silhouette.light is None:
            return np.zeros((n, k), bool)
        flat, margin = self.sample_px.reshape(-1, 2), ARM_MARGIN + 0.5
        deep = self.silhouette.hidden(qpos, flat, -margin, part="shadow")
        return (deep & ~self.silhouette.hidden(qpos, flat, margin, part="arm")).reshape(n, k)

    def shade_ratios(self, frame, qpos, background, cells) -> np.ndarray:
        """The brightness (RGB norm) of the samples `shaded` in ``frame`` of
        the ``cells`` (n,) bool known empty, over their ``background``'s:
        each a measure of the share of light the arm's shadow leaves."""
        mask = self.shaded(qpos) & np.asarray(cells, bool)[:, None]
        lit = np.linalg.norm(background[mask], axis=-1)
        dark = np.linalg.norm(self.samples(frame)[mask], axis=-1)
        keep = lit > SHADE_FLOOR
        return dark[keep] / lit[keep]

    def _by_centre(self, mask) -> np.ndarray:
        """(n,) samples of piece colour per cell, square patches: each patch of
        ``mask`` (n, k) that hangs together on the board-wide grid counts
        for the cell nearest its centre, unless it has more than `MERGED`
        pieces' worth of samples (then each cell keeps its own)."""
        from scipy import ndimage

        grid = np.zeros(self.grid_shape, bool)
        grid[self.grid_at[..., 0][mask], self.grid_at[..., 1][mask]] = True
        labels, count = ndimage.label(grid)
        of = labels[self.grid_at[..., 0], self.grid_at[..., 1]] * mask  # (n, k); 0: none
        counts = np.zeros(len(mask))
        for label in range(1, count + 1):
            members = of == label
            size = members.sum()
            if size > MERGED * self.piece_samples:
                counts += members.sum(axis=1)
                continue
            centre = self.sample_xy[members].mean(axis=0)
            counts[np.argmin(np.linalg.norm(self.points_xy - centre, axis=1))] += size
        return counts
