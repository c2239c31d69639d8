"""Agents: estimators, the option layer, modular and end-to-end agents.

Filled in by the modular-agent and baselines issues.
"""
