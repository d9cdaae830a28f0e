"""A lean offscreen MuJoCo renderer: one GL context, one scene, a fixed image size.

`mujoco.Renderer` converts every segmentation frame into (object id, type) pairs in
Python, which costs more than the render itself at our sizes. This renderer keeps
the raw id-colour image and lets callers decode only the geoms they need.
"""

from __future__ import annotations

import functools
import os
from typing import NamedTuple

import mujoco
import numpy as np
from OpenGL import GL

from avsim.errors import RenderError
from avsim.sensors.culling import FULL_VIEW_NDC, cullable, has_reflective_material, outside_view, window_of_region
from avsim.termination import raise_if_interrupted

_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
# GL 4.6 (and GL_EXT_texture_filter_anisotropic): a texture's sampling ratio, and the most the GL allows.
_TEXTURE_MAX_ANISOTROPY = 0x84FE
_MAX_TEXTURE_MAX_ANISOTROPY = 0x84FF


def context_with_framebuffer(model: mujoco.MjModel, width_px: int, height_px: int) -> mujoco.MjrContext:
    """A MuJoCo rendering context whose offscreen framebuffer is exactly width_px x height_px.

    MuJoCo sizes the framebuffer from the model's `visual/global` offwidth and offheight, which a
    scene sets for its largest renderer (the supersampled segmentation). llvmpipe's cost per frame
    grows with the framebuffer, not only with the part drawn: a 640x480 frame in a 1280x960
    framebuffer took 6-10 % longer, with the same pixels. So each renderer gets its own size, and
    the model's settings are put back.
    """
    settings = model.vis.global_
    shared_size = settings.offwidth, settings.offheight
    settings.offwidth, settings.offheight = width_px, height_px
    try:
        return mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
    finally:
        settings.offwidth, settings.offheight = shared_size


def _cannot_render(exc: Exception) -> RenderError:
    """The one-line error for a GL context that did not start; a Ctrl-C inside EGL's ctypes calls is
    re-raised as what it is, not reported as a broken EGL."""
    raise_if_interrupted(exc)
    backend = os.environ.get("MUJOCO_GL", "egl")
    detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    device = os.environ.get("MUJOCO_EGL_DEVICE_ID")
    if backend == "egl" and device is not None:  # a device the machine lacks, not a missing EGL
        fix = f"unset MUJOCO_EGL_DEVICE_ID (={device}) or set it to a device this machine has"
    else:
        fix = ("install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri) or run with MUJOCO_GL=osmesa "
               "(needs libosmesa6)")
    return RenderError(f"cannot start offscreen rendering with MUJOCO_GL={backend} ({detail}); {fix}")


def check_offscreen_rendering() -> None:
    """Start a 1x1 GL context and free it: a one-line RenderError where this process cannot render
    offscreen (no EGL), so that the batch commands and the data generator refuse before their work,
    not run by run."""
    try:
        context = mujoco.GLContext(1, 1)
        context.make_current()
        context.free()
    except Exception as exc:  # the GL backends raise several unrelated types
        raise _cannot_render(exc) from None


class GLInfo(NamedTuple):
    """The GL a process renders with: its GL_RENDERER (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"), its GL_VERSION
    (e.g. "4.5 (Compatibility Profile) Mesa 22.3.6"), and the most anisotropy it filters a texture at."""

    renderer: str
    version: str
    max_anisotropy: float


@functools.cache
def _gl_info() -> GLInfo | None:
    """This process's GL, read once a process from a 1x1 context that is freed again; None where no context
    starts here (`check_offscreen_rendering` says so where the runs render on this machine; a Ray cluster's
    runs render on its own)."""
    try:
        context = mujoco.GLContext(1, 1)
        context.make_current()
    except Exception:  # the GL backends raise several unrelated types
        return None
    try:
        return _current_gl_info()
    finally:
        context.free()


def _current_gl_info() -> GLInfo:
    """The current GL context's renderer, version and anisotropy limit."""
    def text(name: int) -> str:
        return (GL.glGetString(name) or b"?").decode()

    return GLInfo(text(GL.GL_RENDERER), text(GL.GL_VERSION), float(GL.glGetFloatv(_MAX_TEXTURE_MAX_ANISOTROPY)))


def gl_description() -> str | None:
    """"llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Compatibility Profile) Mesa 22.3.6": the GL that draws
    this process's frames, for a batch's manifest and a report (None where no context starts here). Frames
    are a function of the state on one GL; another GL, or another Mesa, may draw some pixels differently, and
    under `camera.texture_anisotropy` filters textures in its own way (docs/realism_filtering.md)."""
    info = _gl_info()
    return None if info is None else f"{info.renderer}, OpenGL {info.version}"


def _too_much_anisotropy(ratio: int, info: GLInfo) -> RenderError:
    return RenderError(f"camera.texture_anisotropy = {ratio} but this GL filters at most {info.max_anisotropy:g}:1 "
                       f"({info.renderer}); set camera.texture_anisotropy to 1")


def check_texture_anisotropy(ratio: int) -> None:
    """A one-line RenderError where this machine's GL cannot filter textures at `ratio`:1
    (`camera.texture_anisotropy`), so that a batch refuses before its first run, not at each run's renderer."""
    info = _gl_info() if ratio > 1 else None
    if info is not None and info.max_anisotropy < ratio:
        raise _too_much_anisotropy(ratio, info)


class OffscreenRenderer:
    """Renders a model's fixed cameras to (H, W, 3) uint8 arrays, row 0 at the top.

    With `segmentation=True` each pixel's colour encodes (scene geom index + 1) as
    R + 256 G + 65536 B, and 0 for the background.
    """

    def __init__(self, model: mujoco.MjModel, width_px: int, height_px: int, segmentation: bool,
                 fog: bool = False, max_geom: int = 10000, cull: bool = True, texture_anisotropy: int = 1) -> None:
        """cull: leave the geoms the camera cannot see out of each render, where that cannot change
        a pixel (`avsim.sensors.culling`); False draws every geom, as a check of it.
        texture_anisotropy: 1 keeps MuJoCo's trilinear mip-mapping; N > 1 filters every 2-D texture
        anisotropically, up to N samples along a pixel's footprint (`camera.texture_anisotropy`), as the GL
        implements it: llvmpipe (Mesa 22.3) weights every texel of the footprint's ellipse at any N > 1."""
        try:
            self._gl = mujoco.GLContext(width_px, height_px)
            self._gl.make_current()
            self._con = context_with_framebuffer(model, width_px, height_px)
        except Exception as exc:  # the GL backends raise several unrelated types
            raise _cannot_render(exc) from None
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        if texture_anisotropy > 1:
            self._filter_textures_anisotropically(texture_anisotropy)
        self._model = model
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        if segmentation:
            self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
            self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
        # Fog would blend id colours, so it is only ever drawn in colour renders.
        self._scene.flags[mujoco.mjtRndFlag.mjRND_FOG] = int(fog and not segmentation)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._perturb = mujoco.MjvPerturb()
        self._rect = mujoco.MjrRect(0, 0, width_px, height_px)
        self.cull = cull
        # A region read back alone is rasterised alone (`_rasterise_only`); False draws the whole
        # frame, as a check of it.
        self.rasterise_region_only = True
        self._stencil_region: tuple[int, int, int, int] | None = None
        self._buffer = np.empty((height_px, width_px, 3), dtype=np.uint8)

    def _filter_textures_anisotropically(self, ratio: int) -> None:
        """Set every 2-D texture MuJoCo uploaded to sample up to `ratio` texels along a pixel's footprint.

        MuJoCo uploads its textures once, with trilinear mip-maps; a texture's filter is its own GL
        state, read at every draw, so setting it here changes every later frame and nothing else.
        """
        info = _current_gl_info()
        if info.max_anisotropy < ratio:
            self.close()
            raise _too_much_anisotropy(ratio, info)
        for i in range(self._con.ntexture):
            if self._con.textureType[i] == mujoco.mjtTexture.mjTEXTURE_2D:
                GL.glBindTexture(GL.GL_TEXTURE_2D, int(self._con.texture[i]))
                GL.glTexParameterf(GL.GL_TEXTURE_2D, _TEXTURE_MAX_ANISOTROPY, float(ratio))
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    def render(self, data: mujoco.MjData, camera_id: int, option: mujoco.MjvOption,
               region: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Render, and read back the whole image or only `region` = (x0, y0, x1, y1).

        region is in image pixels (row 0 at the top), end-exclusive. Reading back is the
        larger part of a frame's cost on a software rasteriser, so callers that need a
        small part of the image ask only for it. The geoms outside the region's view are
        then left out of the render too (where culling is exact), and only the region's
        pixels are shaded (`_rasterise_only`); neither changes any of the region's pixels.
        Returns a view of an internal buffer, valid until the next call, of shape
        (y1 - y0, x1 - x0, 3).
        """
        self._gl.make_current()
        self._camera.fixedcamid = camera_id
        self._update_scene(data, camera_id, option, region)
        masked = region is not None and self._rasterise_only(region)
        try:
            mujoco.mjr_render(self._rect, self._scene, self._con)
        finally:
            if masked:  # a later whole frame is drawn whole
                GL.glDisable(GL.GL_STENCIL_TEST)
        if region is None:
            mujoco.mjr_readPixels(self._buffer, None, self._rect, self._con)
            return self._buffer[::-1]  # OpenGL rows run bottom-up
        x0, y0, x1, y1 = region
        height = self._rect.height
        out = self._buffer.reshape(-1)[: (y1 - y0) * (x1 - x0) * 3].reshape(y1 - y0, x1 - x0, 3)
        mujoco.mjr_readPixels(out, None, mujoco.MjrRect(x0, height - y1, x1 - x0, y1 - y0), self._con)
        return out[::-1]

    def _rasterise_only(self, region: tuple[int, int, int, int]) -> bool:
        """Confine the next render's fragments to `region` (x0, y0, x1, y1) with the stencil test;
        True if it did (the caller turns the test off after the render).

        llvmpipe shades every covered pixel of the framebuffer, read back or not. A smaller
        framebuffer, or a shifted viewport, would rasterise only the region but moves pixels: the
        offset enters the GL's float arithmetic. The stencil test changes no arithmetic: the frame
        is set up exactly as before, and fragments outside the region are dropped before shading.
        The region's pixels are the same, bit for bit (`tests/sensors/test_gl.py`). MuJoCo leaves
        the stencil buffer alone except to draw reflections, so with a reflective material in the
        model the whole frame is drawn. The mask is written once per region: `mjr_render` clears
        colour and depth, never the stencil.
        """
        if not self.rasterise_region_only or has_reflective_material(self._model):
            return False
        x0, y0, x1, y1 = region = tuple(region)
        if region == (0, 0, self._rect.width, self._rect.height):
            return False
        if region != self._stencil_region:
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)  # the mask goes into our framebuffer
            GL.glStencilMask(0xFF)
            GL.glClearStencil(0)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
            GL.glScissor(x0, self._rect.height - y1, x1 - x0, y1 - y0)  # GL rows run bottom-up
            GL.glEnable(GL.GL_SCISSOR_TEST)
            GL.glClearStencil(1)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
            GL.glDisable(GL.GL_SCISSOR_TEST)
            GL.glStencilFunc(GL.GL_EQUAL, 1, 0xFF)
            GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
            self._stencil_region = region
        GL.glEnable(GL.GL_STENCIL_TEST)
        return True

    def _update_scene(self, data: mujoco.MjData, camera_id: int, option: mujoco.MjvOption,
                      region: tuple[int, int, int, int] | None) -> None:
        """Fill the scene from `data`, without the geoms `camera_id` cannot see where culling is exact:
        in the whole image, or in `region` (x0, y0, x1, y1) when only it is read back.

        MuJoCo leaves a geom whose colour has alpha 0 out of the scene, so the hidden geoms' alphas
        are zeroed for the update and put back at once: the model is as it was after the call.
        """
        model = self._model
        hidden = None
        if self.cull and cullable(model, camera_id):
            width, height = self._rect.width, self._rect.height
            window = FULL_VIEW_NDC if region is None else window_of_region(region, width, height)
            hidden = np.flatnonzero(outside_view(model, data, camera_id, width / height, window))
        if hidden is None or hidden.size == 0:
            mujoco.mjv_updateScene(model, data, option, self._perturb, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene)
            return
        alphas = model.geom_rgba[hidden, 3].copy()
        model.geom_rgba[hidden, 3] = 0.0
        try:
            mujoco.mjv_updateScene(model, data, option, self._perturb, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene)
        finally:
            model.geom_rgba[hidden, 3] = alphas

    @property
    def scene_geom_count(self) -> int:
        """Geoms in the last rendered scene (what a render has to draw)."""
        return self._scene.ngeom

    def segment_ids_of(self, geom_ids: list[int]) -> list[int]:
        """Segment colour value (index + 1) of each model geom in the last rendered scene; 0 if absent."""
        wanted = {gid: 0 for gid in geom_ids}
        for i in range(self._scene.ngeom):
            geom = self._scene.geoms[i]
            if geom.objtype == _GEOM and geom.objid in wanted:
                wanted[geom.objid] = geom.segid + 1
        return [wanted[gid] for gid in geom_ids]

    def geom_id_lookup(self) -> np.ndarray:
        """Table mapping a segment colour value to the model geom id (-1: background or not a geom)."""
        table = np.full(self._scene.ngeom + 1, -1, dtype=np.int32)
        for i in range(self._scene.ngeom):
            geom = self._scene.geoms[i]
            if geom.objtype == _GEOM:
                table[geom.segid + 1] = geom.objid
        return table

    def close(self) -> None:
        # GL object names belong to a context: freeing ours while another renderer's context is
        # current would delete *its* textures and buffers (seen with many cars in one process).
        """Free the renderer's GL context and MuJoCo rendering context."""
        self._gl.make_current()
        self._con.free()
        self._gl.free()
