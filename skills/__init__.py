"""Skills: controllers that turn a subgoal into motor actions.

Filled in by the modular-agent issue.
"""
