#!/usr/bin/env python3
"""The gateway (`facetscan serve --nats`) and a 3-node cluster, against real nats-servers (fleet_support.py).

Simulated scanners (facetscan-fw-hil on the device twins) stream to the gateway over TCP as to `serve`; the
gateway publishes every scan to SCANS through its disk spool; workers recognize. Tests: scanners + gateway + two
workers; the server away (scans spooled) and the gateway SIGKILLed and restarted on its spool; a full spool
holding the scanners; a 3-node cluster (the shipped node configs) losing one node mid-batch.
"""
import atexit
import glob
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import fleet_support as fs
from fleet_support import HANG_GUARD_S, Proc, free_port, run, wait_until

SCENES = ("default", "cube-pyramid-separate", "corner")


def scene_file(scene):
    return os.path.join(fs.ARGS.source, "hw-sim", "scenes", f"{scene}.json")


def drain_config():
    """A firmware config that gives the host 60 s (not 2 s) to take the last queued frames: these tests are
    about delivery through the gateway, and a loaded machine may keep the gateway from reading for seconds."""
    fd, path = tempfile.mkstemp(prefix="fs_gateway_fw_", suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump({"stream_drain_ms": 60000}, f)
    atexit.register(os.remove, path)
    return path


DRAIN_CONFIG = drain_config()


def stream_scan(gateway, scene, wait=True, scan_id=1):
    """One simulated scanner streams one 500-stripe scan of `scene` to the gateway."""
    cmd = [fs.ARGS.fw_hil, "--config", DRAIN_CONFIG, "--scene", scene_file(scene), "--stream",
           f"127.0.0.1:{gateway.port}", "--scan-id", str(scan_id)]
    if wait:
        return run(cmd)
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def spooled(spool):
    return sorted(glob.glob(os.path.join(spool, "*.fscan")))


class GatewayTest(fs.FleetCase):
    def gateway(self, spool, *extra, url=None):
        p = Proc([fs.ARGS.facetscan, "serve", "--nats", url or self.server.url, *self.ca, "--listen",
                  "127.0.0.1:0", "--spool", spool, *extra], fs.ENV.user_env("gateway"))
        self.procs.append(p)
        p.port = int(p.wait_line(r"listening on \S+ \(port (\d+)\)").group(1))
        return p

    def published_ids(self, gw, count):
        """The message ids the gateway logged as published (in order), once there are `count`."""
        def ids():
            found = [m.group(1) for line in list(gw.lines)
                     if (m := re.search(r"published to facetscan\.scans\.\S+ as (\S+) \(", line))]
            return found if len(found) >= count else None
        return wait_until(ids, f"{count} published scan(s)")

    def assert_results(self, ids_to_scene):
        results = wait_until(lambda: (r := self.results()) and len(r) >= len(ids_to_scene) and r,
                             f"{len(ids_to_scene)} results")
        time.sleep(1)  # a duplicate would be published right after
        results = self.results()
        self.assertEqual(sorted(r["scan_id"] for r in results), sorted(ids_to_scene))  # one result each
        for r in results:
            self.assert_matches_local(r, ids_to_scene[r["scan_id"]])
        return results

    def test_scanners_gateway_two_workers(self):
        # One scan in flight per worker, each held 3 s: the three scans, streamed at once, are published within
        # that time, so while one worker holds its first scan the other must take the next (a worker with two
        # threads, or scans spaced wider than the hold, could leave w2 idle on a loaded machine).
        self.worker("w1", "--threads", "1", "--test-hold-ms", "3000")
        self.worker("w2", "--threads", "1", "--test-hold-ms", "3000")
        spool = os.path.join(self.server.dir, "spool")
        gw = self.gateway(spool)
        scanners = [stream_scan(gw, scene, wait=False, scan_id=i + 1) for i, scene in enumerate(SCENES)]
        for s in scanners:
            self.assertEqual(s.wait(timeout=HANG_GUARD_S), 0)
        ids = self.published_ids(gw, 3)  # SCANNER-SCANID-START-CRC, in the order the scans completed
        results = self.assert_results({i: SCENES[int(i.split("-")[-3]) - 1] for i in ids})
        for r in results:
            self.assertEqual(r["scanner_id"], "127-0-0-1")  # one id per scanner address
            self.assertEqual(r["scan_status"], "complete")
        self.assertEqual({r["worker"]["id"] for r in results}, {"w1", "w2"})
        gw.stop()
        self.assertEqual(gw.proc.returncode, 0, gw.lines)
        self.assertTrue(any("gateway: 3 scan(s) received, 3 published" in line for line in gw.lines), gw.lines)
        self.assertEqual(spooled(spool), [])

    def test_server_away_spool_survives_gateway_kill(self):
        spool = os.path.join(self.server.dir, "spool")
        self.server.stop()
        gw = self.gateway(spool, "--scanner", "cell-s")  # starts while the server is away
        stream_scan(gw, "default")
        wait_until(lambda: len(spooled(spool)) == 1, "the first scan in the spool")
        stream_scan(gw, "corner")
        wait_until(lambda: len(spooled(spool)) == 2, "the second scan in the spool")
        gw.wait_line(r"NATS unreachable: scans stay in the spool")
        gw.stop(signal.SIGKILL)
        kept = spooled(spool)
        self.assertEqual(len(kept), 2, kept)
        self.assertTrue(all(re.search(r"/\d{12}_cell-s_complete\.fscan$", p) for p in kept), kept)

        gw2 = self.gateway(spool, "--scanner", "cell-s")  # a new gateway takes over the spool
        gw2.wait_line(r"2 scan\(s\) .* left by a previous run, sent first")
        stream_scan(gw2, "cube-pyramid-separate")
        wait_until(lambda: len(spooled(spool)) == 3, "the third scan in the spool")
        self.server.start()
        self.worker("w1")
        ids = self.published_ids(gw2, 3)  # oldest first: the previous run's scans, then the new one
        gw2.wait_line(r"NATS takes scans again")
        results = self.assert_results(dict(zip(ids, ["default", "corner", "cube-pyramid-separate"])))
        self.assertEqual({r["scanner_id"] for r in results}, {"cell-s"})
        self.assertEqual(spooled(spool), [])

    def test_full_spool_holds_scanners(self):
        spool = os.path.join(self.server.dir, "spool")
        self.server.stop()
        gw = self.gateway(spool, "--scanner", "cell-f", "--spool-max", "1")  # an empty spool takes one scan
        stream_scan(gw, "corner")
        wait_until(lambda: len(spooled(spool)) == 1, "the first scan in the spool")
        second = stream_scan(gw, "default", wait=False)
        gw.wait_line(r"spool full \(1 scan\(s\), .*\): scan 1 from \S+ waits")
        self.assertEqual(second.wait(timeout=HANG_GUARD_S), 0)  # its scan is taken, held in serve's queue
        self.assertEqual(len(spooled(spool)), 1)  # the bound holds
        # SIGTERM while a scan waits for room: it is spooled (over the bound) and the gateway exits.
        gw.stop()
        self.assertEqual(gw.proc.returncode, 0, gw.lines)
        self.assertTrue(any("2 scan(s) (" in line and "left in the spool" in line for line in gw.lines), gw.lines)
        self.assertEqual(len(spooled(spool)), 2)
        gw2 = self.gateway(spool, "--scanner", "cell-f", "--spool-max", "1")
        self.server.start()
        self.worker("w1")
        ids = self.published_ids(gw2, 2)
        self.assert_results(dict(zip(ids, ["corner", "default"])))


class Node:
    """One nats-server of the shipped 3-node cluster configs (toolchain/deploy/nats/cluster/node-N.conf)."""

    def __init__(self, work, index, ports):
        self.dir = os.path.join(work, f"node-{index}")
        shutil.rmtree(self.dir, ignore_errors=True)
        os.makedirs(os.path.join(self.dir, "store"))
        self.port, self.route_port = ports[index - 1]
        mqtt_port, http_port = free_port(), free_port()
        with open(os.path.join(fs.ENV.deploy, "cluster", f"node-{index}.conf")) as f:
            text = f.read()
        for old, new in (("port: 4222", f"port: {self.port}"), ("port: 6222", f"port: {self.route_port}"),
                         ("port: 1883", f"port: {mqtt_port}"),
                         ('http: "127.0.0.1:8222"', f'http: "127.0.0.1:{http_port}"'),
                         ('store_dir: "/var/lib/facetscan/nats"', f'store_dir: "{self.dir}/store"')):
            text, n = re.subn(r"^(\s*)" + re.escape(old) + "$", lambda m: m.group(1) + new, text, flags=re.M)
            assert n == 1, f"node-{index}.conf: expected one line '{old}', found {n}"
        for k, (_, route) in enumerate(ports, start=1):
            text, n = re.subn(re.escape(f"nats-route://nats{k}.plant:6222"), f"nats-route://localhost:{route}", text)
            assert n == 1, f"node-{index}.conf: route to nats{k}.plant"
        text = text.replace("/etc/facetscan/nats/", fs.ENV.certs + "/")
        self.conf = os.path.join(self.dir, "nats-server.conf")
        with open(self.conf, "w") as f:
            f.write(text)
        self.proc = None
        self.start()

    def start(self):
        env = dict(os.environ)
        env.update(fs.ENV.passwords)
        self.log = open(os.path.join(self.dir, "server.log"), "a")
        self.proc = subprocess.Popen(["nats-server", "-c", self.conf], env=env, stdout=self.log,
                                     stderr=subprocess.STDOUT)

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self.log.close()


class ClusterTest(unittest.TestCase):
    def setUp(self):
        work = os.path.join(fs.ENV.work, "cluster")
        ports = [(free_port(), free_port()) for _ in range(3)]
        # The nodes include ../accounts.conf: written once, before any node starts. (Copied by each node's
        # constructor, node 3's copy truncated the file while node 2 was reading it: node 2 ran without the
        # FACETSCAN account, "Unknown account" on its routes, and fleet-setup failed for the whole wait.)
        os.makedirs(work, exist_ok=True)
        shutil.copy(os.path.join(fs.ENV.deploy, "accounts.conf"), work)
        self.nodes = []
        # Cleanups run even when setUp fails below (tearDown would not): no server outlives the test.
        self.addCleanup(lambda: [n.kill() for n in self.nodes])
        for i in (1, 2, 3):
            self.nodes.append(Node(work, i, ports))
        self.url = ",".join(f"tls://localhost:{n.port}" for n in self.nodes)
        self.ca = ["--nats-ca", os.path.join(fs.ENV.certs, "ca.pem")]
        self.procs = []

        attempts = []

        def setup_done():  # the cluster elects its JetStream leader first
            p = run([fs.ARGS.facetscan, "fleet-setup", "--nats", self.url, *self.ca, "--replicas", "3",
                     "--ack-wait", "2"], env=fs.ENV.user_env("admin"), check=False)
            attempts.append(p.stderr.strip())
            return p.returncode == 0
        try:
            wait_until(setup_done, "fleet-setup on the 3-node cluster", timeout=3 * HANG_GUARD_S, step=1.0)
        except AssertionError as e:
            raise AssertionError(f"{e}; fleet-setup said: {attempts[:3]} ... {attempts[-2:]}") from None

    def tearDown(self):
        for i, p in enumerate(self.procs):
            p.stop(signal.SIGKILL)
            with open(os.path.join(self.nodes[0].dir, f"proc-{i}.log"), "w") as f:
                f.write(" ".join(p.cmd) + "\n" + "\n".join(p.lines) + "\n")

    def results(self):
        # Right after a node is killed a call may fail (its streams elect new leaders): retried, never read as
        # "no results".
        def read():
            p = run([fs.ARGS.facetscan, "results", "--nats", self.url, *self.ca, "--json"],
                    env=fs.ENV.user_env("shopfloor"), check=False)
            return p if p.returncode == 0 else None
        out = wait_until(read, "facetscan results on the cluster", step=1.0).stdout
        return [json.loads(line) for line in out.splitlines() if line.strip()]

    def test_node_killed_mid_batch(self):
        for wid in ("w1", "w2"):
            p = Proc([fs.ARGS.facetscan, "worker", "--nats", self.url, *self.ca, "-l", fs.ENV.library,
                      "--worker-id", wid, "--test-hold-ms", "300"], fs.ENV.user_env("worker"))
            self.procs.append(p)
            p.wait_line(r"ready \(")
        scenes = list(SCENES) * 2
        ids = {}
        for i, scene in enumerate(scenes):
            out = run([fs.ARGS.facetscan, "submit", "--nats", self.url, *self.ca, "--scanner", f"cell-{i}",
                       fs.ENV.scans[scene]], env=fs.ENV.user_env("gateway")).stdout
            ids[re.search(r"as (\S+) \(", out).group(1)] = scene
        wait_until(lambda: len(self.results()) >= 1, "a first result")
        self.nodes[0].kill()  # SIGKILL one of three: the replicated streams keep a majority
        results = wait_until(lambda: (r := self.results()) and len(r) >= len(ids) and r, "every result")
        time.sleep(1)
        results = self.results()
        self.assertEqual(sorted(r["scan_id"] for r in results), sorted(ids))  # none lost, none twice
        for r in results:
            self.assertEqual([o["model"] for o in r["objects"]],
                             [o["model"] for o in fs.ENV.expected[ids[r["scan_id"]]]])



class DemoFleetTest(unittest.TestCase):
    def test_demo_fleet(self):
        out_dir = os.path.join(fs.ENV.work, "demo-fleet")
        p = run([fs.ARGS.facetscan, "demo", "--fleet", "2", "--workers", "2", "--fleet-scans", "2", "-o", out_dir],
                timeout=240)
        lines = p.stdout.splitlines()
        results = [line for line in lines if re.match(r"scanner-\d \S+: \d+ object\(s\)", line)]
        self.assertEqual(len(results), 4, p.stdout)
        per_scanner = {}
        for line in results:
            m = re.match(r"(scanner-\d) (\S+): (\d+) object\(s\)", line)
            per_scanner.setdefault(m.group(1), set()).add((m.group(2), int(m.group(3))))
        # scanner-1 scans the default scene (4 objects), scanner-2 cube-pyramid-separate (2); two scans each, with
        # their own ids (--scan-id 1, 2).
        self.assertEqual({n for _, n in per_scanner["scanner-1"]}, {len(fs.ENV.expected["default"])})
        self.assertEqual({n for _, n in per_scanner["scanner-2"]}, {len(fs.ENV.expected["cube-pyramid-separate"])})
        self.assertEqual(len(per_scanner["scanner-1"]), 2)
        self.assertEqual(len(per_scanner["scanner-2"]), 2)
        self.assertIn("fleet demo: 4 of 4 scan(s) recognized by 2 worker(s)", p.stdout)
        # Everything it started is gone.
        self.assertEqual(subprocess.run(["pgrep", "-f", os.path.join(out_dir, "fleet")], capture_output=True).returncode, 1)


if __name__ == "__main__":
    sys.exit(fs.main())
