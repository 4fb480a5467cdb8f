#!/usr/bin/env python3
"""`cpack -G DEB` against the install rules (tests/packaging/CMakeLists.txt).

  - the package is kneedyn_<version>_amd64.deb, <version> from CMakeLists.txt's project();
  - its file list is exactly what `cmake --install BUILD --prefix /usr` puts in place
    (DESTDIR staging): nothing missing, nothing extra;
  - its Depends names, for every shared library that an installed ELF file needs (NEEDED
    entries, resolved through ldconfig's cache and `dpkg -S`, independently of CPack's
    dpkg-shlibdeps), the Debian package that holds it; and python3 and python3-numpy for
    the Python module (in Debian's /usr/lib/python3/dist-packages).
"""
import os
import re
import subprocess
import sys
import time

from packaging_common import source_build_work, verdict


def run(cmd, **kw):
    print("+ " + " ".join(str(c) for c in cmd), flush=True)
    return subprocess.run([str(c) for c in cmd], check=True, **kw)


def output(cmd):
    return subprocess.run([str(c) for c in cmd], check=True, capture_output=True, text=True).stdout


def is_elf(path):
    with open(path, "rb") as f:
        return f.read(4) == b"\x7fELF"


def needed(path):
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", output(["readelf", "-d", path]))


def ldconfig_paths():
    paths = {}
    for line in output(["/sbin/ldconfig", "-p"]).splitlines():
        m = re.match(r"\s+(\S+) \(([^)]*)\) => (\S+)", line)
        if m and "x86-64" in m.group(2):
            paths.setdefault(m.group(1), m.group(3))
    return paths


def owner(path):
    """Debian package holding path (merged /usr: tried as given and resolved)."""
    for candidate in dict.fromkeys([path, os.path.realpath(path), re.sub(r"^/usr/lib/", "/lib/", path),
                                    re.sub(r"^/lib/", "/usr/lib/", path)]):
        r = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True)
        if r.returncode == 0:
            return r.stdout.split(":")[0].strip()
    return None


def main():
    source, build, work = source_build_work()
    problems = []

    version = re.search(r"project\(kneedyn\s+VERSION\s+([0-9.]+)", (source / "CMakeLists.txt").read_text()).group(1)
    arch = output(["dpkg", "--print-architecture"]).strip()
    t0 = time.monotonic()
    run(["cpack", "-G", "DEB", "-B", work / "cpack", "--config", build / "CPackConfig.cmake"], stdout=subprocess.DEVNULL)
    print("cpack -G DEB: %.1f s" % (time.monotonic() - t0))
    debs = sorted((work / "cpack").glob("*.deb"))
    name = "kneedyn_%s_%s.deb" % (version, arch)
    if [d.name for d in debs] != [name]:
        print("FAIL: cpack wrote %s, expected %s" % ([d.name for d in debs], name))
        return 1
    deb = debs[0]

    # What the install rules put in place under /usr.
    stage = work / "destdir"
    run(["cmake", "--install", build, "--prefix", "/usr"], env=dict(os.environ, DESTDIR=str(stage)),
        stdout=subprocess.DEVNULL)
    installed = {"/" + p.relative_to(stage).as_posix() for p in stage.rglob("*") if p.is_file() or p.is_symlink()}
    packaged = set()
    for line in output(["dpkg-deb", "-c", deb]).splitlines():
        fields = line.split(None, 5)
        if fields[0].startswith("d"):
            continue
        packaged.add(fields[5].split(" -> ")[0].lstrip("."))
    for path in sorted(installed - packaged):
        problems.append("installed by cmake --install but not in %s: %s" % (deb.name, path))
    for path in sorted(packaged - installed):
        problems.append("in %s but not installed by cmake --install: %s" % (deb.name, path))
    for must in ("/usr/bin/kneedyn", "/usr/lib/python3/dist-packages/kneedyn/__init__.py",
                 "/usr/share/kneedyn/scenes/chapter_impact.yaml", "/usr/lib/pkgconfig/kneedyn.pc",
                 "/usr/lib/cmake/kneedyn/kneedynConfig.cmake"):
        if must not in packaged:
            problems.append("%s lacks %s" % (deb.name, must))
    print("%s: %d files, the install rules %d" % (deb.name, len(packaged), len(installed)))

    # Depends against the shared libraries the installed ELF files need.
    fields = {k: output(["dpkg-deb", "-f", deb, k]).strip() for k in ("Package", "Version", "Architecture", "Depends")}
    if (fields["Package"], fields["Version"], fields["Architecture"]) != ("kneedyn", version, arch):
        problems.append("control fields %s" % fields)
    depends = {re.match(r"\s*([a-z0-9.+-]+)", alt).group(1)
               for item in fields["Depends"].split(",") for alt in item.split("|") if alt.strip()}
    libs = ldconfig_paths()
    required = {}
    for path in sorted(stage.rglob("*")):
        if path.is_file() and not path.is_symlink() and is_elf(path):
            for soname in needed(path):
                if soname not in libs:
                    problems.append("%s needs %s, which ldconfig does not know" % (path.name, soname))
                    continue
                pkg = owner(libs[soname])
                if pkg is None:
                    problems.append("%s needs %s (%s), which no Debian package holds" % (path.name, soname, libs[soname]))
                else:
                    required.setdefault(pkg, set()).add(path.name)
    required.setdefault("python3", set()).add("kneedyn/__init__.py")
    required.setdefault("python3-numpy", set()).add("kneedyn/__init__.py (import numpy)")
    for pkg, users in sorted(required.items()):
        if pkg not in depends:
            problems.append("Depends lacks %s (needed by %s)" % (pkg, ", ".join(sorted(users))))
    print("Depends: %s" % fields["Depends"])
    print("needed packages: %s" % ", ".join(sorted(required)))

    return verdict(problems, "OK: %s holds what the install rules install, and Depends covers its %d runtime packages"
                   % (deb.name, len(required)), work=work)


if __name__ == "__main__":
    sys.exit(main())
