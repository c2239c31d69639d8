"""`LearnedBallSkill`: the ball skill with a learned low-level controller.

What is geometric and what is learned
=====================================

Everything that turns a subgoal into *where the ball should go* stays the
scripted skill's (`skills.ball`): the legs (walks, push lines, corner arcs),
the pure-pursuit carrot, the speed profile (``v_des``: corners, the contact
speed, the push speed and the box's remaining distance), meeting the box
(back-offs, the recentring carrot while pushing), the drive direction (the
ball rolls either way; the sign with the smaller turn, with hysteresis), and
the status (success, failure, stuck).

What is learned is `skills.ball.controller.Drive.command`'s job: the map
from the carrot and speed target to the raw ``[roll, steer]`` action (the
scripted yaw-rate and roll loops, their gains, feed-forwards, deadband and
the push bias). `LearnedDrive` is a `Drive` whose ``command`` computes the
scripted loops only as the *teacher* (for behaviour cloning and
comparison) and for the geometric values they share (the drive sign and
heading error), then returns the policy's action.

The policy's observation (`FEATURES`, float32, 12 values, all in the
drive frame: +forward = the direction the ball rolls, +left):

==  =============  ===========================================================
 0  cos_err        cosine of the heading error towards the carrot
 1  sin_err        sine of it
 2  err            heading error / pi
 3  carrot_fwd     carrot ahead of the ball (m, drive frame)
 4  carrot_left    carrot to the left (m, drive frame)
 5  reach          distance to the carrot (m)
 6  v_des          the speed target of the path / contact geometry / 3.5 m/s
 7  v_along        velocity along the drive direction / 3.5 m/s
 8  v_left         velocity to the left / 3.5 m/s
 9  yaw_rate       yaw rate of the drive frame / 6.5 rad/s
10  pushing        1 while the ball is in contact with the box it pushes
11  sign           drive direction (+1: rolling towards the face, -1 back)
==  =============  ===========================================================

These are the inputs of the scripted ``Drive.command`` (position,
velocity, heading, yaw rate, carrot, speed target, pushing), made
path-relative; the box's offset from its line and its remaining distance
enter through the carrot (recentring) and ``v_des`` (the push's braking
curve), as in the scripted controller.

The policy's output is ``[throttle, steer]`` in the drive frame; the fixed
(not learned) map to the environment's action is ``roll = -sign *
throttle`` (a negative roll rolls towards the face), ``steer = steer``,
both clipped to [-1, 1]. The option environment
(`hier_agents.learning.skill_env.SkillEnv` with the ``ball`` spec) takes the policy's action;
`policy_action` / `env_action` convert.

The checkpoint (``ball_policy.pt``, next to this file) is a dict with
``"actor"`` (the mean network's state dict: 12 -> 64 -> 64 -> 2, tanh),
``"features"`` (the names above, checked on load) and ``"meta"`` (how it
was trained). At run time the network is evaluated in numpy (~10 us).
The skill trainer makes one from the ``ball`` spec
(`hier_agents.learning.skills.ball`; ``results/learned_ball/`` records how the
shipped one was trained and measured)::

    python -m hier_agents.learning.train_skill ball --frames 80000 --bc-frames 20000 \
        --dagger-frames 20000 --envs 2 --seed 0 --logdir runs/ball
    cp runs/ball/ball_policy.pt skills/learned/ball_policy.pt
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from skills.ball.controller import Drive
from skills.ball.skill import BallSkill
from skills.learned.base import LearnedSkill
from skills.learned.policy import NumpyPolicy
from skills.learned.policy import load_policy as _load

__all__ = [
    "LearnedBallSkill",
    "LearnedDrive",
    "NumpyPolicy",
    "FEATURES",
    "POLICY_PATH",
    "load_policy",
    "policy_action",
    "env_action",
]

FEATURES = (
    "cos_err",
    "sin_err",
    "err",
    "carrot_fwd",
    "carrot_left",
    "reach",
    "v_des",
    "v_along",
    "v_left",
    "yaw_rate",
    "pushing",
    "sign",
)
OBS_DIM = len(FEATURES)
#: Index of the drive sign in the feature vector.
SIGN = FEATURES.index("sign")
#: The shipped checkpoint.
POLICY_PATH = Path(__file__).with_name("ball_policy.pt")

_SPEED = 3.5
_RATE = 6.5


def env_action(throttle_steer, sign: float) -> np.ndarray:
    """The environment's raw [roll, steer] for a drive-frame [throttle, steer]."""
    a = np.asarray(throttle_steer, float)
    return np.clip(np.array([-sign * a[0], a[1]]), -1.0, 1.0)


def policy_action(roll_steer, sign: float) -> np.ndarray:
    """The drive-frame [throttle, steer] of a raw [roll, steer] (the inverse
    of `env_action` inside [-1, 1])."""
    a = np.asarray(roll_steer, float)
    return np.array([-sign * a[0], a[1]])


def load_policy(path=None) -> NumpyPolicy:
    """The policy of a ball checkpoint (default: the shipped one)."""
    return _load(path or POLICY_PATH, FEATURES)


class LearnedDrive(Drive):
    """A `Drive` whose command comes from a policy (see the module docstring).

    ``policy``: a callable features -> drive-frame [throttle, steer];
    ``"teacher"``: the scripted loops' action (the same as `BallSkill`);
    None: record only (the option environment supplies the action) and
    return zeros. After every ``command``: ``obs`` (the features) and
    ``teacher`` (the scripted loops' drive-frame [throttle, steer]).
    """

    __slots__ = ("policy", "obs", "teacher")

    def __init__(self, policy=None) -> None:
        super().__init__()
        self.policy = policy
        self.obs = np.zeros(OBS_DIM, np.float32)
        self.teacher = np.zeros(2)

    def command(
        self, config, px, py, vx, vy, heading, rate, speed, carrot_x, carrot_y, v_des, pushing
    ):
        # The scripted loops: the teacher's action and the geometric values
        # they share with the policy (the drive sign with its hysteresis,
        # the heading error, the speed along the drive direction).
        roll_t, steer_t, err, v_scaled, v_along = super().command(
            config, px, py, vx, vy, heading, rate, speed, carrot_x, carrot_y, v_des, pushing
        )
        sign = self.sign
        face = heading if sign > 0 else heading + math.pi
        c, s = math.cos(face), math.sin(face)
        dx, dy = carrot_x - px, carrot_y - py
        obs = self.obs
        obs[0] = math.cos(err)
        obs[1] = math.sin(err)
        obs[2] = err / math.pi
        obs[3] = max(-3.0, min(3.0, c * dx + s * dy))
        obs[4] = max(-3.0, min(3.0, -s * dx + c * dy))
        obs[5] = min(3.0, math.hypot(dx, dy))
        obs[6] = min(v_des, 2 * _SPEED) / _SPEED
        obs[7] = v_along / _SPEED
        obs[8] = (-s * vx + c * vy) / _SPEED
        obs[9] = max(-3.0, min(3.0, rate / _RATE))
        obs[10] = 1.0 if pushing else 0.0
        obs[SIGN] = sign
        self.teacher = policy_action((roll_t, steer_t), sign)
        if self.policy is None:
            return 0.0, 0.0, err, v_scaled, v_along
        out = self.teacher if self.policy == "teacher" else self.policy(obs)
        roll, steer = env_action(out, sign)
        return float(roll), float(steer), err, v_scaled, v_along


class LearnedBallSkill(BallSkill, LearnedSkill):
    """`BallSkill` whose low-level controller is a learned policy (module
    docstring), plugged in through `BallSkill`'s ``drive`` hook. Name
    ``"learned-ball"``; a `skills.learned.base.LearnedSkill`.

    Args:
      policy: a callable features -> drive-frame [throttle, steer], a
        checkpoint path, ``"teacher"`` (the scripted loops: behaves as
        `BallSkill`), or None for the shipped checkpoint.
      record_only: act returns zeros and only records ``features`` (the
        skill environment's mode: the learner supplies the action).
      **overrides: `skills.ball.BallConfig` fields, as for `BallSkill`.
    """

    name = "learned-ball"
    FEATURES = FEATURES
    ACTION_DIM = 2

    def __init__(self, policy=None, *, record_only: bool = False, config=None, **overrides):
        if record_only:
            policy = None
        elif policy is None or isinstance(policy, (str, Path)) and policy != "teacher":
            policy = load_policy(policy)
        super().__init__(config, drive=lambda: LearnedDrive(policy), **overrides)
        self.policy = policy

    def __repr__(self) -> str:
        kind = (
            "record-only"
            if self.policy is None
            else ("teacher" if self.policy == "teacher" else type(self.policy).__name__)
        )
        return f"LearnedBallSkill({kind})"

    @property
    def features(self) -> np.ndarray:
        """The policy's observation at the last ``act`` (a copy)."""
        return self._drive.obs.copy()

    @property
    def teacher_action(self) -> np.ndarray:
        """The scripted loops' drive-frame [throttle, steer] at the last ``act``."""
        return self._drive.teacher.copy()

    def env_action(self, policy_action) -> np.ndarray:
        """The raw [roll, steer] of a drive-frame [throttle, steer]."""
        return env_action(policy_action, float(self._drive.obs[SIGN]))
