"""The input contract of the Python tools (reports/, benchmarks/*.py), as the C++ programs keep
it (the exit codes in README.md; formulations/output_file.hpp): bad input is refused before any
run with a message naming the argument and its value, exit code 2, no traceback, and nothing
written. A tool raises BadInput (or calls the checks below, which do) and wraps its main in
`exit_code(prog, main)`:

    def main(argv=None):
      args = ap.parse_args(argv)
      tool_input.kneedyn_executable("--kneedyn", args.kneedyn)
      tool_input.output_directory("--out", args.out)
      header, runs = tool_input.checked(bench_data.load_bench, "--bench", args.bench)
      ...
    if __name__ == "__main__":
      sys.exit(tool_input.exit_code("report", main))

An external program that fails (callgrind_annotate, kneedyn score, ...) where the tool cannot
go on is a failed run, not bad input: run_command (or raising command_failed(...)) ends the
tool through exit_code with exit 1 and one line naming the command, its exit code and the
last lines of its stderr, instead of a CalledProcessError traceback.
"""
import json
import math
import os
import shlex
import subprocess
import sys
import tempfile


class BadInput(ValueError):
  """Bad input: the message names the argument (or field) and its value."""


class CommandFailed(RuntimeError):
  """An external program failed (a nonzero exit, or it could not start): a failed run, exit 1.
  A RuntimeError, so code that records a failed step and goes on may still catch it."""


def echo(value, limit=200):
  """A value as typed, cut for messages."""
  text = str(value)
  return text if len(text) <= limit else text[:limit - 3] + "..."


def exit_code(prog, main, argv=None):
  """main(argv)'s return code, or 'prog: error: message' and 2 when it raises BadInput, 1 when
  it raises CommandFailed."""
  try:
    rc = main(argv)
  except BadInput as e:
    print(f"{prog}: error: {e}", file=sys.stderr)
    return 2
  except CommandFailed as e:
    print(f"{prog}: error: {e}", file=sys.stderr)
    return 1
  return 0 if rc is None else rc


def command_failed(cmd, returncode, stderr, lines=3):
  """The CommandFailed for `cmd` (a list) that exited `returncode`: one line with the command,
  the exit code and the last `lines` non-blank lines of its stderr (joined by ' | ')."""
  tail = [line.strip() for line in (stderr or "").splitlines() if line.strip()][-lines:]
  said = echo(" | ".join(tail), 600) if tail else "nothing on stderr"
  how = f"exited {returncode}" if returncode >= 0 else f"was killed by signal {-returncode}"
  return CommandFailed(f"`{echo(shlex.join(str(c) for c in cmd), 400)}` {how}: {said}")


def run_command(cmd, **kwargs):
  """subprocess.run(cmd, capture_output=True, text=True, **kwargs) when it exits 0; CommandFailed
  when it exits otherwise or cannot start (not found, not executable)."""
  try:
    p = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
  except (OSError, subprocess.SubprocessError) as e:
    raise CommandFailed(f"`{echo(shlex.join(str(c) for c in cmd), 400)}` could not run: {echo(e)}") from None
  if p.returncode != 0:
    raise command_failed(cmd, p.returncode, p.stderr)
  return p


def checked(load, option, path, *args):
  """load(path, *args) with an unreadable, missing, directory or malformed file (OSError,
  ValueError incl. JSON errors, KeyError, TypeError, AttributeError, IndexError, and the
  RecursionError of JSON nested thousands deep) as BadInput naming option."""
  existing_file(option, path)
  try:
    return load(path, *args)
  except BadInput:
    raise
  except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError) as e:
    raise BadInput(f"{option} = '{echo(path)}': not a file this tool reads ({type(e).__name__}: {echo(e)})") from None
  except RecursionError:  # Python's json recurses per level of nesting
    raise BadInput(f"{option} = '{echo(path)}': not a file this tool reads (JSON nested too deep to read)") from None


def existing_file(option, path):
  """A regular file or a pipe (the shell's <(command)) that exists."""
  if path is None or str(path) == "":
    raise BadInput(f"{option} is empty: a file is needed")
  if not os.path.exists(path):
    raise BadInput(f"{option} = '{echo(path)}': file not found")
  if os.path.isdir(path):
    raise BadInput(f"{option} = '{echo(path)}': a directory, not a file")
  return path


def json_document(option, path, kinds=(dict,)):
  """The JSON document in the file `path`, of one of the Python types `kinds` (dict: an
  object, list: an array)."""
  def load(p):
    with open(p, encoding="utf-8") as f:
      data = json.load(f)
    if not isinstance(data, kinds):
      names = " or ".join({dict: "an object", list: "an array"}.get(k, k.__name__) for k in kinds)
      raise BadInput(f"{option} = '{echo(p)}': a JSON {type(data).__name__}, not {names}")
    return data
  return checked(load, option, path)


def json_object(option, path):
  """The JSON object (dict) in the file `path`."""
  return json_document(option, path, (dict,))


def executable(option, path):
  """A regular file this user may execute."""
  existing_file(option, path)
  if not os.access(path, os.X_OK):
    raise BadInput(f"{option} = '{echo(path)}': not executable")
  return path


def kneedyn_executable(option, path):
  """The kneedyn program: executable, and its --version starts with 'kneedyn '."""
  executable(option, path)
  try:
    out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=60).stdout
    out = out.splitlines()[0] if out else ""
  except (OSError, subprocess.SubprocessError) as e:
    raise BadInput(f"{option} = '{echo(path)}': could not run it ({echo(e)})") from None
  if not out.startswith("kneedyn "):
    raise BadInput(f"{option} = '{echo(path)}': not the kneedyn program ('--version' printed "
                   f"'{echo(out.strip(), 80)}', not 'kneedyn <version> ...')")
  return path


def _nearest_existing_ancestor(path):
  p = os.path.abspath(path)
  while not os.path.exists(p):
    parent = os.path.dirname(p)
    if parent == p:
      break
    p = parent
  return p


def _unwritable(directory):
  """Why `directory` cannot be made or written, or None. A probe directory is made and
  removed in its nearest existing ancestor: access() says yes to root even under /proc."""
  base = _nearest_existing_ancestor(directory)
  try:
    os.rmdir(tempfile.mkdtemp(prefix=".kneedyn-probe-", dir=base))
  except OSError as e:
    return f"cannot be created or written in '{echo(base)}' ({echo(e.strerror or e)})"
  return None


def output_directory(option, path):
  """A directory that exists or can be made (not an existing file), checked before any run
  as formulations/output_file.hpp does."""
  if path is None or str(path) == "":
    raise BadInput(f"{option} is empty: a directory is needed")
  if os.path.exists(path) and not os.path.isdir(path):
    raise BadInput(f"{option} = '{echo(path)}': an existing file, not a directory")
  why = _unwritable(path)
  if why:
    raise BadInput(f"{option} = '{echo(path)}': {why}")
  return path


def output_file(option, path):
  """A file that can be written: not a directory, in a directory that exists or can be made."""
  if path is None or str(path) == "":
    raise BadInput(f"{option} is empty: a file name is needed")
  if os.path.isdir(path):
    raise BadInput(f"{option} = '{echo(path)}': a directory, not a file")
  why = _unwritable(os.path.dirname(os.path.abspath(path)))
  if why:
    raise BadInput(f"{option} = '{echo(path)}': {why}")
  return path


def number(option, value, low=None, high=None, low_open=False, integer=False):
  """A finite number within [low, high] (low excluded when low_open)."""
  ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
  if ok and integer:
    ok = float(value).is_integer()
  if ok and low is not None:
    ok = value > low if low_open else value >= low
  if ok and high is not None:
    ok = value <= high
  if not ok:
    lo = "" if low is None else ("(" if low_open else "[") + f"{low:g}"
    hi = "" if high is None else f"{high:g}]"
    what = "a whole number" if integer else "a finite number"
    rng = f" in {lo or '(-inf'}, {hi or 'inf)'}" if (low is not None or high is not None) else ""
    raise BadInput(f"{option} = {echo(value)}: must be {what}{rng}")
  return value
