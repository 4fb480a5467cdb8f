"""Helpers shared by the Python test scripts under tests/ (test_support.hpp is the C++ side)."""
import sys


def finish(errors, fail_prefix, summary, stream=None):
  """Prints each error after fail_prefix (on stream, default stderr), then the summary line on
  stdout; returns the script's exit status: 1 if there are errors, else 0."""
  for e in errors:
    print(fail_prefix, e, file=stream or sys.stderr)
  print(summary)
  return 1 if errors else 0
