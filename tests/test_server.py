"""The job server (``tattotronix serve``; issue 32): every route, the token on a network
bind, bad uploads, the one job at a time (409), pause with the needle lifted, resume,
stop, the WebSocket's live state, and a job found again by a restarted server."""

from __future__ import annotations

import io
import json
import os
import signal
import stat
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from PIL import Image, ImageDraw
from starlette.websockets import WebSocketDisconnect

from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import TEST_HOOK_ENV
from tattotronix.server.auth import is_loopback, load_or_make_token
from tattotronix.server.plans import sniff_kind
from tattotronix.server.web import create_app
from tests.conftest import small_art

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def art(tmp_path: Path) -> bytes:
    return small_art(tmp_path / "small.png").read_bytes()


def _client(folder: Path, **kw: Any) -> TestClient:
    return TestClient(create_app(folder, **kw))


def _plan(client: TestClient, art: bytes, **form: Any) -> dict[str, Any]:
    r = client.post("/api/plans", files={"file": ("small.png", art, "image/png")},
                    data={"width_mm": "24", **form})
    assert r.status_code == 201, r.text
    return dict(r.json())


def _wait(client: TestClient, done: Callable[[dict[str, Any]], bool],
          timeout: float = 120.0) -> dict[str, Any]:
    end = time.monotonic() + timeout
    while True:
        st = client.get("/api/jobs/current").json()
        if done(st):
            return dict(st)
        assert time.monotonic() < end, st
        time.sleep(0.2)


# ------------------------------------------------------------------ token

def test_loopback_needs_no_token_and_a_network_bind_does(tmp_path: Path) -> None:
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.20")
    assert _client(tmp_path / "a").get("/api/health").status_code == 200
    token, made = load_or_make_token(tmp_path / "b")
    assert made and len(token) >= 16
    assert stat.S_IMODE((tmp_path / "b" / "token").stat().st_mode) == 0o600
    assert load_or_make_token(tmp_path / "b") == (token, False)  # the same, not printed
    c = _client(tmp_path / "b", token=token)
    assert c.get("/").status_code == 200  # the page's shell: it asks for the token
    r = c.get("/api/health")
    assert r.status_code == 401 and "token" in r.json()["detail"]
    assert c.get("/api/health", headers={"Authorization": "Bearer nope"}).status_code == 403
    assert c.get("/api/health", headers={"Authorization": f"Bearer {token}"}).status_code == 200
    assert c.get(f"/api/health?token={token}").status_code == 200
    assert c.post("/api/jobs/current/stop").status_code == 401  # nothing moves without it
    with pytest.raises(WebSocketDisconnect) as closed, c.websocket_connect("/api/ws") as ws:
        ws.receive_text()
    assert closed.value.code == 1008
    with c.websocket_connect(f"/api/ws?token={token}") as ws:
        assert json.loads(ws.receive_text()) == {"status": "none"}


def test_other_sites_pages_and_host_names_are_refused(tmp_path: Path) -> None:
    """A page of another site in the user's browser cannot act (a POST or the WebSocket
    with its Origin), nor reach a loopback server by another host name (DNS rebinding)."""
    c = _client(tmp_path / "a")
    r = c.post("/api/jobs/current/resume", headers={"Origin": "http://evil.example"})
    assert r.status_code == 403 and "another site" in r.json()["detail"]
    r = c.post("/api/jobs/current/resume", headers={"Origin": "http://testserver"})
    assert r.status_code == 409  # its own page: the action is taken (no job here)
    with pytest.raises(WebSocketDisconnect) as closed, c.websocket_connect(
            "/api/ws", headers={"Origin": "http://evil.example"}) as ws:
        ws.receive_text()
    assert closed.value.code == 1008
    local = _client(tmp_path / "b", hosts=["localhost", "127.0.0.1"])
    assert local.get("/api/health").status_code == 400  # Host: testserver
    assert local.get("/api/health", headers={"Host": "127.0.0.1:8420"}).status_code == 200


def test_behind_a_token_the_api_description_is_too(tmp_path: Path) -> None:
    token, _ = load_or_make_token(tmp_path)
    c = _client(tmp_path, token=token)
    assert c.get("/openapi.json").status_code == 404 and c.get("/docs").status_code == 404
    assert c.get("/api/openapi.json").status_code == 401
    doc = c.get("/api/openapi.json", headers={"Authorization": f"Bearer {token}"}).json()
    assert "/api/jobs" in doc["paths"]


def test_a_token_file_others_can_read_is_refused(tmp_path: Path) -> None:
    load_or_make_token(tmp_path)
    os.chmod(tmp_path / "token", 0o644)
    with pytest.raises(TattotronixError, match="can be read by others"):
        load_or_make_token(tmp_path)


# ------------------------------------------------------------------ uploads and plans

@pytest.mark.parametrize(("data", "status", "match"), [
    (b"", 400, "empty"),
    (b"GIF89a....", 415, "not a PNG, JPEG or SVG"),
    (b"%PDF-1.7", 415, "not a PNG, JPEG or SVG"),
    (PNG_MAGIC + b"\x00\x00\x00\rIHDR", 422, "png"),  # truncated: the loader refuses it
    (b'<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="10mm">'
     b'<image href="file:///etc/passwd" width="10" height="10"/></svg>', 422, "external"),
])
def test_bad_uploads_get_one_message(tmp_path: Path, data: bytes, status: int,
                                     match: str) -> None:
    c = _client(tmp_path)
    r = c.post("/api/plans", files={"file": ("x.png", data, "image/png")},
               data={"width_mm": "24"})
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    assert isinstance(detail, str) and match.lower() in detail.lower(), detail
    assert "\n" not in detail.strip()
    assert list((tmp_path / "plans").iterdir()) == []  # a refused upload is not kept


def test_an_upload_over_the_limit_is_refused_and_stored_nowhere(tmp_path: Path,
                                                                 art: bytes) -> None:
    c = _client(tmp_path, max_upload_bytes=len(art) - 1)
    r = c.post("/api/plans", files={"file": ("big.png", art, "image/png")})
    assert r.status_code == 413 and "at most" in r.json()["detail"]
    assert list((tmp_path / "plans").iterdir()) == []


def test_sniffing_goes_by_content_not_by_name() -> None:
    assert sniff_kind(PNG_MAGIC + b"rest") == "png"
    assert sniff_kind(b"\xff\xd8\xff\xe0") == "jpg"
    assert sniff_kind(b'\xef\xbb\xbf<?xml version="1.0"?>\n<svg/>') == "svg"


def test_out_of_range_settings_and_placements(tmp_path: Path, art: bytes) -> None:
    c = _client(tmp_path)
    files = {"file": ("small.png", art, "image/png")}
    r = c.post("/api/plans", files=files, data={"width_mm": "-3"})
    assert r.status_code == 422
    r = c.post("/api/plans", files=files, data={"width_mm": "24", "fill": "zigzag"})
    assert r.status_code == 422 and "hatch" in r.json()["detail"]
    r = c.post("/api/plans", files=files, data={"width_mm": "24", "u_mm": "10"})
    assert r.status_code == 400 and "both" in r.json()["detail"]
    r = c.post("/api/plans", files=files, data={"width_mm": "24", "u_mm": "140",
                                               "v_mm": "0"})
    assert r.status_code == 422 and "panel" in r.json()["detail"]  # off the panel


@pytest.mark.slow
def test_a_plan_its_preview_and_its_path(tmp_path: Path, art: bytes) -> None:
    c = _client(tmp_path)
    info = _plan(c, art, rotate_deg="10", u_mm="5", v_mm="-3", fill="cross")
    assert info["name"] == "small" and info["stats"]["entries"] >= 2
    assert info["stats"]["duration_s"] > 0 and 0 < info["stats"]["coverage"] <= 1
    assert c.get(f"/api/plans/{info['id']}").json()["stats"] == info["stats"]
    png = c.get(f"/api/plans/{info['id']}/preview.png")
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content.startswith(PNG_MAGIC)
    path = c.get(f"/api/plans/{info['id']}/path").json()
    assert len(path["uv"]) == len(path["kind"]) and 1 in path["kind"]
    us = [p[0] for p, k in zip(path["uv"], path["kind"], strict=True) if k == 1]
    assert 5 - 14 < min(us) and max(us) < 5 + 14  # 24 mm wide, centred at u = 5
    assert c.get("/api/plans/nope").status_code == 404
    assert c.get("/api/plans/nope/preview.png").status_code == 404
    stored = tmp_path / "plans" / info["id"]
    assert (stored / "small.png").read_bytes() == art
    assert (stored / "data" / "trajectories" / "small.npz").is_file()
    traj = (stored / "data" / "trajectories" / "small.npz").read_bytes()
    again = _client(tmp_path)  # a restarted server plans it again on first use
    assert again.get(f"/api/plans/{info['id']}").json() == info
    assert again.get(f"/api/plans/{info['id']}/path").json() == path
    assert (stored / "data" / "trajectories" / "small.npz").read_bytes() == traj
    assert again.get("/api/plans/..%2F..%2Fjobs").status_code == 404
    schema = c.get("/openapi.json").json()
    for route in ("/api/plans", "/api/plans/strokes", "/api/plans/{pid}",
                  "/api/plans/{pid}/preview.png", "/api/plans/{pid}/path", "/api/jobs",
                  "/api/jobs/current", "/api/jobs/current/pause",
                  "/api/jobs/current/resume", "/api/jobs/current/stop",
                  "/api/plans/{pid}/predict", "/api/plans/{pid}/servo/{image}",
                  "/api/drafts"):
        assert route in schema["paths"], route


def test_a_draft_says_what_is_wrong_with_a_placement_at_once(tmp_path: Path,
                                                               art: bytes) -> None:
    c = _client(tmp_path)

    def draft(**form: str) -> dict[str, Any]:
        r = c.post("/api/drafts", files={"file": ("small.png", art, "image/png")},
                   data={"width_mm": "24", **form})
        assert r.status_code == 200, r.text
        return dict(r.json())

    ok = draft(u_mm="5", v_mm="-3")
    assert ok["stats"]["ok"] is True and ok["stats"]["problem"] is None
    assert ok["stats"]["entries"] >= 2 and "duration_s" not in ok["stats"]  # untimed
    us = [p[0] for p, k in zip(ok["uv"], ok["kind"], strict=True) if k == 1]
    assert 5 - 14 < min(us) and max(us) < 5 + 14
    off = draft(u_mm="95", v_mm="0")  # half of it past the panel's right edge (u = 100)
    assert off["stats"]["ok"] is False and "off the" in off["stats"]["problem"]
    assert "uv" not in off
    square = io.BytesIO()  # ink to its corners: one at the panel's far corner
    img = Image.new("L", (44, 44), 255)
    ImageDraw.Draw(img).rectangle([2, 2, 41, 41], fill=0)
    img.save(square, "PNG")
    r = c.post("/api/drafts", files={"file": ("square.png", square.getvalue(), "image/png")},
               data={"width_mm": "30", "u_mm": "84.5", "v_mm": "54.5"})
    far = r.json()["stats"]
    assert far["ok"] is False and "out of the arm's reach" in far["problem"], far
    assert c.post("/api/drafts", files={"file": ("a.png", b"GIF89a", "image/gif")}
                  ).status_code == 415
    assert c.post("/api/drafts", files={"file": ("a.png", art, "image/png")},
                  data={"u_mm": "3"}).status_code == 400  # the centre needs u and v
    r = c.post("/api/drafts", files={"file": ("a.png", art, "image/png")},
               data={"fill": "zigzag"})
    assert r.status_code == 422 and "fill" in r.json()["detail"]
    assert not list((tmp_path / "drafts").iterdir())  # nothing kept
    assert not list((tmp_path / "plans").iterdir())


@pytest.mark.slow
def test_the_servos_predicted_ink_beside_the_planned(tmp_path: Path, art: bytes) -> None:
    c = _client(tmp_path)
    pid = _plan(c, art)["id"]
    assert c.get(f"/api/plans/{pid}/servo/ink.png").status_code == 404  # not yet
    r = c.post(f"/api/plans/{pid}/predict", json={"servos": "mg996r"})
    assert r.status_code == 200, r.text
    res = r.json()
    assert res["metrics"]["backend"] == "servo" and res["metrics"]["verdict"]
    assert {"ink.png", "ink_vs_plan.png"} <= set(res["images"])
    png = c.get(f"/api/plans/{pid}/servo/ink_vs_plan.png")
    assert png.status_code == 200 and png.content.startswith(PNG_MAGIC)
    assert c.get(f"/api/plans/{pid}/servo/../../token").status_code == 404
    r = c.post(f"/api/plans/{pid}/predict", json={"servos": "nope"})
    assert r.status_code == 422


@pytest.mark.slow
def test_strokes_are_planned_and_bad_strokes_refused(tmp_path: Path) -> None:
    c = _client(tmp_path)
    r = c.post("/api/plans/strokes", json={"strokes": [[[-20, -10], [20, -10], [20, 10]],
                                                       [[-30, 15], [-10, 25]]]})
    assert r.status_code == 201, r.text
    assert r.json()["stats"]["entries"] == 2
    r = c.post("/api/plans/strokes", json={"strokes": [[[0, 0], [500, 0]]]})
    assert r.status_code == 422 and "off the panel" in r.json()["detail"]
    assert c.post("/api/plans/strokes", json={"strokes": []}).status_code == 422
    assert c.post("/api/plans/strokes", json={"strokes": "x"}).status_code == 422


# ------------------------------------------------------------------ jobs

def test_job_actions_without_a_job(tmp_path: Path) -> None:
    c = _client(tmp_path)
    assert c.get("/api/jobs/current").status_code == 404
    for action in ("pause", "resume", "stop"):
        r = c.post(f"/api/jobs/current/{action}")
        assert r.status_code == 409 and "no job" in r.json()["detail"], action
    assert c.post("/api/jobs", json={"plan": "nope"}).status_code == 404


@pytest.mark.slow
def test_a_job_pauses_with_the_needle_up_resumes_and_stops(tmp_path: Path, art: bytes,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    # each session of the job waits at its 200th frame of drawing until it is stopped, so
    # a pause is never late for it however busy the machine (the job is 24 s long)
    monkeypatch.setenv(TEST_HOOK_ENV, "draw:200:wait")
    # the server's process ignores SIGINT, as one a script starts in the background does:
    # its jobs' processes must still hear the pause
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        _pause_resume_and_stop(tmp_path, art, monkeypatch)
    finally:
        signal.signal(signal.SIGINT, previous)


def _pause_resume_and_stop(tmp_path: Path, art: bytes, monkeypatch: pytest.MonkeyPatch
                           ) -> None:
    c = _client(tmp_path)
    pid = _plan(c, art)["id"]
    r = c.post("/api/jobs", json={"plan": pid, "real": True})
    assert r.status_code == 400 and "confirm" in r.json()["detail"]  # the arm would move
    r = c.post("/api/jobs", json={"plan": pid, "realtime": True})
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["dry_run"] is True and job["status"] in ("starting", "drawing")
    st = _wait(c, lambda s: s["status"] == "drawing" and s["frame"] > 20)
    assert 0 < st["share"] < 1 and st["remaining_s"] < job["remaining_s"]
    assert st["tip_mm"] is not None and len(st["tip_mm"]) == 3
    with c.websocket_connect("/api/ws") as ws:  # a browser connecting mid-job
        live = json.loads(ws.receive_text())
        assert live["id"] == job["id"] and live["frames"] == st["frames"]
    r = c.post("/api/jobs", json={"plan": pid})
    assert r.status_code == 409 and "pause or stop it first" in r.json()["detail"]
    r = c.post("/api/jobs/current/pause")
    assert r.status_code == 200 and r.json()["status"] == "pausing"
    st = _wait(c, lambda s: s["status"] == "paused")
    assert "lift to the clearance height completed" in st["message"]
    assert st["arm_status"] == "paused" and st["tip_mm"][2] > 1.0  # the needle is up
    stopped_at = st["frame"]
    assert c.post("/api/jobs", json={"plan": pid}).status_code == 409  # resume or stop
    assert c.post("/api/jobs/current/resume").status_code == 200
    st = _wait(c, lambda s: s["status"] == "drawing" and s["frame"] > stopped_at)
    assert c.post("/api/jobs/current/stop").json()["status"] == "stopping"
    st = _wait(c, lambda s: s["status"] == "stopped")
    assert st["arm_status"] == "paused" and st["tip_mm"][2] > 1.0
    assert c.post("/api/jobs/current/resume").status_code == 409  # a stopped job is over
    monkeypatch.delenv(TEST_HOOK_ENV)
    r = c.post("/api/jobs", json={"plan": pid, "realtime": False})
    assert r.status_code == 201  # a new job may start
    st = _wait(c, lambda s: s["status"] in ("done", "failed"))
    assert st["status"] == "done", st
    assert st["frame"] == st["frames"] and st["share"] == 1.0


def _crash_mid_job(tmp_path: Path, art: bytes,
                   until: Callable[[dict[str, Any]], bool]) -> TestClient:
    """Start a job, wait ``until`` its state says so, kill its runner (SIGKILL: it dies
    with the server, a power cut), and restart the server on its folder."""
    c = _client(tmp_path)
    pid = _plan(c, art, width_mm="12")["id"]  # an 8 s drawing: the resume paces the rest
    assert c.post("/api/jobs", json={"plan": pid}).status_code == 201
    st = _wait(c, until)
    doc = json.loads((tmp_path / "jobs" / st["id"] / "job.json").read_text())
    os.kill(doc["pid"], signal.SIGKILL)
    time.sleep(0.5)
    return _client(tmp_path)


@pytest.mark.slow
def test_a_restarted_server_offers_to_resume_a_job_its_crash_cut(tmp_path: Path,
                                                                  art: bytes) -> None:
    again = _crash_mid_job(tmp_path, art,
                           lambda s: s["status"] == "drawing" and s["frame"] > 10)
    st = again.get("/api/jobs/current").json()
    assert st["status"] == "resumable" and "resume" in st["message"]
    assert st["arm_status"] == "drawing"  # what a session that died leaves
    assert again.post("/api/jobs/current/resume").status_code == 200
    done = _wait(again, lambda s: s["status"] in ("done", "failed"), timeout=300)
    assert done["status"] == "done" and done["frame"] == done["frames"], done
    (runs,) = (tmp_path / "jobs" / done["id"] / "metrics" / "runs").glob("*-arm.json")
    late = json.loads(runs.read_text())["late_ms"]  # paced: how late the frames went out
    assert -1.0 < late["median"] <= late["p99"] <= late["worst"]


@pytest.mark.slow
def test_stopping_a_job_whose_process_died_lifts_the_needle_first(tmp_path: Path,
                                                                   art: bytes) -> None:
    again = _crash_mid_job(tmp_path, art, lambda s: s["status"] == "drawing"
                           and s["frame"] > 10 and s["tip_mm"][2] < 0.5)  # needle in
    assert again.get("/api/jobs/current").json()["status"] == "resumable"
    r = again.post("/api/jobs/current/stop")
    assert r.status_code == 200 and r.json()["status"] == "stopping"
    st = _wait(again, lambda s: s["status"] in ("stopped", "failed"))
    assert st["status"] == "stopped", st
    assert "parked" in st["message"] and "the needle lifted" in st["message"]
    assert "every output is off" in st["message"]
    assert st["arm_status"] == "paused" and st["tip_mm"][2] > 1.0  # lifted from the work
    runs = tmp_path / "jobs" / st["id"] / "runs"
    last = [json.loads(x) for x in
            next(runs.glob("*-arm")).joinpath("poses.jsonl").read_text().splitlines()][-1]
    assert last["phase"] == "lift"  # the park sent the lift and nothing else
    assert again.post("/api/jobs/current/resume").status_code == 409  # stopped is over


def test_a_garbled_job_file_leaves_a_server_that_starts(tmp_path: Path) -> None:
    (tmp_path / "jobs" / "x").mkdir(parents=True)
    (tmp_path / "jobs" / "x" / "job.json").write_text("{not json")
    c = _client(tmp_path)
    assert c.get("/api/jobs/current").status_code == 404
    assert c.get("/api/health").json() == {"ok": True, "job": False}


def test_the_page_is_served_and_names_every_control(tmp_path: Path) -> None:
    html = _client(tmp_path).get("/").text
    for needle in ("/api/plans", "/api/plans/strokes", "/api/jobs", "/api/ws",
                   'id="pause"', 'id="resume"', 'id="stop"', "confirm("):
        assert needle in html, needle
    assert io.BytesIO(html.encode()).getbuffer().nbytes < 50_000


def _serve(tmp_path: Path, *args: str) -> tuple[Any, str, int]:
    """``tattotronix serve`` on a free port; (the process, its first lines, the port)."""
    import socket
    import subprocess
    import sys

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [sys.executable, "-m", "tattotronix.server.cli", "serve", "--port", str(port),
         "--folder", str(tmp_path / "srv"), *args],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    assert proc.stdout is not None
    while True:
        line = proc.stdout.readline()
        assert line, "".join(lines)
        lines.append(line)
        if line.startswith("serving "):
            break
    return proc, "".join(lines), port


def _get(port: int, path: str, token: str | None = None) -> int:
    import urllib.error
    import urllib.request

    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", headers=(
        {"Authorization": f"Bearer {token}"} if token else {}))
    end = time.monotonic() + 30
    while True:
        try:
            with urllib.request.urlopen(req, timeout=5) as r:
                return int(r.status)
        except urllib.error.HTTPError as exc:
            return int(exc.code)
        except OSError:
            assert time.monotonic() < end
            time.sleep(0.2)


@pytest.mark.slow
def test_serve_binds_locally_without_a_token_and_to_the_network_with_one(
        tmp_path: Path) -> None:
    proc, out, port = _serve(tmp_path)
    try:
        assert "token" not in out and _get(port, "/api/health") == 200
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    proc, out, port = _serve(tmp_path, "--host", "0.0.0.0")
    try:
        token = out.split("): ", 1)[1].split()[0]
        assert _get(port, "/api/health") == 401
        assert _get(port, "/api/health", token) == 200
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    proc, out, port = _serve(tmp_path, "--host", "0.0.0.0")  # printed once only
    try:
        assert token not in out and _get(port, "/api/health", token) == 200
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def _call(port: int, method: str, path: str, body: object | None = None) -> Any:
    import urllib.request

    req = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}", method=method,
        data=None if body is None else json.dumps(body).encode(),
        headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=300) as r:
        return json.loads(r.read())


@pytest.mark.slow
def test_a_server_killed_mid_job_restarts_and_the_job_resumes_to_the_end(
        tmp_path: Path) -> None:
    proc, _, port = _serve(tmp_path)
    try:
        _get(port, "/api/health")
        pid = _call(port, "POST", "/api/plans/strokes",
                    {"strokes": [[[-10, -5], [10, -5], [10, 5]], [[-15, 8], [-5, 12]]]}
                    )["id"]
        job = _call(port, "POST", "/api/jobs", {"plan": pid})
        end = time.monotonic() + 120
        while (st := _call(port, "GET", "/api/jobs/current"))["frame"] < 10:
            assert time.monotonic() < end, st
            time.sleep(0.2)
        runner = json.loads((tmp_path / "srv" / "jobs" / job["id"] / "job.json").read_text())
        # a power cut: the server and the job's process die at once
        proc.send_signal(signal.SIGKILL)
        os.kill(runner["pid"], signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    proc, _, port = _serve(tmp_path)  # restarted on its folder
    try:
        _get(port, "/api/health")
        st = _call(port, "GET", "/api/jobs/current")
        assert st["id"] == job["id"] and st["status"] == "resumable", st
        _call(port, "POST", "/api/jobs/current/resume")
        end = time.monotonic() + 300
        while (st := _call(port, "GET", "/api/jobs/current"))["status"] not in ("done",
                                                                                "failed"):
            assert time.monotonic() < end, st
            time.sleep(0.3)
        assert st["status"] == "done" and st["frame"] == st["frames"], st
    finally:
        proc.terminate()
        proc.wait(timeout=30)
