"""The drawing in 3-D: MuJoCo's offscreen renderer (``mujoco.Renderer``) on the generated
MJCF, the arm posed at every video frame and the ink growing on the panel (docs/toolpath.md,
"The drawing").

The frames are those of the 2-D animation (:func:`tattotronix.report.animation.drawing_clip`:
the same times, joint angles and ink source, the simulated run's when there is one). Each
frame sets the joint angles, runs ``mj_forward`` and renders from a fixed camera chosen
from the model's geometry: from a fixed direction, it looks at the panel and the arm's
geoms (their bounding boxes at a spread of the clip's poses), as close as keeps them all
in the frame between its captions. The render model is the MJCF with a sky, a dark floor
and the ink; the arm, the bench and the panel are the MJCF's (boxes, or the CAD meshes
when the robot stage had them).

The ink is a texture on the panel: a raster of the panel's top face (about one and a half
texels to a pixel where the panel is nearest), into which the tip's path is drawn, with
OpenCV, wherever the tip is below the panel surface (as in the 2-D animation), and which
is uploaded again when it has grown. On a curved surface (:class:`SkinInk`) the limb's
mesh takes the panel's place and the raster is the design's own plane, mapped onto the
mesh by each vertex's point in the design's chart; the ink is drawn where the tip is in
the skin along its normal.

OpenGL: :func:`select_gl` chooses the platform for the whole process before MuJoCo is
imported (``MUJOCO_GL``: honoured when set; otherwise EGL, else OSMesa, whichever first
renders a frame in a child process), and says why neither works.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.io.workers import usable_cores, worker_signals
from tattotronix.plants.base import Workpiece
from tattotronix.plants.mujoco_plant import WORKPIECE, with_workpiece
from tattotronix.plotting import pin_fonts
from tattotronix.report.animation import (
    INK_RGB,
    ClipWriter,
    DrawingClip,
    RenderResult,
    needle_label,
    render_drawing,
)
from tattotronix.robot.loaders import load_mujoco_spec

__all__ = [
    "GL_BACKENDS",
    "SIZE_PX",
    "Camera",
    "DrawingScene",
    "SkinInk",
    "arm_camera",
    "render_drawing_3d",
    "render_drawing_both",
    "select_gl",
]

log = logging.getLogger("tattotronix.animation")

Array = NDArray[np.float64]
#: The offscreen OpenGL platforms tried, in order (``MUJOCO_GL``).
GL_BACKENDS = ("egl", "osmesa")
#: Rendered frame size, px (both multiples of 16 for H.264).
SIZE_PX = (640, 480)
#: The camera's direction: azimuth and elevation, degrees (MuJoCo's free camera: from in
#: front of the panel and to the right of the arm, looking down on the panel's face).
AZIMUTH_DEG = 115.0
ELEVATION_DEG = -45.0
#: Share of the frame's half-width and half-height the scene's box may fill.
FILL = 0.92
#: GIF frames the shared palette is made from (the arm's shading changes as it turns).
GIF_PALETTE_FRAMES = 12
#: The caption strips' heights, shares of the frame's: the title (top), the source (foot).
TITLE_H = 0.075
FOOT_H = 0.045
#: Ink texels to a pixel of the panel where it is nearest the camera (the ink is drawn
#: one texel wide; the 2-D animation draws it one pixel wide).
TEXELS_PER_PX = 1.5
#: The sky: a gradient, top and bottom colour (RGB, 0-1).
SKY_RGB = ((0.93, 0.95, 0.97), (0.75, 0.8, 0.86))
#: The floor: a checker of two dark greys (RGB, 0-1), and its square, m.
FLOOR_RGB = ((0.3, 0.32, 0.35), (0.25, 0.27, 0.3))
FLOOR_SQUARE_M = 0.1
#: Largest ink texture side, texels.
MAX_TEXELS = 2048
#: How much of the pen above the needle's tip the skin's film frames, m.
SKIN_PEN_M = 0.03
#: The skin film's vertical field of view, degrees (the panel's: MuJoCo's 45).
SKIN_FOVY_DEG = 12.0
#: The panel texture's name in the render model.
_INK_TEXTURE = "tattotronix_ink"
_PROBE = ("import mujoco\n"
          "r = mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 16, 16)\n"
          "r.render()\n"
          "r.close()\n")


@functools.cache
def select_gl() -> str:
    """The OpenGL platform MuJoCo renders offscreen with in this process (``MUJOCO_GL``).

    ``MUJOCO_GL`` set in the environment is used as it is. Otherwise, on Linux, when MuJoCo
    is not yet imported here, each of :data:`GL_BACKENDS` (then GLFW, when there is a
    display) is tried in a child process (a 16 x 16 frame of an empty model, about half a
    second) and the first that renders is set in ``os.environ`` for MuJoCo's import. When
    MuJoCo was imported first, or on macOS and Windows, MuJoCo's own choice stands:
    returned as ``""``.

    Raises:
        TattotronixError: no platform renders here; the message gives each one's failure
            and what to install.
    """
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen:
        return chosen
    if "mujoco" in sys.modules or sys.platform != "linux":
        return ""  # MuJoCo's own choice: CGL on macOS, WGL on Windows
    failures = []
    display = bool(os.environ.get("DISPLAY"))
    for backend in GL_BACKENDS + (("glfw",) if display else ()):
        env = {**os.environ, "MUJOCO_GL": backend}
        env.pop("PYOPENGL_PLATFORM", None)
        try:
            r = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                               text=True, timeout=120)
        except subprocess.TimeoutExpired:
            failures.append(f"{backend}: no frame in 120 s")
            continue
        if r.returncode == 0:
            os.environ["MUJOCO_GL"] = backend
            log.debug("offscreen rendering with MUJOCO_GL=%s", backend)
            return backend
        lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
        failures.append(f"{backend}: {lines[-1] if lines else f'exit {r.returncode}'}")
    raise TattotronixError(
        "no OpenGL for MuJoCo's offscreen renderer: tried MUJOCO_GL="
        + "; ".join(failures) + ". Install Mesa's EGL (apt-get install libegl1 "
        "libgl1-mesa-dri) or OSMesa (apt-get install libosmesa6), or set MUJOCO_GL")


@dataclass(frozen=True)
class Camera:
    """A MuJoCo free camera.

    Attributes:
        lookat: the point looked at, m.
        distance: from the camera to ``lookat``, m.
        azimuth, elevation: the direction, degrees.
    """

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float

    def project(self, points_m: Array, fovy_deg: float, size_px: tuple[int, int]) -> Array:
        """(N, 2) where each of ``points_m`` ((N, 3), m) is in a frame of ``size_px``
        (width, height) with vertical field of view ``fovy_deg``: pixel column and row, row
        0 at the top."""
        forward, right, up = _axes(self.azimuth, self.elevation)
        rel = np.asarray(points_m, dtype=np.float64).reshape(-1, 3) - (
            np.asarray(self.lookat) - self.distance * forward)
        depth = rel @ forward
        tv = np.tan(np.radians(fovy_deg) / 2)
        th = tv * size_px[0] / size_px[1]
        x, y = rel @ right / (depth * th), rel @ up / (depth * tv)
        return np.column_stack([(x + 1) / 2 * size_px[0], (1 - y) / 2 * size_px[1]])

    def mjv(self) -> Any:  # Any: mujoco.MjvCamera
        """As a ``mujoco.MjvCamera``."""
        import mujoco

        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        return cam


def _axes(azimuth: float, elevation: float) -> tuple[Array, Array, Array]:
    """The free camera's forward, right and up unit vectors."""
    az, el = np.radians(azimuth), np.radians(elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def arm_camera(points_m: Array, *, fovy_deg: float, aspect: float,
               azimuth: float = AZIMUTH_DEG, elevation: float = ELEVATION_DEG,
               fill: float = FILL, band: tuple[float, float] = (-1.0, 1.0)) -> Camera:
    """The camera that looks from ``azimuth``/``elevation`` at ``points_m``, as close as
    keeps them within ``fill`` of the frame's width and of the band ``band`` of its
    height, and centred in both.

    Args:
        points_m: (N, 3) points the frame must hold (the corners of the geoms' boxes), m.
        fovy_deg: the vertical field of view, degrees (the model's ``vis.global_.fovy``).
        aspect: the frame's width over its height.
        azimuth, elevation: the camera's direction, degrees.
        fill: share of the half-width and of the band's half-height the points may fill.
        band: the rows the points may fill, as -1 (the frame's bottom edge) to 1 (its top
            edge): the frame less its captions.
    """
    corners = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    forward, right, up = _axes(azimuth, elevation)
    tv = np.tan(np.radians(fovy_deg) / 2)
    th = tv * aspect
    lookat = (lo + hi) / 2
    band_mid, band_half = (band[0] + band[1]) / 2, (band[1] - band[0]) / 2
    # first: as close as holds the points about their box's centre (a point c is in the
    # frame when |c.right| <= th (d + c.forward), and so for up)
    rel = corners - lookat
    d = float(np.max(np.maximum(np.abs(rel @ right) / (th * fill),
                                np.abs(rel @ up) / (tv * fill * band_half)) - rel @ forward))
    for _ in range(8):  # then centre their image in the band, and fit it again
        rel = corners - lookat
        depth = d + rel @ forward
        x = rel @ right / (depth * th)  # -1..1 across the frame
        y = rel @ up / (depth * tv)
        lookat = lookat + right * (x.max() + x.min()) / 2 * d * th \
            + up * ((y.max() + y.min()) / 2 - band_mid) * d * tv
        scale = max((x.max() - x.min()) / 2 / fill, (y.max() - y.min()) / 2 / (fill * band_half))
        d *= scale
    return Camera(lookat=(float(lookat[0]), float(lookat[1]), float(lookat[2])),
                  distance=float(d), azimuth=azimuth, elevation=elevation)


def _geom_boxes(model: Any, data: Any, geoms: NDArray[np.intp]) -> Array:
    """(G * 8, 3) the corners of the geoms' bounding boxes (``geom_aabb``, in each geom's
    frame) at ``data``'s pose, world frame, m."""
    aabb = model.geom_aabb[geoms]  # (G, 6): centre, half-sizes
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                     dtype=np.float64)
    local = aabb[:, None, :3] + aabb[:, None, 3:] * signs[None]  # (G, 8, 3)
    rot = data.geom_xmat[geoms].reshape(-1, 3, 3)
    world = np.einsum("gij,gkj->gki", rot, local) + data.geom_xpos[geoms][:, None, :]
    return world.reshape(-1, 3)


@dataclass(frozen=True)
class SkinInk:
    """The ink's canvas on a curved surface: the limb in the panel's place, and the
    design's plane as the texture (about its placement point, mm).

    Attributes:
        limb: the limb's mesh (arm frame, m).
        vertex_uv_mm: (V, 2) each vertex's point in the design's chart (NaN where the
            chart does not reach it).
        tip_uvz_mm: (S, 3) each tip sample of the clip (``clip.tip_t``) in the chart:
            design point and height over the skin along its normal (negative: in it).
        box_mm: ``(u0, v0, u1, v1)`` the raster's extent in the design plane (the design
            and a margin of bare skin around it).
        res_mm: the raster's finest texel, mm: coarser where the camera sees fewer than
            :data:`TEXELS_PER_PX` of them to a pixel at the ink (the ink is drawn one texel
            wide), or where the box would pass :data:`MAX_TEXELS`.
    """

    limb: Workpiece
    vertex_uv_mm: Array
    tip_uvz_mm: Array
    box_mm: tuple[float, float, float, float]
    res_mm: float


@dataclass(frozen=True)
class _Canvas:
    """Where the ink is drawn: the texture's size and bare colour, each tip sample's texel
    (4-bit fixed point) and whether it is in the work, the geom the camera frames, and
    how the foot caption names the surface."""

    size: tuple[int, int]  # texels (width, height)
    base: NDArray[np.uint8]
    px: NDArray[np.int32]
    below: NDArray[np.bool_]
    depth: Array  # (S,) height over the surface at each tip sample (m or mm: sign only)
    surface: str


def _panel_canvas(spec: Any, plain: Any, camera: Camera, size_px: tuple[int, int],
                  clip: DrawingClip) -> _Canvas:
    """The panel's top face as the canvas: TEXELS_PER_PX texels to a pixel where the panel
    is nearest; the panel's colour goes into the texture, the geom's is white."""

    panel = spec.geom("panel")
    half = np.asarray(panel.size, dtype=np.float64)  # box half-sizes, m
    centre = np.asarray(panel.pos, dtype=np.float64)
    lo, span = centre[:2] - half[:2], 2 * half[:2]
    top = centre[2] + half[2]
    corners = np.array([[x, y, top] for y in (lo[1] + span[1], lo[1])
                        for x in (lo[0], lo[0] + span[0])])
    px = camera.project(corners, float(plain.vis.global_.fovy), size_px)
    along_x = np.linalg.norm(px[[1, 3]] - px[[0, 2]], axis=1).max()
    along_y = np.linalg.norm(px[[2, 3]] - px[[0, 1]], axis=1).max()
    tw, th = (int(np.clip(round(TEXELS_PER_PX * e), 64, MAX_TEXELS))
              for e in (along_x, along_y))
    base = np.clip(np.asarray(panel.rgba[:3]) * 255, 0, 255).astype(np.uint8)
    # a 2-D texture covers each face of a box once: row 0 along the face's +y edge,
    # column 0 along its -x edge (an image of the panel seen from above)
    _ink_material(spec, tw, th, base)
    panel.material = _INK_TEXTURE
    panel.rgba = [1.0, 1.0, 1.0, 1.0]
    col = (clip.tip_m[:, 0] - lo[0]) / span[0] * tw
    row = (lo[1] + span[1] - clip.tip_m[:, 1]) / span[1] * th
    depth = clip.tip_m[:, 2] - clip.panel_origin_m[2]
    return _Canvas((tw, th), base, np.rint(np.column_stack([col, row]) * 16).astype(np.int32),
                   depth < 0.0, depth, "the panel surface")


def _skin_canvas(spec: Any, skin: SkinInk, plain: Any, camera: Camera,
                 size_px: tuple[int, int], clip: DrawingClip) -> _Canvas:
    """The design's plane as the canvas, mapped onto the limb's mesh: each face whose
    three vertices lie in the raster takes their chart points as texture coordinates;
    every other face takes one bare texel of the margin (a face across the cylinder's
    seam would otherwise stretch the whole design over the back of the limb)."""

    u0, v0, u1, v1 = skin.box_mm
    if not (u1 > u0 and v1 > v0 and skin.res_mm > 0):
        raise TattotronixError(f"the skin's ink raster {skin.box_mm} at {skin.res_mm} mm "
                               "is empty")
    # pixels to a mm where the ink is (the middle of the tips in the skin), either way
    tip = np.asarray(skin.tip_uvz_mm, dtype=np.float64)
    inside = tip[:, 2] < 0.0
    at = np.mean(clip.tip_m[inside] if inside.any() else clip.tip_m, axis=0)
    px = camera.project(np.vstack([at, at + [1e-3, 0, 0], at + [0, 1e-3, 0]]),
                        float(plain.vis.global_.fovy), size_px)
    px_per_mm = float(np.linalg.norm(px[1:] - px[0], axis=1).max())
    res = max(float(skin.res_mm), 1.0 / (TEXELS_PER_PX * max(px_per_mm, 1e-9)),
              (u1 - u0) / MAX_TEXELS, (v1 - v0) / MAX_TEXELS)
    tw, th = int(math.ceil((u1 - u0) / res)), int(math.ceil((v1 - v0) / res))
    base = np.clip(np.asarray(skin.limb.rgba[:3]) * 255, 0, 255).astype(np.uint8)
    _ink_material(spec, tw, th, base)
    geom = spec.geom(WORKPIECE)
    geom.material = _INK_TEXTURE
    geom.rgba = [1.0, 1.0, 1.0, 1.0]
    uv = np.asarray(skin.vertex_uv_mm, dtype=np.float64)
    inside = (np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= u0) & (uv[:, 0] <= u1)
              & (uv[:, 1] >= v0) & (uv[:, 1] <= v1))
    st = np.column_stack([(np.nan_to_num(uv[:, 0]) - u0) / (u1 - u0),
                          (v1 - np.nan_to_num(uv[:, 1])) / (v1 - v0)])  # t: rows down
    bare = len(st)  # one more coordinate: the margin's first texel
    faces = np.asarray(skin.limb.faces, dtype=np.int64)
    face_st = np.where(inside[faces].all(axis=1)[:, None], faces, bare)
    mesh = spec.mesh(WORKPIECE)
    mesh.usertexcoord = np.vstack([st, [[0.5 / tw, 0.5 / th]]]).ravel().tolist()
    mesh.userfacetexcoord = face_st.ravel().tolist()
    col = (tip[:, 0] - u0) / res
    row = (v1 - tip[:, 1]) / res
    return _Canvas((tw, th), base, np.rint(np.column_stack([col, row]) * 16).astype(np.int32),
                   tip[:, 2] < 0.0, tip[:, 2], "the skin")


def _ink_material(spec: Any, tw: int, th: int, base: NDArray[np.uint8]) -> None:
    """The ink texture (bare, ``base`` colour) and its material."""
    import mujoco

    tex = spec.add_texture(name=_INK_TEXTURE, type=mujoco.mjtTexture.mjTEXTURE_2D,
                           width=tw, height=th, nchannel=3)
    tex.data = np.broadcast_to(base, (th, tw, 3)).tobytes()
    mat = spec.add_material(name=_INK_TEXTURE, specular=0.1, shininess=0.1)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = _INK_TEXTURE


class DrawingScene:
    """The render model (the MJCF with the ink texture on the panel, a sky and a dark
    floor), its renderer, the camera and the ink so far; :meth:`render` draws frame ``k``
    of ``clip``.

    Args:
        clip: the sampled drawing.
        mjcf: the generated MJCF (``data/robot/<name>.xml``).
        size_px: frame size (width, height), px.
        antialias: 4x multisampling (off by default: it doubles a frame's cost with Mesa's
            software OpenGL).
        shadows: the key light's shadows (off by default: as costly again, and jagged
            at a shadow map the software renderer affords).
        azimuth, elevation: the camera's direction, degrees.
        skin: a limb in the panel's place, the ink on it (:class:`SkinInk`).

    Raises:
        TattotronixError: the MJCF is missing or unreadable, it lacks a joint of the
            clip or the panel, the skin's tips are not the clip's, or no OpenGL renders
            here.
    """

    def __init__(self, clip: DrawingClip, mjcf: Path, size_px: tuple[int, int] = SIZE_PX, *,
                 antialias: bool = False, shadows: bool = False,
                 azimuth: float = AZIMUTH_DEG, elevation: float = ELEVATION_DEG,
                 skin: SkinInk | None = None):
        select_gl()
        # PyOpenGL says at INFO that it runs without its C accelerator: not news here
        logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)
        import cv2
        import mujoco

        self._mj, self._cv2 = mujoco, cv2
        self.clip = clip
        self.size_px = size_px
        spec = load_mujoco_spec(Path(mjcf))  # missing or corrupt: named, with the stage
        if skin is not None:
            if len(skin.tip_uvz_mm) != len(clip.tip_t):
                raise TattotronixError(f"the skin's ink has {len(skin.tip_uvz_mm)} tip "
                                       f"samples, the clip {len(clip.tip_t)}")
            with_workpiece(spec, skin.limb)
            # a long lens from afar: near, the arm's links swept between it and the skin
            spec.visual.global_.fovy = SKIN_FOVY_DEG
        target = "panel" if skin is None else WORKPIECE
        plain = _compile(spec, mjcf)
        if mujoco.mj_name2id(plain, mujoco.mjtObj.mjOBJ_GEOM, target) < 0:
            raise TattotronixError(f"{mjcf} has no geom '{target}': re-run the 'robot' stage")
        self._qadr = _qpos_addresses(plain, clip.joints, mjcf)
        self.camera = (_frame_camera(plain, clip, self._qadr, size_px, azimuth, elevation,
                                     target) if skin is None
                       else _skin_camera(skin, clip, size_px, azimuth, elevation,
                                         float(plain.vis.global_.fovy)))
        canvas = (_panel_canvas(spec, plain, self.camera, size_px, clip) if skin is None
                  else _skin_canvas(spec, skin, plain, self.camera, size_px, clip))
        tw, th = canvas.size
        base = canvas.base
        spec.add_texture(name="tattotronix_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=64, height=64,
                         rgb1=SKY_RGB[0], rgb2=SKY_RGB[1])
        _floor(spec)
        m = _compile(spec, mjcf)
        m.vis.quality.shadowsize = 1024 if shadows else 0
        m.vis.quality.offsamples = 4 if antialias else 0
        self.model, self.data = m, mujoco.MjData(m)
        self._tex = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXTURE, _INK_TEXTURE)
        t0 = int(m.tex_adr[self._tex])
        self._texels = m.tex_data[t0:t0 + th * tw * 3].reshape(th, tw, 3)  # a view
        self._base = base.astype(np.uint16)
        self.alpha = np.zeros((th, tw), np.uint8)

        self._cam = self.camera.mjv()
        try:
            self.renderer = mujoco.Renderer(m, height=size_px[1], width=size_px[0])
        except Exception as exc:
            gl = os.environ.get("MUJOCO_GL", "")
            raise TattotronixError(
                f"MuJoCo's offscreen renderer cannot start (MUJOCO_GL={gl or 'unset'}): "
                f"{exc}. Set MUJOCO_GL=egl or osmesa before anything imports mujoco "
                "(tattotronix.report.render3d.select_gl does it)") from None
        self._ctx = getattr(self.renderer, "_mjr_context", None)
        if self._ctx is None:  # mujoco.Renderer keeps its rendering context there
            raise TattotronixError(
                f"mujoco {mujoco.__version__}: its Renderer has no rendering context to "
                "upload the ink texture to (report this; pin the mujoco of pyproject.toml)")
        #: what the scene shows (geom groups, ...): MuJoCo's defaults
        self.option = mujoco.MjvOption()
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows

        # the ink's source in texels (4-bit fixed point), and where it is below the surface
        self.below, self._px, self._depth = canvas.below, canvas.px, canvas.depth
        self._done = 0  # tip samples already inked
        self._stale = False  # the texture has ink the renderer has not
        self._font = _font(size_px)
        source = "the simulated run" if "simulated" in clip.source else "the planned trajectory"
        self._foot = (f"rendered by MuJoCo (offscreen) from {source}; ink where the tip was "
                      f"below {canvas.surface}; time x{clip.compression:.1f}")

    def pose(self, k: int) -> None:
        """Put the arm where it is at frame ``k`` (``mj_forward``)."""
        self.data.qpos[self._qadr] = self.clip.q[k]
        self._mj.mj_forward(self.model, self.data)

    def ink_until(self, t: float) -> None:
        """Draw the ink up to time ``t`` into the texture (uploaded at the next render)."""
        clip, cv2 = self.clip, self._cv2
        stop = int(np.searchsorted(clip.tip_t, t, side="right"))
        if stop > self._done:
            idx = np.arange(max(self._done, 1), stop)
            keep = self.below[idx - 1] & self.below[idx]
            if keep.any():
                seg = np.stack([self._px[idx[keep] - 1], self._px[idx[keep]]], axis=1)
                cv2.polylines(self.alpha, list(seg), False, 255, 1, cv2.LINE_AA, 4)
                # blend only where the new ink is (the ink only grows)
                h, w = self.alpha.shape
                lo = np.clip(seg.reshape(-1, 2).min(axis=0) // 16 - 2, 0, None)
                hi = seg.reshape(-1, 2).max(axis=0) // 16 + 3
                cs = slice(int(lo[0]), int(min(hi[0], w)))
                rs = slice(int(lo[1]), int(min(hi[1], h)))
                a = self.alpha[rs, cs, None].astype(np.uint16)
                ink = np.asarray(INK_RGB, np.uint16)
                self._texels[rs, cs] = (self._base * (255 - a) + ink * a) // 255
                self._stale = True
            self._done = stop

    def render(self, k: int, *, captions: bool = True) -> NDArray[np.uint8]:
        """Frame ``k`` as an (H, W, 3) uint8 RGB array. Frames are drawn in order: the
        ink of frame ``k`` is all the ink up to its time."""
        mj, clip = self._mj, self.clip
        t = float(clip.t[k])
        self.ink_until(t)
        if self._stale:
            mj.mjr_uploadTexture(self.model, self._ctx, self._tex)
            self._stale = False
        self.pose(k)
        r = self.renderer
        r.update_scene(self.data, self._cam, self.option)
        frame = r.render()
        if captions:
            down = bool(np.interp(t, clip.tip_t, self._depth) < 0.0)
            label, colour = needle_label(down, int(clip.state[k]))
            self._caption(frame, f"{clip.name}:  t = {t:6.1f} s of {clip.duration_s:.1f} s   "
                                 f"{label}", colour)
        return frame

    def _caption(self, frame: NDArray[np.uint8], text: str, colour: str) -> None:
        """The time and needle state in a white strip at the top, and the source in one
        at the foot (Pillow)."""
        from matplotlib.colors import to_rgb
        from PIL import Image, ImageDraw

        h, w = frame.shape[:2]
        big, small = self._font
        for y0, y1, words, fill, font in (
                (0, int(round(TITLE_H * h)), text,
                 tuple(int(round(255 * c)) for c in to_rgb(colour)), big),
                (h - int(round(FOOT_H * h)), h, self._foot, (73, 80, 87), small)):
            strip = Image.new("RGB", (w, y1 - y0), (255, 255, 255))
            ImageDraw.Draw(strip).text((w / 2, (y1 - y0) / 2 + 1), words, fill=fill,
                                       font=font, anchor="mm")
            frame[y0:y1] = np.asarray(strip)

    def close(self) -> None:
        """Free the renderer (its OpenGL context)."""
        self.renderer.close()


def _floor(spec: Any) -> None:
    """A dark checked floor under the bench (the MJCF's is the arm's grey), drawn in
    coarse quads."""
    import mujoco

    ground = next((g for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_PLANE), None)
    if ground is None:
        return
    spec.add_texture(name="tattotronix_floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=64, height=64,
                     rgb1=FLOOR_RGB[0], rgb2=FLOOR_RGB[1])
    mat = spec.add_material(name="tattotronix_floor", texuniform=True,
                            texrepeat=[1 / FLOOR_SQUARE_M / 2] * 2, specular=0.0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "tattotronix_floor"
    ground.material = "tattotronix_floor"
    ground.rgba = [1.0, 1.0, 1.0, 1.0]
    # a plane is drawn as a grid of its third size: the MJCF's 1 cm over 4 m is 160 000
    # quads, two thirds of a frame's cost; a square of the checker each draws the same
    ground.size = [ground.size[0], ground.size[1], FLOOR_SQUARE_M]


def _compile(spec: Any, mjcf: Path) -> Any:
    """``spec.compile()``, a failure named as the MJCF's."""
    try:
        return spec.compile()
    except Exception as exc:
        raise TattotronixError(f"{mjcf}: MuJoCo cannot compile it for rendering ({exc}): "
                               "re-run the 'robot' stage") from None


def _qpos_addresses(model: Any, joints: tuple[str, ...], mjcf: Path) -> NDArray[np.intp]:
    """Where each named joint's angle is in ``qpos``."""
    import mujoco

    adr = []
    for j in joints:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        if jid < 0:
            raise TattotronixError(f"{mjcf} has no joint {j!r}: re-run the 'robot' stage")
        adr.append(int(model.jnt_qposadr[jid]))
    return np.array(adr, dtype=np.intp)


def _frame_camera(model: Any, clip: DrawingClip, qadr: NDArray[np.intp],
                  size_px: tuple[int, int], azimuth: float, elevation: float,
                  target: str = "panel") -> Camera:
    """The camera on the panel (or the geom ``target``) and the arm's geoms at a spread
    of the clip's frames."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    panel = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, target)],
                     dtype=np.intp)
    arm = np.flatnonzero(model.geom_bodyid > 0).astype(np.intp)
    pts = [_geom_boxes(model, data, panel)]
    for k in np.unique(np.linspace(0, len(clip.t) - 1, 24).round().astype(int)):
        data.qpos[qadr] = clip.q[k]
        mujoco.mj_kinematics(model, data)
        pts.append(_geom_boxes(model, data, arm))
    return arm_camera(np.vstack(pts), fovy_deg=float(model.vis.global_.fovy),
                      aspect=size_px[0] / size_px[1], azimuth=azimuth, elevation=elevation,
                      band=(-1.0 + 2 * FOOT_H, 1.0 - 2 * TITLE_H))


def _skin_camera(skin: SkinInk, clip: DrawingClip, size_px: tuple[int, int],
                 azimuth: float, elevation: float, fovy_deg: float) -> Camera:
    """The camera on the design's part of the limb (every vertex the raster's box holds)
    and the lower part of the pen over it (:data:`SKIN_PEN_M` above each tip sample in
    the skin): the design is a few centimetres on a limb the arm dwarfs, so framed as on the
    panel, with the whole arm, it filled a tenth of the frame's width."""
    uv = skin.vertex_uv_mm
    u0, v0, u1, v1 = skin.box_mm
    with np.errstate(invalid="ignore"):
        near = ((uv[:, 0] >= u0) & (uv[:, 0] <= u1) & (uv[:, 1] >= v0) & (uv[:, 1] <= v1))
    pts = [skin.limb.vertices_m[near]]
    inside = skin.tip_uvz_mm[:, 2] < 0  # the tip in the skin: marking
    marking = clip.tip_m[inside] if np.any(inside) else clip.tip_m
    pts += [marking, marking + np.array([0.0, 0.0, SKIN_PEN_M])]
    return arm_camera(np.vstack(pts), fovy_deg=fovy_deg, aspect=size_px[0] / size_px[1],
                      azimuth=azimuth, elevation=elevation,
                      band=(-1.0 + 2 * FOOT_H, 1.0 - 2 * TITLE_H))


def _font(size_px: tuple[int, int]) -> tuple[Any, Any]:
    """The caption fonts (matplotlib's bold and regular sans), sized to the frame."""
    from matplotlib import font_manager
    from PIL import ImageFont

    pin_fonts()
    bold = font_manager.findfont(font_manager.FontProperties(weight="bold"))
    regular = font_manager.findfont(font_manager.FontProperties())
    w = size_px[0]
    return (ImageFont.truetype(bold, max(8, round(15 * w / 640))),
            ImageFont.truetype(regular, max(7, round(10 * w / 640))))


def render_drawing_3d(clip: DrawingClip, mjcf: Path, gif: Path | None = None,
                      mp4: Path | None = None, *, size_px: tuple[int, int] = SIZE_PX,
                      gif_width_px: int | None = None, gif_every: int = 2,
                      antialias: bool = False, shadows: bool = False,
                      skin: SkinInk | None = None) -> RenderResult:
    """Render the drawing in 3-D with MuJoCo to a GIF and/or an MP4 (on the panel, or on
    a limb with ``skin``).

    Args:
        clip: the sampled drawing (:func:`tattotronix.report.animation.drawing_clip`).
        mjcf: the generated MJCF.
        gif: the GIF to write (every ``gif_every``-th frame, one shared palette), or None.
        mp4: the MP4 to write (H.264, yuv420p, ``clip.fps``), or None. Skipped, with a
            log line, when ``imageio-ffmpeg`` is not installed.
        size_px: frame size, px; both multiples of 16.
        gif_width_px: GIF width, px (default: the frame's).
        gif_every: GIF frame stride.
        antialias, shadows: as :class:`DrawingScene`.
        skin: the limb in the panel's place and the ink in the design's chart.

    Returns:
        What was written and what it cost (``timings_s``: setup, frames, gif; ``gl``,
        the OpenGL platform, is logged).

    Raises:
        TattotronixError: as :class:`DrawingScene`.
    """
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    scene = DrawingScene(clip, mjcf, size_px, antialias=antialias, shadows=shadows,
                         skin=skin)
    try:
        n = len(clip.t)
        sink = ClipWriter(gif, mp4, fps=clip.fps, size_px=size_px,
                          gif_width_px=gif_width_px or size_px[0], gif_every=gif_every,
                          palette_frames=GIF_PALETTE_FRAMES)
        timings["setup"] = time.perf_counter() - t0
        timings["frames"] = sink.add_all(n, scene.render)
        sink.close()
        timings.update(sink.timings_s)
    finally:
        scene.close()
    log.debug("3-D drawing rendered with MUJOCO_GL=%s", os.environ.get("MUJOCO_GL", ""))
    return RenderResult(frames=n, gif=gif, gif_frames=sink.gif_frames, mp4=sink.mp4,
                        wall_s=time.perf_counter() - t0, timings_s=timings)


def render_drawing_both(clip: DrawingClip, mjcf: Path,
                        videos_2d: tuple[Path | None, Path | None],
                        videos_3d: tuple[Path | None, Path | None]
                        ) -> tuple[RenderResult, RenderResult]:
    """The 2-D rendering (:func:`tattotronix.report.animation.render_drawing`) and the 3-D
    one (:func:`render_drawing_3d`), each to its (GIF, MP4): at once when this process may
    use two cores (the 3-D one in a forked process, before any OpenGL context exists, so
    it makes its own), else one after the other. Each writes the same bytes either way.

    Raises:
        TattotronixError: as either rendering.
    """
    if usable_cores() < 2:
        return render_drawing(clip, *videos_2d), render_drawing_3d(clip, mjcf, *videos_3d)
    import multiprocessing

    # a Pool, not a bare Process: leaving the block (a Ctrl-C, an error here) ends the worker
    with multiprocessing.get_context("fork").Pool(1, worker_signals) as pool:
        three_d = pool.apply_async(render_drawing_3d, (clip, mjcf, *videos_3d))
        two_d = render_drawing(clip, *videos_2d)
        return two_d, three_d.get()
