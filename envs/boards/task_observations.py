"""Observations of the board task (`envs.boards.task.BoardTask`): the public
description (`envs.description.BoardDescription`), the observation spec and
values, and world positions of board points, pass areas and the pinch site.

`ObservationsMixin` is one of `BoardTask`'s bases; it reads the attributes
`BoardTask.after_compile` sets and the game state of
`envs.boards.task_record.GameRecordMixin` (``_planes``, ``_history``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.entities.manipulators import kinova
from dm_env import specs

from envs.boards import arena as arena_lib


class ObservationsMixin:
    """Description, observations and positions of `BoardTask`."""

    # Set by `BoardTask`.
    _arena: arena_lib.BoardArena
    _data: Any  # mujoco.MjData (mujoco has no type stubs)
    _pinch_site: int

    def description(self):
        """The public `envs.description.BoardDescription` of this task (built
        once: the arm's own model is compiled from a fresh arm and hand)."""
        if self._description is None:
            self._description = self._describe()
        return self._description

    def _describe(self):
        from envs.description import BoardDescription, CameraDescription

        arena = self._arena
        arm_desc = self._describe_arm()
        game = self.game
        cx, cy = arena.centre
        zones = self._describe_pass_zones()
        front, front_2 = (
            CameraDescription(
                name,
                tuple(float(v) for v in cam.pos),
                tuple(float(v) for v in cam.xyaxes),
                float(cam.fovy or 45.0),
                (self._cameras[name].height, self._cameras[name].width)
                if name in self._cameras
                else None,
                multisamples=self._multisamples,
            )
            for name, cam in (
                ("front_camera", arena.front_camera),
                ("front_camera_2", arena.front_camera_2),
            )
        )
        return BoardDescription(
            game=game.name,
            board_size=game.size,
            komi=float(game.komi),
            num_points=game.num_points,
            pass_action=game.pass_action,
            point_positions=tuple(
                tuple(float(v) for v in self.point_position(a)) for a in range(game.num_points)
            ),
            pad_half=float(arena.pad_half),
            pass_zones=zones,
            board_centre=(float(cx), float(cy)),
            board_half=float(arena.half_board),
            registering=self._registering,
            control_timestep=float(self.control_timestep),
            time_limit_steps=int(self.time_limit_steps),
            arm=arm_desc,
            front_camera=front,
            front_camera_2=front_2,
            rows=game.rows,
            cols=game.cols,
            input=game.rules.input,
            agent_player=self.agent_player,
            allow_double_pass=self._allow_double_pass or game.pass_action is None,
            piece_radius=float(arena.piece_radius),
            piece_spread=float(
                max(self._piece_noise, float(game.rules.input == "point")) * arena.pad_half
            ),
            shadow_light=arena.shadow_light,
        )

    def _describe_arm(self):
        """The `envs.description.ArmDescription`: the arm's own model, a fresh
        arm and hand mounted as in the arena, and its action bounds."""
        from dm_control import mjcf

        from envs.description import ArmDescription

        root = mjcf.RootElement(model="jaco")
        arm, hand = kinova.JacoArm(name="arm"), kinova.JacoHand(name="hand")
        arm.attach(hand)
        frame = root.attach(arm.mjcf_model)
        frame.pos = arena_lib.ARM_OFFSET
        xml = root.to_xml_string()
        assets = root.get_assets()
        joints = list(arm.joints) + list(hand.joints)
        spec = self._model.actuator_ctrlrange[self._act_ids]
        return ArmDescription(
            xml=xml,
            assets=assets,
            joint_names=tuple(j.full_identifier for j in joints),
            pinch_site=hand.pinch_site.full_identifier,
            tool_center_point=hand.tool_center_point.full_identifier,
            base_position=tuple(float(v) for v in arena_lib.ARM_OFFSET),
            action_minimum=tuple(float(v) for v in spec[:, 0]),
            action_maximum=tuple(float(v) for v in spec[:, 1]),
        )

    def _describe_pass_zones(self) -> dict:
        """The pass areas left and right of the board (empty without passes):
        ``{side: {"centre": (x, y, z), "half": (hx, hy)}}``."""
        arena = self._arena
        cx, cy = arena.centre
        zones = {}
        if arena.pass_geom is not None:
            size = tuple(float(v) for v in arena.pass_geom.size)
            # The pass sensor covers the board's footprint and beyond; the
            # part outside the board on each side is what a robot can touch.
            for side, sign in (("left", -1.0), ("right", 1.0)):
                # (the pass geom is centred at z = 0: its top is at its half-height)
                zones[side] = {
                    "centre": (cx + sign * 0.5 * (arena.half_board + size[0]), cy, size[2]),
                    "half": (0.5 * (size[0] - arena.half_board), size[1]),
                }
        return zones

    # -- observations -------------------------------------------------------

    def observation_spec(self):
        game, dof = self.game, len(self._joint_qpos)
        spec = {
            "arm/joints_pos": specs.Array((dof,), np.float64, "arm/joints_pos"),
            "arm/joints_vel": specs.Array((dof,), np.float64, "arm/joints_vel"),
            "arm/joints_torque": specs.Array((dof,), np.float64, "arm/joints_torque"),
            "arm/pinch_site_pos": specs.Array((3,), np.float64, "arm/pinch_site_pos"),
            "arm/pinch_site_rmat": specs.Array((9,), np.float64, "arm/pinch_site_rmat"),
            "board_state": specs.Array(
                (game.rows, game.cols, game.num_planes), bool, "board_state"
            ),
            "move_history": specs.BoundedArray(
                (self._max_moves,),
                np.int32,
                -1,
                self._spiel_game.num_distinct_actions() - 1,
                "move_history",
            ),
            "agent_player": specs.BoundedArray((1,), np.int32, 0, 1, "agent_player"),
        }
        if game.rules.input == "move":
            spec["selected_point"] = specs.BoundedArray(
                (1,), np.int32, -1, game.num_points - 1, "selected_point"
            )
        return spec

    def observe(self, physics):
        d = self._data
        obs = {
            "arm/joints_pos": self._qpos[self._joint_qpos],
            "arm/joints_vel": self._qvel[self._joint_dof],
            "arm/joints_torque": self._qfrc_actuator[self._joint_dof],
            "arm/pinch_site_pos": d.site_xpos[self._pinch_site].copy(),
            "arm/pinch_site_rmat": d.site_xmat[self._pinch_site].copy(),
            "board_state": self._planes.copy(),
            "move_history": self._history.copy(),
            "agent_player": np.array([self._agent], np.int32),
        }
        if self.game.rules.input == "move":
            obs["selected_point"] = np.array([self._selected], np.int32)
        return obs

    # -- positions ---------------------------------------------------------

    def point_position(self, action: int) -> np.ndarray:
        """World (x, y, z) of board point ``action`` on the board's top."""
        x, y = self._arena.point_position(action)
        return np.array([x, y, arena_lib.BOARD_TOP])

    def pass_position(self, side: str = "left") -> np.ndarray:
        """World (x, y, z) of a point of a pass area (Go only), on the pass geom's
        top 5 cm beside the board's ``side`` edge, level with the rows nearest
        the arm (the easiest part of the area to reach)."""
        arena = self._arena
        if arena.pass_geom is None:
            raise ValueError("this game has no pass areas")
        cx, cy = arena.centre
        sign = -1.0 if side == "left" else 1.0
        return np.array(
            [
                cx + sign * (arena.half_board + 0.05),
                cy + 0.75 * arena.half_board,
                0.5 * arena_lib.SQUARE_HALF_HEIGHT,
            ]
        )

    def pinch_site_position(self) -> np.ndarray:
        return self._data.site_xpos[self._pinch_site].copy()
