"""`CheckpointAgent`: a trained end-to-end agent's policy, played by the episode runner.

The agent reads what its network was trained on, built by the same
`hier_agents.baselines.impala.inputs.AgentInputs` as the actors' training
environment (cameras, proprioception and, for the planner conditions and
``state``, the privileged abstract state), and acts with the policy's mean
(or samples, ``stochastic``), holding each action for the run's
``action_repeat`` control steps as its actors did. `checkpoint_setup` is the
``checkpoint:PATH`` agent kind's plan: the environment settings the run was
trained with (its cameras at its image size, its overrides), whether it is
privileged and what the run summary says of it.
"""

from __future__ import annotations

import numpy as np

from hier_agents.agents.base import AgentSetup, HeldAction, trained_setup
from hier_agents.modular.agent import OptionStats
from physics_planning.cli import UsageError

__all__ = ["CheckpointAgent", "checkpoint_setup"]


def checkpoint_setup(env_name: str, path: str, stochastic: bool = False) -> AgentSetup:
    """The plan of ``checkpoint:PATH`` on ``env_name``.

    Raises:
      FileNotFoundError: no checkpoint at ``path``.
      UsageError: not a checkpoint of ``python -m hier_agents.train``; one of
        another family's environment.
    """
    import envs
    from hier_agents.baselines.impala.checkpoints import load_checkpoint, observed
    from hier_agents.modular.families import family

    ckpt = load_checkpoint(path)
    config = ckpt["config"]
    if family(config["env"]) != family(env_name):
        raise UsageError(
            f"checkpoint {path} was trained on {config['env']!r}, a "
            f"{family(config['env'])} environment; cannot play {env_name!r}"
        )
    size = int(config["image_size"])
    overrides = {
        name: ((size, size) if config["cameras"] else None)
        for name in envs.overrides(env_name)
        if name.endswith("_camera")
    }
    overrides.update(envs.recorded_options(env_name, config.get("env_overrides", {})))
    from hier_agents.baselines.impala.checkpoints import net_from_checkpoint

    _, spec = net_from_checkpoint(ckpt)
    observations, privileged = observed(config, spec)
    summary = {
        "condition": config["condition"] + (" (sampled)" if stochastic else ""),
        "trained_env": config["env"],
        "training_frames": int(ckpt["counters"].get("frames", 0)),
        "training_updates": int(ckpt["counters"].get("updates", 0)),
        "observations": observations,
        "privileged": privileged,
    }

    def build(view, seed, simulator):
        return CheckpointAgent(ckpt, view, seed, simulator, stochastic=stochastic)

    return trained_setup(overrides, summary, build)


class CheckpointAgent:
    """A checkpoint's policy acting on timesteps (the
    `hier_agents.agents.base.Agent` contract).

    Args:
      ckpt: a loaded checkpoint (`hier_agents.baselines.impala.checkpoints.load_checkpoint`).
      view: the environment as the agent sees it (specs, ``description()``).
      seed: the run's seed (the auxiliary planner's; each episode's own seed
        reseeds the policy's samples and the planner).
      simulator: the environment itself, for privileged inputs (the planner
        conditions, ``state``); None otherwise.
      stochastic: sample actions instead of taking the policy's mean.

    Raises:
      UsageError: the environment gives other inputs than the network's.
    """

    estimates = False
    scene = None
    gave_up = None

    def __init__(
        self, ckpt: dict, view, seed: int | None, simulator=None, *, stochastic: bool = False
    ):
        import torch

        from hier_agents.baselines.impala.inputs import ActionMap, AgentInputs, make_auxiliary
        from hier_agents.baselines.impala.checkpoints import net_from_checkpoint

        config = ckpt["config"]
        self.net, spec = net_from_checkpoint(ckpt)
        torch.set_num_threads(1)
        description = view.description()
        planner, estimator = make_auxiliary(config["condition"], description, seed, simulator)
        self.inputs = AgentInputs(
            description,
            view.observation_spec(),
            view.action_spec(),
            config["condition"],
            state=config.get("state", False),
            task=None if simulator is None else simulator.task,
            planner=planner,
            estimator=estimator,
            t_abs=config["t_abs"],
            abs_reward=config["abs_reward"],
        )
        if self.inputs.spec != spec:
            self.inputs.close()
            raise UsageError(
                f"the environment gives inputs {self.inputs.spec}, the checkpoint expects {spec}"
            )
        self.actions = ActionMap(view.action_spec())
        self.privileged = bool(spec.privileged)
        self.training_frames = int(ckpt["counters"].get("frames", 0))
        self.stochastic = bool(stochastic)
        self._generator = torch.Generator()
        self._state = self.net.initial_state(1)
        self._first = np.ones(1, dtype=bool)
        # A run trained with --action-repeat K decides every K control steps
        # (sooner when an auxiliary sub-episode ends), as its actors did.
        self.held = HeldAction(config.get("action_repeat", 1))

    @property
    def episode_stats(self) -> OptionStats:
        """The auxiliary task's targets issued and reached this episode."""
        info = self.inputs.episode_info()
        issued, reached = info.get("subgoals_issued", 0), info.get("subgoals_reached", 0)
        return OptionStats(issued=issued, reached=reached, unfinished=issued - reached)

    def reset(self, description, timestep, seed: int | None = None) -> None:
        self._generator.manual_seed(0 if seed is None else int(seed))
        self.inputs.reset(timestep, seed)
        self._state = self.net.initial_state(1)
        self._first[0] = True
        self.held.reset()

    def act(self, timestep) -> np.ndarray:
        if not self._first[0]:
            _, discount_abs = self.inputs.after_step(timestep)
            if self.inputs.planning and discount_abs == 0.0:
                self.held.release()  # a new target: decide now
        held = self.held.next()
        if held is not None:
            return held
        obs = self.inputs.observe(timestep.observation)
        batch = {k: v[None] for k, v in obs.items()}
        action, _, self._state = self.net.act(
            batch,
            self._first,
            self._state,
            deterministic=not self.stochastic,
            generator=self._generator,
            policy_only=True,  # acting needs no value
        )
        self._first[0] = False
        return self.held.hold(self.actions(action[0]))

    def end_episode(self, timestep) -> None:
        """Counts the auxiliary target the last step reached."""
        if not self._first[0]:
            self.inputs.after_step(timestep)

    def close(self) -> None:
        self.inputs.close()
