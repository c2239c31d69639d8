"""Inputs and outputs of `hier_agents.baselines.impala.agent_env.AgentEnv`:
the experimental conditions and planner-action order (what differs per
family, discounts and proprioceptive keys among it, is the family adapter's:
`hier_agents.modular.families`), the network's `InputSpec`, the per-step `StepResult`,
and how the underlying environment is loaded (see `agent_env`'s module
docstring for the semantics). Everything public here is re-exported by
`agent_env`, where it is imported from.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

import envs
from abstract_planners.sokoban import MOVES

CONDITIONS = ("vanilla", "random-planner", "expert-planner")

#: Order of the MuJoBan ``planner_action`` one-hot.
PLANNER_ACTIONS = MOVES


@dataclass(frozen=True)
class InputSpec:
    """What the network gets (see the module docstring).

    Attributes:
      images: ``(camera name, (3, H, W))`` per uint8 image, possibly empty.
      proprio_dim: length of ``"proprio"``.
      planner_shape: ``(C, H, W)`` of ``"planner"``, None without a planner.
      planner_action_dim: length of the ``"planner_action"`` one-hot, 0 if absent.
      action_dim: action size A.
      state_shape: ``(C, H, W)`` of ``"state"``, None unless ``state=True``.
    """

    images: tuple[tuple[str, tuple[int, int, int]], ...]
    proprio_dim: int
    planner_shape: tuple[int, int, int] | None
    planner_action_dim: int
    action_dim: int
    state_shape: tuple[int, int, int] | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        """The observation keys, in order: ``"proprio"``, the cameras,
        ``"planner"``, ``"planner_action"``, ``"state"`` (those present)."""
        return (
            ("proprio",)
            + tuple(name for name, _ in self.images)
            + (("planner",) if self.planner_shape is not None else ())
            + (("planner_action",) if self.planner_action_dim else ())
            + (("state",) if self.state_shape is not None else ())
        )

    @property
    def privileged(self) -> bool:
        """Whether an input comes from the simulator's abstract state instead
        of the agent's sensors: ``"state"`` (``state=True``) or the planner
        planes (planner conditions; built from the ground-truth estimator)."""
        return self.planner_shape is not None or self.state_shape is not None


class StepResult(NamedTuple):
    """One `AgentEnv.step` (see the module docstring for the semantics)."""

    obs: dict[str, np.ndarray]
    reward_env: float
    discount_env: float
    reward_abs: float
    discount_abs: float
    last: bool
    info: dict


def _gamma(value, default: float, name: str) -> float:
    value = default if value is None else float(value)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"{name} must be in [0, 1], got {value!r}")
    return value


def _load_env(env_name: str, seed, image_size: int, cameras: bool, overrides: dict):
    """``envs.load(env_name)`` with every camera at ``image_size`` squared (or
    off without ``cameras``), frames rendered only when read (``lazy_cameras``:
    an action held for several control steps renders one frame, not one per
    step) and physics errors not raised, unless ``overrides`` say otherwise.
    KeyError for an unknown name."""
    valid = envs.overrides(env_name)  # KeyError for an unknown name
    kwargs = dict(overrides)
    for name in valid:
        if name.endswith("_camera"):
            kwargs.setdefault(name, (int(image_size), int(image_size)) if cameras else None)
    for name, value in (("raise_on_physics_error", False), ("lazy_cameras", True)):
        if name in valid:
            kwargs.setdefault(name, value)
    return envs.load(env_name, seed=seed, **kwargs)


def main_camera_only(env_name: str) -> dict[str, None]:
    """The `envs.load` overrides that turn off every camera of ``env_name``
    but its main one (``task.main_camera``: MuJoBan's top view; the board
    games have only the front view, so nothing). Builds the environment once
    with its cameras off (well under a second) to read the main camera.

    Raises:
      KeyError: unknown name (`envs.UnknownEnvironmentError`)."""
    env = envs.load(env_name, **envs.no_cameras(env_name))
    try:
        main = env.task.main_camera
    finally:
        env.close()
    return {key: None for key in envs.no_cameras(env_name) if key != main}
