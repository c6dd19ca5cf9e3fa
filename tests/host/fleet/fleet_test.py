#!/usr/bin/env python3
"""The fleet (host/fleet, docs/fleet.md) against a real nats-server: no mocks.

Every test starts its own nats-server from the shipped one-node config (toolchain/deploy/nats/nats-server.conf
with accounts.conf: TLS, JetStream on file storage, MQTT, least-privilege users), with the ports, the store and
the certificate folder replaced, and runs `facetscan fleet-setup | worker | submit | results` as the users of
that config. The scans are recorded once per run with facetscan-fw-hil (three scenes); the expected objects of
each are what `facetscan recognize x.fscan` finds locally with the same library.

Exit 77 (ctest: skipped) when nats-server / mosquitto_sub / openssl are missing, unless CI=true (then fail).
"""
import argparse
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import unittest
import urllib.request

ARGS = None
HANG_GUARD_S = 90  # generous guard against hangs; no test asserts a duration


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(pred, what, timeout=HANG_GUARD_S, step=0.1):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(step)
    raise AssertionError(f"gave up waiting for {what} after {timeout} s (hang guard)")


class Env:
    """What every test shares: certificates, passwords, the library and the recorded scans."""

    def __init__(self, work):
        self.work = work
        os.makedirs(work, exist_ok=True)
        src = ARGS.source
        self.deploy = os.path.join(src, "toolchain", "deploy", "nats")
        self.certs = os.path.join(work, "certs")
        shutil.rmtree(self.certs, ignore_errors=True)
        subprocess.run([os.path.join(self.deploy, "gen-certs.sh"), self.certs], check=True, capture_output=True)
        self.passwords = {}
        with open(os.path.join(self.certs, "passwords.env")) as f:
            for line in f:
                k, v = line.strip().split("=", 1)
                self.passwords[k] = v
        self.library = os.path.join(work, "lib.fslib")
        run([ARGS.facetscan, "library", "build", os.path.join(src, "hw-sim", "scenes", "meshes"), "-o",
             self.library])
        # Three scenes recorded in parallel (each ~6 MB, 500 stripes).
        self.scans = {}
        procs = []
        for scene in ("default", "cube-pyramid-separate", "corner"):
            path = os.path.join(work, f"{scene}.fscan")
            self.scans[scene] = path
            if not os.path.exists(path):
                procs.append(subprocess.Popen(
                    [ARGS.fw_hil, "--scene", os.path.join(src, "hw-sim", "scenes", f"{scene}.json"), "--record",
                     path + ".tmp"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        for p in procs:
            assert p.wait(timeout=HANG_GUARD_S) == 0, "facetscan-fw-hil --record failed"
        for path in self.scans.values():
            if os.path.exists(path + ".tmp"):
                os.replace(path + ".tmp", path)
        # Local recognition of each scan: what every fleet result must say.
        self.expected = {}
        for scene, path in self.scans.items():
            out = run([ARGS.facetscan, "recognize", path, "-l", self.library, "--json", "-", "-q"]).stdout
            self.expected[scene] = json.loads(out)["objects"]
        # A poison scan: the ScanBegin is intact (it is accepted and published), a byte in the middle is not
        # (its frame fails the CRC at every delivery).
        self.poison = os.path.join(work, "poison.fscan")
        data = bytearray(open(self.scans["default"], "rb").read())
        data[len(data) // 2] ^= 0xFF
        open(self.poison, "wb").write(bytes(data))

    def user_env(self, user, password=None):
        e = dict(os.environ)
        e["FACETSCAN_NATS_USER"] = user
        e["FACETSCAN_NATS_PASSWORD"] = password if password is not None else \
            self.passwords[f"FACETSCAN_{user.upper()}_PASSWORD"]
        return e


ENV = None


def run(cmd, env=None, check=True, timeout=HANG_GUARD_S):
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    if check and p.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} exited {p.returncode}:\n{p.stdout}\n{p.stderr}")
    return p


class Server:
    """nats-server from the shipped config, on free ports, with its own store (kept across restarts)."""

    def __init__(self, name):
        self.dir = os.path.join(ENV.work, name)
        shutil.rmtree(self.dir, ignore_errors=True)
        os.makedirs(os.path.join(self.dir, "store"))
        self.port, self.mqtt_port, self.http_port = free_port(), free_port(), free_port()
        with open(os.path.join(ENV.deploy, "nats-server.conf")) as f:
            text = f.read()
        # Only setting lines are replaced (line-anchored), each exactly once.
        for old, new in (("port: 4222", f"port: {self.port}"), ("port: 1883", f"port: {self.mqtt_port}"),
                         ('http: "127.0.0.1:8222"', f'http: "127.0.0.1:{self.http_port}"'),
                         ('store_dir: "/var/lib/facetscan/nats"', f'store_dir: "{self.dir}/store"')):
            text, n = re.subn(r"^(\s*)" + re.escape(old) + "$", lambda m: m.group(1) + new, text, flags=re.M)
            assert n == 1, f"nats-server.conf: expected one line '{old}', found {n}"
        assert "/etc/facetscan/nats/" in text
        text = text.replace("/etc/facetscan/nats/", ENV.certs + "/")
        self.conf = os.path.join(self.dir, "nats-server.conf")
        with open(self.conf, "w") as f:
            f.write(text)
        shutil.copy(os.path.join(ENV.deploy, "accounts.conf"), self.dir)
        self.url = f"tls://localhost:{self.port}"
        self.proc = None
        self.start()

    def start(self):
        env = dict(os.environ)
        env.update(ENV.passwords)
        if getattr(self, "log", None):
            self.log.close()
        self.log = open(os.path.join(self.dir, "server.log"), "a")
        self.proc = subprocess.Popen(["nats-server", "-c", self.conf], env=env, stdout=self.log,
                                     stderr=subprocess.STDOUT)

        def ready():
            assert self.proc.poll() is None, "nats-server exited: " + open(self.log.name).read()[-2000:]
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return True
            except OSError:
                return False
        wait_until(ready, "nats-server to listen")

    def kill(self):
        self.proc.kill()
        self.proc.wait()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()


class Proc:
    """A facetscan process whose stderr lines are collected."""

    def __init__(self, cmd, env):
        self.lines = []
        self.cmd = cmd
        self.proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_line(self, pattern):
        rx = re.compile(pattern)

        def found():
            for line in list(self.lines):
                m = rx.search(line)
                if m:
                    return m
            assert self.proc.poll() is None or self.reader.is_alive(), \
                f"{self.cmd[1]} exited {self.proc.returncode}:\n" + "\n".join(self.lines)
            return None
        return wait_until(found, f"'{pattern}' from {' '.join(self.cmd[:2])}")

    def stop(self, sig=signal.SIGTERM):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.reader.join(timeout=5)


class FleetTest(unittest.TestCase):
    def setUp(self):
        self.server = Server(self.id().split(".")[-1])
        self.procs = []
        self.ca = ["--nats-ca", os.path.join(ENV.certs, "ca.pem")]
        run([ARGS.facetscan, "fleet-setup", "--nats", self.server.url, *self.ca, "--ack-wait", "2",
             "--max-deliver", "3"], env=ENV.user_env("admin"))

    def tearDown(self):
        for i, p in enumerate(self.procs):
            p.stop(signal.SIGKILL)
            with open(os.path.join(self.server.dir, f"proc-{i}.log"), "w") as f:
                f.write(" ".join(p.cmd) + "\n" + "\n".join(p.lines) + "\n")
        self.server.stop()

    def worker(self, wid, *extra):
        p = Proc([ARGS.facetscan, "worker", "--nats", self.server.url, *self.ca, "-l", ENV.library,
                  "--worker-id", wid, *extra], ENV.user_env("worker"))
        self.procs.append(p)
        p.wait_line(r"ready \(")
        return p

    def submit(self, files, scanner, *extra, user="gateway", check=True):
        return run([ARGS.facetscan, "submit", "--nats", self.server.url, *self.ca, "--scanner", scanner, *extra,
                    *files], env=ENV.user_env(user), check=check)

    def results(self, *extra, user="shopfloor"):
        out = run([ARGS.facetscan, "results", "--nats", self.server.url, *self.ca, "--json", *extra],
                  env=ENV.user_env(user)).stdout
        return [json.loads(line) for line in out.splitlines() if line.strip()]

    def assert_matches_local(self, result, scene):
        got = result["objects"]
        want = ENV.expected[scene]
        self.assertEqual([o["model"] for o in got], [o["model"] for o in want], result["scan_id"])
        for g, w in zip(got, want):
            for a, b in zip(g["translation"], w["translation"]):
                self.assertAlmostEqual(a, b, delta=0.01)
        self.assertEqual(result["library"]["models"], 6)
        self.assertRegex(result["library"]["hash"], r"^[0-9a-f]{8}$")

    def test_happy_path_two_workers(self):
        w1 = self.worker("w1", "--test-hold-ms", "200")
        w2 = self.worker("w2", "--test-hold-ms", "200")
        scenes = ["default", "cube-pyramid-separate", "corner"]
        submitted = {}  # scan id -> scene
        for cell in ("cell-1", "cell-2"):
            out = self.submit([ENV.scans[s] for s in scenes], cell).stdout
            ids = re.findall(r"as (\S+) \(", out)
            self.assertEqual(len(ids), 3, out)
            submitted.update(zip(ids, scenes))
        results = wait_until(lambda: (r := self.results()) and len(r) >= 6 and r, "6 results")
        time.sleep(1)  # a duplicate would be published right after
        results = self.results()
        self.assertEqual(sorted(r["scan_id"] for r in results), sorted(submitted))  # one result each
        for r in results:
            self.assert_matches_local(r, submitted[r["scan_id"]])
            self.assertTrue(r["scan_id"].startswith(r["scanner_id"] + "-1-1000000000-"), r["scan_id"])
            self.assertIn(r["worker"]["id"], ("w1", "w2"))
        self.assertEqual({r["worker"]["id"] for r in results}, {"w1", "w2"})  # both took scans
        for p in (w1, w2):
            p.stop()
        self.assertEqual(len(self.results("--scanner", "cell-2")), 3)

    def test_worker_sigkilled_mid_recognition(self):
        w1 = self.worker("w1", "--test-hold-ms", "60000")  # holds the scan (marked in progress) until killed
        out = self.submit([ENV.scans["default"]], "cell-k").stdout
        scan_id = re.search(r"as (\S+) \(", out).group(1)
        w1.wait_line(re.escape(f"recognizing {scan_id} (delivery 1)"))
        w2 = self.worker("w2")
        time.sleep(1)  # w2 idles: the scan is w1's while w1 lives
        self.assertFalse(any("recognizing" in line for line in w2.lines), w2.lines)
        w1.proc.send_signal(signal.SIGKILL)
        w1.proc.wait()
        w2.wait_line(re.escape(f"recognizing {scan_id} (delivery 2)"))
        w2.wait_line(re.escape(f"result {scan_id}: 4 object(s)"))
        results = self.results()
        self.assertEqual([r["scan_id"] for r in results], [scan_id])
        self.assertEqual(results[0]["worker"], {"id": "w2", "delivery": 2})
        self.assert_matches_local(results[0], "default")

    def test_server_killed_and_restarted_mid_batch(self):
        self.worker("w1", "--test-hold-ms", "300")
        self.worker("w2", "--test-hold-ms", "300")
        scenes = ["default", "cube-pyramid-separate", "corner"] * 2
        ids = []
        for i, s in enumerate(scenes):
            out = self.submit([ENV.scans[s]], f"cell-{i}").stdout
            ids.append(re.search(r"as (\S+) \(", out).group(1))
        wait_until(lambda: len(self.results()) >= 1, "a first result")
        self.server.kill()  # SIGKILL: no clean shutdown of the store
        time.sleep(1)
        self.server.start()
        results = wait_until(lambda: (r := self.results()) and len(r) >= len(ids) and r, "every result")
        time.sleep(1)
        results = self.results()
        self.assertEqual(sorted(r["scan_id"] for r in results), sorted(ids))  # none lost, none twice
        for r in results:
            self.assert_matches_local(r, scenes[ids.index(r["scan_id"])])

    def test_same_scan_twice_stored_once(self):
        first = self.submit([ENV.scans["corner"]], "cell-d").stdout
        second = self.submit([ENV.scans["corner"]], "cell-d").stdout
        self.assertNotIn("duplicate", first)
        self.assertIn("duplicate: already stored", second)
        self.assertEqual(re.search(r"SCANS seq (\d+)", first).group(1), re.search(r"SCANS seq (\d+)", second).group(1))
        self.worker("w1")
        out = self.submit([ENV.scans["corner"]], "cell-d", "--wait", user="client").stdout
        self.assertIn(f"{len(ENV.expected['corner'])} object(s)", out)
        time.sleep(1)
        results = self.results()
        self.assertEqual(len(results), 1, results)
        self.assert_matches_local(results[0], "corner")

    def test_poison_scan_dead_lettered(self):
        self.worker("w1")
        p = self.submit([ENV.poison, ENV.scans["cube-pyramid-separate"]], "cell-p", "--wait", user="client",
                        check=False)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertIn("1 of 2 scan(s) failed", p.stderr)
        dead = self.results("--dead", user="client")  # dead letters hold scans: not for the shop floor
        self.assertEqual(len(dead), 1, dead)
        self.assertIn("failed 3 time(s)", dead[0]["reason"])
        self.assertIn("CRC", dead[0]["reason"].upper())
        self.assertEqual(dead[0]["bytes"], os.path.getsize(ENV.poison))
        results = self.results()
        self.assertEqual(len(results), 1)
        self.assert_matches_local(results[0], "cube-pyramid-separate")

    def test_mqtt_subscriber_receives_result(self):
        sub = subprocess.Popen(
            ["mosquitto_sub", "-h", "localhost", "-p", str(self.server.mqtt_port), "--cafile",
             os.path.join(ENV.certs, "ca.pem"), "-u", "shopfloor", "-P",
             ENV.passwords["FACETSCAN_SHOPFLOOR_PASSWORD"], "-i", "shopfloor-test", "-t", "facetscan/results/#",
             "-v", "-C", "1", "-W", str(HANG_GUARD_S)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # The MQTT subscription is in place once the server lists it (monitoring endpoint /connz).
        def subscribed():
            url = f"http://127.0.0.1:{self.server.http_port}/connz?subs=1"
            conns = json.load(urllib.request.urlopen(url, timeout=2)).get("connections") or []
            return any("facetscan.results.>" in (c.get("subscriptions_list") or []) for c in conns)
        wait_until(subscribed, "mosquitto_sub's subscription")
        self.worker("w1")
        self.submit([ENV.scans["default"]], "cell-m")
        out, err = sub.communicate(timeout=HANG_GUARD_S)
        self.assertEqual(sub.returncode, 0, err)
        topic, payload = out.strip().split(" ", 1)
        self.assertEqual(topic, "facetscan/results/cell-m")
        result = json.loads(payload)
        self.assertEqual(result["scanner_id"], "cell-m")
        self.assert_matches_local(result, "default")

    def test_users_and_transport_policy(self):
        e = ENV.user_env("gateway", password="wrong-" + secrets.token_hex(4))
        p = run([ARGS.facetscan, "submit", "--nats", self.server.url, *self.ca, ENV.scans["corner"]], env=e,
                check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("Authorization", p.stderr)
        # The results-only user cannot publish scans (its publish is refused: no stream acknowledgement).
        p = run([ARGS.facetscan, "submit", "--nats", self.server.url, *self.ca, ENV.scans["corner"]],
                env=ENV.user_env("shopfloor"), check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertEqual(self.results(), [])
        # A gateway may not read results.
        p = run([ARGS.facetscan, "results", "--nats", self.server.url, *self.ca], env=ENV.user_env("gateway"),
                check=False)
        self.assertNotEqual(p.returncode, 0)
        # Plain text to a non-loopback address is refused before any connection; --insecure lifts that.
        p = run([ARGS.facetscan, "worker", "--nats", "nats://192.0.2.1:4222", "-l", ENV.library], check=False)
        self.assertEqual(p.returncode, 1)
        self.assertIn("refusing plain-text NATS to 192.0.2.1:4222", p.stderr)
        p = run([ARGS.facetscan, "results", "--nats", "nats://192.0.2.1:4222", "--insecure"], check=False)
        self.assertNotIn("refusing", p.stderr)
        self.assertIn("cannot connect", p.stderr)


def main():
    global ARGS, ENV
    ap = argparse.ArgumentParser()
    ap.add_argument("--facetscan", required=True)
    ap.add_argument("--fw-hil", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    ARGS, rest = ap.parse_known_args()
    missing = [t for t in ("nats-server", "mosquitto_sub", "openssl") if shutil.which(t) is None]
    if missing:
        msg = f"fleet_test: {', '.join(missing)} missing (toolchain/setup installs them)"
        if os.environ.get("CI") == "true":
            print(msg + ": FAIL under CI=true", file=sys.stderr)
            return 1
        print(msg + ": SKIPPED", file=sys.stderr)
        return 77
    ENV = Env(ARGS.work)
    prog = unittest.main(argv=[sys.argv[0], "-v", *rest], exit=False)
    return 0 if prog.result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
