"""Offscreen RGB rendering of named cameras, shared by every environment.

One ``mujoco.Renderer`` (one OpenGL context) is kept per image size and reused
for every frame; a frame is written into a preallocated buffer and copied out
once. Nothing is rendered until a camera is actually asked for, so an
environment whose cameras are switched off never creates a GL context.

On a software rasteriser (Mesa llvmpipe) a frame's cost is draw calls and
vertices, not pixels, so the arenas keep their visible geom count small
(merged wall slabs, one mesh for all pegs) and switch shadows off. Frames no
larger than `SMALL_FRAME` pixels a side are drawn with MuJoCo's built-in
shapes (spheres, capsules, cylinders, planes and boxes) tessellated as
`SMALL_FRAME_TESSELLATION` says instead of the model's ``visual/quality``
(which larger frames, such as videos, keep): at the observations' 84x84 and
96x96 and the camera estimator's 199x199 this changes a handful of
silhouette pixels (bounds in ``tests/test_rendering.py``) and takes about a
third off the cost of a MuJoBan frame.
"""

from __future__ import annotations

import atexit
import os
import weakref
from dataclasses import dataclass
from typing import Any

from envs import _gl  # noqa: F401  (sets MUJOCO_GL before mujoco renders)

import mujoco
import numpy as np

from envs.profile import PROFILE


class RenderError(RuntimeError):
    """Raised when no OpenGL context can be created for offscreen rendering."""


@dataclass(frozen=True)
class CameraConfig:
    """A camera observation: which MuJoCo camera, at which resolution.

    Attributes:
      camera: the camera's full name in the compiled model.
      height: image height in pixels.
      width: image width in pixels.
    """

    camera: str
    height: int = 96
    width: int = 96

    def __post_init__(self):
        for name in ("height", "width"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(
                    f"camera {self.camera!r}: {name} must be a positive int, got {value!r}"
                )


@dataclass(frozen=True)
class Marker:
    """A render-only flat disc (a thin cylinder with a vertical axis) drawn
    over `Cameras.render` frames when asked for; nothing collides with it and
    the scene's depth test hides it behind taller geoms.

    Attributes:
      position: world (x, y, z) of the disc's centre, metres.
      radius: metres.
      rgba: colour, components in [0, 1].
    """

    position: tuple[float, float, float]
    radius: float
    rgba: tuple[float, float, float, float] = (0.9, 0.9, 0.9, 1.0)


#: Largest side, in pixels, of a frame drawn with `SMALL_FRAME_TESSELLATION`.
SMALL_FRAME = 256
#: ``visual/quality`` fields used for small frames (each at most the model's
#: own): slices and stacks of round shapes, and quads per side of a plane or
#: box face. Quads carry per-vertex lighting: they are reduced only when every
#: light of the model is directional (MuJoBan's headlight), where one quad
#: draws the same pixels as four; a spot or point light (the board games')
#: needs them for its falloff.
SMALL_FRAME_TESSELLATION = {"numslices": 16, "numstacks": 10, "numquads": 1}

#: Half-thickness of a `Marker` disc, metres.
MARKER_HALF_HEIGHT = 0.002
_IDENTITY = np.eye(3).ravel()


_LIVE: "weakref.WeakSet[Cameras]" = weakref.WeakSet()
_EXIT_HOOK_REGISTERED = False


def _close_all() -> None:
    # Free GL contexts while EGL is still initialised; at interpreter teardown
    # their finalizers would otherwise fail noisily.
    for cameras in list(_LIVE):
        cameras.close()


def _register_exit_hook() -> None:
    # atexit runs handlers last-in first-out: registering after MuJoCo's EGL
    # module (imported with the first context) makes ours run before its
    # eglTerminate.
    global _EXIT_HOOK_REGISTERED
    if not _EXIT_HOOK_REGISTERED:
        atexit.register(_close_all)
        _EXIT_HOOK_REGISTERED = True


class _KeepCurrentContext:
    """Inside a ``with`` block a renderer may make its own OpenGL context
    current; on exit the context that was current before is current again
    (none if none was). EGL only; with other backends nothing is changed.

    MuJoCo's GL objects (framebuffers, textures) are named per context, and
    another library in the same process that frees or draws with its own
    while ours is current touches ours instead: dm_control does both, and
    believes its context stays current between its calls. Restoring the
    previous context after every frame keeps both right
    (``tests/test_rendering.py``)."""

    __slots__ = ("_egl", "_saved")

    def __init__(self):
        self._egl = os.environ.get("MUJOCO_GL", "").lower() == "egl"

    def __enter__(self):
        if self._egl:
            from mujoco.egl import egl_ext as EGL

            self._saved = (
                EGL.eglGetCurrentDisplay(),
                EGL.eglGetCurrentSurface(EGL.EGL_DRAW),
                EGL.eglGetCurrentSurface(EGL.EGL_READ),
                EGL.eglGetCurrentContext(),
            )
        return self

    def __exit__(self, *exc):
        if self._egl:
            from mujoco import egl as mujoco_egl
            from mujoco.egl import egl_ext as EGL

            display, draw, read, context = self._saved
            if context:
                EGL.eglBindAPI(EGL.EGL_OPENGL_API)  # a context's free resets the thread's API
                EGL.eglMakeCurrent(display, draw, read, context)
            else:
                EGL.eglMakeCurrent(
                    mujoco_egl.EGL_DISPLAY,
                    EGL.EGL_NO_SURFACE,
                    EGL.EGL_NO_SURFACE,
                    EGL.EGL_NO_CONTEXT,
                )
        return False


class _Quality:
    """Sets the model's ``visual/quality`` tessellation fields to ``values``
    (each at most the model's own) inside a ``with`` block, then restores them."""

    def __init__(self, model: mujoco.MjModel, values: dict | None):
        self._quality = model.vis.quality
        values = dict(values or {})
        if np.any(model.light_type != mujoco.mjtLightType.mjLIGHT_DIRECTIONAL):
            values.pop("numquads", None)
        self._values = {k: min(v, getattr(self._quality, k)) for k, v in values.items()}
        self._saved: dict[str, Any] = {}  # the quality values replaced, to restore

    def __enter__(self):
        for key, value in self._values.items():
            self._saved[key] = getattr(self._quality, key)
            setattr(self._quality, key, value)

    def __exit__(self, *exc):
        for key, value in self._saved.items():
            setattr(self._quality, key, value)
        self._saved.clear()


class Cameras:
    """Renders RGB images from cameras of one compiled model.

    Args:
      model: the compiled model; only its ``visual/quality`` tessellation is
        changed, and only while a small frame's context is made or drawn.
      small_frame_tessellation: draw frames of at most `SMALL_FRAME` pixels
        a side with `SMALL_FRAME_TESSELLATION` (the default); False draws
        every frame with the model's own ``visual/quality``.
    """

    def __init__(self, model: mujoco.MjModel, *, small_frame_tessellation: bool = True):
        self._model = model
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._quality: dict[tuple[int, int], _Quality] = {}
        self._small = bool(small_frame_tessellation)
        self._option = mujoco.MjvOption()
        _LIVE.add(self)

    def camera_id(self, name: str) -> int:
        cam_id = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if cam_id < 0:
            names = [self._model.camera(i).name for i in range(self._model.ncam)]
            raise ValueError(f"no camera named {name!r}; the model has {names}")
        return cam_id

    def _renderer(self, height: int, width: int) -> mujoco.Renderer:
        key = (height, width)
        renderer = self._renderers.get(key)
        if renderer is None:
            max_h, max_w = self._model.vis.global_.offheight, self._model.vis.global_.offwidth
            if height > max_h or width > max_w:
                raise ValueError(
                    f"a {height}x{width} frame is larger than the model's offscreen buffer "
                    f"({max_h}x{max_w}); build the environment with "
                    f"render_size=({height}, {width}) or larger"
                )
            small = self._small and max(height, width) <= SMALL_FRAME
            quality = _Quality(self._model, SMALL_FRAME_TESSELLATION if small else None)
            try:
                with quality, _KeepCurrentContext():
                    renderer = mujoco.Renderer(self._model, height=height, width=width)
            except Exception as exc:  # GL errors come in many types
                raise RenderError(
                    f"could not create a {width}x{height} offscreen OpenGL context "
                    f"(MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}): {exc}. "
                    "On a headless Linux machine install Mesa's EGL (libegl1, libgl1-mesa-dri) "
                    "or switch the cameras off."
                ) from exc
            self._renderers[key] = renderer
            self._quality[key] = quality
            _register_exit_hook()
        return renderer

    def prepare(self, height: int, width: int) -> None:
        """Creates the GL context for this image size ahead of the first frame."""
        self._renderer(height, width)

    def render(
        self, data: mujoco.MjData, camera: int | str, height: int, width: int, markers=()
    ) -> np.ndarray:
        """Returns a fresh (height, width, 3) uint8 image from `camera`, with
        the `Marker` discs in `markers` drawn over the scene (as many as the
        scene has room for)."""
        with PROFILE.section("render"):
            return self._render(data, camera, height, width, markers)

    def _render(self, data, camera, height, width, markers) -> np.ndarray:
        if isinstance(camera, str):
            camera = self.camera_id(camera)
        renderer = self._renderer(height, width)
        with self._quality[(height, width)]:  # quads are read per frame
            renderer.update_scene(data, camera=camera, scene_option=self._option)
            self._add_markers(renderer.scene, markers)
            with _KeepCurrentContext():
                return renderer.render()  # makes its context current first

    @staticmethod
    def _add_markers(scene, markers) -> None:
        if markers:
            for marker in markers[: scene.maxgeom - scene.ngeom]:
                mujoco.mjv_initGeom(
                    scene.geoms[scene.ngeom],
                    mujoco.mjtGeom.mjGEOM_CYLINDER,
                    np.array([marker.radius, MARKER_HALF_HEIGHT, 0.0]),
                    np.asarray(marker.position, np.float64),
                    _IDENTITY,
                    np.asarray(marker.rgba, np.float32),
                )
                scene.ngeom += 1

    def close(self) -> None:
        for renderer in self._renderers.values():
            try:
                # MjrContext.free deletes GL objects in the *current* context:
                # make this renderer's context current first, or it would
                # delete another live renderer's framebuffers (garbage frames).
                gl_context = getattr(renderer, "_gl_context", None)
                with _KeepCurrentContext():
                    if gl_context is not None:
                        gl_context.make_current()
                    renderer.close()
            except Exception:  # the context may already be gone at interpreter exit
                pass
        self._renderers.clear()
        self._quality.clear()

    def __del__(self):
        self.close()
