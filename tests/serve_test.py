#!/usr/bin/env python3
"""`occmap serve` end to end on a rendered lab scene, over real HTTP on 127.0.0.1 (ephemeral ports).

Usage: serve_test.py OCCMAP_BINARY SOURCE_DIR

Checks: a non-loopback --listen without a token exits 2; the chosen port is printed; /api/site;
/api/state advancing; /events delivering frame events; /metrics; the map PNG; a camera's JPEG
and MJPEG; POST /api/calibrate with true floor points of a camera (projected through the
site's own calibration) gives a sub-pixel RMS; PUT /api/site adding a zone writes a valid site
file with a .bak and the zone's count then appears in the frame events; a bad PUT is refused
with the loader's message and writes nothing; with a token, requests without it are refused
(the pages sent to /login) and with it (header, query or the session cookie POST /api/login
sets, HttpOnly and SameSite=Strict) accepted, and logout clears the cookie; path traversal (400) and an oversized body (413) are
refused; a cache folder that cannot be written is said once, not an error; SIGTERM stops it
(exit 0) with its outputs valid. Needs only python3.
"""
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from serve_lib import ServerTest  # noqa: E402

occmap, src = sys.argv[1], sys.argv[2]
h = ServerTest(occmap, "occmap-serve-test-")
check, start, work = h.check, h.start, h.work


def request(port, path, method="GET", body=None, headers=None, timeout=30):
    data = None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
    headers = dict(headers or {})
    if data is not None:
        headers.setdefault("Content-Type", "application/json")  # the only kind of body written
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return r.status, r.headers, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args, **kwargs):
        return None


def no_redirect(port, path, headers=None):
    """GET without following a redirect: its status, headers and body."""
    opener = urllib.request.build_opener(_NoRedirect)
    try:
        with opener.open(urllib.request.Request(f"http://127.0.0.1:{port}{path}", headers=headers or {}), timeout=30) as r:
            return r.status, r.headers, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def get_json(port, path, **kw):
    status, _, body = request(port, path, **kw)
    return status, json.loads(body) if body else None


def raw(port, text):
    """One request sent exactly as written; the status code of the answer."""
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        try:
            s.sendall(text if isinstance(text, bytes) else text.encode())
        except OSError:
            pass  # refused before the body was read
        data = b""
        while b"\r\n" not in data:
            chunk = s.recv(4096)
            if not chunk:
                break
            data += chunk
    return int(data[9:12]) if data.startswith(b"HTTP/1.1 ") else -1


def events(port, want, timeout_s=60, query=""):
    """Frame events (parsed) from /events until want(list) is true or the time is up."""
    frames = []
    with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as s:
        s.sendall(f"GET /events{query} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
        buf = b""
        deadline = time.time() + timeout_s
        while time.time() < deadline and not want(frames):
            try:
                chunk = s.recv(65536)
            except socket.timeout:
                break
            if not chunk:
                break
            buf += chunk
            # Chunked transfer: the SSE text is inside the chunks; events end with a blank line.
            while True:
                start = buf.find(b"event: frame\ndata: ")
                if start < 0:
                    break
                end = buf.find(b"\n\n", start)
                if end < 0:
                    break
                frames.append(json.loads(buf[start + len(b"event: frame\ndata: "):end]))
                buf = buf[end + 2:]
    return frames


try:
    # A lab scene of 100 frames (10 s at its 10 fps: serve plays files at their rate).
    lab = os.path.join(work, "lab")
    r = subprocess.run([occmap, "synth", "--scene", "lab", "--frames", "100", "--out", lab], capture_output=True)
    if r.returncode != 0:
        raise SystemExit("FAIL synth: " + r.stderr.decode())
    site = os.path.join(lab, "site.yaml")
    cache = os.path.join(work, "cache")

    # Exposed without a token: refused at start.
    r = subprocess.run([occmap, "serve", site, "--listen", "0.0.0.0:0"], capture_output=True, text=True, timeout=60)
    check(r.returncode == 2 and "token" in r.stderr, f"non-loopback without a token: exit 2 ({r.returncode}: {r.stderr.strip()})")

    out = os.path.join(work, "out")
    p, port = start([site, "--listen", "127.0.0.1:0", "--out", out, "--cache-dir", cache, "--no-video"], "serve")
    check(port > 0, f"listening on port {port}")

    status, s = get_json(port, "/api/site")
    check(status == 200 and s["name"] == "lab" and [c["id"] for c in s["cameras"]] == ["cam1", "cam2", "cam3", "cam4"]
          and s["grid"]["cols"] == 450 and s["grid"]["rows"] == 325 and "cameras:" in s["yaml"], "/api/site")

    # The state advances.
    first = None
    deadline = time.time() + 120
    while time.time() < deadline:
        status, st = get_json(port, "/api/state")
        if st["frame"] >= 0:
            first = first if first is not None else st["frame"]
            if st["frame"] > first:
                break
        time.sleep(0.2)
    check(first is not None and st["frame"] > first and st["running"] and len(st["cameras"]) == 4,
          f"/api/state advances ({first} -> {st['frame']})")

    fr = events(port, lambda f: len(f) >= 3)
    check(len(fr) >= 3 and fr[-1]["frame"] > fr[0]["frame"] and {"detections", "tracks", "zones", "lines", "map_version"} <= set(fr[0]),
          f"/events delivers frame events ({[f['frame'] for f in fr]})")

    status, headers, body = request(port, "/metrics")
    text = body.decode()
    check(status == 200 and "occmap_frames_total " in text and 'occmap_camera_up{camera="cam1"} 1' in text
          and 'occmap_latency_seconds{quantile="0.5"}' in text, "/metrics")

    status, headers, body = request(port, "/api/map.png")
    check(status == 200 and body[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(body[16:20], "big") == 450
          and int.from_bytes(body[20:24], "big") == 325, "/api/map.png: 450 x 325")
    status, headers, body = request(port, "/api/cameras/cam1/frame.jpg")
    check(status == 200 and body[:2] == b"\xff\xd8" and headers["Content-Type"] == "image/jpeg", "cam1 frame.jpg")
    with socket.create_connection(("127.0.0.1", port), timeout=30) as sk:
        sk.sendall(b"GET /api/cameras/cam2/mjpeg HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        got = b""
        try:
            while got.count(b"--occmapframe") < 2 and len(got) < 10_000_000:
                chunk = sk.recv(65536)
                if not chunk:
                    break
                got += chunk
        except socket.timeout:
            pass  # the run may have ended: one picture then
    check(b"multipart/x-mixed-replace" in got and b"Content-Type: image/jpeg" in got and b"\xff\xd8" in got,
          "cam2 MJPEG: a JPEG part")

    # Calibrate cam1 from true floor points (its own calibration's projections).
    floor = ["1,1", "3,1", "5,2", "2,4", "6,5", "4,3", "8,1", "1,6", "7,3", "3,5.5"]
    csv = subprocess.run([sys.executable, os.path.join(src, "tests", "project_floor_points.py"),
                          os.path.join(lab, "calib", "intr_cam1.xml"), os.path.join(lab, "calib", "extr_cam1.xml")] + floor,
                         capture_output=True, text=True, check=True).stdout
    points = []
    for line in csv.splitlines()[1:]:
        u, v, x, y, _ = line.split(",")
        if 0 <= float(u) < 640 and 0 <= float(v) < 480:
            points.append({"u_px": float(u), "v_px": float(v), "x_m": float(x), "y_m": float(y)})
    status, cal = get_json(port, "/api/calibrate", method="POST", body={"camera": "cam1", "points": points},
                           headers={"Content-Type": "application/json"})
    check(status == 200 and len(points) >= 4 and cal["rms_px"] < 1.0 and cal["floor_rms_m"] < 0.02,
          f"calibrate cam1 from {len(points)} points: RMS {cal.get('rms_px') if cal else None} px, floor {cal.get('floor_rms_m') if cal else None} m")
    status, headers, body = request(port, cal["overlay_url"])
    check(status == 200 and body[:2] == b"\xff\xd8", "the pending calibration's grid overlay")
    status, bad = get_json(port, "/api/calibrate", method="POST", body={"camera": "cam1", "points": points[:2]})
    check(status == 400 and "error" in bad, f"calibrate with 2 points: 400 ({bad})")

    # A bad edit: the loader's message, nothing written.
    before = open(site).read()
    status, bad = get_json(port, "/api/site", method="PUT", body={"zones": [{"name": "z", "polygon_m": [[0, 0], [1, 0]]}]})
    check(status == 400 and "site.yaml" in bad.get("error", "") and open(site).read() == before
          and not os.path.exists(site + ".bak"), f"PUT a two-point zone: 400 ({bad})")

    # Save a zone over the whole floor and cam1's pending calibration.
    zone = {"name": "everywhere", "polygon_m": [[0, 0], [9, 0], [9, 6.5], [0, 6.5]]}
    status, put = get_json(port, "/api/site", method="PUT", body={"zones": [zone], "calibrations": {"cam1": "pending"}})
    check(status == 200 and put["ok"] and put["site"]["zones"][0]["name"] == "everywhere", f"PUT /api/site ({status})")
    check(os.path.exists(site + ".bak") and open(site + ".bak").read() == before, "site.yaml.bak holds the previous file")
    r = subprocess.run([occmap, "check", site], capture_output=True, text=True)
    check(r.returncode == 0 and "everywhere" in open(site).read(), f"the saved site is valid ({r.stderr.strip()})")
    fr = events(port, lambda f: any(z["name"] == "everywhere" and z["count"] > 0 for e in f for z in e["zones"]), 120)
    counts = [z["count"] for e in fr for z in e["zones"] if z["name"] == "everywhere"]
    check(counts and max(counts) > 0, f"the zone's count in the frame events after the restart (max {max(counts) if counts else None})")

    # Traversal and size.
    for target in ["/../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2fsite.yaml", "/a%5c..%5cb"]:
        code = raw(port, f"GET {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
        check(code == 400, f"GET {target}: 400 ({code})")
    big = b"x" * (1536 * 1024)
    code = raw(port, b"PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: %d\r\n"
               b"Connection: close\r\n\r\n" % len(big) + big)
    check(code == 413, f"1.5 MiB body: 413 ({code})")

    # A cache that cannot be written (a file where its folder should be: the tests may run as
    # root, whom no mode stops) is said once and the pipeline runs: a cache is no output.
    blocked = os.path.join(work, "blocked-cache")
    open(blocked, "w").write("not a folder")
    p3, port3 = start([site, "--listen", "127.0.0.1:0", "--out", os.path.join(work, "out3"), "--cache-dir", blocked,
                       "--no-video"], "serve-blocked-cache")
    deadline = time.time() + 120
    st = {"frame": -1}
    while time.time() < deadline and st["frame"] < 0:
        st = get_json(port3, "/api/state")[1]
        time.sleep(0.2)
    said = open(os.path.join(work, "serve-blocked-cache.log")).read()
    check(st["frame"] >= 0 and said.count(f"could not write the table cache {blocked}/lab.lut: ") == 1
          and "going on without it" in said, f"a cache that cannot be written: said once, the run goes on ({said.strip()[-300:]})")
    p3.send_signal(signal.SIGTERM)
    check(p3.wait(timeout=60) == 0, "the server with a blocked cache stops on SIGTERM")

    # A token: refused without, accepted with.
    p2, port2 = start([site, "--listen", "127.0.0.1:0", "--token", "t0ken", "--out", os.path.join(work, "out2"),
                       "--cache-dir", cache, "--no-video"], "serve-token")
    for path in ["/api/site", "/events", "/metrics", "/api/cameras/cam1/frame.jpg"]:
        status, _, _ = request(port2, path)
        check(status == 401, f"{path} without the token: 401 ({status})")
    check(request(port2, "/api/site?token=wrong")[0] == 401, "a wrong token: 401")
    check(request(port2, "/api/site?token=t0ken")[0] == 200, "?token=: 200")
    check(request(port2, "/api/site", headers={"Authorization": "Bearer t0ken"})[0] == 200, "Bearer: 200")
    # The pages send a browser to /login; signing in there sets the session cookie, which the API takes.
    status, headers, _ = no_redirect(port2, "/system")
    check(status == 303 and headers["Location"] == "/login?next=/system", f"/system without the token: 303 to /login ({status})")
    status, _, body = request(port2, "/login")
    check(status == 200 and b"/api/login" in body, f"the login page needs no token ({status})")
    check(request(port2, "/api/login", method="POST", body={"token": "wrong"})[0] == 401, "login with a wrong token: 401")
    status, headers, _ = request(port2, "/api/login", method="POST", body={"token": "t0ken"})
    cookie = headers.get("Set-Cookie", "")
    check(status == 200 and cookie == "occmap_token=74306b656e; Path=/; Max-Age=2592000; HttpOnly; SameSite=Strict",
          f"login: 200 and an HttpOnly, SameSite=Strict cookie ({status}, {cookie})")
    jar = {"Cookie": cookie.split(";")[0]}
    check(request(port2, "/api/site", headers=jar)[0] == 200, "the session cookie: 200")
    check(get_json(port2, "/api/session", headers=jar)[1] == {"token_required": True, "signed_in": True, "via": "cookie"},
          "/api/session with the cookie")
    status, headers, _ = no_redirect(port2, "/?token=t0ken")
    check(status == 303 and headers["Location"] == "/" and "HttpOnly" in headers.get("Set-Cookie", ""),
          f"the page with ?token=: the cookie set, sent to / ({status})")
    status, headers, _ = request(port2, "/api/logout", method="POST", body={}, headers=jar)
    check(status == 200 and "Max-Age=0" in headers.get("Set-Cookie", ""), f"logout clears the cookie ({status})")
    p2.send_signal(signal.SIGTERM)
    check(p2.wait(timeout=60) == 0, "the token server stops on SIGTERM")

    # SIGTERM: a clean stop, outputs valid.
    t0 = time.time()
    p.send_signal(signal.SIGTERM)
    code = p.wait(timeout=60)
    check(code == 0, f"SIGTERM: exit {code} in {time.time() - t0:.1f} s")
    r = subprocess.run([sys.executable, os.path.join(src, "tests", "check_run_outputs.py"), out, "final"],
                       capture_output=True, text=True)
    check(r.returncode == 0, f"outputs valid after SIGTERM {r.stdout.strip()}")
finally:
    code = h.finish()
sys.exit(code)
