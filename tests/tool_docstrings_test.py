#!/usr/bin/python3
"""Each Python tool's module docstring is its usage text: it names every long option the
tool's parser defines, and the tool's usage lines name no option the parser lacks.

  tool_docstrings_test.py [--root DIR]

Tools: every tracked .py file under reports/, benchmarks/ and examples/ that calls
add_argument. Each is parsed with the ast module, never imported or run. Its options are the
string arguments of its add_argument calls that start with "--" (positional arguments and
-h/--help left out); an add_argument call whose option names are not string literals is a
failure, since it cannot be checked.

Forward check: every option appears in the module docstring as a whole word (`--calibrate`
is not found inside `--calibrate-grid`).

Reverse check, on the usage lines only. A docstring also names other programs' options
(`kneedyn run ... --quiet`, `valgrind --tool=callgrind`, `cmake --build`), so an option in
the prose is not checked. A usage line is an indented docstring line whose command is the
tool itself (its file name, after optional VAR=value settings and a python interpreter),
with its continuation lines (after a trailing backslash, or indented deeper than it). In
them, text in parentheses or backquotes is left out (it names other programs: "(runs
report.py --reconstruction ...)"), and every --option left must be one the parser defines.
A tool's docstring must have at least one usage line, so the reverse check always has
something to check.

Before scanning, the checks run on planted tools and must flag each planted fault and
nothing in a clean one, so the test cannot pass by matching nothing. Exit 0 when every tool
passes, 1 otherwise, 2 on bad arguments.
"""
import ast
import os
import re
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
from comment_references_test import root_argument  # noqa: E402
from outside_paths_test import tracked_files  # noqa: E402
from py_test_support import finish  # noqa: E402

TOOL_DIRS = ("reports/", "benchmarks/", "examples/")
OPTION = re.compile(r"(?<![\w-])--[A-Za-z][\w-]*")
ENV_SETTING = re.compile(r"^[A-Za-z_]\w*=\S*$")
INTERPRETER = re.compile(r"^(\S*/)?python3?(\.\d+)?$")


def parser_options(tree):
  """({long options of the add_argument calls}, [problems]) of a parsed module."""
  options, problems = set(), []
  for node in ast.walk(tree):
    if not isinstance(node, ast.Call):
      continue
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name != "add_argument":
      continue
    for arg in node.args:
      if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
        problems.append(f"line {node.lineno}: add_argument with an option name that is not a string literal "
                        "(cannot be checked against the docstring)")
      elif arg.value.startswith("--") and arg.value != "--help":
        options.add(arg.value)
  return options, problems


def mentions(doc, option):
  """True when `option` is a whole word of doc (not a prefix of a longer option)."""
  return re.search(r"(?<![\w-])" + re.escape(option) + r"(?![\w-])", doc) is not None


def is_usage_line(line, tool):
  """An indented line whose command (after VAR=value settings and a python) is `tool`."""
  if not line[:1].isspace():
    return False
  words = line.split()
  while words and (ENV_SETTING.match(words[0]) or INTERPRETER.match(words[0])):
    words = words[1:]
  return bool(words) and os.path.basename(words[0]) == tool


def usage_blocks(doc, tool):
  """The usage lines of doc for `tool`, each joined with its continuation lines."""
  lines = doc.splitlines()
  blocks, i = [], 0
  while i < len(lines):
    if not is_usage_line(lines[i], tool):
      i += 1
      continue
    indent = len(lines[i]) - len(lines[i].lstrip())
    block = [lines[i]]
    i += 1
    while i < len(lines) and lines[i].strip() and (
        block[-1].rstrip().endswith("\\") or len(lines[i]) - len(lines[i].lstrip()) > indent):
      block.append(lines[i])
      i += 1
    blocks.append("\n".join(block))
  return blocks


def usage_options(block):
  """The --options of a usage block, less those in backquotes or parentheses."""
  text = re.sub(r"`[^`]*`", " ", block)
  while True:  # innermost parentheses first, so nested ones go too
    shorter = re.sub(r"\([^()]*\)", " ", text)
    if shorter == text:
      break
    text = shorter
  return set(OPTION.findall(text))


def problems_of(rel, source):
  """["rel: problem"] for one tool's source, or None when it is no tool (no add_argument call)."""
  try:
    tree = ast.parse(source, filename=rel)
  except SyntaxError as e:
    return [f"{rel}: not parsable ({e.msg}, line {e.lineno})"]
  if not any(isinstance(n, ast.Call) and "add_argument" in (getattr(n.func, "attr", None), getattr(n.func, "id", None))
             for n in ast.walk(tree)):
    return None
  options, found = parser_options(tree)
  problems = [f"{rel}: {p}" for p in found]
  doc = ast.get_docstring(tree)
  if doc is None:
    return problems + [f"{rel}: no module docstring (the tool's usage text), options {sorted(options)}"]
  problems += [f"{rel}: option {o} is defined by add_argument but not named in the module docstring"
               for o in sorted(options) if not mentions(doc, o)]
  tool = os.path.basename(rel)
  blocks = usage_blocks(doc, tool)
  if not blocks:
    problems.append(f"{rel}: the module docstring has no usage line (an indented line running {tool})")
  for block in blocks:
    first = block.splitlines()[0].strip()
    problems += [f"{rel}: usage line '{first[:60]}' names {o}, which the parser does not define"
                 for o in sorted(usage_options(block) - options)]
  return problems


# Planted tools: each bad one has one fault, named by the fragment its problem must contain.
PLANTED_CLEAN = '''"""A planted tool.

    PYTHONPATH=x /usr/bin/python3 tools/planted.py --out DIR [--jobs N] \\
        [--calibrate BIN [--calibrate-grid N]] NAME
    planted.py --out DIR ...   (runs `other --foreign` and report.py --reconstruction
                               first)
    other.py --not-ours

Prose may name other programs' options: `kneedyn run --rtol 1e-8`, valgrind --tool=callgrind.
"""
import argparse
ap = argparse.ArgumentParser()
ap.add_argument("--out", required=True)
ap.add_argument("-j", "--jobs", type=int)
ap.add_argument("--calibrate")
ap.add_argument("--calibrate-grid", type=int)
ap.add_argument("name")
'''
PLANTED_BAD = [
    (PLANTED_CLEAN.replace('ap.add_argument("name")', 'ap.add_argument("--seed")'), "option --seed"),
    (PLANTED_CLEAN.replace("[--calibrate BIN [--calibrate-grid N]]", "[--calibrate-grid N]"), "option --calibrate "),
    (PLANTED_CLEAN.replace("[--jobs N]", "[--jobs N] [--verbose]"), "names --verbose"),
    (PLANTED_CLEAN.replace("[--calibrate BIN", "[--calibrate BIN --dry-run"), "names --dry-run"),
    (PLANTED_CLEAN.replace("    planted.py --out DIR ...", "    planted.py --out DIR --typo"), "names --typo"),
    (PLANTED_CLEAN.replace("  first)", "  first) --late"), "names --late"),
    (PLANTED_CLEAN.replace("tools/planted.py", "tools/other.py").replace("    planted.py", "    other.py"),
     "no usage line"),
    (PLANTED_CLEAN.replace('ap.add_argument("name")', 'ap.add_argument(FLAG)'), "not a string literal"),
    (PLANTED_CLEAN.replace('"""A planted tool.', 'USAGE = """A planted tool.'), "no module docstring"),
]


def self_check():
  errors = [f"clean planted tool flagged: {p}" for p in problems_of("tools/planted.py", PLANTED_CLEAN)]
  if problems_of("tools/not_a_tool.py", '"""No parser."""\nimport os\n') is not None:
    errors.append("a module without add_argument taken for a tool")
  for source, fragment in PLANTED_BAD:
    found = problems_of("tools/planted.py", source) or []
    if not any(fragment in p for p in found):
      errors.append(f"planted fault {fragment!r} not flagged (found: {found})")
  return errors


def main():
  root = root_argument("tool_docstrings_test", __doc__)
  if root is None:
    return 2
  broken = self_check()
  if broken:
    return finish(broken, "CHECK BROKEN:", "tool_docstrings_test: the checks fail on planted tools")
  tools, problems = 0, []
  for rel in tracked_files(root):
    if not (rel.endswith(".py") and rel.startswith(TOOL_DIRS)):
      continue
    try:
      with open(os.path.join(root, rel), encoding="utf-8") as f:
        found = problems_of(rel, f.read())
    except (OSError, UnicodeDecodeError) as e:
      found = [f"{rel}: unreadable ({e})"]
    if found is not None:
      tools += 1
      problems += found
  if tools < 10:  # the tools of reports/, benchmarks/ and examples/: a wrong root finds none
    problems.append(f"only {tools} tools with add_argument found under {root}")
  return finish(problems, "FAIL:", f"tool_docstrings_test: {tools} tools, {len(problems)} problem(s)")


if __name__ == "__main__":
  sys.exit(main())
