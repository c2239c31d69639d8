"""What every package of physics-planning shares: the version and the
command-line toolkit (`physics_planning.cli`). It imports nothing of the
project, so `abstract_planners`, `envs`, `skills` and `hier_agents` may all
import it."""

__version__ = "0.2.0"
