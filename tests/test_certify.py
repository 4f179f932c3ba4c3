"""The certify stage: every figure in README.md and docs/ traced to data; links resolve."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path

import pytest
import yaml

from tattotronix.devtools.certify import (
    EXPERIMENT_ENV,
    OUTPUT_NAME,
    CertifyReport,
    Failure,
    certify,
    dvc_outputs,
    extract_figures,
    extract_links,
    heading_slugs,
    load_sources,
)

from .conftest import PYTHON, ROOT

ENV = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}


def project(tmp: Path, readme: str, *, docs: Mapping[str, str] | None = None,
            metrics: Mapping[str, object] | None = None, params: object = None,
            exemptions: object = None, files: Mapping[str, str] | None = None) -> Path:
    """A small project: README.md, docs/*.md, data/metrics/*.json, params.yaml and
    docs/certify.yaml."""
    (tmp / "docs").mkdir(parents=True, exist_ok=True)
    (tmp / "README.md").write_text(readme, encoding="utf-8")
    for name, text in (docs or {}).items():
        (tmp / "docs" / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / "docs" / name).write_text(text, encoding="utf-8")
    for name, obj in (metrics or {"a.json": {}}).items():
        path = tmp / "data" / "metrics" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(obj), encoding="utf-8")
    (tmp / "params.yaml").write_text(yaml.safe_dump(params or {"paths": {"data": "data"}}))
    if exemptions is not None:
        (tmp / "docs" / "certify.yaml").write_text(yaml.safe_dump(exemptions),
                                                   encoding="utf-8")
    for name, text in (files or {}).items():
        (tmp / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / name).write_text(text, encoding="utf-8")
    return tmp


def failing(report: CertifyReport) -> list[str]:
    """Each failure as 'document:line: text'."""
    return [f"{f.document}:{f.line}: {f.text}" for f in report.failures]


def texts(markdown: str) -> list[str]:
    return [f.text for f in extract_figures(markdown)]


# --------------------------------------------------------------------------- tracing


def test_a_figure_is_traced_at_its_written_precision(tmp_path: Path) -> None:
    root = project(tmp_path, "Worst: 51.5 µm.\n\nAgain: 51.50 µm.\n",
                   metrics={"runs/x.json": {"run": {"marking_max_um": 51.47}}})
    report = certify(root)
    assert [t.figure.text for t in report.traced] == ["51.5 µm"]
    assert str(report.traced[0].source) == "data/metrics/runs/x.json run.marking_max_um = 51.47"
    assert failing(report) == ["README.md:3: 51.50 µm"]
    assert "51.50" in report.format() and "not traced" in report.failures[0].why


def test_rounding_accepts_half_up_and_half_even_and_the_binary_value(tmp_path: Path) -> None:
    # 2.675 is 2.67499999... in binary: format() writes 2.67, a person writes 2.68;
    # 0.125 is exact: half-even gives 0.12, half-up 0.13. All are traced.
    root = project(tmp_path, "2.68 mm, 2.67 mm; 0.12 s and 0.13 s; 0.14 s\n",
                   metrics={"a.json": {"x": 2.675, "y": 0.125}})
    report = certify(root)
    assert sorted(t.figure.text for t in report.traced) == [
        "0.12 s", "0.13 s", "2.67 mm", "2.68 mm"]
    assert failing(report) == ["README.md:1: 0.14 s"]


def test_signs_are_prose_magnitudes_are_compared(tmp_path: Path) -> None:
    root = project(tmp_path, "tip at (258.96, -9.444) mm; 9.444 mm below\n",
                   metrics={"a.json": {"tcp": [258.96, -9.444]}})
    report = certify(root)
    assert report.ok, report.format()
    assert [str(f.value) for f in report.figures] == ["258.96", "-9.444", "9.444"]


def test_thousands_separators(tmp_path: Path) -> None:
    readme = "frames: 29 593 s, thin 29\u2009593 s, narrow 29\u202f593 s; 16,656 mm\n"
    figs = extract_figures(readme)
    assert [(f.number, int(f.value), f.decimals) for f in figs] == [
        ("29 593", 29593, 0), ("29 593", 29593, 0), ("29 593", 29593, 0), ("16,656", 16656, 0)]
    root = project(tmp_path, readme, metrics={"a.json": {"frames": 29593, "n": 16656.2}})
    assert certify(root).ok


def test_chains_share_their_unit() -> None:
    assert texts("| settled mean / max | 2.01 / 51.5 µm |") == ["2.01 µm", "51.5 µm"]
    assert texts("from 0.2132 to 2.1093 % of it") == ["0.2132 %", "2.1093 %"]
    assert texts("ranges 1.7485 … 1.7573 mm and 1..2 mm") == [
        "1.7485 mm", "1.7573 mm", "1 mm", "2 mm"]
    assert texts("76–98 mm, but 76–98x") == ["76 mm", "98 mm"]
    assert texts("at 3, 4 and 5 mm") == ["3 mm", "4 mm", "5 mm"]
    assert texts("(0, -0.09, -0.0018) N m") == ["0 N m", "-0.09 N m", "-0.0018 N m"]
    assert texts("between 0.302 and 0.345 N·m") == ["0.302 N·m", "0.345 N·m"]
    # a chain across a line break, as wrapped prose has it
    figs = extract_figures("first line 2.01 /\n51.5 um and\nthe 0.3\nmm needle")
    assert [(f.text, f.line) for f in figs] == [("2.01 um", 1), ("51.5 um", 2), ("0.3 mm", 3)]


def test_units_must_end_at_a_word_boundary() -> None:
    assert texts("5 steps, 3 samples, 2 mmHg, the 1990s, 4 sec, 7 Nms, 10 mm/rev") == []
    assert texts("MG996R 55 g, x2 mm, v1.2 s, PCA9685, 0x40 s") == []
    assert texts("it takes 12 s. Then (0.3 mm) and 25% and 5mm and 6 mm/s.") == [
        "12 s", "0.3 mm", "25 %", "5 mm", "6 mm/s"]
    assert [f.unit for f in extract_figures("1 um 2 µm 3 N m 4 Nm 5 N·m")] == [
        "µm", "µm", "N·m", "N·m", "N·m"]


def test_code_comments_tags_and_link_targets_are_not_read(tmp_path: Path) -> None:
    readme = (
        "Run `python x.py --tol 51.50 µm` first.\n"
        "```bash\n"
        "echo 12.34 mm\n"
        "```\n"
        "~~~\n9.99 s\n~~~\n"
        "<!-- a comment: 77.7 mm\n   over two lines 88.8 mm -->\n"
        "A ``span with ` inside 66.6 mm`` and `a span\nover 55.5 mm two lines`.\n"
        "[the 1.5 mm page](https://example.com/44.4%) and https://x.org/33.3%20s\n"
        '<img src="x/22.2 mm.png" width="11 %"> <https://y.org/9.1%>\n'
        "the one figure: 1.5 mm\n"
    )
    assert texts(readme) == ["1.5 mm", "1.5 mm"]
    root = project(tmp_path, readme.replace("x/22.2 mm.png", "https://z/a.png"),
                   metrics={"a.json": {"plunge_mm": 1.5}})
    assert certify(root).ok


def test_a_percentage_is_traced_by_a_fraction(tmp_path: Path) -> None:
    root = project(tmp_path, "ink IoU 99.6 %, converged 100 %; 99.7 %\n",
                   metrics={"a.json": {"ink_iou": 0.9963164892297618, "converged_pct": 100.0}})
    report = certify(root)
    traced = {t.figure.text: t for t in report.traced}
    assert traced["99.6 %"].from_fraction and not traced["100 %"].from_fraction
    assert failing(report) == ["README.md:1: 99.7 %"]
    assert report.summary()["traced_from_fraction"] == 1


def test_no_other_unit_scaling(tmp_path: Path) -> None:
    # anchors every 5 mm, stored as 0.005 m: not traced (exempt it, saying so)
    root = project(tmp_path, "anchors every 5 mm\n",
                   params={"ik": {"anchor_spacing_m": 0.005}})
    assert failing(certify(root)) == ["README.md:1: 5 mm"]


def test_params_yaml_is_a_source_and_booleans_are_not_numbers(tmp_path: Path) -> None:
    root = project(tmp_path, "the 0.3 mm needle; 1 %\n",
                   metrics={"a.json": {"completed": True, "rows": [{"ok": False}]}},
                   params={"draw": {"needle_mm": 0.3, "flag": True}})
    report = certify(root)
    assert [str(t.source) for t in report.traced] == ["params.yaml draw.needle_mm = 0.3"]
    assert failing(report) == ["README.md:1: 1 %"]


def test_sources_walk_nested_metrics(tmp_path: Path) -> None:
    project(tmp_path, "", metrics={"deep/er/m.json": {"a": [{"b": [1.5, True, "2.5"]}],
                                                       "c": None, "nan": float("nan")}},
            params={"x": {"y": [2, "1e-06", "word"]}})
    sources, problems = load_sources(tmp_path)
    assert not problems
    assert [str(s) for s in sources.items] == [
        "data/metrics/deep/er/m.json a[0].b[0] = 1.5",
        "params.yaml x.y[0] = 2",
        "params.yaml x.y[1] = 1e-06",
    ]


def test_the_stage_output_is_not_a_source(tmp_path: Path) -> None:
    root = project(tmp_path, "7 s\n", metrics={OUTPUT_NAME: {"figures": 7}})
    assert failing(certify(root)) == ["README.md:1: 7 s"]


def test_docs_are_certified_too(tmp_path: Path) -> None:
    root = project(tmp_path, "nothing\n", docs={"x.md": "# X\n\n12.5 mm\n",
                                                "deep/y.md": "13.5 mm\n"})
    report = certify(root)
    assert report.documents == ("README.md", "docs/deep/y.md", "docs/x.md")
    assert failing(report) == ["docs/deep/y.md:1: 13.5 mm", "docs/x.md:3: 12.5 mm"]


# --------------------------------------------------------------------------- links


DOC = """# The Control Loop

## Gains & limits (`controller.wn`)

## Gains & limits (`controller.wn`)

Settings
--------

<a name="custom-anchor"></a>
"""


def test_heading_slugs_follow_github() -> None:
    assert heading_slugs(DOC) == {
        "the-control-loop", "gains--limits-controllerwn", "gains--limits-controllerwn-1",
        "settings", "custom-anchor"}
    assert heading_slugs("```\n# not a heading\n```\n# Yes: 5.5 mm!\n") == {"yes-55-mm"}


def test_links_and_images_must_resolve(tmp_path: Path) -> None:
    readme = (
        "# Top\n"
        "[doc](docs/x.md) [top](#top) [gains](docs/x.md#gains--limits-controllerwn-1)\n"
        "![figure](data/fig.png) [dir](docs/) [q](docs/x.md?plain=1#settings)\n"
        "[web](https://example.com/missing) [mail](mailto:a@b.c)\n"
        "[missing](docs/nope.md)\n"
        "![missing image](data/figures/none.png)\n"
        "[bad anchor](docs/x.md#no-such-heading) [bad local](#nowhere)\n"
        '<img src="data/gone.png"> [ref]\n'
        "\n[ref]: docs/gone.md\n"
        "`[in code](docs/nope.md)`\n"
    )
    root = project(tmp_path, readme, docs={"x.md": DOC + "[back](../README.md#top)\n"},
                   files={"data/fig.png": "png"})
    report = certify(root)
    assert failing(report) == [
        "README.md:5: docs/nope.md",
        "README.md:6: data/figures/none.png",
        "README.md:7: #nowhere",
        "README.md:7: docs/x.md#no-such-heading",
        "README.md:8: data/gone.png",
        "README.md:10: docs/gone.md",
    ]
    whys = {f.text: f.why for f in report.failures}
    assert whys["data/figures/none.png"].startswith("broken image")
    assert whys["docs/x.md#no-such-heading"].startswith("broken anchor")
    assert report.external_links == 2
    assert len(report.links) == 13


def test_a_link_out_of_the_project_fails(tmp_path: Path) -> None:
    root = project(tmp_path / "p", "[up](../outside.md)\n")
    (tmp_path / "outside.md").write_text("x")
    assert "outside the project" in certify(root).failures[0].why


def test_link_kinds_are_found() -> None:
    links = extract_links('[![alt](img.png)](page.md "title")\n[r]: <a b.md>\n'
                          "<a href='h.md'>x</a>\n")
    assert [(k.kind, k.target) for k in links] == [
        ("link", "page.md"), ("image", "img.png"), ("reference", "a b.md"), ("html", "h.md")]


DVC_YAML = """
vars:
  - artworks:
      emblem: artwork.source=emblem
stages:
  kinematics:
    foreach: ${artworks}
    do:
      cmd: python stages/kinematics.py artwork.name=${key} ${item}
      outs:
        - ${paths.data}/figures/${key}/placement.png
      metrics:
        - ${paths.data}/metrics/kinematics/${key}.json:
            cache: false
  robot:
    cmd: python stages/robot.py
    outs:
      - ${paths.data}/robot
"""


def test_dvc_outputs_count_as_present_only_when_allowed(tmp_path: Path) -> None:
    readme = ("![placement](data/figures/emblem/placement.png) [urdf](data/robot/a.urdf)\n"
              "![not an output](data/figures/emblem/other.png)\n")
    root = project(tmp_path, readme, files={"dvc.yaml": DVC_YAML})
    assert dvc_outputs(root) == {"data/figures/emblem/placement.png", "data/robot",
                                 "data/metrics/kinematics/emblem.json"}
    assert failing(certify(root)) == [
        "README.md:1: data/figures/emblem/placement.png", "README.md:1: data/robot/a.urdf",
        "README.md:2: data/figures/emblem/other.png"]
    assert failing(certify(root, allow_dvc_outputs=True)) == [
        "README.md:2: data/figures/emblem/other.png"]


def test_dvc_lock_outputs_count_too(tmp_path: Path) -> None:
    lock = {"schema": "2.0", "stages": {"x": {"outs": [{"path": "data/out/x.png"}]}}}
    root = project(tmp_path, "![x](data/out/x.png)\n",
                   files={"dvc.lock": yaml.safe_dump(lock)})
    assert certify(root, allow_dvc_outputs=True).ok


# --------------------------------------------------------------------------- exemptions


README = "The original's line: 300 µm.\n\nOurs: 51.5 µm.\n"
METRICS = {"runs/x.json": {"marking_max_um": 51.47}}


def exemption(figure: str = "300 µm", reason: str | None = "the original's line width",
              document: str = "README.md") -> dict[str, object]:
    entry: dict[str, object] = {"document": document, "figure": figure}
    if reason is not None:
        entry["reason"] = reason
    return {"exemptions": [entry]}


def test_a_needed_exemption_passes(tmp_path: Path) -> None:
    report = certify(project(tmp_path, README, metrics=METRICS, exemptions=exemption()))
    assert report.ok, report.format()
    assert [(e.figure.text, e.exemption.reason) for e in report.exempted] == [
        ("300 µm", "the original's line width")]
    # um and µm are one unit; the number must be as written
    report = certify(project(tmp_path, README, metrics=METRICS,
                             exemptions=exemption(figure="300  um")))
    assert report.ok, report.format()


def test_an_exemption_without_reason_fails(tmp_path: Path) -> None:
    for reason in (None, "", "  "):
        report = certify(project(tmp_path, README, metrics=METRICS,
                                 exemptions=exemption(reason=reason)))
        assert failing(report) == ["docs/certify.yaml:2: README.md: 300 µm"]
        assert "reason" in report.failures[0].why


def test_a_stale_exemption_fails(tmp_path: Path) -> None:
    # now traceable: a note (a new metric can match a quoted number by chance), not a
    # failure
    report = certify(project(tmp_path, README, metrics=METRICS,
                             exemptions=exemption(figure="51.5 µm", reason="old")))
    assert len(report.failures) == 1  # 300 µm untraced
    [stale] = report.notes
    assert (stale.document, stale.text) == ("docs/certify.yaml", "README.md: 51.5 µm")
    assert "perhaps no longer needed" in stale.why and "marking_max_um" in stale.why
    assert report.summary()["notes"] == 1
    # matches no figure (written with other decimals, or in another document)
    for ex in (exemption(figure="300.0 µm"), exemption(document="docs/x.md")):
        report = certify(project(tmp_path, README, metrics=METRICS,
                                 docs={"x.md": "no figures\n"}, exemptions=ex))
        assert any("no longer needed" in f.why for f in report.failures), report.format()


def test_malformed_exemptions_fail(tmp_path: Path) -> None:
    ex: object
    for ex in ({"exemptions": [{"document": "README.md", "figure": "300"}]},
               {"exemptions": [{"document": "README.md", "figure": "300 µm", "reason": "r",
                                "why": "typo"}]},
               {"exempt": []},
               {"exemptions": ["300 µm"]},
               {"exemptions": [{"document": "nope.md", "figure": "300 µm", "reason": "r"}]}):
        report = certify(project(tmp_path, README, metrics=METRICS, exemptions=ex))
        assert any(f.document == "docs/certify.yaml" for f in report.failures), ex


def test_ignored_sources_trace_nothing_and_a_stale_rule_fails(tmp_path: Path) -> None:
    metrics = {"k.json": {"timing": {"solve_s": 0.25}, "wall_s": 7.9}}
    ignore = [{"file": "data/metrics/*", "key": "timing.*", "reason": "wall-clock"}]
    rules: dict[str, list[dict[str, str]]] = {"exemptions": [], "ignore_sources": ignore}
    report = certify(project(tmp_path, "0.25 s and 7.9 s\n", metrics=metrics,
                             exemptions=rules))
    assert failing(report) == ["README.md:1: 0.25 s"]
    assert report.summary()["sources_ignored"] == 1
    ignore.append({"key": "*never_s", "reason": "r"})
    report = certify(project(tmp_path, "7.9 s\n", metrics=metrics, exemptions=rules))
    assert [f.why for f in report.failures] == [
        "ignore rule no longer needed: it matches no source"]


def test_the_summary_is_the_same_for_identical_runs(tmp_path: Path) -> None:
    root = project(tmp_path, README, metrics=METRICS, exemptions=exemption())
    a, b = certify(root).summary(), certify(root).summary()
    assert a == b
    assert {k: a[k] for k in ("documents", "figures", "traced", "exempted", "failures")} == {
        "documents": 1, "figures": 2, "traced": 1, "exempted": 1, "failures": 0}


# --------------------------------------------------------------------------- acceptance


def _copy_project(dest: Path) -> Path:
    """The project's files as git sees them (tracked and new, not ignored), with the
    committed metrics; stage outputs (figures) are absent, as in a fresh clone."""
    try:
        names = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=ROOT, capture_output=True, check=True).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        names = ["README.md", "params.yaml", "dvc.yaml", "dvc.lock"]
        names += [p.relative_to(ROOT).as_posix() for sub in ("docs", "data/metrics")
                  for p in (ROOT / sub).rglob("*") if p.is_file()]
    for name in filter(None, names):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


@pytest.fixture(scope="module")
def real_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _copy_project(tmp_path_factory.mktemp("project"))


def test_the_real_documents_are_certified(real_copy: Path) -> None:
    report = certify(real_copy, allow_dvc_outputs=True)
    assert report.ok, report.format()
    assert report.documents[0] == "README.md"
    assert len(report.traced) > 30


def test_a_readme_number_edited_to_disagree_with_its_metrics_fails(
        tmp_path: Path, real_copy: Path) -> None:
    root = shutil.copytree(real_copy, tmp_path / "p")
    readme = (root / "README.md").read_text(encoding="utf-8")
    row = re.search(r"^\| settled mean / max \| (\d+\.\d+) / ", readme, re.M)
    assert row, "README has no 'settled mean / max' row"
    written = row.group(1)
    run = json.loads((root / "data/metrics/runs/emblem-mujoco.json").read_text())
    decimals = len(written.split(".")[1])
    assert written == f"{run['settled_mean_um']:.{decimals}f}"  # it is the metric, now
    sources, _ = load_sources(root)
    step = 10.0 ** -decimals
    for k in range(3, 40):  # the first nearby value no source happens to round to
        edited = f"{float(written) + k * step:.{decimals}f}"
        if sources.trace(extract_figures(f"{edited} µm")[0]) is None:
            break
    a, b = row.span(1)
    (root / "README.md").write_text(readme[:a] + edited + readme[b:], encoding="utf-8")
    line = readme.count("\n", 0, a) + 1
    report = certify(root, allow_dvc_outputs=True)
    assert failing(report) == [f"README.md:{line}: {edited} µm"], report.format()
    assert report.failures[0].why.startswith("not traced")


# --------------------------------------------------------------------------- the stage


def _stage(root: Path, env: Mapping[str, str] | None = None
           ) -> subprocess.CompletedProcess[str]:
    run_env = {k: v for k, v in ENV.items() if k != EXPERIMENT_ENV}
    return subprocess.run([PYTHON, str(ROOT / "stages" / "certify.py")], cwd=root,
                          env={**run_env, **(env or {})}, capture_output=True, text=True,
                          timeout=300)


def test_the_stage_writes_the_counts_or_exits_2(tmp_path: Path) -> None:
    good = project(tmp_path / "good", README, metrics=METRICS, exemptions=exemption())
    run = _stage(good)
    assert run.returncode == 0, run.stderr
    out = json.loads((good / "data" / OUTPUT_NAME).read_text())
    assert {k: out[k] for k in ("documents", "figures", "traced", "exempted", "links",
                                "failures")} == {
        "documents": 1, "figures": 2, "traced": 1, "exempted": 1, "links": 0, "failures": 0}
    assert not any("time" in k or k.endswith("_s") for k in out)
    first = (good / "data" / OUTPUT_NAME).read_bytes()
    assert _stage(good).returncode == 0
    assert (good / "data" / OUTPUT_NAME).read_bytes() == first  # same again

    bad = project(tmp_path / "bad", README + "\n[x](missing.md)\n", metrics=METRICS)
    run = _stage(bad)
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    assert "certify: error: 2 failure(s)" in run.stderr
    assert "README.md:1: 300 µm: not traced" in run.stderr
    assert "README.md:5: missing.md: broken link" in run.stderr
    assert not (bad / "data" / OUTPUT_NAME).exists()


def test_inside_an_experiment_the_drift_is_a_metric_not_a_failure(tmp_path: Path) -> None:
    """``dvc exp run`` (DVC_EXP_BASELINE_REV set) changes numbers on purpose: the stage
    records the documents' drift in certify.json and succeeds, so the experiment is
    saved; outside one, the same drift fails the stage (``main`` never carries it)."""
    bad = project(tmp_path / "bad", README, metrics=METRICS)
    run = _stage(bad, {EXPERIMENT_ENV: "0" * 40})
    assert run.returncode == 0, run.stderr
    assert "recorded, not enforced" in run.stdout + run.stderr
    out = json.loads((bad / "data" / OUTPUT_NAME).read_text())
    assert out["failures"] == 1
    assert out["drift"] == ["README.md:1: 300 µm: not traced: no number in "
                            "data/metrics/**/*.json or params.yaml rounds to 300 at 0 "
                            "decimal(s) (closest: data/metrics/runs/x.json marking_max_um = "
                            "51.47); correct it, or exempt it with a reason in "
                            "docs/certify.yaml"]
    # an empty variable is no experiment
    (bad / "data" / OUTPUT_NAME).unlink()
    assert _stage(bad, {EXPERIMENT_ENV: ""}).returncode == 2
    assert not (bad / "data" / OUTPUT_NAME).exists()


def test_inside_an_experiment_the_log_is_a_short_summary() -> None:
    """Dozens of drifted figures, each failure a long line: the experiment's log gets a
    count per document and the first three, each line at most 100 characters (the whole
    list is certify.json's ``drift``)."""
    why = ("not traced: no number in data/metrics/**/*.json or params.yaml rounds to 18.7 "
           "at 1 decimal(s) (closest: data/metrics/runs/emblem-mujoco.json marking_max_um "
           "= 24.93); correct it, or exempt it with a reason in docs/certify.yaml")
    failures = tuple(Failure("README.md" if i < 40 else "docs/control.md", i + 1,
                             f"{i}.5 µm", why) for i in range(56))
    report = CertifyReport(root=ROOT, documents=("README.md", "docs/control.md"), figures=(),
                           traced=(), exempted=(), links=(), external_links=0, sources=0,
                           sources_ignored=0, failures=failures)
    lines = report.drift_summary().splitlines()
    assert len(lines) == 5 and max(map(len, lines)) <= 100, lines
    assert lines[0] == ("56 documented figure(s) or link(s) no longer match (README.md 40, "
                        "docs/control.md 16)")
    assert lines[1] == "  README.md:1: 0.5 µm: not traced"
    assert lines[-1] == "  ... and 53 more"
    assert len(report.format().splitlines()) == 57  # the whole list, outside an experiment
