"""Public task descriptions: what a robot is told before an episode.

``env.description()`` returns one of these frozen dataclasses. They hold the
static, public facts an agent may use besides its observations (the
observation boundary, `hier_agents.boundary`): the grid's shape and cell
size, board and pad geometry, the control timestep, the cameras' poses and
intrinsics (multisampling included), MuJoBan's looks (object colours and
the light), and for the arm its own kinematic model. Nothing in them changes
during an episode or depends on the simulator's state; walls, targets and
boxes of a MuJoBan level are *not* here (the agent must see them).

Grid convention (MuJoBan): cell ``(row, col)`` with row 0 at the top has its
centre at ``x = (col - (W-1)/2) * cell``, ``y = ((H-1)/2 - row) * cell``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "CameraDescription",
    "MujobanLooks",
    "MujobanDescription",
    "ArmDescription",
    "BoardDescription",
]


@dataclass(frozen=True)
class CameraDescription:
    """A fixed pinhole camera (MuJoCo convention: ``fovy`` is the vertical
    field of view in degrees; the camera looks along its -z axis, image rows
    grow along its -y axis).

    Attributes:
      name: the observation key of its frames.
      position: world (x, y, z) of the camera.
      xyaxes: the camera's x and y axes in world coordinates (6 numbers).
      fovy: vertical field of view, degrees.
      shape: (height, width) of the frames the environment renders, or None
        when the camera is switched off.
      multisamples: samples per pixel of the renderer's multisampling (0 or
        1: none). With n samples a pixel shows a surface's own colour only
        where the surface covers all of them, i.e. where the pixel centre lies
        at least `coverage_inset` pixels inside the surface's outline along
        each axis; pixels on outlines show blends.
    """

    name: str
    position: tuple[float, float, float]
    xyaxes: tuple[float, ...]
    fovy: float
    shape: tuple[int, int] | None
    multisamples: int = 0

    @property
    def coverage_inset(self) -> float:
        """Pixels (see ``multisamples``): the farthest a sample lies from its
        pixel centre along an axis in the standard n-sample patterns,
        ``(n - 1) / (2 n)`` (0.375 for 4 samples); 0 without multisampling."""
        n = max(int(self.multisamples), 1)
        return (n - 1) / (2 * n)

    def rotation(self) -> np.ndarray:
        """(3, 3) world-from-camera rotation (columns: camera x, y, z)."""
        x = np.asarray(self.xyaxes[:3], float)
        y = np.asarray(self.xyaxes[3:], float)
        x = x / np.linalg.norm(x)
        y = y - x * (x @ y)
        y = y / np.linalg.norm(y)
        return np.stack([x, y, np.cross(x, y)], axis=1)

    def _frame_shape(self, shape) -> tuple[int, int]:
        """``shape`` (height, width), or by default this camera's."""
        size = shape or self.shape
        if size is None:
            raise TypeError(f"camera {self.name!r} is off: give the frame shape")
        return size

    def focal(self, height: int) -> float:
        """Focal length in pixels for frames ``height`` pixels tall."""
        return 0.5 * height / math.tan(math.radians(self.fovy) / 2)

    def project(self, points, shape=None) -> np.ndarray:
        """Pixel coordinates (row, col), floats, of world points (..., 3) in
        frames of ``shape`` (default: this camera's). Pixel centres are at
        integer + 0.5."""
        height, width = self._frame_shape(shape)
        pts = np.asarray(points, float)
        local = (pts - np.asarray(self.position, float)) @ self.rotation()
        f = self.focal(height)
        depth = -local[..., 2]
        col = 0.5 * width + f * local[..., 0] / depth
        row = 0.5 * height - f * local[..., 1] / depth
        return np.stack([row, col], axis=-1)

    def unproject(self, pixels, z: float = 0.0, shape=None) -> np.ndarray:
        """World points (..., 3) on the plane ``z`` seen at pixel coordinates
        (..., 2) = (row, col)."""
        height, width = self._frame_shape(shape)
        px = np.asarray(pixels, float)
        f = self.focal(height)
        rays = (
            np.stack(
                [
                    (px[..., 1] - 0.5 * width) / f,
                    (0.5 * height - px[..., 0]) / f,
                    -np.ones(px.shape[:-1]),
                ],
                axis=-1,
            )
            @ self.rotation().T
        )
        origin = np.asarray(self.position, float)
        t = (z - origin[2]) / rays[..., 2]
        return origin + t[..., None] * rays


@dataclass(frozen=True)
class MujobanLooks:
    """The colours of what a MuJoBan agent must recognise, and the light.

    Attributes (RGBA in [0, 1]):
      box, box_on_pad: a box, and a box while it covers a pad.
      pad, pad_covered: a target pad, and one a box covers (the ring left
        around the box).
      right_ear, left_ear: the walker's two ear spheres (red at the head's
        +x, blue at -x).
      headlight_ambient, headlight_diffuse: the only light, at the camera.

    Walls and floors are not here: their textures change between episodes.
    """

    box: tuple[float, float, float, float]
    box_on_pad: tuple[float, float, float, float]
    pad: tuple[float, float, float, float]
    pad_covered: tuple[float, float, float, float]
    right_ear: tuple[float, float, float, float]
    left_ear: tuple[float, float, float, float]
    headlight_ambient: float
    headlight_diffuse: float

    def facing_rgb(self, rgba, shade: float = 1.0) -> np.ndarray:
        """RGB (0-255 floats) of an untextured surface of colour ``rgba``
        whose normal makes an angle with cosine ``shade`` with the line of
        sight to the headlight (1: facing the top camera). MuJoCo's
        fixed-function lighting, no specular: ``min(1, rgba * (ambient +
        diffuse * shade)) * 255``."""
        light = self.headlight_ambient + self.headlight_diffuse * shade
        return np.minimum(np.asarray(rgba, float)[:3] * light, 1.0) * 255.0


@dataclass(frozen=True)
class MujobanDescription:
    """The public facts of a MuJoBan environment.

    Attributes:
      grid_shape: (rows, cols) of the arena's grid; levels are padded with walls.
      cell_size: metres per cell.
      pegs: whether pegs stand at every interior grid intersection.
      max_boxes: the most boxes a level may have.
      control_timestep: seconds per ``env.step``.
      time_limit_steps: control steps per episode.
      pad_tolerance: cells (along both axes) a box centre may be from a pad
        centre to cover it.
      box_half, box_half_height, ball_radius, peg_radius: metres.
      top_camera, egocentric_camera: the cameras (``shape`` None when off).
      action_names: what each action component drives.
      looks: object colours and light (`MujobanLooks`); None when unknown.
    """

    grid_shape: tuple[int, int]
    cell_size: float
    pegs: bool
    max_boxes: int
    control_timestep: float
    time_limit_steps: int
    pad_tolerance: float
    box_half: float
    box_half_height: float
    ball_radius: float
    peg_radius: float
    top_camera: CameraDescription
    egocentric_camera: CameraDescription | None = None
    action_names: tuple[str, ...] = ("roll", "steer")
    looks: MujobanLooks | None = None

    def cell_centre(self, row: int, col: int) -> tuple[float, float]:
        """World (x, y) of a cell's centre."""
        height, width = self.grid_shape
        return ((col - (width - 1) / 2) * self.cell_size, ((height - 1) / 2 - row) * self.cell_size)

    def world_to_cell(self, xy) -> tuple[int, int]:
        """The nearest cell (row, col) to world (x, y), clipped to the grid."""
        height, width = self.grid_shape
        row = round((height - 1) / 2 - float(xy[1]) / self.cell_size)
        col = round(float(xy[0]) / self.cell_size + (width - 1) / 2)
        return min(max(row, 0), height - 1), min(max(col, 0), width - 1)

    def world_to_grid(self, xy) -> np.ndarray:
        """Continuous grid coordinates (row, col) of world points (..., 2)."""
        height, width = self.grid_shape
        xy = np.asarray(xy, float)
        return np.stack(
            [
                (height - 1) / 2 - xy[..., 1] / self.cell_size,
                xy[..., 0] / self.cell_size + (width - 1) / 2,
            ],
            axis=-1,
        )


@dataclass(frozen=True)
class ArmDescription:
    """The arm's own kinematic model, as the robot's maker would ship it.

    ``xml`` and ``assets`` compile (``mujoco.MjModel.from_xml_string(xml,
    assets)``) to a model holding only the arm and hand, mounted where they
    are in the environment, with the joints of ``joint_names`` in the order
    of the ``arm/joints_pos`` observation (its ``qpos`` is exactly that
    observation).
    """

    xml: str
    assets: dict = field(repr=False, compare=False)
    joint_names: tuple[str, ...]
    pinch_site: str
    tool_center_point: str
    base_position: tuple[float, float, float]
    action_minimum: tuple[float, ...]
    action_maximum: tuple[float, ...]

    def model(self):
        """A freshly compiled ``mujoco.MjModel`` of the arm."""
        import mujoco

        return mujoco.MjModel.from_xml_string(self.xml, dict(self.assets))


@dataclass(frozen=True)
class BoardDescription:
    """The public facts of a board-game environment (MuJoXO, MuJoGo).

    Attributes:
      game: a registered game (`envs.boards.games.GAMES`): ``"tic_tac_toe"``,
        ``"go"``, ``"connect_four"``, ...
      board_size: points per side.
      komi: Go's komi (0 for tic-tac-toe).
      num_points: ``rows * cols``, the board's points.
      pass_action: the pass action id (Go) or None.
      point_positions: (num_points, 3) world (x, y, z) of each point on the
        board's top, in action order (``row * cols + col``).
      pad_half: half-side (m) of each point's touch-sensitive square.
      pass_zones: per side (``"left"``, ``"right"``) the pass area's centre
        (x, y, z of its top) and half-sizes (x, y); empty without passes.
      board_centre: world (x, y) of the board's centre; board_half: its
        half-side (m).
      registering: which robot geoms register a touch: ``"arm"`` (any),
        ``"fingers"`` or ``"fingertips"``.
      control_timestep, time_limit_steps: as in `MujobanDescription`.
      arm: the arm's kinematic model.
      front_camera: the front camera (``shape`` None when off).
      shadow_light: the world (x, y, z) of a point light that casts shadows
        (the arm's fall on the board), or None when no light does.
      front_camera_2: the original code's second, higher view, the whole
        board in view (``shape`` None when off, the default).
      rows, cols: the board's points per column and per row (``board_size``
        is ``rows`` when they are equal, else ``(rows, cols)``).
      input: how touches play (`envs.boards.games.GameRules`): ``"point"``,
        ``"column"`` or ``"move"``.
      agent_player: the agent's OpenSpiel player, 0, 1 or ``"random"``
        (drawn per episode; the ``agent_player`` observation says which).
      allow_double_pass: False when the task ignores the agent's pass right
        after its own pass until it plays a stone (MuJoGo, the original's
        rule).
      piece_radius: a piece's radius (m), as seen from above.
      piece_spread: how far (m, along x and along y) from its point a
        piece's centre may lie: an opponent's new piece lands within
        ``piece_noise`` times ``pad_half`` of it; where a touch places the
        piece (``input`` ``"point"``), the agent's lands where it touched,
        within ``pad_half``.
    """

    game: str
    board_size: int | tuple
    komi: float
    num_points: int
    pass_action: int | None
    point_positions: tuple[tuple[float, float, float], ...]
    pad_half: float
    pass_zones: dict = field(compare=False)
    board_centre: tuple[float, float]
    board_half: float
    registering: str
    control_timestep: float
    time_limit_steps: int
    arm: ArmDescription
    front_camera: CameraDescription | None = None
    rows: int = 0
    cols: int = 0
    input: str = "point"
    agent_player: int | str = 0
    allow_double_pass: bool = True
    front_camera_2: CameraDescription | None = None
    piece_radius: float = 0.0
    piece_spread: float = 0.0
    shadow_light: tuple[float, float, float] | None = None

    def point_position(self, action: int) -> np.ndarray:
        """World (x, y, z) of board point ``action`` on the board's top."""
        return np.asarray(self.point_positions[int(action)], float)
