"""Test-session set-up.

``envs`` is imported first so that it chooses the headless OpenGL backend
(``MUJOCO_GL=egl`` unless set) before any test module imports ``mujoco``,
whose rendering reads the variable once, at import.
"""

import envs  # noqa: F401
