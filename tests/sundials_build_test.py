#!/usr/bin/env python3
"""The SUNDIALS inside kneedyn's programs is the optimized build (cmake/sundials.cmake).

For each binary given: no dynamic dependency on a libsundials shared object (every SUNDIALS
symbol resolves inside the binary), IDASolve and CVode are defined in it, and the SUNDIALS
functions in it are optimized code. The measure: the share of instructions that address
memory through the frame pointer %rbp. Code compiled at -O0 keeps every local and argument
in the stack frame and reaches it through %rbp (Debian's libsundials_idas.so: 34 %); at -O2
or -O3 GCC keeps them in registers and omits the frame pointer (a few per cent at most).

  sundials_build_test.py BINARY...            check the binaries
  sundials_build_test.py --share LIB_OR_BIN   print the %rbp share of its SUNDIALS functions
"""
import bisect
import re
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
from py_test_support import finish  # noqa: E402

# SUNDIALS' public and internal C prefixes (IDAS, CVODES, ARKODE, vectors, matrices,
# linear and nonlinear solvers, the context).
SUNDIALS_FUNCTION = re.compile(
    r"^(IDA|ida|CVode|cvode|cv[A-Z]|ARK|ark|ERKStep|erkStep|N_V|SUN|sun|SUNDlsMat|dense|band)")
MAX_FRAME_SHARE = 0.10


def symbols_of(path, extra=()):
    """nm output of path; the dynamic symbols of a stripped shared object (the Python module)."""
    out = subprocess.run(["nm", *extra, path], capture_output=True, text=True).stdout
    if not out.strip():
        out = subprocess.run(["nm", "-D", "--defined-only", *extra, path], check=True,
                             capture_output=True, text=True).stdout
    return out


def frame_pointer_share(path):
    """(functions, instructions, of which address (%rbp)) over the SUNDIALS functions of path.

    Function extents come from the symbol table with sizes (nm -S), so that a stripped shared
    object is measured through its dynamic symbols."""
    ranges = []
    for line in symbols_of(path, ("-S",)).splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "Tt" and SUNDIALS_FUNCTION.match(parts[3]):
            start, size = int(parts[0], 16), int(parts[1], 16)
            if size:
                ranges.append((start, start + size))
    ranges = sorted(set(ranges))
    starts = [r[0] for r in ranges]
    dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", path], check=True,
                         capture_output=True, text=True).stdout
    total = through_rbp = 0
    for line in dis.splitlines():
        m = re.match(r"^\s+([0-9a-f]+):\s+\S", line)
        if not m:
            continue
        addr = int(m.group(1), 16)
        i = bisect.bisect_right(starts, addr) - 1
        if i >= 0 and addr < ranges[i][1]:
            total += 1
            through_rbp += "(%rbp)" in line
    return len(ranges), total, through_rbp


def check(path):
    errors = []
    needed = subprocess.run(["readelf", "-d", path], check=True, capture_output=True,
                            text=True).stdout
    for lib in re.findall(r"\[(libsundials[^\]]*)\]", needed):
        errors.append(f"{path}: needs {lib} (Debian's unoptimized SUNDIALS)")
    symbols = symbols_of(path)
    for name in ("IDASolve", "CVode"):
        if not re.search(rf" [Tt] {name}$", symbols, re.M):
            errors.append(f"{path}: {name} is not defined in the binary")
    functions, total, through_rbp = frame_pointer_share(path)
    share = through_rbp / total if total else 1.0
    print(f"{path}: {functions} SUNDIALS functions, {total} instructions, "
          f"{100 * share:.1f} % address (%rbp) (limit {100 * MAX_FRAME_SHARE:.0f} %)")
    if total == 0:
        errors.append(f"{path}: no SUNDIALS functions found")
    elif share > MAX_FRAME_SHARE:
        errors.append(f"{path}: {100 * share:.1f} % of the SUNDIALS instructions address the "
                      f"stack frame through %rbp (> {100 * MAX_FRAME_SHARE:.0f} %): unoptimized code")
    return errors


def main(argv):
    if len(argv) == 3 and argv[1] == "--share":
        functions, total, through_rbp = frame_pointer_share(argv[2])
        print(f"{argv[2]}: {functions} functions, {total} instructions, "
              f"{100 * through_rbp / max(total, 1):.1f} % (%rbp)")
        return 0
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    errors = [e for path in argv[1:] for e in check(path)]
    failed = len({e.split(':')[0] for e in errors})
    return finish(errors, "FAIL:", f"{len(argv) - 1 - failed} passed, {failed} failed", sys.stdout)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
