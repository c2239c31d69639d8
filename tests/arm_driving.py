"""Test helper: drive the Jaco arm's fingertips onto a board point with joint commands.

Plain closed-loop control through the environment's own action interface:
the pinch site follows Cartesian waypoints (at most 2 cm per control step,
first at a safe height over the board, then straight down into the pad); the
task's IK turns each waypoint into joint targets and a proportional
joint-velocity command tracks them. Only `env.step` moves the arm.
"""

from __future__ import annotations

import numpy as np

SAFE_HEIGHT = 0.1  # metres above the target while travelling
STEP = 0.02  # metres per control step


def _drive(env, goal, steps, stop=None, gain=8.0):
    task = env.task
    spec = env.action_spec()
    timestep = None
    model = env.physics.model
    joints = model.dof_jntid[task._joint_dof[:6]]  # pylint: disable=protected-access
    wrap = ~model.jnt_limited[joints].astype(bool)
    for _ in range(steps):
        pinch = task.pinch_site_position()
        delta = goal - pinch
        distance = np.linalg.norm(delta)
        waypoint = goal if distance <= STEP else pinch + delta * (STEP / distance)
        q_target = task.solve_ik(waypoint)
        if q_target is None:
            q_target = task.solve_ik(goal)
        q = env.physics.data.qpos[task._joint_qpos[:6]]  # pylint: disable=protected-access
        delta = q_target - q
        # Continuous joints: the short way round.
        delta[wrap] = (delta[wrap] + np.pi) % (2 * np.pi) - np.pi
        action = np.zeros(spec.shape)
        action[:6] = gain * delta
        action[6:] = spec.maximum[6:]  # close the fingers
        timestep = env.step(np.clip(action, spec.minimum, spec.maximum))
        if timestep.last() or (stop is not None and stop()):
            break
        if distance < 2e-3 and stop is None:
            break
    return timestep


def touch_point(env, target_xyz, *, press_depth=0.01, steps=80, until=None):
    """Moves the closed hand over ``target_xyz``, presses down, lifts.

    Returns the last timestep (the move registers while pressing; with the
    arm reset on, the arm then jumps to a new random pose). The press stops
    when a move registers, or when ``until()`` (if given) is true.
    """
    task = env.task
    target = np.asarray(target_xyz, float)
    before = task.moves_registered
    registered = until or (lambda: task.moves_registered > before)  # noqa: E731
    pinch = task.pinch_site_position()
    high = max(pinch[2], target[2] + SAFE_HEIGHT)
    for goal, stop in (
        (np.array([pinch[0], pinch[1], high]), None),
        (np.array([target[0], target[1], high]), None),
        (target - (0, 0, press_depth), registered),
    ):
        timestep = _drive(env, goal, steps, stop)
        if timestep.last() or registered():
            return timestep
    return _drive(env, np.array([target[0], target[1], high]), steps // 2)


def lift(env, height=SAFE_HEIGHT, steps=40):
    """Raises the hand straight up by ``height`` (m); returns the last timestep."""
    pinch = env.task.pinch_site_position()
    return _drive(env, pinch + (0.0, 0.0, height), steps)


def central_action(task):
    """The legal action of a board task whose touches lie nearest the board's
    centre (the easiest to reach)."""
    centre = np.array(task.arena.centre)

    def spread(action):
        zones = task.game.touches(task.state, action)
        return max(np.abs(task.arena.point_xy[z] - centre).max() for z in zones)

    return min(sorted(task.state.legal_actions()), key=spread)


# -- set-ups that place the arm directly (for tests of registration) ---------


def _yaw_quat(yaw, base):
    from envs.boards.task import _quat_mul  # pylint: disable=import-outside-toplevel

    return _quat_mul([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)], base)


#: The hand pointing up (its z axis along the world z axis).
UP_QUAT = np.array([1.0, 0.0, 0.0, 0.0])


def place_hand(env, xyz, *, yaw=None, up=False, fingers=None):
    """Puts the arm at rest with its pinch site at ``xyz`` pointing down.

    With ``yaw`` (or ``up``) the hand's tool centre point is placed instead,
    pointing down with that yaw (or pointing up). ``fingers``: the finger
    joints (default closed). Returns False if the IK fails.
    """
    import mujoco  # pylint: disable=import-outside-toplevel

    task = env.task
    xyz = np.asarray(xyz, float)
    if yaw is None and not up:
        q = task.solve_ik(xyz)
    else:
        from envs.boards.task import DOWN_QUAT  # pylint: disable=import-outside-toplevel

        q = task._solve_tcp(xyz, _yaw_quat(yaw or 0.0, UP_QUAT if up else DOWN_QUAT))
    if q is None:
        return False
    data, model = env.physics.data.ptr, env.physics.model.ptr
    data.qpos[task._joint_qpos[:6]] = q
    if fingers is None:
        fingers = task._finger_range[:, 1]
    data.qpos[task._joint_qpos[6:]] = fingers
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    return True


def hold_action(env, arm_velocity=None):
    """An action keeping the arm still (or moving its joints at ``arm_velocity``)
    with the fingers closing."""
    spec = env.action_spec()
    action = np.zeros(spec.shape)
    if arm_velocity is not None:
        action[:6] = arm_velocity
    action[6:] = spec.maximum[6:]
    return np.clip(action, spec.minimum, spec.maximum)


def substep_touches(env, action):
    """Steps a copy of the physics through one control step, substep by substep.

    Returns ``(readings, contacts)``: the zones' touch-sensor readings per
    substep (substeps x zones, squares then pass) and per substep the set of
    (robot geom name, board geom name) pairs in contact. The environment's
    own state is untouched.
    """
    import mujoco  # pylint: disable=import-outside-toplevel

    task = env.task
    model, data = env.physics.model.ptr, env.physics.data.ptr
    copy = mujoco.MjData(model)
    mujoco.mj_copyData(copy, model, data)
    copy.ctrl[task._act_ids] = action
    adr = model.sensor_adr[[env.physics.bind(s).element_id for s in task._touch_sensors]]
    board = env.physics.bind(task.arena.board_body).element_id
    robot = task._is_arm | task._is_hand
    readings, contacts = [], []
    for _ in range(task.physics_steps_per_control_step):
        mujoco.mj_step(model, copy, 1)
        readings.append(copy.sensordata[adr].copy())
        pairs = set()
        for c in copy.contact[: copy.ncon]:
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            if c.dist > 0:
                continue
            for a, b in ((g1, g2), (g2, g1)):
                if robot[a] and model.geom_bodyid[b] == board:
                    pairs.add(
                        (
                            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, a),
                            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, b),
                        )
                    )
        contacts.append(pairs)
    return np.array(readings), contacts


def press_from_above(env, target_xyz, *, height=0.05, press_depth=0.01, steps=60):
    """Puts the closed hand ``height`` above ``target_xyz`` and drives it down.

    Stops when a move registers; returns the last timestep.
    """
    task = env.task
    target = np.asarray(target_xyz, float)
    if not place_hand(env, target + (0, 0, height)):
        raise RuntimeError(f"no IK solution above {target}")
    before = task.moves_registered
    return _drive(
        env, target - (0, 0, press_depth), steps, stop=lambda: task.moves_registered > before
    )
