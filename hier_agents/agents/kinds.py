"""The agent kinds shipped: ``modular``, ``checkpoint:PATH``, ``sb3:PATH`` and ``random[:HOLD]``.

* ``modular``: estimator + planner + skill (`hier_agents.modular`), parts
  named by the ``planner``, ``skill`` and ``estimator`` options
  (`hier_agents.modular.components.resolve`); privileged exactly when its
  estimator reads the simulator.
* ``checkpoint:PATH``: a trained end-to-end agent (`python -m
  hier_agents.train`; PATH its run directory or checkpoint file),
  `hier_agents.agents.checkpoint.CheckpointAgent`; the ``stochastic`` option
  samples its policy instead of taking its mean.
* ``sb3:PATH``: a Stable-Baselines3 model (``python -m
  hier_agents.baselines.sb3``; PATH its run directory or a ``.zip``),
  `hier_agents.agents.sb3.Sb3Agent`; ``stochastic`` samples its policy.
* ``random[:HOLD]``: uniformly random actions, a new draw every HOLD
  control steps (default 1): the floor every trained agent must clear.

`hier_agents.agents.registry` registers them (`SHIPPED`) on first use.
"""

from __future__ import annotations

from pathlib import Path

from hier_agents.agents.base import READS, AgentKind, AgentSetup, TrainedKind
from hier_agents.agents.sb3 import Sb3Kind
from physics_planning.cli import UsageError, plural

__all__ = ["ModularKind", "CheckpointKind", "RandomKind", "Sb3Kind", "SHIPPED"]


class ModularKind(AgentKind):
    """The modular agent (module docstring)."""

    name = "modular"
    help = "estimator + planner + skill (--planner, --skill, --estimator)"
    options = ("planner", "skill", "estimator")

    def check(self, env_name: str, arg, options: dict) -> None:
        from hier_agents.modular import components

        fam = components.family(env_name)
        for part in self.options:
            if options.get(part) is not None:
                components.check(part, fam, options[part])

    def setup(self, env_name: str, arg, options: dict) -> AgentSetup:
        from hier_agents.modular import components

        fam = components.family(env_name)
        parts = {part: options.get(part) for part in self.options}
        estimator = parts["estimator"]
        access = components.access(fam, estimator)

        def build(view, seed, simulator):
            return components.make_agent(
                env_name, view.description(), seed=seed, simulator=simulator, **parts
            )

        summary = {
            "agent": "modular",
            "planner": parts["planner"] or next(iter(components.PLANNERS[fam])),
            "skill": parts["skill"] or next(iter(components.SKILLS[fam])),
            "estimator": components.estimator_name(fam, estimator),
            "privileged": access != "observations",
            "reads": access,
        }
        return AgentSetup(components.env_overrides(env_name, estimator), access, summary, build)

    def describe(self, summary: dict) -> str:
        who = (
            f"estimator {summary.get('estimator', '?')}"
            f"{_privilege(summary)}, "
            f"planner {summary['planner']}, skill {summary['skill']}"
        )
        if summary.get("training_frames"):
            who += (
                f" (learned parts trained on "
                f"{plural(summary['training_frames'], 'frame', spec=',')})"
            )
        return who

    def job_inputs(self, env_name: str, arg, options: dict) -> dict:
        """``{"kind": "modular", the parts given, "learned_files": content
        hashes of the learned parts' checkpoints}``
        (`hier_agents.modular.components.learned_files`): a retrained part is
        a new job."""
        from hier_agents.modular.components import learned_files

        return {"kind": "modular", **options, "learned_files": learned_files(env_name, options)}

    def from_job_inputs(self, inputs: dict) -> tuple[object, dict]:
        return None, {k: inputs[k] for k in self.options if k in inputs}


def _privilege(summary: dict) -> str:
    """ " (PRIVILEGED: reads ...)" for a privileged modular run's summary, else ""."""
    if not summary.get("privileged"):
        return ""
    return f" (PRIVILEGED: reads {READS[summary.get('reads', 'simulator')]})"


class CheckpointKind(TrainedKind):
    """A trained end-to-end agent (module docstring)."""

    name = "checkpoint"
    help = "a trained end-to-end agent: a python -m hier_agents.train run directory or file"

    def check(self, env_name: str, arg, options: dict) -> None:
        if not Path(arg).exists():
            raise UsageError(f"--agent checkpoint:{arg}: no checkpoint or run directory at {arg!r}")
        from hier_agents.baselines.impala.checkpoints import load_checkpoint

        load_checkpoint(arg)

    def setup(self, env_name: str, arg, options: dict) -> AgentSetup:
        from hier_agents.agents.checkpoint import checkpoint_setup

        return checkpoint_setup(env_name, arg, bool(options.get("stochastic", False)))


class RandomKind(AgentKind):
    """Uniformly random actions (module docstring)."""

    name = "random"
    help = "uniform random actions, each held HOLD control steps (default 1)"
    metavar = "HOLD"

    def parse(self, text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = 0
        if value < 1:
            raise UsageError(
                f"a random agent is 'random' or 'random:HOLD' with HOLD >= 1 "
                f"control steps per draw, got 'random:{text}'"
            )
        return value

    def default(self) -> int:
        return 1

    def setup(self, env_name: str, arg, options: dict) -> AgentSetup:
        import envs
        from hier_agents.agents.random_actions import RandomAgent

        hold = int(arg)

        def build(view, seed, simulator):
            return RandomAgent(view.action_spec(), hold)

        summary = {
            "condition": f"uniform random actions, held {plural(hold, 'step')}",
            "trained_env": "-",
            "training_frames": 0,
            "training_updates": 0,
        }
        return AgentSetup(dict(envs.no_cameras(env_name)), "observations", summary, build)

    def describe(self, summary: dict) -> str:
        return str(summary.get("condition", summary["agent"]))

    def job_inputs(self, env_name: str, arg, options: dict) -> dict:
        return {"kind": "random", "hold": int(arg)}

    def from_job_inputs(self, inputs: dict) -> tuple[object, dict]:
        return int(inputs["hold"]), {}


#: The kinds shipped, in the order ``--list`` shows them (``modular`` first:
#: the default); `hier_agents.agents.registry` registers them on first use.
SHIPPED = (ModularKind(), CheckpointKind(), Sb3Kind(), RandomKind())
