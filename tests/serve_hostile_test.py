#!/usr/bin/env python3
"""`occmap serve` against hostile requests, over real HTTP on 127.0.0.1 (a lab scene at quarter size).

Usage: serve_hostile_test.py OCCMAP_BINARY

Checks, each with the server up afterwards (GET /api/state 200):
- deep JSON (100,000 levels) in every write route's fields: 400 "nesting deeper than 64 levels"
  (was a SIGSEGV in the message's dump()); a 1 MB value is never echoed whole;
- DNS rebinding: a foreign Host is refused (403) for reads and writes; localhost, 127.0.0.1 and
  an --allow-host name are served; the same for `occmap fuse --listen` and its --allow-host;
- cross-site writes: Origin of another site, Sec-Fetch-Site cross-site or same-site, a body
  that is not application/json: refused, nothing changed; the same origin's JSON is taken;
- bodies: a chunked body is cut at 1 MiB (413, the server's memory does not grow by the 64 MiB
  sent); a POST with neither Content-Length nor chunked is answered at once as an empty body;
- slow clients: 40 connections sending a header line a second do not stop the API, and each is
  cut after the header deadline;
- a token of one character beyond loopback is refused at start (exit 2).
Needs only python3.
"""
import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from serve_lib import ServerTest  # noqa: E402

occmap = sys.argv[1]
h = ServerTest(occmap, "occmap-serve-hostile-")
check, start, work = h.check, h.start, h.work


def exchange(port, head, body=b"", timeout=30):
    """One request as written (head without the blank line); (status, parsed JSON body or text)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        data = head.encode() + b"\r\n" + body
        try:
            s.sendall(data)
        except OSError:
            pass  # refused before the body was read
        got = b""
        try:
            while True:
                chunk = s.recv(65536)
                if not chunk:
                    break
                got += chunk
                end = got.find(b"\r\n\r\n")
                if end >= 0:
                    headers = got[:end].decode(errors="replace").lower()
                    length = [int(h.split(":")[1]) for h in headers.split("\r\n") if h.startswith("content-length:")]
                    if length and len(got) >= end + 4 + length[0]:
                        break
        except (socket.timeout, ConnectionResetError):
            pass
    if not got.startswith(b"HTTP/1.1 "):
        return -1, got[:200]
    status = int(got[9:12])
    payload = got[got.find(b"\r\n\r\n") + 4:]
    try:
        return status, json.loads(payload)
    except ValueError:
        return status, payload[:200]


def request(port, method, path, body=None, host=None, headers=None, content_type="application/json"):
    data = b"" if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
    lines = [f"{method} {path} HTTP/1.1", f"Host: {host or f'127.0.0.1:{port}'}", "Connection: close"]
    if body is not None:
        lines.append(f"Content-Length: {len(data)}")
        if content_type:
            lines.append(f"Content-Type: {content_type}")
    lines += [f"{k}: {v}" for k, v in (headers or {}).items()]
    return exchange(port, "\r\n".join(lines) + "\r\n", data)


def up(port):
    status, st = request(port, "GET", "/api/state")
    return status == 200 and isinstance(st, dict) and "frame" in st


def rss_kb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return -1


def error_of(reply):
    return reply.get("error", "") if isinstance(reply, dict) else str(reply)


try:
    lab = os.path.join(work, "lab")
    r = subprocess.run([occmap, "synth", "--scene", "lab", "--frames", "60", "--scale", "0.25", "--out", lab],
                       capture_output=True)
    if r.returncode != 0:
        raise SystemExit("FAIL synth: " + r.stderr.decode())
    site = os.path.join(lab, "site.yaml")
    before = open(site).read()

    # A token of one character is no gate beyond loopback.
    r = subprocess.run([occmap, "serve", site, "--listen", "0.0.0.0:0", "--token", "a"], capture_output=True, text=True,
                       timeout=60)
    check(r.returncode == 2 and "16 characters" in r.stderr, f"--token a on 0.0.0.0: exit 2 ({r.returncode}: {r.stderr.strip()})")

    p, port = start([site, "--listen", "127.0.0.1:0", "--out", os.path.join(work, "out"), "--no-cache", "--no-video",
                     "--allow-host", "occmap.test"], "serve")
    check(up(port), "the server answers")

    # --- 1. Deep JSON ------------------------------------------------------------------------
    deep = "[" * 100000 + "]" * 100000
    for method, path, text in [
        ("POST", "/api/calibrate", '{"camera": "cam1", "points": [%s]}' % deep),
        ("POST", "/api/board/views", '{"camera": "cam1", "board": %s, "capture": true}' % deep),
        ("POST", "/api/board/calibrate", '{"camera": "cam1", "board": {"kind": %s}}' % deep),
        ("PUT", "/api/site", '{"zones": [{"name": "z", "polygon_m": %s}]}' % deep),
        ("PUT", "/api/site", '{"lines": %s}' % deep),
        ("PUT", "/api/site", '{"mask_polygons_px": {"cam1": %s}}' % deep),
    ]:
        status, reply = request(port, method, path, text.encode())
        check(status == 400 and "nesting deeper than 64 levels" in error_of(reply) and up(port),
              f"{method} {path} 100,000 deep: 400, up ({status}: {error_of(reply)[:100]})")
    big = "x" * 1_000_000
    for method, path, body in [("PUT", "/api/site", {"zones": big}), ("PUT", "/api/site", {"zones": [{"name": big}]}),
                               ("POST", "/api/calibrate", {"camera": "cam1", "points": [big]}),
                               ("POST", "/api/calibrate", {"camera": big, "points": []}),
                               ("PUT", "/api/site", {big: 1})]:
        status, reply = request(port, method, path, body)
        check(status == 400 and len(error_of(reply)) < 400 and "bytes)" in error_of(reply),
              f"{method} {path} with a 1 MB value: 400, cut ({status}: {len(error_of(reply))} bytes: {error_of(reply)[:120]})")

    # --- 2. Host and Origin ------------------------------------------------------------------
    for host in ["attacker.example", f"attacker.example:{port}", "127.0.0.1.attacker.example"]:
        status, reply = request(port, "GET", "/api/site", host=host)
        check(status == 403 and "--allow-host" in error_of(reply), f"GET /api/site, Host: {host}: 403 ({status})")
    status, _ = request(port, "PUT", "/api/site", {"zones": []}, host=f"attacker.example:{port}")
    check(status == 403 and open(site).read() == before, f"PUT /api/site, Host: attacker.example: 403, site unchanged ({status})")
    for host in [f"localhost:{port}", f"127.0.0.1:{port}", f"occmap.test:{port}", f"OCCMAP.TEST.:{port}", f"[::1]:{port}"]:
        status, _ = request(port, "GET", "/api/site", host=host)
        check(status == 200, f"GET /api/site, Host: {host}: 200 ({status})")
    write = {"camera": "cam1", "points": []}
    for name, kw, want in [
        ("Origin of another site", {"headers": {"Origin": "http://attacker.example"}}, 403),
        ("Origin of another port", {"headers": {"Origin": "http://127.0.0.1:1"}}, 403),
        ("Origin null", {"headers": {"Origin": "null"}}, 403),
        ("Sec-Fetch-Site: cross-site", {"headers": {"Sec-Fetch-Site": "cross-site"}}, 403),
        ("Sec-Fetch-Site: same-site", {"headers": {"Sec-Fetch-Site": "same-site"}}, 403),
        ("text/plain", {"content_type": "text/plain"}, 415),
        ("a form", {"content_type": "application/x-www-form-urlencoded"}, 415),
        ("no Content-Type", {"content_type": None}, 415),
        ("the same origin", {"headers": {"Origin": f"http://127.0.0.1:{port}", "Sec-Fetch-Site": "same-origin"}}, 400),
        ("no Origin (curl)", {}, 400),
    ]:
        status, reply = request(port, "POST", "/api/calibrate", write, **kw)
        # 400 is the handler's own answer to no points: the request got through.
        check(status == want, f"POST /api/calibrate, {name}: {want} ({status}: {error_of(reply)[:100]})")
    status, _ = request(port, "DELETE", "/api/board/views?camera=cam1", headers={"Origin": "http://attacker.example"})
    check(status == 403, f"DELETE from another origin: 403 ({status})")
    status, _ = request(port, "PATCH", "/api/site", {"zones": []})
    check(status == 405, f"PATCH: 405 ({status})")

    # --- 4. Bodies -----------------------------------------------------------------------------
    rss0 = rss_kb(p.pid)
    sent = 0
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        s.sendall(f"PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
                  "Transfer-Encoding: chunked\r\n\r\n".encode())
        chunk = b"%x\r\n" % (64 << 10) + b" " * (64 << 10) + b"\r\n"
        try:
            # As a client would: stop sending once the server has answered.
            while sent < (64 << 20) and not select.select([s], [], [], 0)[0]:
                s.sendall(chunk)
                sent += 64 << 10
        except OSError:
            pass  # cut at the limit
        try:
            got = s.recv(4096)
        except OSError:
            got = b""
    rss1 = rss_kb(p.pid)
    check(got.startswith(b"HTTP/1.1 413") and sent < (64 << 20) and rss1 - rss0 < 32 * 1024,
          f"64 MiB chunked: 413 after {sent >> 20} MiB sent, RSS {rss0 // 1024} -> {rss1 // 1024} MB ({got[:40]!r})")
    check(up(port), "up after the chunked body")
    t0 = time.time()
    status, reply = exchange(port, f"POST /api/calibrate HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n")
    took = time.time() - t0
    check(status == 400 and "expected JSON" in error_of(reply) and took < 5,
          f"POST without a length: an empty body, answered in {took:.1f} s ({status}: {error_of(reply)})")
    status, reply = exchange(port, f"POST /api/calibrate HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
                             "Transfer-Encoding: chunked\r\n", b"5\r\n[1,2]\r\n0\r\n\r\n")
    check(status == 400 and "JSON object" in error_of(reply), f"a small chunked body is read ({status}: {error_of(reply)})")
    status, reply = request(port, "POST", "/api/nowhere", b"x" * 100)
    check(status == 404, f"POST to no route: 404 ({status})")

    # --- 4. Slow headers ----------------------------------------------------------------------
    stop = threading.Event()
    cut_after = []

    def slow_client():
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=60) as s:
                t_open = time.time()
                s.sendall(f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode())
                n = 0
                while not stop.is_set():
                    try:
                        s.sendall(f"X-Slow-{n}: 1\r\n".encode())
                    except OSError:
                        cut_after.append(time.time() - t_open)
                        return
                    n += 1
                    stop.wait(1.0)
        except OSError:
            cut_after.append(-1)

    clients = [threading.Thread(target=slow_client, daemon=True) for _ in range(40)]
    for c in clients:
        c.start()
    time.sleep(2)
    answered = []
    for _ in range(5):
        t0 = time.time()
        ok = up(port)
        answered.append((ok, time.time() - t0))
        time.sleep(0.5)
    check(all(ok for ok, _ in answered), f"the API answers under 40 slow clients ({[f'{d:.1f}s' for _, d in answered]})")
    time.sleep(10)
    stop.set()
    for c in clients:
        c.join(timeout=5)
    check(len(cut_after) == 40 and all(0 <= t < 15 for t in cut_after),
          f"every slow client is cut (after {sorted(round(t, 1) for t in cut_after)[:3]}..{max(cut_after, default=-1):.1f} s)")
    check(up(port) and open(site).read() == before, "up at the end, the site file unchanged")

    p.send_signal(signal.SIGTERM)
    check(p.wait(timeout=60) == 0, "SIGTERM: exit 0")

    # --- 2. Host for `occmap fuse --listen`: the same check, with its own --allow-host. No broker
    # listens on the port given: the fuse waits for one with its view up.
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        broker_port = free.getsockname()[1]
    f, fport = start([site, "--listen", "127.0.0.1:0", "--broker", f"mqtt://127.0.0.1:{broker_port}", "--no-cache",
                      "--no-video", "--out", os.path.join(work, "fuse"), "--allow-host", "occmap.test"], "fuse", "fuse")
    for host, want in [("attacker.example", 403), (f"attacker.example:{fport}", 403), (f"occmap.test:{fport}", 200),
                       (f"localhost:{fport}", 200), (f"127.0.0.1:{fport}", 200)]:
        status, reply = request(fport, "GET", "/api/site", host=host)
        check(status == want and (want == 200 or "--allow-host" in error_of(reply)),
              f"fuse: GET /api/site, Host: {host}: {want} ({status})")
    f.send_signal(signal.SIGTERM)
    check(f.wait(timeout=60) == 0, "fuse: SIGTERM: exit 0")
finally:
    code = h.finish()
sys.exit(code)
