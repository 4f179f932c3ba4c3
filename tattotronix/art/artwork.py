"""Artwork input: a PNG, JPG or SVG file (or a built-in) to a grey raster on the mask grid.

The raster is what the ``mask`` stage thresholds. It is ``width_mm`` wide at ``res_mm``
per pixel, with the source's aspect ratio (docs/original.md, "2.1 Artwork and mask"):

* Raster files (PNG, JPG) go through Pillow. Transparency is composited onto opaque
  white, then the image is converted to 8-bit grey. The grid is ``out_w =
  round(width_mm / res_mm)``, ``out_h = round(h_px * (width_mm / w_px) / res_mm)``.
  Enlarging is bilinear, as the original; shrinking averages areas (``cv2.INTER_AREA``),
  so a thin line in a large photo is thinned, not skipped.
* SVG goes through resvg (``resvg_py``), rendered at twice the mask resolution and then
  averaged down 2 x 2, so each edge pixel is decided by four sub-pixels and small
  counters stay open. The file may be in any encoding XML allows (its declaration, or a
  byte-order mark, says which). It must be self-contained: a reference to another file or
  to the network (``<image href="photo.png">``, ``url(http://...)``, ``@import``) is
  refused, naming it, unless ``artwork.svg_local_files`` allows files in the SVG's own
  folder; embedded ``data:`` images and ``#id`` references are always fine. ``<text>``
  is drawn with the system's fonts for a family it names, and with DejaVu (shipped with
  matplotlib, so always there) for a generic or missing one; the log names the text.

Every way an input can be unusable ends in a one-line :class:`TattotronixError` that says
what was wrong and what to do: a missing or unsupported file, a corrupt or truncated
image, a file that is not an image, an SVG that does not parse, a decompression bomb
(checked on the header or the declared SVG size, before decoding), an SVG that refers to
external files, and an image with no drawable ink (one flat tone).
"""

from __future__ import annotations

import io
import json
import logging
import math
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageOps

from tattotronix.art.mask import NoInkError
from tattotronix.art.sizing import drawing_width_mm, grid_pitch_mm, svg_strokes, thinnest_stroke
from tattotronix.config.schema import ArtworkConfig
from tattotronix.errors import TattotronixError

__all__ = [
    "ASSETS_DIR",
    "Artwork",
    "ArtworkGrid",
    "BUILTINS",
    "artwork_grid",
    "DEFAULT_ARTWORK",
    "SUPPORTED_SUFFIXES",
    "artwork_name",
    "builtin_path",
    "grid_shape",
    "load_artwork",
    "read_svg",
    "resolve_source",
    "svg_external_refs",
    "svg_intrinsic_size",
    "svg_physical_width_mm",
]

log = logging.getLogger(__name__)

ASSETS_DIR = Path(__file__).resolve().parent / "assets"
"""The built-in artworks (see ``assets/LICENSES.md``)."""

BUILTINS: dict[str, str] = {"emblem": "emblem.svg", "portrait": "portrait.jpg",
                           "lineart": "lineart.svg"}
"""Built-in artwork name -> file under :data:`ASSETS_DIR`."""

DEFAULT_ARTWORK = "emblem"
"""What ``artwork.source: null`` draws."""

RASTER_SUFFIXES = (".png", ".jpg", ".jpeg")
SVG_SUFFIXES = (".svg",)
SUPPORTED_SUFFIXES = RASTER_SUFFIXES + SVG_SUFFIXES

SVG_OVERSAMPLE = 2
"""Vector art is rendered at this multiple of the mask resolution, then averaged down."""

CSS_DPI = 96.0
"""CSS pixels per inch: how SVG lengths in mm, pt, in map to pixels."""

FLAT_TONE_LEVELS = 8.0
"""A raster whose grey levels span less than this (0..255 scale) has no drawable ink."""

_SVG_UNITS_PX = {
    "": 1.0,
    "px": 1.0,
    "in": CSS_DPI,
    "cm": CSS_DPI / 2.54,
    "mm": CSS_DPI / 25.4,
    "pt": CSS_DPI / 72.0,
    "pc": CSS_DPI / 6.0,
}
_PHYSICAL_UNITS = ("in", "cm", "mm", "pt", "pc")
_SVG_LENGTH = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([a-z%]*)\s*$")
_SVG_DEFAULT_PX = 100.0  # resvg's size for an SVG with neither width/height nor viewBox
_XML_DECL = re.compile(r"^\s*<\?xml\b[^>]*\?>")
_XML_ENCODING = re.compile(rb"^\s*<\?xml\b[^>]*?\bencoding\s*=\s*[\"']([A-Za-z][\w.:-]*)[\"']")
_CSS_URL = re.compile(r"url\(\s*([\"']?)([^\"')]*)\1\s*\)|@import\s+([\"'])([^\"']*)\3")
_HREF_ATTRS = ("href", "{http://www.w3.org/1999/xlink}href", "src")
_SHOWN_REFS = 3  # external references named in a refusal


@dataclass(frozen=True)
class Artwork:
    """An artwork on the mask grid.

    Attributes:
        grey: (H, W) float64 grey levels, 0 black .. 255 white. Row 0 is the top.
        res_mm: grid pitch, mm per pixel.
        name: names the outputs (``data/artwork/<name>.png``).
        source: what was read: ``builtin:<name>`` for a built-in, else the file's path
            (relative to the working directory when it lies under it).
        kind: ``"png"``, ``"jpeg"`` or ``"svg"``.
        original_px: (width, height) of the source in its own pixels (for SVG, its
            intrinsic size in CSS pixels, rounded).
        render_px: (width, height) of the intermediate SVG rendering, or None.
        transparent: some of its canvas is fully transparent (an SVG's usually is): its
            ink is what is drawn on it, so the mask never draws the light side instead
            (``mask.auto_invert`` is for light art on an opaque dark field).
    """

    grey: NDArray[np.float64]
    res_mm: float
    name: str
    source: str
    kind: str
    original_px: tuple[int, int]
    render_px: tuple[int, int] | None = None
    transparent: bool = False

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the grid in pixels."""
        h, w = self.grey.shape
        return h, w

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width, height) of the drawing in mm."""
        h, w = self.grey.shape
        return w * self.res_mm, h * self.res_mm

    def as_uint8(self) -> NDArray[np.uint8]:
        """The grey raster rounded to 8 bits (what ``data/artwork/<name>.png`` holds)."""
        return np.clip(np.rint(self.grey), 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------- naming


def builtin_path(name: str) -> Path:
    """The file of a built-in artwork.

    Args:
        name: one of :data:`BUILTINS` (``"emblem"``, ``"portrait"``).

    Raises:
        TattotronixError: ``name`` is not a built-in.
    """
    try:
        return ASSETS_DIR / BUILTINS[name]
    except KeyError:
        raise TattotronixError(
            f"no built-in artwork named '{name}': built-ins are {', '.join(BUILTINS)}"
        ) from None


def resolve_source(source: str | Path | None) -> Path:
    """The file an ``artwork.source`` value means.

    ``None`` is the built-in emblem. A path that exists is used as is. A bare built-in
    name (``emblem``, ``portrait``) that is not an existing file means that built-in.

    Raises:
        TattotronixError: the file does not exist.
    """
    if source is None or str(source).strip() == "":
        return builtin_path(DEFAULT_ARTWORK)
    path = Path(source).expanduser()
    if path.exists():
        return path.resolve()
    if str(source) in BUILTINS:
        return builtin_path(str(source))
    raise TattotronixError(
        f"artwork file not found: {source} (give a PNG, JPG or SVG path, "
        f"or a built-in: {', '.join(BUILTINS)})"
    )


def source_label(source: str | Path | None) -> str | None:
    """How outputs record an ``artwork.source``: ``builtin:<name>`` for a built-in, else
    the file's path (cwd-relative if under it); None for a file that does not exist."""
    try:
        return _source_label(resolve_source(source))
    except TattotronixError:
        return None


def _same_file(label_a: str, label_b: str) -> bool:
    if label_a.startswith("builtin:") or label_b.startswith("builtin:"):
        return label_a == label_b
    return Path(label_a).expanduser().resolve() == Path(label_b).expanduser().resolve()


def check_same_source(recorded_in: Path, source: str | Path | None, name: str,
                      replacing: bool) -> None:
    """Refuse to mix two artworks that share a name (by default a file's stem:
    ``mine.png`` and ``mine.svg`` are both ``mine``).

    Args:
        recorded_in: a JSON file an earlier run wrote for ``name``, with the ``source``
            it was made from (the artwork's metrics, a run's metrics); nothing is checked
            when it is missing, unreadable or records no source.
        source: this run's ``artwork.source``.
        name: the artwork's name.
        replacing: this run would overwrite ``recorded_in`` (check it only for a name
            taken from the file's stem: a name given on purpose may take a new file);
            else it reads what ``recorded_in`` describes.

    Raises:
        TattotronixError: the file records another source; says which, and how to give
            this one a name of its own.
    """
    label = source_label(source)
    try:
        recorded = json.loads(recorded_in.read_text()).get("source")
    except (OSError, ValueError, AttributeError):
        return
    if label is None or not isinstance(recorded, str) or _same_file(recorded, label):
        return
    path = Path(label.removeprefix("builtin:"))
    own = f"{path.stem}-{path.suffix.lstrip('.') or 'file'}"
    if replacing:
        raise TattotronixError(
            f"two artworks named '{name}': {recorded_in} was written for {recorded}, and "
            f"this run would replace it with {label}'s; give this one a name of its own "
            f"(artwork.name={own}), or delete the other's outputs")
    raise TattotronixError(
        f"the artwork '{name}' was made from {recorded} ({recorded_in}), not {label}: run "
        "the artwork stage for this file first, with the same artwork.name (a name of its "
        f"own, artwork.name={own}, keeps the other)")


def artwork_name(cfg_artwork: ArtworkConfig) -> str:
    """The name of an artwork's outputs: ``name``, else the source's stem, else ``emblem``.

    Args:
        cfg_artwork: the ``artwork`` settings.

    Raises:
        TattotronixError: the name would not be a plain file name.
    """
    name = cfg_artwork.name
    source = cfg_artwork.source
    if name is None or str(name).strip() == "":
        name = DEFAULT_ARTWORK if source is None or str(source).strip() == "" else Path(
            str(source)
        ).stem
    name = str(name).strip()
    if not name or name.startswith(".") or "/" in name or "\\" in name:
        raise TattotronixError(
            f"bad artwork name '{name}': it names output files, so use a plain name "
            "such as artwork.name=my_logo"
        )
    return name


# ----------------------------------------------------------------------------- grid


def grid_shape(size_px: tuple[float, float], width_mm: float, res_mm: float) -> tuple[int, int]:
    """(H, W) of the mask grid for a source of ``size_px`` = (width, height) pixels.

    ``W = round(width_mm / res_mm)``, ``H = round(h * (width_mm / w) / res_mm)``, each
    at least 1.

    Raises:
        TattotronixError: a non-positive width, resolution or source size.
    """
    w_px, h_px = size_px
    if not (width_mm > 0 and res_mm > 0 and math.isfinite(width_mm) and math.isfinite(res_mm)):
        raise TattotronixError(
            f"bad drawing size: mask.width_mm={width_mm}, mask.res_mm={res_mm} "
            "(both must be positive)"
        )
    if not (w_px > 0 and h_px > 0 and math.isfinite(w_px) and math.isfinite(h_px)):
        raise TattotronixError(f"the artwork has no area ({w_px} x {h_px} px)")
    out_w = max(round(width_mm / res_mm), 1)
    out_h = max(round(h_px * (width_mm / w_px) / res_mm), 1)
    return out_h, out_w


def _check_pixels(what: str, w: int, h: int, max_pixels: int, fix: str) -> None:
    if w * h > max_pixels:
        raise TattotronixError(
            f"{what} is {w} x {h} = {w * h} px, more than artwork.max_pixels={max_pixels} "
            f"(a decompression bomb?); {fix}"
        )


def _source_label(path: Path) -> str:
    """``builtin:<name>`` for a built-in file, else the path (cwd-relative if under it)."""
    for name, file in BUILTINS.items():
        if path == ASSETS_DIR / file:
            return f"builtin:{name}"
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


# ----------------------------------------------------------------------------- decoding


def _has_transparency(im: Image.Image) -> bool:
    """Whether any pixel of the image is fully transparent."""
    if im.mode not in ("RGBA", "LA", "PA", "La", "RGBa", "P") and "transparency" not in im.info:
        return False
    alpha = np.asarray(im.convert("RGBA").getchannel("A"))
    return bool(alpha.min() == 0)


def _to_grey(im: Image.Image) -> NDArray[np.float64]:
    """Grey levels 0..255 of a Pillow image, transparency composited onto white."""
    if im.mode in ("RGBA", "LA", "PA", "La", "RGBa", "P") or "transparency" in im.info:
        rgba = im.convert("RGBA")
        white = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
        im = Image.alpha_composite(white, rgba)
    if im.mode.startswith("I;16") or im.mode == "I":
        g = np.asarray(im, dtype=np.float64)
        return np.clip(g / 257.0 if g.max() > 255 else g, 0, 255)
    if im.mode == "F":
        return np.clip(np.asarray(im, dtype=np.float64), 0, 255)
    return np.asarray(im.convert("L"), dtype=np.float64)


def _open_raster(
    path: Path | io.BytesIO, label: str, max_pixels: int
) -> tuple[Image.Image, str]:
    """Open and decode a PNG/JPG, its size checked on the header first; with its format."""
    saved = Image.MAX_IMAGE_PIXELS
    try:
        # Image.open reads the header only; we check its size ourselves before decoding
        # (with our limit and our message), so Pillow's global guard is off meanwhile.
        Image.MAX_IMAGE_PIXELS = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im: Image.Image = Image.open(path)
            w, h = im.size
            _check_pixels(
                f"{label}", w, h, max_pixels,
                "refusing to decode it: scale it down, or raise artwork.max_pixels if you "
                "trust it",
            )
            im.load()
            fmt = (im.format or "").lower()
            im = ImageOps.exif_transpose(im) or im
    except TattotronixError:
        raise
    except Image.DecompressionBombError as exc:
        raise TattotronixError(
            f"{label} is too large to decode safely ({_one_line(exc)}); scale it down, or "
            "raise artwork.max_pixels if you trust it"
        ) from None
    except PermissionError as exc:
        raise TattotronixError(f"cannot read {label}: {_one_line(exc)}") from None
    except Image.UnidentifiedImageError:
        raise TattotronixError(
            f"{label} is not an image Pillow can read: give a PNG, JPG or SVG file"
        ) from None
    except (OSError, SyntaxError, ValueError, EOFError, MemoryError) as exc:
        raise TattotronixError(
            f"cannot decode {label}: {_one_line(exc)} (the file is corrupt or truncated; "
            "re-export it)"
        ) from None
    finally:
        Image.MAX_IMAGE_PIXELS = saved
    return im, fmt


def _svg_length(value: str | None) -> float | None:
    """An absolute SVG length in CSS px, or None for missing, relative or bad values."""
    if value is None:
        return None
    m = _SVG_LENGTH.match(value)
    if not m or m.group(2) not in _SVG_UNITS_PX:
        return None
    v = float(m.group(1)) * _SVG_UNITS_PX[m.group(2)]
    return v if v > 0 and math.isfinite(v) else None


def svg_physical_width_mm(text: str, label: str = "SVG") -> float | None:
    """The width an SVG declares in a physical unit (mm, cm, in, pt, pc), mm; None when
    its ``width`` is missing, relative, in px or unitless."""
    m = _SVG_LENGTH.match(_parse_svg(text, label).get("width") or "")
    if not m or m.group(2) not in _PHYSICAL_UNITS:
        return None
    px = _svg_length(m.group(0))
    return None if px is None else px * 25.4 / CSS_DPI


def _parse_svg(text: str, label: str) -> ET.Element:
    """The SVG's XML root; a parse error is refused naming ``label``."""
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise TattotronixError(
            f"{label} does not parse as SVG: {_one_line(exc)}; fix or re-export it"
        ) from None


def svg_intrinsic_size(text: str, label: str = "SVG") -> tuple[float, float]:
    """(width, height) in CSS px that an SVG declares, as resvg sizes it.

    ``width``/``height`` when absolute; a missing one follows the ``viewBox`` aspect;
    neither: the ``viewBox`` size; nothing at all: 100 x 100.

    Raises:
        TattotronixError: the text is not well-formed XML, or its root is not ``<svg>``.
    """
    root = _parse_svg(text, label)
    if root.tag.rsplit("}", 1)[-1] != "svg":
        raise TattotronixError(
            f"{label} is not an SVG (its root element is <{root.tag.rsplit('}', 1)[-1]}>)"
        )
    vb: tuple[float, float] | None = None
    parts = re.split(r"[\s,]+", (root.get("viewBox") or "").strip())
    if len(parts) == 4:
        try:
            vw, vh = float(parts[2]), float(parts[3])
            if vw > 0 and vh > 0 and math.isfinite(vw) and math.isfinite(vh):
                vb = (vw, vh)
        except ValueError:
            pass
    w, h = _svg_length(root.get("width")), _svg_length(root.get("height"))
    if w is not None and h is not None:
        return w, h
    if vb is not None:
        if w is not None:
            return w, w * vb[1] / vb[0]
        if h is not None:
            return h * vb[0] / vb[1], h
        return vb
    return (w or _SVG_DEFAULT_PX, h or _SVG_DEFAULT_PX)


def read_svg(path: Path, label: str = "SVG") -> str:
    """The text of an SVG file, decoded as XML says: the encoding its declaration names
    (``<?xml version="1.0" encoding="ISO-8859-1"?>``), else its byte-order mark, else
    UTF-8. The declaration is dropped from the text (it names bytes no longer there).

    Raises:
        TattotronixError: the file cannot be read, names an unknown encoding, or is not
            text in its encoding.
    """
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise TattotronixError(f"cannot read {label}: {_one_line(exc)}") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        encoding = "utf-16"
    elif raw.startswith(b"\xef\xbb\xbf"):
        encoding = "utf-8-sig"
    else:
        m = _XML_ENCODING.match(raw)
        encoding = m.group(1).decode("ascii") if m else "utf-8"
    try:
        text = raw.decode(encoding)
    except LookupError:
        raise TattotronixError(f"{label} declares an unknown encoding {encoding!r}; save it "
                               "as UTF-8") from None
    except UnicodeDecodeError as exc:
        raise TattotronixError(f"{label} is not a text SVG file: it is not {encoding} "
                               f"({_one_line(exc)}); fix its encoding declaration or save it "
                               "as UTF-8") from None
    return _XML_DECL.sub("", text, count=1)


def _is_internal(ref: str) -> bool:
    """A reference inside the SVG itself: ``#id``, or an embedded ``data:`` URI."""
    ref = ref.strip()
    return ref == "" or ref.startswith("#") or ref.lower().startswith("data:")


def svg_external_refs(text: str, label: str = "SVG") -> list[tuple[str, str]]:
    """Every reference of an SVG to something outside it, as ``(where, reference)``:
    ``("<image href>", "photo.png")`` (also ``xlink:href`` and ``src``), a CSS ``url(...)``
    or ``@import`` in any attribute (``style``, ``fill``, ...) or in a ``<style>`` element.
    ``#id`` references and ``data:`` URIs are internal and not listed.

    Raises:
        TattotronixError: the text is not well-formed XML.
    """
    root = _parse_svg(text, label)

    def css(where: str, value: str) -> list[tuple[str, str]]:
        refs = (m.group(2) if m.group(2) is not None else m.group(4)
                for m in _CSS_URL.finditer(value))
        return [(where, r.strip()) for r in refs if not _is_internal(r)]

    found: list[tuple[str, str]] = []
    for el in root.iter():
        if not isinstance(el.tag, str):
            continue
        tag = el.tag.rsplit("}", 1)[-1]
        for attr, value in el.attrib.items():
            where = f"<{tag} {attr.rsplit('}', 1)[-1]}>"
            if attr in _HREF_ATTRS and not _is_internal(value):
                found.append((where, value.strip()))
            found += css(where, value)
        if tag == "style" and el.text:
            found += css("<style>", el.text)
    return list(dict.fromkeys(found))


def _local_ref_target(ref: str, folder: Path) -> Path | None:
    """The file a reference names in ``folder`` (or below it), or None for a URL, an
    absolute path or a path that leaves the folder."""
    target = ref.split("#", 1)[0]
    if (not target or re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", target)
            or target.startswith(("/", "\\")) or Path(target).is_absolute()):
        return None
    path = (folder / target).resolve()
    return path if path.is_relative_to(folder.resolve()) else None


def _check_svg_refs(text: str, path: Path, label: str, local_files: bool) -> None:
    """Refuse an SVG's external references (see the module docstring)."""
    bad = []
    for where, ref in svg_external_refs(text, label):
        shown = f"{where} {ref!r}"
        if local_files:
            target = _local_ref_target(ref, path.parent)
            if target is not None and target.is_file():
                continue
            if target is not None:
                shown += " (no such file)"
        bad.append(shown)
    if not bad:
        return
    listed = ", ".join(bad[:_SHOWN_REFS]) + (
        f" and {len(bad) - _SHOWN_REFS} more" if len(bad) > _SHOWN_REFS else "")
    if local_files:
        fix = ("only files in the SVG's own folder are allowed (artwork.svg_local_files=true):"
               " move them there, or embed them as data: URIs")
    else:
        fix = ("embed them (data: URIs), or set artwork.svg_local_files=true to allow files "
               "in the SVG's own folder")
    raise TattotronixError(f"{label} refers to external files or URLs, which are not drawn: "
                           f"{listed}; {fix}")


TEXT_FONTS: tuple[str, str, str] = ("DejaVu Sans", "DejaVu Serif", "DejaVu Sans Mono")
"""The fonts resvg draws ``<text>`` with when it names no family or sans-serif, serif,
monospace (resvg's own defaults, Arial, Times New Roman and Courier New, are on few Linux
machines)."""

_SHOWN_TEXTS = 5  # <text> elements named in the log


def _dejavu_files() -> list[str]:
    """The DejaVu fonts matplotlib ships: always there, so ``<text>`` is drawn on a machine
    with no system fonts too (resvg draws nothing for text it has no font for)."""
    import matplotlib

    folder = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    return sorted(str(f) for f in folder.glob("DejaVu*.ttf"))


def _log_text(text: str, label: str) -> bool:
    """Whether an SVG has ``<text>``, which resvg draws with the system's fonts for a family
    it names, else DejaVu (:data:`TEXT_FONTS`, :func:`_dejavu_files`); the log
    names the elements, as they are drawn with this machine's fonts."""
    texts = [el for el in _parse_svg(text, label).iter()
             if isinstance(el.tag, str) and el.tag.rsplit("}", 1)[-1] == "text"]
    if not texts:
        return False
    ids = [el.get("id") or f"'{''.join(el.itertext()).strip()[:20]}'" for el in texts]
    shown = ", ".join(ids[:_SHOWN_TEXTS]) + (
        f" and {len(ids) - _SHOWN_TEXTS} more" if len(ids) > _SHOWN_TEXTS else "")
    log.info("%s: %d <text> element(s) (%s) drawn with this machine's fonts (DejaVu for "
             "a generic or unnamed family); for the designed letter shapes convert text to "
             "paths (Inkscape: Path > Object to Path)", label, len(texts), shown)
    return True


def _render_svg(
    path: Path, width_mm: float, res_mm: float, max_pixels: int, local_files: bool = False
) -> tuple[NDArray[np.float64], tuple[int, int], tuple[int, int], bool]:
    """Render an SVG at :data:`SVG_OVERSAMPLE` x the grid, average down to the grid; and
    whether its canvas is transparent anywhere."""
    import resvg_py

    label = f"artwork {path}"
    text = read_svg(path, label)
    size = svg_intrinsic_size(text, label)
    _check_svg_refs(text, path, label, local_files)
    out_h, out_w = grid_shape(size, width_mm, res_mm)
    render_w = SVG_OVERSAMPLE * out_w
    render_h = max(round(render_w * size[1] / size[0]), 1)
    _check_pixels(
        f"{label} rendered {width_mm:g} mm wide at {res_mm / SVG_OVERSAMPLE:g} mm/px",
        render_w, render_h, max_pixels,
        "check its width/height/viewBox, or raise artwork.max_pixels",
    )
    has_text = _log_text(text, label)
    sans, serif, mono = TEXT_FONTS if has_text else (None, None, None)
    try:
        png = resvg_py.svg_to_bytes(
            svg_string=text, width=render_w, dpi=CSS_DPI,
            resources_dir=str(path.parent) if local_files else None,
            font_files=_dejavu_files() if has_text else None,
            font_family=sans, sans_serif_family=sans, serif_family=serif,
            monospace_family=mono,
        )
    except (ValueError, RuntimeError, OSError) as exc:
        raise TattotronixError(
            f"{label} cannot be rendered: {_one_line(exc)}; fix or re-export the SVG"
        ) from None
    im, _ = _open_raster(io.BytesIO(bytes(png)), f"{label} (rendered)", max_pixels)
    hi = _to_grey(im)
    grey = cv2.resize(hi.astype(np.float32), (out_w, out_h), interpolation=cv2.INTER_AREA)
    return (grey.astype(np.float64), (round(size[0]), round(size[1])), (im.width, im.height),
            _has_transparency(im))


def _svg_grid(path: Path, label: str, width_mm: float | None, default_width_mm: float | None,
              res_mm: float, min_line_px: float, height_mm: float | None = None
              ) -> tuple[float, float]:
    """The drawn width and the grid pitch of an SVG, mm (:mod:`tattotronix.art.sizing`)."""
    text = read_svg(path, label)
    size = svg_intrinsic_size(text, label)
    width = drawing_width_mm(width_mm, default_width_mm, svg_physical_width_mm(text, label),
                             height_mm=height_mm, aspect=size[0] / size[1])
    if min_line_px <= 0:
        return width, res_mm
    strokes = svg_strokes(path, width / size[0])
    return width, grid_pitch_mm(res_mm, thinnest_stroke(strokes), min_line_px)


def _resample(grey: NDArray[np.float64], out_h: int, out_w: int) -> NDArray[np.float64]:
    """Bilinear when enlarging, area averaging when shrinking."""
    h, w = grey.shape
    shrink = out_w < w or out_h < h
    interp = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
    out = cv2.resize(grey.astype(np.float32), (out_w, out_h), interpolation=interp)
    return np.clip(out.astype(np.float64), 0.0, 255.0)


# ----------------------------------------------------------------------------- entry


def load_artwork(
    source: str | Path | None,
    width_mm: float | None,
    res_mm: float,
    max_pixels: int,
    name: str | None = None,
    *,
    svg_local_files: bool = False,
    default_width_mm: float | None = None,
    min_line_px: float = 0.0,
    height_mm: float | None = None,
) -> Artwork:
    """Read an artwork and put it on the mask grid.

    Args:
        source: a PNG, JPG or SVG path; a built-in name (``emblem``, ``portrait``); or
            None for the built-in emblem.
        width_mm: drawing width, mm; None: an SVG's own physical width, else
            ``default_width_mm`` (:func:`tattotronix.art.sizing.drawing_width_mm`).
        res_mm: the coarsest mask grid pitch, mm per pixel; an SVG whose thinnest stroke
            spans fewer than ``min_line_px`` pixels gets a finer one
            (:func:`tattotronix.art.sizing.grid_pitch_mm`). :attr:`Artwork.res_mm` is the
            pitch used.
        max_pixels: refuse sources (and SVG renderings, and grids) with more pixels.
        name: output name; default the source's stem.
        svg_local_files: an SVG may refer to files in its own folder (``<image
            href="photo.png">``); by default any external reference is refused.
        default_width_mm: the width of an artwork with no physical size of its own
            (``mask.default_width_mm``; needed when ``width_mm`` is None).
        min_line_px: the fewest pixels a stroked line may span (0: never refine).
        height_mm: the drawing's height instead of ``width_mm`` (not both), mm.

    Returns:
        The grey raster on the grid.

    Raises:
        TattotronixError: a missing, unsupported, corrupt, oversized or non-image file,
            an SVG that does not parse or refers to external files; :class:`NoInkError` for
            a flat image.
    """
    path = resolve_source(source)
    label = f"artwork {path}"
    if path.is_dir():
        raise TattotronixError(f"{label} is a directory: give a PNG, JPG or SVG file")
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise TattotronixError(
            f"unsupported artwork type '{path.suffix or '(none)'}' for {path}: "
            "give a PNG, JPG or SVG file"
        )
    if suffix in SVG_SUFFIXES:
        width_mm, res_mm = _svg_grid(path, label, width_mm, default_width_mm, res_mm,
                                     min_line_px, height_mm)
        grey, original_px, render_px, transparent = _render_svg(
            path, width_mm, res_mm, max_pixels, svg_local_files)
        kind = "svg"
    else:
        im, fmt = _open_raster(path, label, max_pixels)
        width_mm = drawing_width_mm(width_mm, default_width_mm, height_mm=height_mm,
                                    aspect=im.width / im.height)
        kind = fmt or suffix.lstrip(".")
        original_px, render_px = (im.width, im.height), None
        transparent = _has_transparency(im)
        out_h, out_w = grid_shape(original_px, width_mm, res_mm)
        _check_pixels(
            f"the grid for {label} ({width_mm:g} mm at {res_mm:g} mm/px)",
            out_w, out_h, max_pixels, "lower mask.width_mm or raise mask.res_mm",
        )
        grey = _resample(_to_grey(im), out_h, out_w)
    lo, hi = float(grey.min()), float(grey.max())
    if hi - lo < FLAT_TONE_LEVELS:
        raise NoInkError(
            f"{label} has no drawable ink: at {width_mm:g} mm wide and {res_mm:g} mm/px it "
            f"is one flat tone (grey {lo:.0f}..{hi:.0f}); give an image with a drawing in it"
        )
    art = Artwork(
        grey=grey,
        res_mm=float(res_mm),
        name=name or path.stem,
        source=_source_label(path),
        kind=kind,
        original_px=original_px,
        render_px=render_px,
        transparent=transparent,
    )
    w_mm, h_mm = art.size_mm
    log.info(
        "artwork %s: %s %d x %d px -> %d x %d px grid, %.1f x %.1f mm",
        art.name, kind, *original_px, art.shape[1], art.shape[0], w_mm, h_mm,
    )
    return art


@dataclass(frozen=True)
class ArtworkGrid:
    """What the mask stage needs of the artwork stage's choices (its metrics file).

    Attributes:
        res_mm: the grid pitch, mm. transparent: :attr:`Artwork.transparent`.
    """

    res_mm: float
    transparent: bool


def artwork_grid(metrics: Path, shape: tuple[int, ...]) -> ArtworkGrid:
    """The grid the artwork stage chose for a raster of ``shape``, read from its metrics
    file (``res_mm``, ``raster_px`` and ``transparent``): the one record of it.

    Raises:
        TattotronixError: the metrics are unreadable or do not describe this raster (the
            message says to re-run the ``artwork`` stage).
    """
    import json

    fix = "re-run the 'artwork' stage"
    try:
        rec = json.loads(metrics.read_text(encoding="utf-8"))
        res_mm, (w, h) = float(rec["res_mm"]), rec["raster_px"]
        transparent = bool(rec.get("transparent", False))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise TattotronixError(f"cannot read the artwork's grid from {metrics} "
                               f"({_one_line(exc)}): {fix}") from None
    if (int(h), int(w)) != tuple(shape[:2]) or not res_mm > 0:
        raise TattotronixError(f"the artwork raster is {shape[1]} x {shape[0]} px but "
                               f"{metrics} records {w} x {h} px: {fix}")
    return ArtworkGrid(res_mm, transparent)
