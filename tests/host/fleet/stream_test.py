#!/usr/bin/env python3
"""Streamed scans (`facetscan serve --nats --stream`, docs/fleet.md#streamed-scans) against a real nats-server.

The gateway publishes each scan's SCANS message at its ScanBegin and its frames as parts in PARTS while the
simulated scanner streams; a worker takes the scan at once and reads the parts as they come. Tests: scanners +
streaming gateway + two workers (one result each, equal to local recognition, taken before the scan ended);
a worker SIGKILLed holding a streamed scan (redelivered, the other worker reads the parts again); the server
SIGKILLed in the middle of a real-time scan (the stream is abandoned, the scan goes whole through the spool:
one result); a scanner cut in the middle of its scan (the partial scan is streamed and recognized as such).
"""
import atexit
import json
import os
import re
import signal
import sys
import tempfile
import time

import fleet_support as fs
import gateway_test as gt
from fleet_support import HANG_GUARD_S, Proc, wait_until


def realtime_config():
    """A firmware config for real-time scans on a loaded machine: these tests are about streaming, so the loop
    may run late (the deadline faults of a 2-core machine shared with nats-server are not what is tested)."""
    fd, path = tempfile.mkstemp(prefix="fs_stream_fw_", suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump({"stream_drain_ms": 60000,
                   "loop": {"late_limit_us": 1000000, "max_consecutive_late": 1000000, "max_dwell_ms": 100000,
                            "camera_timeout_ms": 100000}}, f)
    atexit.register(os.remove, path)
    return path


REALTIME_CONFIG = realtime_config()


def realtime_scanner(gateway, *extra):
    """A simulated scanner at the scanner's own rate (500 stripes in about 2.5 s)."""
    return Proc([fs.ARGS.fw_hil, "--config", REALTIME_CONFIG, "--realtime", *extra, "--stream",
                 f"127.0.0.1:{gateway.port}"], None)


class StreamTest(fs.FleetCase):
    def gateway(self, spool, *extra):
        p = Proc([fs.ARGS.facetscan, "serve", "--nats", self.server.url, *self.ca, "--listen", "127.0.0.1:0",
                  "--spool", spool, "--stream", *extra], fs.ENV.user_env("gateway"))
        self.procs.append(p)
        p.port = int(p.wait_line(r"listening on \S+ \(port (\d+)\)").group(1))
        return p

    def streamed_ids(self, gw, count):
        def ids():
            found = [m.group(1) for line in list(gw.lines) if (m := re.search(r"streamed as (\S+) \(", line))]
            return found if len(found) >= count else None
        return wait_until(ids, f"{count} streamed scan(s)")

    def one_result_each(self, count):
        wait_until(lambda: len(self.results()) >= count, f"{count} results")
        time.sleep(1)  # a duplicate would come right after
        results = self.results()
        ids = [r["scan_id"] for r in results]
        self.assertEqual(len(ids), len(set(ids)), ids)
        self.assertEqual(len(results), count, ids)
        return results

    def test_streamed_scans_two_workers(self):
        self.worker("w1", "--threads", "1")
        self.worker("w2", "--threads", "1")
        spool = os.path.join(self.server.dir, "spool")
        gw = self.gateway(spool, "--part-size", "64KiB")
        for i, scene in enumerate(gt.SCENES):
            gt.stream_scan(gw, scene, scan_id=i + 1)
        ids = self.streamed_ids(gw, 3)
        results = self.one_result_each(3)
        by_id = {r["scan_id"]: r for r in results}
        self.assertEqual(sorted(by_id), sorted(ids))
        for sid in ids:
            r = by_id[sid]
            # SCANNER-SCANID-START-s<nonce>: the id fixed at ScanBegin
            self.assertRegex(sid, r"^127-0-0-1-\d+-\d+-s[0-9a-f]{16}$")
            self.assert_matches_local(r, gt.SCENES[int(sid.split("-")[-3]) - 1])
            self.assertEqual(r["scan_status"], "complete")
            parts, size = r["stream"]["parts"], r["stream"]["bytes"]
            self.assertGreater(parts, 50)  # ~6 MB in parts of 64 KiB and one more stripe at most
            self.assertGreaterEqual(size, (parts - 1) * 65536)
            self.assertLess(size, parts * (65536 + 20000))
        gw.stop()
        self.assertEqual(gw.proc.returncode, 0, gw.lines)
        self.assertTrue(any("3 scan(s) received, 3 published (3 streamed, 0 stream(s) abandoned" in line
                            for line in gw.lines), gw.lines)
        self.assertEqual(gt.spooled(spool), [])  # nothing went through the spool

    def test_realtime_scan_is_taken_before_it_ends(self):
        self.worker("w1")
        gw = self.gateway(os.path.join(self.server.dir, "spool"))
        scanner = realtime_scanner(gw, "--steps", "200")
        self.procs.append(scanner)
        self.assertEqual(scanner.proc.wait(timeout=HANG_GUARD_S), 0)
        [r] = self.one_result_each(1)
        # The worker took the scan at its ScanBegin and read it as it came: it had it before the last part.
        self.assertTrue(r["stream"]["taken_before_end"], r)
        self.assertEqual([o["model"] for o in r["objects"]], [o["model"] for o in fs.ENV.expected["default"]])

    def test_worker_sigkilled_holding_a_streamed_scan(self):
        w1 = self.worker("w1", "--test-hold-ms", "60000")
        gw = self.gateway(os.path.join(self.server.dir, "spool"))
        gt.stream_scan(gw, "corner")
        [sid] = self.streamed_ids(gw, 1)
        w1.wait_line(r"recognizing " + re.escape(sid) + r" \(delivery 1, \d+ part\(s\)\)")
        w1.stop(signal.SIGKILL)
        self.worker("w2")
        [r] = self.one_result_each(1)
        self.assertEqual(r["scan_id"], sid)
        self.assertEqual(r["worker"], {"id": "w2", "delivery": 2})  # read the stored parts again
        self.assert_matches_local(r, "corner")

    def test_server_killed_mid_stream_scans_sent_whole(self):
        w1 = self.worker("w1", "--part-timeout", "5")
        spool = os.path.join(self.server.dir, "spool")
        gw = self.gateway(spool, "--scanner", "cell-k")
        scanner = realtime_scanner(gw)
        self.procs.append(scanner)
        w1.wait_line(r"reading the parts of cell-k-1-")  # the scan streams (2.5 s at the scanner's rate)
        self.server.kill()
        self.assertEqual(scanner.proc.wait(timeout=HANG_GUARD_S), 0)
        first = gw.wait_line(r"streaming scan 1 as (\S+) failed \(.*\): it goes whole through the spool").group(1)
        # A second scan while the server is still away: its stream fails at once and it waits in the spool
        # too (the gateway goes on taking scans while the first stream's "abandoned" waits for the server).
        gt.stream_scan(gw, "corner", scan_id=2)
        second = gw.wait_line(r"streaming scan 2 as (\S+) failed").group(1)
        wait_until(lambda: len(gt.spooled(spool)) == 2, "both scans in the spool")
        self.assertTrue(all(re.search(r"_s[0-9a-f]{16}\.fscan$", p) for p in gt.spooled(spool)))
        self.server.start()
        results = self.one_result_each(2)
        # Sent whole, each keeps its streamed id: had its stream reached a worker after all, RESULTS would
        # have stored one of the two results.
        self.assertEqual(sorted(r["scan_id"] for r in results), sorted([first, second]))
        for r in results:
            self.assertNotIn("stream", r)  # recognized from the whole scan
            scene = "default" if r["scan_id"] == first else "corner"
            self.assertEqual([o["model"] for o in r["objects"]], [o["model"] for o in fs.ENV.expected[scene]])
        # The first stream's SCANS message was stored: its worker (or a redelivery) drops it, nothing goes to DEAD.
        w1.wait_line(r"dropped " + re.escape(first) + r": its gateway abandoned the stream")
        self.assertEqual(self.results("--dead", user="client"), [])
        self.assertEqual(gt.spooled(spool), [])

    def test_scanner_cut_mid_scan_streams_a_partial_scan(self):
        w1 = self.worker("w1")
        gw = self.gateway(os.path.join(self.server.dir, "spool"), "--reconnect-grace", "500")
        scanner = realtime_scanner(gw)
        self.procs.append(scanner)
        w1.wait_line(r"reading the parts of 127-0-0-1-1-")  # the scan began
        time.sleep(1.0)  # about 200 of 500 stripes
        scanner.stop(signal.SIGKILL)
        [r] = self.one_result_each(1)
        self.assertEqual(r["scan_status"], "disconnected before ScanEnd")
        self.assertFalse(r["input"]["complete_scan"])
        self.assertGreater(r["stream"]["parts"], 1)


if __name__ == "__main__":
    sys.exit(fs.main())
