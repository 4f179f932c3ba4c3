"""The job server's latency and its effect on a running job (issue 32).

* ``upload to draft``: ``POST /api/drafts`` of the logo-sized SVG (150 x 40 mm, twelve
  regions; ``bench_toolpath.logo_svg``): the placement's problems and its toolpath, what
  the page draws at once. Goal: upload to preview <= 1 s on 2 cores.
* ``upload to plan`` and ``preview``: ``POST /api/plans`` (the timed plan, saved), then
  ``GET .../preview.png``, warm, through FastAPI's test client (no network).
* ``frame pacing``: a real-time dry run of a small drawing, with no client and with a
  WebSocket client following it (the page): how late each frame went out (the session's
  ``late_ms``: median, 99th percentile and worst), ms. Goal: the server adds none.

    python benchmarks/bench_server.py [--repeat 3]
    python benchmarks/run.py server
"""

from __future__ import annotations

import json
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

from run import Row, bench_main, median_time

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_toolpath import logo_svg  # noqa: E402
from fastapi.testclient import TestClient  # noqa: E402

from tattotronix.server.web import create_app  # noqa: E402

SMALL = """<svg xmlns="http://www.w3.org/2000/svg" width="20mm" height="10mm" viewBox="0 0 20 10">
<rect x="1" y="1" width="8" height="8"/><circle cx="15" cy="5" r="4"/></svg>"""


def _latency(client: TestClient, svg: bytes, repeat: int) -> list[Row]:
    def upload() -> str:
        r = client.post("/api/plans", files={"file": ("logo.svg", svg, "image/svg+xml")})
        assert r.status_code == 201, r.text
        return str(r.json()["id"])

    def draft() -> None:
        r = client.post("/api/drafts", files={"file": ("logo.svg", svg, "image/svg+xml")})
        assert r.status_code == 200 and r.json()["stats"]["ok"], r.text

    draft()  # warm
    t_draft, _ = median_time(draft, repeat)
    upload()
    t_plan, pid = median_time(upload, repeat)

    def preview() -> None:
        pid_new = upload()
        assert client.get(f"/api/plans/{pid_new}/preview.png").status_code == 200

    t_both, _ = median_time(preview, repeat)
    return [("upload to draft [logo SVG]", t_draft, "s",
             "POST /api/drafts: problems and toolpath; goal <= 1 s"),
            ("upload to plan [logo SVG]", t_plan, "s", "POST /api/plans"),
            ("upload to preview [logo SVG]", t_both, "s",
             f"+ GET preview.png ({t_both - t_plan:.2f} s)")]


def _pacing(client: TestClient, folder: Path, follow: bool) -> dict[str, float]:
    """How late the frames of a real-time dry run went out, ms (``late_ms``: median, p99,
    worst; a WebSocket client following it when ``follow``)."""
    r = client.post("/api/plans", files={"file": ("small.svg", SMALL.encode(), "image/svg+xml")},
                    data={"width_mm": "20"})
    pid = r.json()["id"]
    stop = threading.Event()

    def watch() -> None:
        with client.websocket_connect("/api/ws") as ws:
            while not stop.is_set():
                ws.receive_text()

    watcher = threading.Thread(target=watch, daemon=True) if follow else None
    assert client.post("/api/jobs", json={"plan": pid, "realtime": True}).status_code == 201
    if watcher:
        watcher.start()
    while client.get("/api/jobs/current").json()["status"] not in ("done", "failed"):
        time.sleep(0.2)
    stop.set()
    state = client.get("/api/jobs/current").json()
    (metrics,) = (folder / "jobs" / state["id"] / "metrics" / "runs").glob("*-arm.json")
    return dict(json.loads(metrics.read_text())["late_ms"])


def bench(repeat: int) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        client = TestClient(create_app(folder))
        rows = _latency(client, logo_svg().encode(), repeat)
        alone = _pacing(client, folder, follow=False)
        watched = _pacing(client, folder, follow=True)
        for key in ("median", "p99", "worst"):
            rows += [(f"frame lateness {key}, no client", alone[key], "ms", ""),
                     (f"frame lateness {key}, a WebSocket client", watched[key], "ms",
                      f"{watched[key] - alone[key]:+.3f} ms over alone")]
        return rows


def main(argv: Sequence[str] | None = None) -> int:
    return bench_main(bench, __doc__ or "", argv, repeat=3)


if __name__ == "__main__":
    raise SystemExit(main())
