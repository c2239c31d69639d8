"""Skills: controllers that turn a subgoal into motor actions.

* `skills.base`: the `Skill` role (``reset(description, subgoal, scene)``,
  ``act(timestep, scene)``, ``hold()``, ``status``);
* `skills.scene`: the scene estimates skills act on (`BallScene`, `ArmScene`);
* `skills.ball`: the MuJoBan rolling-ball walk-and-push skill;
* `skills.arm`: the Jaco arm's reach-and-touch skill (mink IK on its own model).

Skills sit behind the observation boundary: they see the subgoal, the
estimator's scene, the timestep and the task's public description, never the
simulator.
"""
