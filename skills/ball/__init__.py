"""The MuJoBan ball skill: the rolling ball carries out Sokoban subgoals.

`BallSkill` (name ``"ball"``) executes the `Subgoal`s of
`abstract_planners.sokoban_solver.SokobanSolverPlanner`: one move letter
(``plan(state)``) or a tuple of letters, the walk to a box and its push
(``next_push(state)``). It is a closed-loop controller on the walker's
position, velocity and heading and on the box positions, all read from the
estimator's `skills.scene.BallScene` every control step (the observation
boundary: the skill never reads the simulator; with the ``camera``
estimator it acts on what the top camera and the walker's proprioception
show). Grid geometry comes from the task's public
`envs.description.MujobanDescription`. ~40 us of Python per ``act``; ~0.2 ms
per ``reset``.

Usage (the option layer's loop, `hier_agents.modular.options.run_option`)::

    skill = BallSkill()
    skill.reset(env.description(), subgoal, scene)   # scene: estimator.estimate(timestep)
    while skill.status is Status.RUNNING and steps < T_abs:
        timestep = env.step(skill.act(timestep, scene))
        scene = estimator.estimate(timestep)

An empty subgoal, ``Subgoal(action=(), state=state)``, means "hold": centre
any box the walker left short of its cell centre (e.g. a push cut off by the
option layer whose box already rounds onto its pad without covering it),
then stand still; it succeeds once the boxes are settled.

Trajectory
==========

At ``reset`` the subgoal's moves are replayed on the planned-from state and
extended with a look-ahead from ``subgoal.plan``: after a walk, up to and
including the next push; after a push, the pushes that continue it in the
same direction. The moves become *legs*: a walk, ending (for a push) on the
push line through the box's actual centre, up to where the walker stands
when the box is centred in its last cell. Pushes in one direction are one
leg, so the box is never stopped in between; re-planning between subgoals
(the option layer re-estimates at least every T_abs steps) rebuilds the same
trajectory from wherever the walker is.

A walk's cell centres are first joined by straight lines wherever the ball
keeps 0.3 cells (its radius plus 0.1) from every wall and box cell and, in
levels with pegs (a 45-degree square post, 0.05 m from its axis to its
corners, at every interior grid intersection, blocking the ball as well as
the boxes), 0.35 cells (the ball's radius, the peg's and 0.1 m) from every
grid intersection (so staircases become diagonals in open rooms without
pegs, never in corridors, and with pegs the ball stays near the cell-centre
lines), then every corner is rounded by the widest arc (radius <= 1 cell)
that is just as clear and whose chord keeps the ball's radius from them (and
the ball's plus the peg's radius from pegs: the pursuit cuts inside fast
arcs). A turn into a push line keeps a straight run of 0.3 m before the
contact. A box that the walker left short of its cell centre while standing
behind it (its push was cut off) is first pushed on to the centre; while
holding (an empty subgoal), a box off its centre with the walker elsewhere
is reached from its far side by the shortest walk and pushed back.

Control
=======

*Steering*: pure pursuit on the trajectory (a carrot ``0.45 + 0.35 v``
metres ahead); the ball rolls either way (the face only sets the sign of the
roll command), so the drive direction is the one needing the smaller turn,
with hysteresis. A yaw-rate loop turns the head (feed-forward of the
measured steer deadband and gain, rate feedback): the head is torque
driven with a ~0.2 s lag, ~0.3 s per 90 degrees.

*Pushing*: boxes (half-size 0.4 m, 2.5 kg) slide without rotating on floor
friction 0.5 (~12 N; once not pushed they decelerate at ~4.9 m/s^2, from
1 m/s they coast ~0.1 m), and the ball meets them with friction 1, so a ball
moving sideways while in contact drags its box sideways. A box more than
0.05 m off its cell's centre line catches on the pegs ahead of it. The ball
meets the box on the push line through the box's actual centre (within
``align_gap`` of it, a ball more than ``align_tol`` (``finish_align_tol``
for the short push that centres a box left short) off that line backs off
and comes in again, the tolerance widening by itself per back-off, also
across re-plans of the same push) and, once touching, aims ``k_recentre`` times the box's
offset from its cell's centre line on the other side of that line: its
sideways motion drags the box back onto the line before the pegs can catch
it. A box that stops advancing while off its line (caught on a peg
already) is dragged from wherever the ball is: the carrot moves
``max_recentre`` sideways from the ball, towards the line, until the box
moves on (``stall_steps``, ``stall_off``).

*Speed*: the minimum of the cruise speed and, for every constraint at path
distance ``s`` ahead with speed ``v_c`` (arcs ``sqrt(a_lat r)``, sharp
corners, the contact with the box, the end of a walk), ``sqrt(v_c^2 +
2 a s)``; while pushing, at most ``push_speed`` (1.5 m/s), and the box's
remaining distance ``r`` caps it at ``sqrt(2 a_push (r - lead))`` with
``a_push`` = 3.5 m/s^2, below the box's own floor deceleration, so the ball
stays in contact and steers the box to the end (faster pushes or planned
decelerations near 4.9 m/s^2 let boxes run on and miss the pad's 0.1-cell
tolerance). The box then stops within ``center_tol`` of its cell centre. The
target is scaled down with the heading error and tracked by a proportional
roll command with feed-forward. The ball meets the box at
``contact_speed`` (1.2 m/s) and pushing accelerates at only ~2.6 m/s^2:
one push takes ~1 s, each further cell of a straight push ~0.55 s. Before
the ball meets the box, the push's cap only limits it to what it can brake
to by the contact; a leg rebuilt while the ball already touches the box (a
re-plan mid-push) has no meeting speed (braking there would let the box
slide on alone).

Status
======

* SUCCESS when the scene's abstract cells (boxes as a set, and the player)
  equals the subgoal's state and, if the trajectory ends with the subgoal,
  the pushed box is settled (< 0.1 m/s) within ``center_tol`` (0.08 cells)
  of its cell centre, or the walker stands near its last cell. When the plan
  goes on the same way (the next push continues in the same direction, the
  walk continues) reaching the abstract state is enough, so the ball does
  not stop between subgoals. *Chaining*: when the plan goes on after a push
  that ends a stroke (the next walk is known, ``subgoal.plan`` not empty),
  the push is done as soon as the box, sliding on alone at its floor
  deceleration (``box_decel``, 4.9 m/s^2), will stop within half of
  ``center_tol`` of its cell centre: the ball turns to the next walk
  without waiting for the box to come to rest (``chain=False`` waits).
* FAILURE, with ``failure_reason`` = ``"<kind>: <details>"``, kinds:
  ``illegal move`` (in the given state; at ``reset``), ``stuck`` (no
  progress for ``stuck_steps`` steps: blocked path, box against a wall or
  snagged on a peg), ``box disturbed`` (a box that should stay put moved more
  than ``disturb_tol``), ``box off line`` (the pushed box left its push line
  by 0.2 m), ``estimate deviates`` (the estimated boxes are none of the
  placements the trajectory passes through), ``box overshot`` (it settled
  outside its target cell), ``not reached`` (stopped, but the estimate never
  matched).

The skill keeps no state between ``reset`` calls except the walker's last
heading (for its yaw rate) and drive direction, forgotten when a timestep is
the first of an episode or the environment changes (and a back-off from a
box, kept across a re-plan that pushes the same box the same way).

Parameters
==========

Every speed, tolerance and gain named above is a field of the frozen
`BallConfig` (``skills.ball.config``): ``BallSkill(cruise_speed=3.0)``
overrides one, ``BallSkill(config)`` takes a whole record; unknown names
raise `TypeError`.

Modules
=======

`config` (the parameters), `paths` (grid geometry: clearances, string
pulling, corner arcs), `legs` (the trajectory: subgoal to legs),
`controller` (pursuit, speed profile, box contact, yaw-rate and roll loops),
`skill` (`BallSkill`: reset, act, status).
"""

from skills.ball.config import BallConfig
from skills.ball.paths import BALL_RADIUS, BOX_HALF, CONTACT, PEG_RADIUS
from skills.ball.skill import BallSkill

__all__ = ["BallSkill", "BallConfig", "BOX_HALF", "BALL_RADIUS", "CONTACT", "PEG_RADIUS"]
