#!/usr/bin/env python3
"""The build report (OUT/report.html) in a real browser: headless Chromium
driven by chromedriver over the W3C WebDriver HTTP protocol (standard library
only).

Builds the demo's data (scripts/demo.sh: `geodrive synth --scenes 2 --seed 7
--monst3r`, then `geodrive build-dataset`), opens its report and checks: no
console errors, the counts and one row per pair as in manifest.jsonl, sorting
by coverage (both directions), each pair's video elements and H.264 playback
(or, where H.264 does not play, links and the preview strips), the page in a
narrow window, and writes screenshots to WORK_DIR (report.png: the first
screen at 1280x900; report_pairs.png, report_videos.png, report_narrow.png). A second, small run with one clip's MonST3R folder broken checks
the failures section against failures.jsonl.

Usage: report_browser_test.py WORK_DIR   (GEODRIVE_BINARY: the geodrive binary)
Skips (exit 77) when Chromium or chromedriver is absent, unless
GEODRIVE_REQUIRE_BROWSER=1 (CI), where that fails.
"""

import base64
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

CHROMIUM = os.environ.get("GEODRIVE_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("GEODRIVE_CHROMEDRIVER", "/usr/bin/chromedriver")
SKIP = 77
H264 = 'video/mp4; codecs="avc1.42E01E"'
failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)
    return ok


def run(args, ok_codes=(0,)):
    t = time.time()
    p = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    print("$ %s  (%.1f s, exit %d)" % (" ".join(args), time.time() - t,
                                        p.returncode), flush=True)
    if p.returncode not in ok_codes:
        print(p.stdout)
        raise SystemExit("command failed: %s" % " ".join(args))
    return p.stdout


def read_jsonl(path):
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class WebDriver:
    """A chromedriver process and one session on it."""

    def __init__(self, profile_dir):
        self.port = free_port()
        self.log = open(os.path.join(profile_dir, "..", "chromedriver.log"),
                        "w")
        self.proc = subprocess.Popen(
            [CHROMEDRIVER, "--port=%d" % self.port],
            stdout=self.log, stderr=subprocess.STDOUT)
        self.base = "http://127.0.0.1:%d" % self.port
        self.session = None
        deadline = time.time() + 30
        while True:
            try:
                if self.request("GET", "/status").get("ready"):
                    break
            except (urllib.error.URLError, ConnectionError):
                pass
            if time.time() > deadline or self.proc.poll() is not None:
                raise RuntimeError("chromedriver did not start")
            time.sleep(0.1)
        args = ["--headless=new", "--no-sandbox", "--disable-gpu",
                "--disable-dev-shm-usage", "--disable-quic", "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update", "--disable-sync",
                "--hide-scrollbars", "--window-size=1280,900",
                "--user-data-dir=" + profile_dir]
        caps = {"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": CHROMIUM, "args": args},
            "goog:loggingPrefs": {"browser": "ALL"}}}}
        self.session = self.request("POST", "/session", caps)["sessionId"]

    def request(self, method, path, body=None, timeout=120):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(
            self.base + path, data=data, method=method,
            headers={"Content-Type": "application/json; charset=utf-8"})
        try:
            with urllib.request.urlopen(req, timeout=timeout) as r:
                return json.loads(r.read().decode())["value"]
        except urllib.error.HTTPError as e:
            raise RuntimeError("%s %s: %s" % (method, path,
                                               e.read().decode()[:2000]))

    def s(self, method, path, body=None):
        return self.request(method, "/session/%s%s" % (self.session, path),
                            body)

    def js(self, script, *args):
        return self.s("POST", "/execute/sync",
                      {"script": script, "args": list(args)})

    def js_async(self, script, *args):
        return self.s("POST", "/execute/async",
                      {"script": script, "args": list(args)})

    def go(self, url):
        self.s("POST", "/url", {"url": url})
        deadline = time.time() + 30
        while self.js("return document.readyState") != "complete":
            if time.time() > deadline:
                raise RuntimeError("page did not load: " + url)
            time.sleep(0.05)

    def click(self, css):
        el = self.s("POST", "/element", {"using": "css selector",
                                          "value": css})
        eid = next(iter(el.values()))  # {"element-6066-…": id}
        self.s("POST", "/element/%s/click" % eid, {})

    def console(self):
        return self.s("POST", "/se/log", {"type": "browser"})

    def screenshot(self, path):
        png = base64.b64decode(self.s("GET", "/screenshot"))
        with open(path, "wb") as f:
            f.write(png)
        return len(png)

    def viewport(self, width, height):
        """Sizes the window so that the page's viewport is width x height."""
        self.s("POST", "/window/rect", {"width": width, "height": height})
        inner = self.js("return [window.innerWidth, window.innerHeight]")
        self.s("POST", "/window/rect", {"width": 2 * width - inner[0],
                                        "height": 2 * height - inner[1]})

    def quit(self):
        try:
            if self.session:
                self.request("DELETE", "/session/" + self.session, timeout=30)
        except Exception as e:  # the driver is stopped below either way
            print("quit: %s" % e)
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.log.close()


def file_url(path):
    return "file://" + urllib.request.pathname2url(os.path.abspath(path))


def check_console(d, page):
    entries = d.console()
    for e in entries:
        print("  console %s: %s" % (e.get("level"), e.get("message")))
    severe = [e for e in entries if e.get("level") == "SEVERE"]
    check(not severe, "%s: no console errors (%d entries)" % (page,
                                                              len(entries)))


ROWS_JS = """
return Array.prototype.map.call(
  document.querySelectorAll('#pair-table tbody tr'), function (tr) {
    var c = tr.cells[4];
    return {cls: tr.className, clip: tr.getAttribute('data-clip'),
            v: c.hasAttribute('data-v') ? parseFloat(c.getAttribute('data-v'))
                                        : null,
            text: c.textContent};
  });
"""


def check_sorted(rows, descending, what):
    vals = [r["v"] for r in rows]
    present = [v for v in vals if v is not None]
    # Rows without a value (failed clips) stay last.
    ok = vals[:len(present)] == present
    ok = ok and present == sorted(present, reverse=descending)
    check(ok, what + ": " + " ".join(str(v) for v in vals))


def check_demo_report(d, out, work):
    manifest = read_jsonl(os.path.join(out, "manifest.jsonl"))
    fails = read_jsonl(os.path.join(out, "failures.jsonl"))
    report = os.path.join(out, "report.html")
    check(len(manifest) > 0, "the demo built pairs (%d)" % len(manifest))
    d.go(file_url(report))
    check_console(d, "demo report")
    check(d.js("return document.title") == "geodrive build-dataset report",
          "title")
    # Counts as in the logs.
    counts = d.js("return [document.getElementById('count-pairs').textContent,"
                  " document.getElementById('count-failed').textContent]")
    check(counts == [str(len(manifest)), str(len(fails))],
          "counts %s = manifest %d, failures %d" % (counts, len(manifest),
                                                    len(fails)))
    rows = d.js(ROWS_JS)
    pair_rows = [r for r in rows if r["cls"] == "pair-row"]
    fail_rows = [r for r in rows if r["cls"] == "fail-row"]
    check(len(pair_rows) == len(manifest),
          "pair rows %d = manifest lines %d" % (len(pair_rows), len(manifest)))
    check(len(fail_rows) == len(fails),
          "failed-clip rows %d = failures lines %d" % (len(fail_rows),
                                                      len(fails)))
    clips = [m["clip_id"] for m in manifest]
    check([r["clip"] for r in pair_rows] == clips,
          "every clip of the manifest has its row, in order")
    # Displayed values: coverage with 3 decimals, PSNR in dB, the LiDAR scale
    # in m/unit, "—" where there is none (meta.json per pair).
    cells = d.js("""
      return Array.prototype.map.call(
        document.querySelectorAll('#pair-table tr.pair-row'), function (tr) {
          return Array.prototype.map.call(tr.cells, function (c) {
            return [c.textContent, c.getAttribute('data-v')]; });
        });""")
    bad = []
    for row, m in zip(cells, manifest):
        meta = json.load(open(os.path.join(out, m["pair_dir"], "meta.json")))
        psnr = [p for p in meta["quality"]["psnr_static"] if p is not None]
        want_psnr = "%.1f dB" % (sum(psnr) / len(psnr)) if psnr else "—"
        want_scale = ("%.2f m/unit" % meta["scale"]["value"]
                      if meta["scale"]["source"] == "lidar" else "—")
        want = [m["clip_id"], "%.3f" % m["mean_coverage"], want_psnr,
                want_scale]
        got = [row[0][0], row[4][0], row[5][0], row[6][0]]
        if got != want or abs(float(row[4][1]) - m["mean_coverage"]) > 1e-6:
            bad.append((got, want))
    check(not bad, "coverage, PSNR and scale shown as 0.405, 23.3 dB, "
          "1.23 m/unit (first row %s)%s" % (
              [c[0] for c in cells[0]] if cells else None,
              "; wrong: %s" % bad if bad else ""))
    # Sorting by coverage, then the other way.
    d.click("#sort-coverage button")
    check_sorted(d.js(ROWS_JS), False, "ascending by coverage")
    check(d.js("return document.getElementById('sort-coverage')"
               ".getAttribute('aria-sort')") == "ascending", "aria-sort set")
    d.click("#sort-coverage button")
    rows_desc = d.js(ROWS_JS)
    check_sorted(rows_desc, True, "descending by coverage")
    check(len(rows_desc) == len(rows), "sorting keeps every row")
    # Histograms: count axis with ticks, full captions.
    hist = d.js("""
      return Array.prototype.map.call(document.querySelectorAll('figure.hist'),
        function (f) {
          var svg = f.querySelector('svg');
          return {yticks: svg ? svg.querySelectorAll('text.yt').length : 0,
                  xticks: svg ? svg.querySelectorAll('text.xt').length : 0,
                  caption: f.querySelector('figcaption').textContent};
        });""")
    check(len(hist) >= 2 and all(h["yticks"] >= 2 and h["xticks"] >= 2
                                 for h in hist if h["caption"]),
          "histograms have count and value ticks: %s" % hist)
    # The videos of every pair: elements, sources, poster, preview strip.
    vids = d.js("""
      return Array.prototype.map.call(document.querySelectorAll('article.card'),
        function (a) {
          function v(cls) {
            var e = a.querySelector('video.' + cls);
            return e ? {src: e.getAttribute('src'),
                        poster: e.getAttribute('poster')} : null;
          }
          var strip = a.querySelector('figure.strip img');
          return {clip: a.getAttribute('data-clip'), gt: v('gt'),
                  cond: v('cond'),
                  strip: strip ? strip.getAttribute('src') : null};
        });""")
    check([v["clip"] for v in vids] == clips[:60],
          "a video card per pair (%d)" % len(vids))
    bad = []
    for v, m in zip(vids, manifest):
        pd = m["pair_dir"]
        ok = (v["gt"] and v["cond"] and
              v["gt"]["src"] == pd + "/gt.mp4" and
              v["cond"]["src"] == pd + "/cond.mp4" and
              v["gt"]["poster"] == pd + "/first_frame.png" and
              v["strip"] == pd + "/preview.png")
        if not ok:
            bad.append(v)
    check(not bad, "each card: gt.mp4 and cond.mp4 players, the first frame "
          "as poster, preview.png strip (first %s)%s" % (
              vids[0] if vids else None, "; wrong: %s" % bad if bad else ""))
    # H.264 playback: what the browser says, and the first video's metadata.
    can = d.js("return document.createElement('video').canPlayType(arguments[0])",
               H264)
    print("canPlayType(%s) = %r" % (H264, can))
    if can:
        meta = d.js_async("""
          var done = arguments[arguments.length - 1];
          var v = document.querySelector('video.gt');
          var t0 = Date.now();
          (function poll() {
            if (v.readyState >= 1 || v.error || Date.now() - t0 > 20000)
              done({readyState: v.readyState, duration: v.duration,
                    width: v.videoWidth, height: v.videoHeight,
                    error: v.error ? v.error.code : null});
            else setTimeout(poll, 50);
          })();""")
        print("first gt video: %s" % meta)
        m0 = manifest[0]
        fps = json.load(open(os.path.join(out, m0["pair_dir"],
                                          "meta.json")))["fps"]
        check(meta["readyState"] >= 1 and meta["error"] is None and
              abs(meta["duration"] - m0["num_frames"] / fps) < 0.2 and
              meta["width"] > 0,
              "H.264 plays: the first video's metadata loaded (%s; %d frames "
              "at %g fps)" % (meta, m0["num_frames"], fps))
        played = d.js_async("""
          var done = arguments[arguments.length - 1];
          var v = document.querySelector('video.cond');
          v.play().then(function () {
            setTimeout(function () {
              done({t: v.currentTime, paused: v.paused}); }, 700);
          }, function (e) { done({error: String(e)}); });""")
        print("cond video after play(): %s" % played)
        check(played.get("t", 0) > 0, "the condition video plays")
    else:
        n = d.js("return [document.querySelectorAll('video').length,"
                 " document.querySelectorAll('.card .novideo a').length,"
                 " document.querySelectorAll('.card figure.strip img').length,"
                 " document.getElementById('codec-note').hidden]")
        check(n[0] == 0 and n[1] == 2 * len(vids) and n[2] == len(vids) and
              n[3] is False,
              "no H.264: links instead of the players, the preview strips and"
              " the note shown (%s)" % n)
    check_console(d, "demo report after playing")
    # Screenshots: the first screen at 1280x900, then a narrow window.
    d.viewport(1280, 900)
    d.js("window.scrollTo(0, 0)")
    size = d.screenshot(os.path.join(work, "report.png"))
    check(size > 10000, "screenshot report.png (%d bytes)" % size)
    d.js("document.getElementById('pairs').scrollIntoView()")
    d.screenshot(os.path.join(work, "report_pairs.png"))
    d.js("document.getElementById('videos').scrollIntoView()")
    d.screenshot(os.path.join(work, "report_videos.png"))
    d.js("window.scrollTo(0, 0)")
    d.viewport(400, 900)
    narrow = d.js("""
      var de = document.documentElement;
      var s = document.querySelector('#pairs .scroll');
      var card = document.querySelector('article.card .vids');
      var figs = card ? card.children : [];
      return {inner: window.innerWidth, page: de.scrollWidth,
              tableScrolls: s.scrollWidth > s.clientWidth,
              stacked: figs.length == 2 &&
                       figs[1].getBoundingClientRect().top >=
                       figs[0].getBoundingClientRect().bottom};""")
    check(narrow["page"] <= narrow["inner"] and narrow["stacked"],
          "narrow window: no page-wide horizontal scroll, videos stacked (%s)"
          % narrow)
    d.screenshot(os.path.join(work, "report_narrow.png"))
    d.viewport(1280, 900)


def check_failure_report(d, out):
    manifest = read_jsonl(os.path.join(out, "manifest.jsonl"))
    fails = read_jsonl(os.path.join(out, "failures.jsonl"))
    check(len(fails) == 1, "the broken run recorded one failure")
    d.go(file_url(os.path.join(out, "report.html")))
    check_console(d, "failure report")
    got = d.js("""
      return {
        count: document.getElementById('count-failed').textContent,
        rows: Array.prototype.map.call(
          document.querySelectorAll('#pair-table tr.fail-row'), function (r) {
            return [r.getAttribute('data-clip'), r.cells[7].textContent]; }),
        pairs: document.querySelectorAll('#pair-table tr.pair-row').length,
        items: Array.prototype.map.call(
          document.querySelectorAll('ol.failures li'), function (li) {
            return [li.querySelector('.clip').textContent,
                    li.querySelector('.stage').textContent,
                    li.querySelector('.msg').textContent]; })};""")
    want = [[f["clip_id"], f["stage"], f["error"]] for f in fails]
    check(got["count"] == str(len(fails)), "failed count %s" % got["count"])
    check(got["pairs"] == len(manifest), "pair rows %d = manifest lines %d" % (
        got["pairs"], len(manifest)))
    check(got["rows"] == [w[:2] for w in want],
          "a table row per failed clip with its stage: %s" % got["rows"])
    check(got["items"] == want,
          "failures listed with clip, stage and message: %s" % got["items"])
    # Failed clips have no coverage: last in either order.
    for order in ("ascending", "descending"):
        d.click("#sort-coverage button")
        rows = d.js(ROWS_JS)
        check([r["cls"] for r in rows][-len(fails):] == ["fail-row"] *
              len(fails), "sorted %s by coverage, failed clips last: %s" % (
                  order, [(r["clip"], r["v"]) for r in rows]))


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    work = os.path.abspath(sys.argv[1])
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not os.access(p, os.X_OK)]
    if missing:
        if os.environ.get("GEODRIVE_REQUIRE_BROWSER") == "1":
            print("FAIL: %s missing and GEODRIVE_REQUIRE_BROWSER=1 "
                  "(apt-get install chromium chromium-driver)" % missing)
            return 1
        print("SKIP: chromium/chromedriver not installed "
              "(apt-get install chromium chromium-driver)")
        return SKIP
    geodrive = os.environ.get("GEODRIVE_BINARY")
    if not geodrive or not os.access(geodrive, os.X_OK):
        raise SystemExit("GEODRIVE_BINARY: not an executable: %r" % geodrive)
    t0 = time.time()
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    synth, out = os.path.join(work, "synth"), os.path.join(work, "pairs")
    try:
        # The demo's data (scripts/demo.sh), shorter and smaller: two 8 s
        # scenes at 450x800 give 6 pairs (the demo's 20 s at 1600x900 give
        # 18); the report's checks read the counts from the manifest.
        run([geodrive, "synth", "--out", synth, "--scenes", "2", "--seed", "7",
             "--monst3r", "--duration", "8", "--size", "450x800"])
        run([geodrive, "build-dataset", "--dataroot", synth, "--version",
             "v1.0-mini", "--monst3r", synth + "/monst3r", "--out", out,
             "--threads", "2", "--quiet"])
        # A run with two clips, one of them without its camera trajectory.
        clips = sorted(os.listdir(os.path.join(synth, "monst3r")))
        bad_root = os.path.join(work, "monst3r_broken")
        for c in clips[:2]:
            shutil.copytree(os.path.join(synth, "monst3r", c),
                            os.path.join(bad_root, c))
        os.remove(os.path.join(bad_root, clips[1], "pred_traj.txt"))
        out_bad = os.path.join(work, "pairs_broken")
        run([geodrive, "build-dataset", "--dataroot", synth, "--version",
             "v1.0-mini", "--monst3r", bad_root, "--out", out_bad, "--quiet"],
            ok_codes=(3,))
    finally:
        # The synthetic world and its copy are not needed any more.
        shutil.rmtree(synth, ignore_errors=True)
        shutil.rmtree(os.path.join(work, "monst3r_broken"), ignore_errors=True)
    print("data built in %.1f s" % (time.time() - t0), flush=True)

    profile = tempfile.mkdtemp(prefix="chromium-profile-", dir=work)
    d = None
    try:
        d = WebDriver(profile)
        check_demo_report(d, out, work)
        check_failure_report(d, out_bad)
    finally:
        if d:
            d.quit()
        shutil.rmtree(profile, ignore_errors=True)
    print("total %.1f s; screenshots: %s" % (
        time.time() - t0, os.path.join(work, "report.png")))
    if failures:
        print("%d check(s) failed:\n  %s" % (len(failures),
                                             "\n  ".join(failures)))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
