"""The drawing in 3-D (MuJoCo's offscreen renderer, the ``animate`` stage's drawing3d) and
the live viewer (``viewer=true``) under a virtual X display."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tattotronix.errors import TattotronixError
from tattotronix.report.animation import INK_RGB, DrawingClip, drawing_clip, mp4_available
from tattotronix.report.render3d import SIZE_PX, DrawingScene, render_drawing_3d, select_gl
from tattotronix.robot.description import RobotDescription

from .conftest import ROOT, default_signals, stage_env
from .test_figures import _layout, _run_log, _tiny_drawing

# MuJoCo reads MUJOCO_GL once, when it is first imported: choose before any test imports
# it (collection imports every test module before the first test runs)
try:
    GL: str | None = select_gl()
    GL_ERROR = ""
except TattotronixError as exc:
    GL, GL_ERROR = None, str(exc)

SIZE = (320, 240)
PANEL_ORIGIN = (0.21, 0.0, 0.005)
SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]


@pytest.fixture()
def gl() -> str:
    """The offscreen OpenGL platform ("" for MuJoCo's own choice); a test that renders
    fails, saying why, without one."""
    assert GL is not None, GL_ERROR
    return GL


@pytest.fixture(scope="module")
def tiny_clip(desc: RobotDescription, models: tuple[Path, Path]) -> Callable[..., DrawingClip]:
    """The tiny drawing (a 16 mm circle, 4 s) from a simulated run, sampled as asked."""
    tiny = _tiny_drawing(desc, models[0])
    log = _run_log(desc, tiny)

    def make(**kwargs: float) -> DrawingClip:
        return drawing_clip(desc, models[0], "tiny", tiny["t"], tiny["q"], tiny["kind"],
                            tiny["tcp"], tiny["marked"], PANEL_ORIGIN, run_t=log["t"],
                            run_q=log["q"], run_tip_m=log["tip"], **kwargs)
    return make


@pytest.fixture(scope="module")
def clip(tiny_clip: Callable[..., DrawingClip]) -> DrawingClip:
    """The tiny drawing at 10 frames/s (41 frames)."""
    return tiny_clip(fps=10.0)


def _ink(frame: np.ndarray, blank: np.ndarray) -> np.ndarray:
    """Pixels darker than on ``blank`` (the same view without ink) and of the ink's hue
    (blue-black: more blue than red)."""
    f, b = frame.astype(int), blank.astype(int)
    return ((b.sum(axis=2) - f.sum(axis=2)) > 60) & (f[..., 2] > f[..., 0])


# --- the offscreen renderer ----------------------------------------------------------------

def test_the_offscreen_frame_shows_the_arm_where_the_camera_puts_it(
        gl: str, clip: DrawingClip, models: tuple[Path, Path]) -> None:
    scene = DrawingScene(clip, models[1], SIZE)
    try:
        k = len(clip.t) // 2  # half-way round the circle: needle down
        with_arm = scene.render(k, captions=False).copy()
        assert with_arm.std() > 20, "a blank frame"
        # the same frame with the arm's geoms hidden (their group switched off)
        m = scene.model
        arm = m.geom_bodyid > 0
        m.geom_group[arm] = 5
        scene.option.geomgroup[5] = 0
        no_arm = scene.render(k, captions=False).copy()
        moved = np.abs(with_arm.astype(int) - no_arm.astype(int)).sum(axis=2) > 40
        assert moved.mean() > 0.03, f"the arm covers {moved.mean():.1%} of the frame"
        # its pixels are the arm's grey, lit (rgba 0.85 0.85 0.82), not the bench's brown
        rgb = with_arm[moved].astype(float)
        assert np.mean(rgb.max(axis=1) - rgb.min(axis=1)) < 25
        # and they are where the camera projects the arm's bodies (the tip included)
        bodies = scene.data.xpos[1:]
        tip = clip.tip_m[np.searchsorted(clip.tip_t, clip.t[k])]
        px = scene.camera.project(np.vstack([bodies, tip]), float(m.vis.global_.fovy), SIZE)
        cols = np.clip(np.rint(px[:, 0]).astype(int), 0, SIZE[0] - 1)
        rows = np.clip(np.rint(px[:, 1]).astype(int), 0, SIZE[1] - 1)
        hits = [bool(moved[max(r - 4, 0):r + 5, max(c - 4, 0):c + 5].any())
                for r, c in zip(rows, cols, strict=True)]
        assert sum(hits) >= len(hits) - 1, hits  # a body hidden behind another may miss
        # the whole arm in the frame: none of it at the edges
        assert not moved[:, [0, -1]].any() and not moved[[0, -1], :].any()
    finally:
        scene.close()


def test_the_ink_grows_on_the_panel(gl: str, clip: DrawingClip,
                                    models: tuple[Path, Path]) -> None:
    scene = DrawingScene(clip, models[1], SIZE)
    try:
        # the arm out of the way, to see the whole circle
        scene.model.geom_group[scene.model.geom_bodyid > 0] = 5
        scene.option.geomgroup[5] = 0
        blank = scene.render(0, captions=False).copy()  # before the needle goes down
        mid = scene.render(len(clip.t) // 2, captions=False).copy()
        last = scene.render(len(clip.t) - 1, captions=False).copy()
    finally:
        scene.close()
    assert INK_RGB[2] > INK_RGB[0]
    ink = [_ink(f, blank) for f in (mid, last)]
    assert 0 < ink[0].sum() < ink[1].sum(), [int(i.sum()) for i in ink]
    assert not (ink[0] & ~ink[1]).any()  # it only grows
    # on the panel: the circle's centre is where the camera projects the panel origin
    rows, cols = np.nonzero(ink[1])
    centre = scene.camera.project(np.array([PANEL_ORIGIN]),
                                  float(scene.model.vis.global_.fovy), SIZE)[0]
    assert abs(cols.mean() - centre[0]) < 4 and abs(rows.mean() - centre[1]) < 4


def _cylinder(radius_m: float, z_axis_m: float, n_around: int = 48,
              x_m: tuple[float, float] = (0.15, 0.27)) -> tuple[np.ndarray, np.ndarray]:
    """A closed-round tube along x (the tiny circle's panel under it), its vertices (m)
    and outward-wound triangles."""
    th = np.linspace(-np.pi, np.pi, n_around, endpoint=False)
    xs = np.linspace(*x_m, 13)
    ring = np.column_stack([np.sin(th), np.cos(th)]) * radius_m  # y, z about the axis
    v = np.array([[x, y, z + z_axis_m] for x in xs for y, z in ring])
    faces = []
    for i in range(len(xs) - 1):
        for j in range(n_around):
            a, b = i * n_around + j, i * n_around + (j + 1) % n_around
            c, d = a + n_around, b + n_around
            faces += [[a, c, b], [b, c, d]]
    return v, np.array(faces, dtype=np.int64)


def test_the_ink_grows_on_a_limb_in_the_panels_place(gl: str, clip: DrawingClip,
                                                    models: tuple[Path, Path]) -> None:
    """The skin's canvas: a wide tube whose top is the panel's surface under the tiny circle,
    charted by unrolling it (u along it, v around it from the top, mm); the ink shows on
    it where the camera puts the circle, grows, and no face across the tube's seam (its
    underside, off the chart) takes the design."""
    from tattotronix.plants import Workpiece
    from tattotronix.plants.mujoco_plant import WORKPIECE
    from tattotronix.report.render3d import SkinInk

    radius = 0.1  # flat enough that the whole circle is in it
    axis_z = PANEL_ORIGIN[2] - radius
    verts, faces = _cylinder(radius, axis_z, n_around=360, x_m=(0.19, 0.23))
    chart = lambda p: np.column_stack([  # noqa: E731  (arm m -> design mm, height mm)
        p[:, 0] * 1e3, radius * 1e3 * np.arctan2(p[:, 1], p[:, 2] - axis_z),
        (np.hypot(p[:, 1], p[:, 2] - axis_z) - radius) * 1e3])
    uv = chart(verts)[:, :2]
    tips = chart(clip.tip_m)
    box = (tips[:, 0].min() - 4, tips[:, 1].min() - 4, tips[:, 0].max() + 4,
           tips[:, 1].max() + 4)
    uv[np.abs(uv[:, 1]) > 0.9 * np.pi * radius * 1e3] = np.nan  # off the chart: the seam
    skin = SkinInk(Workpiece(verts, faces), uv, tips, box, 0.1)
    size = (2 * SIZE[0], 2 * SIZE[1])  # the tiny circle a few pixels more across
    scene = DrawingScene(clip, models[1], size, skin=skin)
    try:
        m = scene.model
        names = [m.geom(i).name for i in range(m.ngeom)]
        assert WORKPIECE in names and "panel" not in names
        mesh = m.geom_dataid[names.index(WORKPIECE)]
        fadr, fnum = m.mesh_faceadr[mesh], m.mesh_facenum[mesh]
        face_tc = m.mesh_facetexcoord[fadr:fadr + fnum]
        bare = face_tc.max()  # the one extra coordinate: a texel of bare skin
        inside = ((uv[:, 0] >= box[0]) & (uv[:, 0] <= box[2]) & (uv[:, 1] >= box[1])
                  & (uv[:, 1] <= box[3]))
        off = ~inside[faces].all(axis=1)
        assert off.any() and (~off).any()
        np.testing.assert_array_equal(np.all(face_tc == bare, axis=1), off)
        m.geom_group[m.geom_bodyid > 0] = 5  # the arm out of the way, and its tip's site
        scene.option.geomgroup[5] = 0
        scene.option.sitegroup[:] = 0
        blank = scene.render(0, captions=False).copy()
        mid = scene.render(len(clip.t) // 2, captions=False).copy()
        last = scene.render(len(clip.t) - 1, captions=False).copy()
    finally:
        scene.close()
    # darker than the bare skin (the ink's blue, half blended into a pink skin, is no
    # bluer than red: _ink's hue test is the panel's)
    ink = [(blank.astype(int).sum(axis=2) - f.astype(int).sum(axis=2)) > 60
           for f in (mid, last)]
    assert 0 < ink[0].sum() < ink[1].sum(), [int(i.sum()) for i in ink]
    assert not (ink[0] & ~ink[1]).any()  # it only grows
    rows, cols = np.nonzero(ink[1])
    down = clip.tip_m[tips[:, 2] < 0]
    centre = scene.camera.project(down.mean(axis=0)[None], float(m.vis.global_.fovy),
                                  size)[0]
    # where the tips are, to a tenth of the ink's own size on the frame (the skin's film
    # frames the design close up: a pixel is less than on the panel's)
    tol = 0.1 * np.array([np.ptp(cols), np.ptp(rows)]) + 2.0
    assert abs(cols.mean() - centre[0]) < tol[0] and abs(rows.mean() - centre[1]) < tol[1]


def test_the_3d_video_has_the_clip_s_frames(gl: str, tiny_clip: Callable[..., DrawingClip],
                                            models: tuple[Path, Path], tmp_path: Path) -> None:
    short = tiny_clip(video_s=2.0, fps=10.0)  # the 4 s drawing in 2 s
    assert len(short.t) == 21
    gif, mp4 = tmp_path / "drawing3d.gif", tmp_path / "drawing3d.mp4"
    res = render_drawing_3d(short, models[1], gif=gif, mp4=mp4, size_px=SIZE)
    assert res.frames == 21 and res.gif_frames == 11  # every other frame, the last held
    with Image.open(gif) as im:
        assert im.n_frames == 11 and im.size == SIZE
        first = np.asarray(im.convert("RGB"))
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB"))
    assert np.abs(last.astype(int) - first.astype(int)).sum(axis=2).astype(bool).mean() > 0.01
    if mp4_available():
        import imageio.v2 as imageio

        with imageio.get_reader(str(mp4)) as r:
            assert r.get_meta_data()["size"] == SIZE
            assert sum(1 for _ in r) == 21
    else:
        assert res.mp4 is None and not mp4.exists()


@pytest.mark.slow
def test_the_animate_stage_writes_the_3d_video_beside_the_2d_one(
        draw_data: Path, desc: RobotDescription, models: tuple[Path, Path]) -> None:
    _layout(draw_data, desc, _tiny_drawing(desc, models[0]))
    r = subprocess.run([sys.executable, "stages/animate.py", f"paths.data={draw_data}",
                        "artwork.name=tiny"], cwd=ROOT, env=stage_env(), capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    fig = draw_data / "figures" / "tiny"
    with Image.open(fig / "drawing.gif") as a, Image.open(fig / "drawing3d.gif") as b:
        assert a.n_frames == b.n_frames > 1  # the same frames
        assert b.size == SIZE_PX
    for stem in ("drawing", "drawing3d"):
        assert (fig / f"{stem}.mp4").exists() == mp4_available()
    assert "drawing3d (MuJoCo, MUJOCO_GL=" in r.stdout + r.stderr
    assert not [p.name for p in draw_data.rglob(".*tmp*")]


def test_a_model_without_the_panel_is_refused(gl: str, clip: DrawingClip,
                                              models: tuple[Path, Path],
                                              tmp_path: Path) -> None:
    bad = tmp_path / "robot.xml"
    bad.write_text(models[1].read_text().replace('name="panel"', 'name="board"'))
    with pytest.raises(TattotronixError, match="no geom 'panel'.*'robot' stage"):
        DrawingScene(clip, bad, SIZE)


def _select_gl_in_child(code: str, **env: str) -> subprocess.CompletedProcess[str]:
    """``select_gl`` in a fresh process (MuJoCo not imported, MUJOCO_GL and DISPLAY unset)."""
    base = {k: v for k, v in os.environ.items()
            if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")}
    return subprocess.run([sys.executable, "-c", "import tattotronix.report.render3d as R\n"
                           + code + "\nprint(R.select_gl())"], env={**base, **env},
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_select_gl_falls_back_to_osmesa_when_egl_fails() -> None:
    # no EGL vendor library: EGL cannot start
    r = _select_gl_in_child("", __EGL_VENDOR_LIBRARY_FILENAMES="/nonexistent/egl.json")
    if r.stdout.strip() == "egl":
        pytest.skip("this libEGL is not glvnd's: its vendor cannot be taken away")
    if r.returncode == 0:
        assert r.stdout.strip() == "osmesa"
    else:  # no OSMesa here either (apt-get install libosmesa6)
        assert "MUJOCO_GL=egl:" in r.stderr and "osmesa:" in r.stderr, r.stderr


def test_select_gl_says_what_failed_when_nothing_renders() -> None:
    r = _select_gl_in_child("R.GL_BACKENDS = ('bogus',)")
    assert r.returncode != 0
    assert "no OpenGL for MuJoCo's offscreen renderer: tried MUJOCO_GL=bogus:" in r.stderr
    assert "libosmesa6" in r.stderr


# --- the live viewer under Xvfb ------------------------------------------------------------

@pytest.fixture()
def display() -> Iterator[str]:
    """A virtual X display (Xvfb, 1920 x 1080, 24-bit) for the test; its name (":N")."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb; .ci/run installs it)")
    read, write = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(write), "-screen", "0", "1920x1080x24",
                             "-nolisten", "tcp"], pass_fds=(write,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    try:
        with os.fdopen(read) as f:
            number = f.readline().strip()  # written once the server listens
        assert number.isdigit(), "Xvfb gave no display number"
        yield f":{number}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _viewer_run(data: Path, display: str, backend: str, window: str
                ) -> subprocess.Popen[str]:
    env = {k: v for k, v in stage_env().items()
           if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "WAYLAND_DISPLAY")}
    env["DISPLAY"] = display  # the viewer's window: GLFW on this display
    art = data.parent / "small.png"
    return subprocess.Popen(
        [sys.executable, "stages/draw.py", f"paths.data={data}", "draw.progress=false",
         f"backend={backend}", f"artwork.source={art}", *SMALL, "viewer=true",
         f"window={window}"], cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, preexec_fn=default_signals)


def _grab(display: str) -> np.ndarray:
    from PIL import ImageGrab

    return np.asarray(ImageGrab.grab(xdisplay=display).convert("RGB"))


def _brown(shot: np.ndarray) -> np.ndarray:
    """The bench (rgba 0.55 0.42 0.3), as lit: reddish brown."""
    f = shot.astype(int)
    r, g, b = f[..., 0], f[..., 1], f[..., 2]
    return (r > g + 12) & (g > b + 8) & (r > 60) & (r < 230)


def _watch(proc: subprocess.Popen[str], display: str,
           look: Callable[[np.ndarray], None]) -> tuple[subprocess.Popen[str], str]:
    """Screenshot ``display`` every 0.4 s while ``proc`` runs (at most 5 min), handing each
    to ``look``; then its stderr. A run still going at the end is killed."""
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline:
            look(_grab(display))
            time.sleep(0.4)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc, err


@pytest.mark.slow
def test_the_mujoco_viewer_shows_the_arm_drawing(draw_data: Path, display: str) -> None:
    """``viewer=true`` opens MuJoCo's passive viewer; its window, screenshot while the
    drawing runs (paced in real time), shows the bench and an arm that moves."""
    shots: list[tuple[float, np.ndarray]] = []

    def look(shot: np.ndarray) -> None:
        if _brown(shot).sum() > 2000:  # the viewer is up and draws the scene
            shots.append((time.monotonic(), shot))

    proc, err = _watch(_viewer_run(draw_data, display, "mujoco", "[0,8]"), display, look)
    assert proc.returncode == 0, err
    assert "needs a display" not in err, err
    assert len(shots) >= 4, f"{len(shots)} screenshots showed the scene: {err[-2000:]}"
    # the arm is what moves: the pixels that change between the first and the last
    # screenshot of the run are the arm's grey (rgba 0.85 0.85 0.82) in one of them
    first, last = shots[0][1], shots[-1][1]
    for name, shot in (("first", first), ("last", last)):  # for a person looking into it
        Image.fromarray(shot).save(draw_data.parent / f"viewer_{name}.png")
    moved = np.abs(first.astype(int) - last.astype(int)).sum(axis=2) > 60
    assert moved.sum() > 300, f"only {moved.sum()} pixels changed: is the arm moving?"
    grey = []
    for shot in (first, last):
        px = shot[moved].astype(int)
        grey.append(((px.max(axis=1) - px.min(axis=1)) < 30) & (px.min(axis=1) > 90))
    assert (grey[0] | grey[1]).mean() > 0.5, "what moved is not the arm's grey"
    # and it moved over the bench (in its columns, below the bench's height above it)
    rows, cols = np.nonzero(_brown(last))
    top = max(0, rows.min() - (rows.max() - rows.min()))
    box = moved[top:rows.max() + 1, cols.min():cols.max() + 1]
    assert box.sum() > 0.9 * moved.sum()
    run = draw_data / "runs" / "small-mujoco"
    assert (run / "log.npz").exists()


@pytest.mark.slow
def test_the_pybullet_gui_runs(draw_data: Path, display: str) -> None:
    """``viewer=true backend=pybullet`` opens the PyBullet GUI (a window appears on the
    display) and finishes the window."""
    lit = [0.0]

    def look(shot: np.ndarray) -> None:
        lit[0] = max(lit[0], float((shot.max(axis=2) > 30).mean()))

    proc, err = _watch(_viewer_run(draw_data, display, "pybullet", "[0,2]"), display, look)
    assert proc.returncode == 0, err
    assert "needs a display" not in err, err
    assert lit[0] > 0.1, f"no window on the display ({lit[0]:.1%} of it lit)"
    assert (draw_data / "runs" / "small-pybullet" / "log.npz").exists()
