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
* looks: the original's (labmaze's ``sky_03`` skybox, headlight only, the
  box, pad and peg colours); every labmaze ``style_01`` wall and floor
  texture is compiled in, and each episode the task points the wall and
  floor materials at one of each. Wall tops and the floor show one copy of
  the texture per cell, aligned with the cells, as the original's
  texturing planes do; outside the grid the skybox shows.

Grid convention: cell ``(row, col)`` with row 0 at the top of the level text
has its centre at ``x = (col - (W-1)/2) * cell``, ``y = ((H-1)/2 - row) * cell``;
+y is "up" in the top-down camera image.
"""

from __future__ import annotations

import numpy as np
from dm_control import composer, mjcf
from labmaze import assets as labmaze_assets

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
# Looks: the original task's (physics_planning_games, mujoban.py).
#: A box, and a box while it covers a pad (the original paints the pad's
#: activator box blue).
BOX_RGBA = (173 / 255, 179 / 255, 60 / 255, 1.0)
BOX_ON_PAD_RGBA = (0.0, 0.0, 1.0, 1.0)
#: A target pad with no box on it, and one covered by a box (the green ring
#: around a blue box).
PAD_RGBA = (1.0, 0.0, 0.0, 1.0)
PAD_COVERED_RGBA = (0.0, 1.0, 0.0, 1.0)
#: The headlight of dm_control composer's base arena (diffuse 0.6, specular
#: 0) with the original's ambient 0.8, and no other light: a surface facing
#: the top camera renders as ``min(1, rgba * 1.4)``.
HEADLIGHT_AMBIENT = 0.8
HEADLIGHT_DIFFUSE = 0.6
#: labmaze texture styles drawn by the original: skybox ``sky_03``, wall and
#: floor textures of ``style_01`` (one of each drawn per episode).
SKY_STYLE = "sky_03"
TEXTURE_STYLE = "style_01"
#: Whether MuJoCo sleeps resting bodies by default (simulated again when
#: touched): 4-5x cheaper physics on Boxoban levels, the bodies' behaviour
#: within 1% of the original's (`envs.mujoban.behaviour`). The original
#: implementation does not (`ORIGINAL`).
SLEEP = True
#: MuJoCo's ``sleep_tolerance`` with sleeping on: a body whose velocities stay
#: below it (m/s, rad/s) may fall asleep. Ten times below MuJoCo's default, so
#: that a box still creeping into its rest is not frozen short of it
#: (docs/results/speed.md measures both).
SLEEP_TOLERANCE = 1e-4
#: The original implementation's values of the settings whose defaults here
#: differ from them (`envs.original_options`).
ORIGINAL = {"sleep": False}
#: Multisampling of offscreen frames by default: MuJoCo's default, the
#: original's (4 samples per pixel; with 0, object outlines move by up to a
#: pixel).
MULTISAMPLES = 4


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

    def _build(
        self,
        grid_shape=(10, 10),
        max_boxes=4,
        cell_size=1.0,
        pegs=False,
        offscreen_size=(256, 256),
        wall_slabs=32,
        noslip_iterations=5,
        sleep=SLEEP,
        multisamples=MULTISAMPLES,
        name="mujoban",
    ):
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
        if sleep:  # resting bodies are frozen until touched (not the original's)
            root.option.flag.sleep = "enable"
            root.option.sleep_tolerance = SLEEP_TOLERANCE

        self._set_visual(offscreen_size, multisamples)
        self._add_textures_and_floor()
        maze_size = max(height, width) * cell_size
        fovy = float(
            np.rad2deg(2 * np.arctan2(TOP_CAMERA_PADDING * maze_size / 2, TOP_CAMERA_DISTANCE))
        )
        self.top_camera = root.worldbody.add(
            "camera",
            name="top_camera",
            pos=(0, 0, TOP_CAMERA_DISTANCE),
            xyaxes=(1, 0, 0, 0, 1, 0),
            fovy=fovy,
        )

        self._add_cells(wall_slabs)
        self.pegs = []
        if pegs:
            self._add_pegs()

    def _set_visual(self, offscreen_size, multisamples) -> None:
        """Rendering options: no shadows, ``multisamples``, the offscreen
        buffer size, the headlight (the scene's only light)."""
        root = self._mjcf_root
        root.visual.quality.shadowsize = 0
        self.multisamples = int(multisamples)
        root.visual.quality.offsamples = self.multisamples
        root.visual.__getattr__("global").offheight = int(offscreen_size[0])
        root.visual.__getattr__("global").offwidth = int(offscreen_size[1])
        root.visual.headlight.ambient = (HEADLIGHT_AMBIENT,) * 3
        root.visual.headlight.diffuse = (HEADLIGHT_DIFFUSE,) * 3
        root.visual.headlight.specular = (0.0, 0.0, 0.0)
        root.visual.map.znear = 0.01

    def _add_textures_and_floor(self) -> None:
        """The sky, every wall and floor texture of the style, the wall and
        floor materials and the floor plane."""
        root, cell_size = self._mjcf_root, self.cell_size
        height, width = self.grid_shape
        sky = labmaze_assets.get_sky_texture_paths(SKY_STYLE)
        root.asset.add(
            "texture",
            name="skybox",
            type="skybox",
            fileleft=sky.left,
            fileright=sky.right,
            fileup=sky.up,
            filedown=sky.down,
            filefront=sky.front,
            fileback=sky.back,
        )
        # Every texture of the style is compiled in (uploaded to the GL
        # context once); an episode only re-points the materials' texture ids.
        self.wall_textures = [
            root.asset.add("texture", name=f"wall_{key}", type="2d", file=path)
            for key, path in sorted(labmaze_assets.get_wall_texture_paths(TEXTURE_STYLE).items())
        ]
        self.floor_textures = [
            root.asset.add("texture", name=f"floor_{key}", type="2d", file=path)
            for key, path in sorted(labmaze_assets.get_floor_texture_paths(TEXTURE_STYLE).items())
        ]
        # Textures are stretched over each geom face (texuniform off) and
        # repeated once per cell: ``texrepeat`` is the face's size in cells.
        self.wall_cell_material = root.asset.add(
            "material", name="wall_cell", texture=self.wall_textures[0], texrepeat=(1, 1)
        )
        half_w, half_h = width * cell_size / 2, height * cell_size / 2
        self.floor_material = root.asset.add(
            "material", name="floor", texture=self.floor_textures[0], texrepeat=(width, height)
        )
        self.floor = root.worldbody.add(
            "geom",
            name="floor",
            type="plane",
            size=(half_w, half_h, 0.5),
            material=self.floor_material,
            contype=FLOOR_BIT,
            conaffinity=WALKER_BIT,
            # MuJoCo's default geom friction, as dm_control's maze floor; the
            # boxes touch the floor only through the task's contact pairs.
            condim=3,
            friction=(1.0, 0.005, 0.0001),
        )

    def _add_cells(self, wall_slabs) -> None:
        """Per cell a hidden collision box (a wall when the level says so), a
        pool of render-only wall slabs and one target pad per box."""
        root, cell_size = self._mjcf_root, self.cell_size
        height, width = self.grid_shape
        hc = cell_size / 2
        self.wall_cells = []  # [row][col] collision geoms
        for r in range(height):
            row = []
            for c in range(width):
                x, y = self.cell_centre(r, c)
                row.append(
                    root.worldbody.add(
                        "geom",
                        name=f"wall_{r}_{c}",
                        type="box",
                        size=(hc, hc, WALL_HEIGHT / 2),
                        pos=(x, y, WALL_HEIGHT / 2),
                        group=HIDDEN_GROUP,
                        material=self.wall_cell_material,
                        # Compiled as colliding so that MuJoCo puts them in the
                        # world body's collision tree; the task switches the
                        # non-wall cells off per level.
                        contype=WALKER_BIT,
                        conaffinity=WALKER_BIT | BOX_BIT,
                        condim=3,
                    )
                )
            self.wall_cells.append(row)
        # Render-only wall slabs. Real Boxoban levels need at most 19 (10 on
        # average); a level that needs more than the pool is drawn with its
        # per-cell collision geoms instead (slower to render, same look).
        # Each slab has a material of its own: its texrepeat is the slab's
        # size in cells, set with the level.
        num_slabs = min(int(wall_slabs), height * width)
        self.slab_materials = [
            root.asset.add("material", name=f"wall_slab_{i}", texture=self.wall_textures[0])
            for i in range(num_slabs)
        ]
        self.wall_slabs = [
            root.worldbody.add(
                "geom",
                name=f"wall_slab_{i}",
                type="box",
                size=(hc, hc, WALL_HEIGHT / 2),
                pos=(0, 0, -10),
                group=HIDDEN_GROUP,
                contype=0,
                conaffinity=0,
                material=self.slab_materials[i],
            )
            for i in range(num_slabs)
        ]
        self.pads = [
            root.worldbody.add(
                "geom",
                name=f"pad_{i}",
                type="box",
                size=(0.5 * cell_size, 0.5 * cell_size, 0.004),
                pos=(0, 0, -10),
                group=HIDDEN_GROUP,
                contype=0,
                conaffinity=0,
                rgba=PAD_RGBA,
            )
            for i in range(self.max_boxes)
        ]

    def _add_pegs(self) -> None:
        """Pegs at the inner grid corners: hidden collision boxes turned 45
        degrees and one visual mesh of all of them."""
        root, hc = self._mjcf_root, self.cell_size / 2
        height, width = self.grid_shape
        centres = []
        for r in range(1, height):
            for c in range(1, width):
                x, y = self.cell_centre(r, c)
                x, y = x - hc, y + hc  # top-left corner of cell (r, c)
                centres.append((x, y))
                half = PEG_RADIUS / np.sqrt(2)
                self.pegs.append(
                    root.worldbody.add(
                        "geom",
                        name=f"peg_{r}_{c}",
                        type="box",
                        size=(half, half, PEG_HEIGHT / 2),
                        pos=(x, y, PEG_HEIGHT / 2),
                        quat=(np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)),
                        group=HIDDEN_GROUP,
                        rgba=(0, 0, 0, 0),
                        contype=0,
                        conaffinity=WALKER_BIT | BOX_BIT,
                        condim=3,
                    )
                )
        # Four sides with corners on the grid lines: the turned square.
        vert, face = _peg_mesh(np.asarray(centres), PEG_RADIUS, PEG_HEIGHT, sides=4)
        root.asset.add("mesh", name="pegs_mesh", vertex=vert, face=face)
        root.worldbody.add(
            "geom",
            name="pegs_visual",
            type="mesh",
            mesh="pegs_mesh",
            contype=0,
            conaffinity=0,
            rgba=PEG_RGBA,
            mass=0,
            density=0,
        )

    def cell_centre(self, row: int, col: int) -> tuple[float, float]:
        height, width = self.grid_shape
        return ((col - (width - 1) / 2) * self.cell_size, ((height - 1) / 2 - row) * self.cell_size)

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
    return [(r0, c0, r1, c1) for r0, c0, r1, c1 in rects]
