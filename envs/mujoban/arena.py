"""The MuJoBan arena: a walled grid maze that is rebuilt in place every episode.

The arena is compiled once for a fixed *capacity* (grid height x width, number
of boxes). A new level changes only model fields that MuJoCo reads at every
step or frame, never anything that would need a recompile:

* **collision walls**: one hidden box geom per grid cell, all fixed in place;
  a cell is a wall when its geom's ``contype``/``conaffinity`` are switched on;
* **visual walls**: a pool of render-only slabs (no collision) that are resized
  to cover the level's wall cells with few rectangles, because a software
  renderer pays per drawn geom (a level needing more rectangles than the pool
  shows its collision cells instead);
* **pads**: render-only flat geoms, moved onto the level's targets; the task
  recolours them while a box covers them;
* **pegs** (optional): as in the original task, a square post (0.05 m from
  its centre to each corner, 0.25 m tall) turned 45 degrees at every interior
  grid intersection, colliding with the walker and the boxes; the collision
  geoms are hidden and all pegs are drawn by a single mesh;
* wall and floor appearance: several textured materials compiled in; each
  episode picks one for the walls and one for the floor and tints it.

Grid convention: cell ``(row, col)`` with row 0 at the top of the level text
has its centre at ``x = (col - (W-1)/2) * cell``, ``y = ((H-1)/2 - row) * cell``;
+y is "up" in the top-down camera image.
"""

from __future__ import annotations

import io

import numpy as np
from dm_control import composer, mjcf
from PIL import Image

# Collision bits. Walker geoms use (contype=1, conaffinity=1) from its XML.
WALKER_BIT = 1
BOX_BIT = 2
FLOOR_BIT = 4

HIDDEN_GROUP = 5  # not drawn by default scene options (groups 0-2 are)

WALL_HEIGHT = 1.0
#: Pegs (the original's ``_PEG_SIZE``, ``_PEG_HEIGHT``, ``_PEG_ANGLE``): a box
#: geom of half-sizes PEG_RADIUS/sqrt(2) x PEG_RADIUS/sqrt(2) x PEG_HEIGHT/2
#: turned 45 degrees about z, so its corners lie PEG_RADIUS from its axis,
#: pointing along the grid lines.
PEG_RADIUS = 0.05
PEG_HEIGHT = 0.25
PEG_RGBA = (0.5, 0.5, 0.5, 1.0)
#: Top camera as dm_control's ``MazeWithTargets``: 100 m above the centre,
#: looking down, its field of view fitting 1.1 times the larger grid side.
TOP_CAMERA_DISTANCE = 100.0
TOP_CAMERA_PADDING = 1.1
PAD_RGBA = (0.8, 0.2, 0.2, 1.0)          # a target pad with no box on it
PAD_COVERED_RGBA = (0.2, 0.8, 0.2, 1.0)  # a target pad covered by a box


def _skyline_png(seed: int = 7, face: int = 256) -> bytes:
    """A cube-map skybox whose four sides show four different skylines.

    The layout is MuJoCo's 3x4 grid ``.U..LFRBD...`` ... simplified to a strip
    of six faces (``gridsize="1 6"``, ``gridlayout="RLUDFB"``). Each side face
    gets buildings of its own colour and height profile, so the walker can tell
    its heading from the egocentric view.
    """
    rng = np.random.default_rng(seed)
    sky_top = np.array([70, 110, 170], np.float32)
    sky_bottom = np.array([170, 195, 225], np.float32)
    rows = np.linspace(0.0, 1.0, face, dtype=np.float32)[:, None, None]
    side = (sky_top * (1 - rows) + sky_bottom * rows) * np.ones((1, face, 1), np.float32)
    palettes = [(60, 50, 80), (90, 40, 30), (30, 70, 50), (80, 80, 30)]

    def side_face(k: int) -> np.ndarray:
        img = side.copy()
        col = 0
        base_height = 0.25 + 0.12 * k
        while col < face:
            w = int(rng.integers(face // 24, face // 8))
            h = int(face * (0.5 - base_height * rng.uniform(0.3, 1.0) * 0.9))
            img[max(h, 0):, col:col + w] = np.array(palettes[k]) * rng.uniform(0.7, 1.2)
            col += w
        img[int(face * 0.55):] = np.array(palettes[k]) * 0.5  # ground band
        return img

    top = np.broadcast_to(sky_top, (face, face, 3))
    bottom = np.full((face, face, 3), 40, np.float32)
    faces = [side_face(0), side_face(1), top, bottom, side_face(2), side_face(3)]
    strip = np.concatenate(faces, axis=1).clip(0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(strip).save(buf, format="PNG")
    return buf.getvalue()


def _peg_mesh(centres: np.ndarray, radius: float, height: float, sides: int = 8):
    """Vertices and faces of many vertical prisms (one per centre), as one mesh."""
    angles = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    verts, faces = [], []
    for k, (x, y) in enumerate(centres):
        base = k * (2 * sides)
        for z in (0.0, height):
            verts.extend([(x + px, y + py, z) for px, py in ring])
        for i in range(sides):
            j = (i + 1) % sides
            faces.append((base + i, base + sides + j, base + j))
            faces.append((base + i, base + sides + i, base + sides + j))
        for i in range(1, sides - 1):  # caps
            faces.append((base, base + i + 1, base + i))
            faces.append((base + sides, base + sides + i, base + sides + i + 1))
    return np.asarray(verts, np.float64).ravel(), np.asarray(faces, np.int32).ravel()


class MujobanArena(composer.Arena):
    """The maze arena. See the module docstring for what changes per episode."""

    def _build(self, grid_shape=(10, 10), max_boxes=4, cell_size=1.0, pegs=False,
               offscreen_size=(256, 256), wall_slabs=32, noslip_iterations=5,
               sleep=False, name="mujoban"):
        self._mjcf_root = mjcf.RootElement(model=name)
        height, width = grid_shape
        self.grid_shape = (int(height), int(width))
        self.cell_size = float(cell_size)
        self.max_boxes = int(max_boxes)
        self.has_pegs = bool(pegs)
        root = self._mjcf_root
        # Bodies that only carry joints (attachment frames) get a tiny mass.
        root.compiler.boundmass = 1e-5
        root.compiler.boundinertia = 1e-11
        # The solver options of dm_control composer's base arena, which the
        # original MuJoBan arena inherits: elliptic friction cones and 5
        # iterations of the noslip solver (no slip at sticking contacts).
        root.option.cone = "elliptic"
        root.option.noslip_iterations = int(noslip_iterations)
        root.option.noslip_tolerance = 0.0
        if sleep:  # a deviation: resting bodies are frozen until touched
            root.option.flag.sleep = "enable"

        root.visual.quality.shadowsize = 0
        root.visual.quality.offsamples = 0
        root.visual.__getattr__("global").offheight = int(offscreen_size[0])
        root.visual.__getattr__("global").offwidth = int(offscreen_size[1])
        root.visual.headlight.ambient = (0.4, 0.4, 0.4)
        root.visual.headlight.diffuse = (0.6, 0.6, 0.6)
        root.visual.headlight.specular = (0.1, 0.1, 0.1)
        root.visual.map.znear = 0.01

        root.asset.add("texture", name="skyline", type="skybox",
                       file=mjcf.Asset(_skyline_png(), ".png"),
                       gridsize=(1, 6), gridlayout="RLUDFB")
        self.floor_materials, self.wall_materials = [], []
        for i, (builtin, mark) in enumerate([("checker", "none"), ("checker", "edge"),
                                             ("gradient", "none"), ("flat", "random")]):
            tex = root.asset.add("texture", name=f"floor_tex_{i}", type="2d", builtin=builtin,
                                 mark=mark, rgb1=(0.9, 0.9, 0.9), rgb2=(0.6, 0.6, 0.6),
                                 markrgb=(0.3, 0.3, 0.3), random=0.05, width=64, height=64)
            self.floor_materials.append(root.asset.add(
                "material", name=f"floor_mat_{i}", texture=tex,
                texrepeat=(width, height), texuniform=False, reflectance=0.0))
        # Wall textures carry no per-cell marks: slabs that merge many cells
        # must look like the cells drawn one by one.
        for i, (builtin, mark) in enumerate([("flat", "random"), ("gradient", "none"),
                                             ("flat", "none"), ("checker", "random")]):
            tex = root.asset.add("texture", name=f"wall_tex_{i}", type="2d", builtin=builtin,
                                 mark=mark, rgb1=(0.95, 0.95, 0.95), rgb2=(0.7, 0.7, 0.7),
                                 markrgb=(0.4, 0.4, 0.4), random=0.1, width=32, height=32)
            self.wall_materials.append(root.asset.add(
                "material", name=f"wall_mat_{i}", texture=tex, texuniform=True,
                texrepeat=(1 / cell_size, 1 / cell_size)))

        root.worldbody.add("light", name="sun", directional=True, castshadow=False,
                           pos=(0, 0, 10), dir=(0.3, 0.2, -1), diffuse=(0.5, 0.5, 0.5))
        half_w, half_h = width * cell_size / 2, height * cell_size / 2
        self.floor = root.worldbody.add(
            "geom", name="floor", type="plane", size=(half_w + 2, half_h + 2, 0.5),
            material=self.floor_materials[0], contype=FLOOR_BIT, conaffinity=WALKER_BIT,
            # MuJoCo's default geom friction, as dm_control's maze floor; the
            # boxes touch the floor only through the task's contact pairs.
            condim=3, friction=(1.0, 0.005, 0.0001))

        maze_size = max(height, width) * cell_size
        fovy = float(np.rad2deg(2 * np.arctan2(TOP_CAMERA_PADDING * maze_size / 2,
                                               TOP_CAMERA_DISTANCE)))
        self.top_camera = root.worldbody.add(
            "camera", name="top_camera", pos=(0, 0, TOP_CAMERA_DISTANCE),
            xyaxes=(1, 0, 0, 0, 1, 0), fovy=fovy)

        hc = cell_size / 2
        self.wall_cells = []  # [row][col] collision geoms
        for r in range(height):
            row = []
            for c in range(width):
                x, y = self.cell_centre(r, c)
                row.append(root.worldbody.add(
                    "geom", name=f"wall_{r}_{c}", type="box", size=(hc, hc, WALL_HEIGHT / 2),
                    pos=(x, y, WALL_HEIGHT / 2), group=HIDDEN_GROUP,
                    material=self.wall_materials[0],
                    # Compiled as colliding so that MuJoCo puts them in the
                    # world body's collision tree; the task switches the
                    # non-wall cells off per level.
                    contype=WALKER_BIT, conaffinity=WALKER_BIT | BOX_BIT, condim=3))
            self.wall_cells.append(row)
        # Render-only wall slabs. Real Boxoban levels need at most 19 (10 on
        # average); a level that needs more than the pool is drawn with its
        # per-cell collision geoms instead (slower to render, same look).
        self.wall_slabs = [
            root.worldbody.add("geom", name=f"wall_slab_{i}", type="box",
                               size=(hc, hc, WALL_HEIGHT / 2), pos=(0, 0, -10),
                               group=HIDDEN_GROUP, contype=0, conaffinity=0,
                               material=self.wall_materials[0])
            for i in range(min(int(wall_slabs), height * width))]
        self.pads = [
            root.worldbody.add("geom", name=f"pad_{i}", type="box",
                               size=(0.5 * cell_size, 0.5 * cell_size, 0.004),
                               pos=(0, 0, -10), group=HIDDEN_GROUP, contype=0, conaffinity=0,
                               rgba=PAD_RGBA)
            for i in range(self.max_boxes)]

        self.pegs = []
        if pegs:
            centres = []
            for r in range(1, height):
                for c in range(1, width):
                    x, y = self.cell_centre(r, c)
                    x, y = x - hc, y + hc  # top-left corner of cell (r, c)
                    centres.append((x, y))
                    half = PEG_RADIUS / np.sqrt(2)
                    self.pegs.append(root.worldbody.add(
                        "geom", name=f"peg_{r}_{c}", type="box",
                        size=(half, half, PEG_HEIGHT / 2), pos=(x, y, PEG_HEIGHT / 2),
                        quat=(np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)),
                        group=HIDDEN_GROUP, rgba=(0, 0, 0, 0),
                        contype=0, conaffinity=WALKER_BIT | BOX_BIT, condim=3))
            # Four sides with corners on the grid lines: the turned square.
            vert, face = _peg_mesh(np.asarray(centres), PEG_RADIUS, PEG_HEIGHT, sides=4)
            root.asset.add("mesh", name="pegs_mesh", vertex=vert, face=face)
            root.worldbody.add("geom", name="pegs_visual", type="mesh", mesh="pegs_mesh",
                               contype=0, conaffinity=0, rgba=PEG_RGBA,
                               mass=0, density=0)

    def cell_centre(self, row: int, col: int) -> tuple[float, float]:
        height, width = self.grid_shape
        return ((col - (width - 1) / 2) * self.cell_size,
                ((height - 1) / 2 - row) * self.cell_size)

    @property
    def mjcf_model(self):
        return self._mjcf_root


def wall_rectangles(walls: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Covers the True cells of a 2D bool array with few disjoint rectangles.

    Horizontal runs in each row are merged downwards with identical runs in the
    following rows. Returns ``(row0, col0, row1, col1)`` with exclusive ends.
    """
    height, width = walls.shape
    rects: list[list[int]] = []
    open_runs: dict[tuple[int, int], list[int]] = {}
    for r in range(height):
        runs, c = [], 0
        while c < width:
            if walls[r, c]:
                c0 = c
                while c < width and walls[r, c]:
                    c += 1
                runs.append((c0, c))
            else:
                c += 1
        next_open = {}
        for run in runs:
            rect = open_runs.get(run)
            if rect is None:
                rect = [r, run[0], r + 1, run[1]]
                rects.append(rect)
            else:
                rect[2] = r + 1
            next_open[run] = rect
        open_runs = next_open
    return [tuple(rect) for rect in rects]
