"""``python -m hier_agents.baselines.sb3``: `hier_agents.baselines.sb3.cli.main`."""

import sys

from hier_agents.baselines.sb3.cli import main

if __name__ == "__main__":
    sys.exit(main())
