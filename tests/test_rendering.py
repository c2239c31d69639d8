"""`envs.rendering.Cameras`: small frames drawn with coarser tessellation
look like the model's own, and the model's settings are left as they were."""

import ctypes
import os

import mujoco
import numpy as np
import pytest

import envs
from fast_cover import cover
from envs.rendering import SMALL_FRAME, SMALL_FRAME_TESSELLATION, Cameras

#: Bounds on how a small frame drawn with `SMALL_FRAME_TESSELLATION` may
#: differ from the same frame drawn with the model's tessellation, over the
#: states below: mean absolute difference per channel (0-255), and the
#: shares of pixels whose largest channel difference exceeds 8 and 32 (the
#: few silhouette pixels of round shapes).
MAX_MEAN_DIFFERENCE = 0.5
MAX_SHARE_ABOVE_8 = 0.005
MAX_SHARE_ABOVE_32 = 0.003

CASES = [
    ("mujoban/level5", dict(top_camera=(96, 96), egocentric_camera=(96, 96))),
    ("mujoban/level5-pegs", dict(top_camera=(96, 96), egocentric_camera=None)),
    # The camera estimator's frame (`CameraEstimator.env_overrides`).
    ("mujoban/level4-pegs", dict(top_camera=(199, 199), egocentric_camera=None, multisamples=0)),
    ("mujoxo/mixture", dict(front_camera=(84, 84))),
    ("mujogo/7x7", dict(front_camera=(84, 84))),
]


def _scene(geom: str, offscreen: int = 64, quality: str = ""):
    """A model of one ``geom`` under a directional light, a camera "c"
    looking down at it, and its data after ``mj_forward``."""
    xml = f"""<mujoco><visual>{quality}<global offwidth="{offscreen}" offheight="{offscreen}"/>
      </visual><worldbody><light directional="true" dir="0 0 -1"/>{geom}
      <camera name="c" pos="0 0 1.6" xyaxes="1 0 0 0 1 0"/></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _assert_current(renderer) -> None:
    """With EGL, ``renderer``'s context is the current one (as dm_control
    assumes of its own between its calls)."""
    if os.environ.get("MUJOCO_GL") == "egl":
        from mujoco.egl import egl_ext as EGL

        assert (
            ctypes.cast(EGL.eglGetCurrentContext(), ctypes.c_void_p).value
            == ctypes.cast(renderer._gl_context._context, ctypes.c_void_p).value
        )


@pytest.mark.parametrize(
    "name,options",
    cover([pytest.param(*c, id=c[0]) for c in CASES], lambda name, _: [name.split("/")[0]]),
)
def test_small_frames_match_the_models_own_tessellation(name, options):
    env = envs.load(name, seed=3, **options)
    try:
        env.reset()
        model, data = env.physics.model.ptr, env.physics.data.ptr
        quality_before = {k: getattr(model.vis.quality, k) for k in SMALL_FRAME_TESSELLATION}
        coarse, full = Cameras(model), Cameras(model, small_frame_tessellation=False)
        rng = np.random.default_rng(0)
        spec = env.action_spec()
        means, above_8, above_32 = [], [], []
        for _ in range(8):
            for _ in range(3):
                env.step(rng.uniform(spec.minimum, spec.maximum))
            for cfg in env.task.camera_configs.values():
                a = coarse.render(data, cfg.camera, cfg.height, cfg.width).astype(int)
                b = full.render(data, cfg.camera, cfg.height, cfg.width).astype(int)
                diff = np.abs(a - b)
                means.append(diff.mean())
                above_8.append((diff.max(-1) > 8).mean())
                above_32.append((diff.max(-1) > 32).mean())
        assert max(means) <= MAX_MEAN_DIFFERENCE
        assert max(above_8) <= MAX_SHARE_ABOVE_8
        assert max(above_32) <= MAX_SHARE_ABOVE_32
        assert {k: getattr(model.vis.quality, k) for k in quality_before} == quality_before
        coarse.close()
        full.close()
    finally:
        env.close()


def test_the_coarse_tessellation_is_really_used_and_large_frames_keep_the_models():
    # A lone sphere filling a small frame: its silhouette differs between
    # 16 and the model's 64 slices; a frame larger than SMALL_FRAME is drawn
    # with the model's 64 whichever the setting.
    model, data = _scene(
        '<geom type="sphere" size="0.5" rgba="1 1 1 1"/>',
        offscreen=300,
        quality='<quality numslices="64" numstacks="32"/>',
    )
    coarse, full = Cameras(model), Cameras(model, small_frame_tessellation=False)
    try:
        small = SMALL_FRAME
        coarse_frame = coarse.render(data, "c", small, small)
        assert (coarse_frame != full.render(data, "c", small, small)).any()
        big = SMALL_FRAME + 1
        np.testing.assert_array_equal(
            coarse.render(data, "c", big, big), full.render(data, "c", big, big)
        )
        assert (model.vis.quality.numslices, model.vis.quality.numstacks) == (64, 32)
    finally:
        coarse.close()
        full.close()


def test_frames_survive_another_renderer_freeing_its_context_after_ours_drew():
    # mujoco.Renderer.close (as dm_control's free at a composer recompile)
    # frees its GL objects in whatever context is current; it must not be
    # ours, or our next frames are garbage. After our frame the context
    # current before it (the other's) is current again, as dm_control assumes.
    geom = '<geom type="box" size="0.3 0.2 0.1" rgba="0.8 0.3 0.1 1"/>'
    model, data = _scene(geom)
    ours = Cameras(model)
    try:
        reference = ours.render(data, "c", 48, 48)
        other = mujoco.Renderer(_scene(geom)[0], 32, 32)
        other.render()
        ours.render(data, "c", 48, 48)  # ours drew last
        _assert_current(other)
        other.close()
        for _ in range(3):
            np.testing.assert_array_equal(ours.render(data, "c", 48, 48), reference)
    finally:
        ours.close()


def test_closing_our_cameras_leaves_another_renderers_context_current_and_working():
    model, data = _scene('<geom type="sphere" size="0.3" rgba="0.2 0.6 0.9 1"/>')
    other = mujoco.Renderer(model, 32, 32)  # another library's, current after creation
    try:
        other.update_scene(data, camera="c")
        before = other.render()
        ours = Cameras(model)
        ours.render(data, "c", 48, 48)
        ours.close()
        _assert_current(other)
        other.update_scene(data, camera="c")
        np.testing.assert_array_equal(other.render(), before)
    finally:
        other.close()
