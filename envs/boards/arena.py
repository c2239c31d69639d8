"""The board-game arena of the original MuJoXO / MuJoGo (Mirza et al. 2020).

The world frame is the original's: the board lies at the origin on the floor
and the Jaco arm's base is attached at ``ARM_OFFSET = (0, 0.4, 0)``, so the
arm reaches towards -y. Everything is compiled once; per move only the
pieces' colours, groups and positions change.

* **board**: a static body ``board`` holding one box geom per square
  (half-width ``SQUARE_HALF`` = 0.05 m, 0.02 m thick, top at ``BOARD_TOP``).
  Tic-tac-toe's 3x3 squares are the board (a grey checkerboard) centred at
  the origin; Go has one wooden box under 7x7 invisible square geoms centred
  on the line intersections (0.10 m apart), the whole board shifted by
  ``GO_Y_OFFSET`` = -0.08 m (its centre 0.48 m from the arm base);
* **touch sensors**: a MuJoCo touch sensor on a box site of half-size
  ``SENSOR_FRACTION`` (0.7) x ``SQUARE_HALF`` per square, at the board top,
  so there are gaps between sensors. A touch sensor sums the normal force of
  every contact of the board body whose point lies inside its site. Go adds
  a *pass* geom and sensor at floor level under the board, half-size
  (2 x 0.35, 0.35): the parts left and right of the board are the pass areas;
* **contact sensors** (see `envs.boards.task`) record which square geoms the
  fingers touch and where;
* **lines** (Go): render-only thin boxes on the board;
* **pieces**: one render-only cylinder per point, hidden while the point is
  empty, taller for a promoted piece (checkers' kings). Pieces never
  collide. Move games add a render-only yellow disc under the selected
  piece (``selection``).

Other OpenSpiel games (`envs.boards.games.GAMES`) are laid out from their
rules: the board centred like Go's and as wide or as deep as the 7x7 Go
board (`GO_REFERENCE_SIZE` x 0.10 m), a square grid or a hex
rhombus (each row shifted by half a point), with checker squares, plain
tiles or a wooden board with lines (`GameRules.look`).

Point ``a`` of an N x N board sits at row ``a // N`` and column ``a % N``;
column 0 is at -x, row 0 is the row farthest from the arm (-y) and rows grow
towards the arm, in both games as in the original (tic-tac-toe: OpenSpiel's
first printed row is the far one; Go: GTP row 1 is the far one).

Physics options are composer's defaults, as in the original: timestep 2 ms,
Euler integrator, elliptic friction cones, 5 noslip iterations; the floor has
friction 0.4, solimp (0.95, 0.99, 0.001), solref (0.002, 1).
"""

from __future__ import annotations

import numpy as np
from dm_control import composer

from envs.boards import games as games_lib

HIDDEN_GROUP = 5
#: Where the arm's base is attached (the original's ``_ARM_Y_OFFSET``).
ARM_OFFSET = (0.0, 0.4, 0.0)
#: Half-width of a board square (the original's ``square_halfwidth``).
SQUARE_HALF = 0.05
#: Half-height of the square boxes; their top is at ``2 * SQUARE_HALF_HEIGHT``.
SQUARE_HALF_HEIGHT = 0.01
BOARD_TOP = 2 * SQUARE_HALF_HEIGHT
#: Touch-sensor sites are this fraction of a square's half-width.
SENSOR_FRACTION = 0.7
#: The Go board's shift along y (towards the far side).
GO_Y_OFFSET = -0.08
#: Activation threshold of the touch sensors (N).
TOUCH_THRESHOLD = 1e-3
#: Original Go board size; other sizes shrink the squares to keep its width.
GO_REFERENCE_SIZE = 7

#: Colour (rgba) of the plain tiles (`GameRules.look` ``"plain"``).
PLAIN_TILE = (0.16, 0.45, 0.24, 1.0)
#: Colour (rgba) of the disc under a selected piece (move games).
SELECTION_RGBA = (1.0, 0.85, 0.0, 1.0)
#: A promoted piece's height, in plain pieces' heights.
KING_HEIGHT = 2.5
#: The light's position (m): above the board's centre, pointing down (the original's).
LIGHT_POS = (0.0, 0.0, 1.5)
#: Side (texels) of the shadow map with ``shadows``: the original leaves
#: MuJoCo's 4096. At 84x84 with 4 samples a 1024-texel map draws frames
#: within `SHADOW_MAP_BOUND` of the 4096-texel map's (measured: 0.05 and 0.17
#: of 255 on average on MuJoXO and MuJoGo, 0.1% and 0.4% of pixels off by
#: more than 8, on shadow edges) at about a third of its cost
#: (``benchmarks/board_looks.py``, results/board_looks.json).
SHADOW_MAP_SIZE = 1024
#: The bound the tests hold `SHADOW_MAP_SIZE` to against MuJoCo's 4096-texel
#: map: (mean absolute difference per channel of 255, share of pixels off by
#: more than 8 in some channel).
SHADOW_MAP_BOUND = (0.5, 0.01)
#: Marker (cylinder) radius and half-height, as the original's; other games'
#: pieces have `PIECE_FRACTION` of a square's half-width as radius.
PIECE_SIZE = {"tic_tac_toe": (0.025, 0.01), "go": (0.04, 0.01)}
PIECE_FRACTION = 0.7


class BoardArena(composer.Arena):
    """Floor, board, squares with touch sensors, pieces, light and the front camera.

    Args:
      game: the `envs.boards.games.BoardGame` (its rules give the layout).
      offscreen_size: largest (height, width) rendered.
      physics_timestep: seconds (the original's 0.002).
      multisamples: samples per pixel of rendered frames (the original's 4).
      shadows: the light casts shadows (the original's does).
    """

    def _build(
        self,
        game=None,
        offscreen_size=(256, 256),
        physics_timestep=0.002,
        multisamples=0,
        shadows=False,
        name="board_arena",
    ):
        # composer's base arena: timestep 2 ms, elliptic cones, noslip 5.
        super()._build(name=name)
        if game is None:
            from envs.boards.games import BoardGame

            game = BoardGame("go", GO_REFERENCE_SIZE)
        self._set_layout(game)
        rules = game.rules

        self._add_scene(offscreen_size, physics_timestep, multisamples, shadows)
        board, sensor_mat = self._add_points()
        self.pass_geom = self.pass_site = None
        if rules.pass_zones:
            self._add_pass_zones(board, sensor_mat)
        if rules.look == "wood":
            self._add_lines(board)
        elif rules.look == "plain" and not self.hex:
            self._add_lines(board, between=True)
        self._add_pieces(game)
        self._add_cameras()

    def _set_layout(self, game) -> None:
        """The board's geometry from the game's rules: point spacing, square
        and sensor half-sizes, the board's centre and half-extents."""
        self.game = game
        self.kind, self.size = game.name, game.size
        self.rows, self.cols = game.rows, game.cols
        self.hex = game.rules.layout == "hex"
        if game.name == "tic_tac_toe":
            spacing = 2 * SQUARE_HALF
            self.centre = (0.0, 0.0)
        else:  # the 7x7 Go board's extent (7 x 0.10 m) for every board
            spacing = (
                2
                * SQUARE_HALF
                * GO_REFERENCE_SIZE
                / max(games_lib.layout_width(game), games_lib.layout_depth(game))
            )
            self.centre = (0.0, GO_Y_OFFSET)
        self.spacing = spacing
        #: Distance between rows (a hex board's rows are closer).
        self.row_spacing = spacing * (np.sqrt(3) / 2 if self.hex else 1.0)
        half = 0.5 * min(spacing, self.row_spacing)
        self.square_half = half
        self.half_board = 0.5 * spacing * games_lib.layout_width(game)
        self.half_depth = 0.5 * self.row_spacing * self.rows
        #: Half-size of a touch sensor's site: a press registers inside it.
        self.pad_half = SENSOR_FRACTION * half

    def _add_pieces(self, game) -> None:
        """One hidden render-only cylinder per point and, for move games, the
        hidden disc marking the selected piece."""
        root, rules, half = self._mjcf_root, game.rules, self.square_half
        if game.name in PIECE_SIZE:
            radius, piece_half_height = PIECE_SIZE[game.name]
            if game.name == "go" and self.size != GO_REFERENCE_SIZE:
                radius *= GO_REFERENCE_SIZE / self.size
        else:
            radius, piece_half_height = PIECE_FRACTION * half, PIECE_SIZE["go"][1]
        self.piece_radius, self.piece_half_height = radius, piece_half_height
        self.colours = rules.colours
        self.pieces = [
            root.worldbody.add(
                "geom",
                name=f"piece_{a}",
                type="cylinder",
                size=(radius, piece_half_height),
                pos=(0, 0, -1),
                group=HIDDEN_GROUP,
                contype=0,
                conaffinity=0,
                rgba=self.colours[0],
            )
            for a in range(game.num_points)
        ]
        self.selection = None
        if rules.input == "move":
            self.selection = root.worldbody.add(
                "geom",
                name="selection",
                type="cylinder",
                size=(0.95 * half, 0.001),
                pos=(0, 0, -1),
                group=HIDDEN_GROUP,
                contype=0,
                conaffinity=0,
                rgba=SELECTION_RGBA,
            )

    def _add_cameras(self) -> None:
        """The original's front camera and its code's second, steeper view."""
        root = self._mjcf_root
        # The original's front camera, facing the arm and the board (fovy 45).
        self.front_camera = root.worldbody.add(
            "camera",
            name="front_camera",
            pos=(0.0, -0.6, 0.75),
            xyaxes=(1.0, 0.0, 0.0, 0.0, 0.7, 0.75),
        )
        # The original code's second view, higher and steeper so that a 7x7
        # Go board fits (its ``front_2``); observed only when asked for.
        self.front_camera_2 = root.worldbody.add(
            "camera",
            name="front_camera_2",
            pos=(0.0, -0.65, 0.85),
            xyaxes=(1.0, 0.0, 0.0, 0.0, 0.85, 0.6),
        )

    def _add_scene(self, offscreen_size, physics_timestep, multisamples, shadows) -> None:
        """Physics and rendering options, the sky, the ground and the light.
        With ``shadows`` the light casts them into a `SHADOW_MAP_SIZE` map."""
        root = self._mjcf_root
        root.option.timestep = float(physics_timestep)
        root.visual.quality.shadowsize = SHADOW_MAP_SIZE if shadows else 0
        root.visual.quality.offsamples = int(multisamples)
        root.visual.__getattr__("global").offheight = int(offscreen_size[0])
        root.visual.__getattr__("global").offwidth = int(offscreen_size[1])

        # The original's sky, ground and light.
        root.asset.add(
            "texture",
            type="skybox",
            builtin="gradient",
            rgb1=(0.4, 0.6, 0.8),
            rgb2=(0.0, 0.0, 0.0),
            width=100,
            height=100,
        )
        ground_tex = root.asset.add(
            "texture",
            name="groundplane",
            type="2d",
            builtin="checker",
            rgb1=(0.2, 0.3, 0.4),
            rgb2=(0.1, 0.2, 0.3),
            width=300,
            height=300,
            mark="edge",
            markrgb=(0.8, 0.8, 0.8),
        )
        ground_mat = root.asset.add(
            "material",
            name="groundplane",
            texture=ground_tex,
            texrepeat=(5, 5),
            texuniform=True,
            reflectance=0.2,
        )
        self.floor = root.worldbody.add(
            "geom",
            name="ground",
            type="plane",
            material=ground_mat,
            size=(1, 1, 0.1),
            friction=(0.4,),
            solimp=(0.95, 0.99, 0.001),
            solref=(0.002, 1),
        )
        #: Where the light casting shadows is (``shadows``), else None.
        self.shadow_light = LIGHT_POS if shadows else None
        root.worldbody.add(
            "light",
            pos=LIGHT_POS,
            dir=(0, 0, -1),
            diffuse=(0.7, 0.7, 0.7),
            specular=(0.3, 0.3, 0.3),
            directional=False,
            castshadow=bool(shadows),
        )
        root.statistic.center = (0.0, 0.0, 0.0)

    def _add_points(self):
        """The board body: per point a square geom and a touch-sensor site (a
        wooden board under invisible squares for the ``"wood"`` look).
        Returns (board body, the sensor sites' material)."""
        root, game, half = self._mjcf_root, self.game, self.square_half
        cx, cy = self.centre
        board = root.worldbody.add("body", name="board")
        self.board_body = board
        dark = root.asset.add("material", name="square_dark", rgba=(0.2, 0.2, 0.2, 1))
        light = root.asset.add("material", name="square_light", rgba=(0.8, 0.8, 0.8, 1))
        tile = root.asset.add("material", name="square_plain", rgba=PLAIN_TILE)
        sensor_mat = root.asset.add("material", name="sensor", rgba=(0, 1, 0, 0.3))
        box = (half, half, SQUARE_HALF_HEIGHT)
        site_size = (self.pad_half, self.pad_half, 0.5 * SQUARE_HALF_HEIGHT)
        look = game.rules.look
        if look == "wood":
            board.add(
                "geom",
                name="goboard",
                type="box",
                size=(self.half_board, self.half_depth, SQUARE_HALF_HEIGHT),
                pos=(cx, cy, SQUARE_HALF_HEIGHT),
                rgba=(0.85, 0.65, 0.35, 1),
            )
        self.squares, self.sensor_sites, self.touch_sensors = [], [], []
        self.point_xy = np.zeros((game.num_points, 2))
        for a in range(game.num_points):
            row, col = divmod(a, game.cols)
            x, y = self.point_position(a)
            self.point_xy[a] = (x, y)
            if look == "wood":  # invisible squares on the wooden board
                style = dict(rgba=(0, 1, 0, 0), group=HIDDEN_GROUP)
            elif look == "plain":
                style = dict(material=tile)
            else:
                style = dict(material=dark if row % 2 == col % 2 else light)
            self.squares.append(
                board.add(
                    "geom",
                    name=f"square_{a}",
                    type="box",
                    size=box,
                    pos=(x, y, SQUARE_HALF_HEIGHT),
                    **style,
                )
            )
            site = board.add(
                "site",
                name=f"sensor_{a}",
                type="box",
                size=site_size,
                pos=(x, y, BOARD_TOP),
                material=sensor_mat,
                group=composer.SENSOR_SITES_GROUP,
            )
            self.sensor_sites.append(site)
        return board, sensor_mat

    def _add_pass_zones(self, board, sensor_mat) -> None:
        """Go's pass area: a hidden geom and its sensor site around the board."""
        cx, cy = self.centre
        pass_size = (2 * self.half_board, self.half_depth, 0.5 * SQUARE_HALF_HEIGHT)
        self.pass_geom = board.add(
            "geom",
            name="pass",
            type="box",
            size=pass_size,
            pos=(cx, cy, 0.0),
            rgba=(0, 1, 0, 0),
            group=HIDDEN_GROUP,
        )
        self.pass_site = board.add(
            "site",
            name="pass",
            type="box",
            size=pass_size,
            pos=(cx, cy, 0.0),
            material=sensor_mat,
            group=composer.SENSOR_SITES_GROUP,
        )

    def _add_lines(self, board, between: bool = False) -> None:
        """Render-only lines on a square board: through the points (the
        wooden board) or, ``between``, along the tiles' edges."""
        cx, cy = self.centre
        line_rgba = (0.1, 0.08, 0.05, 1)
        line_half = 0.002
        z = BOARD_TOP + 0.0005
        rows, cols = (self.rows + 1, self.cols + 1) if between else (self.rows, self.cols)
        extent_x = 0.5 * (cols - 1) * self.spacing
        extent_y = 0.5 * (rows - 1) * self.row_spacing
        for k in range(rows):
            y = cy + (k - (rows - 1) / 2) * self.row_spacing
            board.add(
                "geom",
                name=f"line_x_{k}",
                type="box",
                pos=(cx, y, z),
                size=(extent_x + line_half, line_half, 0.0005),
                rgba=line_rgba,
                contype=0,
                conaffinity=0,
            )
        for k in range(cols):
            x = cx + (k - (cols - 1) / 2) * self.spacing
            board.add(
                "geom",
                name=f"line_y_{k}",
                type="box",
                pos=(x, cy, z),
                size=(line_half, extent_y + line_half, 0.0005),
                rgba=line_rgba,
                contype=0,
                conaffinity=0,
            )

    def point_position(self, action: int) -> tuple[float, float]:
        """World (x, y) of board point ``action``."""
        row, col = divmod(int(action), self.cols)
        cx, cy = self.centre
        shift = 0.5 * row - 0.5 * games_lib.hex_offset(self.rows) if self.hex else 0.0
        return (
            cx + (col + shift - (self.cols - 1) / 2) * self.spacing,
            cy + (row - (self.rows - 1) / 2) * self.row_spacing,
        )

    def attach_arm(self, arm):
        """Attaches the arm's base at `ARM_OFFSET`."""
        frame = self.attach(arm)
        frame.pos = ARM_OFFSET
        return frame
