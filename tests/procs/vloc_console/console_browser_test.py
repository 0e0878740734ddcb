#!/usr/bin/env python3
"""vloc_console in a real browser (headless Chromium through chromedriver's
WebDriver protocol; python3 standard library only).

A process group under vloc_launch (dead_reckoning, a feature_frontend that
judges the ground too flat to match, crosssite_ba, traverse_graph,
vloc_console with a token, sim_rover on two sites) runs on its own LCM port.
The page must: show both sites on the map with the pair 0 -> 1 failed; take
manual tie points clicked on the two left images (the simulator's truth,
tests/procs/vloc_console/true_clicks.h) and turn the pair into a localized
one; restart a process from the process table. A page from another origin
must fail to open a second console that has no token (so could otherwise
act from loopback), while the console's own page acts. Screenshots go to
$VLOC_SCREENSHOT_DIR (default: the build folder).

Exits 77 (ctest: skipped) with one line when chromium or chromedriver is
missing: scripts/install_deps.sh installs both.
"""
import base64
import http.server
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

ROOT = os.environ.get("VLOC_SOURCE_DIR", os.getcwd())
BIN = os.environ.get("VLOC_BIN_DIR", os.path.join(ROOT, "build", "bin"))
BUILD = os.environ.get("VLOC_BUILD_DIR", os.path.join(ROOT, "build"))
SIM_CONFIG = "tests/procs/vloc_console/manual_tie_sim.yaml"
LCM_URL = "udpm://239.255.76.67:7959?ttl=0&recv_buf_size=33554432"
TOKEN = "browser-test-token"
CLICKS = 12


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class WebDriver:
    """The few W3C WebDriver commands the test needs."""

    def __init__(self, port):
        self.base = "http://127.0.0.1:%d" % port
        self.session = None

    def call(self, method, path, body=None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            return json.load(r)["value"]

    def start(self, chromium):
        caps = {"capabilities": {"alwaysMatch": {"browserName": "chrome", "goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     "--window-size=2200,1500", "--force-device-scale-factor=1"]}}}}
        self.session = self.call("POST", "/session", caps)["sessionId"]

    def s(self, path):
        return "/session/%s%s" % (self.session, path)

    def open(self, url):
        self.call("POST", self.s("/url"), {"url": url})

    def js(self, script, *args):
        return self.call("POST", self.s("/execute/sync"), {"script": script, "args": list(args)})

    def click_at(self, x, y):
        self.call("POST", self.s("/actions"), {"actions": [{
            "type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"},
            "actions": [{"type": "pointerMove", "duration": 0, "x": int(round(x)), "y": int(round(y)),
                         "origin": "viewport"},
                        {"type": "pointerDown", "button": 0}, {"type": "pointerUp", "button": 0}]}]})
        self.call("DELETE", self.s("/actions"))

    def click(self, css, timeout=10):
        """Clicks the element `css` names, found and clicked in one script: the page redraws its
        tables every second, so an element WebDriver found can be gone by the time it is clicked."""
        wait_for(self, "const e = document.querySelector(%s); if (!e || e.disabled) return false; "
                       "e.click(); return true;" % json.dumps(css), timeout, "%s to click" % css)

    def screenshot(self, path):
        with open(path, "wb") as f:
            f.write(base64.b64decode(self.call("GET", self.s("/screenshot"))))
        print("screenshot", path)

    def quit(self):
        if self.session:
            try:
                self.call("DELETE", self.s(""))
            except Exception:
                pass


def wait_for(driver, script, timeout, what):
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            value = driver.js(script)
        except Exception:
            value = None
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError("timed out after %.0f s waiting for %s" % (timeout, what))


def flat_frontend_config(folder):
    """The front end's config with the texture floor raised past any real ground."""
    text = open(os.path.join(ROOT, "config/procs/feature_frontend.yaml")).read()
    text = text.replace("navcam: {include: ../navcam.yaml}",
                        "navcam: {include: %s}" % os.path.join(ROOT, "config/navcam.yaml"))
    text = text.replace("frontend:\n", "frontend:\n  min_region_std: 1000.0\n", 1)
    path = os.path.join(folder, "feature_frontend_flat.yaml")
    open(path, "w").write(text)
    return path


def console_config(folder):
    """The console's config with site 0's terrain orthoimage (sim_rover --render-sample) under the map."""
    subprocess.run([os.path.join(BIN, "sim_rover"), "--config", SIM_CONFIG, "--render-sample", folder], cwd=ROOT,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    text = open(os.path.join(ROOT, "config/procs/vloc_console.yaml")).read().split("orthoimage:")[0]
    text += "orthoimage: {path: %s, x_min_m: -10.0, y_max_m: 20.0, m_per_px: 0.04}\n" % \
        os.path.join(folder, "terrain_ortho.png")
    path = os.path.join(folder, "vloc_console.yaml")
    open(path, "w").write(text)
    return path


def group_file(folder, http_port):
    def proc(name, args, extra=""):
        quoted = ", ".join(json.dumps(a) for a in args + ["--lcm-url", "${VLOC_LCM_URL}"])
        return "  - name: %s\n    command: ${VLOC_BIN}/%s\n    args: [%s]\n%s" % (name, name, quoted, extra)
    text = "group: console_test\ndefaults: {restart: on-failure, max_restarts: 3, stop_timeout: 5, " \
           "working_dir: %s}\nprocesses:\n" % ROOT
    text += proc("dead_reckoning", ["--config", "config/procs/dead_reckoning.yaml"])
    text += proc("feature_frontend", ["--config", flat_frontend_config(folder)])
    text += proc("crosssite_ba", ["--config", "config/procs/crosssite_ba.yaml", "--state-dir", folder])
    text += proc("traverse_graph", ["--config", "config/procs/traverse_graph.yaml"])
    text += proc("vloc_console", ["--config", console_config(folder), "--port", str(http_port)],
                 "    env: {VLOC_CONSOLE_TOKEN: %s}\n" % TOKEN)
    text += proc("sim_rover", ["--config", SIM_CONFIG, "--speed", "0"],
                 "    depends_on: [dead_reckoning, feature_frontend, crosssite_ba, traverse_graph, vloc_console]\n"
                 "    start_delay: 1.0\n    restart: never\n")
    path = os.path.join(folder, "console_test.yaml")
    open(path, "w").write(text)
    return path


def true_clicks():
    out = subprocess.run([os.path.join(BUILD, "tests", "vloc_true_clicks"), "--config", SIM_CONFIG,
                          "--previous", "0", "--current", "1", "--count", str(CLICKS)],
                         check=True, capture_output=True, text=True, cwd=ROOT).stdout
    return json.loads(out)["points"]


def select_images(driver, previous_pair, current_pair):
    driver.js("""const [p, c] = arguments;
      const a = document.getElementById('prev-image'), b = document.getElementById('cur-image');
      a.value = String(p); b.value = String(c); a.dispatchEvent(new Event('change'));""",
              previous_pair, current_pair)
    wait_for(driver, "return window.vloc.imagesReady()", 20, "both images of the pick")


def pick(driver, point):
    select_images(driver, point["previous_pair"], point["current_pair"])
    driver.js("document.getElementById('prev-canvas').scrollIntoView({block: 'center'})")
    for which, u, v in (("prev", point["previous_u"], point["previous_v"]),
                        ("cur", point["current_u"], point["current_v"])):
        x, y = driver.js("return window.vloc.imageToClient(arguments[0], arguments[1], arguments[2])", which, u, v)
        driver.click_at(x, y)


def click_site(driver, site):
    driver.js("window.scrollTo(0, 0)")
    x, y = driver.js("return window.vloc.siteToClient(arguments[0])", site)
    driver.click_at(x, y)


def check_map_shows_sites(driver, shots):
    wait_for(driver, "return window.vloc.stats.mapSites >= 2", 90, "both sites on the map")
    wait_for(driver, "return window.vloc.ortho && window.vloc.ortho.width == 1000", 10, "the orthoimage under the map")
    status = wait_for(driver, "const s = window.vloc.sites[1]; return s && s.frontend && s.frontend.status",
                      60, "FRONTEND_STATUS of pair 0 -> 1")
    assert status == "low texture", "pair 0 -> 1 should have failed automatically, got %s" % status
    assert not driver.js("const l = window.vloc.sites[1].localization; return l && l.ok"), "no BA before the picks"
    wait_for(driver, "const i = window.vloc.images; return i[0] && i[1] && i[0].length == 3 && i[1].length == 3",
             30, "the left images of both sites")
    click_site(driver, 1)
    info = wait_for(driver, "const t = document.getElementById('site-info').textContent; "
                            "return t.includes('FRONTEND 0 -> 1: low texture') && t", 10, "site 1's details")
    assert "BA: none" in info, info
    driver.screenshot(os.path.join(shots, "console_map_failed_pair.png"))
    print("map: %d sites, pair 0 -> 1 %s" % (driver.js("return window.vloc.stats.mapSites"), status))


def check_manual_tie_points(driver, shots):
    driver.js("window.vloc.selectPair(0, 1); document.getElementById('manual').checked = true;")
    points = true_clicks()
    assert len(points) >= 10, "too few true clicks: %d" % len(points)
    for p in points:
        pick(driver, p)
    picked = driver.js("return window.vloc.picks.length")
    assert picked == len(points), "page registered %d of %d picks" % (picked, len(points))
    driver.screenshot(os.path.join(shots, "console_manual_picks.png"))
    driver.click("#send-ties")
    reply = wait_for(driver, "return window.vloc.lastTieReply", 10, "the console's answer to the picks")
    assert reply.get("ok"), "picks refused: %s" % reply
    loc = wait_for(driver, "const l = window.vloc.sites[1].localization; return l && l.ok && l",
                   60, "site 1 localized by the BA from the picks")
    dr = driver.js("return window.vloc.sites[1].dr")
    shift = ((loc["x"] - dr["x"]) ** 2 + (loc["y"] - dr["y"]) ** 2) ** 0.5
    print("manual tie: %d clicks -> BA %s, used %d, rms %.3f px, moved %.3f m from dead reckoning" %
          (len(points), loc["status"], loc["used"], loc["final_rms_px"], shift))
    assert loc["used"] >= 6
    wait_for(driver, "const s = window.vloc.sites[1], l = s.localization; "
                     "return s.opt && Math.hypot(s.opt.x - l.x, s.opt.y - l.y) < 0.05", 30,
             "the optimised traverse on the map moving site 1 to the BA's pose")
    click_site(driver, 1)
    wait_for(driver, "return document.getElementById('site-info').textContent.includes('BA vs 0: ok')", 10,
             "site 1's BA summary on the page")
    driver.js("window.vloc.selectPair(0, 1)")
    wait_for(driver, "const t = window.vloc.tiePoints[1]; return t && t.points.length > 0", 20, "the tie points drawn")
    select_images(driver, points[0]["previous_pair"], points[0]["current_pair"])
    driver.js("window.scrollTo(0, 0)")
    driver.screenshot(os.path.join(shots, "console_localized_pair.png"))


def check_watch_only_without_token(driver):
    """The same page without the token: buttons disabled, and a forced order is refused by the console."""
    url = driver.js("return location.href")
    driver.open(url.split("#")[0])
    wait_for(driver, "return window.vloc.connected && Object.keys(window.vloc.procman).length", 20, "the page again")
    time.sleep(0.5)
    assert not driver.js("return window.vloc.mayAct"), "without the token the page must only watch"
    assert driver.js("return document.querySelector(\"button[data-action='restart']\").disabled")
    driver.js("document.getElementById('token').value = ''; window.vloc.lastOrderReply = null;"
              "document.querySelector(\"button[data-action='restart']\").disabled = false;"
              "document.querySelector(\"button[data-action='restart']\").click();")
    reply = wait_for(driver, "return window.vloc.lastOrderReply", 10, "the console's answer to a forced order")
    assert not reply.get("ok") and "only watches" in reply.get("error", ""), reply
    driver.open(url)
    driver.call("POST", driver.s("/refresh"), {})  # only the fragment changed: load the page anew
    wait_for(driver, "return window.vloc.connected && window.vloc.mayAct", 20, "the page with the token again")
    print("without the token: buttons disabled, a forced order refused (%s)" % reply["error"])


def check_restart_from_page(driver, shots):
    row = "const r = (window.vloc.procman['%s'] || {procs: []}).procs.find(p => p.name == 'crosssite_ba'); "
    host = wait_for(driver, "const h = Object.keys(window.vloc.procman); return h.length && h[0]", 20,
                    "PROCMAN_STATUS")  # 'host:launcher pid'
    before = wait_for(driver, row % host + "return r && r.state == 'running' && r", 20, "crosssite_ba running")
    assert driver.js("return window.vloc.mayAct"), "the token given in the URL should allow acting"
    check_watch_only_without_token(driver)
    driver.js("document.getElementById('procs-panel').scrollIntoView()")
    driver.click("tr[data-proc='crosssite_ba'] button[data-action='restart']")
    reply = wait_for(driver, "return window.vloc.lastOrderReply", 10, "the console's answer to the order")
    assert reply.get("ok"), "restart refused: %s" % reply
    after = wait_for(driver, row % host + "return r && r.state == 'running' && r.pid != %d && r" % before["pid"],
                     30, "crosssite_ba restarted (new pid)")
    print("restart from the page: crosssite_ba pid %d -> %d" % (before["pid"], after["pid"]))
    driver.screenshot(os.path.join(shots, "console_processes.png"))


ATTACKER_PAGE = """<html><body><script>
window.result = {opened: false, closed: false, error: false, reply: null};
const ws = new WebSocket('ws://127.0.0.1:%d/ws');
ws.onopen = () => { window.result.opened = true;
  ws.send(JSON.stringify({type: 'order', id: 1, host: '', target: 'crosssite_ba', target_kind: 'process',
                          action: 'stop'})); };
ws.onmessage = (e) => { window.result.reply = e.data; };
ws.onerror = () => { window.result.error = true; };
ws.onclose = () => { window.result.closed = true; };
</script>attacker</body></html>"""


def serve_attacker_page(console_port):
    """A page on another origin (http://127.0.0.1:<other port>/) that tries to drive the console."""
    body = (ATTACKER_PAGE % console_port).encode()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    server = http.server.HTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def console_status(port):
    with urllib.request.urlopen("http://127.0.0.1:%d/api/status" % port, timeout=10) as r:
        return json.load(r)


def check_foreign_page_cannot_act(driver, shots):
    """A second console on loopback without a token (its own LCM port: its orders go nowhere)."""
    port = free_port()
    console = subprocess.Popen([os.path.join(BIN, "vloc_console"), "--config", "config/procs/vloc_console.yaml",
                                "--port", str(port), "--lcm-url", "udpm://239.255.76.67:7958?ttl=0"], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               env={k: v for k, v in os.environ.items() if k != "VLOC_CONSOLE_TOKEN"})
    attacker = serve_attacker_page(port)
    try:
        deadline = time.time() + 20
        while True:
            try:
                console_status(port)
                break
            except Exception:
                if time.time() > deadline:
                    raise AssertionError("the second console did not start")
                time.sleep(0.2)
        driver.open("http://127.0.0.1:%d/" % attacker.server_address[1])
        result = wait_for(driver, "const r = window.result; return r && (r.closed || r.error || r.reply) && r", 20,
                          "the foreign page's WebSocket to end")
        assert not result["opened"] and result["reply"] is None, "a foreign page opened the console: %s" % result
        status = console_status(port)
        assert status["orders_sent"] == 0 and status["origins_refused"] >= 1, status
        # The console's own page, same machine, no token: it may act.
        driver.open("http://127.0.0.1:%d/" % port)
        wait_for(driver, "return window.vloc && window.vloc.connected && window.vloc.mayAct", 20,
                 "the console's own page allowed to act")
        reply = wait_for(driver, "if (!window.sent) { window.sent = true; send({type: 'order', host: 'nohost', "
                                 "target: 'nothing', target_kind: 'process', action: 'stop'})"
                                 ".then((r) => { window.orderReply = r; }); } return window.orderReply", 10,
                         "the own page's order")
        assert reply.get("ok"), "the console's own page was refused: %s" % reply
        assert console_status(port)["orders_sent"] == 1
        print("foreign origin: WebSocket refused (%d refused, 0 orders); own page: order sent"
              % status["origins_refused"])
    finally:
        attacker.shutdown()
        console.terminate()
        console.wait(10)


def main():
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    chromedriver = shutil.which("chromedriver")
    if not chromium or not chromedriver:
        print("SKIP: chromium and chromedriver are needed (Debian: chromium chromium-driver; "
              "scripts/install_deps.sh installs them)")
        return 77
    shots = os.environ.get("VLOC_SCREENSHOT_DIR", BUILD)
    os.makedirs(shots, exist_ok=True)
    folder = tempfile.mkdtemp(prefix="vloc_console_browser_")
    http_port, driver_port = free_port(), free_port()
    env = dict(os.environ, VLOC_BIN=BIN, VLOC_ROOT=ROOT)
    launcher = subprocess.Popen([os.path.join(BIN, "vloc_launch"), "--config", group_file(folder, http_port),
                                 "--lcm-url", LCM_URL, "--log-dir", folder], cwd=ROOT, env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    chrome = subprocess.Popen([chromedriver, "--port=%d" % driver_port], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    driver = WebDriver(driver_port)
    failed = 0
    try:
        deadline = time.time() + 20
        while True:
            try:
                driver.start(chromium)
                break
            except Exception:
                if time.time() > deadline:
                    raise
                time.sleep(0.3)
        driver.open("http://127.0.0.1:%d/#token=%s" % (http_port, TOKEN))
        for check in (check_map_shows_sites, check_manual_tie_points, check_restart_from_page,
                      check_foreign_page_cannot_act):
            try:
                check(driver, shots)
                print("PASS", check.__name__)
            except Exception as e:  # one line per failed check, then the logs' tails
                failed += 1
                print("FAIL %s: %s" % (check.__name__, e))
                try:
                    driver.screenshot(os.path.join(shots, "console_failure_%s.png" % check.__name__))
                except Exception:
                    pass
                break
    finally:
        driver.quit()
        chrome.terminate()
        launcher.terminate()
        launcher.wait(30)
        chrome.wait(10)
    if failed:
        for name in ("feature_frontend", "crosssite_ba", "vloc_console", "sim_rover"):
            log = os.path.join(folder, name + ".log")
            if os.path.exists(log):
                print("---- %s (tail)" % log)
                print("".join(open(log, errors="replace").readlines()[-15:]))
    shutil.rmtree(folder, ignore_errors=True)
    passed = 4 - failed if not failed else 0
    print("%d passed, %d failed" % (passed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
