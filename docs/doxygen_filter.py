#!/usr/bin/env python3
"""Doxygen INPUT_FILTER for kneedyn's headers (docs/build_docs.py).

The headers comment in plain `//` prose, as the developers' guide asks (short, with
units, saying why). Doxygen reads only `///`-style comments, so this filter hands it the
plain ones as documentation, escaped so that they read as text, not as Doxygen commands:

  - the comment block at the top of a file        -> that file's description (@file)
  - a comment block right above a declaration     -> the declaration's description
  - `code;  // text` or `code,  // text` (members, enumerators) -> `///<` after the member

The C header (kneedyn/problem.h, C89) comments in `/* */` blocks; they are read the same way:
a block at the top, a block right above a declaration, and `code;  /* text */` after a member.

Comments written for Doxygen (`///`, `//!`, `/** */`) pass through unchanged, so their
commands are checked and their warnings fail the docs build (WARN_AS_ERROR). Line count
is preserved, so Doxygen's line numbers are the header's.
"""
import re
import sys

SPECIAL = re.compile(r"([\\@<>&#%$])")
PLAIN = re.compile(r"^(\s*)//(?![/!])\s?(.*)$")
TRAILING = re.compile(r"^(.*?[;,{])(\s*)//(?![/!])\s?(.*)$")
C_OPEN = re.compile(r"^(\s*)/\*(?![*!])\s?(.*)$")  # a C block comment's first line
C_TRAILING = re.compile(r"^(.*?[;,{])(\s*)/\*(?![*!])\s?(.*?)\s*\*/\s*$")


def c_blocks(lines):
    """The `/* */` blocks standing on lines of their own, as lists of // lines: the same line
    count, text without the comment's frame. Other lines are returned as they are."""
    out = list(lines)
    i = 0
    while i < len(lines):
        m = C_OPEN.match(lines[i])
        if not m:
            t = C_TRAILING.match(lines[i])
            if t and outside_string(t.group(1)):
                out[i] = "%s%s// %s\n" % (t.group(1), t.group(2), t.group(3))
            i += 1
            continue
        j = i
        while j < len(lines) and "*/" not in lines[j]:
            j += 1
        if j == len(lines) or lines[j].split("*/", 1)[1].strip():
            i += 1  # unterminated, or code after the comment: left as it is
            continue
        indent = m.group(1)
        for k in range(i, j + 1):
            text = m.group(2) if k == i else re.sub(r"^\s*\*?(?!/)\s?", "", lines[k].rstrip("\n"))
            text = text.split("*/", 1)[0].rstrip()
            out[k] = "%s// %s\n" % (indent, text)
        i = j + 1
    return out


def escape(text):
    # "--help" stays two hyphens (Doxygen would print an en dash): its escapes \-- and \---.
    return re.sub(r"-{2,3}", lambda m: "\\" + m.group(0), SPECIAL.sub(r"\\\1", text))


def outside_string(code):
    return code.count('"') % 2 == 0 and code.count("'") % 2 == 0


def convert(lines, path):
    out = list(lines)
    i = 0
    seen_code = False
    while i < len(lines):
        m = PLAIN.match(lines[i])
        if not m:
            t = TRAILING.match(lines[i])
            if t and outside_string(t.group(1)):
                out[i] = "%s%s///< %s\n" % (t.group(1), t.group(2), escape(t.group(3)))
            if lines[i].strip() and not lines[i].lstrip().startswith("#"):
                seen_code = True
            i += 1
            continue
        j = i
        while j < len(lines) and PLAIN.match(lines[j]):
            j += 1
        nxt = lines[j].strip() if j < len(lines) else ""
        if not seen_code and not any(l.strip() and not PLAIN.match(l) and not l.lstrip().startswith("#")
                                     for l in lines[:i]):
            # First comment block of the file: the file's description ("@file NAME" reads
            # one word, the file's path; the text goes on as the description).
            for k in range(i, j):
                indent, text = PLAIN.match(lines[k]).groups()
                out[k] = "%s/// %s%s\n" % (indent, "@file %s " % path if k == i else "", escape(text))
            seen_code = True
        elif nxt and not nxt.startswith("#") and nxt not in ("}", "};", "public:", "private:", "protected:") \
                and not nxt.startswith("namespace"):
            for k in range(i, j):
                indent, text = PLAIN.match(lines[k]).groups()
                out[k] = "%s/// %s\n" % (indent, escape(text))
        i = j
    return out


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        lines = f.readlines()
    if sys.argv[1].endswith(".h"):
        lines = c_blocks(lines)
    sys.stdout.write("".join(convert(lines, sys.argv[1])))


if __name__ == "__main__":
    main()
