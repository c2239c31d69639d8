"""Observations of the MuJoBan task (`envs.mujoban.task.Mujoban`): the walker's
compiled addresses, the observation spec and values, the abstract state's
entity and pixel layers, and the state accessors estimators and skills read.

`ObservationsMixin` is one of `Mujoban`'s bases; its methods read the
attributes `Mujoban.after_compile` sets (``_model``, ``_data``, the MjData
views ``_qpos`` etc., ``_rounding``, ``_static_layer``). The module also holds
the layer conventions: `ENTITY_CHANNELS`, `PIXEL_COLOURS` and
`entity_layer_to_pixels` (re-exported by `envs.mujoban.task`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.locomotion.walkers import legacy_base
from dm_env import specs

from envs.mujoban import arena as arena_lib

#: Channels of ``full_entity_layer``.
ENTITY_CHANNELS = ("wall", "target", "player", "box")
WALL, TARGET, PLAYER, BOX = range(4)

#: Colours of ``pixel_layer``, one pixel per grid cell: the original's (the
#: player blue whether on a target or not).
PIXEL_COLOURS = {
    "floor": (0, 0, 0),
    "wall": (128, 128, 128),
    "target": (255, 0, 0),
    "box": (255, 255, 0),
    "box_on_target": (0, 255, 0),
    "player": (0, 0, 255),
    "player_on_target": (0, 0, 255),
}


def _as_slice(index: np.ndarray):
    """``index`` as an equivalent slice when it is a run of step +1 or -1."""
    ints = [int(i) for i in index]
    if (
        len(ints) >= 2
        and all(b - a == ints[1] - ints[0] for a, b in zip(ints, ints[1:]))
        and abs(ints[1] - ints[0]) == 1
    ):
        stop = ints[-1] + (ints[1] - ints[0])
        return slice(ints[0], None if stop < 0 else stop, ints[1] - ints[0])
    return np.asarray(ints)


class ObservationsMixin:
    """Walker binding, observations and state accessors of `Mujoban`."""

    # Set by `Mujoban` (its parts, compiled-model indices and episode state).
    _arena: arena_lib.MujobanArena
    _walker: legacy_base.Walker
    _data: Any  # mujoco.MjData (mujoco has no type stubs)
    _qpos: np.ndarray
    _box_qpos: np.ndarray
    _num_boxes: int
    _rounding: tuple[float, float, float, int, int]
    _static_layer: np.ndarray
    _covered: tuple[bool, ...]

    def _add_walker_touch_sensor(self) -> None:
        model = self._walker.mjcf_model
        shell_body = model.find("geom", "shell").parent
        site = shell_body.add(
            "site",
            name="touch_site",
            type="sphere",
            size=(0.21,),
            group=arena_lib.HIDDEN_GROUP,
            rgba=(0, 0, 0, 0),
        )
        model.sensor.add("touch", name="sensor_touch", site=site)

    def _bind_walker(self, bind) -> None:
        """Compiled addresses of the walker's joints, actuators, head body and
        sensors (``bind`` = ``physics.bind``), and its aliveness rule."""
        walker_model = self._walker.mjcf_model
        root_joints = self._walker._root_joints  # pylint: disable=protected-access
        self._walker_root_qpos = [int(a) for a in np.ravel([bind(j).qposadr for j in root_joints])]
        self._walker_root_dof = np.array([bind(j).dofadr for j in root_joints]).ravel()
        all_joints = walker_model.find_all("joint")
        self._walker_joint_qpos = np.array([bind(j).qposadr for j in all_joints]).ravel()
        self._walker_joint_dof = np.array([bind(j).dofadr for j in all_joints]).ravel()
        self._steer_qpos = int(bind(walker_model.find("joint", "steer")).qposadr)
        actuators = self._walker.actuators
        self._act_ids = np.array([bind(a).element_id for a in actuators])
        act_joints = [
            walker_model.find("joint", a.joint.name if hasattr(a.joint, "name") else a.joint)
            for a in actuators
        ]
        # Slices where the addresses are consecutive: a view and a copy are
        # cheaper than fancy indexing, and observe() runs every step.
        self._act_qpos = _as_slice(np.array([bind(j).qposadr for j in act_joints]).ravel())
        self._act_dof = _as_slice(np.array([bind(j).dofadr for j in act_joints]).ravel())
        self._head_body = int(bind(self._walker.root_body).element_id)
        # The original's termination rule, walker aliveness < -0.5. dm_control's
        # legacy walkers (the rolling ball among them) return a constant 0: then
        # there is nothing to evaluate per step.
        aliveness = getattr(type(self._walker), "aliveness", None)
        self._aliveness = None
        if aliveness is not None and aliveness is not legacy_base.Walker.aliveness:
            self._aliveness = self._walker.aliveness

        def sensor_slice(name):
            sensor = bind(walker_model.find("sensor", name))
            adr, dim = int(sensor.adr), int(sensor.dim)
            return slice(adr, adr + dim)

        self._sensor_slices = {
            "walker/sensors_touch": sensor_slice("sensor_touch"),
            "walker/sensors_accelerometer": sensor_slice("sensor_torso_accel"),
            "walker/sensors_gyro": sensor_slice("sensor_torso_gyro"),
            "walker/sensors_velocimeter": sensor_slice("sensor_torso_vel"),
        }

    # -- observations -------------------------------------------------------

    def observation_spec(self):
        height, width = self.grid_shape
        n_act = len(self._act_ids)
        spec = {
            "walker/joints_pos": specs.Array((n_act,), np.float64, "walker/joints_pos"),
            "walker/joints_vel": specs.Array((n_act,), np.float64, "walker/joints_vel"),
            "walker/joints_torque": specs.Array((n_act,), np.float64, "walker/joints_torque"),
            "walker/orientation": specs.Array((9,), np.float64, "walker/orientation"),
        }
        for name, sl in self._sensor_slices.items():
            spec[name] = specs.Array((sl.stop - sl.start,), np.float64, name)
        spec["full_entity_layer"] = specs.Array((height, width, 4), bool, "full_entity_layer")
        spec["pixel_layer"] = specs.BoundedArray(
            (height, width, 3), np.uint8, 0, 255, "pixel_layer"
        )
        return spec

    def observe(self, physics):
        obs = {
            "walker/joints_pos": self._qpos[self._act_qpos].copy(),
            "walker/joints_vel": self._qvel[self._act_dof].copy(),
            "walker/joints_torque": self._qfrc_actuator[self._act_dof].copy(),
            "walker/orientation": self._xmat[self._head_body].copy(),
        }
        sensordata = self._sensordata.copy()
        for name, sl in self._sensor_slices.items():
            obs[name] = sensordata[sl]
        # Rebuilt only when the abstract state changes; every observation
        # gets its own copy (users keep observations, e.g. in replay buffers).
        obs["full_entity_layer"] = self._entity_layer.copy()
        obs["pixel_layer"] = self._pixel_layer.copy()
        return obs

    # -- state accessors (used by estimators, skills and tests) -------------

    def box_positions(self, physics=None) -> np.ndarray:
        """World (x, y) of the level's boxes, shape (num_boxes, 2)."""
        return self._data.qpos[self._box_qpos[: self._num_boxes]].copy()

    def walker_position(self, physics=None) -> np.ndarray:
        """World (x, y) of the walker (its root joints' position)."""
        return self._qpos[self._walker_root_qpos[:2]]

    def walker_velocity(self, physics=None) -> np.ndarray:
        """World (vx, vy) of the walker's root."""
        return self._data.qvel[self._walker_root_dof[:2]].copy()

    def walker_heading(self, physics=None) -> float:
        """Heading of the walker's face in the world frame, radians from +x."""
        xmat = self._data.xmat[self._head_body]
        # The face sits on the head body's local +y axis (column 1 of xmat).
        return float(np.arctan2(xmat[4], xmat[1]))

    def world_to_cell(self, xy) -> tuple[int, int]:
        """Nearest grid cell (row, col) to a world point, clipped to the grid."""
        inv, cx, cy, rmax, cmax = self._rounding
        x, y = float(xy[0]), float(xy[1])
        return min(max(round(cy - y * inv), 0), rmax), min(max(round(x * inv + cx), 0), cmax)

    @property
    def abstract_cells(self) -> tuple[tuple[tuple[int, int], ...], tuple[int, int]]:
        """The current estimate: (box cells in box order, player cell)."""
        return self._box_cells, self._player_cell

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        return self._arena.cell_centre(row, col)

    @property
    def pads_covered(self) -> np.ndarray:
        """Per target pad (in `level.targets` sorted order), covered or not."""
        return np.array(self._covered, bool)

    def _set_layers(self, box_cells, player) -> None:
        self._box_cells = tuple(box_cells)
        self._player_cell = tuple(player)
        layer = self._static_layer.copy()
        for r, c in box_cells:
            layer[r, c, BOX] = True
        layer[player[0], player[1], PLAYER] = True
        pixels = entity_layer_to_pixels(layer)
        layer.flags.writeable = False
        pixels.flags.writeable = False
        self._entity_layer, self._pixel_layer = layer, pixels


_COLOUR_TABLE = np.zeros((16, 3), np.uint8)


def _build_colour_table() -> None:
    for code in range(16):
        wall, target, player, box = (bool(code >> k & 1) for k in range(4))
        if wall:
            name = "wall"
        elif box:
            name = "box_on_target" if target else "box"
        elif player:
            name = "player_on_target" if target else "player"
        elif target:
            name = "target"
        else:
            name = "floor"
        _COLOUR_TABLE[code] = PIXEL_COLOURS[name]


_build_colour_table()
_CHANNEL_WEIGHTS = np.array([1, 2, 4, 8], np.uint8)


def entity_layer_to_pixels(layer: np.ndarray) -> np.ndarray:
    """``pixel_layer`` from ``full_entity_layer``: one RGB pixel per cell."""
    return _COLOUR_TABLE[layer.astype(np.uint8) @ _CHANNEL_WEIGHTS]
