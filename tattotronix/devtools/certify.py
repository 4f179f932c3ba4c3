"""Certify the documents: every figure traced to data, every local link resolves.

The documents are ``README.md`` and every ``docs/**/*.md`` under the project root. The
check fails when

* a **figure** (a number directly followed by one of the units ``um``/``µm``, ``mm``,
  ``mm/s``, ``N m``/``N·m``/``Nm``, ``%``, ``s``) cannot be traced, at its written
  precision, to a number in a metrics file (``data/metrics/**/*.json``) or in
  ``params.yaml``, and no exemption with a reason covers it;
* an **exemption** (``docs/certify.yaml``) has no reason, or names no figure of its
  document ("no longer needed"); one whose figure now traces everywhere is a *note*
  (``CertifyReport.notes``), not a failure: a new metric can match a quoted number by
  chance;
* a **local link or image** (``[t](x)``, ``![a](x)``, ``[r]: x``, ``<img src="x">``,
  ``<a href="x">``) names a missing file (relative to the document's folder, ``/x``
  from the project root; ``?query`` and ``#anchor`` stripped) or a file outside the
  project, or a ``#anchor`` that is no heading of the markdown file it points at
  (GitHub's slugs: lower-case, punctuation but ``-`` and ``_`` dropped, spaces to
  ``-``, repeats ``-1``, ``-2``). ``http(s)://``, ``mailto:`` and other scheme links
  are not checked (no network). With ``allow_dvc_outputs``, a missing target that a
  stage of dvc.yaml/dvc.lock declares as an output counts as present.

Traceability rule
-----------------
A figure written ``W`` with ``k`` decimals (``Decimal(W).as_tuple().exponent == -k``;
thousands separators removed) is *traced* by a source value ``v`` when ``|v|`` rounded
to ``k`` decimals equals ``|W|`` under any of

1. ``Decimal(repr(v))`` (the shortest decimal that round-trips ``v``), ``ROUND_HALF_UP``
   (a person rounding the printed value);
2. the same, ``ROUND_HALF_EVEN``;
3. ``Decimal(v)`` (the exact binary value), ``ROUND_HALF_EVEN`` (what Python's
   ``format(v, '.kf')`` and ``round`` write).

Magnitudes are compared (a figure's sign is prose: "-9.444" and "9.444 below" are both
fine). A ``%`` figure is also traced by a fraction ``f`` when ``100 f`` matches (ink IoU
0.9963 -> "99.6 %"). No other unit scaling: a figure in mm is not traced by the same
length in metres; such a figure needs an exemption that says so.

What is not read as a figure: fenced code blocks (````` and ``~~~``), inline code spans,
HTML comments, HTML tags, link targets and bare URLs. Indented code blocks are read as
prose (they cannot be told from list continuations without a full markdown parser).
The unit ``s`` must be separated from its number by a space ("12 s", not "1990s").
Numbers joined by ``/``, ``to``, ``–``, ``..``, ``…``, ``, `` or ``and`` just before a
unit share it ("2.01 / 51.5 µm"), as do the numbers of a parenthesised tuple
("(258.96, -9.444, 245.5775) mm").

Exemptions
----------
``docs/certify.yaml``::

    exemptions:
      - document: README.md       # path from the project root
        figure: "300 µm"          # the figure as written (whitespace normalised)
        reason: "the original's line width; no metric records it"

      ignore_sources:
      - file: "data/metrics/*"    # glob on the file's path (``*`` crosses ``/`` and ``.``)
        key: "*solve_s"           # glob on the key path inside it
        reason: "wall-clock times change between identical runs"

A figure is matched by its number as written and its unit (``um``/``µm`` and the
``N m`` spellings are one unit each). Every occurrence of that figure in the document is
exempted. ``ignore_sources`` takes numbers out of the sources (wall-clock times would
make certification depend on the machine); a rule that matches no number fails too.
An entry without a reason, or with an unknown key, is a failure.

When several sources trace a figure, the report names one: an exact value before a
rounded one, a key naming the unit (``_um``, ``_mm``, ``_s``, ``torque``, ``pct``)
before others, a metrics file before params.yaml.
"""

from __future__ import annotations

import json
import math
import os
import re
import unicodedata
from collections.abc import Iterator
from dataclasses import dataclass
from decimal import (
    ROUND_HALF_EVEN,
    ROUND_HALF_UP,
    Decimal,
    InvalidOperation,
    localcontext,
)
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import yaml

from tattotronix.io.jsontypes import JsonDict

__all__ = [
    "EXEMPTIONS_FILE",
    "EXPERIMENT_ENV",
    "METRICS_DIR",
    "OUTPUT_NAME",
    "PARAMS_FILE",
    "UNITS",
    "CertifyReport",
    "Exempted",
    "Exemption",
    "Failure",
    "Figure",
    "IgnoreRule",
    "Link",
    "Source",
    "Sources",
    "Traced",
    "certify",
    "document_paths",
    "dvc_outputs",
    "extract_figures",
    "extract_links",
    "heading_slugs",
    "load_sources",
    "source_rank",
]

EXEMPTIONS_FILE = "docs/certify.yaml"
METRICS_DIR = "data/metrics"
PARAMS_FILE = "params.yaml"
#: The certify stage's own metrics file: never a source (it would trace its own counts).
OUTPUT_NAME = "certify.json"
#: set by ``dvc exp run`` (and only there): the git revision an experiment starts from;
#: inside one, the certify stage records the drift instead of failing (stages/certify.py)
EXPERIMENT_ENV = "DVC_EXP_BASELINE_REV"

#: Canonical unit for every spelling the extractor accepts.
UNITS = {
    "um": "µm", "µm": "µm", "μm": "µm", "mm": "mm", "mm/s": "mm/s", "%": "%", "s": "s",
    "N m": "N·m", "N·m": "N·m", "N⋅m": "N·m", "Nm": "N·m",
}

# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class Figure:
    """A number with a unit, as written in a document."""

    document: str   # path from the project root, posix
    line: int       # 1-based
    text: str       # "<number> <unit>" as written, whitespace normalised
    number: str     # the number as written (whitespace normalised)
    value: Decimal  # the number (separators removed, sign kept)
    decimals: int   # digits after the point (0 for integers)
    unit: str       # canonical unit (see UNITS)
    context: str    # the whole written chain, e.g. "2.01 / 51.5 um"

    @property
    def magnitude(self) -> Decimal:
        return abs(self.value)

    @property
    def exponent(self) -> int:
        exp = self.value.as_tuple().exponent
        assert isinstance(exp, int)
        return exp


@dataclass(frozen=True)
class Source:
    """A number in a metrics file or params.yaml, and where it is."""

    file: str   # path from the project root, posix
    key: str    # "loop.kp[0]"
    value: float | int

    def __str__(self) -> str:
        return f"{self.file} {self.key} = {self.value!r}"


@dataclass(frozen=True)
class Traced:
    """A figure and the source value that rounds to it."""

    figure: Figure
    source: Source
    from_fraction: bool = False   # a % figure traced by 100 x a fraction


@dataclass(frozen=True)
class Exemption:
    """One entry of docs/certify.yaml."""

    document: str
    figure: str
    reason: str
    line: int               # line of the entry in the exemption file
    key: tuple[str, str]    # (number as written, canonical unit)


@dataclass(frozen=True)
class IgnoreRule:
    """An entry of ``ignore_sources`` in docs/certify.yaml: source numbers that must not
    trace a figure (wall-clock times, which change between identical runs)."""

    file: str   # glob on the file's path from the root (``*`` matches across ``/``)
    key: str    # glob on the key path, e.g. ``timing.*`` or ``*solve_s``
    reason: str
    line: int

    def matches(self, src: Source) -> bool:
        return fnmatchcase(src.file, self.file) and fnmatchcase(src.key, self.key)


@dataclass(frozen=True)
class Exempted:
    """A figure that is not traced, and the exemption that covers it."""

    figure: Figure
    exemption: Exemption


@dataclass(frozen=True)
class Link:
    """A link or image target in a document."""

    document: str
    line: int
    target: str
    kind: str   # "link", "image", "reference", "html"


@dataclass(frozen=True)
class Failure:
    """One reason the documents do not pass."""

    document: str
    line: int
    text: str
    why: str

    def __str__(self) -> str:
        return f"{self.document}:{self.line}: {self.text}: {self.why}"


@dataclass(frozen=True)
class CertifyReport:
    """What :func:`certify` found. ``ok`` when there is no failure."""

    root: Path
    documents: tuple[str, ...]
    figures: tuple[Figure, ...]
    traced: tuple[Traced, ...]
    exempted: tuple[Exempted, ...]
    links: tuple[Link, ...]          # local targets checked
    external_links: int              # http(s), mailto, ... (not checked)
    sources: int                     # numbers in the metrics files and params.yaml
    sources_ignored: int             # of those, the ones ignore_sources set aside
    failures: tuple[Failure, ...]
    #: exemptions whose figure now traces everywhere (a new metric may match a quoted
    #: number by chance, so this is a note to look at, not a failure)
    notes: tuple[Failure, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.failures

    def summary(self) -> JsonDict:
        """Counts for the metrics JSON (nothing that changes between identical runs)."""
        per_doc: dict[str, dict[str, int]] = {
            d: {"figures": 0, "traced": 0, "exempted": 0, "links": 0, "failures": 0}
            for d in self.documents
        }
        for f in self.figures:
            per_doc[f.document]["figures"] += 1
        for t in self.traced:
            per_doc[t.figure.document]["traced"] += 1
        for e in self.exempted:
            per_doc[e.figure.document]["exempted"] += 1
        for link in self.links:
            per_doc[link.document]["links"] += 1
        for fail in self.failures:
            if fail.document in per_doc:
                per_doc[fail.document]["failures"] += 1
        return {
            "documents": len(self.documents),
            "figures": len(self.figures),
            "traced": len(self.traced),
            "traced_from_fraction": sum(t.from_fraction for t in self.traced),
            "exempted": len(self.exempted),
            "links": len(self.links),
            "external_links": self.external_links,
            "sources": self.sources,
            "sources_ignored": self.sources_ignored,
            "failures": len(self.failures),
            "notes": len(self.notes),
            "per_document": per_doc,
        }

    def format(self) -> str:
        """A human-readable report: one line of counts, then one line per failure."""
        s = self.summary()
        head = (f"{s['documents']} document(s), {s['figures']} figure(s) ({s['traced']} "
                f"traced, {s['exempted']} exempted), {s['links']} local link(s)")
        if self.ok:
            return f"{head}: all certified"
        lines = [f"{len(self.failures)} failure(s) in {head}:"]
        lines += [f"  {f}" for f in self.failures]
        return "\n".join(lines)

    def drift_summary(self, examples: int = 3, width: int = 100) -> str:
        """What no longer matches, for a person inside an experiment: a count per document
        and the first few figures, each line at most ``width`` characters (the whole list
        is :meth:`format`, and certify.json's ``drift``)."""
        if self.ok:
            return self.format()
        per_doc: dict[str, int] = {}
        for f in self.failures:
            per_doc[f.document] = per_doc.get(f.document, 0) + 1
        counts = ", ".join(f"{doc} {n}" for doc, n in per_doc.items())
        lines = [_clip(f"{len(self.failures)} documented figure(s) or link(s) no longer "
                       f"match ({counts})", width)]
        lines += [_clip(f"  {f.document}:{f.line}: {f.text}: {f.why.split(':')[0]}", width)
                  for f in self.failures[:examples]]
        if len(self.failures) > examples:
            lines.append(f"  ... and {len(self.failures) - examples} more")
        return "\n".join(lines)


def _clip(line: str, width: int) -> str:
    return line if len(line) <= width else line[:width - 3] + "..."


# --------------------------------------------------------------------------- masking

_MASK = "\x00"


def _blank(text: str) -> str:
    """Same length and line breaks, nothing readable."""
    return re.sub(r"[^\n]", _MASK, text)


def _splice(text: str, spans: list[tuple[int, int]]) -> str:
    if not spans:
        return text
    parts, pos = [], 0
    for a, b in sorted(spans):
        if a < pos:
            a = pos
        if b <= a:
            continue
        parts += [text[pos:a], _blank(text[a:b])]
        pos = b
    parts.append(text[pos:])
    return "".join(parts)


_FENCE_OPEN = re.compile(r"^ {0,3}(`{3,}|~{3,})(.*)$")


def _mask_fences(text: str) -> str:
    """Blank every fenced code block (fence lines included)."""
    out: list[str] = []
    fence: str | None = None
    for line in text.splitlines(keepends=True):
        body = line.rstrip("\r\n")
        if fence is None:
            m = _FENCE_OPEN.match(body)
            if m and not (m.group(1)[0] == "`" and "`" in m.group(2)):
                fence = m.group(1)
                out.append(_blank(line))
                continue
            out.append(line)
        else:
            close = re.match(r"^ {0,3}(`{3,}|~{3,})[ \t]*$", body)
            if close and close.group(1)[0] == fence[0] and len(close.group(1)) >= len(fence):
                fence = None
            out.append(_blank(line))
    return "".join(out)


_COMMENT_OR_TICKS = re.compile(r"<!--|`+")
_BLANK_LINE = re.compile(r"\n[ \t\x00]*\n")


def _comment_and_code_spans(text: str) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """HTML comments and inline code spans, scanned left to right (CommonMark-ish)."""
    comments: list[tuple[int, int]] = []
    codes: list[tuple[int, int]] = []
    pos = 0
    while True:
        m = _COMMENT_OR_TICKS.search(text, pos)
        if not m:
            break
        if m.group() == "<!--":
            end = text.find("-->", m.end())
            end = len(text) if end < 0 else end + 3
            comments.append((m.start(), end))
            pos = end
            continue
        n = len(m.group())
        close = re.compile(rf"(?<!`)`{{{n}}}(?!`)").search(text, m.end())
        if close and not _BLANK_LINE.search(text, m.end(), close.start()):
            codes.append((m.start(), close.end()))
            pos = close.end()
        else:
            pos = m.end()
    return comments, codes


# --------------------------------------------------------------------------- links

_LINK = re.compile(
    r"(?P<bang>!?)\[(?P<text>(?:[^\[\]\\]|\\.|\[(?:[^\[\]\\]|\\.)*\])*)\]"
    r"\((?P<dest>[ \t]*\n?[ \t]*(?:<[^<>\n]*>|[^\s()<>]*(?:\([^\s()]*\)[^\s()<>]*)*)"
    r"(?:[ \t]*\n?[ \t]+(?:\"[^\"\n]*\"|'[^'\n]*'|\([^()\n]*\)))?[ \t]*\n?[ \t]*)\)"
)
_REFDEF = re.compile(r"^ {0,3}\[(?!\^)(?:[^\]\\]|\\.)+\]:[ \t]*(?P<dest><[^<>\n]*>|\S+)", re.M)
_HTML_ATTR = re.compile(
    r"<(?P<tag>img|a|source)\b[^>]*?\b(?:src|href)\s*=\s*"
    r"(?:\"(?P<d>[^\"]*)\"|'(?P<s>[^']*)'|(?P<u>[^\s>]+))",
    re.I,
)
_HTML_TAG = re.compile(r"</?[A-Za-z][A-Za-z0-9-]*(?:\s[^<>]*)?/?>")
_AUTOLINK = re.compile(r"<[A-Za-z][A-Za-z0-9+.-]*:[^<>\s]*>")
_BARE_URL = re.compile(r"\b(?:[A-Za-z][A-Za-z0-9+.-]*://|mailto:|www\.)[^\s<>()\[\]`]*")
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def _dest_target(dest: str) -> str:
    dest = dest.strip()
    if dest.startswith("<"):
        return dest[1:dest.index(">")] if ">" in dest else dest[1:]
    return dest.split()[0] if dest else ""


def _line_at(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _inline_links(text: str, start: int = 0,
                  end: int | None = None) -> Iterator[re.Match[str]]:
    """Inline links and images, the ones nested in a link's text included."""
    for m in _LINK.finditer(text, start, len(text) if end is None else end):
        yield m
        yield from _inline_links(text, m.start("text"), m.end("text"))


def _links_and_url_spans(coded: str, document: str) -> tuple[list[Link], list[tuple[int, int]]]:
    """Every link target in ``coded`` (code and comments already blanked), and the spans
    to blank before reading figures (link targets, URLs, HTML tags)."""
    links: list[Link] = []
    spans: list[tuple[int, int]] = []
    for m in _inline_links(coded):
        target = _dest_target(m.group("dest"))
        kind = "image" if m.group("bang") else "link"
        links.append(Link(document, _line_at(coded, m.start()), target, kind))
        spans.append(m.span("dest"))
    for m in _REFDEF.finditer(coded):
        links.append(Link(document, _line_at(coded, m.start()),
                          _dest_target(m.group("dest")), "reference"))
        spans.append((m.start(), m.end()))
    for m in _HTML_ATTR.finditer(coded):
        target = next(g for g in (m.group("d"), m.group("s"), m.group("u")) if g is not None)
        links.append(Link(document, _line_at(coded, m.start()), target.strip(), "html"))
    for rx in (_HTML_TAG, _AUTOLINK, _BARE_URL):
        spans += [m.span() for m in rx.finditer(coded)]
    links.sort(key=lambda k: k.line)
    return links, spans


def extract_links(text: str, document: str = "") -> list[Link]:
    """Every link, image, reference definition and HTML src/href target in ``text``
    (outside code and HTML comments)."""
    fenced = _mask_fences(text)
    comments, codes = _comment_and_code_spans(fenced)
    return _links_and_url_spans(_splice(fenced, comments + codes), document)[0]


def _github_slug(heading: str) -> str:
    """GitHub's heading id: lower-case, punctuation dropped (``-`` and ``_`` kept),
    each space a hyphen."""
    t = re.sub(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\([^)]*\)", r"\1", heading)  # links -> text
    t = re.sub(r"<[^>]+>", "", t).strip().lower()
    out = []
    for ch in t:
        if ch == " ":
            out.append("-")
        elif ch in "-_" or unicodedata.category(ch)[0] in "LNM":
            out.append(ch)
    return "".join(out)


_ATX = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
_SETEXT = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
_HTML_ID = re.compile(r"<[A-Za-z][^>]*?\b(?:id|name)\s*=\s*[\"']([^\"']+)[\"']", re.I)


def heading_slugs(text: str) -> set[str]:
    """The anchors a markdown file offers: its headings' GitHub slugs (``-1``, ``-2`` for
    repeats) and any HTML ``id``/``name`` attribute."""
    fenced = _mask_fences(text)
    comments, _ = _comment_and_code_spans(fenced)
    visible = _splice(fenced, comments)
    occurrences: dict[str, int] = {}
    slugs: set[str] = set()

    def add(title: str) -> None:
        base = result = _github_slug(title)
        while result in occurrences:
            occurrences[base] += 1
            result = f"{base}-{occurrences[base]}"
        occurrences[result] = 0
        slugs.add(result)

    lines = visible.splitlines()
    for i, line in enumerate(lines):
        m = _ATX.match(line)
        if m:
            add(m.group(2) or "")
            continue
        prev = lines[i - 1] if i else ""
        if (i and _SETEXT.match(line) and prev.strip() and _MASK not in prev
                and not _ATX.match(prev) and not _SETEXT.match(prev)
                and not prev.lstrip().startswith(("|", ">", "-", "*", "+"))):
            add(prev.strip())
    slugs.update(m.group(1) for m in _HTML_ID.finditer(visible))
    return slugs


# --------------------------------------------------------------------------- figures

_WS = "[ \\t\u00a0\u2009\u202f]"
_GAP0 = f"{_WS}*(?:\\n{_WS}*)?"                  # optional space, at most one line break
_GAP1 = f"(?:{_WS}+(?:\\n{_WS}*)?|\\n{_WS}*)"     # some space, at most one line break
_NUM = (
    r"(?<!\w)(?<!\w\.)[-\u2212]?"
    r"(?:[1-9]\d{0,2}(?:[ \u00a0\u2009\u202f]\d{3})+(?!\d)"   # 29 593 (space, thin space)
    r"|[1-9]\d{0,2}(?:,\d{3})+(?!\d)"                       # 16,656
    r"|\d+)"
    r"(?:\.\d+)?(?:[eE][-+\u2212]?\d+)?"
)
_SEP = (f"(?:{_GAP0}(?:/|\u2013|\u2014|\\.\\.\\.?|\u2026){_GAP0}"   # / – — .. ... …
        f"|,{_GAP1}(?:and{_GAP1})?"                              # ", "  ", and "
        f"|{_GAP1}(?:to|and){_GAP1})")                            # " to "  " and "
_CHAIN = f"{_NUM}(?:{_SEP}{_NUM})*+"   # possessive: a chain is read whole, once
_UNIT = ("(?:(?P<unit>mm/s|mm|[µμ]m|um|N(?:[ \u00a0\u2009\u202f]|[·⋅])?m|%)"
         "|(?<=[ \t\n\u00a0\u2009\u202f])(?P<sec>s))(?![\\w/])")
_CHAINS = re.compile(f"\\((?P<paren>{_CHAIN}){_GAP0}\\)|(?P<chain>{_CHAIN})")
_UNIT_AFTER = re.compile(f"{_GAP0}{_UNIT}")
_NUM_RX = re.compile(_NUM)


def _norm_ws(text: str) -> str:
    return re.sub(r"[\s\u00a0\u2009\u202f]+", " ", text).strip()


def _figure_key(fig: Figure) -> tuple[str, str]:
    return fig.number.replace("\u2212", "-").lstrip("-"), fig.unit


def _figures_in(masked: str, document: str) -> list[Figure]:
    figures = []
    # Chains are found first, left to right and each read once (linear time); a chain is
    # a figure when a unit follows it.
    for m in _CHAINS.finditer(masked):
        u = _UNIT_AFTER.match(masked, m.end())
        if u is None:
            continue
        unit_text = _norm_ws(u.group("unit") or u.group("sec"))
        unit = UNITS[unit_text]
        group = "paren" if m.group("paren") is not None else "chain"
        base = m.start(group)
        context = _norm_ws(masked[m.start():u.end()])
        for n in _NUM_RX.finditer(m.group(group)):
            number = _norm_ws(n.group())
            plain = re.sub(r"[\s,\u00a0\u2009\u202f]", "", n.group()).replace("\u2212", "-")
            try:
                value = Decimal(plain)
            except InvalidOperation:  # pragma: no cover - the regex admits only numbers
                continue
            exp = value.as_tuple().exponent
            assert isinstance(exp, int)
            figures.append(Figure(
                document=document, line=_line_at(masked, base + n.start()),
                text=f"{number} {unit_text}", number=number, value=value,
                decimals=max(0, -exp), unit=unit, context=context))
    return figures


def extract_figures(text: str, document: str = "") -> list[Figure]:
    """Every figure (number + unit) in a markdown text, outside code, comments, HTML tags,
    link targets and URLs."""
    return _read_document(text, document)[0]


def _read_document(text: str, document: str) -> tuple[list[Figure], list[Link]]:
    fenced = _mask_fences(text)
    comments, codes = _comment_and_code_spans(fenced)
    coded = _splice(fenced, comments + codes)
    links, spans = _links_and_url_spans(coded, document)
    return _figures_in(_splice(coded, spans), document), links


# --------------------------------------------------------------------------- sources

_FLOAT_TEXT = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")


def _numbers(node: Any, prefix: str = "", *, yaml_strings: bool = False
             ) -> Iterator[tuple[str, float | int]]:
    """Every finite number in a JSON/YAML tree with its key path (booleans are not).
    ``yaml_strings``: also a string that is a float literal, which YAML 1.1 leaves a
    string ("1e-06")."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _numbers(v, f"{prefix}.{k}" if prefix else str(k),
                                yaml_strings=yaml_strings)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _numbers(v, f"{prefix}[{i}]", yaml_strings=yaml_strings)
    elif isinstance(node, bool):
        return
    elif isinstance(node, int):
        yield prefix, node
    elif isinstance(node, float):
        if math.isfinite(node):
            yield prefix, node
    elif yaml_strings and isinstance(node, str) and _FLOAT_TEXT.match(node.strip()):
        # YAML 1.1 reads "1e-06" as a string; it is still a configured number
        value = float(node)
        if math.isfinite(value):
            yield prefix, value


_UNIT_HINTS = {
    "µm": ("_um",), "mm": ("_mm",), "mm/s": ("mm_s",), "s": ("_s",),
    "N·m": ("_nm", "torque", "effort"), "%": ("pct", "percent"),
}


def _names_unit(key: str, hints: tuple[str, ...]) -> bool:
    """Whether a key path names a unit (``settled_mean_um``, ``peak_torque_nm``)."""
    low = key.lower()
    return any(re.search(re.escape(h) + "(?![a-z0-9])", low) for h in hints)


def source_rank(fig: Figure, src: Source, scaled: bool) -> tuple[bool, bool, bool, bool]:
    """How well ``src`` explains ``fig`` (lower first): an exact value before a rounded
    one, a key naming the unit before others, a metrics file before params.yaml, the value
    itself before a fraction read as a ``%``."""
    exact = abs(Decimal(repr(src.value))) * (100 if scaled else 1) == fig.magnitude
    hinted = _names_unit(src.key, _UNIT_HINTS.get(fig.unit, ()))
    return not exact, not hinted, src.file == PARAMS_FILE, scaled


class Sources:
    """Numbers from the metrics files and params.yaml, indexed by rounded magnitude."""

    def __init__(self, items: list[Source]):
        self.items = tuple(items)
        self._index: dict[tuple[int, bool], dict[Decimal, list[Source]]] = {}

    def __len__(self) -> int:
        return len(self.items)

    @staticmethod
    def _rounded(v: float | int, exponent: int, scale: int) -> set[Decimal]:
        quantum = Decimal((0, (1,), exponent))
        out: set[Decimal] = set()
        with localcontext() as ctx:
            ctx.prec = 120
            try:
                if isinstance(v, int):
                    return {(abs(Decimal(v)) * scale).quantize(quantum, ROUND_HALF_UP)}
                shortest = abs(Decimal(repr(v))) * scale
                exact = abs(Decimal(v)) * scale
                out.add(shortest.quantize(quantum, ROUND_HALF_UP))
                out.add(shortest.quantize(quantum, ROUND_HALF_EVEN))
                out.add(exact.quantize(quantum, ROUND_HALF_EVEN))
            except InvalidOperation:  # too large for the quantum
                return set()
        return out

    def _table(self, exponent: int, fraction: bool) -> dict[Decimal, list[Source]]:
        key = (exponent, fraction)
        if key not in self._index:
            table: dict[Decimal, list[Source]] = {}
            for src in self.items:
                for r in self._rounded(src.value, exponent, 100 if fraction else 1):
                    table.setdefault(r, []).append(src)
            self._index[key] = table
        return self._index[key]

    def candidates(self, fig: Figure) -> list[tuple[Source, bool]]:
        """Every source that rounds to ``fig``, each with whether it is a fraction read as
        a ``%`` (100 x the value)."""
        found = [(s, False) for s in self._table(fig.exponent, False).get(fig.magnitude, [])]
        if fig.unit == "%":
            found += [(s, True) for s in self._table(fig.exponent, True).get(
                fig.magnitude, [])]
        return found

    def trace(self, fig: Figure) -> Traced | None:
        """The source that rounds to ``fig`` (preferring one whose key names the unit)."""
        candidates = self.candidates(fig)
        if not candidates:
            return None
        src, scaled = min(candidates, key=lambda c: source_rank(fig, *c))
        return Traced(fig, src, scaled)

    def closest(self, fig: Figure) -> Source | None:
        """The source nearest in magnitude (a hint for an untraced figure), among those
        whose key names the figure's unit (``_um``, ``_mm``, ...) when there are any."""
        target = float(fig.magnitude)
        hints = _UNIT_HINTS.get(fig.unit, ())
        best: tuple[bool, float, Source] | None = None
        for src in self.items:
            hinted = _names_unit(src.key, hints)
            for scale in ((1.0, 100.0) if fig.unit == "%" else (1.0,)):
                cand = (not hinted, abs(abs(float(src.value)) * scale - target), src)
                if best is None or cand[:2] < best[:2]:
                    best = cand
        return None if best is None else best[2]


def _rel(path: Path, root: Path) -> str:
    try:
        return path.relative_to(root).as_posix()
    except ValueError:
        return path.as_posix()


def load_sources(root: Path, metrics_dir: Path | None = None
                 ) -> tuple[Sources, list[Failure]]:
    """Every number in ``<metrics_dir>/**/*.json`` (default ``data/metrics``; the certify
    stage's own ``certify.json`` excluded) and in ``params.yaml``; unreadable files are
    failures."""
    root = Path(root)
    metrics = root / METRICS_DIR if metrics_dir is None else root / metrics_dir
    items: list[Source] = []
    failures: list[Failure] = []
    files = sorted(p for p in metrics.rglob("*.json") if p.is_file()) if metrics.is_dir() \
        else []
    for path in files:
        if path.parent == metrics and path.name == OUTPUT_NAME:
            continue
        rel = _rel(path, root)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            failures.append(Failure(rel, 1, path.name, f"cannot read the metrics file: {exc}"))
            continue
        items += [Source(rel, key, v) for key, v in _numbers(data)]
    params = root / PARAMS_FILE
    if params.is_file():
        try:
            data = yaml.safe_load(params.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as exc:
            failures.append(Failure(PARAMS_FILE, 1, PARAMS_FILE, f"cannot read it: {exc}"))
        else:
            items += [Source(PARAMS_FILE, key, v)
                      for key, v in _numbers(data, yaml_strings=True)]
    return Sources(items), failures


# --------------------------------------------------------------------------- exemptions


def _entry_lines(node: Any, name: str, count: int) -> list[int]:
    """The line of each item of the top-level list ``name`` (1 when unknown)."""
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            if k.value == name and isinstance(v, yaml.SequenceNode) and len(v.value) == count:
                return [item.start_mark.line + 1 for item in v.value]
    return [1] * count


def _load_exemptions(root: Path) -> tuple[list[Exemption], list[IgnoreRule], list[Failure]]:
    """Read docs/certify.yaml: ``exemptions`` and ``ignore_sources``; problems are failures."""
    path = root / EXEMPTIONS_FILE
    if not path.is_file():
        return [], [], []
    text = path.read_text(encoding="utf-8")
    fail: list[Failure] = []
    try:
        node = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        return [], [], [Failure(EXEMPTIONS_FILE, 1, "exemptions", f"not valid YAML: {exc}")]
    if data is None:
        return [], [], []
    allowed = {"exemptions", "ignore_sources"}
    if (not isinstance(data, dict) or not set(data) <= allowed
            or not all(isinstance(v, list | None) for v in data.values())):
        return [], [], [Failure(EXEMPTIONS_FILE, 1, "exemptions",
                                "the file holds `exemptions:` (a list of {document, figure, "
                                "reason}) and optionally `ignore_sources:` (a list of "
                                "{file, key, reason})")]

    def entries(name: str, keys: set[str]) -> Iterator[tuple[dict[str, str], int]]:
        items = data.get(name) or []
        for entry, line in zip(items, _entry_lines(node, name, len(items)), strict=True):
            if not isinstance(entry, dict):
                fail.append(Failure(EXEMPTIONS_FILE, line, str(entry),
                                    f"an entry of `{name}` is a mapping {sorted(keys)}"))
                continue
            unknown = set(map(str, entry)) - keys
            if unknown:
                fail.append(Failure(EXEMPTIONS_FILE, line, str(entry),
                                    f"unknown key(s) {sorted(unknown)}; allowed: "
                                    f"{', '.join(sorted(keys))}"))
            yield {k: _norm_ws(str(entry.get(k) or "")) for k in keys}, line

    out: list[Exemption] = []
    seen: set[tuple[str, tuple[str, str]]] = set()
    for e, line in entries("exemptions", {"document", "figure", "reason"}):
        label = f"{e['document'] or '?'}: {e['figure'] or '?'}"
        if not e["document"] or not e["figure"]:
            fail.append(Failure(EXEMPTIONS_FILE, line, label,
                                "an exemption needs `document` and `figure`"))
            continue
        figs = extract_figures(e["figure"])
        if len(figs) != 1:
            fail.append(Failure(EXEMPTIONS_FILE, line, label,
                                "`figure` must be one number with a unit, as written"))
            continue
        ex = Exemption(e["document"], e["figure"], e["reason"], line, _figure_key(figs[0]))
        if not ex.reason:
            fail.append(Failure(EXEMPTIONS_FILE, line, label,
                                "an exemption needs a stated `reason`"))
        if (ex.document, ex.key) in seen:
            fail.append(Failure(EXEMPTIONS_FILE, line, label, "duplicate exemption"))
            continue
        seen.add((ex.document, ex.key))
        out.append(ex)
    rules: list[IgnoreRule] = []
    for e, line in entries("ignore_sources", {"file", "key", "reason"}):
        rule = IgnoreRule(e["file"] or "*", e["key"] or "*", e["reason"], line)
        label = f"ignore {rule.file} {rule.key}"
        if rule.key == "*":
            fail.append(Failure(EXEMPTIONS_FILE, line, label,
                                "an ignore rule needs a `key` pattern narrower than *"))
            continue
        if not rule.reason:
            fail.append(Failure(EXEMPTIONS_FILE, line, label,
                                "an ignore rule needs a stated `reason`"))
        rules.append(rule)
    return out, rules, fail


# --------------------------------------------------------------------------- DVC outputs

_INTERP = re.compile(r"\$\{\s*([^}]+?)\s*\}")


def _lookup(ctx: Any, dotted: str) -> Any:
    cur = ctx
    for part in re.findall(r"[^.\[\]]+", dotted):
        if isinstance(cur, dict) and part in cur:
            cur = cur[part]
        elif isinstance(cur, list) and part.isdigit() and int(part) < len(cur):
            cur = cur[int(part)]
        else:
            raise KeyError(dotted)
    return cur


def _interpolate(value: str, ctx: dict[str, Any]) -> str:
    return _INTERP.sub(lambda m: str(_lookup(ctx, m.group(1))), value)


def _out_paths(body: dict[str, Any], ctx: dict[str, Any]) -> Iterator[str]:
    for section in ("outs", "metrics", "plots"):
        for entry in body.get(section) or []:
            names = [entry] if isinstance(entry, str) else list(entry) if isinstance(
                entry, dict) else []
            for name in names:
                try:
                    yield _interpolate(str(name), ctx)
                except KeyError:
                    continue


def dvc_outputs(root: Path) -> set[str]:
    """Paths (from the root, posix) that a stage of ``dvc.yaml`` or ``dvc.lock`` declares
    as an output (``outs``, ``metrics``, ``plots``), ``${...}`` and ``foreach`` resolved
    from ``params.yaml`` and ``vars``."""
    root = Path(root)
    found: set[str] = set()

    def load(name: str) -> Any:
        try:
            return yaml.safe_load((root / name).read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError):
            return None

    lock = load("dvc.lock")
    if isinstance(lock, dict):
        for stage in (lock.get("stages") or {}).values():
            for out in (stage or {}).get("outs") or []:
                if isinstance(out, dict) and "path" in out:
                    found.add(str(out["path"]))
    pipeline = load("dvc.yaml")
    if isinstance(pipeline, dict):
        params = load(PARAMS_FILE)
        ctx: dict[str, Any] = dict(params) if isinstance(params, dict) else {}
        for var in pipeline.get("vars") or []:
            if isinstance(var, dict):
                ctx.update(var)
        for body in (pipeline.get("stages") or {}).values():
            if not isinstance(body, dict):
                continue
            if "foreach" in body and isinstance(body.get("do"), dict):
                items: Any = body["foreach"]
                if isinstance(items, str):
                    m = _INTERP.fullmatch(items.strip())
                    try:
                        items = _lookup(ctx, m.group(1)) if m else None
                    except KeyError:
                        items = None
                pairs = (list(items.items()) if isinstance(items, dict)
                         else list(enumerate(items)) if isinstance(items, list) else [])
                for key, item in pairs:
                    found.update(_out_paths(body["do"], {**ctx, "key": key, "item": item}))
            else:
                found.update(_out_paths(body, ctx))
    return {Path(os.path.normpath(p)).as_posix() for p in found}


# --------------------------------------------------------------------------- certify


def document_paths(root: Path) -> list[Path]:
    """README.md and every docs/**/*.md under ``root``, in a stable order."""
    root = Path(root)
    docs = [root / "README.md"] if (root / "README.md").is_file() else []
    if (root / "docs").is_dir():
        docs += sorted(p for p in (root / "docs").rglob("*.md") if p.is_file())
    return docs


def _check_link(link: Link, doc_path: Path, root: Path, outputs: set[str] | None,
                slugs: dict[Path, set[str]]) -> Failure | None:
    target = link.target
    label = "image" if link.kind == "image" else "link"
    path_part, _, anchor = target.partition("#")
    path_part = unquote(path_part.partition("?")[0])
    anchor = unquote(anchor)
    if not path_part:
        dest = doc_path
    elif path_part.startswith("/"):
        dest = root / path_part.lstrip("/")
    else:
        dest = doc_path.parent / path_part
    dest = Path(os.path.normpath(dest))
    rel = _rel(dest, root)
    if rel.startswith("../") or Path(rel).is_absolute():
        return Failure(link.document, link.line, target,
                       f"{label} points outside the project ({rel})")
    if not dest.exists():
        if outputs is not None and any(rel == o or rel.startswith(o + "/") for o in outputs):
            return None
        return Failure(link.document, link.line, target, f"broken {label}: {rel} does not exist")
    if anchor and dest.is_file() and dest.suffix.lower() in (".md", ".markdown"):
        if dest not in slugs:
            slugs[dest] = heading_slugs(dest.read_text(encoding="utf-8"))
        if anchor not in slugs[dest]:
            return Failure(link.document, link.line, target,
                           f"broken anchor: {rel} has no heading #{anchor}")
    return None


def certify(root: Path, *, allow_dvc_outputs: bool = False,
            metrics_dir: Path | None = None) -> CertifyReport:
    """Certify README.md and docs/**/*.md under ``root`` (see the module docstring).

    Args:
        root: the project root.
        allow_dvc_outputs: a missing link target that a stage of dvc.yaml/dvc.lock
            declares as an output counts as present (a fresh clone before ``dvc repro``).
        metrics_dir: where the metrics JSON files are (relative to ``root`` or absolute;
            default ``data/metrics``).
    """
    root = Path(root).resolve()
    all_sources, failures = load_sources(root, metrics_dir)
    where = f"{_rel(root / (metrics_dir or METRICS_DIR), root)}/**/*.json or {PARAMS_FILE}"
    exemptions, rules, exemption_failures = _load_exemptions(root)
    failures += exemption_failures
    for rule in rules:
        if not any(rule.matches(src) for src in all_sources.items):
            failures.append(Failure(EXEMPTIONS_FILE, rule.line, f"ignore {rule.file} {rule.key}",
                                    "ignore rule no longer needed: it matches no source"))
    sources = Sources([src for src in all_sources.items
                       if not any(rule.matches(src) for rule in rules)])
    outputs = dvc_outputs(root) if allow_dvc_outputs else None

    documents: list[str] = []
    figures: list[Figure] = []
    traced: list[Traced] = []
    exempted: list[Exempted] = []
    notes: list[Failure] = []
    links: list[Link] = []
    external = 0
    slugs: dict[Path, set[str]] = {}
    if not (root / "README.md").is_file():
        failures.append(Failure("README.md", 1, "README.md", "the project has no README.md"))

    by_key = {(e.document, e.key): e for e in exemptions}
    used: dict[tuple[str, tuple[str, str]], list[Traced | Figure]] = {k: [] for k in by_key}
    for path in document_paths(root):
        doc = _rel(path, root)
        documents.append(doc)
        doc_figures, doc_links = _read_document(path.read_text(encoding="utf-8"), doc)
        figures += doc_figures
        for fig in doc_figures:
            hit = sources.trace(fig)
            ex = by_key.get((doc, _figure_key(fig)))
            if ex is not None:
                used[(doc, ex.key)].append(hit if hit is not None else fig)
            if hit is not None:
                traced.append(hit)
            elif ex is not None:
                exempted.append(Exempted(fig, ex))
            else:
                near = sources.closest(fig)
                hint = f" (closest: {near})" if near is not None else ""
                failures.append(Failure(
                    doc, fig.line, fig.text,
                    f"not traced: no number in {where} rounds to {fig.magnitude} at "
                    f"{fig.decimals} decimal(s){hint}; "
                    f"correct it, or exempt it with a reason in {EXEMPTIONS_FILE}"))
        for link in doc_links:
            if link.target.startswith("//") or _SCHEME.match(link.target):
                external += 1
                continue
            links.append(link)
            fail = _check_link(link, path, root, outputs, slugs)
            if fail is not None:
                failures.append(fail)

    for key, ex in by_key.items():
        hits = used[key]
        label = f"{ex.document}: {ex.figure}"
        if ex.document not in documents:
            failures.append(Failure(EXEMPTIONS_FILE, ex.line, label,
                                    f"exemption for a document that is not certified "
                                    f"({ex.document}); documents: README.md, docs/**/*.md"))
        elif not hits:
            failures.append(Failure(EXEMPTIONS_FILE, ex.line, label,
                                    f"exemption no longer needed: {ex.document} has no "
                                    f"figure {ex.figure!r}"))
        elif all(isinstance(h, Traced) for h in hits):
            first = hits[0]
            assert isinstance(first, Traced)
            notes.append(Failure(EXEMPTIONS_FILE, ex.line, label,
                                 f"exemption perhaps no longer needed: {ex.document}:"
                                 f"{first.figure.line} is traced to {first.source} (by "
                                 f"chance, if the figure is quoted)"))

    failures.sort(key=lambda f: (f.document != "README.md", f.document, f.line, f.text))
    return CertifyReport(
        root=root, documents=tuple(documents), figures=tuple(figures), traced=tuple(traced),
        exempted=tuple(exempted), links=tuple(links), external_links=external,
        sources=len(sources), sources_ignored=len(all_sources) - len(sources),
        failures=tuple(failures), notes=tuple(notes))
