"""End-to-end baselines: the paper's IMPALA-style actor-critic, in torch.

Modules and their contracts (shapes: T time, B batch, A action size):

* `agent_env` -- `AgentEnv(env_name, condition, ...)`: an `envs` environment
  seen by a learning agent. ``condition`` is ``"vanilla"``,
  ``"random-planner"`` or ``"expert-planner"``. ``input_spec`` (`InputSpec`)
  says what the network gets; ``reset() -> obs`` and ``step(action) ->
  StepResult`` where ``action`` lies in [-1, 1]^A (mapped to the
  environment's bounds) and ``obs`` is a dict of numpy arrays: ``"proprio"``
  float32 (P,), one uint8 (3, H, W) image per camera name in
  ``input_spec.images``, and for the planner conditions ``"planner"`` float32
  (C, H, W) (current and target abstract state planes) and, where
  ``input_spec.planner_action_dim > 0``, ``"planner_action"`` float32 one-hot.
  `StepResult` holds ``obs, reward_env, discount_env, reward_abs,
  discount_abs, last, info``; the auxiliary task (planner conditions) pays
  ``abs_reward`` when the estimated abstract state reaches the planner's
  target within ``t_abs`` control steps.
* `network` -- `ImpalaNet(input_spec, two_values)`: the paper's appendix
  architecture; ``forward(obs [T, B, ...], first [T, B], state) ->
  (NetOutput(mean, std, value_env, value_abs), state)``.
* `vtrace` -- V-trace targets (Espeholt et al. 2018) and the two-head
  actor-critic loss.
* `learner`, `actors`, `train` -- the actor-learner loop (local processes or
  Ray actors), checkpoints, TensorBoard; ``python -m hier_agents.train``.
"""
