"""MuJoBan's physical behaviour, measured the same way on any MuJoBan model.

The checks that a cheaper model must pass before it becomes a default, and
that tell this library's model from the original implementation's
(``physics_planning_games``): a few seconds of scripted physics from one
fixed open level (`LEVEL`: the walker two cells west of a box), with the
walker turned to face a chosen world direction before each scenario.

`measure` takes a reset dm_control ``Physics`` of either implementation
(it finds the parts by the names both give them: the walker's ``root_x``,
``root_y`` and ``steer`` joints and ``roll`` and ``steer`` actuators, a box
body named ``box...`` with three slide joints) and returns `QUANTITIES`, in
metres:

* ``roll_m``: how far the walker rolls from rest in 0.5 s at full ``roll``;
* ``coast_m``: how much further it rolls in the next 0.5 s with no control;
* ``push_box_m``: how far the box moves when the walker, facing it from two
  cells away, rolls at it for 1.5 s at full ``roll`` and then coasts 0.5 s;
* ``slide_10N_m``, ``slide_20N_m``, ``slide_40N_m``: how far the box slides
  when a horizontal force of 10, 20 or 40 N pushes its centre for 0.5 s,
  after 0.5 s more at rest (the box's floor friction holds 12.3 N).

`roll_distances` measures the walker's own limit on `CORRIDOR` (a straight
open run of 36 cells, longer than any Boxoban level's, in a ``grid_shape``
of `CORRIDOR_SHAPE`): the distance it covers from rest at full ``roll``
after each control step, the fastest any path can be travelled; and
`steer_angles` how fast it turns its heading from rest.

Each scenario starts from the state `measure` found (velocities zeroed, the
walker settled for 0.2 s), so the scenarios do not disturb each other.
Everything is stepped with ``mj_step`` at the model's own timestep; only
MuJoCo runs (no task hooks), so these are properties of the model.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

#: A 10x10 Boxoban-format level: an 8x8 room, the walker at row 5, column
#: 3, a box two cells east of it and its pad below.
LEVEL = (
    "##########",
    "#        #",
    "#        #",
    "#        #",
    "#        #",
    "#  @ $   #",
    "#        #",
    "#     .  #",
    "#        #",
    "##########",
)
#: A straight corridor: the walker at its west end, 36 open cells east of it
#: (the box and pad at the far end only make the level valid).
CORRIDOR = (
    "#" * 40,
    "#" + " " * 38 + "#",
    "#@" + " " * 34 + ".$ #",
    "#" + " " * 38 + "#",
    "#" * 40,
)
#: The ``grid_shape`` an environment needs to hold `CORRIDOR`.
CORRIDOR_SHAPE = (len(CORRIDOR), len(CORRIDOR[0]))
#: What `measure` returns, in this order.
QUANTITIES = (
    "roll_m",
    "coast_m",
    "push_box_m",
    "slide_10N_m",
    "slide_20N_m",
    "slide_40N_m",
)
#: Two models behave the same when every quantity differs by at most this
#: fraction of the reference's value, or by `ABS_TOLERANCE_M`, whichever is larger.
REL_TOLERANCE = 0.01
ABS_TOLERANCE_M = 0.002

_SETTLE_S = 0.2
_PROBE_S = 0.1


def level_text(level: tuple = LEVEL) -> str:
    """``level`` (`LEVEL` or `CORRIDOR`) as a one-level Boxoban file's text."""
    return "; 0\n" + "\n".join(level) + "\n"


def within_tolerance(value: float, reference: float) -> bool:
    """Whether ``value`` is ``reference`` within `REL_TOLERANCE` or `ABS_TOLERANCE_M`."""
    return abs(value - reference) <= max(REL_TOLERANCE * abs(reference), ABS_TOLERANCE_M)


class _Parts:
    """Addresses of the walker's and the box's joints and actuators in ``model``."""

    def __init__(self, model: mujoco.MjModel):
        def joint(suffix: str) -> int:
            return _one(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt, suffix)

        def actuator(suffix: str) -> int:
            return _one(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu, suffix)

        self.root = [int(model.jnt_qposadr[joint(s)]) for s in ("root_x/", "root_y/")]
        self.steer = int(model.jnt_qposadr[joint("steer")])
        self.roll_act, self.steer_act = actuator("roll"), actuator("steer")
        boxes = [
            b
            for b in range(model.nbody)
            if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "").startswith("box")
            and model.body_jntnum[b] == 3
        ]
        if not boxes:
            raise ValueError("the model has no box body with three slide joints")
        self.box = boxes[0]
        first = int(model.body_jntadr[self.box])
        self.box_qpos = [int(model.jnt_qposadr[first + k]) for k in range(2)]


def _one(model: mujoco.MjModel, kind, count: int, suffix: str) -> int:
    found = [i for i in range(count) if (mujoco.mj_id2name(model, kind, i) or "").endswith(suffix)]
    if len(found) != 1:
        raise ValueError(f"expected one {kind.name} named '...{suffix}', found {len(found)}")
    return found[0]


def measure(physics) -> dict[str, float]:
    """The `QUANTITIES` of the model in ``physics`` (a dm_control ``Physics``
    just reset on `LEVEL`), in metres. The physics state is left changed.

    Raises:
      ValueError: the model lacks one of the parts named in the module docstring.
    """
    m, d, parts, start = _settled(physics)

    def restart(heading: float) -> None:
        mujoco.mj_setState(m, d, start, mujoco.mjtState.mjSTATE_INTEGRATION)
        _face(m, d, parts, heading, start)

    walker = lambda: d.qpos[parts.root].copy()  # noqa: E731
    box = lambda: d.qpos[parts.box_qpos].copy()  # noqa: E731
    out = {}
    restart(math.pi / 2)  # north: the room's open side
    a = walker()
    _run(m, d, 0.5, {parts.roll_act: 1.0})
    b = walker()
    _run(m, d, 0.5)
    out["roll_m"] = _dist(a, b)
    out["coast_m"] = _dist(b, walker())
    restart(0.0)  # east: at the box
    a = box()
    _run(m, d, 1.5, {parts.roll_act: 1.0})
    _run(m, d, 0.5)
    out["push_box_m"] = _dist(a, box())
    for newtons in (10, 20, 40):
        restart(math.pi / 2)
        a = box()
        d.xfrc_applied[parts.box, 0] = newtons
        _run(m, d, 0.5)
        d.xfrc_applied[parts.box, 0] = 0.0
        _run(m, d, 0.5)
        out[f"slide_{newtons}N_m"] = _dist(a, box())
    return out


def roll_distances(physics, control_steps: int, substeps: int) -> np.ndarray:
    """Metres the walker covers from rest at full ``roll``, heading east, after
    each of ``control_steps`` control steps of ``substeps`` physics steps
    (shape ``(control_steps,)``, non-decreasing). ``physics``: a dm_control
    ``Physics`` just reset on `CORRIDOR`; its state is left changed.

    Raises:
      ValueError: the model lacks the walker's parts (the module docstring),
        or the walker met something before the last step (its speed fell).
    """
    m, d, parts, start = _settled(physics)
    _face(m, d, parts, 0.0, start)
    d.ctrl[parts.roll_act] = 1.0
    origin = d.qpos[parts.root].copy()
    out = np.empty(control_steps)
    for k in range(control_steps):
        mujoco.mj_step(m, d, substeps)
        out[k] = _dist(origin, d.qpos[parts.root])
    d.ctrl[:] = 0.0
    steps = np.diff(out, prepend=0.0)
    if control_steps > 2 and steps[-1] < 0.9 * steps.max():
        raise ValueError("the walker slowed down: it met something, the run is not free")
    return out


def steer_angles(physics, control_steps: int, substeps: int) -> np.ndarray:
    """Radians the walker's heading (its ``steer`` joint) has turned from rest
    at full ``steer`` after each of ``control_steps`` control steps of
    ``substeps`` physics steps (absolute values). ``physics``: a dm_control
    ``Physics`` just reset on any level; its state is left changed.

    Raises:
      ValueError: the model lacks the walker's parts (the module docstring).
    """
    m, d, parts, _ = _settled(physics)
    origin = float(d.qpos[parts.steer])
    d.ctrl[parts.steer_act] = 1.0
    out = np.empty(control_steps)
    for k in range(control_steps):
        mujoco.mj_step(m, d, substeps)
        out[k] = abs(float(d.qpos[parts.steer]) - origin)
    d.ctrl[:] = 0.0
    return out


def _settled(physics) -> tuple[mujoco.MjModel, mujoco.MjData, _Parts, np.ndarray]:
    """The raw model and data of ``physics``, the walker's and box's addresses,
    and the integration state after velocities and controls are zeroed and the
    physics has run `_SETTLE_S` seconds (the state every scenario starts from).

    Raises:
      ValueError: the model lacks the walker's parts (the module docstring).
    """
    m, d = physics.model.ptr, physics.data.ptr
    parts = _Parts(m)
    d.qvel[:] = 0.0
    d.ctrl[:] = 0.0
    _run(m, d, _SETTLE_S)
    start = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    return m, d, parts, start


def _run(m, d, seconds: float, ctrl: dict | None = None) -> None:
    """``seconds`` of physics with ``ctrl`` (actuator -> value, the rest 0)."""
    d.ctrl[:] = 0.0
    for index, value in (ctrl or {}).items():
        d.ctrl[index] = value
    mujoco.mj_step(m, d, round(seconds / m.opt.timestep))
    d.ctrl[:] = 0.0


def _face(m, d, parts: _Parts, heading: float, start: np.ndarray) -> None:
    """Turns the walker (its ``steer`` joint) so that full ``roll`` moves it
    towards world ``heading`` (radians from +x), measured by a short roll from
    ``start`` and corrected twice."""
    for _ in range(2):
        turn = _heading_error(m, d, parts, heading, start)
        d.qpos[parts.steer] -= turn  # the steer joint turns about -z
    mujoco.mj_forward(m, d)


def _heading_error(m, d, parts: _Parts, heading: float, start: np.ndarray) -> float:
    steer = float(d.qpos[parts.steer])
    before = d.qpos[parts.root].copy()
    _run(m, d, _PROBE_S, {parts.roll_act: 1.0})
    dx, dy = d.qpos[parts.root] - before
    mujoco.mj_setState(m, d, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    d.qpos[parts.steer] = steer
    mujoco.mj_forward(m, d)
    return math.remainder(heading - math.atan2(dy, dx), math.tau)


def _dist(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.hypot(*(b - a)))
