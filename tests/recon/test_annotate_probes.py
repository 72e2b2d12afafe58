"""recon annotate against hostile and unlucky use: two processes saving one file at the same
moment, idle connections by the dozen, a photo swapped for a link after the start, the token
looked for on command lines, a private file's backup, JSON nested to the stack's end."""

import json
import multiprocessing as mp
import os
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from starlette.testclient import TestClient

from recon.annotate import AnnotationSession, create_app
from recon.annotate.server import TOKEN_HEADER, login_cookie, make_server
from recon.annotate.session import SaveConflict

ROOT = Path(__file__).resolve().parents[2]
TOKEN = "t0ken-for-probes"
BASE = "http://127.0.0.1:8765"


def _photo(path, size, seed=0):
    rng = np.random.default_rng(seed)
    Image.fromarray(rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)).save(path)
    return path


@pytest.fixture
def photos(tmp_path):
    return _photo(tmp_path / "front.png", (320, 400), 1), _photo(tmp_path / "side.png", (300, 400), 2)


# --- two processes, one file -----------------------------------------------------------

def _saver(front, side, fdp, k, barrier, results, trials):
    """One recon annotate process's session: each trial, save a point of its own at the
    same moment as the other process, report what it was told, then load the file again."""
    s = AnnotationSession(front, side, fdp, detect=False)
    views = AnnotationSession.views_json(s.views)
    for t in range(trials):
        views["front"]["points"]["2.1"] = [100.0 + k, 100.0 + t]
        barrier.wait()
        try:
            s.save(views)
            results.put((t, k, "saved"))
        except SaveConflict:
            results.put((t, k, "conflict"))
        barrier.wait()
        s.load()  # both start the next trial from what is on disk
        barrier.wait()
    s.close()


def test_two_processes_saving_one_file_at_once_lose_nothing(photos, tmp_path):
    fdp = tmp_path / "person.fdp.json"
    s = AnnotationSession(*photos, fdp, detect=False)
    s.save(AnnotationSession.views_json(s.views))  # both processes start from the same file
    s.close()
    trials = 12
    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(2), ctx.Queue()
    procs = [ctx.Process(target=_saver, args=(*photos, fdp, k, barrier, results, trials)) for k in (0, 1)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(180)
        assert p.exitcode == 0
    told = {}
    while not results.empty():
        t, k, what = results.get()
        told.setdefault(t, {})[k] = what
    assert len(told) == trials
    for t, answers in told.items():
        # Exactly one save per trial; the other process is told of it, as a second tab is.
        assert sorted(answers.values()) == ["conflict", "saved"], (t, answers)


# --- connections ------------------------------------------------------------------------

@pytest.fixture
def served(photos, tmp_path):
    """A real server (uvicorn, the guarded protocol) on a free port with short limits."""
    s = AnnotationSession(*photos, tmp_path / "person.fdp.json", detect=False)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(128)
    server = make_server(create_app(s, TOKEN), idle_timeout=1.0, max_connections=8)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    port = sock.getsockname()[1]
    for _ in range(100):
        if server.started:
            break
        time.sleep(0.05)
    yield port
    server.should_exit = True
    thread.join(10)
    sock.close()
    s.close()


def _get(port, path, headers=None, timeout=5.0):
    import http.client

    c = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    c.request("GET", path, headers={"Host": f"127.0.0.1:{port}", TOKEN_HEADER: TOKEN, **(headers or {})})
    r = c.getresponse()
    body = r.read()
    c.close()
    return r.status, body


def test_idle_connections_neither_lock_the_page_out_nor_stay_open(served):
    port = served
    idle = []
    for _ in range(40):  # five times what one client may hold, none sending a byte
        s = socket.create_connection(("127.0.0.1", port))
        idle.append(s)
    t0 = time.monotonic()
    status, body = _get(port, "/api/state")
    assert status == 200 and b"catalogue" in body and time.monotonic() - t0 < 3
    # A slow trickle of header bytes does not keep a connection either.
    slow = socket.create_connection(("127.0.0.1", port))
    for _ in range(4):
        slow.sendall(b"G")
        time.sleep(0.4)
    time.sleep(1.5)
    for s in idle + [slow]:
        s.settimeout(2)
        try:
            assert s.recv(1) == b""  # closed by the server
        except ConnectionResetError:
            pass
        s.close()
    assert _get(port, "/api/state")[0] == 200


def test_a_slow_answer_is_not_cut_by_the_idle_timeout(served, monkeypatch):
    from recon.annotate import session as session_module

    port = served
    real = session_module.AnnotationSession.state

    def slow_state(self):
        time.sleep(2.5)  # longer than the 1 s idle timeout: the app's own time
        return real(self)

    monkeypatch.setattr(session_module.AnnotationSession, "state", slow_state)
    status, body = _get(port, "/api/state", timeout=10)
    assert status == 200 and b"catalogue" in body


# --- the photos as they were at the start ---------------------------------------------

def test_a_photo_swapped_for_a_link_after_the_start_is_not_served(photos, tmp_path):
    s = AnnotationSession(*photos, tmp_path / "person.fdp.json", detect=False)
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    original = photos[0].read_bytes()
    secret = tmp_path / "secret.txt"
    secret.write_text("private key material")
    photos[0].unlink()
    photos[0].symlink_to(secret)
    r = c.get("/api/photo/front")
    assert r.status_code == 200 and r.content == original and b"private" not in r.content
    photos[0].unlink()
    photos[0].write_bytes(b"replaced")
    assert c.get("/api/photo/front").content == original
    s.close()


# --- the token ------------------------------------------------------------------------

def test_the_token_is_on_no_command_line_and_the_address_works_once(photos, tmp_path):
    """The browser is started with a one-time code; the session's token never leaves the
    server but as an HTTP-only cookie."""
    record = tmp_path / "argv.json"
    fake = tmp_path / "browser.py"
    fake.write_text(f"import json, sys\njson.dump(sys.argv, open({str(record)!r}, 'w'))\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT), BROWSER=f"{sys.executable} {fake} %s")
    proc = subprocess.Popen([sys.executable, "-m", "recon", "annotate", *map(str, photos), "--fdp",
                             str(tmp_path / "p.fdp.json"), "--no-detect"], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        printed = proc.stdout.readline().split(" ", 1)[1].strip()
        for _ in range(100):
            if record.exists() and record.stat().st_size:
                break
            time.sleep(0.1)
        argv = json.loads(record.read_text())
        opened = argv[-1]
        assert "?code=" in opened and "token" not in opened and opened != printed
        port = int(opened.split(":")[2].split("/")[0])
        import http.client

        def visit(url, cookie=None):
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
            path = url.split(str(port), 1)[1] if url.startswith("http") else url
            c.request("GET", path, headers={"Host": f"127.0.0.1:{port}", **({"Cookie": cookie} if cookie else {})})
            r = c.getresponse()
            r.read()
            return r

        first = visit(opened)
        assert first.status == 303 and first.getheader("location") == "/"
        set_cookie = first.getheader("set-cookie")
        assert set_cookie and "httponly" in set_cookie.lower() and "samesite=strict" in set_cookie.lower()
        name, value = set_cookie.split(";")[0].split("=", 1)
        assert name == login_cookie(value) and value not in opened and value not in printed
        assert visit(opened).getheader("set-cookie") is None  # the code is dead once used
        assert visit("/api/state", f"{name}={value}").status == 200
        assert visit("/api/state").status == 401
        # The process list shows neither the token nor a live code.
        ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
        assert value not in ps
    finally:
        proc.terminate()
        proc.wait(10)


def test_another_sites_page_cannot_use_the_cookie(photos, tmp_path):
    s = AnnotationSession(*photos, tmp_path / "person.fdp.json", detect=False)
    c = TestClient(create_app(s, TOKEN), base_url=BASE)
    c.cookies.set(login_cookie(TOKEN), TOKEN)
    assert c.get("/api/state", headers={"sec-fetch-site": "same-origin"}).status_code == 200
    for site in ("same-site", "cross-site"):  # another port of 127.0.0.1 is the same site
        assert c.get("/api/state", headers={"sec-fetch-site": site}).status_code == 403
    s.close()


# --- the backup and the body ------------------------------------------------------------

def test_the_backup_keeps_the_private_files_permissions(photos, tmp_path):
    fdp = tmp_path / "person.fdp.json"
    first = AnnotationSession(*photos, fdp, detect=False)
    first.save(AnnotationSession.views_json(first.views))
    first.close()
    os.chmod(fdp, 0o600)
    old_umask = os.umask(0o022)
    try:
        s = AnnotationSession(*photos, fdp, detect=False)  # a file from before: backed up on save
        views = AnnotationSession.views_json(s.views)
        views["front"]["points"]["2.1"] = [10.0, 20.0]
        s.save(views)
        s.close()
    finally:
        os.umask(old_umask)
    backup = fdp.with_name(fdp.name + ".bak")
    assert stat.S_IMODE(backup.stat().st_mode) == 0o600 and stat.S_IMODE(fdp.stat().st_mode) == 0o600


def test_json_nested_to_the_stacks_end_is_a_400_not_a_500(photos, tmp_path):
    s = AnnotationSession(*photos, tmp_path / "person.fdp.json", detect=False)
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    deep = b'{"views": ' + b"[" * 200000 + b"]" * 200000 + b"}"
    r = c.put("/api/fdp", content=deep, headers={"content-type": "application/json"})
    assert r.status_code == 400 and "nested 200001 levels deep" in r.json()["error"]
    r = c.put("/api/fdp", content=b'{"views": {}, "views": {}}', headers={"content-type": "application/json"})
    assert r.status_code == 400 and "appears twice" in r.json()["error"]
    assert not s.fdp_path.exists()
    s.close()


def test_annotate_says_in_one_line_why_detection_failed(tmp_path):
    """Photos with no face: detection fails, the tool goes on from the generic head, and the
    terminal shows one line why, no traceback."""
    pytest.importorskip("mediapipe", reason="mediapipe is not installed (bash install.sh)")
    front = _photo(tmp_path / "front.png", (640, 800), 3)
    side = _photo(tmp_path / "side.png", (640, 800), 4)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "recon", "annotate", str(front), str(side), "--no-browser"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().split(" ", 1)[1].strip()
        port = int(url.split(":")[2].split("/")[0])
        import http.client

        c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        c.request("GET", url.split(str(port), 1)[1], headers={"Host": f"127.0.0.1:{port}"})
        cookie = c.getresponse().getheader("set-cookie").split(";")[0]
        c.close()
        c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        c.request("GET", "/api/state", headers={"Host": f"127.0.0.1:{port}", "Cookie": cookie})
        state = json.loads(c.getresponse().read())
        assert state["initialisation"]["source"] == "generic"
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=20)
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if "automatic detection failed" in line]
    assert len(lines) == 1 and "front.png" in lines[0], err
