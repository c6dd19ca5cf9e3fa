#!/usr/bin/env python3
"""Streamed scans (`facetscan serve --nats --stream`, docs/fleet.md#streamed-scans) against a real nats-server.

The gateway publishes each scan's SCANS message at its ScanBegin and its frames as parts in PARTS while the
scanner streams; a worker takes the scan at once and reads the parts as they come. Tests: simulated scanners +
streaming gateway + two workers (one result each, equal to local recognition); a paced scan the worker takes
before it ends; a worker SIGKILLed holding a streamed scan (redelivered, the other worker reads the parts
again); the server SIGKILLed in the middle of a paced scan and a second scan during the outage (both streams
abandoned, both scans sent whole through the spool: one result each); a scanner whose link drops mid-scan (the
partial scan is streamed and recognized as such). Paced scans replay a recorded scan's frames over TCP
(ReplayScanner): the real-time firmware twins are too slow under a sanitizer.
"""
import os
import re
import signal
import socket
import sys
import threading
import time

import fleet_support as fs
import gateway_test as gt
from fleet_support import HANG_GUARD_S, Proc, wait_until


FSCAN_HEADER_BYTES = 16  # a .fscan file is this header, then the frames exactly as the scanner sent them


class ReplayScanner(threading.Thread):
    """A scanner at a chosen pace: replays a recorded scan's frames over TCP to the gateway in `seconds`
    (deterministic on any machine, unlike the real-time firmware twins under a sanitizer), or only the first
    `fraction` of them before the connection drops."""

    def __init__(self, port, fscan, seconds, fraction=1.0):
        super().__init__(daemon=True)
        with open(fscan, "rb") as f:
            data = f.read()[FSCAN_HEADER_BYTES:]
        self.data = data[:int(len(data) * fraction)]
        self.port, self.seconds, self.error = port, seconds, None
        self.start()

    def run(self):
        try:
            chunks = [self.data[i:i + 65536] for i in range(0, len(self.data), 65536)]
            with socket.create_connection(("127.0.0.1", self.port)) as sock:
                for c in chunks:
                    sock.sendall(c)
                    time.sleep(self.seconds / len(chunks))
                time.sleep(0.5)  # let the host read the end before the connection closes
        except OSError as e:
            self.error = e

    def finish(self):
        self.join(timeout=HANG_GUARD_S)
        assert not self.is_alive() and self.error is None, self.error


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
        workers = [self.worker("w1", "--threads", "1"), self.worker("w2", "--threads", "1")]
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
        for w in workers:  # a clean exit (under the sanitizer build: nothing leaked)
            w.stop()
            self.assertEqual(w.proc.returncode, 0, w.lines)

    def test_worker_stopped_while_reading_a_stream(self):
        w1 = self.worker("w1")
        gw = self.gateway(os.path.join(self.server.dir, "spool"))
        scanner = ReplayScanner(gw.port, fs.ENV.scans["default"], 3.0)
        w1.wait_line(r"reading the parts of ")
        w1.stop()  # SIGTERM: the scan it reads goes back to the consumer at once, the worker exits cleanly
        self.assertEqual(w1.proc.returncode, 0, w1.lines)
        self.assertTrue(any("stopped: 0 result(s)" in line for line in w1.lines), w1.lines)
        self.worker("w2")
        scanner.finish()
        [r] = self.one_result_each(1)
        self.assertEqual(r["worker"], {"id": "w2", "delivery": 2})
        # Every stripe once: the recording's size less its heartbeats (a few frames of tens of bytes).
        recorded = os.path.getsize(fs.ENV.scans["default"])
        self.assertTrue(recorded - 4096 < r["stream"]["bytes"] <= recorded, (r["stream"], recorded))
        self.assertTrue(r["input"]["complete_scan"])
        self.assertEqual([o["model"] for o in r["objects"]], [o["model"] for o in fs.ENV.expected["default"]])

    def test_paced_scan_is_taken_before_it_ends(self):
        self.worker("w1")
        gw = self.gateway(os.path.join(self.server.dir, "spool"))
        ReplayScanner(gw.port, fs.ENV.scans["default"], 2.0).finish()
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
        scanner = ReplayScanner(gw.port, fs.ENV.scans["default"], 3.0)
        w1.wait_line(r"reading the parts of cell-k-1-")  # the scan streams (for 3 s)
        self.server.kill()
        scanner.finish()
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

    def test_link_dropped_mid_scan_streams_a_partial_scan(self):
        self.worker("w1")
        gw = self.gateway(os.path.join(self.server.dir, "spool"), "--reconnect-grace", "500")
        ReplayScanner(gw.port, fs.ENV.scans["default"], 2.0, fraction=0.4).finish()  # then the link drops
        [r] = self.one_result_each(1)
        self.assertEqual(r["scan_status"], "disconnected before ScanEnd")
        self.assertFalse(r["input"]["complete_scan"])
        self.assertGreater(r["stream"]["parts"], 1)


if __name__ == "__main__":
    sys.exit(fs.main())
