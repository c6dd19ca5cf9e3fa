#!/usr/bin/python3
"""Facetscan's live web view in a real browser (headless Chromium through Selenium; ctest label web).

Starts `facetscan demo --http 127.0.0.1:0 --http-wait 90` on the default scene (the scan starts once the page
is open), opens the page and asserts from the page itself: the progress reaches 500 / 500 stripes, the object
list shows the four objects, the WebGL canvas is not blank (pixels read back), clicking an object in the 3D view
shows its pose, and the console has no errors. Then opens the scan's static report from disk (file://) and
checks its 3D view the same way. Prints the time from the scan's result to the page showing it in 3D (target
<= 1 s; measured, not asserted). Screenshots: OUT/live-view.png, OUT/report-view.png, OUT/top-view.png.

  browser_test.py --facetscan build/bin/facetscan --out build/web-test [--copy-docs docs/]
  browser_test.py --facetscan ... --out ... --overhead   # recognition time with 0 and 3 open pages (serve)
"""
import argparse
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import time

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

EXPECTED = {"truncated_pyramid", "hex_prism", "cube", "wedge"}


def browser(width=1500, height=1100):
    o = webdriver.ChromeOptions()
    o.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-gl=angle",
              "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
              f"--window-size={width},{height}", "--allow-file-access-from-files", "--no-first-run",
              "--disable-extensions", "--disable-background-networking", "--disable-component-update"):
        o.add_argument(a)
    o.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=o)


def start(cmd, log_path, pattern, timeout=120):
    log = open(log_path, "w")
    p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    end = time.time() + timeout
    while time.time() < end:
        m = re.search(pattern, open(log_path).read())
        if m:
            return p, m
        if p.poll() is not None:
            sys.exit(f"FAIL: {' '.join(cmd)} exited with {p.returncode}:\n{open(log_path).read()}")
        time.sleep(0.1)
    p.kill()
    sys.exit(f"FAIL: no '{pattern}' from {' '.join(cmd)} in {timeout} s")


def stop(p, name):
    if p.poll() is None:
        os.kill(p.pid, signal.SIGTERM)
    try:
        code = p.wait(30)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        sys.exit(f"FAIL: {name} did not stop on SIGTERM")
    return code


def console_errors(d):
    return [e for e in d.get_log("browser") if e.get("level") == "SEVERE"]


def check(cond, what):
    if not cond:
        sys.exit("FAIL: " + what)
    print("ok:", what)


def wait(d, fn, what, timeout=120):
    try:
        return WebDriverWait(d, timeout, poll_frequency=0.1).until(lambda _: fn())
    except Exception:
        sys.exit("FAIL: timed out waiting for " + what)


def click_objects_in_view(d, canvas, n):
    """Clicks each object's centre in the 3D view; returns the details text of the first that selects."""
    rect = d.execute_script("const r = arguments[0].getBoundingClientRect(); return [r.width, r.height];", canvas)
    for i in range(n):
        pos = d.execute_script("return window.%s.screenPosition(arguments[0]);" % VIEWER, i)
        if not pos:
            continue
        dx, dy = pos["x"] - rect[0] / 2, pos["y"] - rect[1] / 2
        ActionChains(d).move_to_element_with_offset(canvas, int(dx), int(dy)).click().perform()
        time.sleep(0.2)
        if d.execute_script("return window.%s.selected();" % VIEWER) == i:
            return i
    return -1


VIEWER = "facetApp.viewer"


def live_test(a):
    global VIEWER
    os.makedirs(a.out, exist_ok=True)
    demo_out = os.path.join(a.out, "demo")
    shutil.rmtree(demo_out, ignore_errors=True)
    demo, m = start([a.facetscan, "demo", "-o", demo_out, "--http", "127.0.0.1:0", "--http-wait", "90"],
                    os.path.join(a.out, "demo.log"), r"web view: (http://\S+)")
    url = m.group(1)
    print("page:", url)
    d = browser()
    try:
        d.get(url)
        VIEWER = "facetApp.viewer"
        # The scan runs now (the demo waited for this page's event stream).
        wait(d, lambda: "500 / 500" in d.find_element(By.ID, "progress-text").text, "the progress to reach 500 / 500",
             180)
        check("500 / 500" in d.find_element(By.ID, "progress-text").text, "progress shows stripe 500 / 500")
        wait(d, lambda: d.execute_script("return facetApp.metrics.length") > 0, "the scan in the 3D view", 120)
        names = wait(d, lambda: (lambda l: l if len(l) == 4 else None)(
            [e.text for e in d.find_elements(By.CSS_SELECTOR, "#objects li .name")]), "four objects in the list", 30)
        check(set(names) == EXPECTED, f"object list shows the four objects {sorted(names)}")
        frac = d.execute_script("return facetApp.viewer.drawnFraction();")
        check(frac > 0.05, f"WebGL canvas not blank ({100 * frac:.1f} % of sampled pixels differ from the background)")
        canvas = d.find_element(By.CSS_SELECTOR, "#view canvas")
        hit = click_objects_in_view(d, canvas, 4)
        check(hit >= 0, f"clicking object {hit} in the 3D view selects it")
        det = d.find_element(By.ID, "details").text
        check("position (mm)" in det and "rotation" in det and "confidence" in det and "ambiguity" in det,
              "the details show the pose: " + det.replace("\n", " | ")[:160])
        d.find_elements(By.CSS_SELECTOR, "#objects li")[0].click()
        check(d.find_element(By.ID, "objects").find_elements(By.CSS_SELECTOR, "li.selected"),
              "clicking an object in the list selects it")
        # The scan's record comes twice: at once for the 3D view, again with the report's links once the report
        # is written (later on a loaded machine).
        def history_row():
            rows = d.find_elements(By.CSS_SELECTOR, "#history tbody tr")
            return len(rows) == 1 and "report" in rows[0].text and ".fscan" in rows[0].text
        wait(d, history_row, "the history row with its report and .fscan links", 60)
        check(history_row(), "history lists the scan with its report and .fscan links")
        pics = d.find_elements(By.CSS_SELECTOR, "#pictures img")
        check(len(pics) == 4 and all(d.execute_script("return arguments[0].naturalWidth", p) > 0 for p in pics),
              "the 2D pictures (top view, segmentation, PFRG, ENM) load")
        metrics = d.execute_script("return facetApp.metrics")
        live = [x for x in metrics if x["live"]]
        if live:
            print(f"METRIC web_view_latency_ms {live[0]['lagMs']} (scan result -> 3D view shown in the page; "
                  f"target <= 1000)")
        else:
            print("note: the page loaded after the result; no live latency measured")
        # Show the objects' colours on their points for the screenshot.
        d.execute_script("facetApp.viewer.select(0); document.getElementById('colour-mode').value='height';")
        time.sleep(0.3)
        shot = os.path.join(a.out, "live-view.png")
        d.save_screenshot(shot)
        print("screenshot:", shot)
        errors = console_errors(d)
        check(not errors, f"no console errors {errors}")
    finally:
        d.quit()

    # The static report, from disk.
    report = os.path.abspath(os.path.join(demo_out, "scan-001-id1", "report", "index.html"))
    d = browser(1300, 1500)
    try:
        d.get("file://" + report)
        VIEWER = "facetReportView"
        wait(d, lambda: d.execute_script("return !!window.facetReportView"), "the report's 3D view", 60)
        frac = d.execute_script("return facetReportView.drawnFraction();")
        check(frac > 0.05, f"report (file://): 3D view not blank ({100 * frac:.1f} %)")
        canvas = d.find_element(By.CSS_SELECTOR, "#view3d canvas")
        d.execute_script("arguments[0].scrollIntoView()", canvas)
        hit = click_objects_in_view(d, canvas, 4)
        check(hit >= 0 and "position (mm)" in d.find_element(By.CSS_SELECTOR, ".fs-details").text,
              "report: clicking an object shows its pose")
        d.save_screenshot(os.path.join(a.out, "report-view.png"))
        errors = console_errors(d)
        check(not errors, f"report: no console errors {errors}")
        # The top view (scene.svg: picture, outlines, legend) as a PNG.
        d.set_window_size(800, 1000)
        d.get("file://" + os.path.join(os.path.dirname(report), "scene.svg"))
        time.sleep(0.5)
        size = d.execute_script("const s = document.documentElement; return [s.width.baseVal.value, s.height.baseVal.value];")
        d.set_window_size(int(size[0]), int(size[1]) + 140)
        d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                          {"width": int(size[0]), "height": int(size[1]), "deviceScaleFactor": 1, "mobile": False})
        d.save_screenshot(os.path.join(a.out, "top-view.png"))
    finally:
        d.quit()
    code = stop(demo, "facetscan demo")
    check(code == 0, f"facetscan demo ended cleanly on SIGTERM (exit code {code})")
    if a.copy_docs:
        shutil.copy(os.path.join(a.out, "live-view.png"), os.path.join(a.copy_docs, "live-view.png"))
        shutil.copy(os.path.join(a.out, "top-view.png"), os.path.join(a.copy_docs, "demo-report.png"))
        print("copied the screenshots into", a.copy_docs)
    print("PASS")


def overhead_test(a):
    """Recognition time of scans recognized with no page open, then with 3 pages open (one serve process)."""
    os.makedirs(a.out, exist_ok=True)
    fw = os.path.join(os.path.dirname(a.facetscan), "facetscan-fw-hil")
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    scene = os.path.join(src, "hw-sim", "scenes", "default.json")
    out = os.path.join(a.out, "overhead")
    shutil.rmtree(out, ignore_errors=True)
    serve_log = os.path.join(a.out, "overhead-serve.log")
    serve, m = start([a.facetscan, "serve", "--listen", "127.0.0.1:0", "-l", os.path.join(src, "hw-sim", "scenes", "meshes"),
                      "-o", out, "--http", "127.0.0.1:0"], serve_log, r"web view: (http://\S+)[\s\S]*port (\d+)\)")
    url, port = m.group(1), m.group(2)

    def scan(k):
        subprocess.run([fw, "--galvo", "sim", "--camera", "sim", "--scene", scene, "--stream", f"127.0.0.1:{port}"],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        end = time.time() + 60
        while time.time() < end and len(re.findall(r"recognition: ([\d.]+) ms", open(serve_log).read())) < k:
            time.sleep(0.1)

    n = a.scans
    for k in range(1, n + 1):
        scan(k)
    pages = [browser(1200, 900) for _ in range(3)]
    try:
        for p in pages:
            p.get(url)
        for p in pages:
            WebDriverWait(p, 60).until(lambda _: p.execute_script("return facetApp.metrics.length") > 0)
        for k in range(n + 1, 2 * n + 1):
            scan(k)
        time.sleep(1.5)
        lags = [x["lagMs"] for p in pages for x in p.execute_script("return facetApp.metrics") if x["live"]]
    finally:
        for p in pages:
            p.quit()
    stop(serve, "facetscan serve")
    ms = [float(x) for x in re.findall(r"recognition: ([\d.]+) ms", open(serve_log).read())]
    without, with3 = ms[:n], ms[n:2 * n]
    print(f"METRIC recognition_ms_no_pages {without} median {statistics.median(without):.1f}")
    print(f"METRIC recognition_ms_3_pages {with3} median {statistics.median(with3):.1f}")
    if lags:
        print(f"METRIC web_view_latency_ms_3_pages {lags} max {max(lags)}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--facetscan", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--copy-docs")
    ap.add_argument("--overhead", action="store_true")
    ap.add_argument("--scans", type=int, default=3)
    a = ap.parse_args()
    a.out = os.path.abspath(a.out)
    overhead_test(a) if a.overhead else live_test(a)


if __name__ == "__main__":
    main()
