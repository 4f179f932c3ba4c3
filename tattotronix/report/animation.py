"""The drawing animation (docs/toolpath.md, "The drawing"; the original's: docs/original.md,
"The drawing animation").

Left, the arm in elevation (x-z; every frame origin by Pinocchio FK, the panel and the
bench); right, the panel face-on with the ink so far and the current tip; a title with the
time and the needle state; a time bar with the marking stretches. Time is compressed (the
whole drawing in ``video_s`` seconds, at most real time).

The ink is drawn from a tip path, in panel millimetres, wherever the tip is below the
panel surface: the *simulated* tip when the run log is given (what the arm did), else
the planned one. The frame says which.

Speed: the figure is drawn once; each frame restores the static background and redraws
only the moving artists (blitting on Agg); the ink is a raster at the screen's
resolution that grows with OpenCV. Writes a GIF (Pillow, one shared palette) and, when
``imageio-ffmpeg`` is importable, an H.264 MP4 (yuv420p).
"""

from __future__ import annotations

import importlib.util
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import TattotronixError
from tattotronix.path.kinds import APPROACH, MARK, TRAVEL
from tattotronix.report.figures import arm_poses
from tattotronix.robot.description import RobotDescription

__all__ = [
    "INK_RGB",
    "ClipWriter",
    "DrawingClip",
    "RenderResult",
    "drawing_clip",
    "mp4_available",
    "needle_label",
    "render_drawing",
]

log = logging.getLogger("tattotronix.animation")

Array = NDArray[np.float64]
MM = 1000.0
#: Video length for the whole drawing, s (the original: 557 s in 24 s).
VIDEO_S = 24.0
#: MP4 frame rate, frames/s (the GIF takes every other frame).
FPS = 25.0
#: Rendered frame size, px (MP4; both multiples of 16 for H.264).
SIZE_PX = (1024, 576)
#: GIF width, px.
GIF_WIDTH_PX = 760
#: (needle below the surface, trajectory state) -> title words and colour
_LABEL = {(True, MARK): ("MARKING, needle down", "#c92a2a"),
          (True, APPROACH): ("approach, needle down", "#e8590c"),
          (True, TRAVEL): ("needle down, lifting", "#e8590c"),
          (False, MARK): ("needle up, plunging", "#e8590c"),
          (False, APPROACH): ("approach, needle up", "#e8590c"),
          (False, TRAVEL): ("travel, needle up", "#1971c2")}
#: the ink's colour, RGB (dark blue-black)
INK_RGB = (22, 27, 72)


def needle_label(down: bool, state: int) -> tuple[str, str]:
    """The words and colour (matplotlib) of a frame's needle state: ``down``, the tip
    below the panel surface; ``state``, the trajectory's segment kind."""
    return _LABEL.get((down, state), ("", "black"))


def mp4_available() -> bool:
    """Whether an MP4 can be written here (imageio with its ffmpeg binary)."""
    return all(importlib.util.find_spec(m) is not None for m in ("imageio", "imageio_ffmpeg"))


@dataclass(frozen=True)
class DrawingClip:
    """Everything an animation frame shows, precomputed.

    Attributes:
        name: the artwork.
        t: (F,) drawing time at each video frame, s.
        joints: the joint names, in the order of ``q``'s columns.
        q: (F, n) the joint angles at each frame, rad.
        arm_m: (F, P, 3) the chain's frame origins (base to tip) at each frame, m.
        state: (F,) needle state at each frame: 0 travel, 1 marking, 2 approach.
        tip_t: (S,) times of the tip samples the ink is drawn from, s.
        tip_m: (S, 3) the tip samples, arm frame, m.
        duration_s: the drawing's length, s.
        panel_centre_m, panel_size_m: the panel box, m.
        panel_origin_m: the toolpath's panel origin (surface), m.
        plan_uv_mm: (M, 2) the planned ink points, panel mm (drawn faintly), or empty.
        source: what the ink comes from (shown on the frame).
        video_s: the video's length, s.
        fps: frames per second.
    """

    name: str
    t: Array
    joints: tuple[str, ...]
    q: Array
    arm_m: Array
    state: NDArray[np.int8]
    tip_t: Array
    tip_m: Array
    duration_s: float
    panel_centre_m: Array
    panel_size_m: Array
    panel_origin_m: Array
    plan_uv_mm: Array
    source: str
    video_s: float
    fps: float

    @property
    def compression(self) -> float:
        """Drawing seconds per video second."""
        return self.duration_s / self.video_s if self.video_s > 0 else 1.0


@dataclass(frozen=True)
class RenderResult:
    """What :func:`render_drawing` wrote.

    Attributes:
        frames: video frames rendered.
        gif: the GIF (None when not asked).
        gif_frames: frames in the GIF.
        mp4: the MP4 (None when not asked or not possible).
        wall_s: wall time, s.
        timings_s: per step (setup, frames, gif, mp4), s.
    """

    frames: int
    gif: Path | None
    gif_frames: int
    mp4: Path | None
    wall_s: float
    timings_s: dict[str, float]


def _interp_rows(t_new: Array, t: Array, a: Array) -> Array:
    return np.column_stack([np.interp(t_new, t, a[:, j]) for j in range(a.shape[1])])


def drawing_clip(desc: RobotDescription, urdf: Path, name: str, t: ArrayLike, q: ArrayLike,
                 kind: ArrayLike, tcp_m: ArrayLike, marked: ArrayLike,
                 panel_origin_m: ArrayLike, *, run_t: ArrayLike | None = None,
                 run_q: ArrayLike | None = None, run_tip_m: ArrayLike | None = None,
                 run_label: str = "the simulated run", video_s: float = VIDEO_S,
                 fps: float = FPS) -> DrawingClip:
    """Sample a drawing at the video's frames.

    With ``run_t``, ``run_q`` and ``run_tip_m`` (a run log) the arm and the ink follow
    the simulated run; otherwise the planned trajectory.

    Args:
        desc: the robot description.
        urdf: the generated URDF (Pinocchio FK of every frame).
        name: the artwork.
        t, q, kind, tcp_m, marked: the stored trajectory (times s, angles rad, point
            kinds, FK tip m, the segment ending at each point is ink).
        panel_origin_m: ``toolpath.panel_origin``, m.
        run_t, run_q, run_tip_m: the run log's sample times (s), angles (rad), tip (m).
        run_label: what the run is (shown on the frame).
        video_s: the whole drawing's video length, s (never slower than real time).
        fps: video frames per second.

    Raises:
        TattotronixError: an empty trajectory, or a partial run log.
    """
    from tattotronix.trajectory import segment_kinds

    tt = np.asarray(t, dtype=np.float64)
    qq = np.asarray(q, dtype=np.float64)
    kk = np.asarray(kind, dtype=np.int8)
    if len(tt) < 2 or qq.shape[0] != len(tt):
        raise TattotronixError("the trajectory has fewer than two points: re-run the "
                               "'trajectory' stage")
    duration = float(tt[-1] - tt[0])
    length = min(video_s, duration) if duration > 0 else 1.0 / fps
    n_frames = max(2, int(round(length * fps)) + 1)
    tf = np.linspace(float(tt[0]), float(tt[-1]), n_frames)
    origin = np.asarray(panel_origin_m, dtype=np.float64)
    runs = [run_t, run_q, run_tip_m]
    if any(r is not None for r in runs) and not all(r is not None for r in runs):
        raise TattotronixError("a run log needs its times, joint angles and tip positions")
    if run_t is not None and run_q is not None and run_tip_m is not None:
        rt = np.asarray(run_t, dtype=np.float64)
        q_frames = _interp_rows(tf, rt, np.asarray(run_q, dtype=np.float64))
        tip_t, tip = rt, np.asarray(run_tip_m, dtype=np.float64)
        source = f"{run_label}: ink where the simulated tip was below the panel surface"
    else:
        q_frames = _interp_rows(tf, tt, qq)
        tip_t, tip = tt, np.asarray(tcp_m, dtype=np.float64)
        source = "the planned trajectory: ink where the planned tip is below the panel surface"
    poses = arm_poses(desc, urdf, q_frames)
    chain = poses.chain()
    seg = segment_kinds(kk)
    i = np.clip(np.searchsorted(tt, tf, side="right") - 1, 0, len(seg) - 1)
    plan = np.asarray(tcp_m, dtype=np.float64)[np.asarray(marked, dtype=bool)]
    return DrawingClip(
        name=name, t=tf, joints=tuple(desc.joint_names), q=q_frames,
        arm_m=poses.origins_m[:, chain], state=seg[i].astype(np.int8),
        tip_t=tip_t, tip_m=tip, duration_s=duration,
        panel_centre_m=np.asarray(desc.panel_centre, dtype=np.float64),
        panel_size_m=np.asarray(desc.panel_size, dtype=np.float64), panel_origin_m=origin,
        plan_uv_mm=(plan[:, :2] - origin[:2]) * MM, source=source,
        video_s=length, fps=float(fps))


class _Frames:
    """The figure, drawn once; :meth:`render` returns frame ``k`` as an RGB array."""

    def __init__(self, clip: DrawingClip, size_px: tuple[int, int]):
        import cv2
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Rectangle

        self._cv2 = cv2
        self.clip = clip
        # the layout is made for 10.24 in wide; the dpi scales it to the frame size
        dpi = size_px[0] / 10.24
        fig = Figure(figsize=(10.24, 10.24 * size_px[1] / size_px[0]), dpi=dpi)
        canvas = FigureCanvasAgg(fig)  # no pyplot: nothing global, no display needed
        self.fig, self.canvas = fig, canvas
        centre, size = clip.panel_centre_m * MM, clip.panel_size_m * MM
        origin = clip.panel_origin_m * MM
        arm = clip.arm_m * MM

        # --- left: elevation
        ax = fig.add_axes((0.065, 0.26, 0.43, 0.62))
        xlo = min(float(arm[..., 0].min()), centre[0] - size[0] / 2) - 25
        xhi = max(float(arm[..., 0].max()), centre[0] + size[0] / 2) + 25
        zhi = float(arm[..., 2].max()) + 25
        ax.set_xlim(xlo, xhi)
        ax.set_ylim(-20, zhi)
        ax.set_aspect("equal", adjustable="box")
        ax.set_anchor("W")
        ax.axhline(0, color="#495057", lw=1.0)
        ax.add_patch(Rectangle((xlo - 50, -30), xhi - xlo + 100, 30, facecolor="#e9ecef",
                               edgecolor="none", hatch="//", zorder=0))
        ax.add_patch(Rectangle((centre[0] - size[0] / 2, centre[2] - size[2] / 2), size[0],
                               size[2], facecolor="#d9c7a5", edgecolor="#8a7f70", zorder=1))
        ax.set_xlabel("arm x (mm)", fontsize=10, labelpad=2)
        ax.set_ylabel("arm z (mm)", fontsize=10)
        ax.tick_params(labelsize=9)
        ax.grid(alpha=0.3)
        ax.set_title("the arm, elevation (x-z)", fontsize=10)
        (self.arm_line,) = ax.plot([], [], "-o", color="#212529", lw=2.6, ms=4.5,
                                   mfc="white", mec="#212529", animated=True, zorder=3)
        (self.arm_tip,) = ax.plot([], [], "v", ms=8, animated=True, zorder=4)
        self.ax_arm = ax

        # --- right: the panel face-on, panel mm about the panel origin
        ap = fig.add_axes((0.555, 0.26, 0.43, 0.62))
        u0, u1 = centre[0] - size[0] / 2 - origin[0], centre[0] + size[0] / 2 - origin[0]
        v0, v1 = centre[1] - size[1] / 2 - origin[1], centre[1] + size[1] / 2 - origin[1]
        ap.add_patch(Rectangle((u0, v0), u1 - u0, v1 - v0, facecolor="#f8f1e5",
                               edgecolor="#8a7f70", lw=1.2, zorder=0))
        if len(clip.plan_uv_mm):
            ap.plot(clip.plan_uv_mm[:, 0], clip.plan_uv_mm[:, 1], ",", color="#ced4da",
                    zorder=1, rasterized=True)
        ap.set_xlim(u0 - 3, u1 + 3)
        ap.set_ylim(v0 - 3, v1 + 3)
        ap.set_aspect("equal", adjustable="box")
        ap.set_anchor("E")
        ap.set_xlabel("panel u (mm)", fontsize=10, labelpad=2)
        ap.set_ylabel("panel v (mm)", fontsize=10)
        ap.tick_params(labelsize=9)
        ap.set_title("the panel, face-on: ink so far (plan in light grey)", fontsize=10)
        self.ax_panel = ap
        canvas.draw()  # layout: the ink raster is the panel axes' pixels on screen
        x0, y0, x1, y1 = (int(round(v)) for v in ap.get_window_extent().extents)
        height = int(round(fig.bbox.height))
        self.box = (height - y1, height - y0, x0, x1)  # buffer rows and columns
        (ulo, uhi), (vlo, vhi) = ap.get_xlim(), ap.get_ylim()
        self.alpha = np.zeros((y1 - y0, x1 - x0), np.uint8)
        (self.pen,) = ap.plot([], [], "o", ms=7, animated=True, zorder=3)

        # --- the time bar, with the marking stretches
        at = fig.add_axes((0.065, 0.145, 0.91, 0.03))
        marking = (clip.state == MARK).astype(float)
        at.fill_between(clip.t, 0, 1, where=marking > 0, step="post", color="#ffd8a8", lw=0)
        at.set_xlim(float(clip.t[0]), float(clip.t[-1]))
        at.set_ylim(0, 1)
        at.set_yticks([])
        at.tick_params(labelsize=9, pad=1)
        at.set_xlabel("drawing time (s); orange: marking", fontsize=9.5, labelpad=1)
        (self.cursor,) = at.plot([], [], color="black", lw=2.0, animated=True)
        self.ax_time = at

        fig.text(0.5, 0.008, f"rendered from {clip.source};\nnot a screen capture. "
                 f"Time ×{clip.compression:.1f} ({clip.duration_s:.0f} s in "
                 f"{clip.video_s:.0f} s)", ha="center", va="bottom", fontsize=10.5,
                 linespacing=1.25, color="#343a40")
        canvas.draw()
        self.background = canvas.copy_from_bbox(fig.bbox)
        self._title_setup(fig, size_px)
        r0, r1, c0, c1 = self.box
        # the panel region as drawn (static), and the same with the ink blended in so far
        self.panel_bg = np.asarray(canvas.buffer_rgba())[r0:r1, c0:c1, :3].astype(np.uint16)
        self.panel_rgb = self.panel_bg.astype(np.uint8)

        # the ink's source in raster pixels (4-bit fixed point), and the depth
        uvz = (clip.tip_m - clip.panel_origin_m) * MM
        self.below = uvz[:, 2] < 0.0
        col = (uvz[:, 0] - ulo) / (uhi - ulo) * (x1 - x0)
        row = (vhi - uvz[:, 1]) / (vhi - vlo) * (y1 - y0)
        self.px = np.rint(np.column_stack([col, row]) * 16).astype(np.int32)
        self.uvz = uvz
        self.done = 0  # tip samples already inked

    def _title_setup(self, fig: Any, size_px: tuple[int, int]) -> None:
        """The title is drawn with Pillow into a strip at the top (matplotlib's text
        rendering would cost more than the rest of a frame)."""
        from matplotlib import font_manager
        from PIL import ImageFont

        path = font_manager.findfont(font_manager.FontProperties(weight="bold"))
        self.font = ImageFont.truetype(path, max(8, round(17 * size_px[0] / 1024)))
        self.strip_h = int(0.09 * size_px[1])
        self.width = size_px[0]

    def _title(self, buf: NDArray[np.uint8], text: str, colour: str) -> None:
        from matplotlib.colors import to_rgb
        from PIL import Image, ImageDraw

        strip = Image.new("RGB", (self.width, self.strip_h), (255, 255, 255))
        draw = ImageDraw.Draw(strip)
        rgb = tuple(int(round(255 * c)) for c in to_rgb(colour))
        draw.text((self.width / 2, self.strip_h / 2 + 2), text, fill=rgb, font=self.font,
                  anchor="mm")
        buf[:self.strip_h, :, :3] = np.asarray(strip)

    def _ink_until(self, t: float) -> None:
        clip = self.clip
        stop = int(np.searchsorted(clip.tip_t, t, side="right"))
        if stop <= self.done:
            return
        idx = np.arange(max(self.done, 1), stop)
        keep = self.below[idx - 1] & self.below[idx]
        if keep.any():
            seg = np.stack([self.px[idx[keep] - 1], self.px[idx[keep]]], axis=1)
            self._cv2.polylines(self.alpha, list(seg), False, 255, 1, self._cv2.LINE_AA, 4)
            # re-blend only where the new ink is (the ink only grows)
            h, w = self.alpha.shape
            lo = np.clip(seg.reshape(-1, 2).min(axis=0) // 16 - 2, 0, None)
            hi = seg.reshape(-1, 2).max(axis=0) // 16 + 3
            cs, rs = slice(int(lo[0]), int(min(hi[0], w))), slice(int(lo[1]), int(min(hi[1], h)))
            a = self.alpha[rs, cs, None].astype(np.uint16)
            ink = np.asarray(INK_RGB, np.uint16)
            self.panel_rgb[rs, cs] = (self.panel_bg[rs, cs] * (255 - a) + ink * a) // 255
        self.done = stop

    def render(self, k: int) -> NDArray[np.uint8]:
        """Frame ``k`` as an (H, W, 4) uint8 RGBA array: a view of the canvas, valid
        until the next call."""
        clip = self.clip
        t = float(clip.t[k])
        self._ink_until(t)
        arm = clip.arm_m[k] * MM
        self.arm_line.set_data(arm[:, 0], arm[:, 2])
        uvz = np.array([np.interp(t, clip.tip_t, self.uvz[:, c]) for c in range(3)])
        down = bool(uvz[2] < 0.0)
        label, colour = needle_label(down, int(clip.state[k]))
        self.arm_tip.set_data([arm[-1, 0]], [arm[-1, 2]])
        self.arm_tip.set_color(colour)
        self.pen.set_data([uvz[0]], [uvz[1]])
        self.pen.set_markerfacecolor(colour if down else "none")
        self.pen.set_markeredgecolor(colour)
        self.cursor.set_data([t, t], [0, 1])
        self.canvas.restore_region(self.background)
        self.ax_arm.draw_artist(self.arm_line)
        self.ax_arm.draw_artist(self.arm_tip)
        self.ax_time.draw_artist(self.cursor)
        buf = np.asarray(self.canvas.buffer_rgba())
        r0, r1, c0, c1 = self.box
        buf[r0:r1, c0:c1, :3] = self.panel_rgb
        self.ax_panel.draw_artist(self.pen)  # over the ink
        self._title(buf, f"{clip.name}:  t = {t:6.1f} s of {clip.duration_s:.1f} s   {label}"
                         f"   (tip {uvz[2]:+.1f} mm from the surface)", colour)
        return buf


def _gif_palette(samples: list[Any]) -> Any:
    """One palette for every GIF frame, from a few frames tiled together."""
    from PIL import Image

    w, h = samples[0].size
    sheet = Image.new("RGB", (w, h * len(samples)))
    for i, im in enumerate(samples):
        sheet.paste(im, (0, i * h))
    return sheet.quantize(colors=224, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)


def _write_gif(path: Path, frames: list[Any], palette: Any, durations: list[int]) -> None:
    """Frames quantised to one palette; in every frame after the first, the pixels that
    did not change are transparent (the previous frame stays: disposal 1), which makes
    long runs of one index that LZW packs well."""
    from PIL import Image

    idx = [np.asarray(im.quantize(palette=palette, dither=Image.Dither.NONE)) for im in frames]
    used = np.zeros(256, bool)
    for a in idx:
        used[np.unique(a)] = True
    free = np.flatnonzero(~used)
    if len(free) == 0:  # no spare index: plain frames
        out = [Image.fromarray(a, "P") for a in idx]
        trans = None
    else:
        trans = int(free[0])
        out = [Image.fromarray(idx[0], "P")]
        for prev, cur in zip(idx[:-1], idx[1:], strict=True):
            out.append(Image.fromarray(np.where(cur == prev, trans, cur).astype(np.uint8), "P"))
    pal = palette.getpalette()
    for im in out:
        im.putpalette(pal)
    extra: dict[str, Any] = {} if trans is None else {"transparency": trans, "disposal": 1}
    out[0].save(path, format="GIF", save_all=True, append_images=out[1:], duration=durations,
                loop=0, optimize=False, **extra)


class ClipWriter:
    """Video frames to a GIF and/or an MP4, as they come.

    The MP4 (H.264, yuv420p, ``fps``) takes every frame, encoded as it arrives; the GIF
    every ``gif_every``-th frame and the last, ``gif_width_px`` wide, with one palette
    shared by every frame (from ``palette_frames`` frames spread over the clip), the last
    one held 2 s.

    Args:
        gif: the GIF to write, or None.
        mp4: the MP4 to write, or None. Skipped, with a log line, when ``imageio-ffmpeg``
            is not installed.
        fps: frames per second.
        size_px: the frames' size (the MP4's), px; both multiples of 16 for the MP4.
        gif_width_px: GIF width, px.
        gif_every: GIF frame stride.
        palette_frames: GIF frames the palette is made from (shaded 3-D frames need more
            than flat figures).
    """

    def __init__(self, gif: Path | None, mp4: Path | None, *, fps: float,
                 size_px: tuple[int, int], gif_width_px: int, gif_every: int = 2,
                 palette_frames: int = 4):
        if mp4 is not None and not mp4_available():
            log.info("animation: imageio-ffmpeg is not installed: no MP4 (pip install "
                     "imageio-ffmpeg); writing the GIF only")
            mp4 = None
        self.gif, self.mp4, self.fps = gif, mp4, fps
        self.size_px, self.gif_every = size_px, gif_every
        self.gif_width_px = gif_width_px
        self.palette_frames = palette_frames
        self.gif_h = int(round(size_px[1] * gif_width_px / size_px[0] / 2)) * 2
        self._gif_rgb: list[Any] = []
        self._writer: Any = None
        self.timings_s: dict[str, float] = {}
        if mp4 is not None:
            import imageio.v2 as imageio

            self._writer = imageio.get_writer(
                str(mp4), format="FFMPEG", mode="I", fps=fps, codec="libx264",
                pixelformat="yuv420p", quality=None, macro_block_size=16,
                ffmpeg_log_level="error",
                output_params=["-crf", "20", "-preset", "veryfast", "-movflags", "+faststart"])

    def add(self, k: int, n: int, frame: NDArray[np.uint8]) -> None:
        """Frame ``k`` of ``n``: an (H, W, 3 or 4) uint8 array at ``size_px``."""
        import cv2
        from PIL import Image

        if self._writer is not None:
            self._writer.append_data(np.ascontiguousarray(frame[..., :3]))
        if self.gif is not None and (k % self.gif_every == 0 or k == n - 1):
            small: NDArray[Any] = frame
            if (frame.shape[1], frame.shape[0]) != (self.gif_width_px, self.gif_h):
                small = cv2.resize(frame, (self.gif_width_px, self.gif_h),
                                   interpolation=cv2.INTER_AREA)
            self._gif_rgb.append(Image.fromarray(np.ascontiguousarray(small[..., :3])))

    @property
    def gif_frames(self) -> int:
        """Frames in the GIF so far (0 when none is asked)."""
        return len(self._gif_rgb) if self.gif is not None else 0

    def close(self) -> None:
        """Finish the MP4 and write the GIF."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        gif_rgb = self._gif_rgb
        if self.gif is not None and gif_rgb:
            t0 = time.perf_counter()
            n, k = len(gif_rgb), max(2, self.palette_frames)
            picks = sorted({i * n // (k - 1) for i in range(k - 1)} | {n - 1})
            pal = _gif_palette([gif_rgb[i] for i in picks])
            duration_ms = int(round(1000.0 * self.gif_every / self.fps))
            durations = [duration_ms] * (len(gif_rgb) - 1) + [2000]  # hold the last frame
            _write_gif(self.gif, gif_rgb, pal, durations)
            self.timings_s["gif"] = time.perf_counter() - t0

    def add_all(self, n: int, render: Callable[[int], NDArray[np.uint8]]) -> float:
        """Add frames ``render(0)`` .. ``render(n - 1)``; on any error (Ctrl-C included)
        :meth:`abort` and re-raise. Returns the seconds it took."""
        t0 = time.perf_counter()
        try:
            for k in range(n):
                self.add(k, n, render(k))
        except BaseException:
            self.abort()
            raise
        return time.perf_counter() - t0

    def abort(self) -> None:
        """Close the MP4 writer without writing the GIF (an error while rendering)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None


def render_drawing(clip: DrawingClip, gif: Path | None = None, mp4: Path | None = None, *,
                   size_px: tuple[int, int] = SIZE_PX, gif_width_px: int = GIF_WIDTH_PX,
                   gif_every: int = 2) -> RenderResult:
    """Render the drawing animation to a GIF and/or an MP4.

    Args:
        clip: the sampled drawing (:func:`drawing_clip`).
        gif: the GIF to write (Pillow; every ``gif_every``-th frame, ``gif_width_px``
            wide, one shared palette), or None.
        mp4: the MP4 to write (H.264, yuv420p, ``clip.fps``), or None. Skipped, with a
            log line, when ``imageio-ffmpeg`` is not installed.
        size_px: rendered frame size (MP4 size), px; both multiples of 16.
        gif_width_px: GIF width, px.
        gif_every: GIF frame stride (25 fps / 2 = 12.5 fps).

    Returns:
        What was written and what it cost.
    """
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    frames = _Frames(clip, size_px)
    n = len(clip.t)
    sink = ClipWriter(gif, mp4, fps=clip.fps, size_px=size_px, gif_width_px=gif_width_px,
                      gif_every=gif_every)
    timings["setup"] = time.perf_counter() - t0
    timings["frames"] = sink.add_all(n, frames.render)
    if sink.mp4 is not None:
        timings["mp4"] = timings["frames"]  # encoded while rendering
    sink.close()
    timings.update(sink.timings_s)
    wall = time.perf_counter() - t0
    return RenderResult(frames=n, gif=gif, gif_frames=sink.gif_frames, mp4=sink.mp4,
                        wall_s=wall, timings_s=timings)
