#!/usr/bin/env python3
"""The documentation site (docs/build_docs.py, tests/packaging/CMakeLists.txt).

Builds the site from this build tree into WORK/site, then checks:
  - every internal link of every page resolves: the file exists and holds the fragment's id;
  - the Python `run` entry links to the summary.json schema of docs/outputs.md (a section
    of outputs.html whose heading names summary.json);
  - cli.html holds the `--help` of every subcommand `kneedyn --help` lists, captured at
    build time, and api/cpp.html a section for every installed header;
  - the Doxygen gate can fail: a copy of the installed headers with a planted bad command
    (`\\frobnicate`) must make Doxygen report it.
"""
import html
import html.parser
import re
import shutil
import subprocess
import sys
import time
from urllib.parse import unquote, urldefrag

from packaging_common import source_build_work, verdict


class Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links = set(), []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "a" and "name" in a:
            self.ids.add(a["name"])
        if tag == "a" and a.get("href"):
            self.links.append(a["href"])


def parse(path):
    p = Page()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def main():
    source, build, work = source_build_work()
    site = work / "site"
    t0 = time.monotonic()
    subprocess.run([sys.executable, source / "docs" / "build_docs.py", "--build-dir", build, "--out", site,
                    "--work", work / "build"], check=True)
    print("docs build: %.1f s" % (time.monotonic() - t0))
    problems = []

    pages = {p: parse(p) for p in site.rglob("*.html")}
    checked = 0
    for page, parsed in pages.items():
        for href in parsed.links:
            if re.match(r"^[a-z]+:", href) or href.startswith("//"):
                continue  # external (none expected offline) or mailto
            target, fragment = urldefrag(href)
            dest = (page.parent / unquote(target)).resolve() if target else page
            if dest.is_dir():
                dest = dest / "index.html"
            checked += 1
            if not dest.exists():
                problems.append("%s: link %s: no file %s" % (page.relative_to(site), href, dest))
            elif fragment and dest.suffix == ".html":
                ids = pages[dest].ids if dest in pages else parse(dest).ids
                if fragment not in ids:
                    problems.append("%s: link %s: no id '%s' in %s" % (page.relative_to(site), href, fragment,
                                                                      dest.relative_to(site)))
    print("%d pages, %d internal links checked" % (len(pages), checked))

    # The Python run entry -> the summary.json schema in outputs.html.
    py = (site / "api" / "python.html").read_text(encoding="utf-8")
    start = py.find('id="kneedyn.run"')
    entry = py[start:py.find("</dd>", start)] if start >= 0 else ""
    to_outputs = re.findall(r'href="\.\./outputs\.html#([^"]+)"', entry)
    if start < 0:
        problems.append("api/python.html has no entry kneedyn.run")
    elif not to_outputs:
        problems.append("the kneedyn.run entry does not link into outputs.html")
    else:
        out_html = (site / "outputs.html").read_text(encoding="utf-8")
        m = re.search(r'<section id="%s">\s*<h\d>(.*?)</h\d>' % re.escape(to_outputs[0]), out_html, re.S)
        if not m or "summary.json" not in re.sub("<[^>]+>", "", m.group(1)):
            problems.append("kneedyn.run links to outputs.html#%s, which is not the summary.json section" % to_outputs[0])

    # Every subcommand's --help, and every installed header.
    stage = work / "build" / "stage"
    kneedyn = stage / "bin" / "kneedyn"
    top = subprocess.run([kneedyn, "--help"], check=True, capture_output=True, text=True).stdout
    subs = re.findall(r"^  (\w[\w-]*) ", top.split("Subcommands:")[1], re.M) if "Subcommands:" in top else []
    cli = re.sub(r"\s+", " ", re.sub("<[^>]+>", "", (site / "cli.html").read_text(encoding="utf-8")))
    cli = html.unescape(cli)
    if len(subs) < 3:
        problems.append("kneedyn --help lists %d subcommands: %s" % (len(subs), subs))
    for sub in subs:
        text = subprocess.run(["kneedyn", sub, "--help"], executable=kneedyn, check=True, capture_output=True,
                              text=True).stdout
        first_option = re.search(r"^\s+(--[\w-]+)", text.split("Options:")[-1], re.M)
        usage = re.sub(r"\s+", " ", text.splitlines()[1] if len(text.splitlines()) > 1 else text)
        if usage.strip() not in cli or (first_option and first_option.group(1) not in cli):
            problems.append("cli.html lacks `kneedyn %s --help` (%r)" % (sub, usage.strip()))
    headers = sorted(p.relative_to(stage / "include" / "kneedyn").as_posix()
                     for p in (stage / "include" / "kneedyn").rglob("*") if p.suffix in (".hpp", ".h"))
    cpp = (site / "api" / "cpp.html").read_text(encoding="utf-8")
    missing = [h for h in headers if ">%s<" % h not in cpp]
    if not headers or missing:
        problems.append("api/cpp.html lacks sections for %d of %d installed headers: %s" % (len(missing), len(headers), missing[:5]))
    print("%d subcommands, %d headers" % (len(subs), len(headers)))

    # The Doxygen gate on a planted error.
    sys.path.insert(0, str(source / "docs"))
    import build_docs
    planted = work / "planted" / "include"
    shutil.copytree(stage / "include" / "kneedyn", planted)
    header = planted / headers[0]
    header.write_text(header.read_text() + "\n/// \\frobnicate planted\nint kneedyn_planted_symbol();\n")
    warnings = build_docs.doxygen(planted, work / "planted" / "doxygen", work / "planted" / "warnings.txt")
    if "frobnicate" not in warnings:
        problems.append("Doxygen did not report the planted bad command in %s: %r" % (headers[0], warnings[:300]))

    return verdict(problems, work=work)


if __name__ == "__main__":
    sys.exit(main())
