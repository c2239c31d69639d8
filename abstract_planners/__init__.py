"""Abstract planners: pure game logic and search (no physics, no torch).

Filled in by the abstract-planners issue.
"""
