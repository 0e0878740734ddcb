#!/usr/bin/python3
"""vloc_console's figures on a recorded run, with a headless Chromium page
open: the console's resident memory (RSS, sampled every 0.5 s) while the
run replays, and the latency from each TRAVERSE reaching the console to the
map drawn in the browser (the page stamps each drawn map; LCM on loopback
adds well under a millisecond before it).

  scripts/console_figures.py --log /tmp/demo_hard20/rover/rover_sim.lcmlog [--uav-log LOG]
                             [--speed 4] [--shots /work/notes] [--ping]

--ping also publishes 100 TRAVERSE messages of 20 sites stamped with the
wall clock (build/tests/vloc_traverse_pinger, 5 Hz): the latency from
publishing to the map drawn, LCM included.

The 20-site log comes from `scripts/demo.sh --sites 20 --profile hard --out /tmp/demo_hard20`.
Needs chromium and chromium-driver (scripts/install_deps.sh); python3 stdlib only.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests", "procs", "vloc_console"))
import console_browser_test as browser  # noqa: E402  (WebDriver, free_port, wait_for)

LCM_URL = "udpm://239.255.76.67:7960?ttl=0&recv_buf_size=33554432"


def rss_mb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def replay(log, speed, console_pid, samples):
    player = subprocess.Popen(["lcm-logplayer", "--speed=%g" % speed, "--lcm-url=" + LCM_URL, log],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while player.poll() is None:
        samples.append(rss_mb(console_pid))
        time.sleep(0.5)
    samples.append(rss_mb(console_pid))


def ping(driver):
    driver.js("window.vloc.stats.traverseAgeMs = []; window.vloc.stats.traverseLatencyMs = [];")
    subprocess.run([os.path.join(ROOT, "build", "tests", "vloc_traverse_pinger"), "--lcm-url", LCM_URL,
                    "--sites", "20", "--rate", "5", "--seconds", "20"], check=True, stdout=subprocess.DEVNULL)
    time.sleep(1.0)
    stats = driver.js("return window.vloc.stats")
    age, lat = stats["traverseAgeMs"], stats["traverseLatencyMs"]
    print("TRAVERSE (20 sites) published -> map drawn: median %.1f ms, max %.1f ms (n=%d); "
          "console receipt -> drawn: median %.1f ms" % (statistics.median(age), max(age), len(age),
                                                       statistics.median(lat)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--log", required=True)
    ap.add_argument("--uav-log")
    ap.add_argument("--speed", type=float, default=4.0)
    ap.add_argument("--shots", default=os.path.join(ROOT, "build"))
    ap.add_argument("--ping", action="store_true")
    a = ap.parse_args()
    bin_dir = os.environ.get("VLOC_BIN_DIR", os.path.join(ROOT, "build", "bin"))
    http_port, driver_port = browser.free_port(), browser.free_port()
    console = subprocess.Popen([os.path.join(bin_dir, "vloc_console"), "--config", "config/procs/vloc_console.yaml",
                                "--port", str(http_port), "--lcm-url", LCM_URL], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    chrome = subprocess.Popen(["chromedriver", "--port=%d" % driver_port], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    driver = browser.WebDriver(driver_port)
    try:
        time.sleep(1.5)
        driver.start(browser.shutil.which("chromium"))
        driver.open("http://127.0.0.1:%d/" % http_port)
        browser.wait_for(driver, "return window.vloc.connected", 10, "the page's WebSocket")
        idle = rss_mb(console.pid)
        samples = []
        replay(a.log, a.speed, console.pid, samples)
        time.sleep(1.0)
        stats = driver.js("return window.vloc.stats")
        sites = driver.js("return Object.keys(window.vloc.sites).length")
        lat = stats["traverseLatencyMs"]
        print("rover log %s at x%g: %d sites on the map, %d TRAVERSE drawn" % (a.log, a.speed, sites, len(lat)))
        if lat:
            print("TRAVERSE at the console -> map drawn: median %.1f ms, max %.1f ms (n=%d)" %
                  (statistics.median(lat), max(lat), len(lat)))
        print("console RSS: idle %.1f MB, max %.1f MB, at the end %.1f MB (%d samples)" %
              (idle, max(samples), samples[-1], len(samples)))
        driver.js("const s = Object.keys(window.vloc.sites).map(Number); window.vloc.selectPair(Math.max(...s) - 1, Math.max(...s));")
        time.sleep(2.0)
        driver.screenshot(os.path.join(a.shots, "console_traverse_20_sites.png"))
        if a.uav_log:
            samples = []
            replay(a.uav_log, a.speed, console.pid, samples)
            time.sleep(1.5)
            n = driver.js("return window.vloc.uav.length")
            print("uav log %s: %d UAV states plotted; console RSS max %.1f MB" % (a.uav_log, n, max(samples)))
            driver.js("document.getElementById('uav-panel').scrollIntoView()")
            driver.screenshot(os.path.join(a.shots, "console_uav.png"))
        if a.ping:  # last: its synthetic traverse replaces the replayed one on the map
            ping(driver)
    finally:
        driver.quit()
        chrome.terminate()
        console.terminate()
        console.wait(10)
        chrome.wait(10)
    return 0


if __name__ == "__main__":
    sys.exit(main())
