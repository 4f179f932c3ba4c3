"""The artwork stage: PNG/JPG/SVG input, built-ins, and refusal of bad input."""

from __future__ import annotations

import base64
import io
import os
import re
import struct
import subprocess
import sys
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tattotronix.art.artwork import (
    BUILTINS,
    SVG_OVERSAMPLE,
    artwork_name,
    builtin_path,
    load_artwork,
    resolve_source,
    svg_intrinsic_size,
)
from tattotronix.art.mask import NoInkError, label_regions, make_mask
from tattotronix.config.schema import ArtworkConfig, MaskConfig, PanelConfig
from tattotronix.errors import TattotronixError

ROOT = Path(__file__).resolve().parents[1]
MASK = MaskConfig()
MAX_PX = ArtworkConfig().max_pixels
PANEL_W_MM, PANEL_H_MM = (1000.0 * s for s in PanelConfig().size[:2])


def _load(source: str | Path | None, width_mm: float | None = MASK.default_width_mm,
          **kw: object):
    return load_artwork(source, width_mm, MASK.res_mm, kw.pop("max_pixels", MAX_PX), **kw)


def _rect_image(h: int = 200, w: int = 300) -> np.ndarray:
    a = np.full((h, w), 255, np.uint8)
    a[60:140, 80:220] = 0
    return a


# ----------------------------------------------------------------------------- built-ins


@pytest.fixture(scope="module")
def emblem():
    art = _load(None)
    mask, stats = make_mask(art.grey, art.res_mm, "threshold", MASK.min_region_mm2)
    return art, mask, stats


def test_builtins_exist_and_resolve() -> None:
    for name in BUILTINS:
        assert builtin_path(name).is_file()
        assert resolve_source(name) == builtin_path(name)
    assert resolve_source(None) == builtin_path("emblem")
    with pytest.raises(TattotronixError, match="emblem, portrait"):
        builtin_path("nope")


def test_existing_file_wins_over_builtin_name(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("portrait").write_bytes(b"x")
    assert resolve_source("portrait") == (tmp_path / "portrait").resolve()


def test_artwork_name() -> None:
    assert artwork_name(ArtworkConfig()) == "emblem"
    assert artwork_name(ArtworkConfig(source="art/my_logo.svg")) == "my_logo"
    assert artwork_name(ArtworkConfig(source="portrait")) == "portrait"
    assert artwork_name(ArtworkConfig(source="a.png", name="other")) == "other"
    with pytest.raises(TattotronixError, match="bad artwork name"):
        artwork_name(ArtworkConfig(name="../escape"))


def test_emblem_is_licensed_with_the_project() -> None:
    text = builtin_path("emblem").read_text(encoding="utf-8")
    assert "Apache" in text and "<metadata>" in text
    assert "<text" not in text  # shapes only: no dependence on system fonts
    licences = (builtin_path("emblem").parent / "LICENSES.md").read_text(encoding="utf-8")
    assert "Apache" in licences and "public domain" in licences


def test_emblem_fits_the_panel_and_is_drawable(emblem) -> None:
    art, mask, stats = emblem
    assert art.name == "emblem" and art.kind == "svg" and art.source == "builtin:emblem"
    w_mm, h_mm = art.size_mm
    assert w_mm == pytest.approx(MASK.default_width_mm)
    assert w_mm <= PANEL_W_MM and h_mm <= PANEL_H_MM
    assert h_mm / w_mm < 0.93
    assert 5.0 < stats.ink_pct < 25.0
    assert stats.dropped_regions == 0  # every feature is above the region floor


def test_emblem_has_regions_counters_and_dots(emblem) -> None:
    _, mask, stats = emblem
    assert stats.regions >= 25
    # counters of A, O, R, O, the two joint rings, and the space inside each ring
    assert stats.holes >= 6
    areas_mm2 = label_regions(mask.ink).areas_px * MASK.res_mm**2
    dots = int(np.sum(areas_mm2 < 10.0))
    assert dots >= 12


def test_svg_is_rendered_at_twice_the_mask_resolution(emblem) -> None:
    art, _, _ = emblem
    h, w = art.shape
    assert art.render_px == (SVG_OVERSAMPLE * w, SVG_OVERSAMPLE * h)


@pytest.mark.parametrize("offset_mm", [0.0, 0.0625, 0.125])
def test_svg_small_counters_stay_open(tmp_path: Path, offset_mm: float) -> None:
    # five rings, 1 mm of ink around a 0.6 mm counter (2.4 mask pixels), at sub-pixel offsets
    rings = "".join(
        f"<circle cx='{2 + 4 * i + offset_mm}' cy='{5 + offset_mm}' r='0.8' fill='none' "
        "stroke='black' stroke-width='1'/>"
        for i in range(5)
    )
    svg = tmp_path / "rings.svg"
    svg.write_text(f"<svg xmlns='http://www.w3.org/2000/svg' viewBox='0 0 20 10'>{rings}</svg>")
    art = _load(svg, width_mm=20.0)
    _, stats = make_mask(art.grey, art.res_mm, "threshold", min_region_mm2=1.0)
    assert (stats.regions, stats.holes) == (5, 5)


def test_svg_intrinsic_size_units() -> None:
    ns = "xmlns='http://www.w3.org/2000/svg'"
    assert svg_intrinsic_size(f"<svg {ns} viewBox='0 0 150 88'/>") == (150, 88)
    w, h = svg_intrinsic_size(f"<svg {ns} width='60mm' height='30mm'/>")
    assert h / w == pytest.approx(0.5)
    w, h = svg_intrinsic_size(f"<svg {ns} width='300' viewBox='0 0 10 5'/>")
    assert (w, h) == (300, 150)


def test_portrait_loads_and_gives_edges() -> None:
    art = _load("portrait", width_mm=110.0)
    assert art.name == "portrait" and art.kind == "jpeg" and art.original_px == (512, 600)
    _, stats = make_mask(art.grey, art.res_mm, "edges", MASK.min_region_mm2)
    assert 1.0 < stats.ink_pct < 50.0
    assert stats.regions > 5


# ----------------------------------------------------------------------------- raster route


def test_raster_grid_size(tmp_path: Path) -> None:
    p = tmp_path / "rect.png"
    Image.fromarray(_rect_image()).save(p)
    art = _load(p, width_mm=100.0)
    assert art.shape == (round(200 * (100 / 300) / MASK.res_mm), round(100 / MASK.res_mm))
    assert art.original_px == (300, 200) and art.kind == "png" and art.name == "rect"
    assert art.grey.min() < 10 and art.grey.max() > 245


def _rgba_art() -> Image.Image:
    rgba = np.zeros((200, 300, 4), np.uint8)  # transparent *black* background
    rgba[60:140, 80:220] = (0, 0, 0, 255)  # opaque black art
    return Image.fromarray(rgba, "RGBA")


@pytest.mark.parametrize(
    "convert",
    [
        lambda im: im,
        lambda im: im.convert("LA"),
        lambda im: im.quantize(),  # palette with alpha: saved as a tRNS table
    ],
    ids=["RGBA", "LA", "P"],
)
def test_alpha_is_composited_onto_white(
    tmp_path: Path, convert: Callable[[Image.Image], Image.Image]
) -> None:
    p = tmp_path / "alpha.png"
    convert(_rgba_art()).save(p)
    art = _load(p, width_mm=100.0)
    mask, stats = make_mask(art.grey, art.res_mm, "threshold", MASK.min_region_mm2)
    assert not stats.inverted
    h, w = mask.ink.shape
    rows, cols = np.nonzero(mask.ink)
    # the ink is the opaque rectangle (rows 30..70 %, cols 26.7..73.3 % of the image)
    assert rows.min() / h == pytest.approx(0.3, abs=0.02)
    assert cols.max() / w == pytest.approx(220 / 300, abs=0.02)
    assert stats.regions == 1
    assert stats.ink_pct == pytest.approx(100 * 140 * 80 / (300 * 200), abs=1.5)


# ----------------------------------------------------------------------------- bad input


def _chunk(tag: bytes, data: bytes) -> bytes:
    crc = zlib.crc32(tag + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", crc)


def _bomb_png() -> bytes:
    """A 74-byte PNG whose header claims 100 000 x 100 000 pixels."""
    ihdr = struct.pack(">IIBBBBB", 100_000, 100_000, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\0" * 1000)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat)
            + _chunk(b"IEND", b""))


def _encoded(fmt: str) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(_rect_image()).save(buf, fmt)
    return buf.getvalue()


def _flat(value: int, fmt: str) -> bytes:
    buf = io.BytesIO()
    Image.new("L", (300, 200), value).save(buf, fmt)
    return buf.getvalue()


NS = "xmlns='http://www.w3.org/2000/svg'"
BAD_INPUTS: dict[str, tuple[str, bytes | None, str]] = {
    # id: (file name, content or None for missing, expected words in the message)
    "missing": ("missing.png", None, "not found"),
    "truncated_png": ("trunc.png", _encoded("PNG")[:300], "truncated"),
    "truncated_jpg": ("trunc.jpg", _encoded("JPEG")[:400], "truncated"),
    "text_as_png": ("notes.png", b"hello, I am not an image\n", "not an image"),
    "unsupported": ("notes.txt", b"hello\n", "unsupported"),
    "bad_svg": ("bad.svg", f"<svg {NS}><rect></svg>".encode(), "does not parse"),
    "not_svg": ("page.svg", b"<html><body/></html>", "not an SVG"),
    "all_white": ("white.png", _flat(255, "PNG"), "no drawable ink"),
    "all_black": ("black.jpg", _flat(0, "JPEG"), "no drawable ink"),
    "bomb_png": ("bomb.png", _bomb_png(), "decompression bomb"),
    "bomb_svg": (
        "bomb.svg",
        f"<svg {NS} viewBox='0 0 1 100000'><rect width='1' height='9'/></svg>".encode(),
        "decompression bomb",
    ),
    # an SVG must be self-contained: resvg drops a URL silently and draws a local file
    "svg_url_image": (
        "url.svg",
        (f"<svg {NS} viewBox='0 0 60 40'><image href='http://example.com/a.png' width='60' "
         "height='40'/><rect width='20' height='20'/></svg>").encode(),
        "'http://example.com/a.png'",
    ),
    "svg_absolute_image": (
        "abs.svg",
        (f"<svg {NS} xmlns:xlink='http://www.w3.org/1999/xlink' viewBox='0 0 60 40'><image "
         f"xlink:href='{builtin_path('portrait')}' width='60' height='40'/></svg>").encode(),
        "refers to external files",
    ),
}


def _write_bad(directory: Path, key: str) -> Path:
    fname, content, _ = BAD_INPUTS[key]
    path = directory / fname
    if content is not None:
        path.write_bytes(content)
    return path


@pytest.mark.parametrize("key", list(BAD_INPUTS))
def test_bad_input_is_a_one_line_error(tmp_path: Path, key: str) -> None:
    path = _write_bad(tmp_path, key)
    with pytest.raises(TattotronixError) as info:
        _load(path)
    message = str(info.value)
    assert "\n" not in message
    assert BAD_INPUTS[key][2] in message
    assert str(path) in message or path.name in message
    if "no drawable ink" in message:
        assert isinstance(info.value, NoInkError)


def test_max_pixels_is_checked_before_decoding(tmp_path: Path) -> None:
    p = tmp_path / "rect.png"
    Image.fromarray(_rect_image()).save(p)
    with pytest.raises(TattotronixError, match="artwork.max_pixels=1000"):
        _load(p, max_pixels=1000)


def _stage_env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("DVC_STAGE", None)
    env["HYDRA_FULL_ERROR"] = "0"
    return env


@pytest.fixture(scope="module")
def stage_runs(tmp_path_factory) -> dict[str, tuple[subprocess.CompletedProcess, Path]]:
    """Run ``stages/artwork.py`` on every bad input, all at once (one process each)."""
    base = tmp_path_factory.mktemp("bad_stage")
    procs = {}
    for key in BAD_INPUTS:
        src = _write_bad(base, key)
        out = base / f"out_{key}"
        cmd = [sys.executable, "stages/artwork.py", f"artwork.source={src}",
               f"paths.data={out}"]
        procs[key] = (subprocess.Popen(cmd, cwd=ROOT, env=_stage_env(), text=True,
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE), out)
    results = {}
    for key, (proc, out) in procs.items():
        stdout, stderr = proc.communicate(timeout=120)
        results[key] = (subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr),
                        out)
    return results


@pytest.mark.parametrize("key", list(BAD_INPUTS))
def test_stage_refuses_bad_input_cleanly(stage_runs, key: str) -> None:
    run, out = stage_runs[key]
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith("artwork: error: ") and BAD_INPUTS[key][2] in lines[0]
    assert [p for p in out.rglob("*") if p.is_file()] == []


def _svg_with_image(href: str) -> str:
    return (f"<svg {NS} viewBox='0 0 60 40'><image href='{href}' x='10' y='10' width='40' "
            "height='20'/></svg>")


def test_svg_in_any_encoding_xml_accepts(tmp_path: Path) -> None:
    """A Latin-1 SVG with its declaration is read (it was refused as "not UTF-8"), so is
    UTF-16 with its byte-order mark; a file whose bytes break its declaration is refused."""
    body = f"<svg {NS} viewBox='0 0 60 40'><title>caf\xe9 \xbd</title>" \
        "<rect x='10' y='10' width='40' height='20'/></svg>"
    latin = tmp_path / "latin.svg"
    latin.write_bytes(("<?xml version='1.0' encoding='ISO-8859-1'?>\n" + body).encode("latin-1"))
    utf16 = tmp_path / "utf16.svg"
    utf16.write_bytes(("<?xml version='1.0' encoding='UTF-16'?>" + body).encode("utf-16"))
    plain = tmp_path / "plain.svg"
    plain.write_text(body, encoding="utf-8")
    want = _load(plain, width_mm=60.0).grey
    for path in (latin, utf16):
        np.testing.assert_array_equal(_load(path, width_mm=60.0).grey, want)
    lying = tmp_path / "lying.svg"
    lying.write_bytes(("<?xml version='1.0' encoding='UTF-8'?>" + body).encode("latin-1"))
    with pytest.raises(TattotronixError, match="lying.svg is not a text SVG file: it is not UTF"):
        _load(lying, width_mm=60.0)


def test_svg_local_files_are_an_option(tmp_path: Path) -> None:
    Image.fromarray(_rect_image()).save(tmp_path / "pic.png")
    svg = tmp_path / "art.svg"
    svg.write_text(_svg_with_image("pic.png"))
    with pytest.raises(TattotronixError, match=r"<image href> 'pic.png'.*svg_local_files=true"):
        _load(svg, width_mm=60.0)
    art = _load(svg, width_mm=60.0, svg_local_files=True)
    assert (art.grey < 128).mean() > 0.02  # the picture is drawn
    outside = tmp_path / "sub"
    outside.mkdir()
    for href, why in (("../pic.png", "only files in the SVG's own folder"),
                      (str(tmp_path / "pic.png"), "only files in the SVG's own folder"),
                      ("missing.png", "no such file"),
                      ("https://example.com/x.png", "https://example.com/x.png")):
        (outside / "art.svg").write_text(_svg_with_image(href))
        with pytest.raises(TattotronixError, match=re.escape(why)):
            _load(outside / "art.svg", width_mm=60.0, svg_local_files=True)
    data = "data:image/png;base64," + base64.b64encode(_encoded("PNG")).decode()
    (outside / "art.svg").write_text(_svg_with_image(data))
    assert (_load(outside / "art.svg", width_mm=60.0).grey < 128).mean() > 0.02
