"""What the tests of `occmap serve` and `occmap fuse --listen` share: checks that count their
failures, servers started on a free port of 127.0.0.1 (the port read from the first line on
stdout) and stopped at the end, their logs printed when something failed.

    h = ServerTest(sys.argv[1], "occmap-serve-test-")
    try:
        p, port = h.start([site, "--listen", "127.0.0.1:0"], "serve")
        h.check(port > 0, "listening")
    finally:
        code = h.finish()
    sys.exit(code)
"""
import os
import shutil
import subprocess
import sys
import tempfile


class ServerTest:
    def __init__(self, occmap, prefix):
        self.occmap = occmap
        self.work = tempfile.mkdtemp(prefix=prefix)
        self.failures = []
        self.procs = []

    def check(self, cond, what):
        print(("ok   " if cond else "FAIL ") + what, flush=True)
        if not cond:
            self.failures.append(what)
        return cond

    def start(self, args, name, command="serve"):
        """`occmap COMMAND ARGS` with its stderr in NAME.log; (process, port) once it listens."""
        log = open(os.path.join(self.work, name + ".log"), "w")
        p = subprocess.Popen([self.occmap, "--threads", "2", command] + args, stdout=subprocess.PIPE, stderr=log,
                             text=True)
        self.procs.append(p)
        line = p.stdout.readline()
        prefix = f"occmap {command}: listening on http://127.0.0.1:"
        if not line.startswith(prefix):
            raise SystemExit(f"FAIL {name}: expected '{prefix}PORT/', found {line!r} (log {log.name})")
        return p, int(line[len(prefix):].strip().rstrip("/"))

    def finish(self):
        """In the test's `finally`: kills what still runs, prints the logs if anything failed or the
        test stopped on an exception, removes the work folder; the exit code."""
        aborted = sys.exc_info()[0] is not None
        for p in self.procs:
            if p.poll() is None:
                p.kill()
                p.wait()
        if self.failures or aborted:
            for name in os.listdir(self.work):
                if name.endswith(".log"):
                    print(f"--- {name}:\n" + open(os.path.join(self.work, name)).read()[-3000:])
        shutil.rmtree(self.work, ignore_errors=True)
        if not aborted:
            print(f"{len(self.failures)} failures")
        return 1 if self.failures else 0
