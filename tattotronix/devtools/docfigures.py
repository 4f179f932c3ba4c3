"""Carry the documents' figures over to new metrics.

After a change that moves the metrics (``dvc repro``), every figure that certify traced
before (in the metrics committed at a git revision, ``HEAD`` by default) whose source now
gives another value is rewritten with that value, at its written precision: also when
the old figure still traces, by chance, to some other number (a settled mean of 0.99 um
that became 0.96 still matched an unrelated IoU of 0.99). A figure is rewritten only
when the sources that traced it best before (by certify's own preference: exact, then a
key naming the unit, then a metrics file) agree on the new value; the others, the figures
that traced to nothing before and the lines where the number is not unique, are listed
for a person to settle. ``docs/original.md`` quotes the original's published numbers and
is never touched. Read the diff: a figure written by hand since the revision, which
traced there by chance, is rewritten from that chance source. Unitless figures (a cycle
ratio, a speed factor) are not certify's, so not carried over either.

    python -m tattotronix.devtools.docfigures            # rewrite, from HEAD's metrics
    python -m tattotronix.devtools.docfigures --from REV --dry-run

Then run ``python stages/certify.py``: what is left is what the list names.
"""

from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

from tattotronix.devtools.certify import (
    METRICS_DIR,
    PARAMS_FILE,
    Failure,
    Figure,
    Sources,
    document_paths,
    extract_figures,
    load_sources,
    source_rank,
)

__all__ = ["Change", "Unsettled", "carry_over", "main", "written_as"]

ROOT = Path(__file__).resolve().parents[2]
#: documents whose numbers are quoted, never computed here
QUOTED = ("docs/original.md",)


@dataclass(frozen=True)
class Change:
    """A figure rewritten: ``document:line``, the number before and after."""

    document: str
    line: int
    before: str
    after: str


#: a figure left for a person, and why (certify's own ``document:line: text: why``)
Unsettled = Failure


def written_as(value: float, fig: Figure, scale: int = 1) -> str:
    """``value`` (times ``scale``) written like ``fig``'s number: its decimals (half up),
    its thousands separator and its sign character."""
    text = str(Decimal(repr(abs(float(value)) * scale)).quantize(
        Decimal((0, (1,), fig.exponent)), ROUND_HALF_UP))
    num = fig.number
    whole, dot, frac = text.partition(".")
    if "," in num:
        text = f"{int(whole):,}{dot}{frac}"
    elif " " in num.strip("-+−"):
        text = f"{int(whole):,}".replace(",", " ") + dot + frac
    return num[0] + text if num[:1] in ("-", "+", "−") else text


def carry_over(root: Path, before: Sources, after: Sources, *, write: bool = True
               ) -> tuple[list[Change], list[Unsettled]]:
    """Rewrite every figure of the documents under ``root`` that ``before`` traces, with
    the new value of its sources in ``after`` (see the module docstring)."""
    now = {(s.file, s.key): s.value for s in after.items}
    changes: list[Change] = []
    unsettled: list[Unsettled] = []
    for doc in document_paths(root):
        rel = doc.relative_to(root).as_posix()
        if rel in QUOTED:
            continue
        text = doc.read_text(encoding="utf-8")
        lines = text.split("\n")
        for fig in extract_figures(text, rel):
            found = before.candidates(fig)
            if not found:
                if not after.candidates(fig):
                    unsettled.append(Unsettled(rel, fig.line, fig.text,
                                               "traced to nothing before"))
                continue
            # the best-ranked of the sources that traced it (certify's own preference)
            best = min(source_rank(fig, *c) for c in found)
            new = {written_as(now[(s.file, s.key)], fig, 100 if scaled else 1)
                   for s, scaled in found
                   if source_rank(fig, s, scaled) == best and (s.file, s.key) in now}
            if fig.number in new:
                continue  # one of its sources still gives it
            if len(new) != 1:
                if after.candidates(fig):
                    continue  # traced now, and no one new value to give it
                why = ("its sources are gone" if not new else
                       f"its sources now disagree: {', '.join(sorted(new))}")
                unsettled.append(Unsettled(rel, fig.line, fig.text, why))
                continue
            value = new.pop()
            pattern = re.compile(r"(?<![\d.,])" + re.escape(fig.number) + r"(?![\d])")
            line = lines[fig.line - 1]
            if len(pattern.findall(line)) != 1:
                unsettled.append(Unsettled(rel, fig.line, fig.text,
                                           f"the number is not unique on its line: {value}?"))
                continue
            lines[fig.line - 1] = pattern.sub(value, line)
            changes.append(Change(rel, fig.line, fig.number, value))
        if write:
            doc.write_text("\n".join(lines), encoding="utf-8")
    return changes, unsettled


def sources_at(root: Path, rev: str) -> Sources:
    """The metrics and params.yaml committed at git revision ``rev``."""
    archive = subprocess.run(["git", "archive", "--format=tar", rev, METRICS_DIR,
                              PARAMS_FILE], cwd=root, capture_output=True, check=True).stdout
    with tempfile.TemporaryDirectory() as tmp:
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(tmp, filter="data")
        sources, _ = load_sources(Path(tmp))
    return sources


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--from", dest="rev", default="HEAD",
                        help="the git revision whose metrics the documents agree with")
    parser.add_argument("--dry-run", action="store_true", help="list, write nothing")
    args = parser.parse_args(argv)
    before = sources_at(ROOT, args.rev)
    after, failures = load_sources(ROOT)
    for f in failures:
        print(f"docfigures: {f}", file=sys.stderr)
    changes, unsettled = carry_over(ROOT, before, after, write=not args.dry_run)
    for c in changes:
        print(f"{c.document}:{c.line}: {c.before} -> {c.after}")
    for u in unsettled:
        print(f"settle by hand: {u}")
    print(f"docfigures: {len(changes)} figure(s) {'to rewrite' if args.dry_run else 'rewritten'}"
          f", {len(unsettled)} to settle by hand")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
