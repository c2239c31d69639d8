"""The board-game arena: a board on the floor before a Jaco arm, touch pads, pieces.

Everything is compiled once; per move only geom colours, groups and positions
change:

* **board**: a wooden box whose top is at `BOARD_TOP`; its centre is
  `BOARD_CENTRE`, in front of the arm base at the origin (the arm faces +y);
* **lines**: render-only thin boxes (a 3x3 grid of cells for tic-tac-toe,
  N x N intersections for Go);
* **touch pads**: one thin collision box per board point, invisible (group
  `HIDDEN_GROUP`), lying on the board top; Go adds two large pass pads left and
  right of the board. A contact between a pad and a registering arm geom is a
  touch;
* **pieces**: one render-only cylinder per point, hidden while the point is
  empty, coloured and moved when a piece appears. Pieces never collide.

Point ``a`` of an N x N board sits at row ``a // N`` and column ``a % N``;
rows grow away from the arm when ``rows_away`` (Go: GTP row 1 nearest the
arm), towards it otherwise (tic-tac-toe: OpenSpiel's first printed row is the
far one).
"""

from __future__ import annotations

import numpy as np
from dm_control import composer, mjcf

HIDDEN_GROUP = 5
BOARD_CENTRE = (0.0, 0.5)
BOARD_THICKNESS = 0.02
BOARD_TOP = BOARD_THICKNESS
PAD_HALF_HEIGHT = 0.002
#: Largest span of the playing area (Go: first to last line; tic-tac-toe: 3 cells).
MAX_SPAN = 0.36
PASS_PAD_WIDTH = 0.08

COLOURS = {
    "tic_tac_toe": ((0.8, 0.15, 0.15, 1.0), (0.15, 0.3, 0.85, 1.0)),  # agent X red, O blue
    "go": ((0.05, 0.05, 0.05, 1.0), (0.95, 0.95, 0.95, 1.0)),  # black, white
}


class BoardArena(composer.Arena):
    """Floor, board, lines, touch pads, piece pool, lights and the front camera."""

    def _build(self, kind="go", size=7, offscreen_size=(256, 256), name="board_arena"):
        self._mjcf_root = mjcf.RootElement(model=name)
        root = self._mjcf_root
        self.kind, self.size = kind, int(size)
        n = self.size
        if kind == "tic_tac_toe":
            self.spacing = MAX_SPAN / 3  # cell side
            half_board = 1.5 * self.spacing + 0.03
            pad_half = 0.45 * self.spacing
            self.rows_away = False
        else:
            self.spacing = min(0.05, MAX_SPAN / (n - 1))  # line spacing
            half_board = (n - 1) / 2 * self.spacing + 0.6 * self.spacing
            pad_half = 0.5 * self.spacing  # pads tile the board
            self.rows_away = True
        self.half_board = half_board
        self.pad_half = pad_half

        root.option.timestep = 0.005
        root.option.integrator = "implicitfast"
        root.compiler.boundmass = 1e-5
        root.compiler.boundinertia = 1e-11
        root.visual.quality.shadowsize = 0
        root.visual.quality.offsamples = 0
        root.visual.__getattr__("global").offheight = int(offscreen_size[0])
        root.visual.__getattr__("global").offwidth = int(offscreen_size[1])
        root.visual.headlight.ambient = (0.4, 0.4, 0.4)
        root.visual.headlight.diffuse = (0.6, 0.6, 0.6)
        root.visual.map.znear = 0.01

        root.asset.add("texture", name="sky", type="skybox", builtin="gradient",
                       rgb1=(0.4, 0.6, 0.8), rgb2=(0.1, 0.1, 0.15), width=64, height=64)
        grid = root.asset.add("texture", name="floor_tex", type="2d", builtin="checker",
                              rgb1=(0.45, 0.5, 0.45), rgb2=(0.4, 0.45, 0.4), width=64, height=64)
        floor_mat = root.asset.add("material", name="floor_mat", texture=grid, texrepeat=(6, 6))
        root.worldbody.add("light", name="sun", directional=True, castshadow=False,
                           pos=(0, 0, 3), dir=(0.2, 0.3, -1), diffuse=(0.5, 0.5, 0.5))
        self.floor = root.worldbody.add("geom", name="floor", type="plane", size=(2, 2, 0.1),
                                        material=floor_mat, contype=1, conaffinity=1)
        cx, cy = BOARD_CENTRE
        board_rgba = (0.85, 0.65, 0.35, 1) if kind == "go" else (0.92, 0.92, 0.88, 1)
        self.board = root.worldbody.add(
            "geom", name="board", type="box", size=(half_board, half_board, BOARD_THICKNESS / 2),
            pos=(cx, cy, BOARD_THICKNESS / 2), rgba=board_rgba, contype=1, conaffinity=1)

        line_rgba = (0.1, 0.08, 0.05, 1)
        line_half = 0.0015
        z = BOARD_TOP + 0.0005
        if kind == "tic_tac_toe":
            offsets = (-0.5 * self.spacing, 0.5 * self.spacing)
            extent = 1.5 * self.spacing
        else:
            offsets = [(k - (n - 1) / 2) * self.spacing for k in range(n)]
            extent = (n - 1) / 2 * self.spacing
        for k, o in enumerate(offsets):
            root.worldbody.add("geom", name=f"line_x_{k}", type="box", pos=(cx, cy + o, z),
                               size=(extent + line_half, line_half, 0.0005), rgba=line_rgba,
                               contype=0, conaffinity=0)
            root.worldbody.add("geom", name=f"line_y_{k}", type="box", pos=(cx + o, cy, z),
                               size=(line_half, extent + line_half, 0.0005), rgba=line_rgba,
                               contype=0, conaffinity=0)

        pad_z = BOARD_TOP + PAD_HALF_HEIGHT
        self.pads = []
        self.point_xy = np.zeros((n * n, 2))
        for a in range(n * n):
            x, y = self.point_position(a)
            self.point_xy[a] = (x, y)
            self.pads.append(root.worldbody.add(
                "geom", name=f"pad_{a}", type="box", pos=(x, y, pad_z),
                size=(pad_half, pad_half, PAD_HALF_HEIGHT), group=HIDDEN_GROUP,
                rgba=(0.2, 0.8, 0.2, 0.3), contype=1, conaffinity=1))
        self.pass_pads = []
        if kind == "go":
            for side, sign in (("left", -1), ("right", 1)):
                self.pass_pads.append(root.worldbody.add(
                    "geom", name=f"pass_pad_{side}", type="box",
                    pos=(cx + sign * (half_board + 0.01 + PASS_PAD_WIDTH / 2), cy, pad_z),
                    size=(PASS_PAD_WIDTH / 2, half_board, PAD_HALF_HEIGHT),
                    rgba=(0.3, 0.3, 0.3, 1), contype=1, conaffinity=1))
        piece_radius = (0.4 if kind == "tic_tac_toe" else 0.45) * self.spacing
        self.piece_radius = piece_radius
        self.piece_half_height = 0.006
        self.pieces = [
            root.worldbody.add("geom", name=f"piece_{a}", type="cylinder",
                               size=(piece_radius, self.piece_half_height),
                               pos=(0, 0, -1), group=HIDDEN_GROUP, contype=0, conaffinity=0,
                               rgba=COLOURS[kind][0])
            for a in range(n * n)]
        # Facing the arm and the board from the far side of the board.
        self.front_camera = root.worldbody.add(
            "camera", name="front_camera", pos=(cx, cy + 0.6, 0.6),
            xyaxes=(-1, 0, 0, 0, -0.6, 0.8), fovy=60)

    def point_position(self, action: int) -> tuple[float, float]:
        """World (x, y) of board point ``action``."""
        n = self.size
        row, col = divmod(int(action), n)
        cx, cy = BOARD_CENTRE
        step = self.spacing
        x = cx + (col - (n - 1) / 2) * step
        offset = (row - (n - 1) / 2) * step
        y = cy + offset if self.rows_away else cy - offset
        return x, y

    @property
    def mjcf_model(self):
        return self._mjcf_root
