#!/usr/bin/env python3
"""Paging over HTTP against the same database on local disk, in one run
(issue 38 part B; docs/HTTP.md, "Measured").

Starts nginx on a loopback port serving the database's parent directory and,
for every round trip asked, tools/delay_proxy.py in front of it (this kernel
has no sch_netem). Then, with `sandtable bench paging`:

  1. the baseline: the database directory on local disk;
  2. the same flights over http://.../DB at each round trip;
  3. VIEWERS headless viewers paging from the one nginx at once, each a
     `bench paging URL` process with one loader.

It prints, per source and mode, the hole frames at each speed and the
highest speed with none; for the viewers, holes per viewer and the server's
bytes per second from nginx's access log. --json prints one object.

    bench/http_paging.py DB [--rtts 0,20,100] [--speeds 1000,10000,30000,50000]
        [--seconds 5] [--viewers 20] [--viewer-speed 10000] [--viewer-seconds 10]
        [--cli build/tools/sandtable] [--paging-args "--no-readahead"] [--json]

DB must be big enough for `bench paging` to fly straight for --seconds at the
fastest speed (`sandtable bench make-db --size-km 60 -o DB` is).
"""
import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PAGING = ["--repeat", "1", "--modes", "predictive,demand", "--view-distance", "2000", "--path", "straight",
          "--warm", "--json"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_port(port, seconds=10.0):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.5):
                return True
        except OSError:
            time.sleep(0.05)
    return False


class Nginx:
    """nginx in the foreground on a free loopback port, logging bytes sent."""

    def __init__(self, root):
        self.dir = tempfile.mkdtemp(prefix="sandtable-nginx-")
        self.port = free_port()
        self.log = os.path.join(self.dir, "access.log")
        os.makedirs(os.path.join(self.dir, "tmp"))
        d = self.dir
        with open(os.path.join(d, "nginx.conf"), "w") as c:
            c.write(f"daemon off;\nmaster_process off;\nworker_processes 1;\npid {d}/nginx.pid;\n"
                    f"error_log {d}/error.log warn;\nevents {{ worker_connections 1024; }}\n"
                    f"http {{\n  log_format bytes '$msec $bytes_sent $uri';\n  access_log {self.log} bytes;\n"
                    f"  client_body_temp_path {d}/tmp;\n  keepalive_requests 100000;\n  keepalive_timeout 60s;\n"
                    f"  sendfile on;\n  default_type application/octet-stream;\n"
                    f"  server {{\n    listen 127.0.0.1:{self.port};\n    root {root};\n    location / {{ }}\n  }}\n}}\n")
        self.proc = subprocess.Popen(["nginx", "-p", d, "-c", f"{d}/nginx.conf", "-e", f"{d}/error.log"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if not wait_port(self.port):
            self.stop()
            sys.exit("http_paging: nginx did not start (is nginx-light installed? tools/setup.sh)")

    def served(self, t0, t1):
        """Requests, bytes, and (requests, bytes) by file name, that nginx
        logged between two wall-clock times."""
        n = b = 0
        by_file = {}
        with open(self.log) as f:
            for line in f:
                parts = line.split()
                if len(parts) == 3 and t0 <= float(parts[0]) <= t1:
                    n += 1
                    b += int(parts[1])
                    name = os.path.basename(parts[2])
                    r, sb = by_file.get(name, (0, 0))
                    by_file[name] = (r + 1, sb + int(parts[1]))
        return n, b, by_file

    def stop(self):
        self.proc.terminate()
        self.proc.wait()


class Proxy:
    def __init__(self, upstream, rtt):
        self.proc = subprocess.Popen([sys.executable, os.path.join(ROOT, "tools", "delay_proxy.py"), "0",
                                      "127.0.0.1", str(upstream), str(rtt)], stdout=subprocess.PIPE, text=True)
        self.port = int(self.proc.stdout.readline().split()[1])

    def stop(self):
        self.proc.terminate()
        self.proc.wait()


CACHES = []


def fresh_cache():
    """An environment with an empty mirror and no record cache on disk:
    every flight reads its records over the link (bench paging flies each
    mode over the same ground, and a disk cache would serve the second),
    as a new viewer on its own machine would."""
    CACHES.append(tempfile.mkdtemp(prefix="sandtable-cache-"))
    return dict(os.environ, SANDTABLE_CACHE=CACHES[-1], SANDTABLE_PACK_CACHE_MB="0")


def paging(cli, db, speeds, seconds, extra=()):
    out = subprocess.run([cli, "bench", "paging", db, "--speeds", speeds, "--seconds", str(seconds), *PAGING, *extra],
                         capture_output=True, text=True, env=fresh_cache())
    j = json.loads(out.stdout) if out.stdout.strip().startswith("{") else {}
    if out.returncode != 0 or "error" in j:
        sys.exit(f"http_paging: bench paging {db} failed: {j.get('error', out.stderr.strip()[-400:])}")
    return j


def holes_by_speed(j):
    """{mode: {speed: hole frames}} from a bench paging JSON report."""
    return {mode: {s["speed_kmh"]: s["hole_frames"] for s in m["speeds"]} for mode, m in j["modes"].items()}


def figures(j):
    """Per mode: the highest speed with no hole frame (bench paging's own
    figure), and per speed the coarse frames and the load p99."""
    return {mode: {"highest_clear_kmh": m["max_speed_zero_holes_kmh"],
                   "degraded_frames": {s["speed_kmh"]: s["degraded_frames"] for s in m["speeds"]},
                   "load_p99_ms": {s["speed_kmh"]: s["latency_ms"]["p99"] for s in m["speeds"]}}
            for mode, m in j["modes"].items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("db")
    ap.add_argument("--rtts", default="0,20,100")
    ap.add_argument("--speeds", default="1000,10000,30000,50000")
    ap.add_argument("--seconds", type=float, default=5)
    ap.add_argument("--viewers", type=int, default=20)
    ap.add_argument("--viewer-speed", default="10000")
    ap.add_argument("--viewer-seconds", type=float, default=10)
    ap.add_argument("--cli", default=os.path.join(ROOT, "build", "tools", "sandtable"))
    ap.add_argument("--paging-args", default="",
                    help="more flags for every `bench paging` run, e.g. --no-readahead (no strip prefetch)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    db = os.path.abspath(a.db)
    nginx = Nginx(os.path.dirname(db))
    name = os.path.basename(db)
    report = {"database": db, "speeds_kmh": [float(s) for s in a.speeds.split(",")], "seconds": a.seconds,
              "sources": [], "viewers": {}}
    try:
        sources = [("disk", 0, db)]
        for rtt in [int(r) for r in a.rtts.split(",")]:
            sources.append(("http", rtt, None))
        for kind, rtt, path in sources:
            proxy = Proxy(nginx.port, rtt) if kind == "http" and rtt > 0 else None
            port = proxy.port if proxy else nginx.port
            target = path or f"http://127.0.0.1:{port}/{name}"
            j = paging(a.cli, target, a.speeds, a.seconds, a.paging_args.split())
            if proxy:
                proxy.stop()
            report["sources"].append({"source": kind, "rtt_ms": rtt, "target": target, "holes": holes_by_speed(j),
                                      "modes": figures(j)})
        if a.viewers > 0:
            url = f"http://127.0.0.1:{nginx.port}/{name}"
            cmd = [a.cli, "bench", "paging", url, "--speeds", a.viewer_speed, "--seconds", str(a.viewer_seconds),
                   *PAGING, "--loaders", "1", *a.paging_args.split()]
            t0 = time.time()
            procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                      env=fresh_cache()) for _ in range(a.viewers)]
            outs = [p.communicate()[0] for p in procs]
            t1 = time.time()
            time.sleep(0.3)  # nginx logs a request after answering it
            per = [holes_by_speed(json.loads(o)) for o in outs]
            requests, sent, by_file = nginx.served(t0, t1 + 0.3)
            report["viewers"] = {"count": a.viewers, "speed_kmh": float(a.viewer_speed), "wall_seconds": t1 - t0,
                                 "holes_per_viewer": {m: [v[m][float(a.viewer_speed)] for v in per]
                                                      for m in per[0]},
                                 "server_requests": requests, "server_bytes": sent, "server_bytes_by_file": by_file,
                                 "server_bytes_per_second": sent / max(t1 - t0, 1e-9)}
    finally:
        nginx.stop()
        for d in CACHES + [nginx.dir]:
            shutil.rmtree(d, ignore_errors=True)
    if a.json:
        print(json.dumps(report, indent=2))
        return
    speeds = report["speeds_kmh"]
    print(f"hole frames per {a.seconds:g} s flight, by speed (km/h); last column: highest speed with none")
    print(f"{'source':<14}{'mode':<12}" + "".join(f"{s:>9.0f}" for s in speeds) + f"{'clear to':>10}")
    for s in report["sources"]:
        label = "disk" if s["source"] == "disk" else f"http {s['rtt_ms']} ms"
        for mode, h in s["holes"].items():
            print(f"{label:<14}{mode:<12}" + "".join(f"{int(h.get(v, 0)):>9}" for v in speeds) +
                  f"{s['modes'][mode]['highest_clear_kmh']:>10.0f}")
    v = report["viewers"]
    if v:
        print(f"{v['count']} viewers at {v['speed_kmh']:.0f} km/h at once: " +
              ", ".join(f"{m} holes per viewer {int(min(h))}..{int(max(h))}" for m, h in v["holes_per_viewer"].items()) +
              f"; nginx {v['server_requests']} requests, {v['server_bytes'] / 1e6:.0f} MB in {v['wall_seconds']:.1f} s"
              f" = {v['server_bytes_per_second'] / 1e6:.1f} MB/s (" +
              ", ".join(f"{k} {rb[1] / 1e6:.0f} MB in {rb[0]} requests"
                        for k, rb in sorted(v["server_bytes_by_file"].items(), key=lambda x: -x[1][1])) +
              ")")


if __name__ == "__main__":
    main()
