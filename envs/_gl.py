"""Headless OpenGL default.

Rendering in this library goes through MuJoCo's own offscreen renderer. On a
machine without a display the EGL backend (Mesa's llvmpipe on CPU-only
machines) works where GLFW does not, so ``MUJOCO_GL=egl`` is set here when the
user has not chosen a backend. This module must be imported before
``mujoco``'s rendering module reads the variable, which is why ``envs``
imports it first.
"""

import os

if not os.environ.get("MUJOCO_GL"):
    os.environ["MUJOCO_GL"] = "egl"
# PyOpenGL must agree with MuJoCo about the platform.
if os.environ["MUJOCO_GL"] in ("egl", "osmesa") and not os.environ.get("PYOPENGL_PLATFORM"):
    os.environ["PYOPENGL_PLATFORM"] = os.environ["MUJOCO_GL"]
