#!/usr/bin/python3
"""Opens the generated report in headless Chromium and fails on a missing image, a broken
link or content wider than the viewport.

  browser_test.py --kneedyn PATH [--catalog PATH] [--bench JSON] [--report DIR] [--screenshot PNG]

Without --report it builds a quick report (reports/report.py --quick, plus a two-case
hard-case catalog and the recorded work-precision sweep) in a temporary directory. The
page is copied beside itself with a small script appended; Chromium loads it
(--dump-dom), the script waits for every image and writes what it found into the DOM:
  - images that did not load (naturalWidth 0);
  - in-page links (#id) with no such id; other links are resolved by the browser and
    checked here: relative files must exist;
  - document width beyond the viewport (scrollWidth > innerWidth), with the widest element.
Before the real page, a planted page with one of each fault must be flagged, so the test
cannot pass by checking nothing.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import urllib.parse

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHROMIUM = "/usr/bin/chromium"
WIDTH, HEIGHT = 1280, 900
RECORDED_BENCH = os.path.join(ROOT, "benchmarks", "recorded", "work_precision_chapter_impact.json")

CHECK_JS = """
<script>
window.addEventListener('load', function () {
  var out = {images: [], anchors: [], links: [], width: 0, viewport: window.innerWidth, widest: ''};
  var imgs = Array.prototype.slice.call(document.images);
  imgs.forEach(function (im) {
    if (!im.complete || im.naturalWidth === 0) out.images.push(im.getAttribute('src'));
  });
  Array.prototype.slice.call(document.querySelectorAll('a[href]')).forEach(function (a) {
    var h = a.getAttribute('href');
    if (h.charAt(0) === '#') {
      if (h.length > 1 && !document.getElementById(decodeURIComponent(h.slice(1)))) out.anchors.push(h);
    } else {
      out.links.push(a.href);
    }
  });
  out.width = document.documentElement.scrollWidth;
  var worst = 0;
  Array.prototype.slice.call(document.body.querySelectorAll('*')).forEach(function (el) {
    var r = el.getBoundingClientRect();
    var clipped = false;
    for (var p = el.parentElement; p && p !== document.body; p = p.parentElement) {
      var ov = getComputedStyle(p).overflowX;
      if (ov === 'auto' || ov === 'scroll' || ov === 'hidden') { clipped = true; break; }
    }
    if (!clipped && r.right > worst) { worst = r.right; out.widest = el.tagName + (el.id ? '#' + el.id : '') +
        (el.className ? '.' + el.className : '') + ' right=' + Math.round(r.right); }
  });
  var pre = document.createElement('pre');
  pre.id = 'kneedyn-browser-check';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>
"""

PLANTED = """<!DOCTYPE html><html><head><meta charset='utf-8'></head><body>
<img src='figures/does_not_exist.png' alt='x'>
<a href='#no-such-section'>in-page</a> <a href='no_such_file.csv'>file</a>
<div style='width: 3000px'>wide</div></body></html>"""


def run_chromium(html_path, user_dir, screenshot=None):
  # --disable-dev-shm-usage: a container's small /dev/shm (64 MB) can crash the renderer.
  args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-background-networking",
          "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={user_dir}",
          "--allow-file-access-from-files", f"--window-size={WIDTH},{HEIGHT}", "--virtual-time-budget=10000"]
  if screenshot:
    cmd = args + [f"--screenshot={screenshot}", "file://" + html_path]
  else:
    cmd = args + ["--dump-dom", "file://" + html_path]
  p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
  return p


def check_page(index, user_dir):
  """Problems found on index.html (list of strings)."""
  folder = os.path.dirname(os.path.abspath(index))
  probe = os.path.join(folder, ".browser_check.html")
  with open(index, encoding="utf-8") as f:
    page = f.read()
  page = page.replace("</body>", CHECK_JS + "</body>") if "</body>" in page else page + CHECK_JS
  with open(probe, "w", encoding="utf-8") as f:
    f.write(page)
  try:
    p = run_chromium(probe, user_dir)
  finally:
    os.remove(probe)
  m = re.search(r'<pre id="kneedyn-browser-check">(.*?)</pre>', p.stdout, re.S)
  if not m:
    return [f"chromium gave no result (exit {p.returncode}): {p.stderr[-800:]}"]
  res = json.loads(m.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">")
                   .replace("&amp;", "&"))
  problems = [f"image did not load: {s}" for s in res["images"]]
  problems += [f"in-page link to a missing id: {h}" for h in res["anchors"]]
  for href in res["links"]:
    u = urllib.parse.urlparse(href)
    if u.scheme == "file":
      path = urllib.parse.unquote(u.path)
      if os.path.basename(path) == ".browser_check.html":
        continue
      if not os.path.exists(path):
        problems.append(f"broken link: {os.path.relpath(path, folder)}")
    elif u.scheme not in ("http", "https", "mailto"):
      problems.append(f"link with unexpected scheme: {href}")
  if res["width"] > res["viewport"] + 1:
    problems.append(f"content {res['width']} px wide in a {res['viewport']} px viewport (widest: {res['widest']})")
  return problems


def build_report(args, out):
  py = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable
  cmd = [py, os.path.join(ROOT, "reports", "report.py"), "--kneedyn", args.kneedyn, "--out", out, "--quick"]
  bench = args.bench or (RECORDED_BENCH if os.path.exists(RECORDED_BENCH) else None)
  if bench:
    cmd += ["--bench", bench]
  if args.catalog:
    hc = os.path.join(out, "hard_cases")
    c = subprocess.run([args.catalog, "--out", hc, "--case", "c1_law", "--case", "jcs_singular_pose"],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    if c.returncode == 0:
      cmd += ["--hard-cases", os.path.join(hc, "hard_cases.csv")]
    else:
      print(f"browser_test: catalog failed ({c.returncode}): {c.stderr[-400:]}", file=sys.stderr)
  p = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=ROOT)
  if p.returncode not in (0, 1):
    print(p.stdout[-2000:], p.stderr[-2000:], file=sys.stderr)
  return os.path.join(out, "index.html")


def main():
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--kneedyn")
  ap.add_argument("--catalog", help="kneedyn_catalog binary (adds a two-case hard-case section)")
  ap.add_argument("--bench", help="benchmark JSON (default: the recorded full sweep)")
  ap.add_argument("--report", help="check this existing report directory instead of building one")
  ap.add_argument("--screenshot", help="also write a full-page screenshot (PNG) here")
  args = ap.parse_args()
  if not os.access(CHROMIUM, os.X_OK):
    print(f"browser_test: {CHROMIUM} not found (Debian package chromium; .ci/bootstrap installs it)",
          file=sys.stderr)
    return 1
  if not args.report and not args.kneedyn:
    print("browser_test: give --kneedyn (to build a report) or --report DIR", file=sys.stderr)
    return 2
  with tempfile.TemporaryDirectory(prefix="kneedyn_browser_") as tmp:
    user_dir = os.path.join(tmp, "chromium-profile")
    planted_dir = os.path.join(tmp, "planted")
    os.makedirs(planted_dir)
    with open(os.path.join(planted_dir, "index.html"), "w") as f:
      f.write(PLANTED)
    planted = check_page(os.path.join(planted_dir, "index.html"), user_dir)
    kinds = ("image did not load", "in-page link", "broken link", "px wide")
    missed = [k for k in kinds if not any(k in p for p in planted)]
    if missed:
      print(f"browser_test: the checker missed planted faults {missed}; found {planted}", file=sys.stderr)
      return 1
    out = args.report or os.path.join(tmp, "report")
    index = os.path.join(out, "index.html") if args.report else build_report(args, out)
    if not os.path.exists(index):
      print(f"browser_test: {index} not written", file=sys.stderr)
      return 1
    problems = check_page(index, user_dir)
    if args.screenshot:
      shutil.rmtree(user_dir, ignore_errors=True)
      run_chromium(os.path.abspath(index), user_dir, os.path.abspath(args.screenshot))
  for p in problems:
    print("browser_test: FAIL:", p, file=sys.stderr)
  print(f"browser_test: {'ok' if not problems else str(len(problems)) + ' problems'} "
        f"(planted faults caught: {len(planted)})")
  return 1 if problems else 0


if __name__ == "__main__":
  sys.exit(main())
